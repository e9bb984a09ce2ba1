//! Where the supervisor gets u2 = T and the Lyapunov gains (k1, k2) of the transient phase
//! (Sec. 3.2.1 and Sec. 8 of "Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation": "u2 = T given by the ML"): a [`TransientPredictor`] maps the measured
//! state at the entry to s2 — q₀, ω₀ — and the weight w of χ = E + w·e to (k1, k2, T), the
//! transient DNN's ℝ⁸ → (k1, k2, T) part. Until the DNN exists, [`FixedTransient`] answers a
//! scenario value (default T = 48 s, Table 2's mean; gains the mode of Table 2, 0.085 and 0.25);
//! a DNN plugs in by implementing the trait (a closure does).
//!
//! Each spacecraft predicts from its own state; the follower, the supervisor master, takes
//! u2 = max(T̂_L, T̂_F) (both must have finished the slew), clamped to [t_min, t_max] (the DNN's
//! P99 of T is 129 s against the data's 72 s maximum: 7.2–72 s by default) and rounded up to a
//! whole tick ([`u2_ticks`]).
//!
//! The measured state of a transient entry is drawn as in the paper's Monte Carlo ((85), (87)):
//! quaternion components U(−1, 1), q₄ ≥ 0, normalised; ω₀ ~ N(0, 0.6 rad/s) per axis
//! ([`draw_entry_state`]).

use rand::Rng;
use rand_distr::{Distribution, Normal};

/// The state a spacecraft measures when the transient starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredState {
    /// Scalar last.
    pub q_body_eci: [f64; 4],
    pub omega_body_rad_s: [f64; 3],
}

/// What the transient predictor answers.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TransientGains {
    pub k1: f64,
    pub k2: f64,
    pub t_s: f64,
}

/// (q₀, ω₀, w) → (k1, k2, T): the interface of the transient DNN.
pub trait TransientPredictor: Send + Sync {
    fn predict(&self, x: &MeasuredState, w: f64) -> TransientGains;
}

impl<F: Fn(&MeasuredState, f64) -> TransientGains + Send + Sync> TransientPredictor for F {
    fn predict(&self, x: &MeasuredState, w: f64) -> TransientGains {
        self(x, w)
    }
}

/// The same answer whatever the state (the scenario's value until the DNN exists).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedTransient(pub TransientGains);

impl TransientPredictor for FixedTransient {
    fn predict(&self, _x: &MeasuredState, _w: f64) -> TransientGains {
        self.0
    }
}

/// ω₀'s σ per axis in (87), rad/s.
pub const OMEGA0_SIGMA_RAD_S: f64 = 0.6;

/// A transient entry state per (85), (87).
pub fn draw_entry_state(rng: &mut impl Rng) -> MeasuredState {
    let mut q = [0.0; 4];
    loop {
        for c in &mut q {
            *c = rng.random_range(-1.0..1.0);
        }
        let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        // A draw too close to 0 has no direction: draw again (probability ≈ 0).
        if n > 1e-6 {
            let s = if q[3] < 0.0 { -1.0 / n } else { 1.0 / n };
            q.iter_mut().for_each(|c| *c *= s);
            break;
        }
    }
    let normal = Normal::new(0.0, OMEGA0_SIGMA_RAD_S).expect("σ > 0");
    let omega = [normal.sample(rng), normal.sample(rng), normal.sample(rng)];
    MeasuredState { q_body_eci: q, omega_body_rad_s: omega }
}

/// u2 in ticks of `tick_s`: max of the two predictions, clamped to [t_min_s, t_max_s], rounded
/// up to a whole tick (a non-finite prediction counts as t_max_s: the longest allowed slew).
pub fn u2_ticks(t_leader_s: f64, t_follower_s: f64, t_min_s: f64, t_max_s: f64, tick_s: f64) -> u64 {
    let pick = |t: f64| if t.is_finite() { t } else { t_max_s };
    let t = pick(t_leader_s).max(pick(t_follower_s)).clamp(t_min_s, t_max_s);
    // The division of two whole-tick values can land a hair above the integer.
    let ticks = t / tick_s;
    let r = ticks.round();
    let ticks = if (ticks - r).abs() <= 1e-9 * r.max(1.0) { r } else { ticks.ceil() };
    (ticks as u64).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn u2_is_the_larger_prediction_clamped_and_rounded_up_to_a_tick() {
        assert_eq!(u2_ticks(48.0, 30.0, 7.2, 72.0, 0.01), 4800);
        assert_eq!(u2_ticks(30.0, 48.004, 7.2, 72.0, 0.01), 4801);
        assert_eq!(u2_ticks(129.0, 1.0, 7.2, 72.0, 0.01), 7200);
        assert_eq!(u2_ticks(1.0, 2.0, 7.2, 72.0, 0.01), 720);
        assert_eq!(u2_ticks(f64::NAN, 2.0, 7.2, 72.0, 0.01), 7200);
    }

    #[test]
    fn a_closure_is_a_predictor_and_sees_the_state() {
        let p = |x: &MeasuredState, w: f64| TransientGains {
            k1: 0.1,
            k2: 0.2,
            t_s: 10.0 + w + x.omega_body_rad_s[0].abs(),
        };
        let x = MeasuredState { q_body_eci: [0.0, 0.0, 0.0, 1.0], omega_body_rad_s: [0.5, 0.0, 0.0] };
        assert_eq!(p.predict(&x, 5.0).t_s, 15.5);
    }

    #[test]
    fn entry_states_are_unit_quaternions_with_a_non_negative_scalar_and_spread_rates() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let xs: Vec<MeasuredState> = (0..4000).map(|_| draw_entry_state(&mut rng)).collect();
        for x in &xs {
            let n: f64 = x.q_body_eci.iter().map(|c| c * c).sum();
            assert!((n - 1.0).abs() < 1e-12 && x.q_body_eci[3] >= 0.0);
        }
        let var = xs.iter().map(|x| x.omega_body_rad_s[1].powi(2)).sum::<f64>() / xs.len() as f64;
        assert!((var.sqrt() / OMEGA0_SIGMA_RAD_S - 1.0).abs() < 0.05, "σ {}", var.sqrt());
    }
}
