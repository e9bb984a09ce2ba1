//! `orchestrator vtxo sec7`: the Sec. 7 case measured for the three relative laws (SMC-sign, the
//! paper's; SMC-sat (67); PD (56)) at several steps, with every model on and, to isolate the sign
//! law's sliding band under the zero-order hold, with the accelerometer bias off (every other
//! model on). Runs at the scenario's own step (10 ms) are multi-process; the other steps run
//! in-process (`--reference`, bit-identical, and a 1 ms run has 9.3 million steps). Writes
//! `sec7.md` and `sec7.csv` beside the prediction Z·dt/(2k) for the sign law's band, each run
//! keeping its own run directory (summary, telemetry one row per 0.1 s, plots).
//!
//! The transverse statistics are the plant's, over the last 15 s at every step
//! ([`crate::model::metrics`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_host::{Launcher, Mode, RunOptions, RunResult};
use cohort_runtime::paper::Setup;
use cohort_scenario::Overrides;

use crate::flight::config::{RelativeController, VtxoAlgorithmConfig};
use crate::flight::relative_control::Switching;

/// The scenario files, in table order.
const FILES: [&str; 3] = ["vtxo-sec7.toml", "vtxo-sec7-sat.toml", "vtxo-sec7-pd.toml"];
/// Telemetry rows per simulated second in every run of the campaign.
const ROW_PERIOD_S: f64 = 0.1;

pub struct Options {
    pub out: PathBuf,
    pub topologies: PathBuf,
    pub steps_s: Vec<f64>,
    /// Also run every case with the accelerometer bias off.
    pub ablation: bool,
}

struct Row {
    law: &'static str,
    dt_s: f64,
    bias: bool,
    mode: String,
    /// Z·dt/(2k) per axis (sign law only), m.
    band_m: Option<f64>,
    run: RunResult,
}

fn law_name(a: &VtxoAlgorithmConfig) -> &'static str {
    match (a.relative.controller, a.relative.switching) {
        (RelativeController::Smc, Switching::Sign) => "SMC-sign",
        (RelativeController::Smc, Switching::Sat) => "SMC-sat",
        (RelativeController::Pd, _) => "PD",
        (RelativeController::Off, _) => "off",
    }
}

/// `table[path…] = value`, creating the tables on the way.
fn set_path(table: &mut toml::Table, path: &[&str], value: toml::Value) -> Result<(), String> {
    let (last, inner) = path.split_last().ok_or("empty key path")?;
    let mut t = table;
    for key in inner {
        let entry = t.entry(key.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = entry.as_table_mut().ok_or(format!("{key} is not a table"))?;
    }
    t.insert(last.to_string(), value);
    Ok(())
}

/// `base` at step `dt_s`, with the accelerometer bias on or off.
fn variant(launcher: &dyn Launcher, base: &Setup, dt_s: f64, bias: bool, name: &str) -> Result<Setup, String> {
    let mut s = base.parsed.clone();
    s.scenario.name = name.to_string();
    s.scenario.dt_s = dt_s;
    s.run.telemetry_every_steps = ((ROW_PERIOD_S / dt_s).round() as u64).max(1);
    if !bias {
        let path = ["sensors", "accelerometer", "bias_3sigma_mps2"];
        set_path(&mut s.plant.body, &path, toml::Value::Float(0.0))?;
    }
    launcher.configure(s, name).map_err(|e| e.to_string())
}

fn ms(dt_s: f64) -> String {
    format!("{}", dt_s * 1e3)
}

/// Run the campaign; returns the Markdown table (also written to `out/sec7.md`).
pub fn run(o: &Options, launcher: &dyn Launcher) -> Result<String, String> {
    std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
    let mut rows = Vec::new();
    for bias in if o.ablation { vec![true, false] } else { vec![true] } {
        for &dt_s in &o.steps_s {
            for file in FILES {
                if let Some(sig) = launcher.interrupted() {
                    return Err(format!("interrupted by signal {sig}"));
                }
                let path = o.topologies.join(file);
                let base = launcher.load(&path, &Overrides::default()).map_err(|e| e.to_string())?;
                let a = base.algorithm_as::<VtxoAlgorithmConfig>().ok_or(format!("{file}: not a vtxo scenario"))?;
                let law = law_name(a);
                let stem = file.trim_end_matches(".toml");
                let name =
                    format!("{stem}-{}ms{}", ms(dt_s).replace('.', "_"), if bias { "" } else { "-no-accel-bias" });
                let setup = variant(launcher, &base, dt_s, bias, &name)?;
                let own_step = (dt_s - base.scenario.dt_s).abs() <= 1e-12 * dt_s;
                let mode = if own_step { Mode::MultiProcess } else { Mode::Reference };
                let dir = o.out.join(&name);
                tracing::info!("vtxo sec7: {name} ({:?}) → {}", mode, dir.display());
                let run = launcher.run(&setup, &dir, RunOptions { mode, plots: true }).map_err(|e| e.to_string())?;
                if let Some(e) = &run.error {
                    return Err(format!("{name}: {e}"));
                }
                let band_m = (law == "SMC-sign").then(|| a.relative.smc.z_mps2[0] * dt_s / (2.0 * a.relative.smc.k));
                rows.push(Row { law, dt_s, bias, mode: run.mode.clone(), band_m, run });
            }
        }
    }
    let md = markdown(&rows);
    std::fs::write(o.out.join("sec7.md"), &md).map_err(|e| format!("{}: {e}", o.out.display()))?;
    write_csv(&o.out.join("sec7.csv"), &rows)?;
    Ok(md)
}

const COLUMNS: [(&str, &str); 9] = [
    ("formation_first_within_s", "first < 1 m (s)"),
    ("formation_settled_s", "settled (s)"),
    ("transverse_rms_mm", "transverse RMS (mm)"),
    ("transverse_max_mm", "transverse max (mm)"),
    ("range_error_end_m", "range error end (m)"),
    ("follower_thrust_peak_n", "peak thrust (N)"),
    ("follower_delta_v_mps", "Δv (m/s)"),
    ("follower_impulse_n_s", "∫|F|dt (N·s)"),
    ("follower_v_rel_hat_error_end_mps", "‖v̂_rel − v_rel‖ end (m/s)"),
];

fn g(x: f64) -> String {
    if !x.is_finite() {
        "–".into()
    } else if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-2) {
        format!("{x:.3e}")
    } else {
        format!("{x:.4}")
    }
}

