//! Point-mass orbits of the leader and the follower in ECI, (16)–(17) and (21)–(22): Earth's
//! point mass plus J2 (the generic model of the workspace; drag off), the thrust and the
//! perturbation acceleration held over each step, fixed-step RK4.
//!
//! This module is the only one that uses the workspace's generic astrodynamics
//! (`cohort_astro::orbit`), so its path changes in one place.
//!
//! Departure from a literal reading: the follower is carried as its state relative to the leader,
//! r_rel = r_F − r_L and v_rel, integrated with (22) (r̈_rel = g(r_L + r_rel) − g(r_L) + u_F − u_L),
//! instead of as a second absolute state. The dynamics are the same; the numbers are not: at
//! apogee |r| ≈ 7.8e7 m, where one rounding of an absolute position is ≈ 1.5e-8 m, and over the
//! 930 000 steps of the Sec. 7 run the roundings of two absolute states would random-walk to
//! ≈ 1e-5 m in their difference — more than the 1e-6 m transverse errors the paper reports. The
//! relative state (|r_rel| ≈ 1e3 m) keeps the difference to ≈ 1e-13 m per rounding.

use cohort_astro::orbit::{BodyProps, EarthForces, ForceModel, J2_EARTH};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub use cohort_astro::orbit::{MU_EARTH_M3PS2, R_EARTH_M};

pub type V3 = Vector3<f64>;

/// Earth's gravity: point mass, optionally J2.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Gravity {
    pub mu_m3ps2: f64,
    pub j2: bool,
}

impl Gravity {
    pub fn earth(j2: bool) -> Self {
        Self { mu_m3ps2: MU_EARTH_M3PS2, j2 }
    }

    /// Gravitational acceleration at `r_eci_m`, m/s².
    pub fn accel(&self, r_eci_m: &V3) -> V3 {
        let forces = EarthForces { mu_m3ps2: self.mu_m3ps2, j2: if self.j2 { J2_EARTH } else { 0.0 }, drag: false };
        // Drag is off, so the body properties and the density are never read.
        let body = BodyProps { mass_kg: 1.0, area_m2: 0.0, drag_coeff: 0.0 };
        forces.accel(r_eci_m, &V3::zeros(), &body, 0.0)
    }
}

/// The point-mass model of the agents' navigation, (37): −μ r/|r|³ (no J2).
pub fn point_mass_accel(mu_m3ps2: f64, r_eci_m: &V3) -> V3 {
    let r2 = r_eci_m.norm_squared();
    -mu_m3ps2 / (r2 * r2.sqrt()) * r_eci_m
}

/// The truth of both orbits: the leader's ECI state and the follower's state relative to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrbitPair {
    pub r_leader_eci_m: V3,
    pub v_leader_eci_mps: V3,
    pub r_rel_eci_m: V3,
    pub v_rel_eci_mps: V3,
}

impl OrbitPair {
    pub fn r_follower_eci_m(&self) -> V3 {
        self.r_leader_eci_m + self.r_rel_eci_m
    }
    pub fn v_follower_eci_mps(&self) -> V3 {
        self.v_leader_eci_mps + self.v_rel_eci_mps
    }

    /// One RK4 step with the non-gravitational accelerations of leader and follower (thrust and
    /// perturbation, m/s², ECI) held over it.
    pub fn rk4_step(&mut self, gravity: &Gravity, a_leader_mps2: &V3, a_follower_mps2: &V3, dt_s: f64) {
        let f = |rl: &V3, vl: &V3, rr: &V3, vr: &V3| {
            let gl = gravity.accel(rl);
            let gf = gravity.accel(&(rl + rr));
            (*vl, gl + a_leader_mps2, *vr, gf - gl + a_follower_mps2 - a_leader_mps2)
        };
        let h = dt_s;
        let (rl, vl, rr, vr) = (self.r_leader_eci_m, self.v_leader_eci_mps, self.r_rel_eci_m, self.v_rel_eci_mps);
        let k1 = f(&rl, &vl, &rr, &vr);
        let k2 = f(&(rl + 0.5 * h * k1.0), &(vl + 0.5 * h * k1.1), &(rr + 0.5 * h * k1.2), &(vr + 0.5 * h * k1.3));
        let k3 = f(&(rl + 0.5 * h * k2.0), &(vl + 0.5 * h * k2.1), &(rr + 0.5 * h * k2.2), &(vr + 0.5 * h * k2.3));
        let k4 = f(&(rl + h * k3.0), &(vl + h * k3.1), &(rr + h * k3.2), &(vr + h * k3.3));
        self.r_leader_eci_m = rl + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
        self.v_leader_eci_mps = vl + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        self.r_rel_eci_m = rr + h / 6.0 * (k1.2 + 2.0 * k2.2 + 2.0 * k3.2 + k4.2);
        self.v_rel_eci_mps = vr + h / 6.0 * (k1.3 + 2.0 * k2.3 + 2.0 * k3.3 + k4.3);
    }
}

/// One RK4 step of a single point-mass orbit (the agents' navigation model (36)–(37)) with a
/// held non-gravitational acceleration.
pub fn rk4_point_mass(mu_m3ps2: f64, r: &mut V3, v: &mut V3, a_mps2: &V3, dt_s: f64) {
    let acc = |x: &V3| point_mass_accel(mu_m3ps2, x) + a_mps2;
    let h = dt_s;
    let (r0, v0) = (*r, *v);
    let a1 = acc(&r0);
    let (r2, v2) = (r0 + 0.5 * h * v0, v0 + 0.5 * h * a1);
    let a2 = acc(&r2);
    let (r3, v3) = (r0 + 0.5 * h * v2, v0 + 0.5 * h * a2);
    let a3 = acc(&r3);
    let (r4, v4) = (r0 + h * v3, v0 + h * a3);
    let a4 = acc(&r4);
    *r = r0 + h / 6.0 * (v0 + 2.0 * v2 + 2.0 * v3 + v4);
    *v = v0 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
}

/// The generic module's periapsis state, for cross-checking [`crate::model::orbit_setup`].
pub fn generic_periapsis_state(a_m: f64, e: f64, inc_rad: f64, raan_rad: f64, argp_rad: f64) -> (V3, V3) {
    cohort_astro::orbit::periapsis_state(a_m * (1.0 - e), a_m * (1.0 + e), inc_rad, raan_rad, argp_rad, MU_EARTH_M3PS2)
}
