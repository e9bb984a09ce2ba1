//! Seed 001 analysis (tethered space net robot), from the agents' telemetry and end reports
//! alone, so the multi-process and reference runs of a scenario are analysed identically. The
//! metrics go into `summary.json`, where `orchestrator tsnr compare` reads them:
//!
//! - `mu_<i>.err_rms_<a>_<b>_m`: RMS over the rows with a ≤ t < b (the last phase up to the last
//!   row) of the position tracking error ‖r − r_d‖, one per segment of the scenario's trajectory
//!   (deploy 0–10 s, approach 10–20 s, close 20–30 s in both cases): the paper's Figs. 10–11 show
//!   the error phase by phase;
//! - `mu_<i>.err_peak_<a>_<b>_m`: max of ‖r − r_d‖ within ±1 s of the end of deployment (the
//!   first interior knot, 9–11 s), where the paper has DMPC and SMC peak and AEMC not;
//! - `mu_<i>.terminal_err_m`, `mu_<i>.terminal_err_v_mps`: ‖r − r_d‖ and ‖v − v_d‖ in the last
//!   row, t = T − Δt (the last state an agent measured, against the desired state then, which
//!   is the end point's approach), and `mu_<i>.terminal_ok` (1/0): both within [`TERMINAL_POSITION_TOL_M`] and
//!   [`TERMINAL_VELOCITY_TOL_MPS`]. Absent when the agent's telemetry stops before the last
//!   step (a partial run, a dead agent): its last row is not the terminal state;
//! - `mu_<i>.qp_p50_s`, `mu_<i>.qp_p99_s`, `mu_<i>.qp_max_s`: the agent's QP solve wall time, and
//!   `qp_not_converged`, `qp_infeasible`: failed solves summed over the agents (all absent for
//!   SMC, which solves no QP).
//!
//! The errors are the agents' `err_*` columns: actual (the plant's noise-free reading) minus
//! desired, both at the row's t_k.

use std::collections::BTreeMap;
use std::path::Path;

use cohort_report::Table;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;
use cohort_runtime::solver_stats::SolverStats;
use serde::Deserialize;

use crate::config::formation::TsnrFormation;
use crate::config::net_plant::TsnrNetSetup;

/// The net counts as closed on the target when every MU ends within 10 cm (a fifth of the 0.5 m
/// mesh) of its terminal position …
pub const TERMINAL_POSITION_TOL_M: f64 = 0.1;
/// … and within 5 cm/s of its terminal velocity (Case 2's terminal velocity is ≈ 0.5 m/s).
pub const TERMINAL_VELOCITY_TOL_MPS: f64 = 0.05;
/// Half-width of the window around the end of deployment for the peak error, s.
pub const PEAK_HALF_WINDOW_S: f64 = 1.0;
/// Slack on row times, which are k·Δt in floating point (29.900000000000002).
const T_EPS_S: f64 = 1e-9;

const AXES: [&str; 3] = ["x", "y", "z"];

/// Telemetry columns one MU's metrics need.
pub fn wanted_columns() -> Vec<String> {
    let mut w = vec!["k".to_string(), "t_s".to_string()];
    w.extend(AXES.iter().map(|ax| format!("err_{ax}_m")));
    w.extend(AXES.iter().map(|ax| format!("err_v_{ax}_mps")));
    w
}

/// A time as it appears in a metric name: 10.0 → "10", 2.5 → "2.5".
fn t_name(t_s: f64) -> String {
    format!("{t_s}")
}

