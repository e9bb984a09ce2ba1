//! Seed 003's run analysis, from the run's telemetry and the plant's end-of-run file alone (so
//! the multi-process and reference runs of a scenario get the same numbers): per spacecraft j,
//!
//! - `a{j}_delivery_error_m` = ‖p(t_f) − ρ_f‖ (true, in the true ISO's LVLH frame) and
//!   `a{j}_dv_mps` = ∫‖u‖/m dt, from `snapshots/encounter.csv` (the per-step rows hold the state
//!   at each t_k before its command, never the state at t_f); `encounter_reached` is 0 when the
//!   run stopped before t_f, and then no delivery error is given;
//! - `a{j}_bound_tf_m` = b_e(t_f), the delivery-error bound of Neural-Rendezvous, and
//!   `a{j}_error_over_bound`: the bound of the last row advanced over the last control interval
//!   with the drive L̄ε/m_min of that row, by the agent's own integrator
//!   ([`crate::iso::control::bound::Bound::advance`], so it is the agent's b_e(t_f) bit for bit); only for a
//!   method that keeps a bound (b_e ≥ 0 in the telemetry);
//! - `a{j}_tracking_error_max_m`: the largest ‖p − p_d‖ over the steps with a desired trajectory
//!   (p the plant's true position, p_d the agent's desired position, at each t_k), and
//!   `a{j}_bound_violations`: the steps where it exceeds the agent's b_e(t_k);
//! - `a{j}_t_switch_s` (first step in tracking, NaN if never), `a{j}_mode_switches` (changes
//!   between guidance and tracking; a rebuild is not a switch), `a{j}_rebuilds`,
//!   `a{j}_bad_readings`;
//! - ‖u* − u_ℓ‖ over the tracking steps (what the min-norm control changes of the nominal
//!   command): `a{j}_du_mean_n`, `a{j}_du_max_n`, `a{j}_du_active_share` (steps where the
//!   constraint (35) was active, ‖u* − u_ℓ‖ > 0); `a{j}_clipped_steps` (commands clipped to u_max);
//!
//! and over the spacecraft: `max_delivery_error_m`, `max_dv_mps`, `max_error_over_bound`,
//! `within_bound` (how many delivered within b_e(t_f)).

use std::collections::BTreeMap;
use std::path::Path;

use cohort_report::Table;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;

use crate::iso::control::agent::{MODE_BAD_READINGS, MODE_REBUILT, MODE_TRACKING};
use crate::iso::control::bound::Bound;
use crate::iso::dynamics::plant::ENCOUNTER_FILE;
use crate::iso::host::kinds::NrSetup;

/// The agent columns the analysis reads.
const AGENT_COLUMNS: [&str; 9] =
    ["mode", "du_n", "b_e_m", "b_s_mps", "drive_mps2", "clipped_steps", "p_d_x_m", "p_d_y_m", "p_d_z_m"];

/// One spacecraft's end-of-run values from `snapshots/encounter.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encounter {
    pub reached_t_f: bool,
    pub miss_m: f64,
    pub dv_mps: f64,
    pub p_m: [f64; 3],
    pub rho_f_m: [f64; 3],
}

/// Every spacecraft's entry of the run's `snapshots/encounter.csv`.
pub fn read_encounter(run_dir: &Path, n_agents: u32) -> Result<Vec<Encounter>, String> {
    let path = run_dir.join("snapshots").join(ENCOUNTER_FILE);
    let t = Table::read(&path).map_err(|e| e.to_string())?;
    if t.rows() != 1 {
        return Err(format!("{}: {} rows, expected 1", path.display(), t.rows()));
    }
    let get = |j: u32, name: &str| -> Result<f64, String> {
        t.get(&format!("a{j}_{name}")).map(|c| c[0]).ok_or_else(|| format!("{}: no column a{j}_{name}", path.display()))
    };
    (1..=n_agents)
        .map(|j| {
            Ok(Encounter {
                reached_t_f: get(j, "reached_t_f")? == 1.0,
                miss_m: get(j, "miss_m")?,
                dv_mps: get(j, "dv_mps")?,
                p_m: [get(j, "p_x_m")?, get(j, "p_y_m")?, get(j, "p_z_m")?],
                rho_f_m: [get(j, "rho_f_x_m")?, get(j, "rho_f_y_m")?, get(j, "rho_f_z_m")?],
            })
        })
        .collect()
}

/// b_e at the end of the interval of the last row (None when the agent keeps no bound).
pub fn bound_after_last_row(agent: &Table, dt_s: f64, alpha_per_s: f64, lambda_per_s: f64) -> Option<f64> {
    let last = agent.rows().checked_sub(1)?;
    let (b_e, b_s, drive) = (agent.col("b_e_m")[last], agent.col("b_s_mps")[last], agent.col("drive_mps2")[last]);
    if b_e < 0.0 {
        return None;
    }
    let mut b = Bound::new(b_s, b_e);
    b.advance(dt_s, alpha_per_s, lambda_per_s, drive);
    Some(b.b_e)
}

