//! Seed 003: Neural-Rendezvous (Tsukamoto, Chung et al., "Neural-Rendezvous: Provably Robust
//! Guidance and Control to Encounter Interstellar Objects", arXiv:2208.04883).
//!
//! Two sub-systems, each cut by what it does:
//!
//! - [`iso`] — the ISO encounter (Secs. 2–6): the `iso-encounter` plant ([`iso::dynamics`])
//!   flies one ISO and K spacecraft about the Sun and gives each spacecraft noisy estimates;
//!   each spacecraft's [`iso::control::agent::NrAgent`] flies Algorithm 1 or one of the
//!   baselines ([`iso::config::Method`]): the SN-DNN guidance ([`nn`],
//!   [`iso::guidance::features`]) trained by imitation of the SCP global solution
//!   ([`iso::guidance::scp`], `iso::train`), then min-norm tracking ([`iso::control`]) of the
//!   desired trajectory ([`iso::guidance::desired`]) with the delivery-error bound
//!   ([`iso::control::bound`]). Every controller predicts with the relative model (2)
//!   ([`iso::dynamics::relative`]). [`iso::campaign`] runs and evaluates it in one process.
//! - [`swarm`] — the swarm reconfiguration of Sec. 7.2: the `swarm` plant and the `nr-swarm`
//!   vehicles flying a learned deep set ([`swarm::control::policy`]).
//! - [`nn`] — the spectrally-normalised network both fly; `plots` — the figures' chart kit.
//!
//! In the registry ([`Nr`]): the plant kinds `iso-encounter` and `swarm`, the algorithm kinds
//! `neural-rendezvous` and `nr-swarm` (each sub-system's `host`: kinds, run analysis, figures,
//! verdict); the trainers `orchestrator train nr-iso` and `nr-swarm` (each sub-system's
//! `train::command`); the commands `orchestrator nr campaign` and `orchestrator nr
//! swarm-campaign` (each sub-system's `campaign`). Scenarios: `topologies/nr-iso*.toml`,
//! `topologies/swarm-*.toml`. The crate README gives the set-up, the measured results and every
//! departure.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod iso;
pub mod nn;
mod plots;
pub mod swarm;

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
        &[&iso::host::kinds::IsoEncounterKind, &swarm::host::kinds::SwarmKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&iso::host::kinds::NeuralRendezvousKind, &swarm::host::kinds::NrSwarmKind]
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
    Campaign(iso::campaign::command::CampaignArgs),
    /// The swarm (Sec. 7.2): cases at N = 8, N = 20 and N = 20 disturbed, each flown by NR over
    /// the deep set, the deep set alone (in-process reference runs) and the global SCP:
    /// cases.csv, summary.md (verdicts) and figures in --out. Run from the repository root.
    SwarmCampaign(swarm::campaign::command::SwarmCampaignArgs),
}

impl PaperHost for Nr {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, String> {
        let mut m = iso::host::analysis::analyse(run.setup, run.dirs)?;
        m.extend(swarm::host::analysis::analyse(run.setup, run.dirs)?);
        Ok(m)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        iso::host::verdict::lines(input)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        let swarm = || swarm::host::figures::SwarmFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>);
        iso::host::figures::NrFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>).or_else(swarm)
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
