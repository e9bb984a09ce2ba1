//! An exact solver for the MPCs' box-constrained QP
//!
//! ```text
//! min ½xᵀPx + qᵀx   subject to   l ≤ x ≤ u,        P symmetric positive definite, fixed for the run,
//! ```
//!
//! by the primal–dual active-set method (Hintermüller, Ito, Kunisch, *The primal-dual active set
//! strategy as a semismooth Newton method*, SIAM J. Optim. 13 (2002)), warm-started from the
//! previous solve's active set. Not from the paper: the paper says "quadratic programming" and no
//! more; this is how we solve (25) fast enough for a 10 Hz loop (the measurements are in
//! `papers/tsnr/README.md`).
//!
//! **Iteration.** The variables are split into free (F), at their lower bound (L) and at their
//! upper bound (U). With x_L = l_L and x_U = u_U, the free ones solve P_FF x_F = −q_F − P_F,L∪U x_L∪U
//! (Cholesky of P_FF; of the whole P, factored once, when nothing is bound). Then g = Px + q is
//! the multiplier of each bound, and the sets are updated: a free variable below l (above u) goes
//! to L (U), a bound variable whose multiplier has the wrong sign (g < 0 at l, g > 0 at u) goes
//! free. When an update changes nothing, the KKT conditions hold — g_F = 0, l ≤ x_F ≤ u, g_L ≥ 0,
//! g_U ≤ 0 — and are checked once more explicitly before the solution is returned.
//!
//! **Tolerances.** A free variable goes to a bound only once it is beyond it by more than
//! `X_TOL` (relative), a bound one goes free only once its multiplier is wrong by more than
//! `G_TOL` (relative): without them, a variable exactly at a degenerate bound (g = 0) flips
//! between the sets on rounding alone. A free variable within the tolerance of its bound is
//! clipped to the bound in the answer (a change of at most 1e-12 relative).
//!
//! **Termination.** For a P that is not an M-matrix the method is not guaranteed to finish; it
//! reports [`Stalled`] after `max_iter` iterations (or on a numerically failed factorisation or
//! KKT check) and the caller falls back on an interior-point solve. Every operation is plain f64
//! arithmetic in a fixed order: the same problem gives the same bits on every run.

/// Which of its bounds a variable is held at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    Free,
    Lower,
    Upper,
}

/// The method did not reach a point satisfying the KKT conditions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stalled {
    pub iterations: u32,
}

/// Relative slack before a free variable counts as beyond a bound.
const X_TOL: f64 = 1e-12;
/// Relative slack before a bound variable's multiplier counts as of the wrong sign.
const G_TOL: f64 = 1e-12;
/// Relative slack of the final KKT check (rounding in g = Px + q is ~n·ε of its terms).
const KKT_TOL: f64 = 1e-9;

pub struct ActiveSet {
    n: usize,
    /// P, column-major (symmetric, so also row-major).
    p: Vec<f64>,
    /// Cholesky factor of the whole P, lower, row-major (the all-free case).
    l_full: Vec<f64>,
    sets: Vec<Bound>,
    next: Vec<Bound>,
    x: Vec<f64>,
    g: Vec<f64>,
    free: Vec<usize>,
    /// Scratch: P_FF and its factor (row-major, |F|×|F|), the right-hand side.
    l_ff: Vec<f64>,
    rhs: Vec<f64>,
}

impl ActiveSet {
    /// `p`: P, n×n column-major, symmetric positive definite. None if its Cholesky factorisation
    /// fails (not positive definite to working precision).
    pub fn new(p: Vec<f64>, n: usize) -> Option<Self> {
        assert_eq!(p.len(), n * n);
        let mut l_full = p.clone();
        if !cholesky_in_place(&mut l_full, n) {
            return None;
        }
        Some(Self {
            n,
            p,
            l_full,
            sets: vec![Bound::Free; n],
            next: vec![Bound::Free; n],
            x: vec![0.0; n],
            g: vec![0.0; n],
            free: Vec::with_capacity(n),
            l_ff: vec![0.0; n * n],
            rhs: vec![0.0; n],
        })
    }

    /// The solution of the last successful solve.
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// The active set the next solve starts from.
    pub fn warm_start(&self) -> &[Bound] {
        &self.sets
    }

    /// Move the warm start `by` variables forward (the next problem's variable i is this one's
    /// i + by), the last `by` entries repeated into the tail: for a receding horizon whose
    /// variables are `by` values per step.
    pub fn shift(&mut self, by: usize) {
        let n = self.n;
        if by == 0 || by >= n {
            return;
        }
        self.sets.copy_within(by.., 0);
        for i in n - by..n {
            self.sets[i] = self.sets[i - by];
        }
    }

    /// Forget the warm start (everything free).
    pub fn reset(&mut self) {
        self.sets.fill(Bound::Free);
    }

