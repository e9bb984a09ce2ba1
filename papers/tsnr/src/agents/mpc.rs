//! The receding-horizon machinery AEMC and DMPC share (Sec. 3.2, (19)–(26)): the condensed
//! prediction over N_p steps, the bounded QP, and what to do when a solve fails.
//!
//! Decision variable: U = [û_k; …; û_{k+N_p−1}] (3N_p), the total force on the MU (thrust plus
//! predicted tension, ûᵢ = uᵢ + T̂ᵢ of (13)), N. Predicted states X = Φ x_k + Γ U (19).
//! Cost ½UᵀPU + qᵀU with P = 2H; the thrust bound |uᵢ| ≤ ū per axis over the whole horizon is
//! T̂ − ū ≤ U ≤ T̂ + ū.
//!
//! **Solver** (`algorithm.mpc.qp_solver`; the paper names none). P is fixed for the run and the
//! constraints are simple bounds, so the default solves the QP exactly by the primal–dual active
//! set of [`super::active_set`], warm-started from the previous step's active set moved on by one
//! step (≈ 1.4 iterations of one Cholesky factorisation each on Case 1), with Clarabel for the
//! rare problem where that method stalls (status `SolvedByFallback`, counted). `"clarabel"` uses
//! Clarabel's interior point alone, as this crate did first: it cannot be warm-started, and on
//! this 60-variable problem it spends ≈ 8.5 iterations of one sparse LDLᵀ factorisation of the
//! 180-row KKT system and two solves with iterative refinement each (measured in
//! `papers/tsnr/README.md`). Clarabel's problem structure (P, A, the cone) is built once and
//! each step only overwrites q and b (its data updates, which need presolve and structural-zero
//! dropping off: both are disabled); its tolerances (1e-10) leave the solution ≈ 1e-5 N from the
//! exact one, so the two solvers' runs agree to that and then drift apart as the chaotic net
//! amplifies the difference.
//!
//! No time limit is set, so a solve's result never depends on the machine's speed; its wall time
//! (data update and solve) is measured for the report only.

use std::time::Instant;

