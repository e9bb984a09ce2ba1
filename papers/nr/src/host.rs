//! Seed 003's host side: the hooks of its runs (each sub-system's `host::hooks`, declared on its
//! plant kind), the trainers `orchestrator train nr-iso|nr-swarm`, the generator
//! `orchestrator generate swarm` and the commands
//! `orchestrator nr campaign|swarm-campaign`.

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{CommandError, KindHooks, Launcher, PaperHost};

use crate::{Nr, iso, swarm};

/// `orchestrator nr …`: seed 003's campaigns.
#[derive(Parser)]
#[command(name = "nr", about = "Seed 003 (Neural-Rendezvous, ISO encounter): the paper's evaluation, measured")]
struct NrCli {
    #[command(subcommand)]
    command: NrCmd,
}

#[derive(Subcommand)]
enum NrCmd {
    /// Every method over the test ISOs in-process (delivery error, Δv, per-step compute, NR's
    /// error against b_e(t_f)), the control-interval sweep (Fig. 11) and the γ sweep (Fig. 9,
    /// one training per γ): campaign.md, CSV files and plots in --out. Run from the repository root.
    Campaign(iso::campaign::command::CampaignArgs),
    /// The swarm (Sec. 7.2): cases at N = 8, N = 20 and N = 20 disturbed, each flown by NR over
    /// the deep set, the deep set alone (in-process reference runs) and the global SCP:
    /// cases.csv, summary.md (verdicts) and figures in --out. Run from the repository root.
    SwarmCampaign(swarm::campaign::command::SwarmCampaignArgs),
}

impl PaperHost for Nr {
    fn run_hooks(&self) -> Vec<KindHooks> {
        vec![
            KindHooks::plant("iso-encounter", &iso::host::hooks::IsoRun),
            KindHooks::plant("swarm", &swarm::host::hooks::SwarmRun),
        ]
    }
    fn trainers(&self) -> Vec<clap::Command> {
        vec![iso::train::command::command(), swarm::train::command::command()]
    }
    fn trainer_env(&self, _name: &str) -> Vec<(&'static str, &'static str)> {
        // candle threads its CPU matrix products by this; one thread is the fastest on these
        // small matrices, and the bytes written do not depend on it.
        vec![("RAYON_NUM_THREADS", "1")]
    }
    fn run_trainer(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        match name {
            iso::train::command::NAME => iso::train::command::run(matches),
            swarm::train::command::NAME => swarm::train::command::run(matches),
            _ => Err(CommandError::invalid(format!("nr has no trainer {name:?}"))),
        }
    }
    fn generators(&self) -> Vec<clap::Command> {
        vec![swarm::generate::command()]
    }
    fn run_generator(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        match name {
            swarm::generate::NAME => swarm::generate::run(matches),
            _ => Err(CommandError::invalid(format!("nr has no generator {name:?}"))),
        }
    }
    fn command(&self) -> Option<clap::Command> {
        Some(<NrCli as clap::CommandFactory>::command())
    }
    fn run_command(&self, matches: &clap::ArgMatches, launcher: &dyn Launcher) -> Result<String, CommandError> {
        let cli = NrCli::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        match cli.command {
            NrCmd::Campaign(a) => iso::campaign::command::run(&a, launcher),
            NrCmd::SwarmCampaign(a) => swarm::campaign::command::run(&a, launcher),
        }
    }
}