    /// Solve with linear term `q` and bounds `lo ≤ x ≤ hi` (lo ≤ hi). Ok(iterations): the
    /// solution is [`ActiveSet::x`] and the active set is kept as the next warm start.
    pub fn solve(&mut self, q: &[f64], lo: &[f64], hi: &[f64], max_iter: u32) -> Result<u32, Stalled> {
        let n = self.n;
        assert!(q.len() == n && lo.len() == n && hi.len() == n);
        for it in 1..=max_iter {
            if !self.solve_free(q, lo, hi) {
                self.reset();
                return Err(Stalled { iterations: it });
            }
            self.multipliers(q);
            if !self.update_sets(lo, hi) {
                for i in 0..n {
                    self.x[i] = self.x[i].clamp(lo[i], hi[i]);
                }
                self.multipliers(q);
                if self.kkt_holds(q, lo, hi) {
                    return Ok(it);
                }
                self.reset();
                return Err(Stalled { iterations: it });
            }
        }
        self.reset();
        Err(Stalled { iterations: max_iter })
    }

    /// x with the bound variables at their bounds and the free ones solving P_FF x_F = −q_F −
    /// P_F,B x_B. False if the factorisation failed.
    fn solve_free(&mut self, q: &[f64], lo: &[f64], hi: &[f64]) -> bool {
        let n = self.n;
        self.free.clear();
        for i in 0..n {
            match self.sets[i] {
                Bound::Free => self.free.push(i),
                Bound::Lower => self.x[i] = lo[i],
                Bound::Upper => self.x[i] = hi[i],
            }
        }
        let k = self.free.len();
        if k == 0 {
            return true;
        }
        // rhs_F = −q_F − Σ_{j bound} P_Fj x_j
        for (a, &i) in self.free.iter().enumerate() {
            let mut r = -q[i];
            for j in 0..n {
                if self.sets[j] != Bound::Free {
                    r -= self.p[j * n + i] * self.x[j];
                }
            }
            self.rhs[a] = r;
        }
        let l: &[f64] = if k == n {
            &self.l_full
        } else {
            for (a, &i) in self.free.iter().enumerate() {
                for (b, &j) in self.free.iter().enumerate() {
                    self.l_ff[a * k + b] = self.p[j * n + i];
                }
            }
            if !cholesky_in_place(&mut self.l_ff[..k * k], k) {
                return false;
            }
            &self.l_ff[..k * k]
        };
        cholesky_solve(l, k, &mut self.rhs[..k]);
        for (a, &i) in self.free.iter().enumerate() {
            self.x[i] = self.rhs[a];
        }
        self.x.iter().all(|x| x.is_finite())
    }

    /// g = Px + q.
    fn multipliers(&mut self, q: &[f64]) {
        let n = self.n;
        for i in 0..n {
            let row = &self.p[i * n..(i + 1) * n];
            self.g[i] = q[i] + dot(row, &self.x);
        }
    }

    /// The next active set from x and g; true if it differs from the current one (which it
    /// then replaces).
    fn update_sets(&mut self, lo: &[f64], hi: &[f64]) -> bool {
        let g_tol = G_TOL * self.g_scale();
        for i in 0..self.n {
            let x_tol = X_TOL * (1.0 + lo[i].abs().max(hi[i].abs()));
            self.next[i] = match self.sets[i] {
                Bound::Free if self.x[i] < lo[i] - x_tol => Bound::Lower,
                Bound::Free if self.x[i] > hi[i] + x_tol => Bound::Upper,
                Bound::Lower if self.g[i] < -g_tol => Bound::Free,
                Bound::Upper if self.g[i] > g_tol => Bound::Free,
                s => s,
            };
        }
        let changed = self.next != self.sets;
        std::mem::swap(&mut self.sets, &mut self.next);
        changed
    }

    /// The size of the terms of g = Px + q, for relative tolerances on it.
    fn g_scale(&self) -> f64 {
        let n = self.n;
        let mut s: f64 = 1e-300;
        for i in 0..n {
            let row = &self.p[i * n..(i + 1) * n];
            let t: f64 = row.iter().zip(&self.x).map(|(p, x)| (p * x).abs()).sum();
            s = s.max(t);
        }
        s.max(self.g.iter().fold(0.0, |m, g| m.max(g.abs())))
    }

