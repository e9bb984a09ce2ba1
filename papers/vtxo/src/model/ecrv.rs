//! Exponentially correlated random variables (first-order Gauss–Markov processes), the model of
//! every bias and slow disturbance in the paper: the perturbation acceleration (25), the wheel and
//! thruster biases (30), (33), and the sensor biases (C.3), (C.5), (C.8), (C.11):
//!
//!   ḃ = −b/τ + w.
//!
//! Discretised exactly over a step Δt: b⁺ = e^{−Δt/τ} b + σ √(1 − e^{−2Δt/τ}) n, n ~ N(0, 1), with
//! σ the stationary standard deviation, so the statistics do not depend on the step.
//!
//! Units of the tables (our reading, stated once here): every table value is a 3σ value; for an
//! ECRV it is the stationary 3σ of b (σ = value/3); for a white noise it is the 3σ of one sample
//! (one draw per step, held over the step). A white noise drawn once per step therefore has a
//! power spectral density proportional to the step: at dt = 1 ms its effect on an integrated
//! quantity is √10 smaller than at 10 ms. The paper does not say otherwise.

use nalgebra::SVector;
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// One N(0, 1) draw.
pub fn normal<R: Rng>(rng: &mut R) -> f64 {
    rng.sample(StandardNormal)
}

/// N axes of independent N(0, σ²) draws (one white-noise sample per axis).
pub fn white<const N: usize, R: Rng>(sigma: f64, rng: &mut R) -> SVector<f64, N> {
    SVector::from_fn(|_, _| sigma * normal(rng))
}

/// N independent ECRV axes with one stationary σ and correlation time τ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ecrv<const N: usize> {
    pub value: SVector<f64, N>,
    /// Stationary standard deviation.
    pub sigma: f64,
    pub tau_s: f64,
}

impl<const N: usize> Ecrv<N> {
    /// Started at a given value.
    pub fn starting_at(value: SVector<f64, N>, sigma: f64, tau_s: f64) -> Self {
        Self { value, sigma, tau_s }
    }

    /// Started at a draw from N(0, σ0²) per axis (σ0 = σ: the stationary distribution).
    pub fn drawn<R: Rng>(sigma0: f64, sigma: f64, tau_s: f64, rng: &mut R) -> Self {
        Self { value: white(sigma0, rng), sigma, tau_s }
    }

    /// Advance by `dt_s` (exact discretisation).
    pub fn advance<R: Rng>(&mut self, dt_s: f64, rng: &mut R) {
        let phi = (-dt_s / self.tau_s).exp();
        let q = self.sigma * (1.0 - phi * phi).max(0.0).sqrt();
        for i in 0..N {
            self.value[i] = phi * self.value[i] + q * normal(rng);
        }
    }

    /// The variance of the driving noise over one step of `dt_s`: σ²(1 − e^{−2Δt/τ}) (what a
    /// filter adds to a bias state's covariance per step).
    pub fn step_variance(sigma: f64, tau_s: f64, dt_s: f64) -> f64 {
        sigma * sigma * (1.0 - (-2.0 * dt_s / tau_s).exp())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn stationary_sigma_and_correlation_time() {
        // Δt = τ/20: 1e5 samples span 5000 correlation times.
        let (sigma, tau, dt) = (2.5, 3600.0, 180.0);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut b = Ecrv::<1>::drawn(sigma, sigma, tau, &mut rng);
        let xs: Vec<f64> = (0..100_000)
            .map(|_| {
                b.advance(dt, &mut rng);
                b.value[0]
            })
            .collect();
        let (rho, std) = crate::test_stats::corr_and_std(&xs);
        let tau_est = -dt / rho.ln();
        assert!((std / sigma - 1.0).abs() < 0.05, "σ {std} vs {sigma}");
        assert!((tau_est / tau - 1.0).abs() < 0.10, "τ {tau_est} vs {tau}");
    }
}
