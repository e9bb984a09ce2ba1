//! The receding-horizon machinery AEMC and DMPC share (Sec. 3.2, (19)–(26)): the condensed
//! prediction over N_p steps, the bounded QP in Clarabel, and what to do when a solve fails.
//!
//! Decision variable: U = [û_k; …; û_{k+N_p−1}] (3N_p), the total force on the MU (thrust plus
//! predicted tension, ûᵢ = uᵢ + T̂ᵢ of (13)), N. Predicted states X = Φ x_k + Γ U (19).
//! Cost ½UᵀPU + qᵀU with P = 2H; the thrust bound |uᵢ| ≤ ū per axis over the whole horizon is
//! T̂ − ū ≤ U ≤ T̂ + ū, written for Clarabel as [I; −I] U + s = [ū + T̂; ū − T̂], s ≥ 0.
//!
//! The problem's structure (P, A, the cone) is fixed for the run, so the solver is built once and
//! each step only overwrites q and b (Clarabel's data updates, which need presolve and
//! structural-zero dropping off: both are disabled). No time limit is set, so a solve's result
//! never depends on the machine's speed; its wall time is measured for the report only.

use std::time::Instant;

use crate::cw::{Cw, Discrete, Prediction};
use crate::trajectory::Trajectory;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use cohort_runtime::solver_stats::{SolveLog, SolveOutcome, SolverStats};
use nalgebra::{DMatrix, DVector};

/// A solve's outcome as telemetry records it (a deterministic code, not the wall time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpStatus {
    Solved = 0,
    /// Reduced accuracy only.
    AlmostSolved = 1,
    MaxIterations = 2,
    PrimalInfeasible = 3,
    DualInfeasible = 4,
    /// Numerical error, insufficient progress, or anything else.
    Failed = 5,
    /// Reported solved, but a component of the solution is not finite.
    NonFinite = 6,
}

impl QpStatus {
    fn from_clarabel(s: SolverStatus) -> Self {
        match s {
            SolverStatus::Solved => Self::Solved,
            SolverStatus::AlmostSolved => Self::AlmostSolved,
            SolverStatus::MaxIterations => Self::MaxIterations,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Self::PrimalInfeasible,
            SolverStatus::DualInfeasible | SolverStatus::AlmostDualInfeasible => Self::DualInfeasible,
            _ => Self::Failed,
        }
    }
    pub fn code(self) -> f64 {
        self as u8 as f64
    }
    fn outcome(self) -> SolveOutcome {
        match self {
            Self::Solved => SolveOutcome::Solved,
            Self::PrimalInfeasible | Self::DualInfeasible => SolveOutcome::Infeasible,
            _ => SolveOutcome::NotConverged,
        }
    }
}

/// The condensed model over the horizon and the weights on the stacked error: Q̄ = I_{N_p} ⊗ Q.
pub struct Horizon {
    pub np: usize,
    pub dt_s: f64,
    pub disc: Discrete,
    pub pred: Prediction,
    /// ΓᵀQ̄ (3N_p × 6N_p): maps a stacked error offset to the linear term.
    pub gt_q: DMatrix<f64>,
    /// ΓᵀQ̄Γ (3N_p × 3N_p).
    pub gt_q_g: DMatrix<f64>,
}

impl Horizon {
    pub fn new(cw: Cw, dt_s: f64, np: usize, q_position: f64, q_velocity: f64) -> Self {
        let disc = cw.discretise(dt_s);
        let pred = disc.prediction(np);
        let qbar = DVector::from_fn(6 * np, |i, _| if i % 6 < 3 { q_position } else { q_velocity });
        let mut gt_q = pred.gamma.transpose();
        for (j, mut col) in gt_q.column_iter_mut().enumerate() {
            col *= qbar[j];
        }
        let gt_q_g = &gt_q * &pred.gamma;
        Self { np, dt_s, disc, pred, gt_q, gt_q_g }
    }

    /// X^d: the desired states x^d(t_k + pΔt), p = 1..N_p, stacked.
    pub fn desired(&self, traj: &Trajectory, t_k_s: f64) -> DVector<f64> {
        let mut xd = DVector::zeros(6 * self.np);
        for p in 0..self.np {
            let d = traj.at(t_k_s + (p + 1) as f64 * self.dt_s).state();
            xd.rows_mut(6 * p, 6).copy_from_slice(&d);
        }
        xd
    }

    /// Φ x_k − X^d: the stacked tracking error if U = 0.
    pub fn free_error(&self, x0: &[f64; 6], xd: &DVector<f64>) -> DVector<f64> {
        &self.pred.phi * DVector::from_column_slice(x0) - xd
    }

    /// H = w_e ΓᵀQ̄Γ + w_r I: the Hessian (up to the factor 2) of a cost whose error terms add
    /// up to w_e times the MU's own stacked error and whose force terms to w_r |U|².
    pub fn hessian(&self, w_error: f64, w_force: f64) -> DMatrix<f64> {
        let mut h = &self.gt_q_g * w_error;
        for i in 0..h.nrows() {
            h[(i, i)] += w_force;
        }
        h
    }
}

/// min ½UᵀPU + qᵀU subject to T̂ − ū ≤ U ≤ T̂ + ū, solved by Clarabel.
pub struct BoxQp {
    solver: DefaultSolver<f64>,
    n: usize,
    bound_n: f64,
    b: Vec<f64>,
    log: SolveLog,
}

