//! Sensor models of App. C with the 3σ values of Tables E.12–E.13 (white noise: per sample; bias:
//! stationary ECRV, see [`crate::model::ecrv`]).
//!
//! - Gyro (C.1)–(C.3): ω̃ = δR(ε_ω)[(I + diag f_ω) ω + b_ω + w_ω]; f_ω 3e-4, ε_ω 3 mrad (drawn once),
//!   w_ω 22.5 µrad/s, b_ω 3 deg/h.
//! - Star tracker (C.4)–(C.6): q̃ = δq(w_q) ⊗ δq(b_q) ⊗ q; follower (NISTEx-II) w_q 41 mas,
//!   b_q 0.1 mas; leader 3′ and 3′; τ_q 1 h.
//! - Accelerometer (C.7)–(C.8): ã = a_ng + b_r + w_r; w_r 1 ng, b_r 1 µg, τ_r 1 h.
//! - Radio ranging (C.10)–(C.11), follower: r̃_z = r_rel,z + ε_rz + w_rz; 1 m, 1 m, τ 1 h.
//! - Laser interferometer (Table E.13), follower: r̃_xy = r_rel,xy + ε + w; 0.2 mm, 0.01 mm, τ 1 h.
//!
//! Where the print is wrong or silent (our choices):
//! - the gyro's "w_ω micro-N" is 22.5 µrad/s and the accelerometer's "w_br micro-N" is 1 µg;
//! - the gyro bias has no correlation time in Table E.12: we take 1 h like every other bias;
//! - the accelerometer senses the non-gravitational acceleration (thrust and the perturbation
//!   u_g), averaged over the step that ended at the reading (an accelerometer integrates Δv), in
//!   ECI axes (the paper's (C.7) has no rotation);
//! - ranging measures the ECI z component of r_rel and the interferometer its x and y components
//!   (r_rel^f = [0, 0, 1] km is along ECI z; the paper names no frame);
//! - every sensor is read every step.
//!
//! Biases start from their stationary distribution.

use nalgebra::{Matrix3, SVector};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::model::ecrv::{Ecrv, white};
use crate::model::quaternion::{self, Quat, V3, skew};

/// 3σ values of one sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    pub scale_3sigma: f64,
    pub misalignment_3sigma_rad: f64,
    pub noise_3sigma: f64,
    pub bias_3sigma: f64,
    pub bias_tau_s: f64,
}

/// A sensor with N axes: additive bias (ECRV) and white noise; the gyro also has scale factor
/// and misalignment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axes<const N: usize> {
    pub scale: SVector<f64, N>,
    pub misalignment: Matrix3<f64>,
    pub bias: Ecrv<N>,
    pub noise_sigma: f64,
}

impl<const N: usize> Axes<N> {
    pub fn new<R: Rng>(m: &SensorModel, rng: &mut R) -> Self {
        let scale = white::<N, _>(m.scale_3sigma / 3.0, rng);
        let eps = white::<3, _>(m.misalignment_3sigma_rad / 3.0, rng);
        let bias = Ecrv::drawn(m.bias_3sigma / 3.0, m.bias_3sigma / 3.0, m.bias_tau_s, rng);
        Self { scale, misalignment: Matrix3::identity() - skew(&eps), bias, noise_sigma: m.noise_3sigma / 3.0 }
    }

    /// bias + (I + diag f) x + w, without misalignment (for sensors that have none).
    pub fn read<R: Rng>(&self, x: &SVector<f64, N>, rng: &mut R) -> SVector<f64, N> {
        x + self.scale.component_mul(x) + self.bias.value + white::<N, _>(self.noise_sigma, rng)
    }
}

/// The gyro (C.1).
pub fn read_gyro<R: Rng>(g: &Axes<3>, omega_body_rad_s: &V3, rng: &mut R) -> V3 {
    g.misalignment * g.read(omega_body_rad_s, rng)
}

/// The star tracker (C.4): the bias and noise are small rotations in the body frame.
pub fn read_star_tracker<R: Rng>(st: &Axes<3>, q_body_eci: &Quat, rng: &mut R) -> Quat {
    let w = white::<3, _>(st.noise_sigma, rng);
    let biased = quaternion::compose(&quaternion::from_rotation_vector(&st.bias.value), q_body_eci);
    quaternion::compose(&quaternion::from_rotation_vector(&w), &biased)
}

/// Every sensor of one spacecraft. The relative sensors are the follower's only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorSuite {
    pub gyro: Axes<3>,
    pub star_tracker: Axes<3>,
    pub accelerometer: Axes<3>,
    pub ranging: Option<Axes<1>>,
    pub interferometer: Option<Axes<2>>,
}

