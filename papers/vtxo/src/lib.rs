//! Seed 002: "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft
//! Formation" (R. Pirayeshshirazinezhad, arXiv:2509.13331) — the Virtual Telescope for X-ray
//! Observation (VTXO): a leader (Outer Satellite, agent 1) and a follower (Inner Satellite,
//! agent 2) 1 km apart in a highly elliptical orbit.
//!
//! The paper's kinds are the `vtxo` plant and the `vtxo-formation` algorithm ([`kinds`]), and
//! [`Vtxo`] its registry entry (host side: [`analysis`], [`figures`]). Scenarios:
//! `topologies/vtxo*.toml`.
//!
//! What is here (the flight layer, the Sec. 8 supervisor, [`supervisor`] and [`mission`], and the
//! Sec. 3.2.1 transient gain search with its DNN, [`transient_sa`] and [`transient_dnn`], and the
//! Sec. 3.2.2 science Pareto search with its DNN, [`science_moga`] and [`science_dnn`]):
//! - the truth: [`plant::VtxoPlant`] (orbits, attitude, actuators, disturbances, sensors);
//! - the agents: [`leader::Leader`] and [`follower::Follower`] (MEKF, attitude laws, relative
//!   navigation and the relative-position laws), exchanging [`share`] values every step;
//! - the scenario sections [`config_plant::VtxoPlantConfig`] and
//!   [`config_algorithm::VtxoAlgorithmConfig`] with their validation;
//! - the message layouts ([`layout`], [`share`]), the summary metrics and the MEKF consistency
//!   join ([`metrics`]), and an in-process lockstep loop for tests and studies ([`sim`]).

// Axis loops (`for i in 0..3`) read like the equations they implement.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod automaton;
pub mod config;
pub mod figures;
pub mod flight;
pub mod formation;
pub mod handoff;
pub mod mission;
pub mod model;
pub mod science_data;
pub mod science_dnn;
pub mod science_moga;
pub mod science_sim;
pub mod science_stats;
pub mod science_train;
pub mod science_trainer;
pub mod sec7;
pub mod transient_data;
pub mod transient_dnn;
pub mod transient_gains;
pub mod transient_mc;
pub mod transient_sa;
pub mod transient_sim;
pub mod transient_stats;
pub mod transient_train;
pub mod transient_trainer;
pub mod verdict;
pub mod weights_file;

use std::path::{Path, PathBuf};

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{CommandError, FigureSource, Launcher, Metrics, PaperHost, RunView};
use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind, Setup};

use flight::config::VtxoAlgorithmConfig;
use model::config::VtxoPlantConfig;

/// The paper (see the crate docs).
pub struct Vtxo;

impl Paper for Vtxo {
    fn name(&self) -> &'static str {
        "vtxo"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&formation::kinds::VtxoPlantKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&formation::kinds::VtxoFormationKind, &mission::kind::VtxoMissionKind, &handoff::kind::VtxoHandoffKind]
    }
}

/// `orchestrator vtxo …`: seed 002's campaigns.
#[derive(Parser)]
#[command(name = "vtxo", about = "Seed 002 (VTXO formation flight): the paper's Sec. 7 case, measured")]
struct VtxoCli {
    #[command(subcommand)]
    command: VtxoCmd,
}

#[derive(Subcommand)]
enum VtxoCmd {
    /// The Sec. 7 case for SMC-sign, SMC-sat and PD at each step (the scenario's own 10 ms
    /// multi-process, the others in-process), with every model on and with the accelerometer bias
    /// off (the sign law's band Z·dt/(2k)); `sec7.md` and `sec7.csv`. Run from the repository
    /// root; the defaults take ≈ 40 min on two cores.
    Sec7 {
        /// Output directory (the tables, and every run's directory).
        #[arg(long, default_value = "runs/vtxo-sec7-table")]
        out: PathBuf,
        /// Directory holding vtxo-sec7.toml, vtxo-sec7-sat.toml and vtxo-sec7-pd.toml.
        #[arg(long, default_value = "topologies")]
        topologies: PathBuf,
        /// Steps, ms.
        #[arg(long, value_delimiter = ',', default_values_t = [10.0, 1.0])]
        steps_ms: Vec<f64>,
        /// Skip the runs with the accelerometer bias off.
        #[arg(long)]
        no_ablation: bool,
    },
    /// Closed-loop transient Monte Carlo (Sec. 5.1): fresh draws flown with the DNN's gains and
    /// duration and with simulated annealing's; P99(e), P99(E) against the paper's bounds.
    TransientMc(transient_trainer::McArgs),
}

impl PaperHost for Vtxo {
    fn command(&self) -> Option<clap::Command> {
        Some(<VtxoCli as clap::CommandFactory>::command())
    }
    fn run_command(&self, matches: &clap::ArgMatches, launcher: &dyn Launcher) -> Result<String, CommandError> {
        let cli = VtxoCli::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
        match cli.command {
            VtxoCmd::Sec7 { out, topologies, steps_ms, no_ablation } => {
                if let Some(x) = steps_ms.iter().find(|x| !(x.is_finite() && **x > 0.0 && **x <= 9300e3)) {
                    return Err(CommandError::invalid(format!("--steps-ms {x}: steps must be positive")));
                }
                let o = sec7::Options {
                    out,
                    topologies,
                    steps_s: steps_ms.iter().map(|x| x * 1e-3).collect(),
                    ablation: !no_ablation,
                };
                let md = sec7::run(&o, launcher).map_err(CommandError::failed)?;
                Ok(format!("{md}\nwritten: {}", o.out.join("sec7.md").display()))
            }
            VtxoCmd::TransientMc(a) => transient_trainer::run_mc(&a),
        }
    }
    fn trainers(&self) -> Vec<clap::Command> {
        let mut c = transient_trainer::commands();
        c.extend(science_trainer::commands());
        c
    }
    fn trainer_env(&self, _name: &str) -> Vec<(&'static str, &'static str)> {
        // candle threads its CPU matrix products by this; one thread is the fastest on these
        // small matrices, and the bytes written do not depend on it.
        vec![("RAYON_NUM_THREADS", "1")]
    }
    fn run_trainer(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        if science_trainer::owns(name) {
            return science_trainer::run(name, matches);
        }
        transient_trainer::run(name, matches)
    }
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, String> {
        if run.setup.plant_as::<VtxoPlantConfig>().is_some()
            && run.setup.algorithm_as::<handoff::kind::HandoffSetup>().is_some()
        {
            let mut m = analysis::analyse(run.dirs)?;
            m.extend(handoff::analysis::analyse(run.dirs)?);
            return Ok(m);
        }
        // The join needs both of this paper's sides.
        if run.setup.plant_as::<VtxoPlantConfig>().is_none()
            || run.setup.algorithm_as::<VtxoAlgorithmConfig>().is_none()
        {
            return Ok(Metrics::new());
        }
        analysis::analyse(run.dirs)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        if setup.algorithm_as::<mission::config::VtxoMissionConfig>().is_some() {
            return Some(Box::new(mission::figure::MissionFigures));
        }
        let p = setup.plant_as::<VtxoPlantConfig>()?;
        Some(Box::new(figures::VtxoFigures::of(p)))
    }
}

#[cfg(test)]
pub(crate) mod test_stats {
    /// Lag-1 autocorrelation and (population) standard deviation of a series.
    pub fn corr_and_std(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n;
        let c1 = x.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / (n - 1.0);
        (c1 / var, var.sqrt())
    }
}
