//! The hand-off run's summary ("Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation", Secs. 5.1 and 8), from the telemetry alone (so the multi-process and the
//! reference run are summarised identically). Per spacecraft (`leader_…`, `follower_…`):
//!
//! - `handoff_{s2,s3}_entry_s`: the first row in s2, s3 (the leader's one step after the master's);
//! - `handoff_transient_{k1_n_m, k2_n_m_s, t_hat_s}`: what its transient predictor answered at its
//!   entry to s2, and the master's `follower_handoff_u2_s` = max(T̂_L, T̂_F) in force;
//! - `handoff_error_end_transient_deg`: the plant's true attitude error (principal angle from q_f)
//!   at its entry to s3, i.e. at the end of its transient, and `handoff_error_window_transient_deg`
//!   its mean over the transient's last D = 4 s (e of (73)), beside Sec. 5.1's bound
//!   (`handoff_error_bound_deg` = 0.2°; `handoff_transient_within_bound` 1/0, on the window mean);
//! - `handoff_error_end_deg`: the error at the last row;
//! - `handoff_law_mismatch_rows`: rows where the law that acted is not exactly the one the
//!   location prescribes (0 in a correct run) and `handoff_final_state`;
//! - s3, from its entry while the location stays s3 (Sec. 3.1's science phase, against what the
//!   science DNN expected): `handoff_science_<gain>` (k̂ at its entry, e.g. `…_z_1_s2`) and the
//!   predicted `handoff_science_{energy_hat_j, error_hat_deg}` (NaN with configured gains);
//!   flown: `handoff_science_s` (its length), `handoff_science_error_mean_deg` (e of (72): the
//!   mean true principal-angle error over the rows of s3) and `…_error_max_deg`,
//!   `handoff_science_energy_j` (E of (71): Σᵢ∫|τᵢωᵢ|dt of the plant's applied wheel torque and
//!   true rate, each row held for its step), `handoff_science_rate_rms_deg_s` (RMS of ‖ω‖) and
//!   `handoff_science_rate_end_{x,y,z}_deg_s` (ω at s3's last row: ω_f of Table 3 when s3 lasts
//!   the phase).
//!
//! With `run.telemetry_every_steps` > 1 the entry times are those of the first row after the entry.

use std::collections::BTreeMap;

use cohort_report::Table;
use cohort_report::table::read_table_with;
use cohort_runtime::record::RunDirs;

use crate::automaton::table::{S2, S3};
use crate::handoff::agent::ActingLaw;
use crate::host::analysis::ROLES;

/// Sec. 5.1: P99(e) < 0.2° at the end of the transient.
pub const ERROR_BOUND_DEG: f64 = 0.2;
/// D of (73), s.
pub const WINDOW_S: f64 = 4.0;
const LAWS: [&str; 3] = ["law_stabilisation_on", "law_transient_on", "law_science_on"];
const XYZ: [&str; 3] = ["x", "y", "z"];

fn read(dirs: &RunDirs, file: &str, cols: &[String]) -> Result<Table, String> {
    Table::read_columns(&dirs.telemetry().join(file), cols).map_err(|e| e.to_string())
}

/// The index in [`LAWS`] of the law a location prescribes.
fn law_index(state: usize) -> usize {
    match ActingLaw::of_state(state) {
        ActingLaw::Stabilisation => 0,
        ActingLaw::Transient => 1,
        ActingLaw::Science => 2,
    }
}

/// An agent's table: `cols` (each required) and every `science_*` column it has.
fn read_agent(dirs: &RunDirs, file: &str, cols: &[String]) -> Result<Table, String> {
    let path = dirs.telemetry().join(file);
    let t = read_table_with(&path, &|n| n.starts_with("science_") || cols.iter().any(|c| c == n))
        .map_err(|e| e.to_string())?;
    match cols.iter().find(|c| t.get(c).is_none()) {
        Some(c) => Err(format!("{}: no column {c:?}", path.display())),
        None => Ok(t),
    }
}

