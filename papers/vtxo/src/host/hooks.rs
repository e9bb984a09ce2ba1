//! Seed 002's host hooks ("Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation"): what the orchestrator asks of the paper — its `orchestrator vtxo …`
//! commands (the Sec. 7 table, the Sec. 5.1 transient Monte Carlo), its trainers (Secs. 3.2.1 and
//! 3.2.2), and the hooks of its runs (analysis, verdict, figures), declared on the kinds they serve.

use std::path::{Path, PathBuf};

use clap::{FromArgMatches, Parser, Subcommand};
use cohort_host::{
    AnalysisError, CommandError, FigureSource, KindHooks, Launcher, Metrics, PaperHost, RunHooks, RunView,
};
use cohort_runtime::paper::Setup;

use super::{analysis, figures, sec7, verdict};
use crate::learn::{science, transient};
use crate::model::config::VtxoPlantConfig;
use crate::{handoff, mission};

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
    TransientMc(transient::trainer::McArgs),
}

impl PaperHost for crate::Vtxo {
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
            VtxoCmd::TransientMc(a) => transient::trainer::run_mc(&a),
        }
    }
    fn trainers(&self) -> Vec<clap::Command> {
        let mut c = transient::trainer::commands();
        c.extend(science::trainer::commands());
        c
    }
    fn trainer_env(&self, _name: &str) -> Vec<(&'static str, &'static str)> {
        // candle threads its CPU matrix products by this; one thread is the fastest on these
        // small matrices, and the bytes written do not depend on it.
        vec![("RAYON_NUM_THREADS", "1")]
    }
    fn run_trainer(&self, name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
        if science::trainer::owns(name) {
            return science::trainer::run(name, matches);
        }
        transient::trainer::run(name, matches)
    }
    fn run_hooks(&self) -> Vec<KindHooks> {
        vec![
            KindHooks::pair("vtxo", "vtxo-formation", &FormationRun),
            KindHooks::pair("vtxo", "vtxo-handoff", &HandoffRun),
            KindHooks::pair("vtxo", "vtxo-mission", &MissionRun),
        ]
    }
}

/// The formation flown by the `vtxo-formation` law: Sec. 7's analysis, verdict and figures.
struct FormationRun;

impl RunHooks for FormationRun {
    fn verdict(&self, input: &cohort_host::VerdictInput<'_>) -> Vec<cohort_host::VerdictLine> {
        verdict::lines(input)
    }
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::analyse(run.dirs)?)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        Some(Box::new(figures::VtxoFigures::of(setup.plant_as::<VtxoPlantConfig>()?)))
    }
}

/// The formation handing its leader role over (`vtxo-handoff`): the formation's analysis and the
/// hand-off's own, and the formation's figures.
struct HandoffRun;

impl RunHooks for HandoffRun {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        let mut m = analysis::analyse(run.dirs)?;
        m.extend(handoff::analysis::analyse(run.dirs)?);
        Ok(m)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        Some(Box::new(figures::VtxoFigures::of(setup.plant_as::<VtxoPlantConfig>()?)))
    }
}

/// The mission automaton (`vtxo-mission`): its own figures.
struct MissionRun;

impl RunHooks for MissionRun {
    fn figures(&self, _setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        Some(Box::new(mission::figure::MissionFigures))
    }
}
