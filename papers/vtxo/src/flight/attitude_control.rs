//! Attitude control laws of Sec. 2.11 on the navigation estimates q̂, ω̂, with δq = q̂ ⊗ q_f⁻¹
//! (47) and ω_f = 0, ω̇_f = 0 (VTXO holds inertial targets):
//!
//! - Lyapunov (57), transient: τ̂ = −k₁ sign(δq₄) δq₁:₃ − k₂ (1 − δq₁:₃ᵀδq₁:₃) ω̂;
//! - PD (54), science, k̂ = [k_P, k_D] (55): τ̂ = −k_P sign(δq₄) δq₁:₃ − k_D (ω̂ − ω_f);
//! - SMC (58)–(60), science, k̂ = [z, k_SMC, ε] (63): ŝ = (ω̂ − ω_f) + k sign(δq₄) δq₁:₃ and
//!   τ̂ = J̄{(k/2)[|δq₄|(ω_f − ω̂) − sign(δq₄) δq₁:₃ × (ω_f + ω̂)] + ω̇_f − z sat(ŝ, ε)} + ω̂ × J̄ω̂.
//!
//! Departures from the print: (54) as printed,
//! τ̂ = k_P δq₁:₃ − k_D(ω_f − ω), is positive feedback in both terms; we use the stabilising signs
//! above, with sign(δq₄) so that the shorter rotation is taken as in (57) and (58). (59) uses the
//! true J, which no flight computer knows: we use the nominal J̄. sign(0) is taken as +1.
//!
//! The law is a value ([`AttitudeLaw`]) an agent holds and can be handed at run time, so a
//! supervisor can switch Lyapunov → PD/SMC with gains it chooses.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::model::quaternion::{self, Quat, V3, sign_nonzero};

/// One attitude control law with its gains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum AttitudeLaw {
    /// (57), gains k₁, k₂ (N·m and N·m·s).
    Lyapunov { k1: f64, k2: f64 },
    /// (54), gains k_P (N·m), k_D (N·m·s).
    Pd { k_p: f64, k_d: f64 },
    /// (58)–(60): z (1/s²), k_SMC (1/s), ε (rad/s).
    Smc { z: f64, k: f64, epsilon: f64 },
}

/// sat(s, ε) of (60) per component.
pub fn sat(s: &V3, epsilon: f64) -> V3 {
    s.map(|x| (x / epsilon).clamp(-1.0, 1.0))
}

/// The commanded wheel torque τ̂_in, N·m, body frame.
pub fn torque(law: &AttitudeLaw, q_hat: &Quat, omega_hat: &V3, q_target: &Quat, j_nominal: &Matrix3<f64>) -> V3 {
    let dq = quaternion::error(q_hat, q_target);
    let dv = V3::new(dq[0], dq[1], dq[2]);
    let sg = sign_nonzero(dq[3]);
    match *law {
        AttitudeLaw::Lyapunov { k1, k2 } => -k1 * sg * dv - k2 * (1.0 - dv.norm_squared()) * omega_hat,
        AttitudeLaw::Pd { k_p, k_d } => -k_p * sg * dv - k_d * omega_hat,
        AttitudeLaw::Smc { z, k, epsilon } => {
            let s = omega_hat + k * sg * dv;
            let inner = 0.5 * k * (-dq[3].abs() * omega_hat - sg * dv.cross(omega_hat)) - z * sat(&s, epsilon);
            j_nominal * inner + omega_hat.cross(&(j_nominal * omega_hat))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::attitude::{AttitudeState, Inertia, TorqueInputs};

    const J: Inertia = Inertia { nominal_kg_m2: [0.1383, 0.1577, 0.1039], error_amplitude_kg_m2: [0.0; 3] };

    /// Closed loop on the truth (no noise): the error after `t_s` from a 30° offset and a rate.
    fn settle(law: AttitudeLaw, t_s: f64) -> f64 {
        let qf = Quat::new(0.1, 0.2, -0.1, 0.97).normalize();
        let off = quaternion::from_rotation_vector(&V3::new(0.3, -0.3, 0.2));
        let mut s =
            AttitudeState { q_body_eci: quaternion::compose(&off, &qf), omega_body_rad_s: V3::new(0.01, -0.02, 0.01) };
        let dt = 0.01;
        for k in 0..(t_s / dt) as usize {
            let tau = torque(&law, &s.q_body_eci, &s.omega_body_rad_s, &qf, &J.nominal());
            let inp = TorqueInputs { inertia: &J, held_torque_n_m: tau, gravity_gradient_r_eci_m: None, mu_m3ps2: 0.0 };
            s.rk4_step(k as f64 * dt, dt, &inp);
        }
        quaternion::principal_angle(&quaternion::error(&s.q_body_eci, &qf))
    }

    #[test]
    fn every_law_brings_the_attitude_to_the_target() {
        for (law, t) in [
            (AttitudeLaw::Lyapunov { k1: 0.085, k2: 0.25 }, 300.0),
            (AttitudeLaw::Pd { k_p: 0.1208, k_d: 0.3786 }, 300.0),
            (AttitudeLaw::Smc { z: 2.9947, k: 0.0193, epsilon: 0.2601 }, 1500.0),
        ] {
            let e = settle(law, t);
            assert!(e < 1e-4, "{law:?}: {e} rad left after {t} s");
        }
    }

    #[test]
    fn smc_holds_the_sliding_surface_rate() {
        // On the truth with the true inertia equal to J̄, ṡ = −z sat(s, ε): far from the surface
        // s changes by −z·dt·sign(s) per step.
        let qf = quaternion::identity();
        let law = AttitudeLaw::Smc { z: 0.5, k: 0.1, epsilon: 0.01 };
        let mut st = AttitudeState { q_body_eci: quaternion::identity(), omega_body_rad_s: V3::new(0.3, 0.0, 0.0) };
        let s_of = |st: &AttitudeState| {
            let dq = quaternion::error(&st.q_body_eci, &qf);
            st.omega_body_rad_s + 0.1 * sign_nonzero(dq[3]) * V3::new(dq[0], dq[1], dq[2])
        };
        let s0 = s_of(&st);
        let tau = torque(&law, &st.q_body_eci, &st.omega_body_rad_s, &qf, &J.nominal());
        let inp = TorqueInputs { inertia: &J, held_torque_n_m: tau, gravity_gradient_r_eci_m: None, mu_m3ps2: 0.0 };
        st.rk4_step(0.0, 1e-3, &inp);
        let ds = (s_of(&st) - s0) / 1e-3;
        assert!((ds.x + 0.5).abs() < 1e-3, "ṡ = {ds}");
    }
}