/// ‖p − p_d‖ at each row with a desired trajectory (NaN elsewhere): the plant's true p against
/// the agent's p_d of the same step.
pub fn tracking_errors(plant: &Table, agent: &Table, j: u32) -> Result<Vec<f64>, String> {
    let n = plant.rows().min(agent.rows());
    if plant.steps()[..n] != agent.steps()[..n] {
        return Err(format!("telemetry/agent-{j}.csv: steps do not line up with telemetry/plant.csv"));
    }
    let axes = ["x", "y", "z"];
    let p: Vec<&[f64]> = axes.iter().map(|a| plant.col(&format!("a{j}_p_{a}_m"))).collect();
    let pd: Vec<&[f64]> = axes.iter().map(|a| agent.col(&format!("p_d_{a}_m"))).collect();
    Ok((0..n).map(|k| (0..3).map(|i| (p[i][k] - pd[i][k]).powi(2)).sum::<f64>().sqrt()).collect())
}

fn is_tracking(mode: f64) -> bool {
    mode == MODE_TRACKING || mode == MODE_REBUILT
}

/// The mode and ‖u* − u_ℓ‖ metrics of one agent's telemetry, named `a{j}_…`.
fn mode_metrics(j: u32, agent: &Table, m: &mut BTreeMap<String, f64>) {
    let (mode, du) = (agent.col("mode"), agent.col("du_n"));
    let tracking: Vec<usize> = (0..agent.rows()).filter(|&k| is_tracking(mode[k])).collect();
    let switches = mode.windows(2).filter(|w| is_tracking(w[0]) != is_tracking(w[1])).count();
    let t_switch = tracking.first().map_or(f64::NAN, |&k| agent.t[k]);
    let du_t: Vec<f64> = tracking.iter().map(|&k| du[k]).collect();
    let n = du_t.len() as f64;
    let put = |m: &mut BTreeMap<String, f64>, name: &str, v: f64| {
        m.insert(format!("a{j}_{name}"), v);
    };
    put(m, "t_switch_s", t_switch);
    put(m, "mode_switches", switches as f64);
    put(m, "rebuilds", mode.iter().filter(|x| **x == MODE_REBUILT).count() as f64);
    put(m, "bad_readings", mode.iter().filter(|x| **x == MODE_BAD_READINGS).count() as f64);
    if !du_t.is_empty() {
        put(m, "du_mean_n", du_t.iter().sum::<f64>() / n);
        put(m, "du_max_n", du_t.iter().copied().fold(0.0, f64::max));
        put(m, "du_active_share", du_t.iter().filter(|x| **x > 0.0).count() as f64 / n);
    }
    put(m, "clipped_steps", agent.col("clipped_steps").last().copied().unwrap_or(0.0));
}

/// The metrics of the module docs (empty for a run of other kinds).
pub fn analyse(s: &Setup, dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    let Some(a) = s.algorithm_as::<NrSetup>() else {
        return Ok(BTreeMap::new());
    };
    let n = s.n_agents();
    let encounter = read_encounter(&dirs.root, n)?;
    let wanted: Vec<String> = (1..=n).flat_map(|j| ["x", "y", "z"].map(|a| format!("a{j}_p_{a}_m"))).collect();
    let plant = Table::read_columns(&dirs.telemetry().join("plant.csv"), &wanted).map_err(|e| e.to_string())?;
    let mut m = BTreeMap::new();
    let reached = encounter.iter().all(|e| e.reached_t_f);
    m.insert("encounter_reached".into(), f64::from(u8::from(reached)));
    let (mut worst, mut worst_dv, mut worst_ratio, mut within, mut with_bound) = (0.0f64, 0.0f64, 0.0f64, 0, 0);
    for (j, e) in (1..=n).zip(&encounter) {
        let path = dirs.telemetry().join(format!("agent-{j}.csv"));
        let agent = Table::read_columns(&path, &AGENT_COLUMNS).map_err(|e| e.to_string())?;
        mode_metrics(j, &agent, &mut m);
        let e_track = tracking_errors(&plant, &agent, j)?;
        let b_e = agent.col("b_e_m");
        if e_track.iter().any(|e| e.is_finite()) {
            m.insert(
                format!("a{j}_tracking_error_max_m"),
                e_track.iter().copied().filter(|e| e.is_finite()).fold(0.0, f64::max),
            );
            let over = e_track.iter().zip(b_e).filter(|(e, b)| **b >= 0.0 && e.is_finite() && *e > *b).count();
            if b_e.iter().any(|b| *b >= 0.0) {
                m.insert(format!("a{j}_bound_violations"), over as f64);
            }
        }
        m.insert(format!("a{j}_dv_mps"), e.dv_mps);
        worst_dv = worst_dv.max(e.dv_mps);
        if !e.reached_t_f {
            m.insert(format!("a{j}_miss_at_end_m"), e.miss_m);
            continue;
        }
        m.insert(format!("a{j}_delivery_error_m"), e.miss_m);
        worst = worst.max(e.miss_m);
        let cfg = &a.config;
        if let Some(b) = bound_after_last_row(&agent, s.scenario.dt_s, cfg.alpha_per_s, cfg.lambda_per_s) {
            m.insert(format!("a{j}_bound_tf_m"), b);
            m.insert(format!("a{j}_error_over_bound"), e.miss_m / b);
            worst_ratio = worst_ratio.max(e.miss_m / b);
            with_bound += 1;
            within += usize::from(e.miss_m <= b);
        }
    }
    m.insert("max_dv_mps".into(), worst_dv);
    if reached {
        m.insert("max_delivery_error_m".into(), worst);
    }
    if with_bound > 0 {
        m.insert("max_error_over_bound".into(), worst_ratio);
        m.insert("within_bound".into(), within as f64);
    }
    Ok(m)
}
