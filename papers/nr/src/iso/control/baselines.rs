//! The baselines of Sec. 6.3 of "Neural-Rendezvous" (arXiv:2208.04883), in our reading (the
//! printed gains and settings are lost):
//!
//! - **linear MPC** (the paper's [12]): one QP per step, the relative model (2) linearised at
//!   p = 0 with the ISO's state frozen at its current estimate (an LTI model, discretised exactly
//!   by the matrix exponential), the same terminal constraint and thrust box as the SCP;
//! - **PD** on a fixed plan: u = u_d − m(λ²(p̂ − p_d) + 2λ(ṗ̂ − ṗ_d)) (critically damped at the
//!   rate λ, ours λ = 1/3600 s), u_d the plan's feed-forward;
//! - **robust tracking** on that plan (Slotine and Li, the paper's [10] pp. 397–402):
//!   u = ς − K s with K = αm (the same α as the min-norm control).
//!
//! The fixed plan is the global solution (SCP) from the estimates at t = 0, kept to t_f.

use cohort_runtime::solver_stats::SolveLog;
use nalgebra::{Matrix3, Matrix3x6, Matrix6, Matrix6x3, SMatrix};

use crate::iso::control::tracking::Tracking;
use crate::iso::dynamics::lvlh::{OrbitRates, X6, pos, vel};
use crate::iso::dynamics::relative::accel_jacobian;
use crate::iso::dynamics::two_body::V3;
use crate::iso::guidance::qp::solve_terminal_qp;
use crate::iso::guidance::scp::ScpInput;

/// Φ = e^{AΔt} and Γ = ∫₀^Δt e^{Aτ}dτ B of the model linearised at p = 0, œ frozen.
pub fn linear_model(rates: &OrbitRates, m_kg: f64, dt_s: f64) -> (Matrix6<f64>, Matrix6x3<f64>) {
    let (dp, dq) = accel_jacobian(&X6::zeros(), rates);
    let mut aug = SMatrix::<f64, 9, 9>::zeros();
    aug.fixed_view_mut::<3, 3>(0, 3).copy_from(&Matrix3::identity());
    aug.fixed_view_mut::<3, 3>(3, 0).copy_from(&dp);
    aug.fixed_view_mut::<3, 3>(3, 3).copy_from(&dq);
    aug.fixed_view_mut::<3, 3>(3, 6).copy_from(&(Matrix3::identity() / m_kg));
    let e = (aug * dt_s).exp();
    (e.fixed_view::<6, 6>(0, 0).into_owned(), e.fixed_view::<6, 3>(0, 6).into_owned())
}

/// The linear MPC's command at the start of `inp` (LVLH, N) and whether the terminal constraint
/// had to be softened; None if the QP failed.
pub fn linear_mpc(inp: &ScpInput, log: &mut SolveLog) -> Option<(V3, bool)> {
    if inp.steps() == 0 {
        return Some((V3::zeros(), false));
    }
    linear_mpc_plan(inp, log).map(|(u, soft)| (u[0], soft))
}

/// The linear MPC's whole command sequence.
pub fn linear_mpc_plan(inp: &ScpInput, log: &mut SolveLog) -> Option<(Vec<V3>, bool)> {
    let n = inp.steps();
    let (phi, gamma) = linear_model(&OrbitRates::of(&inp.iso0), inp.m0_kg, inp.dt_s);
    let mut lam = Matrix3x6::<f64>::zeros();
    lam.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
    let mut m = vec![Matrix3::zeros(); n];
    for k in (0..n).rev() {
        m[k] = lam * gamma;
        lam *= phi;
    }
    // lam = S Φᴺ now.
    let d = inp.rho_f_m - lam * inp.x0;
    let qp = solve_terminal_qp(&m, &d, inp.u_max_n, log);
    qp.u_n.map(|u| (u, qp.soft))
}

/// PD on a plan: feed-forward `u_d` plus critically damped feedback at rate `lambda`.
pub fn pd(x_hat: &X6, x_d: &X6, u_d: &V3, m_kg: f64, lambda: f64) -> V3 {
    u_d - m_kg * (lambda * lambda * (pos(x_hat) - pos(x_d)) + 2.0 * lambda * (vel(x_hat) - vel(x_d)))
}

/// Robust tracking u = ς − αm s.
pub fn robust_tracking(tr: &Tracking, alpha: f64, m_kg: f64) -> V3 {
    tr.sigma_n - alpha * m_kg * tr.s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::relative::step;
    use crate::iso::guidance::scp::{ScpSettings, rollout, solve};

    fn input() -> ScpInput {
        crate::iso::guidance::scp::tests::dispersed_input(4)
    }

    #[test]
    fn the_linear_model_matches_the_nonlinear_one_near_the_iso() {
        let inp = input();
        let rates = OrbitRates::of(&inp.iso0);
        let (phi, gamma) = linear_model(&rates, 500.0, 600.0);
        let x = X6::new(2e5, -1e5, 5e4, 3.0, -2.0, 1.0);
        let u = V3::new(0.3, -0.1, 0.2);
        let lin = phi * x + gamma * u;
        // The nonlinear step holds u in inertial axes and lets the ISO move: small differences.
        let non = step(&x, &inp.iso0, 500.0, &u, 1e12, 600.0).x;
        assert!((pos(&lin) - pos(&non)).norm() < 1e-2, "{}", (pos(&lin) - pos(&non)).norm());
    }

    #[test]
    fn linear_mpc_meets_the_terminal_constraint_of_its_own_model() {
        let inp = input();
        let mut log = SolveLog::new("test");
        let (u, soft) = linear_mpc_plan(&inp, &mut log).unwrap();
        assert!(!soft && u.len() == 144);
        let (phi, gamma) = linear_model(&OrbitRates::of(&inp.iso0), inp.m0_kg, inp.dt_s);
        let x_n = u.iter().fold(inp.x0, |x, uk| phi * x + gamma * uk);
        assert!((pos(&x_n) - inp.rho_f_m).norm() < 1e-3 * inp.rho_f_m.norm(), "{}", (pos(&x_n) - inp.rho_f_m).norm());
        assert_eq!(linear_mpc(&inp, &mut log).unwrap().0, u[0]);
        // The nonlinear model under the same commands misses: the frozen ISO and the linearisation
        // at p = 0 are far off 10⁹ m from the ISO (this is what the closed loop must correct).
        let plan = solve(&inp, None, &ScpSettings::default(), &mut log);
        let miss = (rollout(&inp, &u, false).terminal_position() - inp.rho_f_m).norm();
        assert!(miss > 1e3 && plan.miss_m < 1.0, "open-loop miss of the linear plan {miss} m");
    }

    #[test]
    fn pd_and_robust_tracking_are_the_feed_forward_on_the_plan() {
        let x = X6::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0);
        let u = V3::new(0.1, 0.2, 0.3);
        assert_eq!(pd(&x, &x, &u, 500.0, 1e-3), u);
        let tr = Tracking { s: V3::zeros(), sigma_n: u, v: 0.0 };
        assert_eq!(robust_tracking(&tr, 1e-3, 500.0), u);
    }
}
