//! The swarm run's analysis (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883), from the plant's
//! end-of-run file `snapshots/swarm.csv` and the agents' telemetry alone, so the multi-process and
//! reference runs of a scenario get the same numbers:
//!
//! - `collisions` (entries of a pair into ‖diag(0.12, 0.12, 0.30)⁻¹Δp‖ < 1, checked at every
//!   plant sub-step), `collision_pairs`, `min_pair_ellipsoid` (the least pairwise distance in that
//!   metric over the run), `outside_cuboid_substeps`;
//! - per vehicle j: `a{j}_goal_dist_m` at the end of the run, `a{j}_goal_dist_at_t_m` at the
//!   reconfiguration time T (absent when the run stopped before T), `a{j}_effort_mps` = ∫‖u‖dt;
//! - over the swarm: `max_goal_dist_m`, `mean_goal_dist_m`, `within_0_1_m` (vehicles within
//!   0.1 m of their goal at the end), `max_goal_dist_at_t_m`, `total_effort_mps`;
//! - from the agents: `du_active_share` (steps where the min-norm control changed the policy's
//!   command, of all vehicle-steps), `max_observed` (most neighbours a vehicle observed),
//!   `clipped_steps` and `bad_readings` (summed over the vehicles), `filtered_steps` (steps the
//!   safety filter changed a command) and `filter_failures` (its solver failed, the nominal was
//!   flown), summed over the vehicles (0 without a filter);
//! - from the plant's rows: `max_stray_m` and `unlisted_pairs_within_r_comm`, whether the run kept
//!   the neighbour rule's assumption ([`crate::swarm::host::stray`]).

use std::collections::BTreeMap;
use std::path::Path;

use cohort_report::Table;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;

use crate::swarm::control::agent::MODE_BAD_READINGS;
use crate::swarm::dynamics::plant::SWARM_FILE;
use crate::swarm::host::kinds::SwarmSetup;

/// Within this of its goal a vehicle has arrived, m (the 0.1 m).
pub const ARRIVED_M: f64 = 0.1;

/// One vehicle's entry of `snapshots/swarm.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleEnd {
    pub p_m: [f64; 3],
    pub goal_m: [f64; 3],
    pub goal_dist_m: f64,
    pub goal_dist_at_t_m: f64,
    pub effort_mps: f64,
}

/// The run's `snapshots/swarm.csv`: every vehicle's entry and the swarm's columns by name.
pub fn read_end(run_dir: &Path, n: u32) -> Result<(Vec<VehicleEnd>, BTreeMap<String, f64>), String> {
    let path = run_dir.join("snapshots").join(SWARM_FILE);
    let t = Table::read(&path).map_err(|e| e.to_string())?;
    if t.rows() != 1 {
        return Err(format!("{}: {} rows, expected 1", path.display(), t.rows()));
    }
    let get = |name: &str| -> Result<f64, String> {
        t.get(name).map(|c| c[0]).ok_or_else(|| format!("{}: no column {name}", path.display()))
    };
    let vehicles = (1..=n)
        .map(|j| {
            let g = |c: &str| get(&format!("a{j}_{c}"));
            Ok(VehicleEnd {
                p_m: [g("p_x_m")?, g("p_y_m")?, g("p_z_m")?],
                goal_m: [g("goal_x_m")?, g("goal_y_m")?, g("goal_z_m")?],
                goal_dist_m: g("goal_dist_m")?,
                goal_dist_at_t_m: g("goal_dist_at_t_m")?,
                effort_mps: g("effort_mps")?,
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    let swarm = crate::swarm::dynamics::plant::SWARM_COLUMNS
        .iter()
        .map(|c| Ok((c.to_string(), get(c)?)))
        .collect::<Result<_, String>>()?;
    Ok((vehicles, swarm))
}

fn vehicle_metrics(v: &[VehicleEnd], m: &mut BTreeMap<String, f64>) {
    for (j, e) in (1..).zip(v) {
        m.insert(format!("a{j}_goal_dist_m"), e.goal_dist_m);
        if e.goal_dist_at_t_m.is_finite() {
            m.insert(format!("a{j}_goal_dist_at_t_m"), e.goal_dist_at_t_m);
        }
        m.insert(format!("a{j}_effort_mps"), e.effort_mps);
    }
    let n = v.len().max(1) as f64;
    m.insert("max_goal_dist_m".into(), v.iter().map(|e| e.goal_dist_m).fold(0.0, f64::max));
    m.insert("mean_goal_dist_m".into(), v.iter().map(|e| e.goal_dist_m).sum::<f64>() / n);
    m.insert("within_0_1_m".into(), v.iter().filter(|e| e.goal_dist_m <= ARRIVED_M).count() as f64);
    if v.iter().all(|e| e.goal_dist_at_t_m.is_finite()) {
        m.insert("max_goal_dist_at_t_m".into(), v.iter().map(|e| e.goal_dist_at_t_m).fold(0.0, f64::max));
    }
    m.insert("total_effort_mps".into(), v.iter().map(|e| e.effort_mps).sum());
}

/// The metrics of the module docs (empty for a run of other kinds).
pub fn analyse(s: &Setup, dirs: &RunDirs) -> Result<BTreeMap<String, f64>, String> {
    if s.algorithm_as::<SwarmSetup>().is_none() {
        return Ok(BTreeMap::new());
    }
    let n = s.n_agents();
    let (vehicles, swarm) = read_end(&dirs.root, n)?;
    let mut m: BTreeMap<String, f64> = swarm.into_iter().filter(|(k, _)| k != "t_reconfig_s").collect();
    vehicle_metrics(&vehicles, &mut m);
    let r_comm_m =
        s.algorithm_as::<SwarmSetup>().map_or(crate::swarm::dynamics::setup::R_COMM_M, |a| a.config.r_comm_m);
    crate::swarm::host::stray::metrics(s, dirs, &vehicles, r_comm_m, &mut m)?;
    let (mut active, mut steps, mut observed, mut clipped, mut bad) = (0usize, 0usize, 0.0f64, 0.0, 0usize);
    let (mut filtered, mut failures) = (0.0, 0.0);
    for j in 1..=n {
        let path = dirs.telemetry().join(format!("agent-{j}.csv"));
        let a = Table::read_columns(
            &path,
            &["mode", "du_mps2", "n_observed", "clipped_steps", "filtered_steps", "filter_failures"],
        )
        .map_err(|e| e.to_string())?;
        steps += a.rows();
        active += a.col("du_mps2").iter().filter(|d| **d > 0.0).count();
        observed = observed.max(a.col("n_observed").iter().copied().fold(0.0, f64::max));
        clipped += a.col("clipped_steps").last().copied().unwrap_or(0.0);
        filtered += a.col("filtered_steps").last().copied().unwrap_or(0.0);
        failures += a.col("filter_failures").last().copied().unwrap_or(0.0);
        bad += a.col("mode").iter().filter(|x| **x == MODE_BAD_READINGS).count();
    }
    m.insert("du_active_share".into(), active as f64 / steps.max(1) as f64);
    m.insert("max_observed".into(), observed);
    m.insert("clipped_steps".into(), clipped);
    m.insert("bad_readings".into(), bad as f64);
    m.insert("filtered_steps".into(), filtered);
    m.insert("filter_failures".into(), failures);
    Ok(m)
}
