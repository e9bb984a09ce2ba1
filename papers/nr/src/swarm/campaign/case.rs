//! The swarm campaign of Sec. 7.2 of "Neural-Rendezvous" (arXiv:2208.04883): one case (a scenario
//! seed, which draws the starts and goals, the reading noise and the disturbance) flown by
//!
//! - **NR over the deep set** (with the scenario's safety filter, [`crate::swarm::control::safety`]), **NR
//!   without the filter** and **the deep set alone** (no filter): the scenario with
//!   `algorithm.method` = `nr` / `policy`, flown as the orchestrator's in-process reference run (`launch
//!   --reference`: the plant and every vehicle as threads over the in-memory transport, through
//!   the multi-process drivers, so every number equals a multi-process run's); the metrics are the
//!   run's own (`swarm_analysis`), the per-step compute the runtime's `agent_compute` (share +
//!   step of one vehicle, wall clock);
//! - **the global SCP solution** ([`crate::swarm::train::scp::solve`] on the plant's own starts and goals):
//!   flown in the same plant (same seed: the same disturbance and readings), one command per
//!   vehicle per control interval in the drivers' order. At d̄ = 0 its planned accelerations are
//!   applied open-loop (zero after T): the plant then flies the plan exactly, so the numbers are
//!   the plan's. At d̄ > 0 an open-loop plan drifts by metres; we fly it as the plan tracked with
//!   the feedback of the training targets, u = a*ₖ + K_p(p*ₖ − p̂) + K_d(v*ₖ − v̂), K_p = 4 s⁻²,
//!   K_d = 4 s⁻¹ ([`crate::swarm::train::data`]), from the vehicle's noisy reading (after T: p* = goal,
//!   v* = a* = 0). Its compute is one solve of the whole SCP (wall clock).
//!
//! Per case and method: collisions (the plant's count of entries into the ellipsoid), distinct
//! pairs, least ellipsoid distance, vehicles within 0.1 m of their goal at the end (T + 2 s),
//! ∫‖u‖dt summed over the vehicles and its ratio to the SCP's flown value of the same case, the
//! per-vehicle-step compute (p50, p99) and the speed-up of its p50 over one SCP solve.

use std::path::{Path, PathBuf};

use cohort_host::{Launcher, Mode, RunOptions, RunStatus};
use cohort_runtime::model::PlantModel;
use cohort_runtime::paper::{Setup, table_of};
use cohort_runtime::rng::process_rng;
use cohort_wire::transport::Proc;

use crate::swarm::config::{SwarmConfig, SwarmMethod};
use crate::swarm::dynamics::messages::SwarmReading;
use crate::swarm::dynamics::plant::SwarmPlant;
use crate::swarm::dynamics::setup::distance_m;
use crate::swarm::host::analysis::ARRIVED_M;
use crate::swarm::host::kinds::SwarmSetup;
use crate::swarm::train::problem::SwarmCase;
use crate::swarm::train::scp::{SwarmPlan, SwarmScpSettings};

/// Feedback gains of the SCP flown under a disturbance (the training targets').
pub const SCP_K_P_PER_S2: f64 = 4.0;
pub const SCP_K_D_PER_S: f64 = 4.0;

/// What flies a case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CampaignMethod {
    /// NR over the deep set, with the scenario's safety filter (if it has one).
    Nr,
    /// NR over the deep set without a safety filter (what the filter adds).
    NrNoFilter,
    /// The deep set alone, without a safety filter (the paper's SN-DNN alone).
    DeepSet,
    /// The global SCP solution.
    Scp,
}

impl CampaignMethod {
    pub const ALL: [CampaignMethod; 4] =
        [CampaignMethod::Nr, CampaignMethod::NrNoFilter, CampaignMethod::DeepSet, CampaignMethod::Scp];

    pub fn name(self) -> &'static str {
        match self {
            CampaignMethod::Nr => "nr",
            CampaignMethod::NrNoFilter => "nr-no-filter",
            CampaignMethod::DeepSet => "deep-set",
            CampaignMethod::Scp => "scp",
        }
    }
}

