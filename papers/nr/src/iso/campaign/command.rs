//! `orchestrator nr campaign`: the evaluation of Sec. 6.3 of "Neural-Rendezvous"
//! (arXiv:2208.04883) over the test ISOs, in-process ([`crate::iso::campaign::eval`], one spacecraft per
//! run, run seed = `--seed-base` + ISO index), with the settings of a validated scenario
//! (default `topologies/nr-iso.toml`; `algorithm.method` is replaced per run):
//!
//! 1. every method of `--methods` with the scenario's navigation errors, and NMPC with perfect
//!    navigation when NMPC is among them (the global solution's own accuracy);
//! 2. the Fig. 11 analogue: Neural-Rendezvous and the SN-DNN alone at each Δt of `--dts`, the
//!    same network (trained at the scenario's Δt);
//! 3. the Fig. 9 analogue: for each γ of `--gammas`, an SN-DNN trained with C_x = γI (otherwise
//!    the reference options of `orchestrator train nr-iso`, into `OUT/weights/`), flown by NR and
//!    alone, with and without navigation errors. The sweep networks are compared byte for byte
//!    with the scenario's weights file when their options are that file's.
//!
//! Writes `campaign.md` (tables), `summary.csv`, `runs.csv`, `dt_sweep.csv`, `gamma_sweep.csv` and
//! `plots/` ([`crate::iso::campaign::report`]). Per-step compute times are wall-clock times of each
//! agent's `share` + `step` on `--threads` threads, the smallest of `--repeats` identical runs.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use clap::Args;
use cohort_host::{CommandError, Launcher};
use cohort_scenario::Overrides;

use crate::iso::campaign::eval::{CampaignOptions, RunResult, run_all, summarise};
use crate::iso::campaign::report::{self as campaign_report, Report, Row, SweepPoint};
use crate::iso::config::{IsoEncounterConfig, LinearMpcMode, Method};
use crate::iso::dynamics::constants::DV_BUDGET_MPS;
use crate::iso::host::kinds::NrSetup;
use crate::iso::train::imitation::{TrainOptions, train};
use crate::nn::sn_dnn::SnDnn;

#[derive(Args, Debug, Clone)]
pub struct CampaignArgs {
    /// The scenario whose plant and algorithm sections set up every run (its method, ISO and
    /// number of agents are replaced).
    #[arg(long, default_value = "topologies/nr-iso.toml")]
    pub scenario: PathBuf,
    /// ISOs A..B (default the test ISOs).
    #[arg(long, default_value = "200..300")]
    pub isos: String,
    /// Comma list of methods (default all seven): neural-rendezvous, sn-dnn, nmpc, robust-nmpc,
    /// linear-mpc, pd, robust-tracking.
    #[arg(long)]
    pub methods: Option<String>,
    /// Output directory (absent or empty); default runs/nr-campaign-<UTC time>/.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Threads flying runs at once (1 keeps the per-step times clean).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Fly each run this many times and keep each step's smallest wall time (results are checked
    /// bit-identical).
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Replaces plant.nav_scale (0: perfect navigation).
    #[arg(long)]
    pub nav_scale: Option<f64>,
    /// Run seed = seed base + ISO index (+ realisation × 10⁶).
    #[arg(long, default_value_t = 0)]
    pub seed_base: u64,
    /// Noise realisations per ISO (each its own seed; the tables give their spread). The Fig. 11
    /// and Fig. 9 sweeps fly one.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub realisations: u32,
    /// Control intervals of the Fig. 11 sweep, s (each dividing plant.t_f_s), or `none`.
    #[arg(long, default_value = "300,600,1200,2400")]
    pub dts: String,
    /// γ values of the Fig. 9 sweep (one training each, minutes), or `none`.
    #[arg(long, default_value = "0.1,1,10")]
    pub gammas: String,
    /// Seed of the Fig. 9 sweep's trainings.
    #[arg(long, default_value_t = 1)]
    pub train_seed: u64,
    /// Cache of the trainings' SCP data; `none` for no cache.
    #[arg(long, default_value = "target/nr-cache")]
    pub cache: String,
    /// Draw no plots.
    #[arg(long)]
    pub no_plots: bool,
}

