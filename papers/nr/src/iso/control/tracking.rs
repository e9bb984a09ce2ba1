//! The tracking quantities of the min-norm control (25)–(31) of "Neural-Rendezvous"
//! (arXiv:2208.04883), for the relative dynamics (2) and a desired trajectory x_d:
//!
//!   ṗ_r = ṗ_d − Λ(p̂ − p_d),  p̈_r = p̈_d − Λ(ṗ̂ − ṗ_d),  s = ṗ̂ − ṗ_r,
//!   ς = m p̈_r + C(œ̂) ṗ_r + G(p̂, œ̂),  V = m‖s‖²,
//!
//! so that m ṡ = u − ς − C s along (2) (Slotine and Li's composite variable, the paper's [10]).
//! Λ = λI (ours: λ = 1/3600 s). G is taken at the estimated position, as in Slotine–Li.

use crate::iso::dynamics::lvlh::{OrbitRates, X6, pos, vel};
use crate::iso::dynamics::relative::{c_over_m, g_over_m};
use crate::iso::dynamics::two_body::V3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracking {
    pub s: V3,
    /// ς, N.
    pub sigma_n: V3,
    /// V = m‖s‖².
    pub v: f64,
}

/// Tracking terms at the estimate `x_hat` (mass `m_kg`, ISO rates `rates`) for the desired state
/// `x_d` with acceleration `pddot_d`.
pub fn tracking(x_hat: &X6, x_d: &X6, pddot_d: &V3, lambda: f64, m_kg: f64, rates: &OrbitRates) -> Tracking {
    let (ep, ev) = (pos(x_hat) - pos(x_d), vel(x_hat) - vel(x_d));
    let q_r = vel(x_d) - lambda * ep;
    let pddot_r = pddot_d - lambda * ev;
    let s = ev + lambda * ep;
    let sigma_n = m_kg * (pddot_r + c_over_m(rates) * q_r + g_over_m(&pos(x_hat), rates));
    Tracking { s, sigma_n, v: m_kg * s.norm_squared() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::control::min_norm::{feasible_point, min_norm};
    use crate::iso::dynamics::constants::AU_M;
    use crate::iso::dynamics::lvlh::IsoFrame;
    use crate::iso::dynamics::relative::{accel, step};
    use crate::iso::dynamics::two_body::Inertial;

    #[test]
    fn applying_the_feasible_point_makes_v_decay_at_rate_2_alpha() {
        // Along (2) with u = ς − αm s, V̇ = −2αV (C is skew): check over a short step.
        let iso = Inertial::new(V3::new(1.1 * AU_M, 0.2 * AU_M, 0.0), V3::new(-4e3, 40e3, 8e3));
        let rates = IsoFrame::of(&iso).rates;
        let x_d = X6::new(1e8, -2e8, 5e7, -2e4, 3e4, 1e3);
        let u_d = V3::new(0.1, -0.2, 0.05);
        let m = 500.0;
        let x = x_d + X6::new(300.0, -200.0, 100.0, 0.05, 0.02, -0.03);
        let (lambda, alpha) = (1.0 / 3600.0, 1.0 / 3600.0);
        let pddot_d = accel(&x_d, &rates, &(u_d / m));
        let tr = tracking(&x, &x_d, &pddot_d, lambda, m, &rates);
        let u = feasible_point(tr.s.as_slice(), tr.sigma_n.as_slice(), alpha * m);
        let u = V3::from_column_slice(&u);
        // Short enough that the O(h²) growth of s from the part of u − ς normal to s is negligible.
        let h = 0.02;
        let x1 = step(&x, &iso, m, &u, 1e12, h).x;
        let xd1 = step(&x_d, &iso, m, &u_d, 1e12, h).x;
        let pddot_d1 = accel(&xd1, &IsoFrame::of(&iso.coast(h, 1)).rates, &(u_d / m));
        let v1 = tracking(&x1, &xd1, &pddot_d1, lambda, m, &rates).v;
        let rate = (v1 / tr.v).ln() / h;
        assert!((rate + 2.0 * alpha).abs() < 1e-3 * 2.0 * alpha, "V̇/V = {rate:e}, want {:e}", -2.0 * alpha);
        // And the min-norm control from any nominal input satisfies the same decrease or better.
        let mut us = [0.0; 3];
        min_norm(&[0.3, -0.1, 0.2], tr.s.as_slice(), tr.sigma_n.as_slice(), alpha * m, &mut us);
        let x1 = step(&x, &iso, m, &V3::from_column_slice(&us), 1e12, h).x;
        let v1 = tracking(&x1, &xd1, &pddot_d1, lambda, m, &rates).v;
        let r2 = (v1 / tr.v).ln() / h;
        assert!(r2 <= -2.0 * alpha * (1.0 - 1e-3), "V̇/V = {r2:e}");
    }
}