/// One case × method.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseResult {
    pub group: String,
    pub case: usize,
    pub seed: u64,
    pub n: usize,
    pub disturbance_mps2: f64,
    pub method: CampaignMethod,
    /// "ok", or why there are no numbers.
    pub status: String,
    pub collisions: f64,
    pub collision_pairs: f64,
    pub min_ellipsoid: f64,
    pub within_0_1_m: f64,
    pub max_goal_dist_m: f64,
    pub effort_mps: f64,
    /// ∫‖u‖dt over the SCP's of the same case (NaN without one).
    pub effort_ratio: f64,
    /// Per-vehicle-step compute, s (the SCP: one solve).
    pub compute_p50_s: f64,
    pub compute_p99_s: f64,
    /// Every vehicle's compute over every step of the run, summed, s (the SCP: its one solve).
    pub compute_total_s: f64,
    /// One SCP solve of the same case, s.
    pub scp_solve_s: f64,
    /// Vehicle-steps at which the safety filter changed the command, and vehicle-steps flown
    /// (NaN for the SCP).
    pub filtered_steps: f64,
    pub vehicle_steps: f64,
    /// The reference run's directory (NR, the deep set).
    pub run_dir: Option<PathBuf>,
}

impl CaseResult {
    fn empty(group: &str, case: usize, seed: u64, n: usize, d: f64, method: CampaignMethod, status: String) -> Self {
        Self {
            group: group.to_string(),
            case,
            seed,
            n,
            disturbance_mps2: d,
            method,
            status,
            collisions: f64::NAN,
            collision_pairs: f64::NAN,
            min_ellipsoid: f64::NAN,
            within_0_1_m: f64::NAN,
            max_goal_dist_m: f64::NAN,
            effort_mps: f64::NAN,
            effort_ratio: f64::NAN,
            compute_p50_s: f64::NAN,
            compute_p99_s: f64::NAN,
            compute_total_s: f64::NAN,
            scp_solve_s: f64::NAN,
            filtered_steps: f64::NAN,
            vehicle_steps: f64::NAN,
            run_dir: None,
        }
    }

    /// Speed-up of the per-vehicle-step compute (p50) over one SCP solve.
    pub fn speedup(&self) -> f64 {
        self.scp_solve_s / self.compute_p50_s
    }

    /// The same per run: the one SCP solve a run needs (its open-loop plan) against every
    /// vehicle's compute over every step.
    pub fn speedup_total(&self) -> f64 {
        self.scp_solve_s / self.compute_total_s
    }
}

/// The base scenario re-seeded and flown by `method` (nr or policy), without its safety filter
/// unless `filtered`, configured.
pub fn case_setup(
    launcher: &dyn Launcher,
    base: &Setup,
    seed: u64,
    method: SwarmMethod,
    filtered: bool,
    name: &str,
) -> Result<Setup, String> {
    let (Some(plant), Some(alg)) = (base.plant_as::<SwarmConfig>(), base.algorithm_as::<SwarmSetup>()) else {
        return Err(format!("{}: not a swarm scenario flown by nr-swarm", base.scenario.name));
    };
    let mut s = base.parsed.clone();
    s.scenario.name = name.to_string();
    s.scenario.seed = seed;
    // The case's problem is the seed's.
    s.plant.body = table_of(&SwarmConfig { problem_seed: None, ..plant.clone() }).map_err(|e| e.to_string())?;
    let mut config = alg.config.clone();
    config.method = method;
    if !filtered {
        config.safety = None;
    }
    s.algorithm.body = table_of(&config).map_err(|e| e.to_string())?;
    launcher.configure(s, name).map_err(|e| e.to_string())
}

/// Fly `setup` as the in-process reference run into `dir` and read its numbers.
pub fn fly_reference(
    launcher: &dyn Launcher,
    setup: &Setup,
    dir: &Path,
    plots: bool,
    row: &mut CaseResult,
) -> Result<(), String> {
    let r = launcher.run(setup, dir, RunOptions { mode: Mode::Reference, plots }).map_err(|e| e.to_string())?;
    row.run_dir = Some(dir.to_path_buf());
    if r.status != RunStatus::Ok {
        row.status = format!("run {}: {}", r.status, r.error.unwrap_or_default());
        return Ok(());
    }
    row.status = "ok".into();
    row.collisions = r.metric("collisions");
    row.collision_pairs = r.metric("collision_pairs");
    row.min_ellipsoid = r.metric("min_pair_ellipsoid");
    row.within_0_1_m = r.metric("within_0_1_m");
    row.max_goal_dist_m = r.metric("max_goal_dist_m");
    row.effort_mps = r.metric("total_effort_mps");
    row.filtered_steps = r.metric("filtered_steps");
    let (p50, p99, total, steps) = agent_compute(dir)?;
    (row.compute_p50_s, row.compute_p99_s, row.compute_total_s) = (p50, p99, total);
    row.vehicle_steps = steps * row.n as f64;
    Ok(())
}

