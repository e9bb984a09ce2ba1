//! Rigid-body attitude truth of one spacecraft, (13)–(15) with the gravity-gradient torque (23)
//! and the time-varying inertia J = J̄ + δJ(t) of (E.1)–(E.2):
//!
//!   q̇ = ½ ω ⊗ q,   ω̇ = J⁻¹(τ − ω × Jω),   τ = τ_in + τ_g + w_ω,   τ_g = 3μ/|r|³ n × (J n),
//!
//! with n the nadir unit vector in the body frame, J̄ = diag(0.1383, 0.1577, 0.1039) kg·m² and
//! δJ = diag(0.0038 sin t, 0.005 cos t, 0.0011) kg·m² (t in s).
//!
//! Departures from the print, and why:
//! - (12) writes J⁻¹ = J̄⁻¹ + δJ⁻¹; δJ⁻¹ does not exist when sin t or cos t is zero, so we use
//!   J = J̄ + δJ(t).
//! - (14) is kept as printed: no J̇ω term. δJ models an uncertain inertia, not moving mass.
//! - Over one step τ_in and w_ω are held (zero-order hold), the position r (for τ_g) is held at
//!   its value at the start of the step (it moves ≈ 10 m of 7.8e7 m in 10 ms), and J(t) and τ_g
//!   are evaluated at each RK4 stage.
//! - "RK4 … ensuring that the quaternion unity norm constraint is maintained" (Sec. 4) does not
//!   hold for plain RK4 on q (at 0.6 rad/s and dt = 10 ms its norm drifts 5e-12 per hour): ω is
//!   integrated by RK4 and q by the exponential of a fourth-order Magnus step built from RK4's
//!   stages (Sveier et al.'s Runge–Kutta–Munthe-Kaas idea, the paper's ref. [26]), which keeps
//!   ‖q‖ = 1 to rounding with no renormalisation.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::model::quaternion::{self, Quat, V3};

/// The inertia model: J̄ (diagonal) plus δJ(t) = diag(a₁ sin t, a₂ cos t, a₃).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Inertia {
    pub nominal_kg_m2: [f64; 3],
    pub error_amplitude_kg_m2: [f64; 3],
}

impl Inertia {
    pub fn at(&self, t_s: f64) -> Matrix3<f64> {
        let (n, a) = (self.nominal_kg_m2, self.error_amplitude_kg_m2);
        Matrix3::from_diagonal(&V3::new(n[0] + a[0] * t_s.sin(), n[1] + a[1] * t_s.cos(), n[2] + a[2]))
    }
    pub fn nominal(&self) -> Matrix3<f64> {
        Matrix3::from_diagonal(&V3::from(self.nominal_kg_m2))
    }
}

/// The gravity-gradient torque (23), N·m, body frame.
pub fn gravity_gradient(q: &Quat, r_eci_m: &V3, j: &Matrix3<f64>, mu_m3ps2: f64) -> V3 {
    let rn = r_eci_m.norm();
    let nadir = quaternion::attitude_matrix(q) * (-r_eci_m / rn);
    3.0 * mu_m3ps2 / (rn * rn * rn) * nadir.cross(&(j * nadir))
}

/// What acts on the body over one step.
#[derive(Debug, Clone, Copy)]
pub struct TorqueInputs<'a> {
    pub inertia: &'a Inertia,
    /// τ_in + w_ω, held over the step, N·m.
    pub held_torque_n_m: V3,
    /// Position for τ_g (held over the step), m; `None` switches τ_g off.
    pub gravity_gradient_r_eci_m: Option<V3>,
    pub mu_m3ps2: f64,
}

/// One spacecraft's attitude truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttitudeState {
    pub q_body_eci: Quat,
    pub omega_body_rad_s: V3,
}

impl AttitudeState {
    fn derivative(q: &Quat, w: &V3, t_s: f64, inp: &TorqueInputs<'_>) -> (Quat, V3) {
        let j = inp.inertia.at(t_s);
        let mut tau = inp.held_torque_n_m;
        if let Some(r) = &inp.gravity_gradient_r_eci_m {
            tau += gravity_gradient(q, r, &j, inp.mu_m3ps2);
        }
        // J is diagonal: its inverse is the reciprocal of the diagonal.
        let jw = j * w;
        let wdot = (tau - w.cross(&jw)).component_div(&j.diagonal());
        (quaternion::rate(q, w), wdot)
    }

