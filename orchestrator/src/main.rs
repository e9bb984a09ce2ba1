//! `orchestrator`: validate scenarios, launch runs (multi-process over iceoryx2, or the in-process
//! reference), and draw their reports.
//!
//! Exit codes: 0 success; 1 the run failed; 2 invalid input (scenario, arguments, run
//! directory); 128 + signal when interrupted (130 for Ctrl-C).

mod analysis;
mod bench;
mod continuous;
mod dai_analysis;
mod dai_readings;
mod dai_tables;
mod progress;
mod reference;
mod report;
mod report_tsnr;
mod rundir;
mod soak;
mod summary;
mod supervise;
mod sweep_report;
mod tsnr_analysis;
mod tsnr_compare;
mod tsnr_train;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use cohort_runtime::record::RunDirs;
use cohort_scenario::{Overrides, Scenario};
use cohort_wire::transport::iox::IoxRun;

const EXIT_FAILED: u8 = 1;
const EXIT_INVALID: u8 = 2;

#[derive(Parser)]
#[command(name = "orchestrator", version = cohort_wire::BUILD_ID, about = "Cohort: run decentralised spacecraft-formation algorithms the way they would fly")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Validate scenario files without running anything (exit 2 if any is invalid).
    Check {
        /// Scenario files (TOML).
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Validate a scenario, run it, and write its run directory.
    Launch {
        /// Scenario file (TOML).
        file: PathBuf,
        /// Run directory (absent or empty); default runs/<scenario>-<UTC time>/.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override scenario.seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Override scenario.duration_s, in seconds.
        #[arg(long)]
        duration: Option<f64>,
        /// Override run.step_timeout_s, in seconds.
        #[arg(long)]
        step_timeout: Option<f64>,
        /// Run the plant and every agent as threads of this process over the in-memory
        /// transport (the bit-identical reference of the multi-process run).
        #[arg(long)]
        reference: bool,
        /// Do not draw the plots after a successful run.
        #[arg(long)]
        no_plots: bool,
        /// Override run.wait: adaptive, event or poll.
        #[arg(long)]
        wait: Option<String>,
        /// Override run.spin_us (the adaptive spin budget), µs.
        #[arg(long)]
        spin_us: Option<f64>,
        /// Override run.link_delay_steps (0 or 1).
        #[arg(long)]
        link_delay: Option<u32>,
        /// Override run.transport: iceoryx2 or udp.
        #[arg(long)]
        transport: Option<String>,
        /// Pace the plant by the wall clock (sets run.realtime_rate).
        #[arg(long)]
        realtime: bool,
        /// With --realtime: sim seconds per wall second.
        #[arg(long, default_value_t = 1.0, requires = "realtime")]
        rate: f64,
        /// What a dead or silent agent does to the run: degrade (go on without it; exit 1 at the
        /// end if the loss was not planned) or abort (sets run.on_agent_loss).
        #[arg(long, value_name = "degrade|abort")]
        on_agent_loss: Option<String>,
        /// Inject a fault (repeatable): KIND:agent=ID@t=SECONDS[,for=SECONDS][,p=PROB][,steps=N],
        /// KIND one of kill, freeze, restart, delay, drop, corrupt (see topologies/README.md).
        #[arg(long, value_name = "SPEC")]
        fault: Vec<String>,
    },
    /// Run a scenario multi-process again and again for a wall-clock budget, watching latency
    /// per link, deadline misses, message counts, RSS and iceoryx2 entries (exit 1 when one of
    /// them goes wrong; see soak.md in the output directory).
    Soak {
        /// Scenario file (TOML).
        file: PathBuf,
        /// Wall-clock budget: 10m, 90s, 1h.
        #[arg(long, default_value = "10m")]
        wall: String,
        /// Pace the plant by the wall clock.
        #[arg(long)]
        realtime: bool,
        /// With --realtime: sim seconds per wall second.
        #[arg(long, default_value_t = 1.0, requires = "realtime")]
        rate: f64,
        /// Random faults in every run: a comma list of kinds (kill,freeze,restart,delay,drop,corrupt).
        #[arg(long, value_name = "KINDS")]
        faults: Option<String>,
        /// Output directory; default runs/<scenario>-soak-<UTC time>/.
        #[arg(long)]
        out: Option<PathBuf>,
        /// First run's seed (then +1 per run); default the scenario's.
        #[arg(long)]
        seed: Option<u64>,
    },
    /// Run a scenario once per seed (in-process reference runs by default) and write the
    /// distribution of its summary metrics as Markdown and CSV.
    Sweep {
        /// Scenario file (TOML).
        file: PathBuf,
        #[command(flatten)]
        args: SweepArgs,
    },
    /// Seed 001: run a tsnr-formation scenario once per method, multi-process, and write the
    /// analogue of the paper's Tables 1–2 (fuel per MU beside the published values) with each
    /// run's tracking, thrust and solver metrics (compare.md, compare.csv); each run's directory
    /// is DIR/<method>/.
    Compare {
        /// Scenario file (TOML) with algorithm.kind = "tsnr-formation".
        file: PathBuf,
        /// Methods to run, in this order: a comma list of aemc, dmpc, smc (each at most once).
        #[arg(long, value_name = "LIST")]
        algorithms: String,
        /// Output directory (absent or empty); default runs/<scenario>-compare-<UTC time>/.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Draw neither the runs' plots nor the comparison figures.
        #[arg(long)]
        no_plots: bool,
    },
    /// Measure what the multi-process runtime costs (see bench/results.md); run from the
    /// repository root.
    Bench {
        /// A short smoke version (fewer cases, fewer steps, one repetition).
        #[arg(long)]
        quick: bool,
        /// Interleaved repetitions of every case.
        #[arg(long)]
        reps: Option<u32>,
        /// Where results.md and results.json go.
        #[arg(long, default_value = "bench")]
        out: PathBuf,
    },
    /// Seed 004's tables: the analogues of the paper's Tables 2 and 4 (continuous-time) and the
    /// sampled-data study (multi-process at 0.01, 0.1, 1, 10, 100 ms), in Markdown and CSV beside the
    /// published values, with plots; run from the repository root.
    DaiTables {
        /// Output directory (tables, plots, and every run's directory under runs/).
        #[arg(long, default_value = "runs/dai-tables")]
        out: PathBuf,
        /// Directory holding dai.toml and dai-sampled.toml.
        #[arg(long, default_value = "topologies")]
        topologies: PathBuf,
        /// Control periods of the sampled-data study, ms (none: skip the study).
        #[arg(long, value_delimiter = ',', default_values_t = [0.01, 0.1, 1.0, 10.0, 100.0])]
        periods_ms: Vec<f64>,
        /// Run the sampled-data study in-process (bit-identical, faster) instead of multi-process.
        #[arg(long)]
        in_process: bool,
    },
    /// Train a learned model offline and write its weights file and a report beside it.
    Train {
        #[command(subcommand)]
        what: TrainCmd,
    },
    /// Draw PNG plots of a run directory's telemetry into RUN_DIR/plots/.
    Report {
        /// A run directory written by `launch`.
        run_dir: PathBuf,
    },
}

