//! `orchestrator`: validate scenarios, launch runs (multi-process over iceoryx2, or the in-process
//! reference), and draw their reports.
//!
//! Exit codes: 0 success; 1 the run failed; 2 invalid input (scenario, arguments, run
//! directory); 128 + signal when interrupted (130 for Ctrl-C).

mod progress;
mod reference;
mod report;
mod rundir;
mod summary;
mod supervise;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use cohort_scenario::Overrides;
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
    },
    /// Draw PNG plots of a run directory's telemetry into RUN_DIR/plots/.
    Report {
        /// A run directory written by `launch`.
        run_dir: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Check { files } => check(&files),
        Cmd::Launch { file, out, seed, duration, step_timeout, reference, no_plots } => {
            let o = Overrides { seed, duration_s: duration, step_timeout_s: step_timeout };
            launch(&file, out.as_deref(), &o, reference, !no_plots)
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

fn launch(file: &Path, out: Option<&Path>, o: &Overrides, reference: bool, plots: bool) -> ExitCode {
    let s = match cohort_scenario::load(file, o) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(EXIT_INVALID);
        }
    };
    if let Err(e) = supervise::install_signal_handlers() {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_FAILED);
    }
    let dirs = match rundir::create(out, &s.scenario.name) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_INVALID);
        }
    };
    if let Err(e) = std::fs::write(dirs.root.join("scenario.toml"), s.to_toml()) {
        eprintln!("error: {}: {e}", dirs.root.join("scenario.toml").display());
        return ExitCode::from(EXIT_FAILED);
    }
    let run_id = new_run_id();
    let mode = if reference { "reference" } else { "multi-process" };
    eprintln!(
        "launching {} ({mode}): {} agents, {} steps of {} s, seed {} → {}",
        file.display(),
        s.n_agents(),
        s.n_steps(),
        s.scenario.dt_s,
        s.scenario.seed,
        dirs.root.display()
    );
    let progress = progress::Progress::new(s.n_steps(), s.scenario.dt_s, &s.scenario.name);
    let outcome = if reference {
        reference::launch(&s, &dirs, run_id, &progress)
    } else {
        supervise::launch(&s, &dirs, &IoxRun::new(run_id), &progress)
    };
    progress.finish();
    let summary = summary::build(
        &s,
        &dirs,
        summary::Outcome {
            mode,
            run_id: format!("{run_id:016x}"),
            status: outcome.status,
            error: outcome.error.clone(),
            wall_s: outcome.wall_s,
        },
    );
    if let Err(e) = summary::write(&dirs, &summary) {
        eprintln!("error: cannot write {}: {e}", dirs.root.join("summary.json").display());
    }
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
