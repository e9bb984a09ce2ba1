//! The swarm's global solution (Sec. 7.2.1 of "Neural-Rendezvous", arXiv:2208.04883):
//! centralised sequential convex programming over all N vehicles, minimising the total control
//! effort with the tall-ellipsoid collision constraints. The model is the one of
//! [`crate::swarm::train::problem`] (double integrator, |aᵢ| ≤ 2 m/s² per axis, T = 8 s, Δt = 0.1 s).
//!
//! **Each convex subproblem** (a QP, solved by Clarabel) has, per vehicle, the positions and
//! velocities of nodes 1…K and the accelerations of steps 0…K−1 as variables, and
//! - cost Σᵢ Σₖ ‖aᵢₖ‖² Δt (ours: the paper's effort norm is lost; the squared 2-norm keeps the
//!   subproblem a QP and the policy Lipschitz, as for the ISO case). ∫‖u‖dt = Σᵢ Σₖ ‖aᵢₖ‖Δt is
//!   reported beside it ([`SwarmPlan::effort_l1`]), as the issue compares that;
//! - the exact discrete dynamics p⁺ = p + vΔt + ½aΔt², v⁺ = v + aΔt from rest at the start,
//!   and the terminal state at rest at the target;
//! - |aᵢₖ,c| ≤ a_max;
//! - for the *near* pairs only: at every constraint time where the linearisation point has the
//!   pair's ellipsoid distance d̄ = ‖E⁻¹Δp̄‖ below [`SwarmScpSettings::near`], the constraint
//!   nᵀΔp ≥ r with n = E⁻²Δp̄/d̄ and r = [`SwarmScpSettings::margin`] (the linearisation of the
//!   convex ‖E⁻¹Δp‖ ≥ r; since a convex function lies above its tangents, nᵀΔp ≥ r implies
//!   ‖E⁻¹Δp‖ ≥ r: every subproblem is an inner approximation). The constraint times are the
//!   nodes 1…K−1 and the mid-points of the steps (positions there are affine in the variables).
//!
//! **The iteration.** The first linearisation point is the collision-free-ignoring minimum-
//! effort solution (the subproblem without collision constraints) with a small deterministic
//! horizontal bump per vehicle (amplitude [`BUMP_M`], direction i × the golden angle): it breaks
//! the symmetry of exactly head-on pairs, whose linearisation direction is otherwise the line of
//! travel. Every later one is the previous solution. A (pair, time) once near stays constrained
//! (the set only grows, so it stops changing). It stops when the set did not grow and the cost
//! changed by less than [`SwarmScpSettings::tol_rel`]. No trust region: the inner approximation
//! keeps the previous iterate feasible once the set is fixed (the convex–concave procedure), so
//! the cost cannot rise.
//!
//! **Check.** The result is rolled out exactly from its accelerations and the pairwise ellipsoid
//! distance is evaluated at [`FINE_SUBSTEPS`] = 10 points per step (the plant's collision-check
//! rate) on the quadratic arcs between nodes ([`SwarmPlan::min_distance_fine`], must be ≥ 1).
//! The margin r = 1.05 and the mid-point constraints keep the arcs between constraint times
//! outside the ellipsoid as long as the relative horizontal speed stays below ≈ 1.5 m/s (the
//! chord between two points at distance r, 0.05 s apart, stays ≥ 1); the fine check verifies it
//! rather than relying on the argument.

use std::collections::BTreeSet;
use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT, ZeroConeT,
};

use crate::swarm::dynamics::setup::norm;
use crate::swarm::train::problem::{A_MAX_MPS2, DT_S, ELLIPSOID_M, STEPS, SwarmCase, T_S, ellipsoid_distance};

/// Fine-grid points per step of the collision check.
pub const FINE_SUBSTEPS: usize = 10;
/// Amplitude of the first linearisation point's symmetry-breaking bump, m.
pub const BUMP_M: f64 = 0.05;