/// Tracking metrics of MU `id` from its telemetry `table` (columns [`wanted_columns`]), for a
/// trajectory with knots `knots_s` and a run whose last step is `last_k`.
pub fn tracking_metrics(id: u32, table: &Table, knots_s: &[f64], last_k: u64) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    let (t, k) = (table.col("t_s"), table.steps());
    let norm = |stem: &str, unit: &str, r: usize| -> f64 {
        AXES.iter().map(|ax| table.col(&format!("{stem}_{ax}_{unit}"))[r].powi(2)).sum::<f64>().sqrt()
    };
    let e: Vec<f64> = (0..table.rows()).map(|r| norm("err", "m", r)).collect();
    for (p, w) in knots_s.windows(2).enumerate() {
        let last_phase = p + 2 == knots_s.len();
        let inside =
            |ts: f64| ts + T_EPS_S >= w[0] && if last_phase { ts <= w[1] + T_EPS_S } else { ts + T_EPS_S < w[1] };
        let sq: Vec<f64> = e.iter().zip(t).filter(|(_, ts)| inside(**ts)).map(|(e, _)| e * e).collect();
        if !sq.is_empty() {
            let rms = (sq.iter().sum::<f64>() / sq.len() as f64).sqrt();
            m.insert(format!("mu_{id}.err_rms_{}_{}_m", t_name(w[0]), t_name(w[1])), rms);
        }
    }
    if let Some(&t_deployed) = knots_s.get(1).filter(|_| knots_s.len() > 2) {
        let (a, b) = (t_deployed - PEAK_HALF_WINDOW_S, t_deployed + PEAK_HALF_WINDOW_S);
        let peak = e
            .iter()
            .zip(t)
            .filter(|(_, ts)| **ts + T_EPS_S >= a && **ts <= b + T_EPS_S)
            .map(|(e, _)| *e)
            .fold(None, |acc: Option<f64>, e| Some(acc.map_or(e, |x| x.max(e))));
        if let Some(peak) = peak {
            m.insert(format!("mu_{id}.err_peak_{}_{}_m", t_name(a), t_name(b)), peak);
        }
    }
    let last = table.rows().checked_sub(1);
    if let Some(r) = last.filter(|&r| k[r] == last_k) {
        let (ep, ev) = (e[r], norm("err_v", "mps", r));
        m.insert(format!("mu_{id}.terminal_err_m"), ep);
        m.insert(format!("mu_{id}.terminal_err_v_mps"), ev);
        let ok = ep <= TERMINAL_POSITION_TOL_M && ev <= TERMINAL_VELOCITY_TOL_MPS;
        m.insert(format!("mu_{id}.terminal_ok"), if ok { 1.0 } else { 0.0 });
    }
    m
}

/// The part of `status/agent-<i>.json` read here (serde skips the rest).
#[derive(Deserialize)]
struct Status {
    #[serde(default)]
    solver: Option<SolverStats>,
}

fn solver_stats(path: &Path) -> Result<Option<SolverStats>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let s: Status = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(s.solver)
}

