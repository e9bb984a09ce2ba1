//! The hooks of a `tsnr-net` run (analysis, verdict, figures), the trainer
//! `orchestrator train tsnr-tension` and the commands `orchestrator tsnr compare|ablation`.

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{
    AnalysisError, CommandError, FigureSource, KindHooks, Launcher, Metrics, PaperHost, RunHooks, RunView,
};
use cohort_runtime::paper::Setup;
use std::path::{Path, PathBuf};

use super::{ablation, analysis, compare, figures, verdict};
use crate::{Tsnr, train};

/// `orchestrator tsnr …`: seed 001's campaigns.
#[derive(Parser)]
#[command(name = "tsnr", about = "Seed 001 (tethered space net robot): the paper's comparisons, measured")]
struct TsnrCli {
    #[command(subcommand)]
    command: TsnrCmd,
}

#[derive(Subcommand)]
enum TsnrCmd {
    /// Run a tsnr-formation scenario once per method, multi-process, and write the analogue of
    /// the paper's Tables 1–2 (fuel per MU beside the published values) with each run's
    /// tracking, thrust and solver metrics (compare.md, compare.csv); each run's directory is
    /// DIR/<method>/.
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
    /// Run each scenario as given and under named variants, each one change from the file
    /// (tension forecast hold-measured and oracle, R on the thrust, N_p = 10 and 40, no
    /// neighbour costs, Clarabel's QP as the noise floor), AEMC/DMPC/SMC as each change applies,
    /// and tabulate fuel (∫‖u‖dt and Σ‖u_k‖) and tracking (ablation.md, ablation.csv); each run's
    /// directory is DIR/<scenario>/<variant>/<method>/.
    Ablation {
        /// Scenario files (TOML) with algorithm.kind = "tsnr-formation", e.g. both cases.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Output directory (absent or empty); default runs/tsnr-ablation-<UTC time>/.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Oracle iterates: each replays the tension of the run before (1..=10).
        #[arg(long, default_value_t = 3)]
        oracle_iterations: u32,
        /// Shorten every run to this many seconds, keeping only the net snapshot at 0 s (smoke
        /// tests); default the files' durations.
        #[arg(long, value_name = "S")]
        duration: Option<f64>,
        /// Spawn one process per MU for every run (default: the in-process reference, which
        /// gives the same telemetry bit for bit).
        #[arg(long)]
        multi_process: bool,
    },
}

/// `orchestrator train tsnr-tension`.
#[derive(Parser)]
#[command(
    name = "tsnr-tension",
    about = "Seed 001's DNN tension predictor (eqs. (7)–(11)): simulate random capture trajectories with \
             the net plant, train with candle (CPU), write the weights (safetensors) and NAME-report.md/.json \
             beside them. Deterministic for a given seed."
)]
struct TensionArgs {
    /// Weights file to write, e.g. papers/tsnr/weights/tension.safetensors.
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
}

/// The hooks of a run of the `tsnr-net` plant, whatever flies it (the analysis and verdict read
/// the `tsnr-formation` agents' telemetry when they fly it; the figures draw the net either way).
struct NetRun;

impl RunHooks for NetRun {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::analyse(run.setup, run.dirs)?)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        Some(Box::new(figures::TsnrFigures::of(setup)))
    }
}

impl PaperHost for Tsnr {
    fn run_hooks(&self) -> Vec<KindHooks> {
        vec![KindHooks::plant("tsnr-net", &NetRun)]
    }
    fn trainers(&self) -> Vec<clap::Command> {
        vec![<TensionArgs as clap::CommandFactory>::command()]
    }
    fn run_trainer(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        if name != "tsnr-tension" {
            return Err(CommandError::invalid(format!("tsnr has no trainer {name:?}")));
        }
        let a = TensionArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        let command = format!(
            "orchestrator train tsnr-tension --out {} --seed {} --trajectories {} --epochs {}",
            a.out.display(),
            a.seed,
            a.trajectories,
            a.epochs
        );
        let o = train::Options { out: a.out, seed: a.seed, trajectories: a.trajectories, epochs: a.epochs, n_t: 10 };
        let md = train::run(&o, &command).map_err(CommandError::failed)?;
        let (json, md_path) = train::report_paths(&o.out);
        Ok(format!("{md}\nwritten: {}, {} and {}", o.out.display(), md_path.display(), json.display()))
    }
    /// Case 1 with each QP solver: `orchestrator bench` reports the agents' solve times of both
    /// in one invocation (the default exact active set, and Clarabel alone as before).
    fn bench_scenarios(&self) -> Vec<&'static str> {
        vec!["topologies/tsnr-case1.toml", "topologies/tsnr-case1-clarabel.toml"]
    }
    fn command(&self) -> Option<clap::Command> {
        Some(<TsnrCli as clap::CommandFactory>::command())
    }
    fn run_command(&self, matches: &clap::ArgMatches, launcher: &dyn Launcher) -> Result<String, CommandError> {
        let cli = TsnrCli::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        match cli.command {
            TsnrCmd::Compare { file, algorithms, out, no_plots } => {
                compare::command(launcher, &file, &algorithms, out.as_deref(), !no_plots)
            }
            TsnrCmd::Ablation { files, out, oracle_iterations, duration, multi_process } => {
                ablation::command(launcher, &files, out.as_deref(), oracle_iterations, duration, multi_process)
            }
        }
    }
}