#[derive(Subcommand)]
enum TrainCmd {
    /// Seed 001's DNN tension predictor (eqs. (7)–(11)): simulate random capture trajectories with
    /// the net plant, train with candle (CPU), write the weights (safetensors) and
    /// NAME-report.md/.json beside them. Deterministic for a given seed.
    TsnrTension {
        /// Weights file to write, e.g. tsnr/weights/tension.safetensors.
        #[arg(long)]
        out: PathBuf,
        /// Seeds the trajectories, the initial weights and the batch order.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Trajectories of 30 s to simulate (a fifth held out for the report).
        #[arg(long, default_value_t = 300)]
        trajectories: u64,
        /// Passes over the training windows.
        #[arg(long, default_value_t = 25)]
        epochs: usize,
    },
}

#[derive(Args)]
struct SweepArgs {
    /// Number of seeds.
    #[arg(long, default_value_t = 10)]
    seeds: u64,
    /// First seed; the sweep uses first-seed, first-seed + 1, ...
    #[arg(long, default_value_t = 1)]
    first_seed: u64,
    /// Directory for the runs and the results; default runs/<scenario>-sweep-<UTC time>/.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override scenario.duration_s, in seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Run every seed multi-process instead of in-process (the two are bit-identical; the
    /// in-process reference is faster).
    #[arg(long)]
    multi_process: bool,
    /// Keep each run's telemetry (fig1: ~130 MB per run).
    #[arg(long)]
    keep_telemetry: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Check { files } => check(&files),
        Cmd::Launch {
            file,
            out,
            seed,
            duration,
            step_timeout,
            reference,
            no_plots,
            wait,
            spin_us,
            link_delay,
            transport,
            realtime,
            rate,
            fault,
            on_agent_loss,
        } => {
            let mut faults = Vec::new();
            for (k, f) in fault.iter().enumerate() {
                match cohort_scenario::faults::FaultSpec::parse_cli(f) {
                    Ok(spec) => faults.push(spec),
                    Err(e) => {
                        eprintln!("error: --fault (#{}): {e}", k + 1);
                        return ExitCode::from(EXIT_INVALID);
                    }
                }
            }
            let o = Overrides {
                seed,
                duration_s: duration,
                step_timeout_s: step_timeout,
                wait,
                spin_us,
                link_delay_steps: link_delay,
                transport,
                realtime_rate: realtime.then_some(rate),
                faults,
                on_agent_loss,
                method: None,
            };
            launch(&file, out.as_deref(), &o, reference, !no_plots)
        }
        Cmd::Sweep { file, args } => sweep(&file, &args),
        Cmd::Compare { file, algorithms, out, no_plots } => compare(&file, &algorithms, out.as_deref(), !no_plots),
        Cmd::Soak { file, wall, realtime, rate, faults, out, seed } => {
            let wall = match soak::parse_wall(&wall) {
                Ok(w) => w,
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(EXIT_INVALID);
                }
            };
            let faults = match faults.as_deref().map(soak::parse_fault_kinds).transpose() {
                Ok(f) => f.unwrap_or_default(),
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(EXIT_INVALID);
                }
            };
            if realtime && !(rate.is_finite() && rate > 0.0) {
                eprintln!("error: --rate {rate}: must be a positive number");
                return ExitCode::from(EXIT_INVALID);
            }
            if let Err(e) = supervise::install_signal_handlers() {
                eprintln!("error: {e}");
                return ExitCode::from(EXIT_FAILED);
            }
            let out = out.unwrap_or_else(|| {
                let stem = file.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
                PathBuf::from(format!("runs/{stem}-soak-{}", rundir::utc_stamp()))
            });
            let o = soak::Options { file, wall, realtime, rate, faults, out, seed };
            match soak::run(&o) {
                Ok((md, ok)) => {
                    println!("{md}");
                    println!("written: {} (soak.md, soak.json, *.png)", o.out.display());
                    if ok { ExitCode::SUCCESS } else { ExitCode::from(EXIT_FAILED) }
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(EXIT_INVALID)
                }
            }
        }
        Cmd::Bench { quick, reps, out } => {
            if let Err(e) = supervise::install_signal_handlers() {
                eprintln!("error: {e}");
                return ExitCode::from(EXIT_FAILED);
            }
            match bench::run(quick, reps.unwrap_or(if quick { 1 } else { 3 }), &out) {
                Ok(md) => {
                    println!("{md}");
                    println!(
                        "written: {} and {}",
                        out.join("results.md").display(),
                        out.join("results.json").display()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(EXIT_FAILED)
                }
            }
        }
        Cmd::DaiTables { out, topologies, periods_ms, in_process } => {
            if let Err(e) = supervise::install_signal_handlers() {
                eprintln!("error: {e}");
                return ExitCode::from(EXIT_FAILED);
            }
            if let Some(p) = periods_ms.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
                eprintln!("error: --periods-ms {p}: periods must be positive");
                return ExitCode::from(EXIT_INVALID);
            }
            let o = dai_tables::Options {
                out,
                topologies,
                periods_s: periods_ms.iter().map(|p| p * 1e-3).collect(),
                sampled_multi_process: !in_process,
            };
            match dai_tables::run_all(&o) {
                Ok(md) => {
                    println!("{md}");
                    println!("written: {}", o.out.join("dai-tables.md").display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(EXIT_FAILED)
                }
            }
        }
        Cmd::Train { what: TrainCmd::TsnrTension { out, seed, trajectories, epochs } } => {
            let command = format!(
                "orchestrator train tsnr-tension --out {} --seed {seed} --trajectories {trajectories} --epochs {epochs}",
                out.display()
            );
            let o = tsnr_train::Options { out, seed, trajectories, epochs, n_t: 10 };
            match tsnr_train::run(&o, &command) {
                Ok(md) => {
                    println!("{md}");
                    let (json, md_path) = tsnr_train::report_paths(&o.out);
                    println!("written: {}, {} and {}", o.out.display(), md_path.display(), json.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(EXIT_FAILED)
                }
            }
        }
        Cmd::Report { run_dir } => match report::report(&run_dir) {
            Ok(files) => {
                for f in files {
                    println!("{}", f.display());
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(EXIT_INVALID)
            }
        },
    }
}

fn check(files: &[PathBuf]) -> ExitCode {
    let mut bad = false;
    for f in files {
        match cohort_scenario::load(f, &Overrides::default()) {
            Ok(s) => println!(
                "ok: {} ({} agents, {} steps of {} s)",
                f.display(),
                s.n_agents(),
                s.n_steps(),
                s.scenario.dt_s
            ),
            Err(e) => {
                eprintln!("{e}");
                bad = true;
            }
        }
    }
    if bad { ExitCode::from(EXIT_INVALID) } else { ExitCode::SUCCESS }
}

/// A fresh run id: random, so concurrent runs never share iceoryx2 resources.
fn new_run_id() -> u64 {
    let mut b = [0u8; 8];
    if std::fs::File::open("/dev/urandom").and_then(|mut f| std::io::Read::read_exact(&mut f, &mut b)).is_ok() {
        return u64::from_le_bytes(b);
    }
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    (t.as_nanos() as u64) ^ (u64::from(std::process::id()) << 32)
}

/// One run, start to summary: the run directory must exist with its scenario.toml written.
fn run_once(
    s: &Scenario,
    dirs: &RunDirs,
    reference: bool,
    show_progress: bool,
) -> (supervise::LaunchOutcome, summary::Summary) {
    let run_id = new_run_id();
    let continuous = s.dai_continuous().is_some();
    let mode = if continuous {
        "continuous"
    } else if reference {
        "reference"
    } else {
        "multi-process"
    };
    let progress = progress::Progress::new(s.n_steps(), s.scenario.dt_s, &s.scenario.name, show_progress);
    let outcome = if continuous {
        // Seed 004's coupled ODE exists only in-process (see continuous.rs).
        continuous::launch(s, dirs, &progress)
    } else if reference {
        reference::launch(s, dirs, run_id, &progress)
    } else {
        supervise::launch(s, dirs, &IoxRun::new(run_id), &progress)
    };
    progress.finish();
    let mut summary = summary::build(
        s,
        dirs,
        summary::Outcome {
            startup_s: outcome.startup_s,
            mode,
            run_id: format!("{run_id:016x}"),
            status: outcome.status,
            error: outcome.error.clone(),
            wall_s: outcome.wall_s,
            timeline: outcome.timeline.clone(),
        },
    );
    // Derived quantities come from the telemetry alone, so a partial run gets them too.
    match analysis::analyse(s, dirs) {
        Ok(extra) => summary.metrics.extend(extra),
        Err(e) => eprintln!("warning: analysis skipped: {e}"),
    }
    match analysis::fault_effects(s, dirs, &outcome.timeline) {
        Ok(extra) => summary.metrics.extend(extra),
        Err(e) => eprintln!("warning: fault effects skipped: {e}"),
    }
    if let Err(e) = summary::write(dirs, &summary) {
        eprintln!("error: cannot write {}: {e}", dirs.root.join("summary.json").display());
    }
    (outcome, summary)
}

/// The soak's scenario, validated once up front (with its first run's settings).
fn load_for_soak(file: &Path, o: &soak::Options) -> Result<Scenario, String> {
    let ov = Overrides { seed: o.seed, realtime_rate: o.realtime.then_some(o.rate), ..Default::default() };
    let s = cohort_scenario::load(file, &ov).map_err(|e| e.to_string())?;
    if s.dai_continuous().is_some() {
        return Err(format!(
            "{}: a continuous-coupling scenario runs in one process; a soak needs processes",
            file.display()
        ));
    }
    Ok(s)
}

fn load_or_exit(file: &Path, o: &Overrides) -> Result<Scenario, ExitCode> {
    cohort_scenario::load(file, o).map_err(|e| {
        eprintln!("{e}");
        ExitCode::from(EXIT_INVALID)
    })
}

fn prepare(s: &Scenario, out: Option<&Path>) -> Result<RunDirs, ExitCode> {
    let dirs = rundir::create(out, &s.scenario.name).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(EXIT_INVALID)
    })?;
    std::fs::write(dirs.root.join("scenario.toml"), s.to_toml()).map_err(|e| {
        eprintln!("error: {}: {e}", dirs.root.join("scenario.toml").display());
        ExitCode::from(EXIT_FAILED)
    })?;
    Ok(dirs)
}

