//! The global solution (Secs. 3.1 and 6.2.2 of "Neural-Rendezvous", arXiv:2208.04883): the
//! shrinking-horizon MPC (3)–(5) from the estimated state at t to the fixed t_f, discretised at
//! the control interval, by sequential convex programming. Each iteration linearises the
//! relative model (2) about the current plan (the first about the ballistic trajectory or a
//! warm start), solves the condensed QP of [`crate::iso::guidance::qp`] for the whole command sequence, and
//! rolls the nonlinear model out again; it stops when the rolled-out terminal miss is below the
//! tolerance (ours: 1 m) or after `max_iter` iterations. The terminal velocity is free (Remark 2).
//!
//! Departure: no trust region. The relative dynamics are nearly linear over one day (the
//! gravity-gradient terms change by ≲ 1 % with the plan), so the full step converges in two or
//! three iterations; the tests check it.

use cohort_runtime::solver_stats::SolveLog;
use nalgebra::{Matrix3, Matrix3x6};

use crate::iso::dynamics::lvlh::{X6, pos};
use crate::iso::dynamics::relative::{StepJac, step, step_jac};
use crate::iso::dynamics::two_body::{Inertial, V3};
use crate::iso::guidance::qp::solve_terminal_qp;

/// Where a plan starts and what it must reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScpInput {
    pub x0: X6,
    pub iso0: Inertial,
    pub m0_kg: f64,
    pub t0_s: f64,
    pub t_f_s: f64,
    pub dt_s: f64,
    pub rho_f_m: V3,
    pub u_max_n: f64,
    pub isp_s: f64,
}

impl ScpInput {
    /// Control steps left to t_f.
    pub fn steps(&self) -> usize {
        ((self.t_f_s - self.t0_s) / self.dt_s).round().max(0.0) as usize
    }
}

/// The SCP's stopping rule (`algorithm.scp`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScpSettings {
    /// Terminal miss of the rolled-out model at which the iteration stops, m.
    pub tol_m: f64,
    pub max_iter: u32,
}

impl Default for ScpSettings {
    fn default() -> Self {
        Self { tol_m: 1.0, max_iter: 10 }
    }
}

/// A rolled-out command sequence: nodes 0…N, commands 0…N−1 (LVLH axes at each node, N).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Rollout {
    pub u_n: Vec<V3>,
    pub x: Vec<X6>,
    pub iso: Vec<Inertial>,
    pub m_kg: Vec<f64>,
    pub jac: Vec<StepJac>,
}

impl Rollout {
    pub fn terminal_position(&self) -> V3 {
        pos(self.x.last().expect("a rollout has its start node"))
    }
}

/// Roll the model out under `u_n`, with the step Jacobians if `with_jac`.
pub fn rollout(inp: &ScpInput, u_n: &[V3], with_jac: bool) -> Rollout {
    let mut r =
        Rollout { u_n: u_n.to_vec(), x: vec![inp.x0], iso: vec![inp.iso0], m_kg: vec![inp.m0_kg], jac: Vec::new() };
    for u in u_n {
        let (x, iso, m) = (*r.x.last().unwrap(), *r.iso.last().unwrap(), *r.m_kg.last().unwrap());
        let s = if with_jac {
            let (s, j) = step_jac(&x, &iso, m, u, inp.isp_s, inp.dt_s);
            r.jac.push(j);
            s
        } else {
            step(&x, &iso, m, u, inp.isp_s, inp.dt_s)
        };
        r.x.push(s.x);
        r.iso.push(s.iso);
        r.m_kg.push(s.m_kg);
    }
    r
}

/// Mₖ = ∂p_N/∂uₖ from the step Jacobians (backward: Λ_N = [I 0], Λₖ = Λₖ₊₁Aₖ, Mₖ = Λₖ₊₁Bₖ).
pub fn terminal_sensitivities(jac: &[StepJac]) -> Vec<Matrix3<f64>> {
    let mut lam = Matrix3x6::<f64>::zeros();
    lam.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
    let mut m = vec![Matrix3::zeros(); jac.len()];
    for k in (0..jac.len()).rev() {
        m[k] = lam * jac[k].b;
        lam *= jac[k].a;
    }
    m
}

/// A solved plan.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    pub t0_s: f64,
    pub dt_s: f64,
    pub traj: Rollout,
    /// Terminal miss of the rolled-out model, m.
    pub miss_m: f64,
    pub iterations: u32,
    /// The last QP had to soften the terminal constraint (target out of reach).
    pub soft: bool,
    /// A QP failed outright (the plan is the last good iterate).
    pub qp_failed: bool,
}

impl Plan {
    /// The first command (what (5) applies), LVLH, N.
    pub fn first_u(&self) -> V3 {
        self.traj.u_n.first().copied().unwrap_or_else(V3::zeros)
    }
    pub fn converged(&self, s: &ScpSettings) -> bool {
        self.miss_m < s.tol_m
    }
}

