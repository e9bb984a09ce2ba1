//! The synthetic ISO set (Sec. 6.1 and 6.2.2 of "Neural-Rendezvous", arXiv:2208.04883). The
//! paper draws its candidates from the ISO population of its reference [18], which is not
//! available; ours is synthetic and seeded: every index is a deterministic draw from
//! (set seed, index), so training and every run see the same ISOs (0–199 train, 200–299 test).
//!
//! For ISO `i` (reference values; all ours):
//! - encounter point at t_f: distance from the Sun U(0.8, 1.5) AU, direction isotropic;
//! - ISO velocity there: hyperbolic excess speed v∞ ~ U(10, 40) km/s, so speed √(v∞² + 2μ/r),
//!   direction isotropic;
//! - spacecraft `j` at t_f: at the ISO plus ρ_f (LVLH of the ISO then), ρ_f uniform on the
//!   sphere of radius R (ours 100 km; the paper samples ρ_f on a ball's surface for training);
//!   velocity: local circular speed in the prograde ecliptic direction (ẑ × r̂) plus 5 km/s in an
//!   isotropic direction;
//! - both propagated back by t_f (coasting): the ideal trajectories, which meet exactly;
//! - the true initial states: the ideal ones plus N(0, Σ(0)) each, Σ the navigation covariance
//!   at t = 0 ([`crate::iso::dynamics::navigation`]), drawn from their own streams.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::iso::dynamics::constants::{AU_M, MU_SUN_M3PS2};
use crate::iso::dynamics::lvlh::IsoFrame;
use crate::iso::dynamics::navigation::{self, Sigma};
use crate::iso::dynamics::two_body::{Inertial, V3};

/// Coasting step for the ideal trajectories (independent of the control interval, so the ISOs
/// do not change with Δt), s.
const COAST_STEP_S: f64 = 600.0;

fn stream(set_seed: u64, name: &str) -> ChaCha8Rng {
    cohort_runtime::rng::setup_rng(set_seed, name)
}

fn unit(rng: &mut impl Rng) -> V3 {
    loop {
        let v = V3::new(rng.sample(StandardNormal), rng.sample(StandardNormal), rng.sample(StandardNormal));
        let n = v.norm();
        if n > 1e-9 {
            return v / n;
        }
    }
}

/// The ideal encounter of one ISO and one spacecraft.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ideal {
    pub t_f_s: f64,
    /// ISO at t_f.
    pub iso_tf: Inertial,
    /// Spacecraft at t_f (at the ISO plus ρ_f).
    pub sc_tf: Inertial,
    /// Desired terminal position relative to the ISO (its LVLH frame), m.
    pub rho_f_m: V3,
}

impl Ideal {
    /// ISO and spacecraft on the ideal (coasting) trajectories at time t ∈ [0, t_f].
    pub fn at(&self, t_s: f64) -> (Inertial, Inertial) {
        let back = self.t_f_s - t_s;
        let n = (back.abs() / COAST_STEP_S).ceil() as usize;
        if n == 0 {
            return (self.iso_tf, self.sc_tf);
        }
        (self.iso_tf.coast(-back, n), self.sc_tf.coast(-back, n))
    }
}

/// The ISO of index `i` at the encounter.
pub fn iso_at_encounter(set_seed: u64, i: u32) -> Inertial {
    let mut rng = stream(set_seed, &format!("nr.iso[{i}]"));
    let r = rng.random_range(0.8..1.5) * AU_M;
    let r_m = r * unit(&mut rng);
    let v_inf = rng.random_range(10e3..40e3);
    let speed = (v_inf * v_inf + 2.0 * MU_SUN_M3PS2 / r).sqrt();
    Inertial::new(r_m, speed * unit(&mut rng))
}

