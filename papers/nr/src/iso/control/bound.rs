//! The delivery-error bound (49)–(50), (72)–(73) of "Neural-Rendezvous" (arXiv:2208.04883), in
//! our reconstruction by hierarchical contraction (the printed forms are lost): with the
//! composite variable s = ṗ − ṗ_r of the min-norm control and e = p − p_d,
//!
//!   b_s' = −α b_s + L̄ ε(t)/m_min,     b_e' = −λ_min(Λ) b_e + b_s,
//!
//! from the time the tracking starts (or the desired trajectory is rebuilt), b_s and b_e
//! bounding ‖s‖ and ‖e‖; ε(t) is the estimation error level (Example 1: ε₀ e^{−γ_e t}) and L̄ the
//! Lipschitz constant (46) of the control in the estimate, so L̄ε bounds what the estimation
//! error does to u. b_e(t_f) bounds the delivery error ‖p(t_f) − ρ_f‖ (x_d ends at ρ_f).
//!
//! Integrated exactly over each control interval with the drive L̄ε/m_min held at its value at
//! the interval's start (ε decreases, so holding it is conservative). Generic: the swarm layer
//! uses it with its own α, λ and drive.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Bound {
    /// Bound on ‖s‖, m/s.
    pub b_s: f64,
    /// Bound on ‖p − p_d‖, m.
    pub b_e: f64,
}

impl Bound {
    pub fn new(b_s: f64, b_e: f64) -> Self {
        Self { b_s, b_e }
    }

    /// Advance by `h` seconds with rates `alpha` (of s) and `lambda` (λ_min(Λ), of e) and the
    /// drive `c` = L̄ε/m_min (m/s²) held.
    pub fn advance(&mut self, h: f64, alpha: f64, lambda: f64, c: f64) {
        let s_inf = c / alpha;
        let ds0 = self.b_s - s_inf;
        let el = (-lambda * h).exp();
        // ∫₀ʰ e^{−λ(h−τ)} e^{−ατ} dτ = e^{−λh}·(e^{(λ−α)h} − 1)/(λ − α), also for λ = α.
        let delta = lambda - alpha;
        let phi = el * if delta == 0.0 { h } else { (delta * h).exp_m1() / delta };
        self.b_e = self.b_e * el + s_inf * (-(-lambda * h).exp_m1()) / lambda + ds0 * phi;
        self.b_s = s_inf + ds0 * (-alpha * h).exp();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same system by RK4 with small steps.
    fn rk4(b: Bound, h: f64, a: f64, l: f64, c: f64) -> Bound {
        let f = |s: f64, e: f64| (-a * s + c, -l * e + s);
        let (mut s, mut e) = (b.b_s, b.b_e);
        let n = 10_000;
        let dt = h / n as f64;
        for _ in 0..n {
            let k1 = f(s, e);
            let k2 = f(s + 0.5 * dt * k1.0, e + 0.5 * dt * k1.1);
            let k3 = f(s + 0.5 * dt * k2.0, e + 0.5 * dt * k2.1);
            let k4 = f(s + dt * k3.0, e + dt * k3.1);
            s += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            e += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        }
        Bound::new(s, e)
    }

    #[test]
    fn exact_step_matches_numerical_integration_for_equal_and_different_rates() {
        for (a, l) in [(1.0 / 3600.0, 1.0 / 3600.0), (1.0 / 1800.0, 1.0 / 3600.0), (1.0 / 3600.0, 1.0 / 900.0)] {
            let b0 = Bound::new(0.05, 300.0);
            let c = 2e-6;
            let mut b = b0;
            b.advance(600.0, a, l, c);
            let want = rk4(b0, 600.0, a, l, c);
            assert!((b.b_s - want.b_s).abs() < 1e-12 && (b.b_e - want.b_e).abs() < 1e-8, "{b:?} vs {want:?}");
        }
    }

    #[test]
    fn without_drive_the_bound_decays_and_with_drive_it_settles() {
        let mut b = Bound::new(0.0, 100.0);
        b.advance(3600.0, 1.0 / 3600.0, 1.0 / 3600.0, 0.0);
        assert!((b.b_e - 100.0 / std::f64::consts::E).abs() < 1e-9);
        let mut b = Bound::new(0.0, 0.0);
        for _ in 0..1000 {
            b.advance(600.0, 1e-3, 2e-3, 1e-6);
        }
        // Steady state: b_s = c/α, b_e = b_s/λ.
        assert!((b.b_s - 1e-3).abs() < 1e-12 && (b.b_e - 0.5).abs() < 1e-9, "{b:?}");
    }
}
