//! Relative-position control laws of Sec. 2.11 in ECI, commanded accelerations (m/s²):
//!
//! - follower SMC (64)–(67): ŝ = (v̂_rel − v_f) + k(r̂_rel − r_f),
//!   û_F = μ(r̂_F/|r̂_F|³ − r̂_L/|r̂_L|³) + û_L − k(v̂_rel − v_f) − Z sat(ŝ, ε), Z = diag(z), with
//!   sat (67) or, as in Sec. 7, sign (`Switching::Sign`);
//! - follower PD (56): û_F = P(r_f − r̂_rel) + D(v_f − v̂_rel) (no gravity compensation);
//! - leader SMC (70): the same law for r_LF = r_L − r_F (= −r_rel) and target −r_f, treating the
//!   follower's thrust as a known disturbance: û_L = μ(r̂_L/|r̂_L|³ − r̂_F/|r̂_F|³) − û_F
//!   − k(v̂_LF − v_f^LF) − Z sat(ŝ_LF, ε).
//!
//! Departures and choices: the other spacecraft's command in (66) and (70) is its previous-step
//! command (the one it shared last), since using the current one is an algebraic loop; r̂_F = r̂_L + r̂_rel (the follower measures r̂_rel and receives r̂_L). sign(0) = 0
//! here, as in the textbook sliding law (an exact zero never occurs with noisy estimates).

use serde::{Deserialize, Serialize};

use crate::model::orbit::point_mass_accel;
use crate::model::quaternion::V3;

/// The switching function of the SMC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Switching {
    /// sign(s) (Sec. 7).
    Sign,
    /// sat(s, ε) (67).
    Sat,
}

/// One relative-position law with its gains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum RelativeLaw {
    /// k (1/s), Z per axis (m/s²), ε per axis (m/s).
    Smc { k: f64, z_mps2: [f64; 3], epsilon_mps: [f64; 3], switching: Switching },
    /// P (1/s²), D (1/s).
    Pd { p: f64, d: f64 },
    /// No thrust.
    Off,
}

/// What a law needs, all ECI.
#[derive(Debug, Clone, Copy)]
pub struct RelativeState {
    pub r_rel_m: V3,
    pub v_rel_mps: V3,
    pub r_leader_m: V3,
    pub r_target_m: V3,
    pub v_target_mps: V3,
    pub mu_m3ps2: f64,
}

fn switch(s: f64, eps: f64, sw: Switching) -> f64 {
    match sw {
        Switching::Sign => {
            if s > 0.0 {
                1.0
            } else if s < 0.0 {
                -1.0
            } else {
                0.0
            }
        }
        Switching::Sat => (s / eps).clamp(-1.0, 1.0),
    }
}

/// The sliding vector (64).
pub fn sliding_vector(k: f64, st: &RelativeState) -> V3 {
    (st.v_rel_mps - st.v_target_mps) + k * (st.r_rel_m - st.r_target_m)
}

/// −Z switch(s) per axis.
fn switching_term(z: &[f64; 3], eps: &[f64; 3], sw: Switching, s: &V3) -> V3 {
    V3::new(-z[0] * switch(s.x, eps[0], sw), -z[1] * switch(s.y, eps[1], sw), -z[2] * switch(s.z, eps[2], sw))
}

/// The follower's command û_F, m/s², given the leader's last command û_L.
pub fn follower_accel(law: &RelativeLaw, st: &RelativeState, u_leader_mps2: &V3) -> V3 {
    match *law {
        RelativeLaw::Smc { k, z_mps2, epsilon_mps, switching } => {
            let r_f = st.r_leader_m + st.r_rel_m;
            // μ(r_F/|r_F|³ − r_L/|r_L|³) = −(g(r_F) − g(r_L)).
            let grav = point_mass_accel(st.mu_m3ps2, &st.r_leader_m) - point_mass_accel(st.mu_m3ps2, &r_f);
            let s = sliding_vector(k, st);
            grav + u_leader_mps2 - k * (st.v_rel_mps - st.v_target_mps)
                + switching_term(&z_mps2, &epsilon_mps, switching, &s)
        }
        RelativeLaw::Pd { p, d } => p * (st.r_target_m - st.r_rel_m) + d * (st.v_target_mps - st.v_rel_mps),
        RelativeLaw::Off => V3::zeros(),
    }
}