fn launch(file: &Path, out: Option<&Path>, o: &Overrides, reference: bool, plots: bool) -> ExitCode {
    let s = match load_or_exit(file, o) {
        Ok(s) => s,
        Err(code) => return code,
    };
    if let Err(e) = supervise::install_signal_handlers() {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_FAILED);
    }
    if reference && let Some(f) = s.faults.iter().find(|f| f.is_process_fault()) {
        eprintln!(
            "error: --reference runs every process as a thread of this one, so it cannot {} agent {} \
             (process faults signal processes); drop --reference, or keep only delay, drop and corrupt faults",
            f.kind, f.agent
        );
        return ExitCode::from(EXIT_INVALID);
    }
    let dirs = match prepare(&s, out) {
        Ok(d) => d,
        Err(code) => return code,
    };
    let mode = if s.dai_continuous().is_some() {
        "continuous: plant and learner integrated as one ODE in this process, no processes spawned"
    } else if reference {
        "reference"
    } else {
        "multi-process"
    };
    eprintln!(
        "launching {} ({mode}): {} agents, {} steps of {} s, seed {} → {}",
        file.display(),
        s.n_agents(),
        s.n_steps(),
        s.scenario.dt_s,
        s.scenario.seed,
        dirs.root.display()
    );
    let (outcome, summary) = run_once(&s, &dirs, reference, true);
    if let Some(e) = &outcome.error {
        eprintln!("error: {e}");
        eprintln!("run directory (partial): {}", dirs.root.display());
        return ExitCode::from(outcome.exit_code);
    }
    println!(
        "done: {} steps in {:.3} s wall ({:.0} steps/s); run directory: {}",
        summary.steps_completed,
        outcome.wall_s,
        summary.steps_per_s,
        dirs.root.display()
    );
    for (k, v) in &summary.metrics {
        println!("  {k} = {v}");
    }
    if plots {
        match report::report(&dirs.root) {
            Ok(_) => println!("plots: {}", dirs.root.join("plots").display()),
            Err(e) => eprintln!("warning: plots not drawn: {e}"),
        }
    }
    ExitCode::from(outcome.exit_code)
}

