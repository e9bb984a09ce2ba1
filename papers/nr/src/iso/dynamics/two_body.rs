//! Heliocentric two-body motion of the ISO and the spacecraft (the truth of the plant, and the
//! ISO flow of Definition 1 of "Neural-Rendezvous", arXiv:2208.04883). This is the only module
//! that uses the generic astrodynamics of `cohort_astro::orbit` (force-model trait, RK4 step,
//! LVLH frame), so its path changes in one place when that moves to a generic crate.
//!
//! Departure: the paper takes the ISO and planetary states from NAIF/SPICE ephemerides; ours is
//! two-body about the Sun only (no planets), as in reference [23] of the paper.

use cohort_astro::orbit::{BodyProps, DensityHold, ForceModel, rk4_step};
pub use cohort_astro::orbit::{Lvlh, V3};

use crate::iso::dynamics::constants::MU_SUN_M3PS2;

/// Point-mass gravity of the Sun.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunGravity;

impl ForceModel for SunGravity {
    fn accel(&self, r: &V3, _v: &V3, _body: &BodyProps, _density_kgpm3: f64) -> V3 {
        let r2 = r.norm_squared();
        -MU_SUN_M3PS2 / (r2 * r2.sqrt()) * r
    }
    fn density(&self, _r: &V3) -> f64 {
        0.0
    }
}

/// A body's heliocentric inertial state (ecliptic axes), m and m/s.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Inertial {
    pub r_m: V3,
    pub v_mps: V3,
}

/// Body properties are irrelevant without drag; only the mass is read (not even that, here).
const NO_DRAG: BodyProps = BodyProps { mass_kg: 1.0, area_m2: 0.0, drag_coeff: 0.0 };

impl Inertial {
    pub fn new(r_m: V3, v_mps: V3) -> Self {
        Self { r_m, v_mps }
    }

    /// Specific orbital energy v²/2 − μ/r, J/kg.
    pub fn energy_jpkg(&self) -> f64 {
        0.5 * self.v_mps.norm_squared() - MU_SUN_M3PS2 / self.r_m.norm()
    }

    /// The LVLH frame of this body (x radial, z orbit normal, y = z × x).
    pub fn lvlh(&self) -> Lvlh {
        Lvlh::of(&self.r_m, &self.v_mps)
    }

    /// One RK4 step of `dt_s` (negative: backwards) under the Sun's gravity plus the acceleration
    /// `thrust(t_offset_s)`, m/s².
    pub fn step(&mut self, dt_s: f64, thrust: &dyn Fn(f64) -> V3) {
        rk4_step(&SunGravity, &NO_DRAG, DensityHold::Step, &mut self.r_m, &mut self.v_mps, dt_s, thrust);
    }

    /// Coast for `duration_s` (either sign) in `n` equal RK4 steps.
    pub fn coast(&self, duration_s: f64, n: usize) -> Self {
        let mut s = *self;
        let h = duration_s / n.max(1) as f64;
        for _ in 0..n.max(1) {
            s.step(h, &|_| V3::zeros());
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::AU_M;

    #[test]
    fn a_circular_orbit_stays_circular_and_keeps_its_energy_over_a_day() {
        let r = AU_M;
        let vc = (MU_SUN_M3PS2 / r).sqrt();
        let s0 = Inertial::new(V3::new(r, 0.0, 0.0), V3::new(0.0, vc, 0.0));
        let s1 = s0.coast(86_400.0, 144);
        assert!((s1.r_m.norm() / r - 1.0).abs() < 1e-12, "{}", s1.r_m.norm() / r - 1.0);
        let de = (s1.energy_jpkg() / s0.energy_jpkg() - 1.0).abs();
        assert!(de < 1e-12, "{de:e}");
        // The angle swept is n·t.
        let angle = s1.r_m.y.atan2(s1.r_m.x);
        let want = vc / r * 86_400.0;
        assert!((angle - want).abs() < 1e-12, "{angle} vs {want}");
    }

    #[test]
    fn coasting_back_undoes_coasting_forward() {
        let s0 = Inertial::new(V3::new(1.1 * AU_M, 0.2 * AU_M, -0.05 * AU_M), V3::new(-5e3, 38e3, 9e3));
        let back = s0.coast(86_400.0, 144).coast(-86_400.0, 144);
        assert!((back.r_m - s0.r_m).norm() < 1e-3, "{}", (back.r_m - s0.r_m).norm());
        assert!((back.v_mps - s0.v_mps).norm() < 1e-9);
    }
}
