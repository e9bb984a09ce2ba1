//! The hooks of a servicing run (the `orbital` plant flown by
//! `lb-dnn-servicing` agents) — the live scene, the analysis of ζ̃ᵢ and the fault effects, the
//! verdict, the sweep criterion and the figures — and the headline bench scenario.

use std::path::Path;

use cohort_host::{
    AnalysisError, FigureSource, KindHooks, Metrics, PaperHost, RunHooks, RunView, SceneBody, ScenePosition,
    VerdictInput, VerdictLine,
};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::TimelineEvent;

use super::{analysis, figures, sweep, verdict};
use crate::Fig1;

/// Body `b`'s (0 the defunct spacecraft) or an agent's three position columns, `<stem>_{x,y,z}_m`.
fn position(process: &str, stem: &str) -> ScenePosition {
    ScenePosition { process: process.into(), columns: ["x", "y", "z"].map(|ax| format!("{stem}_{ax}_m")) }
}

/// The live view's bodies: each spacecraft at its LVLH position from the plant; servicer i's
/// ghost is where it estimates the defunct spacecraft, qᵢ + η̂ᵢ (η̂ᵢ estimates eᵢ = q₀ − qᵢ, Sec. 4).
fn scene_bodies(setup: &Setup) -> Vec<SceneBody> {
    let mut bodies =
        vec![SceneBody { name: "b0".into(), agent: None, truth: position("plant", "b0_q_lvlh"), estimate: Vec::new() }];
    for i in 1..=setup.n_agents() {
        let own = position("plant", &format!("b{i}_q_lvlh"));
        bodies.push(SceneBody {
            name: format!("agent-{i}"),
            agent: Some(i),
            truth: own.clone(),
            estimate: vec![own, position(&format!("agent-{i}"), "eta_hat")],
        });
    }
    bodies
}

impl PaperHost for Fig1 {
    fn run_hooks(&self) -> Vec<KindHooks> {
        vec![KindHooks::pair("orbital", "lb-dnn-servicing", &Servicing)]
    }
    fn bench_scenarios(&self) -> Vec<&'static str> {
        vec!["topologies/fig1.toml"]
    }
}

/// The hooks of a servicing run: the `orbital` plant flown by `lb-dnn-servicing` agents.
struct Servicing;

impl RunHooks for Servicing {
    fn scene(&self, setup: &Setup) -> Vec<SceneBody> {
        scene_bodies(setup)
    }
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::servicing(run.setup, run.dirs)?)
    }
    fn fault_effects(&self, run: &RunView<'_>, timeline: &[TimelineEvent]) -> Result<Metrics, AnalysisError> {
        Ok(analysis::fault_effects(run.setup, run.dirs, timeline)?)
    }
    fn verdict(&self, input: &VerdictInput<'_>) -> Vec<VerdictLine> {
        verdict::lines(input)
    }
    fn sweep_section(&self, _setup: &Setup, rows: &[(u64, Metrics)]) -> Option<String> {
        sweep::section(rows)
    }
    fn figures(&self, _setup: &Setup, run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        // Only a run whose analysis wrote the joined series gets the paper's figures (and leaves
        // its per-body columns out of the generic ones).
        cohort_report::table::resolve(&run_dir.join(figures::DERIVED_FILE))
            .is_file()
            .then(|| Box::new(figures::Fig1Figures) as Box<dyn FigureSource>)
    }
}
