//! The hooks of a `rigid-body` run (analysis, verdict) and the command
//! `orchestrator dai tables`.

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{AnalysisError, CommandError, KindHooks, Launcher, Metrics, PaperHost, RunHooks, RunView};
use std::path::PathBuf;

use super::{analysis, tables, verdict};
use crate::Dai;

/// `orchestrator dai …`: seed 004's campaigns.
#[derive(Parser)]
#[command(name = "dai", about = "Seed 004 (deterministic-AI attitude learning): the paper's tables, measured")]
struct DaiCli {
    #[command(subcommand)]
    command: DaiCmd,
}

#[derive(Subcommand)]
enum DaiCmd {
    /// The analogues of the paper's Tables 2 and 4 (continuous-time) and the sampled-data study
    /// (multi-process at 0.01, 0.1, 1, 10, 100 ms), in Markdown and CSV beside the published
    /// values, with plots; run from the repository root.
    Tables {
        /// Output directory (tables, plots, and every run's directory under runs/).
        #[arg(long, default_value = "runs/dai-tables")]
        out: PathBuf,
        /// Directory holding dai.toml and dai-sampled-diverges.toml.
        #[arg(long, default_value = "topologies")]
        topologies: PathBuf,
        /// Control periods of the sampled-data study, ms (none: skip the study).
        #[arg(long, value_delimiter = ',', default_values_t = [0.01, 0.1, 1.0, 10.0, 100.0])]
        periods_ms: Vec<f64>,
        /// Run the sampled-data study in-process (bit-identical, faster) instead of multi-process.
        #[arg(long)]
        in_process: bool,
    },
}

/// The hooks of a run of the `rigid-body` plant (the analysis and verdict read the
/// `dai-attitude` agents' telemetry when they fly it).
struct RigidBodyRun;

impl RunHooks for RigidBodyRun {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::analyse(run.setup, run.dirs)?)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
}

impl PaperHost for Dai {
    fn run_hooks(&self) -> Vec<KindHooks> {
        vec![KindHooks::plant("rigid-body", &RigidBodyRun)]
    }
    fn command(&self) -> Option<clap::Command> {
        Some(<DaiCli as clap::CommandFactory>::command())
    }
    fn run_command(&self, matches: &clap::ArgMatches, launcher: &dyn Launcher) -> Result<String, CommandError> {
        let cli = DaiCli::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        match cli.command {
            DaiCmd::Tables { out, topologies, periods_ms, in_process } => {
                if let Some(p) = periods_ms.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
                    return Err(CommandError::invalid(format!("--periods-ms {p}: periods must be positive")));
                }
                let o = tables::Options {
                    out,
                    topologies,
                    periods_s: periods_ms.iter().map(|p| p * 1e-3).collect(),
                    sampled_multi_process: !in_process,
                };
                let md = tables::run_all(&o, launcher).map_err(CommandError::failed)?;
                Ok(format!("{md}\nwritten: {}", o.out.join("dai-tables.md").display()))
            }
        }
    }
}