fn sweep(file: &Path, args: &SweepArgs) -> ExitCode {
    if args.seeds == 0 {
        eprintln!("error: --seeds 0: at least one seed is needed");
        return ExitCode::from(EXIT_INVALID);
    }
    // Validate once up front, with the first seed, so a bad file fails before any run.
    let o = |seed| Overrides { seed: Some(seed), duration_s: args.duration, ..Default::default() };
    if let Err(code) = load_or_exit(file, &o(args.first_seed)) {
        return code;
    }
    if let Err(e) = supervise::install_signal_handlers() {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_FAILED);
    }
    let name = cohort_scenario::load(file, &o(args.first_seed)).map(|s| s.scenario.name).unwrap_or_default();
    let root = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{name}-sweep-{}", rundir::utc_stamp())));
    if let Err(e) = std::fs::create_dir_all(&root) {
        eprintln!("error: {}: {e}", root.display());
        return ExitCode::from(EXIT_INVALID);
    }
    let mode = if args.multi_process { "multi-process" } else { "reference" };
    eprintln!(
        "sweep of {} over seeds {}..={} ({mode}) → {}",
        file.display(),
        args.first_seed,
        args.first_seed + args.seeds - 1,
        root.display()
    );
    let mut rows = Vec::new();
    for seed in args.first_seed..args.first_seed + args.seeds {
        let s = match load_or_exit(file, &o(seed)) {
            Ok(s) => s,
            Err(code) => return code,
        };
        let dirs = match prepare(&s, Some(&root.join(format!("seed-{seed}")))) {
            Ok(d) => d,
            Err(code) => return code,
        };
        let (outcome, summary) = run_once(&s, &dirs, !args.multi_process, false);
        if outcome.status == "interrupted" {
            eprintln!("interrupted at seed {seed}");
            return ExitCode::from(outcome.exit_code);
        }
        if let Some(e) = &outcome.error {
            eprintln!("error: seed {seed}: {e}");
            return ExitCode::from(outcome.exit_code);
        }
        eprintln!("seed {seed}: {} steps in {:.2} s", summary.steps_completed, outcome.wall_s);
        if !args.keep_telemetry {
            // 10 fig1 runs would otherwise leave ~1.5 GB; summaries stay.
            for d in ["telemetry", "timing", "derived"] {
                let _ = std::fs::remove_dir_all(dirs.root.join(d));
            }
        }
        rows.push((seed, summary.metrics));
    }
    match sweep_report::write(&root, file, mode, &rows) {
        Ok(md) => {
            println!("{md}");
            println!("sweep results: {} and {}", root.join("sweep.md").display(), root.join("sweep.csv").display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(EXIT_FAILED)
        }
    }
}

