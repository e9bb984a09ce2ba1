//! The swarm reconfiguration problem of Sec. 7.2 of "Neural-Rendezvous" (arXiv:2208.04883), as
//! the global solution ([`crate::swarm::train::scp`]), the training data ([`crate::swarm::train::data`]) and the
//! in-process evaluation ([`crate::swarm::train::eval`]) see it: the model facts and a seeded draw of
//! starts and targets.
//!
//! **Model** (the paper's radius, cuboid, separations, axes and rates are lost; these are ours,
//! shared with the swarm plant):
//! - each vehicle is a double integrator in 3-D, ṗ = v, v̇ = a, with the acceleration held over
//!   each control step (exact discretisation: p⁺ = p + vΔt + ½aΔt², v⁺ = v + aΔt) and bounded
//!   per axis, |aᵢ| ≤ [`A_MAX_MPS2`] = 2 m/s²;
//! - horizon T = [`T_S`] = 8 s at Δt = [`DT_S`] = 0.1 s ([`STEPS`] = 80 steps), from rest at the
//!   start to rest at the target;
//! - starts and targets in the cuboid [−2, 2] × [−2, 2] × [0.5, 2] m ([`CUBOID_M`]);
//! - collision between vehicles i and j iff ‖E⁻¹(pᵢ − pⱼ)‖ < 1 with E = diag(0.12, 0.12, 0.30) m
//!   ([`ELLIPSOID_M`], the Crazyswarm tall ellipsoid for the downwash); ‖E⁻¹Δp‖ is the
//!   "ellipsoid distance" ([`ellipsoid_distance`]);
//! - communication radius R_comm = [`R_COMM_M`] = 1 m (what a vehicle observes:
//!   [`crate::swarm::control::obs::SwarmObservation::local`]).
//!
//! **Draw** ([`SwarmCase::draw`]): the plant's own sampler, [`crate::swarm::dynamics::setup::draw`] (the
//! paper's two conditions with our values: each start at least [`MIN_TRAVEL_M`] = 1 m from its
//! target, all 2N points pairwise at least [`MIN_SEPARATION`] = 1.25 apart in the ellipsoid
//! distance), for a problem seed drawn from `(seed, label)` ([`problem_seed`]): one sampler serves
//! the scenarios, the campaign and the training data.

use rand::Rng;

/// The model's facts, one definition for the plant and the global solution
/// ([`crate::swarm::dynamics::setup`]); the names the SCP, data and evaluation code use.
pub use crate::swarm::dynamics::setup::{
    A_MAX_MPS2, DT_S, ELLIPSOID_RADII_M as ELLIPSOID_M, R_COMM_M, T_RECONFIG_S as T_S,
};
#[cfg(test)] // used by the unit tests only
pub use crate::swarm::dynamics::setup::{MIN_SAMPLE_SEPARATION as MIN_SEPARATION, MIN_TRAVEL_M};
/// Control steps over the horizon.
pub const STEPS: usize = 80;

/// The time to go to T at node `k`, s (0 from T on).
pub fn t_to_go_s(k: usize) -> f64 {
    STEPS.saturating_sub(k) as f64 * DT_S
}
#[cfg(test)] // used by the unit tests only
pub use crate::swarm::dynamics::setup::CUBOID_M;

/// ‖E⁻¹(a − b)‖: below 1 is a collision.
pub fn ellipsoid_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| ((a[k] - b[k]) / ELLIPSOID_M[k]).powi(2)).sum::<f64>().sqrt()
}

/// One reconfiguration: vehicle i flies from `starts_m[i]` to `goals_m[i]`, at rest at both.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmCase {
    pub starts_m: Vec<[f64; 3]>,
    pub goals_m: Vec<[f64; 3]>,
}

/// A draw that cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("swarm draw of {n} vehicles: {reason}")]
pub struct DrawError {
    pub n: usize,
    pub reason: String,
}

impl SwarmCase {
    /// Vehicles.
    pub fn n(&self) -> usize {
        self.starts_m.len()
    }

    /// Case `label` of `seed` with `n` vehicles: the plant's problem of [`problem_seed`]`(seed,
    /// label)`; the same arguments give the same case.
    pub fn draw(seed: u64, label: &str, n: usize) -> Result<Self, DrawError> {
        let (starts_m, goals_m) = crate::swarm::dynamics::setup::draw(n, problem_seed(seed, label))
            .map_err(|e| DrawError { n, reason: e.to_string() })?;
        Ok(Self { starts_m, goals_m })
    }
}

/// The plant's problem seed of case `label` of `seed` (a stream per label).
pub fn problem_seed(seed: u64, label: &str) -> u64 {
    cohort_runtime::rng::setup_rng(seed, &format!("nr.swarm.case[{label}]")).random()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_draw_meets_both_conditions_and_repeats_per_seed() {
        for n in [1, 8, 20] {
            let c = SwarmCase::draw(3, "t", n).unwrap();
            assert_eq!(c, SwarmCase::draw(3, "t", n).unwrap());
            assert_ne!(c, SwarmCase::draw(4, "t", n).unwrap());
            let all: Vec<[f64; 3]> = c.starts_m.iter().chain(&c.goals_m).copied().collect();
            for (a, p) in all.iter().enumerate() {
                assert!((0..3).all(|k| p[k] >= CUBOID_M[k][0] && p[k] <= CUBOID_M[k][1]), "{p:?}");
                for q in &all[a + 1..] {
                    assert!(ellipsoid_distance(*p, *q) >= MIN_SEPARATION);
                }
            }
            for (s, g) in c.starts_m.iter().zip(&c.goals_m) {
                assert!((0..3).map(|k| (s[k] - g[k]).powi(2)).sum::<f64>() >= MIN_TRAVEL_M * MIN_TRAVEL_M);
            }
        }
        assert!(SwarmCase::draw(1, "t", 0).is_err());
    }

    #[test]
    fn the_ellipsoid_distance_is_one_on_the_semi_axes() {
        let o = [0.0, 0.0, 1.0];
        for (k, e) in ELLIPSOID_M.iter().enumerate() {
            let mut p = o;
            p[k] += e;
            assert!((ellipsoid_distance(o, p) - 1.0).abs() < 1e-12);
        }
    }
}