use super::active_set::ActiveSet;
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
    /// The active-set method stalled and Clarabel solved the problem.
    SolvedByFallback = 7,
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
    /// Whether the solve produced a plan.
    pub fn has_solution(self) -> bool {
        matches!(self, Self::Solved | Self::SolvedByFallback)
    }
    fn outcome(self) -> SolveOutcome {
        match self {
            Self::Solved | Self::SolvedByFallback => SolveOutcome::Solved,
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

/// How [`BoxQp`] solves (the scenario's `algorithm.mpc.qp_solver`).
pub use crate::config::formation::QpSolver;

/// min ½UᵀPU + qᵀU subject to T̂ − ū ≤ U ≤ T̂ + ū: by the exact active-set method of
/// [`super::active_set`] warm-started from the previous step's active set, with Clarabel when it
/// stalls ([`QpSolver::ActiveSet`]), or by Clarabel alone ([`QpSolver::Clarabel`]).
pub struct BoxQp {
    clarabel: DefaultSolver<f64>,
    active: Option<ActiveSet>,
    /// H (P = 2H), kept for replays.
    h: DMatrix<f64>,
    n: usize,
    bound_n: f64,
    /// The active set's iteration cap (Clarabel's is in its settings); `max_iter` for both.
    active_max_iter: u32,
    /// Clarabel's b = [ū + T̂; ū − T̂], and the box T̂ ∓ ū for the active set.
    b: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// The linear term and the tension offset of the last solve (for benchmarks and tests).
    last_q: Vec<f64>,
    last_offset: Vec<f64>,
    /// Active-set solves that stalled and went to Clarabel.
    fallbacks: u64,
    log: SolveLog,
}

/// Clarabel's settings for the box QP (also what the QP benchmark replays with).
pub fn clarabel_settings(max_iter: u32) -> DefaultSettings<f64> {
    DefaultSettings {
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
    }
}

/// Clarabel set up for min ½Uᵀ(2h)U + qᵀU s.t. −ū ≤ U ≤ ū (q and the bounds' offsets are
/// written by data updates before each solve).
pub fn clarabel_box_qp(h: &DMatrix<f64>, bound_n: f64, settings: DefaultSettings<f64>) -> DefaultSolver<f64> {
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
    // A = [I; −I], s ≥ 0: U + s = ū + T̂, −U + s = ū − T̂.
    let colptr: Vec<usize> = (0..=n).map(|j| 2 * j).collect();
    let rowval: Vec<usize> = (0..n).flat_map(|j| [j, n + j]).collect();
    let nzval: Vec<f64> = (0..n).flat_map(|_| [1.0, -1.0]).collect();
    let a = CscMatrix::new(2 * n, n, colptr, rowval, nzval);
    let b = vec![bound_n; 2 * n];
    DefaultSolver::new(&p, &vec![0.0; n], &a, &b, &[NonnegativeConeT(2 * n)], settings)
        .expect("a well-formed box QP (dimensions are fixed by construction)")
}

/// Values per horizon step: the warm start moves by one step (three force components) per solve.
const VALUES_PER_STEP: usize = 3;

impl BoxQp {
    /// `h` symmetric positive definite (P = 2h); `bound_n` = ū > 0; `max_iter` bounds the
    /// iterations of either method.
    pub fn new(h: &DMatrix<f64>, bound_n: f64, max_iter: u32, solver: QpSolver) -> Self {
        let n = h.nrows();
        let clarabel = clarabel_box_qp(h, bound_n, clarabel_settings(max_iter));
        assert!(clarabel.is_data_update_allowed(), "presolve and zero dropping are off");
        let active = match solver {
            QpSolver::ActiveSet => {
                let p_dense: Vec<f64> = (0..n * n).map(|i| 2.0 * h[(i % n, i / n)]).collect();
                Some(ActiveSet::new(p_dense, n).expect("H is positive definite (R > 0 is validated)"))
            }
            QpSolver::Clarabel => None,
        };
        let name = match solver {
            QpSolver::ActiveSet => format!("active-set box QP ({n} variables), clarabel fallback"),
            QpSolver::Clarabel => format!("clarabel box QP ({n} variables, {} inequality rows)", 2 * n),
        };
        Self {
            clarabel,
            active,
            h: h.clone(),
            n,
            bound_n,
            active_max_iter: max_iter,
            b: vec![bound_n; 2 * n],
            lo: vec![0.0; n],
            hi: vec![0.0; n],
            last_q: vec![0.0; n],
            last_offset: vec![0.0; n],
            fallbacks: 0,
            log: SolveLog::new(name),
        }
    }

    /// Solve with the linear term `q` and the predicted tension `offset` (T̂ stacked, 3N_p).
    /// Returns the status, the iteration count and the solution when the status is Solved or
    /// SolvedByFallback. Call once per control step: the active set's warm start is the
    /// previous call's active set moved on by one step.
    pub fn solve(&mut self, q: &[f64], offset: &[f64]) -> (QpStatus, u32, Option<&[f64]>) {
        assert_eq!((q.len(), offset.len()), (self.n, self.n));
        // The wall time covers the data updates too: it is what the controller waits for.
        let started = Instant::now();
        self.last_q.copy_from_slice(q);
        self.last_offset.copy_from_slice(offset);
        let mut first = None;
        if let Some(a) = &mut self.active {
            for i in 0..self.n {
                self.lo[i] = offset[i] - self.bound_n;
                self.hi[i] = offset[i] + self.bound_n;
            }
            a.shift(VALUES_PER_STEP);
            match a.solve(q, &self.lo, &self.hi, self.active_max_iter) {
                Ok(iterations) => {
                    self.log.record(SolveOutcome::Solved, u64::from(iterations), started.elapsed().as_secs_f64());
                    return (QpStatus::Solved, iterations, self.active.as_ref().map(ActiveSet::x));
                }
                Err(stalled) => {
                    self.fallbacks += 1;
                    first = Some(stalled.iterations);
                }
            }
        }
        let (status, iterations) = self.solve_clarabel();
        let status = if first.is_some() && status == QpStatus::Solved { QpStatus::SolvedByFallback } else { status };
        let iterations = iterations + first.unwrap_or(0);
        self.log.record(status.outcome(), u64::from(iterations), started.elapsed().as_secs_f64());
        let x = status.has_solution().then_some(self.clarabel.solution.x.as_slice());
        (status, iterations, x)
    }

    /// Clarabel on the problem in `last_q`/`last_offset`.
    fn solve_clarabel(&mut self) -> (QpStatus, u32) {
        for i in 0..self.n {
            self.b[i] = self.bound_n + self.last_offset[i];
            self.b[self.n + i] = self.bound_n - self.last_offset[i];
        }
        self.clarabel.update_q(&self.last_q).expect("data updates allowed, length fixed");
        self.clarabel.update_b(&self.b).expect("data updates allowed, length fixed");
        self.clarabel.solve();
        let sol = &self.clarabel.solution;
        let mut status = QpStatus::from_clarabel(sol.status);
        if status == QpStatus::Solved && !sol.x.iter().all(|x| x.is_finite()) {
            status = QpStatus::NonFinite;
        }
        (status, sol.iterations)
    }

    /// Solve counts and times; the solver's name says how many active-set solves fell back.
    pub fn stats(&self) -> SolverStats {
        let mut s = self.log.stats();
        if self.active.is_some() {
            s.solver = format!("{}: {} fallback(s)", s.solver, self.fallbacks);
        }
        s
    }

    /// Active-set solves that stalled and were solved by Clarabel instead.
    pub fn fallbacks(&self) -> u64 {
        self.fallbacks
    }

    /// The linear term q and the tension offset of the last solve: the problem, for replaying it
    /// (benchmarks) and checking it (tests).
    pub fn last_problem(&self) -> (&[f64], &[f64]) {
        (&self.last_q, &self.last_offset)
    }

    /// H of the cost ½Uᵀ(2H)U + qᵀU, and the thrust bound ū.
    pub fn hessian(&self) -> (&DMatrix<f64>, f64) {
        (&self.h, self.bound_n)
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
        for solver in [QpSolver::ActiveSet, QpSolver::Clarabel] {
            let mut qp = BoxQp::new(&h, 5.0, 100, solver);
            let q: Vec<f64> = (0..n).map(|i| -2.0 * (1.0 + i as f64) * (3.0 * i as f64 - 7.0)).collect();
            let offset = vec![1.0, -1.0, 0.0, 2.0, 0.5, -3.0];
            let (status, iters, x) = qp.solve(&q, &offset);
            assert_eq!(status, QpStatus::Solved, "{solver:?}");
            assert!(iters > 0);
            let x = x.unwrap();
            for i in 0..n {
                let unconstrained = 3.0 * i as f64 - 7.0;
                let want = unconstrained.clamp(offset[i] - 5.0, offset[i] + 5.0);
                assert!((x[i] - want).abs() < 1e-7, "{solver:?}: x[{i}] = {} want {want}", x[i]);
            }
            let s = qp.stats();
            assert_eq!((s.solves, s.solved), (1, 1));
        }
    }

    /// A dense, well-mixed SPD H (eigenvalues 0.05 … 1) and a linear term that pushes many
    /// variables against the box.
    fn dense_problem(n: usize, seed: u64) -> (DMatrix<f64>, Vec<f64>, Vec<f64>) {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let m = DMatrix::from_fn(n, n, |_, _| next());
        let qr = m.qr();
        let qm = qr.q();
        let d = DMatrix::from_fn(n, n, |i, j| if i == j { 0.05 + 0.95 * i as f64 / (n - 1) as f64 } else { 0.0 });
        let h = &qm * d * qm.transpose();
        let h = (&h + h.transpose()) * 0.5;
        let q: Vec<f64> = (0..n).map(|_| 8.0 * next()).collect();
        let offset: Vec<f64> = (0..n).map(|_| 2.0 * next()).collect();
        (h, q, offset)
    }

    #[test]
    fn active_set_and_clarabel_agree_on_dense_problems_with_many_bounds_active() {
        let mut active_total = 0;
        for seed in 0..20 {
            let (h, q, offset) = dense_problem(30, seed);
            let mut a = BoxQp::new(&h, 1.0, 100, QpSolver::ActiveSet);
            let mut c = BoxQp::new(&h, 1.0, 100, QpSolver::Clarabel);
            let (sa, _, xa) = a.solve(&q, &offset);
            let xa = xa.unwrap().to_vec();
            let (sc, _, xc) = c.solve(&q, &offset);
            assert_eq!((sa, sc), (QpStatus::Solved, QpStatus::Solved), "seed {seed}");
            let diff = xa.iter().zip(xc.unwrap()).map(|(a, c)| (a - c).abs()).fold(0.0, f64::max);
            assert!(diff < 1e-5, "seed {seed}: active set and Clarabel differ by {diff}");
            active_total += xa.iter().zip(&offset).filter(|(x, o)| ((*x - *o).abs() - 1.0).abs() < 1e-12).count();
            assert!(xa.iter().zip(&offset).all(|(x, o)| (x - o).abs() <= 1.0), "seed {seed}: outside the box");
        }
        assert!(active_total > 100, "the problems must exercise the bounds: {active_total} active in all");
    }

    #[test]
    fn a_stalled_active_set_falls_back_on_clarabel_and_is_counted() {
        let (h, q, offset) = dense_problem(30, 7);
        let mut qp = BoxQp::new(&h, 1.0, 100, QpSolver::ActiveSet);
        qp.active_max_iter = 1; // too few for any problem with a bound active
        let (status, iters, x) = qp.solve(&q, &offset);
        assert_eq!(status, QpStatus::SolvedByFallback);
        assert!(iters > 1 && x.is_some());
        assert_eq!(qp.fallbacks(), 1);
        let st = qp.stats();
        assert_eq!((st.solves, st.solved), (1, 1));
        assert!(st.solver.ends_with("1 fallback(s)"), "{}", st.solver);
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
