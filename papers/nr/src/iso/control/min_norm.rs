//! The pointwise min-norm control (27)–(36) and Lemma 2 of "Neural-Rendezvous"
//! (arXiv:2208.04883), in the closed form of our reconstruction (the printed forms are lost):
//!
//!   u* = argmin ‖u − u_ℓ‖²  s.t.  sᵀ(u − ς) + α m ‖s‖² ≤ 0,
//!   u* = u_ℓ                          if ϕ₀ + sᵀu_ℓ ≤ 0,
//!   u* = u_ℓ − (ϕ₀ + sᵀu_ℓ) s/‖s‖²     otherwise,    ϕ₀ = α m ‖s‖² − sᵀς,
//!
//! (s = 0 ⇒ u* = u_ℓ), the constraint being the stability condition (35) for V = m‖s‖² (the
//! skew-symmetric C cancels and ṁ ≤ 0 only helps). The point ς − α m s (37) is always feasible.
//!
//! Generic in the dimension and in what s, ς mean, so the swarm layer (m = 1, C = G = 0) uses
//! the same function; `alpha_m` is the product α·m.

/// How the solution was reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MinNormInfo {
    /// The constraint was active (u* ≠ u_ℓ).
    pub active: bool,
    /// Its KKT multiplier μ ≥ 0 (u* = u_ℓ − μ s), zero when inactive.
    pub multiplier: f64,
}

/// sᵀ(u − ς) + α m ‖s‖²: the constraint's value at `u` (≤ 0 is feasible).
pub fn constraint(u: &[f64], s: &[f64], sigma: &[f64], alpha_m: f64) -> f64 {
    let ss: f64 = s.iter().map(|x| x * x).sum();
    s.iter().zip(u.iter().zip(sigma)).map(|(si, (ui, gi))| si * (ui - gi)).sum::<f64>() + alpha_m * ss
}

/// Write u* into `out` (same length as `u_nominal`).
pub fn min_norm(u_nominal: &[f64], s: &[f64], sigma: &[f64], alpha_m: f64, out: &mut [f64]) -> MinNormInfo {
    assert!(u_nominal.len() == s.len() && s.len() == sigma.len() && out.len() == s.len(), "dimensions agree");
    out.copy_from_slice(u_nominal);
    let ss: f64 = s.iter().map(|x| x * x).sum();
    let excess = constraint(u_nominal, s, sigma, alpha_m);
    if ss == 0.0 || excess <= 0.0 {
        return MinNormInfo { active: false, multiplier: 0.0 };
    }
    let mu = excess / ss;
    out.iter_mut().zip(s).for_each(|(o, si)| *o -= mu * si);
    MinNormInfo { active: true, multiplier: mu }
}

/// The feasible point ς − α m s of (37).
#[cfg(test)] // used by the unit tests only
pub fn feasible_point(s: &[f64], sigma: &[f64], alpha_m: f64) -> Vec<f64> {
    sigma.iter().zip(s).map(|(g, si)| g - alpha_m * si).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| rng.random_range(-scale..scale)).collect()
    }

    #[test]
    fn solution_satisfies_kkt_and_the_constraint_and_is_u_l_when_inactive() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut active, mut inactive) = (0, 0);
        for _ in 0..10_000 {
            let n = rng.random_range(1..7);
            let (u_l, s, sigma) = (random(&mut rng, n, 2.0), random(&mut rng, n, 1.0), random(&mut rng, n, 2.0));
            let am = rng.random_range(0.0..3.0);
            let mut u = vec![0.0; n];
            let info = min_norm(&u_l, &s, &sigma, am, &mut u);
            let g = constraint(&u, &s, &sigma, am);
            // Primal feasibility.
            assert!(g <= 1e-9, "constraint {g}");
            // Stationarity: u − u_ℓ + μ s = 0, dual feasibility μ ≥ 0, complementary slackness μ g = 0.
            let station: f64 =
                u.iter().zip(&u_l).zip(&s).map(|((a, b), c)| (a - b + info.multiplier * c).powi(2)).sum();
            assert!(station.sqrt() < 1e-12, "stationarity {station}");
            assert!(info.multiplier >= 0.0);
            assert!((info.multiplier * g).abs() < 1e-9, "complementary slackness {}", info.multiplier * g);
            if constraint(&u_l, &s, &sigma, am) <= 0.0 {
                assert_eq!(u, u_l, "inactive ⇒ u* = u_ℓ exactly");
                inactive += 1;
            } else {
                assert!(info.active && g.abs() < 1e-9, "active ⇒ on the boundary ({g})");
                active += 1;
            }
        }
        assert!(active > 1000 && inactive > 1000, "{active} active, {inactive} inactive cases");
    }

    #[test]
    fn the_solution_is_the_nearest_feasible_point() {
        // Against random feasible points: none is closer to u_ℓ.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for _ in 0..200 {
            let (u_l, s, sigma) = (random(&mut rng, 3, 2.0), random(&mut rng, 3, 1.0), random(&mut rng, 3, 2.0));
            let mut u = vec![0.0; 3];
            min_norm(&u_l, &s, &sigma, 0.5, &mut u);
            let d = |v: &[f64]| v.iter().zip(&u_l).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
            for _ in 0..200 {
                let v = random(&mut rng, 3, 5.0);
                if constraint(&v, &s, &sigma, 0.5) <= 0.0 {
                    assert!(d(&u) <= d(&v) + 1e-12);
                }
            }
        }
    }

    #[test]
    fn equation_37_is_always_feasible_and_s_zero_gives_u_l() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..1000 {
            let (s, sigma) = (random(&mut rng, 3, 1.0), random(&mut rng, 3, 2.0));
            let am = rng.random_range(0.0..3.0);
            let p = feasible_point(&s, &sigma, am);
            assert!(constraint(&p, &s, &sigma, am).abs() < 1e-12, "(37) gives exactly zero");
        }
        let mut u = vec![0.0; 3];
        let info = min_norm(&[1.0, 2.0, 3.0], &[0.0; 3], &[5.0, 5.0, 5.0], 1.0, &mut u);
        assert_eq!((u, info.active), (vec![1.0, 2.0, 3.0], false));
    }
}