/// Everything checked before anything runs.
struct Plan {
    base: CampaignOptions,
    scenario_weights: Option<PathBuf>,
    out: PathBuf,
    dts: Vec<f64>,
    gammas: Vec<f64>,
}

fn plan(a: &CampaignArgs, launcher: &dyn Launcher) -> Result<Plan, CommandError> {
    let bad = CommandError::invalid;
    let isos = crate::iso::cli::isos("--isos", &a.isos).map_err(bad)?;
    let methods = match &a.methods {
        Some(m) => crate::iso::cli::methods("--methods", m).map_err(bad)?,
        None => Method::ALL.to_vec(),
    };
    if a.threads == 0 || a.threads > 64 {
        return Err(bad(format!("--threads {}: 1–64", a.threads)));
    }
    if a.repeats == 0 || a.repeats > 100 {
        return Err(bad(format!("--repeats {}: 1–100", a.repeats)));
    }
    if let Some(x) = a.nav_scale.filter(|x| !(x.is_finite() && *x >= 0.0)) {
        return Err(bad(format!("--nav-scale {x}: must be a number ≥ 0")));
    }
    let setup = launcher.load(&a.scenario, &Overrides::default())?;
    let file = a.scenario.display();
    let (Some(plant), Some(alg)) = (setup.plant_as::<IsoEncounterConfig>(), setup.algorithm_as::<NrSetup>()) else {
        return Err(bad(format!("{file}: not an iso-encounter scenario flown by neural-rendezvous")));
    };
    if methods.iter().any(|m| m.needs_weights()) && alg.net.is_none() {
        return Err(bad(format!("{file}: algorithm.weights is not set, and {} need the SN-DNN", describe(&methods))));
    }
    let t_f = plant.t_f_s;
    let divides = |dt: f64| dt > 0.0 && ((t_f / dt) - (t_f / dt).round()).abs() < 1e-9 * (t_f / dt);
    let dts = crate::iso::cli::numbers("--dts", &a.dts, divides, &format!("must divide plant.t_f_s = {t_f} s"))
        .map_err(bad)?;
    let gammas = crate::iso::cli::numbers("--gammas", &a.gammas, |g| g >= 0.0, "must be ≥ 0").map_err(bad)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/nr-campaign-{}", cohort_host::utc_stamp())));
    if std::fs::read_dir(&out).is_ok_and(|mut d| d.next().is_some()) {
        return Err(bad(format!("--out {}: not empty", out.display())));
    }
    let mut base = CampaignOptions::new(methods, alg.net.clone());
    base.isos = isos;
    base.plant = IsoEncounterConfig { nav_scale: a.nav_scale.unwrap_or(plant.nav_scale), ..plant.clone() };
    base.algorithm = alg.config.clone();
    base.dt_s = setup.scenario.dt_s;
    base.seed_base = a.seed_base;
    base.realisations = a.realisations;
    base.threads = a.threads;
    base.timing_repeats = a.repeats;
    Ok(Plan { base, scenario_weights: alg.config.weights.clone(), out, dts, gammas })
}

fn describe(methods: &[Method]) -> String {
    methods.iter().filter(|m| m.needs_weights()).map(|m| m.name()).collect::<Vec<_>>().join(" and ")
}

fn stopped(launcher: &dyn Launcher) -> Result<(), CommandError> {
    match launcher.interrupted() {
        Some(sig) => Err(CommandError {
            message: format!("interrupted by signal {sig}; the finished parts are not written"),
            exit_code: 128u8.saturating_add(sig as u8),
        }),
        None => Ok(()),
    }
}

/// Every run of `o`; a signal stops them between runs (the runs under way finish first).
fn fly(o: &CampaignOptions, launcher: &dyn Launcher) -> Result<Vec<RunResult>, CommandError> {
    let runs = run_all(o, &|| launcher.interrupted().is_some());
    stopped(launcher)?;
    runs.map_err(CommandError::failed)
}

