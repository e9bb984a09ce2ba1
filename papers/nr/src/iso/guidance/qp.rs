//! The condensed QP every MPC of the crate solves (Sec. 6.2.2 of "Neural-Rendezvous",
//! arXiv:2208.04883: terminal position as a hard constraint, c₀ = 0; U = {|uᵢ| ≤ u_max};
//! P = ‖u‖², our choice where the paper's is lost):
//!
//!   min Σₖ ‖uₖ‖²  s.t.  Σₖ Mₖ uₖ = d,  |uₖ,ᵢ| ≤ u_max,
//!
//! with Mₖ = ∂p_N/∂uₖ of the (linearised) dynamics and d what the terminal position still needs.
//! Solved by Clarabel in the scaled variable z = u/u_max (box |z| ≤ 1), the equality rows scaled
//! to unit size. When the box makes the terminal constraint infeasible (a target out of reach),
//! the QP is solved again with the constraint softened by a slack e and a heavy weight on ‖e‖²:
//! the plan then gets as close as the thrust allows (counted as `soft`).

use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT, ZeroConeT,
};
use cohort_runtime::solver_stats::{SolveLog, SolveOutcome};
use nalgebra::Matrix3;

use crate::iso::dynamics::two_body::V3;

/// Outcome of one terminal QP.
#[derive(Debug, Clone, PartialEq)]
pub struct QpResult {
    /// The commands, or None when even the softened problem failed.
    pub u_n: Option<Vec<V3>>,
    /// The terminal constraint had to be softened.
    pub soft: bool,
}

/// Weight on the slack of the softened problem, per unit of Σ‖z‖² (z = u/u_max).
const SLACK_WEIGHT: f64 = 1e6;

fn settings() -> DefaultSettings<f64> {
    DefaultSettings { verbose: false, max_iter: 200, ..DefaultSettings::default() }
}

fn outcome(s: SolverStatus) -> SolveOutcome {
    match s {
        SolverStatus::Solved => SolveOutcome::Solved,
        SolverStatus::PrimalInfeasible
        | SolverStatus::DualInfeasible
        | SolverStatus::AlmostPrimalInfeasible
        | SolverStatus::AlmostDualInfeasible => SolveOutcome::Infeasible,
        _ => SolveOutcome::NotConverged,
    }
}

/// Solve; every Clarabel call is recorded in `log`.
pub fn solve_terminal_qp(m: &[Matrix3<f64>], d: &V3, u_max_n: f64, log: &mut SolveLog) -> QpResult {
    let n = m.len();
    if n == 0 {
        return QpResult { u_n: Some(Vec::new()), soft: false };
    }
    let scale = m.iter().flat_map(|mk| mk.iter()).fold(0.0f64, |a, x| a.max(x.abs())) * u_max_n;
    let scale = if scale > 0.0 { scale } else { 1.0 };
    let a_eq = |k: usize, row: usize, col: usize| m[k][(row, col)] * u_max_n / scale;
    let b_eq = d / scale;
    for soft in [false, true] {
        let nv = 3 * n + if soft { 3 } else { 0 };
        let (mut colptr, mut rowval, mut nzval) = (vec![0usize], Vec::new(), Vec::new());
        for j in 0..3 * n {
            let (k, c) = (j / 3, j % 3);
            for row in 0..3 {
                rowval.push(row);
                nzval.push(a_eq(k, row, c));
            }
            rowval.extend([3 + j, 3 + 3 * n + j]);
            nzval.extend([1.0, -1.0]);
            colptr.push(rowval.len());
        }
        if soft {
            for row in 0..3 {
                rowval.push(row);
                nzval.push(-1.0);
                colptr.push(rowval.len());
            }
        }
        let a = CscMatrix::new(3 + 6 * n, nv, colptr, rowval, nzval);
        let diag: Vec<f64> = (0..nv).map(|j| if j < 3 * n { 1.0 } else { SLACK_WEIGHT * (3 * n) as f64 }).collect();
        let p = CscMatrix::new(nv, nv, (0..=nv).collect(), (0..nv).collect(), diag);
        let mut b = vec![b_eq.x, b_eq.y, b_eq.z];
        b.extend(std::iter::repeat_n(1.0, 6 * n));
        let cones: [SupportedConeT<f64>; 2] = [ZeroConeT(3), NonnegativeConeT(6 * n)];
        let Ok(mut solver) = DefaultSolver::new(&p, &vec![0.0; nv], &a, &b, &cones, settings()) else {
            log.record(SolveOutcome::NotConverged, 0, 0.0);
            return QpResult { u_n: None, soft };
        };
        let started = Instant::now();
        solver.solve();
        let wall_s = started.elapsed().as_secs_f64();
        let sol = &solver.solution;
        log.record(outcome(sol.status), u64::from(sol.iterations), wall_s);
        let usable = matches!(sol.status, SolverStatus::Solved | SolverStatus::AlmostSolved)
            && sol.x.iter().all(|x| x.is_finite());
        if usable {
            let u = (0..n).map(|k| V3::new(sol.x[3 * k], sol.x[3 * k + 1], sol.x[3 * k + 2]) * u_max_n).collect();
            return QpResult { u_n: Some(u), soft };
        }
    }
    QpResult { u_n: None, soft: true }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log() -> SolveLog {
        SolveLog::new("test")
    }

    #[test]
    fn unconstrained_solution_is_the_minimum_norm_one() {
        // M_k = c_k I: the minimum-norm solution is u_k = c_k d / Σ c_j².
        let c = [3.0, 2.0, 1.0];
        let m: Vec<_> = c.iter().map(|&ck| Matrix3::identity() * ck).collect();
        let d = V3::new(0.7, -0.2, 0.4);
        let r = solve_terminal_qp(&m, &d, 10.0, &mut log());
        let u = r.u_n.unwrap();
        let s: f64 = c.iter().map(|x| x * x).sum();
        for (k, uk) in u.iter().enumerate() {
            assert!((uk - c[k] * d / s).norm() < 1e-7, "{k}: {uk:?}");
        }
        assert!(!r.soft);
    }

    #[test]
    fn the_box_binds_and_the_terminal_constraint_still_holds() {
        let c = [3.0, 2.0, 1.0];
        let m: Vec<_> = c.iter().map(|&ck| Matrix3::identity() * ck).collect();
        let d = V3::new(5.0, 0.0, 0.0);
        let u = solve_terminal_qp(&m, &d, 1.0, &mut log()).u_n.unwrap();
        let reached: V3 = u.iter().zip(&c).map(|(uk, ck)| uk * *ck).sum();
        assert!((reached - d).norm() < 1e-6, "{reached:?}");
        assert!(u.iter().all(|uk| uk.amax() <= 1.0 + 1e-7));
        // KKT: u_k = clip(λ c_k, ±1) with λ = 0.4.
        let want = [1.0, 0.8, 0.4];
        for k in 0..3 {
            assert!((u[k].x - want[k]).abs() < 1e-6, "{k}: {:?}", u[k]);
        }
    }

    #[test]
    fn an_unreachable_target_is_approached_as_far_as_the_box_allows() {
        let m = vec![Matrix3::identity(); 2];
        let r = solve_terminal_qp(&m, &V3::new(5.0, 0.0, 0.0), 1.0, &mut log());
        assert!(r.soft);
        let u = r.u_n.unwrap();
        assert!(u.iter().all(|uk| (uk.x - 1.0).abs() < 1e-5), "{u:?}");
    }
}