/// Spacecraft `j`'s desired terminal position and arrival velocity for ISO `i`.
pub fn spacecraft_arrival(set_seed: u64, i: u32, j: u32, iso_tf: &Inertial, rho_radius_m: f64) -> (V3, Inertial) {
    let mut rng = stream(set_seed, &format!("nr.iso[{i}].sc[{j}]"));
    let rho_f_m = rho_radius_m * unit(&mut rng);
    let extra = 5e3 * unit(&mut rng);
    (rho_f_m, arrival(iso_tf, &rho_f_m, extra))
}

/// A spacecraft at the ISO plus ρ_f (LVLH) at t_f, with the circular prograde velocity there
/// plus `extra_mps`.
pub fn arrival(iso_tf: &Inertial, rho_f_m: &V3, extra_mps: V3) -> Inertial {
    let r_m = iso_tf.r_m + IsoFrame::of(iso_tf).to_inertial(rho_f_m);
    let prograde = V3::z().cross(&r_m).normalize();
    let vc = (MU_SUN_M3PS2 / r_m.norm()).sqrt();
    Inertial::new(r_m, vc * prograde + extra_mps)
}

/// The ideal encounter of ISO `i` and spacecraft `j`.
pub fn ideal(set_seed: u64, i: u32, j: u32, t_f_s: f64, rho_radius_m: f64) -> Ideal {
    let iso_tf = iso_at_encounter(set_seed, i);
    let (rho_f_m, sc_tf) = spacecraft_arrival(set_seed, i, j, &iso_tf, rho_radius_m);
    Ideal { t_f_s, iso_tf, sc_tf, rho_f_m }
}

/// True initial states: the ideal ones at t = 0 plus N(0, Σ(0)), the ISO's shared by every
/// spacecraft of the encounter.
pub fn dispersed_start(
    set_seed: u64,
    i: u32,
    ideal0: &(Inertial, Inertial),
    j: u32,
    s: &Sigma,
) -> (Inertial, Inertial) {
    let iso = navigation::draw(&ideal0.0, s, &mut stream(set_seed, &format!("nr.iso[{i}].dispersion")));
    let sc = navigation::draw(&ideal0.1, s, &mut stream(set_seed, &format!("nr.iso[{i}].sc[{j}].dispersion")));
    (iso, sc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};

    #[test]
    fn an_index_is_a_fixed_draw_and_the_ideal_trajectories_meet_at_rho_f() {
        let a = ideal(ISO_SET_SEED, 17, 0, T_F_S, 100e3);
        assert_eq!(a, ideal(ISO_SET_SEED, 17, 0, T_F_S, 100e3));
        assert_ne!(a.iso_tf, ideal(ISO_SET_SEED, 18, 0, T_F_S, 100e3).iso_tf);
        assert_ne!(a.sc_tf, ideal(ISO_SET_SEED, 17, 1, T_F_S, 100e3).sc_tf);
        assert!((a.rho_f_m.norm() - 100e3).abs() < 1e-6);
        let (iso0, sc0) = a.at(0.0);
        let (iso_f, sc_f) = (iso0.coast(T_F_S, 144), sc0.coast(T_F_S, 144));
        let p = IsoFrame::of(&iso_f).relative(&sc_f);
        let miss = (V3::new(p[0], p[1], p[2]) - a.rho_f_m).norm();
        assert!(miss < 1e-3, "coasting the ideal start forward misses ρ_f by {miss} m");
    }

    #[test]
    fn the_set_spans_the_stated_ranges() {
        for i in 0..300 {
            let iso = iso_at_encounter(ISO_SET_SEED, i);
            let r = iso.r_m.norm() / AU_M;
            assert!((0.8..1.5).contains(&r), "ISO {i}: r = {r} AU");
            let v_inf = (2.0 * iso.energy_jpkg()).sqrt();
            assert!((10e3..40e3 + 1e-6).contains(&v_inf), "ISO {i}: v∞ = {v_inf}");
            let (_, sc) = spacecraft_arrival(ISO_SET_SEED, i, 0, &iso, 100e3);
            assert!(sc.energy_jpkg() < 0.0, "ISO {i}: the spacecraft is bound to the Sun");
        }
    }
}
