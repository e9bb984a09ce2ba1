//! Seed 002 analysis after a run, from the telemetry alone (so the multi-process and the
//! reference run are analysed identically): the quantities no single process has, joined from the
//! plant's truth and the agents' estimates row by row (step k with step k: the plant's row holds
//! the truth at t_k, the agent's its estimate at t_k after the measurement update, Sec. 2.10.2),
//! written to `derived/vtxo.csv` and summarised in `summary.json`:
//!
//! - per spacecraft (`leader_…`, `follower_…`) and body axis: the MEKF's true attitude error
//!   δθ (q = δq(δθ) ⊗ q̂, (47)–(50)) against its σ_θ — `mekf_within_3sigma_{x,y,z}` (the fraction
//!   of rows with |δθᵢ| ≤ 3σᵢ, the consistency test), `mekf_error_rms_{x,y,z}_rad` and
//!   `mekf_sigma_rms_{x,y,z}_rad`, and `mekf_samples`;
//! - the follower's relative navigation: `follower_r_rel_hat_error_rms_m` (‖r̂_rel − r_rel‖ over
//!   the run, ranging + interferometer), `follower_v_rel_hat_error_end_mps` and `…_max_mps`
//!   (‖v̂_rel − v_rel‖, the accelerometer-integrated velocity, Sec. 2.10.3), the drift that sets
//!   the transverse error with every model on (see the README).
//!
//! The headline metrics of the issue (time to |r_rel − r_f| < 1 m, transverse RMS/max over the
//! last 15 s, range error, thrust peak, impulse, Δv, attitude error mean/P99, energy E) are not
//! recomputed here: the plant accumulates them at every step ([`crate::model::metrics`]), which stays
//! exact when `run.telemetry_every_steps` thins the rows (a sign-law run switches every step, so
//! Δv from every tenth row would be wrong). The joins here use the rows there are: with a stride
//! the consistency fraction is a sample of every n-th step.

use std::collections::{BTreeMap, HashMap};

use cohort_report::Table;
use cohort_runtime::record::{CsvWriter, RunDirs};

use crate::model::metrics::mekf_error_rad;
use crate::model::quaternion::{Quat, V3};

/// Where the joined series go, relative to the run directory.
pub const DERIVED_FILE: &str = "derived/vtxo.csv";
pub const ROLES: [&str; 2] = ["leader", "follower"];
const XYZ: [&str; 3] = ["x", "y", "z"];

fn names(prefix: &str, unit: &str) -> [String; 3] {
    XYZ.map(|ax| format!("{prefix}_{ax}_{unit}"))
}

fn quat_names(prefix: &str) -> [String; 4] {
    ["q1", "q2", "q3", "q4"].map(|n| format!("{prefix}{n}"))
}

fn v3_at(t: &Table, cols: &[String; 3], r: usize) -> V3 {
    V3::new(t.col(&cols[0])[r], t.col(&cols[1])[r], t.col(&cols[2])[r])
}

fn quat_at(t: &Table, cols: &[String; 4], r: usize) -> Quat {
    Quat::new(t.col(&cols[0])[r], t.col(&cols[1])[r], t.col(&cols[2])[r], t.col(&cols[3])[r])
}

/// One spacecraft's running sums of the MEKF join.
#[derive(Default)]
struct Consistency {
    inside: [u64; 3],
    err2: [f64; 3],
    sigma2: [f64; 3],
    n: u64,
}

impl Consistency {
    fn add(&mut self, e: &V3, sigma: &V3) {
        self.n += 1;
        for i in 0..3 {
            self.inside[i] += u64::from(e[i].abs() <= 3.0 * sigma[i]);
            self.err2[i] += e[i] * e[i];
            self.sigma2[i] += sigma[i] * sigma[i];
        }
    }
    fn push(&self, role: &str, m: &mut BTreeMap<String, f64>) {
        if self.n == 0 {
            return;
        }
        let n = self.n as f64;
        m.insert(format!("{role}_mekf_samples"), n);
        for (i, ax) in XYZ.iter().enumerate() {
            m.insert(format!("{role}_mekf_within_3sigma_{ax}"), self.inside[i] as f64 / n);
            m.insert(format!("{role}_mekf_error_rms_{ax}_rad"), (self.err2[i] / n).sqrt());
            m.insert(format!("{role}_mekf_sigma_rms_{ax}_rad"), (self.sigma2[i] / n).sqrt());
        }
    }
}