/// The sweeps fly the methods of the campaign that use the SN-DNN.
fn learned(methods: &[Method]) -> Vec<Method> {
    [Method::NeuralRendezvous, Method::SnDnn].into_iter().filter(|m| methods.contains(m)).collect()
}

fn points(o: &CampaignOptions, runs: &[RunResult], x: f64, nav: &'static str) -> Vec<SweepPoint> {
    summarise(o, runs).into_iter().map(|s| SweepPoint { x, nav, summary: s }).collect()
}

fn dt_sweep(p: &Plan, launcher: &dyn Launcher) -> Result<Vec<SweepPoint>, CommandError> {
    let mut out = Vec::new();
    for &dt in &p.dts {
        stopped(launcher)?;
        let o = CampaignOptions { methods: learned(&p.base.methods), dt_s: dt, realisations: 1, ..p.base.clone() };
        out.extend(points(&o, &fly(&o, launcher)?, dt, "noisy"));
    }
    Ok(out)
}

/// Train one network per γ into `OUT/weights/`, fly it with and without navigation errors.
fn gamma_sweep(
    p: &Plan,
    a: &CampaignArgs,
    launcher: &dyn Launcher,
    notes: &mut Vec<String>,
) -> Result<Vec<SweepPoint>, CommandError> {
    let mut out = Vec::new();
    for &gamma in &p.gammas {
        stopped(launcher)?;
        let path = p.out.join("weights").join(format!("sn-dnn-gamma-{gamma}.safetensors"));
        let mut o = TrainOptions::reference(path.clone(), a.train_seed);
        o.gamma = gamma;
        o.cache_dir = (a.cache != "none").then(|| PathBuf::from(&a.cache));
        let started = Instant::now();
        let report = train(&o).map_err(|e| CommandError::failed(format!("training γ = {gamma}: {e}")))?;
        tracing::info!("γ = {gamma}: trained in {:.0} s ({})", started.elapsed().as_secs_f64(), report.timings());
        notes.push(same_as_scenario(&path, p.scenario_weights.as_deref(), gamma));
        let net = Arc::new(SnDnn::load(&path).map_err(|e| CommandError::failed(e.to_string()))?);
        for (nav, scale) in [("noisy", p.base.plant.nav_scale), ("perfect", 0.0)] {
            let mut c = CampaignOptions {
                methods: learned(&p.base.methods),
                net: Some(net.clone()),
                realisations: 1,
                ..p.base.clone()
            };
            c.plant.nav_scale = scale;
            c.algorithm.weights = Some(path.clone());
            out.extend(points(&c, &fly(&c, launcher)?, gamma, nav));
        }
    }
    Ok(out)
}

/// Whether a sweep network equals the scenario's weights file, when that file was trained with
/// the same γ (its metadata says): a check that the training reproduces the committed bytes.
fn same_as_scenario(trained: &Path, scenario: Option<&Path>, gamma: f64) -> String {
    let Some(file) = scenario else { return String::new() };
    let Ok(net) = SnDnn::load(file) else { return String::new() };
    let t = &net.metadata()["training"];
    if t["gamma"].as_f64() != Some(gamma) {
        return String::new();
    }
    let same = std::fs::read(trained).ok().zip(std::fs::read(file).ok()).is_some_and(|(a, b)| a == b);
    format!(
        "γ = {gamma} (training seed {}): the trained file is {} the scenario's weights file {}",
        t["seed"],
        if same { "byte for byte" } else { "NOT" },
        file.display()
    )
}