/// The leader's command û_L of (70), m/s², given the follower's last command û_F. Only the SMC law
/// has a leader form in the paper; the others give zero (the leader drifts).
pub fn leader_accel(law: &RelativeLaw, st: &RelativeState, u_follower_mps2: &V3) -> V3 {
    match *law {
        RelativeLaw::Smc { k, z_mps2, epsilon_mps, switching } => {
            let mirrored = RelativeState {
                r_rel_m: -st.r_rel_m,
                v_rel_mps: -st.v_rel_mps,
                r_target_m: -st.r_target_m,
                v_target_mps: -st.v_target_mps,
                ..*st
            };
            let r_f = st.r_leader_m + st.r_rel_m;
            let grav = point_mass_accel(st.mu_m3ps2, &r_f) - point_mass_accel(st.mu_m3ps2, &st.r_leader_m);
            let s = sliding_vector(k, &mirrored);
            grav - u_follower_mps2 - k * (mirrored.v_rel_mps - mirrored.v_target_mps)
                + switching_term(&z_mps2, &epsilon_mps, switching, &s)
        }
        RelativeLaw::Pd { .. } | RelativeLaw::Off => V3::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::orbit::MU_EARTH_M3PS2;

    fn state() -> RelativeState {
        RelativeState {
            r_rel_m: V3::new(1e3, 2e3, 10e3),
            v_rel_mps: V3::new(1.0, 1.0, 1.0),
            r_leader_m: V3::new(-7.7e7, 6.3e6, 4.6e5),
            r_target_m: V3::new(0.0, 0.0, 1e3),
            v_target_mps: V3::zeros(),
            mu_m3ps2: MU_EARTH_M3PS2,
        }
    }

    #[test]
    fn smc_sign_cancels_the_model_and_leaves_minus_z_sign_s() {
        // With the law applied to the true relative dynamics (22) (point mass), ṡ = −Z sign(s).
        let st = state();
        let law = RelativeLaw::Smc { k: 1.0, z_mps2: [1.0; 3], epsilon_mps: [0.05; 3], switching: Switching::Sign };
        let u_l = V3::new(1e-4, 0.0, -2e-4);
        let u_f = follower_accel(&law, &st, &u_l);
        let g = |r: &V3| point_mass_accel(MU_EARTH_M3PS2, r);
        let a_rel = g(&(st.r_leader_m + st.r_rel_m)) - g(&st.r_leader_m) + u_f - u_l;
        let s_dot = a_rel + 1.0 * st.v_rel_mps;
        assert!((s_dot + V3::new(1.0, 1.0, 1.0)).norm() < 1e-12, "ṡ = {s_dot}");
    }

    #[test]
    fn leader_law_mirrors_the_follower_law() {
        // If the leader alone controls (û_F = 0), (70) gives ṡ_LF = −Z sign(s_LF) for r_LF = −r_rel.
        let st = state();
        let law = RelativeLaw::Smc { k: 1.0, z_mps2: [0.5; 3], epsilon_mps: [0.05; 3], switching: Switching::Sat };
        let u_l = leader_accel(&law, &st, &V3::zeros());
        let g = |r: &V3| point_mass_accel(MU_EARTH_M3PS2, r);
        let a_lf = g(&st.r_leader_m) - g(&(st.r_leader_m + st.r_rel_m)) + u_l;
        let s_lf = -st.v_rel_mps + 1.0 * (-st.r_rel_m + st.r_target_m);
        let s_dot = a_lf + 1.0 * (-st.v_rel_mps);
        let want = -0.5 * s_lf.map(|x| (x / 0.05).clamp(-1.0, 1.0));
        assert!((s_dot - want).norm() < 1e-12, "{s_dot} vs {want}");
    }

    #[test]
    fn pd_is_eq_56() {
        let st = state();
        let u = follower_accel(&RelativeLaw::Pd { p: 1.0, d: 1.0 }, &st, &V3::zeros());
        assert_eq!(u, V3::new(-1e3 - 1.0, -2e3 - 1.0, -9e3 - 1.0));
    }
}