/// The run's `agent_compute` p50, p99 and total over every agent and step, s, and its steps
/// (summary.json).
fn agent_compute(dir: &Path) -> Result<(f64, f64, f64, f64), String> {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let c = &v["latency_ns"]["agent_compute"];
    match (c["p50"].as_f64(), c["p99"].as_f64(), c["total"].as_f64(), v["steps_completed"].as_f64()) {
        (Some(a), Some(b), Some(t), Some(k)) => Ok((a * 1e-9, b * 1e-9, t * 1e-9, k)),
        _ => Err(format!("{}: no latency_ns.agent_compute or steps_completed", path.display())),
    }
}

/// The SCP's command for vehicle `i` at step `k` (see the module docs).
fn scp_command(plan: &SwarmPlan, i: usize, k: usize, reading: &SwarmReading, feedback: bool) -> [f64; 3] {
    let last = plan.a_mps2[i].len();
    let a = if k < last { plan.a_mps2[i][k] } else { [0.0; 3] };
    if !feedback {
        return a;
    }
    let node = k.min(last);
    let (p, v) = (plan.p_m[i][node], plan.v_mps[i][node]);
    std::array::from_fn(|c| a[c] + SCP_K_P_PER_S2 * (p[c] - reading.p_m[c]) + SCP_K_D_PER_S * (v[c] - reading.v_mps[c]))
}

/// Solve the global SCP for the plant's problem of (`plant`, n, `seed`) and fly it in that plant
/// for `steps` intervals of `dt_s` (module docs); fills `row`.
pub fn fly_scp(plant_cfg: &SwarmConfig, n: usize, seed: u64, dt_s: f64, steps: u64, row: &mut CaseResult) {
    let (starts_m, goals_m) = match crate::swarm::dynamics::setup::draw_in(n, seed, &plant_cfg.cuboid_m) {
        Ok(x) => x,
        Err(e) => {
            row.status = format!("draw: {e}");
            return;
        }
    };
    let plan = match crate::swarm::train::scp::solve(&SwarmCase { starts_m, goals_m }, &SwarmScpSettings::default()) {
        Ok(p) if p.converged => p,
        Ok(p) => {
            row.status = format!("SCP did not converge in {} iterations", p.iterations);
            return;
        }
        Err(e) => {
            row.status = e.to_string();
            return;
        }
    };
    let mut plant = SwarmPlant::new(plant_cfg.params(), n, seed, seed).expect("drawn above");
    // The readings' generator of the plant process (the noise a vehicle would read).
    let mut rng = process_rng(seed, Proc::Plant);
    let feedback = plant_cfg.disturbance_mps2 > 0.0;
    let mut buf = Vec::new();
    for k in 0..steps as usize {
        let readings: Vec<SwarmReading> = (1..=n as u32)
            .map(|id| {
                buf.clear();
                plant.readings(id, &mut rng, &mut buf);
                SwarmReading::parse(&buf).expect("the plant's own readings")
            })
            .collect();
        for (i, r) in readings.iter().enumerate() {
            plant.apply_command(i as u32 + 1, &scp_command(&plan, i, k, r, feedback));
        }
        plant.advance(dt_s);
    }
    let dist: Vec<f64> = plant.positions().iter().zip(plant.goals()).map(|(p, g)| distance_m(*p, *g)).collect();
    let c = plant.collisions();
    row.status = "ok".into();
    row.collisions = c.events as f64;
    row.collision_pairs = c.pairs() as f64;
    row.min_ellipsoid = c.min_distance;
    row.within_0_1_m = dist.iter().filter(|d| **d <= ARRIVED_M).count() as f64;
    row.max_goal_dist_m = dist.iter().copied().fold(0.0, f64::max);
    row.effort_mps = plant.effort_mps().iter().sum();
    row.effort_ratio = 1.0;
    (row.compute_p50_s, row.compute_p99_s, row.compute_total_s, row.scp_solve_s) =
        (plan.solve_s, plan.solve_s, plan.solve_s, plan.solve_s);
}

