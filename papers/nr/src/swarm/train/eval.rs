//! In-process evaluation of a swarm policy alone (Sec. 7.2 of "Neural-Rendezvous",
//! arXiv:2208.04883), against the global solution of the same case: no processes, no noise, no
//! disturbance — only what the learned policy does with exact local observations.
//!
//! The closed loop ([`closed_loop`]): every vehicle observes the swarm's exact state through
//! [`SwarmObservation::local`] (nearest ≤ 6 within R_comm), its policy gives the acceleration,
//! clipped to ±a_max per axis and held over the step; the double integrator is propagated exactly
//! (the model of [`crate::swarm::train::problem`]) for T + 2 s. Collisions are checked on the quadratic
//! arcs at [`FINE_SUBSTEPS`] points per step (the plant's rate); a pair counts once however long
//! it stays in collision. ∫‖u‖dt sums Σₖ ‖aₖ‖Δt over the vehicles and the whole run (the SCP's
//! is over T; it is zero after). The per-step compute time is the wall time of one vehicle's
//! policy call (observation included), averaged over the run.

use std::collections::BTreeSet;
use std::time::Instant;

use crate::swarm::control::obs::{SwarmObservation, SwarmPolicy};
use crate::swarm::train::problem::{A_MAX_MPS2, DT_S, R_COMM_M, STEPS, SwarmCase, ellipsoid_distance, t_to_go_s};
use crate::swarm::train::scp::{self as swarm_scp, FINE_SUBSTEPS, SwarmScpSettings};

/// Steps of T + 2 s.
pub const EVAL_STEPS: usize = STEPS + 20;

/// What one closed-loop run gave.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoop {
    /// Distinct pairs that were ever in collision.
    pub collisions: usize,
    /// Least pairwise ellipsoid distance on the fine grid.
    pub min_distance: f64,
    /// Largest ‖p − g‖ at the end, m.
    pub final_goal_error_m: f64,
    /// ∫‖u‖dt summed over the vehicles, m/s.
    pub effort_l1: f64,
    /// Mean wall time of one vehicle's observation and policy call, s.
    pub step_s: f64,
}

/// Run `policy` on every vehicle of `case` for `steps` steps from rest at the starts.
pub fn closed_loop(policy: &dyn SwarmPolicy, case: &SwarmCase, steps: usize) -> ClosedLoop {
    let n = case.n();
    let (mut p, mut v) = (case.starts_m.clone(), vec![[0.0; 3]; n]);
    let mut colliding = BTreeSet::new();
    let (mut min_distance, mut effort_l1, mut busy_s) = (f64::INFINITY, 0.0, 0.0);
    for k in 0..=steps {
        let a: Vec<[f64; 3]> = if k < steps {
            let started = Instant::now();
            let a = (0..n)
                .map(|i| {
                    let others: Vec<_> = (0..n).filter(|&j| j != i).map(|j| (p[j], v[j])).collect();
                    let obs = SwarmObservation::local(p[i], v[i], case.goals_m[i], &others, R_COMM_M).at(t_to_go_s(k));
                    policy.accel_mps2(&obs).map(|x| x.clamp(-A_MAX_MPS2, A_MAX_MPS2))
                })
                .collect();
            busy_s += started.elapsed().as_secs_f64();
            a
        } else {
            vec![[0.0; 3]; n]
        };
        for m in 0..if k < steps { FINE_SUBSTEPS } else { 1 } {
            let tau = DT_S * m as f64 / FINE_SUBSTEPS as f64;
            let at =
                |i: usize| -> [f64; 3] { std::array::from_fn(|c| p[i][c] + v[i][c] * tau + 0.5 * a[i][c] * tau * tau) };
            let pts: Vec<[f64; 3]> = (0..n).map(at).collect();
            for i in 0..n {
                for j in i + 1..n {
                    let d = ellipsoid_distance(pts[i], pts[j]);
                    min_distance = min_distance.min(d);
                    if d < 1.0 {
                        colliding.insert((i, j));
                    }
                }
            }
        }
        if k == steps {
            break;
        }
        for i in 0..n {
            effort_l1 += (0..3).map(|c| a[i][c] * a[i][c]).sum::<f64>().sqrt() * DT_S;
            for c in 0..3 {
                p[i][c] += v[i][c] * DT_S + 0.5 * a[i][c] * DT_S * DT_S;
                v[i][c] += a[i][c] * DT_S;
            }
        }
    }
    let final_goal_error_m =
        (0..n).map(|i| (0..3).map(|c| (p[i][c] - case.goals_m[i][c]).powi(2)).sum::<f64>().sqrt()).fold(0.0, f64::max);
    ClosedLoop {
        collisions: colliding.len(),
        min_distance,
        final_goal_error_m,
        effort_l1,
        step_s: busy_s / (steps * n).max(1) as f64,
    }
}

