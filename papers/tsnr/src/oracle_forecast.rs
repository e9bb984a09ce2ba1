//! The oracle tension forecast: T̂ᵢ(t_k + nΔt) is the tension the `tsnr-net` plant recorded on
//! MU i at step k + n of an earlier run (`algorithm.mpc.tension_oracle`, that run's
//! `telemetry/plant.csv`). Not in the paper: it bounds what the paper's estimator (7)–(11) could
//! give the controller, a forecast with no error at all.
//!
//! **Causal consistency.** A series recorded in another run is the true future only if this run
//! flies the same path, and it does not: a better forecast changes the plans, the plans the net's
//! motion, the motion the tension. `orchestrator tsnr ablation` therefore iterates: the first
//! oracle run replays the tension of the default (DNN) run, each further one the tension of the
//! oracle run before it, and it reports how far every iterate's forecast was from the tension
//! it then met. At a fixed point (the run reproduces the run it replays) the forecast is exact
//! at every step of every horizon; how close the iterates come is measured, not assumed — the net
//! is chaotic (two runs 1e-12 m apart part within seconds), so the forecast of the last iterate
//! is exact early on and only statistically right later.
//!
//! Beyond the recorded series (the last steps' horizons) the last recorded tension is held, as
//! the DNN holds its last predicted step.

use std::path::Path;

use cohort_report::Table;

use crate::forecast::{ForecastInput, TensionForecast};

/// Every MU's recorded tension, `[mu][k]`, N.
pub type Series = Vec<Vec<[f64; 3]>>;

/// The tension columns of the `tsnr-net` plant for MU `id`.
pub fn tension_columns(id: u32) -> [String; 3] {
    ["x", "y", "z"].map(|ax| format!("mu{id}_tension_{ax}_n"))
}

/// Read the tension of MUs 1..=`n_mus` from a `tsnr-net` plant telemetry file; it must cover
/// `steps` steps of `dt_s` (rows k = 0, 1, … at t = kΔt) with finite values.
pub fn load(path: &Path, n_mus: u32, steps: u64, dt_s: f64) -> Result<Series, String> {
    let wanted: Vec<String> = (1..=n_mus).flat_map(tension_columns).collect();
    let table = Table::read_columns(path, &wanted).map_err(|e| e.to_string())?;
    if (table.rows() as u64) < steps {
        return Err(format!("{} rows, the run has {steps} steps", table.rows()));
    }
    for (r, (&k, &t)) in table.steps().iter().zip(&table.t).enumerate() {
        if k != r as u64 || (t - k as f64 * dt_s).abs() > 1e-9 * (1.0 + t.abs()) {
            return Err(format!(
                "row {r} is step {k} at t = {t} s, not step {r} at {} s (Δt = {dt_s} s)",
                r as f64 * dt_s
            ));
        }
    }
    let mut out = Vec::new();
    for id in 1..=n_mus {
        let cols = tension_columns(id).map(|c| table.col(&c).to_vec());
        if let Some(bad) = cols.iter().flatten().find(|x| !x.is_finite()) {
            return Err(format!("MU {id}: a non-finite tension {bad}"));
        }
        out.push((0..table.rows()).map(|r| [cols[0][r], cols[1][r], cols[2][r]]).collect());
    }
    Ok(out)
}

/// MU i's recorded tension replayed as its forecast.
pub struct OracleForecast {
    series: std::sync::Arc<Series>,
    mu: usize,
}

impl OracleForecast {
    /// The forecast of MU `mu` (1-based) from `series` (one entry per MU, non-empty).
    pub fn new(series: std::sync::Arc<Series>, mu: u32) -> Self {
        assert!(series.get(mu as usize - 1).is_some_and(|s| !s.is_empty()), "validated: a series for MU {mu}");
        Self { series, mu: mu as usize - 1 }
    }
}

impl TensionForecast for OracleForecast {
    fn forecast(&mut self, input: &ForecastInput<'_>, out: &mut [[f64; 3]]) {
        let s = &self.series[self.mu];
        for (n, o) in out.iter_mut().enumerate() {
            *o = s[(input.k as usize + n).min(s.len() - 1)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(k: u64) -> ForecastInput<'static> {
        ForecastInput {
            k,
            t_s: k as f64 * 0.1,
            state: [0.0; 6],
            thrust_prev_n: [0.0; 3],
            tension_measured_n: [99.0; 3],
            neighbours: &[],
        }
    }

    #[test]
    fn it_replays_the_recorded_future_and_holds_the_last_value() {
        let mu2: Vec<[f64; 3]> = (0..5).map(|k| [k as f64, -(k as f64), 0.5]).collect();
        let series = std::sync::Arc::new(vec![vec![[7.0; 3]; 5], mu2]);
        let mut f = OracleForecast::new(series, 2);
        let mut out = [[0.0; 3]; 4];
        f.forecast(&input(1), &mut out);
        assert_eq!(out, [[1.0, -1.0, 0.5], [2.0, -2.0, 0.5], [3.0, -3.0, 0.5], [4.0, -4.0, 0.5]]);
        // The measurement plays no part; past the end the last recorded value is held.
        f.forecast(&input(3), &mut out);
        assert_eq!(out, [[3.0, -3.0, 0.5], [4.0, -4.0, 0.5], [4.0, -4.0, 0.5], [4.0, -4.0, 0.5]]);
    }

    #[test]
    fn a_plant_file_is_read_per_mu_and_checked() {
        let dir = std::env::temp_dir().join(format!("tsnr-oracle-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plant.csv");
        let mut header = vec!["k".to_string(), "t_s".to_string()];
        for id in 1..=2 {
            header.extend(tension_columns(id));
        }
        header.push("net_energy_j".into());
        let mut text = header.join(",") + "\n";
        for k in 0..3 {
            let t = k as f64 * 0.1;
            text += &format!("{k},{t:?},{k}.5,1,2,-{k},3,4,0\n");
        }
        std::fs::write(&path, &text).unwrap();
        let s = load(&path, 2, 3, 0.1).unwrap();
        assert_eq!(s[0], vec![[0.5, 1.0, 2.0], [1.5, 1.0, 2.0], [2.5, 1.0, 2.0]]);
        assert_eq!(s[1][2], [-2.0, 3.0, 4.0]);
        assert!(load(&path, 2, 4, 0.1).unwrap_err().contains("3 rows, the run has 4 steps"));
        assert!(load(&path, 2, 3, 0.2).unwrap_err().contains("row 1 is step 1 at t = 0.1 s"));
        assert!(load(&path, 3, 3, 0.1).unwrap_err().contains("mu3_tension_x_n"));
        std::fs::write(&path, text.replace("1.5,1,2", "NaN,1,2")).unwrap();
        assert!(load(&path, 2, 3, 0.1).unwrap_err().contains("MU 1: a non-finite tension"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
