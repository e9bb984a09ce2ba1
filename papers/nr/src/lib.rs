//! Seed 003: Neural-Rendezvous (Tsukamoto, Chung et al., "Neural-Rendezvous: Provably Robust
//! Guidance and Control to Encounter Interstellar Objects", arXiv:2208.04883).
//!
//! The `iso-encounter` plant ([`plant`]) flies one ISO and K spacecraft about the Sun and gives
//! each spacecraft noisy estimates ([`navigation`], [`messages`]); each spacecraft's
//! [`agent::NrAgent`] flies Algorithm 1 or one of the baselines ([`config::Method`]): the SN-DNN
//! guidance ([`sn_dnn`], [`features`]) trained by imitation of the SCP global solution
//! ([`scp`], [`train`]), then min-norm tracking ([`min_norm`], [`tracking`]) of the desired
//! trajectory ([`desired`]) with the delivery-error bound ([`bound`]). Every controller predicts
//! with the relative model (2) ([`relative`]). [`sim`] and [`campaign`] run and evaluate it in
//! one process. The crate README gives the set-up, the measured results and every departure.
//!
//! In the registry ([`Nr`]): the plant kind `iso-encounter` and the algorithm kind
//! `neural-rendezvous` ([`kinds`]); the run analysis ([`analysis`]) and figures ([`figures`]);
//! the trainer `orchestrator train nr-iso` ([`trainer`]); the command `orchestrator nr campaign`
//! ([`campaign_cmd`], [`campaign_report`]); the swarm's `orchestrator nr swarm-campaign`
//! ([`swarm_campaign_cmd`], [`swarm_campaign`], [`swarm_campaign_report`]). Scenarios: `topologies/nr-iso*.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod agent;
pub mod analysis;
pub mod baselines;
pub mod bound;
pub mod campaign;
pub mod campaign_cmd;
pub mod campaign_report;
pub mod cli;
pub mod config;
pub mod constants;
pub mod desired;
pub mod features;
pub mod figures;
pub mod iso_set;
pub mod kinds;
pub mod lvlh;
pub mod messages;
pub mod min_norm;
pub mod navigation;
pub mod plant;
pub mod plots;
pub mod qp;
pub mod relative;
pub mod scp;
pub mod sim;
pub mod sn_dnn;
pub mod swarm_agent;
pub mod swarm_analysis;
pub mod swarm_campaign;
pub mod swarm_campaign_cmd;
pub mod swarm_campaign_report;
pub mod swarm_config;
pub mod swarm_dagger;
pub mod swarm_data;
pub mod swarm_eval;
pub mod swarm_figures;
pub mod swarm_kinds;
pub mod swarm_messages;
pub mod swarm_nav;
pub mod swarm_obs;
pub mod swarm_pd;
pub mod swarm_plant;
pub mod swarm_policy;
pub mod swarm_problem;
pub mod swarm_safety;
pub mod swarm_scp;
pub mod swarm_setup;
pub mod swarm_train;
pub mod swarm_trainer;
pub mod tracking;
pub mod train;
pub mod trainer;
pub mod two_body;
pub mod verdict;

use std::path::Path;

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{CommandError, FigureSource, Launcher, Metrics, PaperHost, RunView};
use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind, Setup};

/// The paper: see the crate docs.
pub struct Nr;

impl Paper for Nr {
    fn name(&self) -> &'static str {
        "nr"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&kinds::IsoEncounterKind, &swarm_kinds::SwarmKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&kinds::NeuralRendezvousKind, &swarm_kinds::NrSwarmKind]
    }
}

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
    Campaign(campaign_cmd::CampaignArgs),
    /// The swarm (Sec. 7.2): cases at N = 8, N = 20 and N = 20 disturbed, each flown by NR over
    /// the deep set, the deep set alone (in-process reference runs) and the global SCP:
    /// cases.csv, summary.md (verdicts) and figures in --out. Run from the repository root.
    SwarmCampaign(swarm_campaign_cmd::SwarmCampaignArgs),
}

impl PaperHost for Nr {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, String> {
        let mut m = analysis::analyse(run.setup, run.dirs)?;
        m.extend(swarm_analysis::analyse(run.setup, run.dirs)?);
        Ok(m)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        let swarm = || swarm_figures::SwarmFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>);
        figures::NrFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>).or_else(swarm)
    }
    fn trainers(&self) -> Vec<clap::Command> {
        vec![trainer::command(), swarm_trainer::command()]
    }
    fn trainer_env(&self, _name: &str) -> Vec<(&'static str, &'static str)> {
        // candle threads its CPU matrix products by this; one thread is the fastest on these
        // small matrices, and the bytes written do not depend on it.
        vec![("RAYON_NUM_THREADS", "1")]
    }
    fn run_trainer(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        match name {
            trainer::NAME => trainer::run(matches),
            swarm_trainer::NAME => swarm_trainer::run(matches),
            _ => Err(CommandError::invalid(format!("nr has no trainer {name:?}"))),
        }
    }
    fn command(&self) -> Option<clap::Command> {
        Some(<NrCli as clap::CommandFactory>::command())
    }
    fn run_command(&self, matches: &clap::ArgMatches, launcher: &dyn Launcher) -> Result<String, CommandError> {
        let cli = NrCli::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        match cli.command {
            NrCmd::Campaign(a) => campaign_cmd::run(&a, launcher),
            NrCmd::SwarmCampaign(a) => swarm_campaign_cmd::run(&a, launcher),
        }
    }
}
