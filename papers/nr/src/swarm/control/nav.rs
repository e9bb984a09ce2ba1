//! A vehicle's own-state estimator for the swarm (Sec. 7.2 of "Neural-Rendezvous",
//! arXiv:2208.04883): the p̂, v̂ it flies with and shares.
//!
//! The plant reads each vehicle's position and velocity with white noise (1 mm, 1 cm/s); flown raw,
//! a policy with a velocity gain turns the 1 cm/s into command noise, and ∫‖u‖dt, a sum of norms,
//! grows with it (the campaign measured NR at ≈ 1.5× the global solution's effort with the noise
//! and 0.99–1.04× without). The vehicle knows its own command, so a Kalman filter on the double
//! integrator removes most of it: per axis, state x = (p, v), xₖ₊₁ = F xₖ + G uₖ + G wₖ with
//! F = [[1, Δt], [0, 1]], G = (Δt²/2, Δt), wₖ the acceleration the model misses (the disturbance, a
//! clipped command), white with σ_a; both readings, z = x + n, R = diag(σ_p², σ_v²). The first
//! reading initialises x̂ with P = R. The three axes are independent and share one P.
//!
//! Choices (ours; the paper's vehicles use motion capture and the Crazyflie's own filter): σ_p,
//! σ_v and σ_a are scenario keys (`algorithm.estimator`); σ_a stands for what the model misses, so
//! it is the disturbance's per-axis size where there is one (d̄/√3) and small otherwise.

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::iso::config::positive;

type V3 = [f64; 3];

fn d_pos() -> f64 {
    1e-3
}
fn d_vel() -> f64 {
    1e-2
}
fn d_accel() -> f64 {
    0.02
}

/// `[algorithm.estimator]`: the Kalman filter's noise model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorConfig {
    /// σ_p of the position reading, m.
    #[serde(default = "d_pos")]
    pub pos_sigma_m: f64,
    /// σ_v of the velocity reading, m/s.
    #[serde(default = "d_vel")]
    pub vel_sigma_mps: f64,
    /// σ_a of the acceleration the model misses, per axis, m/s².
    #[serde(default = "d_accel")]
    pub accel_sigma_mps2: f64,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

impl EstimatorConfig {
    /// Every problem, with its key path.
    pub fn validate(&self) -> Vec<Problem> {
        let mut p = Vec::new();
        positive(&mut p, "algorithm.estimator.pos_sigma_m", self.pos_sigma_m);
        positive(&mut p, "algorithm.estimator.vel_sigma_mps", self.vel_sigma_mps);
        positive(&mut p, "algorithm.estimator.accel_sigma_mps2", self.accel_sigma_mps2);
        p
    }
}

/// The filter's state (part of the agent's checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct OwnState {
    pub p_m: V3,
    pub v_mps: V3,
    /// Covariance [[pp, pv], [pv, vv]] of every axis.
    pub cov: [f64; 3],
    pub started: bool,
}

impl OwnState {
    /// Predict over `dt_s` with the command `u` that was flown.
    pub fn predict(&mut self, cfg: &EstimatorConfig, u: V3, dt_s: f64) {
        if !self.started {
            return;
        }
        let (h2, q) = (0.5 * dt_s * dt_s, cfg.accel_sigma_mps2 * cfg.accel_sigma_mps2);
        for k in 0..3 {
            self.p_m[k] += self.v_mps[k] * dt_s + h2 * u[k];
            self.v_mps[k] += u[k] * dt_s;
        }
        let [pp, pv, vv] = self.cov;
        self.cov = [
            pp + 2.0 * dt_s * pv + dt_s * dt_s * vv + h2 * h2 * q,
            pv + dt_s * vv + h2 * dt_s * q,
            vv + dt_s * dt_s * q,
        ];
    }