/// The SCP's parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SwarmScpSettings {
    /// r of the linearised constraint nᵀΔp ≥ r (ellipsoid distance).
    pub margin: f64,
    /// A (pair, time) is constrained once its ellipsoid distance at a linearisation point is
    /// below this.
    pub near: f64,
    pub max_iter: u32,
    /// Relative cost change at which the iteration stops.
    pub tol_rel: f64,
}

impl Default for SwarmScpSettings {
    fn default() -> Self {
        Self { margin: 1.05, near: 2.0, max_iter: 30, tol_rel: 1e-4 }
    }
}

/// The global solution of one case.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmPlan {
    /// [vehicle][node 0…K], rolled out exactly from `a_mps2`.
    pub p_m: Vec<Vec<[f64; 3]>>,
    pub v_mps: Vec<Vec<[f64; 3]>>,
    /// [vehicle][step 0…K−1].
    pub a_mps2: Vec<Vec<[f64; 3]>>,
    /// SCP iterations (convex subproblems solved, the first, unconstrained one included).
    pub iterations: u32,
    /// Clarabel iterations over all subproblems.
    pub qp_iterations: u32,
    /// The stopping rule was met (else `max_iter` ran out).
    pub converged: bool,
    /// Linearised collision constraints in the last subproblem.
    pub constraints: usize,
    /// Wall-clock time of the whole SCP, s.
    pub solve_s: f64,
    /// Σᵢ Σₖ ‖aᵢₖ‖² Δt, m²/s³ (the cost).
    pub energy: f64,
    /// ∫‖u‖dt summed over the vehicles, m/s.
    pub effort_l1: f64,
    /// Least pairwise ellipsoid distance on the fine grid (≥ 1: collision-free).
    pub min_distance_fine: f64,
    /// Largest ‖p_K − g‖ of the exact roll-out, m.
    pub terminal_error_m: f64,
}

impl SwarmPlan {
    /// Converged and collision-free on the fine grid.
    pub fn is_safe(&self) -> bool {
        self.converged && self.min_distance_fine >= 1.0
    }
}

/// An SCP that produced no plan.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SwarmScpError {
    #[error("SCP iteration {iteration}: the QP ended {status}")]
    Qp { iteration: u32, status: String },
    #[error("SCP: {0}")]
    Input(String),
}

/// Accelerations [vehicle][step], m/s².
pub type Accels = Vec<Vec<[f64; 3]>>;

/// Column indices of vehicle `i`'s variables.
#[derive(Clone, Copy)]
struct Layout {
    k: usize,
}

impl Layout {
    fn per_vehicle(&self) -> usize {
        9 * self.k
    }
    /// p of node `node` (1…K), axis `c`.
    fn p(&self, i: usize, node: usize, c: usize) -> usize {
        i * self.per_vehicle() + 6 * (node - 1) + c
    }
    fn v(&self, i: usize, node: usize, c: usize) -> usize {
        self.p(i, node, c) + 3
    }
    /// a of step `step` (0…K−1).
    fn a(&self, i: usize, step: usize, c: usize) -> usize {
        i * self.per_vehicle() + 6 * self.k + 3 * step + c
    }
}

/// A constraint time: node `step` plus `tau` (0 or Δt/2) along the step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
struct When {
    half: usize,
}

impl When {
    fn step_tau(self) -> (usize, f64) {
        (self.half / 2, if self.half % 2 == 1 { 0.5 * DT_S } else { 0.0 })
    }
}

/// Position of vehicle `i` on axis `c` at `w` as (column, coefficient) terms plus a constant.
fn position_terms(l: Layout, start: [f64; 3], i: usize, w: When, c: usize) -> (Vec<(usize, f64)>, f64) {
    let (step, tau) = w.step_tau();
    let mut terms = Vec::with_capacity(3);
    let mut constant = 0.0;
    if step == 0 {
        constant = start[c]; // at rest at the start: v₀ = 0
    } else {
        terms.push((l.p(i, step, c), 1.0));
        if tau > 0.0 {
            terms.push((l.v(i, step, c), tau));
        }
    }
    if tau > 0.0 {
        terms.push((l.a(i, step, c), 0.5 * tau * tau));
    }
    (terms, constant)
}