    /// The KKT conditions of the clipped x, to `KKT_TOL` relative.
    fn kkt_holds(&self, q: &[f64], lo: &[f64], hi: &[f64]) -> bool {
        let tol = KKT_TOL * self.g_scale().max(q.iter().fold(0.0, |m: f64, x| m.max(x.abs())));
        (0..self.n).all(|i| {
            let (x, g) = (self.x[i], self.g[i]);
            let at_lo = x <= lo[i];
            let at_hi = x >= hi[i];
            // Free: stationary. At a bound: the multiplier pushes into the box (or is zero).
            (g.abs() <= tol) || (at_lo && g >= -tol) || (at_hi && g <= tol)
        })
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Cholesky A = LLᵀ of the k×k row-major symmetric `a` in place, row by row (the lower triangle
/// becomes L; the upper is not read). False if A is not positive definite to working precision.
fn cholesky_in_place(a: &mut [f64], k: usize) -> bool {
    for i in 0..k {
        let (done, rest) = a.split_at_mut(i * k);
        let row_i = &mut rest[..k];
        for j in 0..i {
            let row_j = &done[j * k..j * k + k];
            row_i[j] = (row_i[j] - dot(&row_i[..j], &row_j[..j])) / row_j[j];
        }
        let d = row_i[i] - dot(&row_i[..i], &row_i[..i]);
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        row_i[i] = d.sqrt();
    }
    true
}

/// Solve LLᵀx = b in place (`l` row-major lower k×k from [`cholesky_in_place`]).
fn cholesky_solve(l: &[f64], k: usize, b: &mut [f64]) {
    for i in 0..k {
        let s = b[i] - dot(&l[i * k..i * k + i], &b[..i]);
        b[i] = s / l[i * k + i];
    }
    for i in (0..k).rev() {
        let mut s = b[i];
        for m in i + 1..k {
            s -= l[m * k + i] * b[m];
        }
        b[i] = s / l[i * k + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// P = tridiag(−1, 4, −1) + 0.5 everywhere (SPD, dense, not an M-matrix), n×n column-major.
    fn p_dense(n: usize) -> Vec<f64> {
        (0..n * n)
            .map(|idx| {
                let (i, j) = (idx % n, idx / n);
                0.5 + if i == j {
                    4.0
                } else if i.abs_diff(j) == 1 {
                    -1.0
                } else {
                    0.0
                }
            })
            .collect()
    }

    fn kkt_residual(p: &[f64], n: usize, q: &[f64], lo: &[f64], hi: &[f64], x: &[f64]) -> f64 {
        let mut worst: f64 = 0.0;
        for i in 0..n {
            let g = q[i] + (0..n).map(|j| p[j * n + i] * x[j]).sum::<f64>();
            assert!(x[i] >= lo[i] && x[i] <= hi[i], "x[{i}] = {} outside [{}, {}]", x[i], lo[i], hi[i]);
            let r = if x[i] == lo[i] {
                (-g).max(0.0)
            } else if x[i] == hi[i] {
                g.max(0.0)
            } else {
                g.abs()
            };
            worst = worst.max(r);
        }
        worst
    }

    #[test]
    fn the_solution_satisfies_the_kkt_conditions_with_bounds_on_both_sides() {
        let n = 12;
        let p = p_dense(n);
        let mut s = ActiveSet::new(p.clone(), n).unwrap();
        let q: Vec<f64> = (0..n).map(|i| 10.0 * ((i as f64) * 1.7).sin()).collect();
        let lo = vec![-1.0; n];
        let hi = vec![1.5; n];
        let iters = s.solve(&q, &lo, &hi, 50).unwrap();
        let x = s.x().to_vec();
        assert!(kkt_residual(&p, n, &q, &lo, &hi, &x) < 1e-12, "{x:?}");
        assert!(x.contains(&-1.0) && x.contains(&1.5), "both bounds active: {x:?}");
        assert!(iters >= 2, "a cold start needs at least one change of the set");
        // Warm-started from its own answer, the same problem takes one iteration and gives the
        // same bits.
        assert_eq!(s.solve(&q, &lo, &hi, 50), Ok(1));
        assert_eq!(s.x(), x.as_slice());
    }

    #[test]
    fn without_active_bounds_it_is_the_unconstrained_minimum() {
        let n = 5;
        let p = p_dense(n);
        let mut s = ActiveSet::new(p.clone(), n).unwrap();
        let q = vec![1.0, -2.0, 0.5, 0.0, 3.0];
        assert_eq!(s.solve(&q, &vec![-100.0; n], &vec![100.0; n], 10), Ok(1));
        for i in 0..n {
            let g = q[i] + (0..n).map(|j| p[j * n + i] * s.x()[j]).sum::<f64>();
            assert!(g.abs() < 1e-14, "gradient {g} at {i}");
        }
    }

    #[test]
    fn the_warm_start_moves_on_by_one_step_and_holds_the_tail() {
        let mut s = ActiveSet::new(p_dense(6), 6).unwrap();
        s.sets = vec![Bound::Lower, Bound::Upper, Bound::Free, Bound::Free, Bound::Upper, Bound::Lower];
        s.shift(2);
        assert_eq!(s.warm_start(), [Bound::Free, Bound::Free, Bound::Upper, Bound::Lower, Bound::Upper, Bound::Lower]);
        s.reset();
        assert!(s.warm_start().iter().all(|b| *b == Bound::Free));
    }

    #[test]
    fn too_few_iterations_stall_and_a_singular_p_is_refused() {
        let n = 12;
        let mut s = ActiveSet::new(p_dense(n), n).unwrap();
        let q: Vec<f64> = (0..n).map(|i| 10.0 * ((i as f64) * 1.7).sin()).collect();
        assert_eq!(s.solve(&q, &vec![-1.0; n], &vec![1.5; n], 1), Err(Stalled { iterations: 1 }));
        // A stall forgets the warm start.
        assert!(s.warm_start().iter().all(|b| *b == Bound::Free));
        assert!(ActiveSet::new(vec![1.0, 1.0, 1.0, 1.0], 2).is_none(), "rank 1");
    }
}