/// The s3 metrics of `role` (module docs): its agent rows `r3..` while in s3, the plant rows
/// `p3..` of the same steps.
fn science_metrics(role: &str, a: &Table, r3: usize, plant: &Table, p3: usize, m: &mut BTreeMap<String, f64>) {
    let key = |k: &str| format!("{role}_handoff_science_{k}");
    for c in a.columns.iter().filter(|c| c.name.starts_with("science_")) {
        m.insert(format!("{role}_handoff_{}", c.name), c.values[r3]);
    }
    let state = a.col("sup_state");
    let n = (r3..a.rows())
        .take_while(|&r| state[r] as usize == S3)
        .zip(p3..plant.rows())
        .take_while(|&(r, p)| a.steps()[r] == plant.steps()[p])
        .count();
    if n == 0 {
        return;
    }
    let rows = p3..p3 + n;
    let err = &plant.col(&format!("{role}_attitude_error_deg"))[rows.clone()];
    let col3 = |name: &str, unit: &str| XYZ.map(|ax| plant.col(&format!("{role}_{name}_{ax}_{unit}")));
    let (w, tau) = (col3("omega_body", "rad_s"), col3("tau_in_body", "n_m"));
    let mut energy_j = 0.0;
    let mut rate2 = 0.0;
    for p in rows.clone() {
        // Each row's torque and rate held for the step that ends at the next row.
        let dt_s = if p + 1 < plant.rows() { plant.t[p + 1] - plant.t[p] } else { plant.t[p] - plant.t[p - 1] };
        energy_j += (0..3).map(|i| (tau[i][p] * w[i][p]).abs()).sum::<f64>() * dt_s;
        rate2 += (0..3).map(|i| w[i][p] * w[i][p]).sum::<f64>();
    }
    let last = p3 + n - 1;
    let span_s = if last + 1 < plant.rows() { plant.t[last + 1] } else { 2.0 * plant.t[last] - plant.t[last - 1] };
    m.insert(key("s"), span_s - plant.t[p3]);
    m.insert(key("error_mean_deg"), err.iter().sum::<f64>() / n as f64);
    m.insert(key("error_max_deg"), err.iter().copied().fold(0.0, f64::max));
    m.insert(key("energy_j"), energy_j);
    m.insert(key("rate_rms_deg_s"), (rate2 / n as f64).sqrt().to_degrees());
    for (i, ax) in XYZ.iter().enumerate() {
        m.insert(key(&format!("rate_end_{ax}_deg_s")), w[i][last].to_degrees());
    }
}

/// The summary metrics (see the module docs).
pub fn analyse(dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    let err_cols: Vec<String> = ROLES.iter().map(|r| format!("{r}_attitude_error_deg")).collect();
    let mut plant_cols = err_cols.clone();
    for role in ROLES {
        for (name, unit) in [("omega_body", "rad_s"), ("tau_in_body", "n_m")] {
            plant_cols.extend(XYZ.map(|ax| format!("{role}_{name}_{ax}_{unit}")));
        }
    }
    let plant = read(dirs, "plant.csv", &plant_cols)?;
    let mut m = BTreeMap::new();
    m.insert("handoff_error_bound_deg".into(), ERROR_BOUND_DEG);
    for (i, role) in ROLES.iter().enumerate() {
        let mut cols: Vec<String> = ["sup_state", "sup_u2_s"].iter().map(|s| s.to_string()).collect();
        cols.extend(LAWS.iter().map(|s| s.to_string()));
        cols.extend(["transient_k1_n_m", "transient_k2_n_m_s", "transient_t_hat_entry_s"].map(String::from));
        let a = read_agent(dirs, &format!("agent-{}.csv", i + 1), &cols)?;
        let state = a.col("sup_state");
        let first = |s: usize| state.iter().position(|x| *x as usize == s);
        let mut mismatches = 0.0;
        for r in 0..a.rows() {
            let want = law_index(state[r] as usize);
            let ok = (0..3).all(|l| a.col(LAWS[l])[r] == if l == want { 1.0 } else { 0.0 });
            mismatches += if ok { 0.0 } else { 1.0 };
        }
        m.insert(format!("{role}_handoff_law_mismatch_rows"), mismatches);
        m.insert(format!("{role}_handoff_final_state"), state.last().copied().unwrap_or(f64::NAN));
        let err = plant.col(&err_cols[i]);
        m.insert(format!("{role}_handoff_error_end_deg"), err.last().copied().unwrap_or(f64::NAN));
        if let Some(r2) = first(S2) {
            m.insert(format!("{role}_handoff_s2_entry_s"), a.t[r2]);
            m.insert(format!("{role}_handoff_transient_k1_n_m"), a.col("transient_k1_n_m")[r2]);
            m.insert(format!("{role}_handoff_transient_k2_n_m_s"), a.col("transient_k2_n_m_s")[r2]);
            m.insert(format!("{role}_handoff_transient_t_hat_s"), a.col("transient_t_hat_entry_s")[r2]);
        }
        if let Some(r3) = first(S3) {
            m.insert(format!("{role}_handoff_s3_entry_s"), a.t[r3]);
            if *role == "follower" {
                m.insert("follower_handoff_u2_s".into(), a.col("sup_u2_s")[r3]);
            }
            // The plant's row of the same step (rows of both files are the same steps).
            if let Some(pr) = plant.steps().iter().position(|k| *k == a.steps()[r3]) {
                m.insert(format!("{role}_handoff_error_end_transient_deg"), err[pr]);
                // (73): e = the mean over the transient's last D = 4 s (the rows of [t3 − D, t3)).
                let from = a.t[r3] - WINDOW_S - 1e-9;
                let w: Vec<f64> = (0..pr).filter(|&q| plant.t[q] >= from).map(|q| err[q]).collect();
                let e = w.iter().sum::<f64>() / w.len() as f64;
                m.insert(format!("{role}_handoff_error_window_transient_deg"), e);
                m.insert(format!("{role}_handoff_transient_within_bound"), f64::from(u8::from(e < ERROR_BOUND_DEG)));
                science_metrics(role, &a, r3, &plant, pr, &mut m);
            }
        }
    }
    Ok(m)
}
