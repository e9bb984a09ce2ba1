//! Seed 001: *An active energy management distributed formation control for tethered space net
//! robot via cooperative game theory* (Ma, Zhang, Liu, Huang, Zhang; Acta Astronautica 2024). Four
//! manoeuvring units at the corners of a spring–damper net: the `tsnr-net` plant ([`net`],
//! [`net_plant`]), Clohessy–Wiltshire relative motion ([`cw`]), desired capture trajectories
//! ([`trajectory`]), the DNN tension predictor (7)–(11) ([`predictor`], trained by
//! `orchestrator train tsnr-tension`, [`train`]), and the `tsnr-formation` agents AEMC, DMPC and
//! SMC ([`agents`]); the run analysis ([`analysis`]), the paper's figures ([`figures`]) and the
//! Tables 1–2 analogue (`orchestrator tsnr compare`, [`compare`]), the ablation campaign
//! (`orchestrator tsnr ablation`, [`ablation`]) with the oracle forecast ([`oracle_forecast`]). Scenarios:
//! `topologies/tsnr-case*.toml`, `net-coast.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod ablation;
pub mod agents;
pub mod analysis;
pub mod compare;
pub mod config;
pub mod cw;
pub mod dnn_forecast;
pub mod figures;
pub mod forecast;
pub mod net;
pub mod net_plant;
pub mod oracle_forecast;
pub mod predictor;
pub mod train;
pub mod trajectory;
pub mod verdict;

use std::path::{Path, PathBuf};

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{CommandError, FigureSource, Launcher, Metrics, PaperHost, RunView};
use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind, Setup};

/// The paper: see the crate docs.
pub struct Tsnr;

impl Paper for Tsnr {
    fn name(&self) -> &'static str {
        "tsnr"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::net_plant::TsnrNetKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::formation::TsnrFormationKind]
    }
}

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

impl PaperHost for Tsnr {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, String> {
        analysis::analyse(run.setup, run.dirs)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        Some(Box::new(figures::TsnrFigures::of(setup)))
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
