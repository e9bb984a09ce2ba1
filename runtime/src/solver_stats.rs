//! What an algorithm that solves an optimisation problem every step reports about its solver:
//! how many solves converged, failed or were infeasible, and how long they took.
//!
//! Solve times are wall-clock and differ between runs, so they never go into telemetry (which
//! must be bit-identical across run modes); [`crate::model::Algorithm::solver_stats`] hands them
//! to the driver, which puts them in the process's end-of-run report.

use serde::{Deserialize, Serialize};

/// End-of-run solver summary (in `status/<agent>.json` and `summary.json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SolverStats {
    /// Which solver and problem, e.g. "clarabel qp (60 vars, 120 rows)".
    pub solver: String,
    pub solves: u64,
    /// Solved to the requested accuracy.
    pub solved: u64,
    /// Ended without a solution: iteration limit, reduced accuracy only, numerical trouble.
    pub not_converged: u64,
    /// A certificate of primal or dual infeasibility.
    pub infeasible: u64,
    pub iterations_max: u64,
    pub iterations_mean: f64,
    /// Solve wall time, s: percentiles from a log-spaced histogram (bins 1 % wide, the upper
    /// edge reported, capped at the largest time seen) and the exact maximum.
    pub solve_time_p50_s: f64,
    pub solve_time_p99_s: f64,
    pub solve_time_max_s: f64,
    pub solve_time_total_s: f64,
}

/// Outcome of one solve, as counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveOutcome {
    Solved,
    NotConverged,
    Infeasible,
}

/// Accumulates solves in constant memory (a run may have 10⁹ steps).
#[derive(Debug, Clone)]
pub struct SolveLog {
    solver: String,
    stats: SolverStats,
    iterations_sum: u64,
    bins: Vec<u64>,
}

/// Histogram range and resolution: 10⁻⁹ s … 10³ s, bins a factor 1.01 apart.
const T_MIN_S: f64 = 1e-9;
const RATIO: f64 = 1.01;
const N_BINS: usize = 2778; // ln(1e12) / ln(1.01) ≈ 2777.1

impl SolveLog {
    pub fn new(solver: impl Into<String>) -> Self {
        Self { solver: solver.into(), stats: SolverStats::default(), iterations_sum: 0, bins: vec![0; N_BINS] }
    }

    pub fn record(&mut self, outcome: SolveOutcome, iterations: u64, wall_s: f64) {
        let s = &mut self.stats;
        s.solves += 1;
        match outcome {
            SolveOutcome::Solved => s.solved += 1,
            SolveOutcome::NotConverged => s.not_converged += 1,
            SolveOutcome::Infeasible => s.infeasible += 1,
        }
        s.iterations_max = s.iterations_max.max(iterations);
        self.iterations_sum += iterations;
        let t = if wall_s.is_finite() { wall_s.max(0.0) } else { 0.0 };
        s.solve_time_max_s = s.solve_time_max_s.max(t);
        s.solve_time_total_s += t;
        self.bins[bin(t)] += 1;
    }

    pub fn stats(&self) -> SolverStats {
        let mut s = self.stats.clone();
        s.solver = self.solver.clone();
        if s.solves > 0 {
            s.iterations_mean = self.iterations_sum as f64 / s.solves as f64;
            s.solve_time_p50_s = self.percentile(0.50);
            s.solve_time_p99_s = self.percentile(0.99);
        }
        s
    }

    /// The upper edge of the bin holding the q-quantile, capped at the maximum seen.
    fn percentile(&self, q: f64) -> f64 {
        let rank = ((q * self.stats.solves as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, n) in self.bins.iter().enumerate() {
            seen += n;
            if seen >= rank {
                return (T_MIN_S * RATIO.powi(i as i32 + 1)).min(self.stats.solve_time_max_s);
            }
        }
        self.stats.solve_time_max_s
    }
}

fn bin(t: f64) -> usize {
    if t <= T_MIN_S {
        return 0;
    }
    (((t / T_MIN_S).ln() / RATIO.ln()) as usize).min(N_BINS - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_within_the_bin_resolution_and_counts_by_outcome() {
        let mut log = SolveLog::new("test");
        // 1..=1000 µs: p50 = 500 µs, p99 = 990 µs, max 1000 µs.
        for k in 1..=1000u64 {
            let outcome = match k % 100 {
                0 => SolveOutcome::Infeasible,
                1 | 2 => SolveOutcome::NotConverged,
                _ => SolveOutcome::Solved,
            };
            log.record(outcome, k % 17, k as f64 * 1e-6);
        }
        let s = log.stats();
        assert_eq!((s.solves, s.solved, s.not_converged, s.infeasible), (1000, 970, 20, 10));
        assert_eq!(s.iterations_max, 16);
        assert!((s.solve_time_p50_s / 500e-6 - 1.0).abs() < 0.011, "{}", s.solve_time_p50_s);
        assert!((s.solve_time_p99_s / 990e-6 - 1.0).abs() < 0.011, "{}", s.solve_time_p99_s);
        assert_eq!(s.solve_time_max_s, 1000e-6);
        assert!((s.solve_time_total_s - 500500e-6).abs() < 1e-12);
    }

    #[test]
    fn extreme_times_land_in_the_end_bins() {
        let mut log = SolveLog::new("test");
        log.record(SolveOutcome::Solved, 1, 0.0);
        log.record(SolveOutcome::Solved, 1, 1e6);
        log.record(SolveOutcome::Solved, 1, f64::NAN);
        let s = log.stats();
        assert_eq!(s.solves, 3);
        assert_eq!(s.solve_time_max_s, 1e6);
        assert!(s.solve_time_p50_s <= 2e-9);
    }
}