impl SensorSuite {
    /// Advance every bias by `dt_s`, in a fixed order.
    pub fn advance<R: Rng>(&mut self, dt_s: f64, rng: &mut R) {
        self.gyro.bias.advance(dt_s, rng);
        self.star_tracker.bias.advance(dt_s, rng);
        self.accelerometer.bias.advance(dt_s, rng);
        if let Some(r) = &mut self.ranging {
            r.bias.advance(dt_s, rng);
        }
        if let Some(i) = &mut self.interferometer {
            i.bias.advance(dt_s, rng);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_stats::corr_and_std;
    use nalgebra::{Vector1, Vector2};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    const N: usize = 100_000;

    fn model(noise: f64, bias: f64) -> SensorModel {
        SensorModel {
            scale_3sigma: 0.0,
            misalignment_3sigma_rad: 0.0,
            noise_3sigma: noise,
            bias_3sigma: bias,
            bias_tau_s: 3600.0,
        }
    }

    /// σ of the noise with the bias held at 0, then σ and τ of the bias stepped at τ/20 with the
    /// noise off; `read` gives one scalar reading of a zero truth.
    fn check<const M: usize>(
        name: &str,
        noise_3sigma: f64,
        bias_3sigma: f64,
        read: impl Fn(&Axes<M>, &mut ChaCha8Rng) -> f64,
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(name.len() as u64 + 100);
        let mut s = Axes::<M>::new(&model(noise_3sigma, bias_3sigma), &mut rng);
        s.bias.value = SVector::zeros();
        let xs: Vec<f64> = (0..N).map(|_| read(&s, &mut rng)).collect();
        let (_, std) = corr_and_std(&xs);
        assert!((std / (noise_3sigma / 3.0) - 1.0).abs() < 0.05, "{name}: noise σ {std:e} vs {:e}", noise_3sigma / 3.0);
        let mut s = Axes::<M>::new(&model(0.0, bias_3sigma), &mut rng);
        let dt = 180.0;
        let xs: Vec<f64> = (0..N)
            .map(|_| {
                s.bias.advance(dt, &mut rng);
                read(&s, &mut rng)
            })
            .collect();
        let (rho, std) = corr_and_std(&xs);
        let tau = -dt / rho.ln();
        assert!((std / (bias_3sigma / 3.0) - 1.0).abs() < 0.05, "{name}: bias σ {std:e} vs {:e}", bias_3sigma / 3.0);
        assert!((tau / 3600.0 - 1.0).abs() < 0.10, "{name}: correlation time {tau} s vs 3600 s");
    }

    #[test]
    fn gyro_noise_and_bias() {
        let (w, b) = (22.5e-6, 3f64.to_radians() / 3600.0);
        check::<3>("gyro", w, b, |s, r| read_gyro(s, &V3::zeros(), r).y);
    }

    #[test]
    fn star_tracker_noise_and_bias_follower_and_leader() {
        let mas = (1e-3 / 3600.0f64).to_radians();
        let arcmin = (1.0 / 60.0f64).to_radians();
        for (name, w, b) in [("st-follower", 41.0 * mas, 0.1 * mas), ("st-leader", 3.0 * arcmin, 3.0 * arcmin)] {
            let read = |s: &Axes<3>, r: &mut ChaCha8Rng| {
                let q = read_star_tracker(s, &quaternion::identity(), r);
                quaternion::rotation_vector(&q).z
            };
            check::<3>(name, w, b, read);
        }
    }

    #[test]
    fn accelerometer_noise_and_bias() {
        let g = 9.80665;
        check::<3>("accelerometer", 1e-9 * g, 1e-6 * g, |s, r| s.read(&V3::zeros(), r).x);
    }

    #[test]
    fn ranging_and_interferometer_noise_and_bias() {
        check::<1>("ranging", 1.0, 1.0, |s, r| s.read(&Vector1::zeros(), r)[0]);
        check::<2>("interferometer", 2e-4, 1e-5, |s, r| s.read(&Vector2::zeros(), r)[1]);
    }

    #[test]
    fn star_tracker_reading_is_the_truth_rotated_by_bias_and_noise() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut st = Axes::<3>::new(&model(0.0, 0.0), &mut rng);
        st.bias.value = V3::new(1e-4, -2e-4, 3e-4);
        let q = Quat::new(0.3, -0.2, 0.1, 0.9).normalize();
        let got = read_star_tracker(&st, &q, &mut rng);
        let d = quaternion::rotation_vector(&quaternion::compose(&got, &quaternion::conjugate(&q)));
        assert!((d - st.bias.value).norm() < 1e-15, "{d}");
    }
}