fn read(dirs: &RunDirs, file: &str, cols: &[String]) -> Result<Table, String> {
    Table::read_columns(&dirs.telemetry().join(file), cols).map_err(|e| e.to_string())
}

/// The join (see the module docs): `derived/vtxo.csv` and its metrics.
pub fn analyse(dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    let r_rel = names("r_rel_eci", "m");
    let v_rel = names("v_rel_eci", "mps");
    let truth_q = ROLES.map(|role| quat_names(&format!("{role}_")));
    let mut want: Vec<String> = r_rel.iter().chain(&v_rel).cloned().collect();
    want.extend(truth_q.iter().flatten().cloned());
    let plant = read(dirs, "plant.csv", &want)?;
    let q_hat = quat_names("q_hat_");
    let sigma = names("sigma_theta", "rad");
    let r_hat = names("r_rel_hat_eci", "m");
    let v_hat = names("v_rel_hat_eci", "mps");
    let acs: Vec<String> = q_hat.iter().chain(&sigma).cloned().collect();
    let leader = read(dirs, "agent-1.csv", &acs)?;
    let mut f_cols = acs.clone();
    f_cols.extend(r_hat.iter().chain(&v_hat).cloned());
    let follower = read(dirs, "agent-2.csv", &f_cols)?;
    let agents = [&leader, &follower];
    // Rows by step: an agent that was dead for a while (a fault) has no rows then.
    let row_of: Vec<HashMap<u64, usize>> =
        agents.iter().map(|a| a.steps().iter().enumerate().map(|(r, k)| (*k, r)).collect()).collect();

    let mut cols = vec!["k".to_string(), "t_s".to_string()];
    for role in ROLES {
        cols.extend(names(&format!("{role}_dtheta"), "rad"));
        cols.extend(names(&format!("{role}_sigma_theta"), "rad"));
    }
    cols.extend(names("follower_r_rel_hat_error", "m"));
    cols.extend(names("follower_v_rel_hat_error", "mps"));
    std::fs::create_dir_all(dirs.root.join("derived")).map_err(|e| format!("derived/: {e}"))?;
    let path = dirs.root.join(DERIVED_FILE);
    let mut out = CsvWriter::create(&path, &cols).map_err(|e| format!("{}: {e}", path.display()))?;

    let mut cons = [Consistency::default(), Consistency::default()];
    let (mut r_err2, mut r_n, mut v_end, mut v_max) = (0.0, 0u64, f64::NAN, 0.0f64);
    let nan3 = V3::repeat(f64::NAN);
    let mut row = Vec::with_capacity(cols.len());
    for (r, &k) in plant.steps().iter().enumerate() {
        row.clear();
        row.push(plant.t[r]);
        for (i, a) in agents.iter().enumerate() {
            let (e, s) = match row_of[i].get(&k) {
                Some(&ar) => {
                    let e = mekf_error_rad(&quat_at(&plant, &truth_q[i], r), &quat_at(a, &q_hat, ar));
                    let s = v3_at(a, &sigma, ar);
                    cons[i].add(&e, &s);
                    (e, s)
                }
                None => (nan3, nan3),
            };
            row.extend(e.iter().chain(s.iter()));
        }
        let (re, ve) = match row_of[1].get(&k) {
            Some(&ar) => {
                let re = v3_at(&follower, &r_hat, ar) - v3_at(&plant, &r_rel, r);
                let ve = v3_at(&follower, &v_hat, ar) - v3_at(&plant, &v_rel, r);
                r_err2 += re.norm_squared();
                r_n += 1;
                // v̂_rel is NaN until the follower knows it (step 0).
                if ve.iter().all(|x| x.is_finite()) {
                    v_end = ve.norm();
                    v_max = v_max.max(v_end);
                }
                (re, ve)
            }
            None => (nan3, nan3),
        };
        row.extend(re.iter().chain(ve.iter()));
        out.row(k, &row).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    out.flush().map_err(|e| format!("{}: {e}", path.display()))?;

    let mut m = BTreeMap::new();
    m.insert("telemetry_rows".into(), plant.rows() as f64);
    for (c, role) in cons.iter().zip(ROLES) {
        c.push(role, &mut m);
    }
    if r_n > 0 {
        m.insert("follower_r_rel_hat_error_rms_m".into(), (r_err2 / r_n as f64).sqrt());
        m.insert("follower_v_rel_hat_error_end_mps".into(), v_end);
        m.insert("follower_v_rel_hat_error_max_mps".into(), v_max);
    }
    Ok(m)
}