    /// One step from t_s to t_s + dt_s: RK4 for ω (its stages carry RK4 quaternions for τ_g), and
    /// for q the exponential of the fourth-order Magnus expansion built from the same stages,
    /// q ← exp(½φ) ⊗ q with φ = ∫ω dt + (Δt²/12) ω₀ × ω₁, where ∫ω dt is RK4's own quadrature of
    /// the stage rates. The update is a unit quaternion, so ‖q‖ stays 1 to rounding.
    pub fn rk4_step(&mut self, t_s: f64, dt_s: f64, inp: &TorqueInputs<'_>) {
        let h = dt_s;
        let (q0, w0) = (self.q_body_eci, self.omega_body_rad_s);
        let k1 = Self::derivative(&q0, &w0, t_s, inp);
        let (q2, w2) = (q0 + 0.5 * h * k1.0, w0 + 0.5 * h * k1.1);
        let k2 = Self::derivative(&q2, &w2, t_s + 0.5 * h, inp);
        let (q3, w3) = (q0 + 0.5 * h * k2.0, w0 + 0.5 * h * k2.1);
        let k3 = Self::derivative(&q3, &w3, t_s + 0.5 * h, inp);
        let (q4, w4) = (q0 + h * k3.0, w0 + h * k3.1);
        let k4 = Self::derivative(&q4, &w4, t_s + h, inp);
        let w1 = w0 + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        let phi = h / 6.0 * (w0 + 2.0 * w2 + 2.0 * w3 + w4) + (h * h / 12.0) * w0.cross(&w1);
        self.q_body_eci = quaternion::compose(&quaternion::from_rotation_vector(&phi), &q0);
        self.omega_body_rad_s = w1;
    }