pub fn analyse(s: &Setup, dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    let (Some(_), Some(a)) = (s.plant_as::<TsnrNetSetup>(), s.algorithm_as::<TsnrFormation>()) else {
        return Ok(BTreeMap::new());
    };
    let want = wanted_columns();
    let last_k = s.n_steps().saturating_sub(1);
    let mut m = BTreeMap::new();
    let (mut not_converged, mut infeasible, mut any_qp) = (0u64, 0u64, false);
    for id in 1..=s.n_agents() {
        let table =
            Table::read_columns(&dirs.telemetry().join(format!("agent-{id}.csv")), &want).map_err(|e| e.to_string())?;
        m.extend(tracking_metrics(id, &table, &a.trajectory.knots_s, last_k));
        if let Some(st) = solver_stats(&dirs.status().join(format!("agent-{id}.json")))? {
            any_qp = true;
            not_converged += st.not_converged;
            infeasible += st.infeasible;
            m.insert(format!("mu_{id}.qp_p50_s"), st.solve_time_p50_s);
            m.insert(format!("mu_{id}.qp_p99_s"), st.solve_time_p99_s);
            m.insert(format!("mu_{id}.qp_max_s"), st.solve_time_max_s);
        }
    }
    if any_qp {
        m.insert("qp_not_converged".into(), not_converged as f64);
        m.insert("qp_infeasible".into(), infeasible as f64);
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 300 rows of 0.1 s; ‖e‖ = 0.05 m in 0–10 s, 0.2 m in 10–20 s except 1 m at 10.5 s (inside
    /// the peak window) and 2 m at 11.5 s (outside it), 0.02 m in 20–30 s; terminal errors
    /// 0.03 m and `v_last` m/s.
    fn synthetic(v_last: f64) -> Table {
        let names = wanted_columns();
        let mut data = vec![Vec::new(); names.len()];
        let mut steps = Vec::new();
        for k in 0..300u64 {
            steps.push(k);
            let t = k as f64 * 0.1;
            let e = match k {
                0..100 => 0.05,
                105 => 1.0,
                115 => 2.0,
                100..200 => 0.2,
                299 => 0.03,
                _ => 0.02,
            };
            // Split over x and z as a 3-4-5 triangle, so the norm is not one column.
            let v = if k == 299 { v_last } else { 0.0 };
            let row = [k as f64, t, 0.6 * e, 0.0, -0.8 * e, 0.0, v, 0.0];
            for (c, x) in row.iter().enumerate() {
                data[c].push(*x);
            }
        }
        // Columns after `k` and `t_s`, as the reader keeps them.
        let columns =
            names.iter().zip(&data).skip(2).map(|(n, d)| cohort_report::Column { name: n.clone(), values: d.clone() });
        Table { k: steps, t: data[1].clone(), columns: columns.collect() }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn phase_rms_peak_and_terminal_errors_of_a_synthetic_table() {
        let m = tracking_metrics(3, &synthetic(0.01), &[0.0, 10.0, 20.0, 30.0], 299);
        let get = |k: &str| *m.get(k).unwrap_or_else(|| panic!("no {k} in {m:?}"));
        assert!(close(get("mu_3.err_rms_0_10_m"), 0.05), "{m:?}");
        let rms_10_20 = ((98.0 * 0.04 + 1.0 + 4.0) / 100.0f64).sqrt();
        assert!(close(get("mu_3.err_rms_10_20_m"), rms_10_20), "{m:?}");
        // 99 rows of 0.02 m and the last of 0.03 m (20.0 … 29.9 s).
        let rms_20_30 = ((99.0 * 0.0004 + 0.0009) / 100.0f64).sqrt();
        assert!(close(get("mu_3.err_rms_20_30_m"), rms_20_30), "{m:?}");
        assert!(close(get("mu_3.err_peak_9_11_m"), 1.0), "the 2 m at 11.5 s is outside 9–11 s: {m:?}");
        assert!(close(get("mu_3.terminal_err_m"), 0.03), "{m:?}");
        assert!(close(get("mu_3.terminal_err_v_mps"), 0.01), "{m:?}");
        assert_eq!(get("mu_3.terminal_ok"), 1.0);
        assert_eq!(m.len(), 7, "{m:?}");
        let slow = tracking_metrics(3, &synthetic(0.06), &[0.0, 10.0, 20.0, 30.0], 299);
        assert_eq!(slow["mu_3.terminal_ok"], 0.0, "0.06 m/s is beyond 0.05 m/s");
        // A run that stopped early has no terminal state.
        let partial = tracking_metrics(3, &synthetic(0.0), &[0.0, 10.0, 20.0, 30.0], 599);
        assert!(!partial.keys().any(|k| k.contains("terminal")), "{partial:?}");
    }

    #[test]
    fn a_run_directory_is_analysed_and_a_missing_column_is_named() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/tsnr-case1.toml");
        let papers: &[&dyn cohort_runtime::paper::Paper] = &[&crate::Tsnr, &cohort_kinds_generic::Generic];
        let s = cohort_runtime::paper::load(&file, &cohort_scenario::Overrides::default(), papers).unwrap();
        let root = std::env::temp_dir().join(format!("cohort-tsnr-analysis-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dirs = RunDirs::new(&root);
        dirs.create_all().unwrap();
        let t = synthetic(0.01);
        let mut csv = wanted_columns().join(",") + ",qp_status\n";
        for r in 0..t.rows() {
            let mut row = vec![t.k[r].to_string(), format!("{:?}", t.t[r])];
            row.extend(t.columns.iter().map(|c| format!("{:?}", c.values[r])));
            csv += &(row.join(",") + ",0\n");
        }
        for id in 1..=4u32 {
            std::fs::write(dirs.telemetry().join(format!("agent-{id}.csv")), &csv).unwrap();
            let st = SolverStats {
                solves: 300,
                not_converged: u64::from(id == 2),
                infeasible: u64::from(id >= 3),
                solve_time_p50_s: 1e-3 * f64::from(id),
                solve_time_p99_s: 2e-3,
                solve_time_max_s: 3e-3,
                ..Default::default()
            };
            let status = serde_json::json!({ "process": format!("agent-{id}"), "solver": st });
            std::fs::write(dirs.status().join(format!("agent-{id}.json")), status.to_string()).unwrap();
        }
        let m = analyse(&s, &dirs).unwrap();
        assert_eq!(m["qp_not_converged"], 1.0);
        assert_eq!(m["qp_infeasible"], 2.0);
        assert_eq!(m["mu_4.qp_p50_s"], 4e-3);
        assert_eq!(m["mu_1.qp_max_s"], 3e-3);
        assert_eq!(m["mu_2.terminal_ok"], 1.0);
        // 7 tracking metrics and 3 solve times per MU, and the two failure counts.
        assert_eq!(m.len(), 4 * 10 + 2, "{m:?}");
        std::fs::write(dirs.telemetry().join("agent-3.csv"), csv.replace("err_v_y_mps", "v_y")).unwrap();
        let e = analyse(&s, &dirs).unwrap_err();
        assert!(e.contains("agent-3.csv: no column \"err_v_y_mps\""), "{e}");
        std::fs::remove_file(dirs.status().join("agent-1.json")).unwrap();
        std::fs::write(dirs.telemetry().join("agent-3.csv"), &csv).unwrap();
        let e = analyse(&s, &dirs).unwrap_err();
        assert!(e.contains("status/agent-1.json"), "{e}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