/// The like-for-like baselines beside the main rows: PD and robust tracking kept to the Δv budget,
/// and linear MPC solved once at t = 0 and flown open-loop (the paper's reading), each flown on
/// the same ISOs and noise as its unconstrained, receding row.
fn variants(
    p: &Plan,
    launcher: &dyn Launcher,
    rows: &mut Vec<Row>,
    all_runs: &mut Vec<(String, RunResult)>,
) -> Result<(), CommandError> {
    let budget = format!("Δv budget {DV_BUDGET_MPS} m/s");
    for m in [Method::Pd, Method::RobustTracking, Method::LinearMpc] {
        if !p.base.methods.contains(&m) {
            continue;
        }
        stopped(launcher)?;
        let mut o = CampaignOptions { methods: vec![m], ..p.base.clone() };
        let what = if m == Method::LinearMpc {
            o.algorithm.linear_mpc = LinearMpcMode::Once;
            "one solve at t = 0".to_string()
        } else {
            o.algorithm.dv_budget_mps = Some(DV_BUDGET_MPS);
            budget.clone()
        };
        extra_row(&o, launcher, &format!("{}, {what}", m.name()), &format!("noisy, {what}"), rows, all_runs)?;
    }
    Ok(())
}

/// Fly `o` (one method) and add its row `label` and its runs, labelled `nav`.
fn extra_row(
    o: &CampaignOptions,
    launcher: &dyn Launcher,
    label: &str,
    nav: &str,
    rows: &mut Vec<Row>,
    all_runs: &mut Vec<(String, RunResult)>,
) -> Result<(), CommandError> {
    let runs = fly(o, launcher)?;
    let s = summarise(o, &runs).remove(0);
    rows.push(Row { label: label.to_string(), summary: s });
    all_runs.extend(runs.into_iter().map(|r| (nav.to_string(), r)));
    Ok(())
}

/// The command.
pub fn run(a: &CampaignArgs, launcher: &dyn Launcher) -> Result<String, CommandError> {
    let started = Instant::now();
    let p = plan(a, launcher)?;
    std::fs::create_dir_all(&p.out).map_err(|e| CommandError::invalid(format!("--out {}: {e}", p.out.display())))?;
    let runs = fly(&p.base, launcher)?;
    let mut rows: Vec<Row> =
        summarise(&p.base, &runs).into_iter().map(|s| Row { label: s.method.name().to_string(), summary: s }).collect();
    let mut all_runs: Vec<(String, RunResult)> = runs.iter().map(|r| ("noisy".to_string(), r.clone())).collect();
    // With perfect navigation: NMPC (the global solution's floor) and NR (where its bound fails).
    for m in [Method::Nmpc, Method::NeuralRendezvous] {
        if !p.base.methods.contains(&m) || p.base.plant.nav_scale == 0.0 {
            continue;
        }
        stopped(launcher)?;
        // One realisation: without navigation noise only the initial dispersion would differ.
        let mut o = CampaignOptions { methods: vec![m], realisations: 1, ..p.base.clone() };
        o.plant.nav_scale = 0.0;
        extra_row(&o, launcher, &format!("{}, perfect navigation", m.name()), "perfect", &mut rows, &mut all_runs)?;
    }
    variants(&p, launcher, &mut rows, &mut all_runs)?;
    let dt = dt_sweep(&p, launcher)?;
    let mut notes = Vec::new();
    let gamma = gamma_sweep(&p, a, launcher, &mut notes)?;
    let report = Report {
        command: command_line(a),
        options: &p.base,
        rows: &rows,
        runs: &all_runs,
        dt_sweep: &dt,
        gamma_sweep: &gamma,
        notes: notes.into_iter().filter(|n| !n.is_empty()).collect(),
        wall_s: started.elapsed().as_secs_f64(),
    };
    let md = campaign_report::write(&p.out, &report, !a.no_plots).map_err(CommandError::failed)?;
    Ok(format!("{md}\nwritten: {}", p.out.display()))
}

fn command_line(a: &CampaignArgs) -> String {
    let mut c = format!(
        "orchestrator nr campaign --scenario {} --isos {} --threads {} --repeats {} --dts {} --gammas {}",
        a.scenario.display(),
        a.isos,
        a.threads,
        a.repeats,
        a.dts,
        a.gammas
    );
    if let Some(m) = &a.methods {
        c += &format!(" --methods {m}");
    }
    if let Some(x) = a.nav_scale {
        c += &format!(" --nav-scale {x}");
    }
    if a.seed_base != 0 {
        c += &format!(" --seed-base {}", a.seed_base);
    }
    if a.realisations != 1 {
        c += &format!(" --realisations {}", a.realisations);
    }
    c
}