/// One evaluated case: the policy's closed loop and the global solution of the same case.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalRow {
    pub label: String,
    pub n: usize,
    pub policy: ClosedLoop,
    /// The SCP's ∫‖u‖dt, solve time and whether it is collision-free (None: it failed).
    pub scp: Option<(f64, f64, bool)>,
}

/// Cases `eval0…` of `seed` with `n` vehicles (labels distinct from the training cases').
pub fn evaluate(policy: &dyn SwarmPolicy, seed: u64, n: usize, cases: usize) -> Result<Vec<EvalRow>, String> {
    (0..cases)
        .map(|c| {
            let label = format!("eval{c}");
            let case = SwarmCase::draw(seed, &label, n).map_err(|e| e.to_string())?;
            let scp = swarm_scp::solve(&case, &SwarmScpSettings::default())
                .ok()
                .map(|p| (p.effort_l1, p.solve_s, p.is_safe()));
            Ok(EvalRow { label, n, policy: closed_loop(policy, &case, EVAL_STEPS), scp })
        })
        .collect()
}

/// The rows as a markdown table plus a totals line.
pub fn markdown(rows: &[EvalRow]) -> String {
    let mut s = String::from(
        "| case | N | collisions (pairs) | min ellipsoid distance | max ‖p − g‖ at T + 2 s (m) | ∫‖u‖dt policy (m/s) | ∫‖u‖dt SCP (m/s) | ratio | policy step (µs) | SCP solve (s) | speed-up |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (se, st) = r.scp.map_or((f64::NAN, f64::NAN), |(e, t, _)| (e, t));
        let p = &r.policy;
        s += &format!(
            "| {} | {} | {} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.1} | {:.3} | {:.0} |\n",
            r.label,
            r.n,
            p.collisions,
            p.min_distance,
            p.final_goal_error_m,
            p.effort_l1,
            se,
            p.effort_l1 / se,
            p.step_s * 1e6,
            st,
            st / p.step_s
        );
    }
    let free = rows.iter().filter(|r| r.policy.collisions == 0).count();
    let reached = rows.iter().filter(|r| r.policy.final_goal_error_m <= 0.1).count();
    let ratio: Vec<f64> = rows.iter().filter_map(|r| r.scp.map(|(e, _, _)| r.policy.effort_l1 / e)).collect();
    s += &format!(
        "\n{} cases: {free} collision-free, {reached} with every vehicle within 0.1 m of its target at T + 2 s; \
         mean ∫‖u‖dt ratio policy/SCP {:.3}.\n",
        rows.len(),
        ratio.iter().sum::<f64>() / ratio.len().max(1) as f64
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PD to the goal that ignores the neighbours.
    struct ToGoal;
    impl SwarmPolicy for ToGoal {
        fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3] {
            std::array::from_fn(|c| 4.0 * obs.goal_offset_m[c] - 4.0 * obs.v_mps[c])
        }
    }

    #[test]
    fn the_closed_loop_counts_a_head_on_collision_and_reaches_the_goals() {
        let (l, r) = ([-1.0, 0.0, 1.2], [1.0, 0.0, 1.2]);
        let swap = SwarmCase { starts_m: vec![l, r], goals_m: vec![r, l] };
        let out = closed_loop(&ToGoal, &swap, EVAL_STEPS);
        assert_eq!(out.collisions, 1);
        assert!(out.min_distance < 0.2, "they pass through each other: {}", out.min_distance);
        assert!(out.final_goal_error_m < 0.05, "{}", out.final_goal_error_m);
        // Side by side moving in parallel: no collision, ∫‖u‖dt the same for both.
        let par = SwarmCase { starts_m: vec![l, [-1.0, 1.0, 1.2]], goals_m: vec![r, [1.0, 1.0, 1.2]] };
        let out2 = closed_loop(&ToGoal, &par, EVAL_STEPS);
        assert_eq!(out2.collisions, 0);
        assert!((out2.effort_l1 - out.effort_l1).abs() < 1e-9);
        assert!(out2.effort_l1 > 0.0 && out2.step_s > 0.0);
    }
}