/// Position of a trajectory (nodes p, v and steps a) at `w`.
fn position_at(p: &[[f64; 3]], v: &[[f64; 3]], a: &[[f64; 3]], w: When) -> [f64; 3] {
    let (step, tau) = w.step_tau();
    std::array::from_fn(|c| p[step][c] + v[step][c] * tau + 0.5 * a.get(step).map_or(0.0, |x| x[c]) * tau * tau)
}

/// One linearised constraint: pair (i, j) at `w`, nᵀ(pᵢ − pⱼ) ≥ r.
struct Cut {
    i: usize,
    j: usize,
    w: When,
    n: [f64; 3],
}

/// The constraint rows Ax + s = b of a subproblem, row by row (entries in any order).
#[derive(Default)]
struct Rows {
    rows: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    b: Vec<f64>,
}

impl Rows {
    /// An entry of the row being written.
    fn put(&mut self, col: usize, val: f64) {
        self.rows.push(self.b.len());
        self.cols.push(col);
        self.vals.push(val);
    }
    /// Close the row with its right-hand side.
    fn end(&mut self, rhs: f64) {
        self.b.push(rhs);
    }
}

/// p_{s+1} − p_s − Δt v_s − ½Δt² a_s = 0, v_{s+1} − v_s − Δt a_s = 0 (node 0 known: at rest at
/// the start), and node K at rest at the target.
fn dynamics_rows(r: &mut Rows, case: &SwarmCase, l: Layout) {
    for i in 0..case.n() {
        for s in 0..l.k {
            for c in 0..3 {
                r.put(l.p(i, s + 1, c), 1.0);
                r.put(l.a(i, s, c), -0.5 * DT_S * DT_S);
                if s > 0 {
                    r.put(l.p(i, s, c), -1.0);
                    r.put(l.v(i, s, c), -DT_S);
                }
                r.end(if s > 0 { 0.0 } else { case.starts_m[i][c] });
                r.put(l.v(i, s + 1, c), 1.0);
                r.put(l.a(i, s, c), -DT_S);
                if s > 0 {
                    r.put(l.v(i, s, c), -1.0);
                }
                r.end(0.0);
            }
        }
        for c in 0..3 {
            r.put(l.p(i, l.k, c), 1.0);
            r.end(case.goals_m[i][c]);
            r.put(l.v(i, l.k, c), 1.0);
            r.end(0.0);
        }
    }
}

/// ±a ≤ a_max.
fn box_rows(r: &mut Rows, n: usize, l: Layout) {
    for i in 0..n {
        for s in 0..l.k {
            for c in 0..3 {
                for sign in [1.0, -1.0] {
                    r.put(l.a(i, s, c), sign);
                    r.end(A_MAX_MPS2);
                }
            }
        }
    }
}

/// −nᵀ(pᵢ − pⱼ) ≤ −r per cut, the known parts moved to the right-hand side.
fn cut_rows(r: &mut Rows, case: &SwarmCase, l: Layout, cuts: &[Cut], margin: f64) {
    for cut in cuts {
        let mut rhs = -margin;
        for c in 0..3 {
            let (ti, ki) = position_terms(l, case.starts_m[cut.i], cut.i, cut.w, c);
            let (tj, kj) = position_terms(l, case.starts_m[cut.j], cut.j, cut.w, c);
            for (col, coef) in ti {
                r.put(col, -cut.n[c] * coef);
            }
            for (col, coef) in tj {
                r.put(col, cut.n[c] * coef);
            }
            rhs += cut.n[c] * (ki - kj);
        }
        r.end(rhs);
    }
}