fn markdown(rows: &[Row]) -> String {
    let mut md = String::from(
        "# Sec. 7 case, measured (`orchestrator vtxo sec7`)\n\nFollower from r_rel(0) = [1, 2, 10] km, v_rel(0) = [1, 1, 1] m/s to r_f = [0, 0, 1] km \
         (ECI), leader drifting, 9 300 s; transverse statistics over the last 15 s at every step. \
         Z·dt/(2k): the sign law's predicted band per axis under a zero-order hold.\n\n| law | dt (ms) | accelerometer bias | mode |",
    );
    for (_, h) in COLUMNS {
        let _ = write!(md, " {h} |");
    }
    md.push_str(" Z·dt/(2k) (mm) | wall (s) |\n|---|---|---|---|");
    md.push_str(&"---|".repeat(COLUMNS.len() + 2));
    md.push('\n');
    for r in rows {
        let _ = write!(md, "| {} | {} | {} | {} |", r.law, ms(r.dt_s), if r.bias { "on" } else { "off" }, r.mode);
        for (k, _) in COLUMNS {
            let _ = write!(md, " {} |", g(r.run.metric(k)));
        }
        let band = r.band_m.map_or("–".to_string(), |b| g(b * 1e3));
        let _ = writeln!(md, " {band} | {:.0} |", r.run.wall_s);
    }
    md
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<(), String> {
    let mut csv = String::from("law,dt_s,accelerometer_bias,mode");
    for (k, _) in COLUMNS {
        let _ = write!(csv, ",{k}");
    }
    csv.push_str(",band_m,wall_s,run_dir\n");
    for r in rows {
        let _ = write!(csv, "{},{:?},{},{}", r.law, r.dt_s, r.bias, r.mode);
        for (k, _) in COLUMNS {
            let _ = write!(csv, ",{:?}", r.run.metric(k));
        }
        let _ = writeln!(csv, ",{:?},{:?},{}", r.band_m.unwrap_or(f64::NAN), r.run.wall_s, r.run.dir.display());
    }
    std::fs::write(path, csv).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_path_creates_the_tables_on_the_way() {
        let mut t: toml::Table = "[sensors.gyro]\nnoise_3sigma_rad_s = 1.0\n".parse().unwrap();
        set_path(&mut t, &["sensors", "accelerometer", "bias_3sigma_mps2"], toml::Value::Float(0.0)).unwrap();
        assert_eq!(t["sensors"]["accelerometer"]["bias_3sigma_mps2"].as_float(), Some(0.0));
        assert_eq!(t["sensors"]["gyro"]["noise_3sigma_rad_s"].as_float(), Some(1.0));
        let mut bad: toml::Table = "sensors = 3\n".parse().unwrap();
        assert!(set_path(&mut bad, &["sensors", "x"], toml::Value::Float(0.0)).is_err());
    }
}
