//! Analysis of a servicing run (orbital plant + Lb-DNN servicers), from the telemetry alone (so
//! it is the same for the multi-process and the reference run): the velocity-estimation error
//! ζ̃ᵢ = ζᵢ − ζ̂ᵢ needs the plant's truth ζᵢ and the agent's estimate ζ̂ᵢ, which no single process
//! has: it is joined here, written to `derived/fig1.parquet` (`.csv` when the telemetry is), and summarised in `summary.json`.

use std::collections::BTreeMap;

use cohort_report::Table;
use cohort_runtime::record::{RunDirs, TelemetryWriter, TimelineEvent};
use cohort_scenario::Scenario;

/// Start of the velocity-estimation-error window (Fig. 3: "≈ 5 m/s after ≈ 150 s").
pub const ZETA_WINDOW_START_S: f64 = 150.0;

/// The servicing analysis: `derived/fig1.parquet` (or `.csv`, as the telemetry) and the ζ̃ᵢ and late ‖eᵢ‖ metrics.
pub fn servicing(s: &Scenario, dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    let n = s.n_agents();
    let axes = ["x", "y", "z"];
    let mut want_plant = vec!["k".to_string(), "t_s".to_string()];
    for i in 1..=n {
        want_plant.push(format!("a{i}_e_norm_m"));
        for ax in axes {
            want_plant.push(format!("a{i}_zeta_{ax}_mps"));
        }
        for ax in axes {
            want_plant.push(format!("a{i}_u_{ax}_mps2"));
        }
    }
    let plant = Table::read_columns(&dirs.telemetry().join("plant.csv"), &want_plant).map_err(|e| e.to_string())?;
    let want_agent: Vec<String> =
        ["k", "zeta_hat_x_mps", "zeta_hat_y_mps", "zeta_hat_z_mps"].iter().map(|x| x.to_string()).collect();
    let agents: Vec<Table> = (1..=n)
        .map(|i| {
            Table::read_columns(&dirs.telemetry().join(format!("agent-{i}.csv")), &want_agent)
                .map_err(|e| e.to_string())
        })
        .collect::<Result<_, _>>()?;
    // Rows are joined by step: an agent that was dead for a while (a fault) has no rows then,
    // and its estimator columns are NaN there (the truth columns come from the plant).
    let rows = plant.rows();
    let row_of: Vec<std::collections::HashMap<u64, usize>> =
        agents.iter().map(|a| a.steps().iter().enumerate().map(|(r, k)| (*k, r)).collect()).collect();
    std::fs::create_dir_all(dirs.root.join("derived")).map_err(|e| format!("derived/: {e}"))?;
    // No copy of the agents' ‖θ̂ᵢ‖ (`theta_norm`, in their own telemetry): nothing here needs a
    // join for it, and it was a fifth of this file.
    let mut cols = vec!["k".to_string(), "t_s".to_string()];
    for i in 1..=n {
        for c in ["e_norm_m", "zeta_err_norm_mps", "u_norm_mps2"] {
            cols.push(format!("a{i}_{c}"));
        }
    }
    // In the run's telemetry format (`derived/fig1.parquet` by default); readers take either.
    let path = dirs.root.join(format!("derived/fig1.{}", s.run.telemetry.extension()));
    let mut out =
        TelemetryWriter::create(s.run.telemetry, &path, &cols).map_err(|e| format!("{}: {e}", path.display()))?;
    let (t, k) = (plant.col("t_s"), plant.steps());
    let end_s = s.scenario.duration_s.round();
    let mut sq = vec![0.0; n as usize];
    let mut max = vec![0.0f64; n as usize];
    let mut samples = vec![0u64; n as usize];
    // Steady state of the truth error ‖eᵢ‖ (every servicer, dead or alive: the plant has it).
    let mut e_last = vec![(0.0f64, 0u64); n as usize];
    let mut row = Vec::with_capacity(cols.len());
    for r in 0..rows {
        row.clear();
        row.push(t[r]);
        let in_window = t[r] + 1e-9 >= ZETA_WINDOW_START_S;
        let last10 = t[r] + 1e-9 >= s.scenario.duration_s - 10.0;
        for i in 1..=n {
            let a = &agents[i as usize - 1];
            let ar = row_of[i as usize - 1].get(&k[r]).copied();
            let zt: f64 = match ar {
                Some(ar) => axes
                    .iter()
                    .map(|ax| {
                        (plant.col(&format!("a{i}_zeta_{ax}_mps"))[r] - a.col(&format!("zeta_hat_{ax}_mps"))[ar])
                            .powi(2)
                    })
                    .sum::<f64>()
                    .sqrt(),
                None => f64::NAN,
            };
            let un: f64 = axes.iter().map(|ax| plant.col(&format!("a{i}_u_{ax}_mps2"))[r].powi(2)).sum::<f64>().sqrt();
            row.extend([plant.col(&format!("a{i}_e_norm_m"))[r], zt, un]);
            if last10 {
                let e = &mut e_last[i as usize - 1];
                *e = (e.0 + plant.col(&format!("a{i}_e_norm_m"))[r], e.1 + 1);
            }
            if in_window && zt.is_finite() {
                samples[i as usize - 1] += 1;
                sq[i as usize - 1] += zt * zt;
                max[i as usize - 1] = max[i as usize - 1].max(zt);
            }
        }
        out.row(k[r], &row).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    out.finish().map_err(|e| format!("{}: {e}", path.display()))?;
    let mut m = BTreeMap::new();
    for i in 0..n as usize {
        if samples[i] > 0 {
            let w = format!("{ZETA_WINDOW_START_S:.0}_{end_s:.0}");
            m.insert(format!("servicer_{}.zeta_err_rms_{w}_mps", i + 1), (sq[i] / samples[i] as f64).sqrt());
            m.insert(format!("servicer_{}.zeta_err_max_{w}_mps", i + 1), max[i]);
        }
        if e_last[i].1 > 0 {
            m.insert(format!("servicer_{}.e_norm_last10s_mean_m", i + 1), e_last[i].0 / e_last[i].1 as f64);
        }
    }
    Ok(m)
}

/// The effect of each process fault on seed 000's headline metric: the mean ‖eᵢ‖ of the
/// servicers no fault touched, over the 10 s before the fault and over the run's last 10 s.
pub fn fault_effects(
    s: &Scenario,
    dirs: &RunDirs,
    timeline: &[TimelineEvent],
) -> Result<BTreeMap<String, f64>, String> {
    let mut m = BTreeMap::new();
    let path = cohort_report::table::resolve(&dirs.root.join("derived/fig1.csv"));
    if !path.is_file() {
        return Ok(m);
    }
    let faults: Vec<_> = timeline.iter().filter(|e| matches!(e.event.as_str(), "kill" | "freeze")).collect();
    if faults.is_empty() {
        return Ok(m);
    }
    let hit: Vec<u32> = faults.iter().map(|e| e.agent).collect();
    let survivors: Vec<u32> = (1..=s.n_agents()).filter(|i| !hit.contains(i)).collect();
    let mut want = vec!["t_s".to_string()];
    want.extend(survivors.iter().map(|i| format!("a{i}_e_norm_m")));
    let t = Table::read_columns(&path, &want).map_err(|e| e.to_string())?;
    let mean_over = |from: f64, to: f64| {
        let (mut sum, mut n) = (0.0, 0usize);
        for (r, &ts) in t.col("t_s").iter().enumerate() {
            if ts + 1e-9 >= from && ts < to - 1e-9 {
                for i in &survivors {
                    sum += t.col(&format!("a{i}_e_norm_m"))[r];
                    n += 1;
                }
            }
        }
        (n > 0).then(|| sum / n as f64)
    };
    let end = s.scenario.duration_s;
    for e in faults {
        let key = format!("fault.{}_agent{}_t{:.0}", e.event, e.agent, e.t_s);
        if let Some(x) = mean_over(e.t_s - 10.0, e.t_s) {
            m.insert(format!("{key}.survivors_e_norm_mean_before_m"), x);
        }
        if let Some(x) = mean_over(end - 10.0, end) {
            m.insert(format!("{key}.survivors_e_norm_mean_last10s_m"), x);
        }
    }
    Ok(m)
}