/// Solve the shrinking-horizon problem from `inp`, linearising first about `warm` (a command
/// sequence of the right length) or else the ballistic trajectory.
pub fn solve(inp: &ScpInput, warm: Option<&[V3]>, s: &ScpSettings, log: &mut SolveLog) -> Plan {
    let n = inp.steps();
    let start: Vec<V3> = match warm {
        Some(w) if w.len() == n => w.to_vec(),
        _ => vec![V3::zeros(); n],
    };
    let mut traj = rollout(inp, &start, true);
    let mut plan = Plan { t0_s: inp.t0_s, dt_s: inp.dt_s, ..Plan::default() };
    plan.miss_m = (traj.terminal_position() - inp.rho_f_m).norm();
    if n == 0 || (plan.miss_m < s.tol_m && start.iter().all(|u| *u == V3::zeros())) {
        plan.traj = traj;
        return plan;
    }
    for it in 1..=s.max_iter {
        let m = terminal_sensitivities(&traj.jac);
        let d: V3 =
            inp.rho_f_m - traj.terminal_position() + m.iter().zip(&traj.u_n).map(|(mk, uk)| mk * uk).sum::<V3>();
        let qp = solve_terminal_qp(&m, &d, inp.u_max_n, log);
        let Some(u) = qp.u_n else {
            plan.qp_failed = true;
            break;
        };
        let next = rollout(inp, &u, true);
        let miss = (next.terminal_position() - inp.rho_f_m).norm();
        let stalled = qp.soft && miss >= 0.99 * plan.miss_m;
        (traj, plan.miss_m, plan.iterations, plan.soft) = (next, miss, it, qp.soft);
        if miss < s.tol_m || stalled {
            break;
        }
    }
    plan.traj = traj;
    plan
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};
    use crate::iso::dynamics::iso_set;
    use crate::iso::dynamics::lvlh::IsoFrame;
    use crate::iso::dynamics::navigation::NavSigmas;

    pub(crate) fn dispersed_input(i: u32) -> ScpInput {
        let ideal = iso_set::ideal(ISO_SET_SEED, i, 0, T_F_S, 100e3);
        let s0 = NavSigmas::default().at(0.0, T_F_S, 1.0);
        let (iso0, sc0) = iso_set::dispersed_start(ISO_SET_SEED, i, &ideal.at(0.0), 0, &s0);
        ScpInput {
            x0: IsoFrame::of(&iso0).relative(&sc0),
            iso0,
            m0_kg: 500.0,
            t0_s: 0.0,
            t_f_s: T_F_S,
            dt_s: 600.0,
            rho_f_m: ideal.rho_f_m,
            u_max_n: 1.0,
            isp_s: 220.0,
        }
    }

    #[test]
    fn scp_reaches_the_target_within_a_metre_in_a_few_iterations() {
        for i in [0, 1, 2, 3, 4] {
            let inp = dispersed_input(i);
            let mut log = SolveLog::new("test");
            let plan = solve(&inp, None, &ScpSettings::default(), &mut log);
            assert!(plan.converged(&ScpSettings::default()), "ISO {i}: miss {} m", plan.miss_m);
            assert!(plan.iterations <= 4, "ISO {i}: {} iterations", plan.iterations);
            assert!(plan.traj.u_n.iter().all(|u| u.amax() <= 1.0 + 1e-6));
            assert!(!plan.soft && !plan.qp_failed);
            // The start is ≈ 10⁵ m off: the ballistic miss must have been large.
            let ballistic =
                (rollout(&inp, &vec![V3::zeros(); inp.steps()], false).terminal_position() - inp.rho_f_m).norm();
            assert!(ballistic > 1e4, "ISO {i}: ballistic miss {ballistic}");
        }
    }

    #[test]
    fn terminal_sensitivities_predict_the_effect_of_a_small_change() {
        let inp = dispersed_input(9);
        let u0 = vec![V3::new(0.01, -0.02, 0.005); inp.steps()];
        let base = rollout(&inp, &u0, true);
        let m = terminal_sensitivities(&base.jac);
        let mut u1 = u0.clone();
        u1[40] += V3::new(0.0, 0.01, 0.0);
        let moved = rollout(&inp, &u1, false).terminal_position() - base.terminal_position();
        let predicted = m[40] * V3::new(0.0, 0.01, 0.0);
        assert!((moved - predicted).norm() < 1e-3 * predicted.norm(), "{moved:?} vs {predicted:?}");
    }

    #[test]
    fn a_plan_re_solved_from_its_own_second_node_keeps_its_commands() {
        // Bellman on the shrinking horizon: re-planning from the plan's next node changes nothing.
        let inp = dispersed_input(11);
        let s = ScpSettings { tol_m: 1e-3, max_iter: 10 };
        let plan = solve(&inp, None, &s, &mut SolveLog::new("test"));
        let next =
            ScpInput { x0: plan.traj.x[1], iso0: plan.traj.iso[1], m0_kg: plan.traj.m_kg[1], t0_s: 600.0, ..inp };
        let again = solve(&next, None, &s, &mut SolveLog::new("test"));
        let du = (again.first_u() - plan.traj.u_n[1]).norm();
        assert!(du < 1e-4 * plan.traj.u_n[1].norm().max(1e-3), "{du}");
    }
}