/// A case's rows, every method of `methods` (NR and the deep set from `base`).
#[allow(clippy::too_many_arguments)]
pub fn fly_case(
    launcher: &dyn Launcher,
    base: &Setup,
    group: &str,
    case: usize,
    seed: u64,
    methods: &[CampaignMethod],
    runs_dir: &Path,
    plots: bool,
) -> Result<Vec<CaseResult>, String> {
    let plant = base.plant_as::<SwarmConfig>().ok_or("not a swarm scenario")?;
    let n = base.n_agents() as usize;
    let d = plant.disturbance_mps2;
    let mut rows = Vec::new();
    for &m in methods {
        let mut row = CaseResult::empty(group, case, seed, n, d, m, String::new());
        let name = format!("{group}-{case:02}-{}", m.name());
        let started = std::time::Instant::now();
        match m {
            CampaignMethod::Scp => fly_scp(plant, n, seed, base.scenario.dt_s, base.n_steps(), &mut row),
            CampaignMethod::Nr | CampaignMethod::NrNoFilter | CampaignMethod::DeepSet => {
                let method = if m == CampaignMethod::DeepSet { SwarmMethod::Policy } else { SwarmMethod::Nr };
                let s = case_setup(launcher, base, seed, method, m == CampaignMethod::Nr, &name)?;
                fly_reference(launcher, &s, &runs_dir.join(&name), plots, &mut row)?;
            }
        }
        tracing::info!(
            "{name} (seed {seed}): {} collisions, least distance {:.3}, {} of {n} within 0.1 m, ∫‖u‖dt {:.2} m/s \
             ({:.1} s)",
            row.collisions,
            row.min_ellipsoid,
            row.within_0_1_m,
            row.effort_mps,
            started.elapsed().as_secs_f64()
        );
        rows.push(row);
    }
    // Ratios and speed-ups against this case's SCP.
    if let Some(scp) = rows.iter().find(|r| r.method == CampaignMethod::Scp && r.status == "ok").cloned() {
        for r in rows.iter_mut() {
            r.effort_ratio = r.effort_mps / scp.effort_mps;
            r.scp_solve_s = scp.scp_solve_s;
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scp_flown_open_loop_is_its_plan_and_with_feedback_rides_out_the_disturbance() {
        let cfg = SwarmConfig::default();
        let mut row = CaseResult::empty("t", 0, 5, 3, 0.0, CampaignMethod::Scp, String::new());
        fly_scp(&cfg, 3, 5, 0.1, 100, &mut row);
        assert_eq!(row.status, "ok");
        let (s, g) = crate::swarm::dynamics::setup::draw(3, 5).unwrap();
        let plan =
            crate::swarm::train::scp::solve(&SwarmCase { starts_m: s, goals_m: g }, &SwarmScpSettings::default())
                .unwrap();
        // Open loop without disturbance: the plant flies the plan (its effort, its clearance).
        assert!(
            (row.effort_mps - plan.effort_l1).abs() < 1e-9 * plan.effort_l1,
            "{} vs {}",
            row.effort_mps,
            plan.effort_l1
        );
        assert_eq!((row.collisions, row.within_0_1_m), (0.0, 3.0));
        assert!(row.max_goal_dist_m < 1e-6 && row.min_ellipsoid >= 1.0, "{row:?}");
        // d̄ = 0.2 m/s²: the feedback keeps every vehicle at its goal.
        let dist = SwarmConfig { disturbance_mps2: 0.2, ..cfg };
        let mut d = CaseResult::empty("t", 0, 5, 3, 0.2, CampaignMethod::Scp, String::new());
        fly_scp(&dist, 3, 5, 0.1, 100, &mut d);
        assert_eq!(d.within_0_1_m, 3.0, "{d:?}");
        assert!(d.effort_mps > row.effort_mps);
    }
}
