//! What one run of a case measured, from its summary and its timing files.

use std::path::Path;

use cohort_runtime::paper::Setup;

use super::types::{Sample, median};
use crate::summary::Summary;

/// One column of a process's timing file (Parquet or CSV), as f64.
fn timing_column(dir: &Path, process: &str, col: &str) -> Vec<f64> {
    cohort_runtime::record::timing_column(&dir.join("timing"), process, col).into_iter().map(|v| v as f64).collect()
}

pub(super) fn sample(s: &Setup, dir: &Path, summary: &Summary, wall_s: f64) -> Sample {
    let round = summary.latency_ns.get("plant_round");
    let steps = summary.steps_completed.max(1);
    let per_k = |cpu: f64| cpu / steps as f64 * 1000.0;
    let mut agent_cpu: Vec<f64> = Vec::new();
    let mut agent_rss: Vec<f64> = Vec::new();
    let mut agent_share: Vec<f64> = Vec::new();
    let mut plant_cpu = f64::NAN;
    let mut plant_rss = f64::NAN;
    let mut agent_pss: Vec<f64> = Vec::new();
    let mut plant_pss = f64::NAN;
    let mb = |kb: u64| kb as f64 / 1024.0;
    let (mut solver_p50, mut solver_p99, mut solver_max): (Vec<f64>, Vec<f64>, Vec<f64>) = Default::default();
    for st in summary.processes.iter().filter_map(|p| p.solver.as_ref()).filter(|st| st.solves > 0) {
        solver_p50.push(st.solve_time_p50_s * 1e6);
        solver_p99.push(st.solve_time_p99_s * 1e6);
        solver_max.push(st.solve_time_max_s * 1e6);
    }
    let largest = |xs: &[f64]| xs.iter().copied().reduce(f64::max);
    let mut wait = cohort_runtime::record::WaitStats::default();
    for p in &summary.processes {
        wait.waits += p.wait.waits;
        wait.spun += p.wait.spun;
        wait.spin_stalls += p.wait.spin_stalls;
        wait.spin_expired += p.wait.spin_expired;
        wait.spin_s += p.wait.spin_s;
        wait.chose_spin += p.wait.chose_spin;
        wait.chose_block += p.wait.chose_block;
        wait.advised += p.wait.advised;
        if p.process == "plant" {
            // The plant's trial is the one its host follows (and the one-host runs' all).
            wait.trial_block_step_us = p.wait.trial_block_step_us;
            wait.trial_spin_step_us = p.wait.trial_spin_step_us;
            plant_cpu = per_k(p.cpu_s);
            plant_rss = mb(p.max_rss_kb);
            plant_pss = mb(p.pss_kb);
        } else {
            agent_cpu.push(per_k(p.cpu_s));
            agent_rss.push(mb(p.max_rss_kb));
            agent_pss.push(mb(p.pss_kb));
            if p.wall_s > 0.0 {
                agent_share.push(p.cpu_s / p.wall_s);
            }
        }
    }
    // Compute share of the round: agent compute (median agent) over plant round, per step.
    let rounds = timing_column(dir, "plant", "round_ns");
    let compute = timing_column(dir, "agent-1", "compute_ns");
    let compute_share = (!rounds.is_empty() && rounds.len() == compute.len()).then(|| {
        let mut r: Vec<f64> = compute.iter().zip(&rounds).map(|(c, r)| c / r.max(1.0)).collect();
        median(&mut r)
    });
    let agent_compute_us = first_agents_median_us(s, dir, "compute_ns", 0);
    let (meas_latency_us, share_latency_max_us) = legs_us(s, dir);
    Sample {
        wall_s,
        steps: summary.steps_completed,
        steps_per_s: summary.steps_per_s,
        round_p50_us: round.map_or(f64::NAN, |p| p.p50 as f64 / 1e3),
        round_p99_us: round.map_or(f64::NAN, |p| p.p99 as f64 / 1e3),
        round_max_ms: round.map_or(f64::NAN, |p| p.max as f64 / 1e6),
        startup_s: summary.startup_s,
        agent_cpu_s_per_1000_steps: median(&mut agent_cpu),
        plant_cpu_s_per_1000_steps: plant_cpu,
        agent_cpu_share: median(&mut agent_share),
        agent_rss_mb: median(&mut agent_rss),
        plant_rss_mb: plant_rss,
        agent_pss_mb: median(&mut agent_pss),
        plant_pss_mb: plant_pss,
        total_pss_mb: summary.pss_total_kb.map_or(f64::NAN, mb),
        compute_share,
        solver_p50_us: (!solver_p50.is_empty()).then(|| median(&mut solver_p50)),
        solver_p99_us: largest(&solver_p99),
        solver_max_us: largest(&solver_max),
        wait,
        agent_compute_us,
        meas_latency_us,
        share_latency_max_us,
    }
}

/// Steps left out of the one-way legs: the first ones, whose measurements wake agents one by one
/// from their start-up wait (the trial's steps stay in: both ways of waiting are the run's).
const LEGS_FROM_STEP: usize = 8;

/// The step's two one-way legs, µs ([`Sample::meas_latency_us`], [`Sample::share_latency_max_us`]).
fn legs_us(s: &Setup, dir: &Path) -> (Option<f64>, Option<f64>) {
    let meas = first_agents_median_us(s, dir, "meas_latency_ns", LEGS_FROM_STEP);
    (meas, median_us_after(timing_column(dir, "plant", "share_latency_max_ns"), LEGS_FROM_STEP))
}

/// The median, µs, of the first eight agents' medians of timing column `col` (ns), each from
/// step `from` on; none when no agent has steps past it.
fn first_agents_median_us(s: &Setup, dir: &Path, col: &str, from: usize) -> Option<f64> {
    let mut each: Vec<f64> = (1..=s.n_agents().min(8))
        .filter_map(|i| median_us_after(timing_column(dir, &format!("agent-{i}"), col), from))
        .collect();
    (!each.is_empty()).then(|| median(&mut each))
}

/// The median, µs, of a column of ns from step `from` on; none when it has no steps past it.
fn median_us_after(mut v: Vec<f64>, from: usize) -> Option<f64> {
    (v.len() > from).then(|| median(&mut v.split_off(from)) / 1e3)
}