impl BoxQp {
    /// `h` symmetric positive definite (P = 2h); `bound_n` = ū > 0.
    pub fn new(h: &DMatrix<f64>, bound_n: f64, max_iter: u32) -> Self {
        let n = h.nrows();
        // P: upper triangle, dense, column by column.
        let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
        for j in 0..n {
            for i in 0..=j {
                rowval.push(i);
                nzval.push(2.0 * h[(i, j)]);
            }
            colptr.push(rowval.len());
        }
        let p = CscMatrix::new(n, n, colptr, rowval, nzval);
        // A = [I; −I].
        let colptr: Vec<usize> = (0..=n).map(|j| 2 * j).collect();
        let rowval: Vec<usize> = (0..n).flat_map(|j| [j, n + j]).collect();
        let nzval: Vec<f64> = (0..n).flat_map(|_| [1.0, -1.0]).collect();
        let a = CscMatrix::new(2 * n, n, colptr, rowval, nzval);
        let b = vec![bound_n; 2 * n];
        let settings = DefaultSettings {
            max_iter,
            verbose: false,
            // Data updates (q, b) are refused once presolve or zero-dropping changed the problem.
            presolve_enable: false,
            input_sparse_dropzeros: false,
            // Tighter than the defaults (1e-8): the forces are O(1) N and the unconstrained optimum
            // must match the closed form to 1e-8 N.
            tol_gap_abs: 1e-10,
            tol_gap_rel: 1e-10,
            tol_feas: 1e-10,
            ..DefaultSettings::default()
        };
        let solver = DefaultSolver::new(&p, &vec![0.0; n], &a, &b, &[NonnegativeConeT(2 * n)], settings)
            .expect("a well-formed box QP (dimensions are fixed by construction)");
        assert!(solver.is_data_update_allowed(), "presolve and zero dropping are off");
        let log = SolveLog::new(format!("clarabel box QP ({n} variables, {} inequality rows)", 2 * n));
        Self { solver, n, bound_n, b, log }
    }

    /// Solve with the linear term `q` and the predicted tension `offset` (T̂ stacked, 3N_p).
    /// Returns the status, the iteration count and the solution when the status is Solved.
    pub fn solve(&mut self, q: &[f64], offset: &[f64]) -> (QpStatus, u32, Option<&[f64]>) {
        assert_eq!((q.len(), offset.len()), (self.n, self.n));
        for i in 0..self.n {
            self.b[i] = self.bound_n + offset[i];
            self.b[self.n + i] = self.bound_n - offset[i];
        }
        self.solver.update_q(&q.to_vec()).expect("data updates allowed, length fixed");
        self.solver.update_b(&self.b).expect("data updates allowed, length fixed");
        let started = Instant::now();
        self.solver.solve();
        let wall_s = started.elapsed().as_secs_f64();
        let sol = &self.solver.solution;
        let mut status = QpStatus::from_clarabel(sol.status);
        if status == QpStatus::Solved && !sol.x.iter().all(|x| x.is_finite()) {
            status = QpStatus::NonFinite;
        }
        self.log.record(status.outcome(), u64::from(sol.iterations), wall_s);
        let x = (status == QpStatus::Solved).then_some(sol.x.as_slice());
        (status, sol.iterations, x)
    }

    pub fn stats(&self) -> SolverStats {
        self.log.stats()
    }
}

/// The last accepted plan Uᵢ and the step it was made at: what a failed solve falls back on.
#[derive(Debug, Clone, Default)]
pub struct Plan {
    pub k: Option<u64>,
    pub u: Vec<f64>,
}

impl Plan {
    /// The plan made at its step, seen from step `k`: shifted by the steps since, the last force
    /// held over the tail (zeros if there is no plan).
    pub fn shifted(&self, k: u64, np: usize) -> Vec<f64> {
        let Some(k0) = self.k else { return vec![0.0; 3 * np] };
        let age = (k - k0) as usize;
        (0..np)
            .flat_map(|p| {
                let src = (p + age).min(np - 1);
                [self.u[3 * src], self.u[3 * src + 1], self.u[3 * src + 2]]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_qp_clips_like_the_exact_solution_of_a_diagonal_problem() {
        // Diagonal P: the bounded optimum is the unconstrained one clipped to the box.
        let n = 6;
        let h = DMatrix::from_fn(n, n, |i, j| if i == j { 1.0 + i as f64 } else { 0.0 });
        let mut qp = BoxQp::new(&h, 5.0, 100);
        let q: Vec<f64> = (0..n).map(|i| -2.0 * (1.0 + i as f64) * (3.0 * i as f64 - 7.0)).collect();
        let offset = vec![1.0, -1.0, 0.0, 2.0, 0.5, -3.0];
        let (status, iters, x) = qp.solve(&q, &offset);
        assert_eq!(status, QpStatus::Solved);
        assert!(iters > 0);
        let x = x.unwrap();
        for i in 0..n {
            let unconstrained = 3.0 * i as f64 - 7.0;
            let want = unconstrained.clamp(offset[i] - 5.0, offset[i] + 5.0);
            assert!((x[i] - want).abs() < 1e-7, "x[{i}] = {} want {want}", x[i]);
        }
        let s = qp.stats();
        assert_eq!((s.solves, s.solved), (1, 1));
    }

    #[test]
    fn shifted_plan_drops_the_past_and_holds_the_tail() {
        let plan = Plan { k: Some(10), u: (0..9).map(f64::from).collect() };
        assert_eq!(plan.shifted(10, 3), (0..9).map(f64::from).collect::<Vec<_>>());
        assert_eq!(plan.shifted(11, 3), vec![3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 6.0, 7.0, 8.0]);
        assert_eq!(plan.shifted(20, 3), vec![6.0, 7.0, 8.0, 6.0, 7.0, 8.0, 6.0, 7.0, 8.0]);
        assert_eq!(Plan::default().shifted(5, 2), vec![0.0; 6]);
    }
}