/// `orchestrator compare`: one multi-process run per method into `root/<method>/`, then the table.
fn compare(file: &Path, algorithms: &str, out: Option<&Path>, plots: bool) -> ExitCode {
    let methods = match tsnr_compare::parse_algorithms(algorithms) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_INVALID);
        }
    };
    // Validate every method's scenario up front, so a bad file or method fails before any run.
    let mut scenarios = Vec::new();
    for m in &methods {
        match load_or_exit(file, &Overrides { method: Some(m.clone()), ..Default::default() }) {
            Ok(s) => scenarios.push((m.clone(), s)),
            Err(code) => return code,
        }
    }
    let Some((_, first)) = scenarios.first() else {
        eprintln!("error: --algorithms {algorithms:?}: no method");
        return ExitCode::from(EXIT_INVALID);
    };
    let root = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from(format!("runs/{}-compare-{}", first.scenario.name, rundir::utc_stamp())));
    // Like a run directory: absent or empty, so an earlier comparison is never mixed in.
    if std::fs::read_dir(&root).is_ok_and(|mut d| d.next().is_some()) {
        eprintln!("error: --out {}: directory exists and is not empty (refusing to mix runs)", root.display());
        return ExitCode::from(EXIT_INVALID);
    }
    if let Err(e) = std::fs::create_dir_all(&root) {
        eprintln!("error: {}: cannot create: {e}", root.display());
        return ExitCode::from(EXIT_INVALID);
    }
    if let Err(e) = supervise::install_signal_handlers() {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_FAILED);
    }
    eprintln!("comparing {} over {} (multi-process) → {}", file.display(), methods.join(", "), root.display());
    let mut runs = Vec::new();
    for (method, s) in &scenarios {
        let dirs = match prepare(s, Some(&root.join(method))) {
            Ok(d) => d,
            Err(code) => return code,
        };
        let (outcome, summary) = run_once(s, &dirs, false, false);
        if let Some(e) = &outcome.error {
            eprintln!("error: {method}: {e}");
            eprintln!("run directory (partial): {}", dirs.root.display());
            return ExitCode::from(outcome.exit_code);
        }
        eprintln!(
            "{method}: {} steps in {:.2} s; fuel {:.2} N·s",
            summary.steps_completed,
            outcome.wall_s,
            summary.metrics.get("fuel_total_ns").copied().unwrap_or(f64::NAN)
        );
        if plots && let Err(e) = report::report(&dirs.root) {
            eprintln!("warning: {method}: plots not drawn: {e}");
        }
        runs.push((method.clone(), summary.metrics));
    }
    // The Figs. 10/11 analogue: every method's tracking error on one figure. A figure is not
    // worth losing the tables over, so a failure is a warning.
    let figures = if plots {
        let dirs: Vec<(String, PathBuf)> = methods.iter().map(|m| (m.clone(), root.join(m))).collect();
        report_tsnr::draw_comparison(&root, &dirs).unwrap_or_else(|e| {
            eprintln!("warning: comparison figures not drawn: {e}");
            Vec::new()
        })
    } else {
        Vec::new()
    };
    let ctx = tsnr_compare::Context {
        file,
        scenario_name: &first.scenario.name,
        seed: first.scenario.seed,
        n_mus: first.n_agents(),
        steps: first.n_steps(),
        dt_s: first.scenario.dt_s,
        figures: &figures,
    };
    match tsnr_compare::write(&root, &ctx, &runs) {
        Ok(md) => {
            println!("{md}");
            println!("comparison: {} and {}", root.join("compare.md").display(), root.join("compare.csv").display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(EXIT_FAILED)
        }
    }
}
