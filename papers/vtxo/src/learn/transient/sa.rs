//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! The transient optimisation of Sec. 3.1 for one data point: min over (k₁, k₂, T) of
//! χ = E + w·e (71), (73)–(76), subject to the dynamics (77) (our [`crate::learn::transient::sim`]), the
//! gain bounds (79) as corrected to (0.01, 0.5) and 7.2 s ≤ T ≤ 72 s (80), by simulated annealing.
//!
//! The annealer moves (k₁, k₂); every candidate is flown once for 72 s and its best T is taken by
//! enumeration on the step grid ([`crate::learn::transient::sim::Flight::best_duration`]), which is exact
//! and cheaper than annealing T. The print gives no schedule: ours is a Metropolis walk whose
//! temperature falls geometrically from 10 % to 0.01 % of the starting χ, with Gaussian moves of
//! standard deviation shrinking from a fifth of the gain range with the square root of the
//! temperature, reflected into the bounds; the walk starts at the mode of Table 2
//! (k₁, k₂) = (0.085, 0.25). Every random number comes from the point's own ChaCha8 stream, so a
//! point's result depends on (seed, index) only, never on threads.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::learn::transient::sim::{self, K_MAX, K_MIN, Outcome, Start, T_MAX_S};

/// The optimum found for one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Optimum {
    pub k1: f64,
    pub k2: f64,
    pub outcome: Outcome,
}

/// χ and the best T of gains (k₁, k₂) from `start` with weight `w`.
pub fn evaluate(start: &Start, w: f64, k1: f64, k2: f64, dt_s: f64) -> Optimum {
    let f = sim::fly(start, k1, k2, T_MAX_S, dt_s);
    Optimum { k1, k2, outcome: f.best_duration(w) }
}

/// Reflect x into [lo, hi].
fn reflect(mut x: f64, lo: f64, hi: f64) -> f64 {
    for _ in 0..4 {
        if x < lo {
            x = 2.0 * lo - x;
        } else if x > hi {
            x = 2.0 * hi - x;
        } else {
            return x;
        }
    }
    x.clamp(lo, hi)
}

/// Anneal `iterations` candidates (the start included) for one point.
pub fn anneal(start: &Start, w: f64, iterations: u32, dt_s: f64, rng: &mut ChaCha8Rng) -> Optimum {
    let mut cur = evaluate(start, w, 0.085, 0.25, dt_s);
    let mut best = cur;
    let chi0 = cur.outcome.chi.max(1e-12);
    let (t0, t1): (f64, f64) = (0.1, 1e-4);
    let n = iterations.max(1);
    let span = K_MAX - K_MIN;
    for i in 1..n {
        let frac = i as f64 / (n - 1).max(1) as f64;
        let temp = t0 * (t1 / t0).powf(frac);
        let sigma = 0.2 * span * (temp / t0).sqrt();
        let z1: f64 = StandardNormal.sample(rng);
        let z2: f64 = StandardNormal.sample(rng);
        let k1 = reflect(cur.k1 + sigma * z1, K_MIN, K_MAX);
        let k2 = reflect(cur.k2 + sigma * z2, K_MIN, K_MAX);
        let cand = evaluate(start, w, k1, k2, dt_s);
        let delta = (cand.outcome.chi - cur.outcome.chi) / chi0;
        let u: f64 = rng.random();
        if delta <= 0.0 || u < (-delta / temp).exp() {
            cur = cand;
        }
        if cur.outcome.chi < best.outcome.chi {
            best = cur;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;
    use crate::model::quaternion::{Quat, V3};

    #[test]
    fn annealing_improves_on_the_start_and_is_reproducible() {
        let s = Start { q: Quat::new(0.3, -0.6, 0.2, 0.7).normalize(), omega_rad_s: V3::new(0.4, 0.7, -0.3) };
        let w = 4.0;
        let run = || anneal(&s, w, 40, 0.1, &mut ChaCha8Rng::seed_from_u64(9));
        let (a, b) = (run(), run());
        assert_eq!(a, b);
        let first = evaluate(&s, w, 0.085, 0.25, 0.1);
        assert!(a.outcome.chi <= first.outcome.chi, "{a:?} vs start {first:?}");
        assert!((K_MIN..=K_MAX).contains(&a.k1) && (K_MIN..=K_MAX).contains(&a.k2));
    }

    #[test]
    fn reflection_stays_in_bounds() {
        for x in [-3.0, -0.2, 0.0, 0.3, 0.51, 1.7, 9.0] {
            let r = reflect(x, K_MIN, K_MAX);
            assert!((K_MIN..=K_MAX).contains(&r), "{x} → {r}");
        }
        assert!((reflect(0.52, K_MIN, K_MAX) - 0.48).abs() < 1e-12);
    }
}