/// Builds and solves one subproblem; returns the accelerations [vehicle][step] and Clarabel's
/// iterations.
fn solve_qp(case: &SwarmCase, cuts: &[Cut], margin: f64, iteration: u32) -> Result<(Accels, u32), SwarmScpError> {
    let (n, k) = (case.n(), STEPS);
    let l = Layout { k };
    let nv = n * l.per_vehicle();
    let mut r = Rows::default();
    dynamics_rows(&mut r, case, l);
    let n_eq = r.b.len();
    box_rows(&mut r, n, l);
    cut_rows(&mut r, case, l, cuts, margin);
    let m = r.b.len();
    let a_mat = CscMatrix::new_from_triplets(m, nv, r.rows, r.cols, r.vals);
    // ½xᵀPx = Σ ‖a‖² Δt on the acceleration columns.
    let diag: Vec<usize> = (0..n).flat_map(|i| (0..3 * k).map(move |j| l.a(i, 0, 0) + j)).collect();
    let p_mat = CscMatrix::new_from_triplets(nv, nv, diag.clone(), diag.clone(), vec![2.0 * DT_S; diag.len()]);
    let cones: [SupportedConeT<f64>; 2] = [ZeroConeT(n_eq), NonnegativeConeT(m - n_eq)];
    let settings = DefaultSettings { verbose: false, max_iter: 200, ..DefaultSettings::default() };
    let mut solver = DefaultSolver::new(&p_mat, &vec![0.0; nv], &a_mat, &r.b, &cones, settings)
        .map_err(|e| SwarmScpError::Qp { iteration, status: format!("unbuildable ({e:?})") })?;
    solver.solve();
    let sol = &solver.solution;
    if !matches!(sol.status, SolverStatus::Solved | SolverStatus::AlmostSolved) || sol.x.iter().any(|x| !x.is_finite())
    {
        return Err(SwarmScpError::Qp { iteration, status: format!("{:?}", sol.status) });
    }
    let a = (0..n)
        .map(|i| (0..k).map(|s| std::array::from_fn(|c| sol.x[l.a(i, s, c)].clamp(-A_MAX_MPS2, A_MAX_MPS2))).collect())
        .collect();
    Ok((a, sol.iterations))
}

/// Exact roll-out from rest at `start`: nodes p, v.
pub fn roll_out(start: [f64; 3], a: &[[f64; 3]]) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (mut p, mut v) = (vec![start], vec![[0.0; 3]]);
    for ak in a {
        let (pk, vk) = (*p.last().expect("node 0"), *v.last().expect("node 0"));
        p.push(std::array::from_fn(|c| pk[c] + vk[c] * DT_S + 0.5 * ak[c] * DT_S * DT_S));
        v.push(std::array::from_fn(|c| vk[c] + ak[c] * DT_S));
    }
    (p, v)
}

/// The smallest pairwise ellipsoid distance at `substeps` points per step of the trajectories
/// (node K included).
pub fn min_distance_fine(p: &[Vec<[f64; 3]>], v: &[Vec<[f64; 3]>], a: &[Vec<[f64; 3]>], substeps: usize) -> f64 {
    let mut best = f64::INFINITY;
    let k = a.first().map_or(0, |x| x.len());
    for s in 0..=k {
        for m in 0..if s == k { 1 } else { substeps } {
            let tau = DT_S * m as f64 / substeps as f64;
            let at = |i: usize| -> [f64; 3] {
                std::array::from_fn(|c| {
                    p[i][s][c] + v[i][s][c] * tau + 0.5 * a[i].get(s).map_or(0.0, |x| x[c]) * tau * tau
                })
            };
            let pts: Vec<[f64; 3]> = (0..p.len()).map(at).collect();
            for i in 0..pts.len() {
                for j in i + 1..pts.len() {
                    best = best.min(ellipsoid_distance(pts[i], pts[j]));
                }
            }
        }
    }
    best
}

/// Vehicle i's symmetry-breaking bump at time `t_s`: BUMP_M sin(πt/T) along the horizontal
/// direction at i × the golden angle.
fn bump(i: usize, t_s: f64) -> [f64; 3] {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (sn, cs) = (golden * i as f64).sin_cos();
    let h = BUMP_M * (std::f64::consts::PI * t_s / T_S).sin();
    [h * cs, h * sn, 0.0]
}