    /// Angular momentum in ECI, A(q)ᵀ J ω, N·m·s.
    pub fn momentum_eci(&self, j: &Matrix3<f64>) -> V3 {
        quaternion::attitude_matrix(&self.q_body_eci).transpose() * (j * self.omega_body_rad_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE_E: Inertia =
        Inertia { nominal_kg_m2: [0.1383, 0.1577, 0.1039], error_amplitude_kg_m2: [0.0038, 0.005, 0.0011] };

    fn free(inertia: &Inertia) -> TorqueInputs<'_> {
        TorqueInputs { inertia, held_torque_n_m: V3::zeros(), gravity_gradient_r_eci_m: None, mu_m3ps2: 0.0 }
    }

    #[test]
    fn quaternion_norm_is_kept_to_1e12_over_an_hour() {
        // Tumbling at the transient phase's 1σ rate (0.6 rad/s, (87)) with δJ(t),
        // gravity gradient at apogee and a torque: everything the truth integrates.
        let r = V3::new(-7.7e7, 6.0e6, 4.0e5);
        let mut worst: f64 = 0.0;
        for w0 in [V3::new(1e-3, -2e-3, 5e-4), V3::new(0.35, -0.3, 0.35)] {
            let mut s = AttitudeState { q_body_eci: Quat::new(0.1, -0.5, 0.3, 0.8).normalize(), omega_body_rad_s: w0 };
            let inp = TorqueInputs {
                inertia: &TABLE_E,
                held_torque_n_m: V3::new(1e-5, -2e-5, 1e-5),
                gravity_gradient_r_eci_m: Some(r),
                mu_m3ps2: crate::model::orbit::MU_EARTH_M3PS2,
            };
            let dt = 0.01;
            for k in 0..360_000 {
                s.rk4_step(k as f64 * dt, dt, &inp);
                worst = worst.max((s.q_body_eci.norm() - 1.0).abs());
            }
        }
        assert!(worst < 1e-12, "‖q‖ − 1 reached {worst:e}");
    }

    #[test]
    fn the_step_is_fourth_order_against_a_fine_reference() {
        // Plain RK4 at 1 µs is the reference; the step's error must fall ≈ 16× per halving.
        let inp = TorqueInputs {
            inertia: &TABLE_E,
            held_torque_n_m: V3::new(2e-3, -1e-3, 3e-3),
            gravity_gradient_r_eci_m: Some(V3::new(7.0e6, 1.0e6, 0.5e6)),
            mu_m3ps2: crate::model::orbit::MU_EARTH_M3PS2,
        };
        let s0 = AttitudeState {
            q_body_eci: Quat::new(0.1, -0.5, 0.3, 0.8).normalize(),
            omega_body_rad_s: V3::new(0.5, -0.4, 0.6),
        };
        let t_end: f64 = 1.0;
        let mut fine = s0.clone();
        let h: f64 = 1e-5;
        for k in 0..(t_end / h).round() as usize {
            let (q0, w0, t) = (fine.q_body_eci, fine.omega_body_rad_s, k as f64 * h);
            let k1 = AttitudeState::derivative(&q0, &w0, t, &inp);
            let k2 = AttitudeState::derivative(&(q0 + 0.5 * h * k1.0), &(w0 + 0.5 * h * k1.1), t + 0.5 * h, &inp);
            let k3 = AttitudeState::derivative(&(q0 + 0.5 * h * k2.0), &(w0 + 0.5 * h * k2.1), t + 0.5 * h, &inp);
            let k4 = AttitudeState::derivative(&(q0 + h * k3.0), &(w0 + h * k3.1), t + h, &inp);
            fine.q_body_eci = q0 + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            fine.omega_body_rad_s = w0 + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        }
        let err = |dt: f64| {
            let mut s = s0.clone();
            for k in 0..(t_end / dt).round() as usize {
                s.rk4_step(k as f64 * dt, dt, &inp);
            }
            (s.q_body_eci - fine.q_body_eci).norm() + (s.omega_body_rad_s - fine.omega_body_rad_s).norm()
        };
        let (e1, e2) = (err(0.1), err(0.05));
        assert!(e1 / e2 > 12.0 && e2 < 1e-6, "errors {e1:e} at 0.1 s, {e2:e} at 0.05 s");
    }

    #[test]
    fn torque_free_body_with_constant_inertia_conserves_angular_momentum() {
        let j = Inertia { error_amplitude_kg_m2: [0.0; 3], ..TABLE_E };
        let mut s = AttitudeState {
            q_body_eci: Quat::new(0.2, 0.1, -0.4, 0.9).normalize(),
            omega_body_rad_s: V3::new(0.3, -0.2, 0.25),
        };
        let h0 = s.momentum_eci(&j.at(0.0));
        let e0 = 0.5 * s.omega_body_rad_s.dot(&(j.at(0.0) * s.omega_body_rad_s));
        let dt = 0.01;
        for k in 0..100_000 {
            s.rk4_step(k as f64 * dt, dt, &free(&j));
        }
        let h1 = s.momentum_eci(&j.at(0.0));
        let e1 = 0.5 * s.omega_body_rad_s.dot(&(j.at(0.0) * s.omega_body_rad_s));
        let dh = (h1 - h0).norm() / h0.norm();
        assert!(dh < 1e-10, "‖ΔH‖/‖H‖ = {dh:e} over 1000 s");
        assert!(((e1 - e0) / e0).abs() < 1e-10, "ΔE/E = {:e}", (e1 - e0) / e0);
    }

    #[test]
    fn gravity_gradient_vanishes_on_principal_axes_and_has_the_textbook_size() {
        let j = TABLE_E.nominal();
        let mu = crate::model::orbit::MU_EARTH_M3PS2;
        let r = V3::new(7.0e6, 0.0, 0.0);
        // Nadir along a principal axis: no torque.
        assert!(gravity_gradient(&quaternion::identity(), &r, &j, mu).norm() < 1e-20);
        // Rotated 45° about z: nadir in the x–y plane, τ_z = 3μ/r³ (J_yy − J_xx) n_x n_y.
        let q = quaternion::from_rotation_vector(&V3::new(0.0, 0.0, std::f64::consts::FRAC_PI_4));
        let t = gravity_gradient(&q, &r, &j, mu);
        let n = quaternion::attitude_matrix(&q) * V3::new(-1.0, 0.0, 0.0);
        let want = 3.0 * mu / 7.0e6f64.powi(3) * (j[(1, 1)] - j[(0, 0)]) * n.x * n.y;
        assert!((t.z - want).abs() < 1e-12 * want.abs() && t.x.abs() < 1e-25 && t.y.abs() < 1e-25, "{t} vs {want}");
    }
}