    /// Fold in the readings (p, v); the first one initialises.
    pub fn update(&mut self, cfg: &EstimatorConfig, p: V3, v: V3) {
        let (rp, rv) = (cfg.pos_sigma_m * cfg.pos_sigma_m, cfg.vel_sigma_mps * cfg.vel_sigma_mps);
        if !self.started {
            *self = OwnState { p_m: p, v_mps: v, cov: [rp, 0.0, rv], started: true };
            return;
        }
        // K = P (P + R)⁻¹ for the 2 × 2 symmetric P, R = diag(rp, rv).
        let [pp, pv, vv] = self.cov;
        let (a, b, d) = (pp + rp, pv, vv + rv);
        let det = a * d - b * b;
        let (i11, i12, i22) = (d / det, -b / det, a / det);
        let k = [[pp * i11 + pv * i12, pp * i12 + pv * i22], [pv * i11 + vv * i12, pv * i12 + vv * i22]];
        for ax in 0..3 {
            let (ep, ev) = (p[ax] - self.p_m[ax], v[ax] - self.v_mps[ax]);
            self.p_m[ax] += k[0][0] * ep + k[0][1] * ev;
            self.v_mps[ax] += k[1][0] * ep + k[1][1] * ev;
        }
        // P ← (I − K) P.
        self.cov = [
            (1.0 - k[0][0]) * pp - k[0][1] * pv,
            (1.0 - k[0][0]) * pv - k[0][1] * vv,
            -k[1][0] * pv + (1.0 - k[1][1]) * vv,
        ];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    #[test]
    fn without_noise_the_estimate_is_the_truth() {
        let cfg = EstimatorConfig::default();
        let mut s = OwnState::default();
        let (mut p, mut v) = ([0.0, 1.0, 2.0], [0.3, -0.1, 0.0]);
        for k in 0..50 {
            s.update(&cfg, p, v);
            for ax in 0..3 {
                assert!((s.p_m[ax] - p[ax]).abs() < 1e-12 && (s.v_mps[ax] - v[ax]).abs() < 1e-12, "k = {k}");
            }
            let u = [0.5, -0.2, (k as f64 * 0.1).sin()];
            s.predict(&cfg, u, 0.1);
            p = [0, 1, 2].map(|a| p[a] + v[a] * 0.1 + 0.005 * u[a]);
            v = [0, 1, 2].map(|a| v[a] + 0.1 * u[a]);
        }
    }

    #[test]
    fn it_cuts_the_velocity_noise_it_is_told_of() {
        let cfg = EstimatorConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut s = OwnState::default();
        let (mut p, mut v) = ([0.0; 3], [0.2, 0.0, -0.1]);
        let (mut raw, mut est, mut n) = (0.0, 0.0, 0.0);
        for k in 0..2000 {
            let mut g = || rng.sample::<f64, _>(StandardNormal);
            let z_p = p.map(|x| x + 1e-3 * g());
            let z_v = v.map(|x| x + 1e-2 * g());
            s.update(&cfg, z_p, z_v);
            if k >= 100 {
                for a in 0..3 {
                    raw += (z_v[a] - v[a]).powi(2);
                    est += (s.v_mps[a] - v[a]).powi(2);
                    n += 1.0;
                }
            }
            let u = [0.1 * (k as f64 * 0.01).cos(), 0.0, 0.05];
            s.predict(&cfg, u, 0.1);
            // The truth also feels the acceleration the filter is told it misses.
            let w = [0; 3].map(|_| cfg.accel_sigma_mps2 * rng.sample::<f64, _>(StandardNormal));
            p = [0, 1, 2].map(|a| p[a] + v[a] * 0.1 + 0.005 * (u[a] + w[a]));
            v = [0, 1, 2].map(|a| v[a] + 0.1 * (u[a] + w[a]));
        }
        let (raw, est) = ((raw / n).sqrt(), (est / n).sqrt());
        assert!(est < 0.5 * raw, "velocity error {est} m/s against the reading's {raw} m/s");
        // P's velocity variance is what the error is.
        assert!((s.cov[2].sqrt() / est - 1.0).abs() < 0.3, "σ_v {} vs measured {est}", s.cov[2].sqrt());
    }

    #[test]
    fn bad_settings_are_named() {
        assert!(EstimatorConfig::default().validate().is_empty());
        let e: Vec<String> = EstimatorConfig { pos_sigma_m: 0.0, vel_sigma_mps: -1.0, accel_sigma_mps2: f64::NAN }
            .validate()
            .iter()
            .map(|p| p.to_string())
            .collect();
        for key in ["pos_sigma_m", "vel_sigma_mps", "accel_sigma_mps2"] {
            assert!(e.iter().any(|p| p.contains(&format!("algorithm.estimator.{key}"))), "{key} not in {e:?}");
        }
        assert!(toml::from_str::<EstimatorConfig>("gain = 1.0").is_err());
    }
}