/// Solve the case.
pub fn solve(case: &SwarmCase, settings: &SwarmScpSettings) -> Result<SwarmPlan, SwarmScpError> {
    if case.n() == 0 || case.goals_m.len() != case.n() {
        return Err(SwarmScpError::Input("as many targets as starts, at least one".into()));
    }
    let started = Instant::now();
    let (n, k) = (case.n(), STEPS);
    let times: Vec<When> = (1..2 * k).map(|half| When { half }).collect();
    let mut active: BTreeSet<(usize, usize, When)> = BTreeSet::new();
    let (mut a, mut qp_iterations) = solve_qp(case, &[], settings.margin, 0)?;
    let (mut iterations, mut converged, mut n_cuts) = (1, false, 0);
    let mut cost = energy(&a);
    let mut change = f64::INFINITY;
    loop {
        let first = iterations == 1;
        let (p, v): (Vec<_>, Vec<_>) = (0..n).map(|i| roll_out(case.starts_m[i], &a[i])).unzip();
        let plain = |i: usize, w: When| position_at(&p[i], &v[i], &a[i], w);
        // The linearisation point: the iterate, bumped the first time.
        let lin = |i: usize, w: When| {
            let q = plain(i, w);
            if !first {
                return q;
            }
            let h = bump(i, w.half as f64 * 0.5 * DT_S);
            std::array::from_fn(|c| q[c] + h[c])
        };
        let before = active.len();
        for &w in &times {
            for i in 0..n {
                for j in i + 1..n {
                    let near = ellipsoid_distance(lin(i, w), lin(j, w)) < settings.near
                        || ellipsoid_distance(plain(i, w), plain(j, w)) < settings.near;
                    if near {
                        active.insert((i, j, w));
                    }
                }
            }
        }
        let grew = active.len() != before;
        if active.is_empty() || (!first && !grew && change < settings.tol_rel) {
            converged = true;
            break;
        }
        if iterations >= settings.max_iter {
            break;
        }
        let cuts: Vec<Cut> =
            active.iter().map(|&(i, j, w)| Cut { i, j, w, n: normal(lin(i, w), lin(j, w), i, j) }).collect();
        n_cuts = cuts.len();
        let (a_new, it) = solve_qp(case, &cuts, settings.margin, iterations)?;
        qp_iterations += it;
        iterations += 1;
        let new_cost = energy(&a_new);
        change = (new_cost - cost).abs() / cost.max(1e-12);
        (a, cost) = (a_new, new_cost);
    }
    let (p, v): (Vec<_>, Vec<_>) = (0..n).map(|i| roll_out(case.starts_m[i], &a[i])).unzip();
    let min_distance_fine = min_distance_fine(&p, &v, &a, FINE_SUBSTEPS);
    let terminal_error_m = (0..n)
        .map(|i| (0..3).map(|c| (p[i][k][c] - case.goals_m[i][c]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    let effort_l1 = a.iter().flatten().map(|x| norm(*x) * DT_S).sum();
    Ok(SwarmPlan {
        p_m: p,
        v_mps: v,
        energy: cost,
        a_mps2: a,
        iterations,
        qp_iterations,
        converged,
        constraints: n_cuts,
        solve_s: started.elapsed().as_secs_f64(),
        effort_l1,
        min_distance_fine,
        terminal_error_m,
    })
}

/// n = E⁻²Δp̄/‖E⁻¹Δp̄‖ for Δp̄ = pᵢ − pⱼ; a fixed horizontal direction (by the pair) if the two
/// points coincide.
fn normal(pi: [f64; 3], pj: [f64; 3], i: usize, j: usize) -> [f64; 3] {
    let d = ellipsoid_distance(pi, pj);
    if d < 1e-9 {
        let ang = (i * 7 + j * 13) as f64;
        return [ang.cos() / ELLIPSOID_M[0], ang.sin() / ELLIPSOID_M[1], 0.0];
    }
    std::array::from_fn(|c| (pi[c] - pj[c]) / (ELLIPSOID_M[c] * ELLIPSOID_M[c] * d))
}

/// Σ ‖a‖² Δt.
fn energy(a: &[Vec<[f64; 3]>]) -> f64 {
    a.iter().flatten().map(|x| norm(*x).powi(2) * DT_S).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_two_vehicle_head_on_swap_is_solved_collision_free() {
        let (l, r) = ([-1.0, 0.0, 1.2], [1.0, 0.0, 1.2]);
        let case = SwarmCase { starts_m: vec![l, r], goals_m: vec![r, l] };
        let plan = solve(&case, &SwarmScpSettings::default()).unwrap();
        assert!(plan.converged, "{} iterations", plan.iterations);
        assert!(plan.min_distance_fine >= 1.0, "min ellipsoid distance {}", plan.min_distance_fine);
        assert!(plan.is_safe());
        assert!(plan.terminal_error_m < 1e-5, "terminal error {}", plan.terminal_error_m);
        assert!(plan.v_mps.iter().all(|v| norm(v[STEPS]) < 1e-5), "not at rest at the end");
        assert!(plan.a_mps2.iter().flatten().flatten().all(|x| x.abs() <= A_MAX_MPS2));
        // The straight swap collides, so avoiding costs more than the unconstrained 2 × 12d²/T³.
        let free = 2.0 * 12.0 * 4.0 / T_S.powi(3);
        assert!(plan.energy > free, "{} vs {free}", plan.energy);
        assert!(plan.constraints > 0);
    }

    #[test]
    fn a_single_vehicle_flies_the_analytic_minimum_energy_solution() {
        let (s, g) = ([-1.5, 0.3, 0.8], [1.0, -0.7, 1.9]);
        let plan = solve(&SwarmCase { starts_m: vec![s], goals_m: vec![g] }, &SwarmScpSettings::default()).unwrap();
        assert_eq!((plan.iterations, plan.constraints), (1, 0));
        assert!(plan.converged && plan.min_distance_fine.is_infinite());
        // Per axis: min Σ a_j² s.t. Σ m_j a_j = d (m_j = (K − j − ½)Δt²) and Σ Δt a_j = 0, so
        // a_j = λ m_j + μ Δt with [λ, μ] from the 2 × 2 Gram system.
        let k = STEPS;
        let m: Vec<f64> = (0..k).map(|j| (k as f64 - j as f64 - 0.5) * DT_S * DT_S).collect();
        let (mm, mh, hh) = (m.iter().map(|x| x * x).sum::<f64>(), m.iter().sum::<f64>() * DT_S, k as f64 * DT_S * DT_S);
        let det = mm * hh - mh * mh;
        for c in 0..3 {
            let d = g[c] - s[c];
            let (lam, mu) = (hh * d / det, -mh * d / det);
            for j in 0..k {
                let want = lam * m[j] + mu * DT_S;
                assert!(
                    (plan.a_mps2[0][j][c] - want).abs() < 1e-6,
                    "axis {c} step {j}: {} vs {want}",
                    plan.a_mps2[0][j][c]
                );
                // And the continuous law 6d/T²(1 − 2t/T) at the step's middle, to O(Δt²).
                let t = (j as f64 + 0.5) * DT_S;
                let cont = 6.0 * d / (T_S * T_S) * (1.0 - 2.0 * t / T_S);
                assert!((want - cont).abs() < 1e-3 * d.abs().max(1.0), "{want} vs continuous {cont}");
            }
        }
        assert!(plan.terminal_error_m < 1e-6);
    }

    #[test]
    fn the_fine_check_sees_a_crossing_between_nodes() {
        // Two vehicles swapping x in one step at 2.4 m/s relative: the nodes are 0.24 m apart (2 in
        // the ellipsoid distance) on either side, the arc between them passes through the other.
        let p = vec![vec![[-0.12, 0.0, 1.0], [0.12, 0.0, 1.0]], vec![[0.12, 0.0, 1.0], [-0.12, 0.0, 1.0]]];
        let v = vec![vec![[2.4, 0.0, 0.0], [2.4, 0.0, 0.0]], vec![[-2.4, 0.0, 0.0], [-2.4, 0.0, 0.0]]];
        let a = vec![vec![[0.0; 3]], vec![[0.0; 3]]];
        assert!(min_distance_fine(&p, &v, &a, 1) >= 1.0, "the nodes alone look safe");
        assert!(min_distance_fine(&p, &v, &a, FINE_SUBSTEPS) < 0.1);
    }
}
