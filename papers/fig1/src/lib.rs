//! Seed 000: *Collaborative Spacecraft Servicing under Partial Feedback using Lyapunov-based Deep
//! Neural Networks* (Nino, Patil, Petersen, Phillips, Dixon). N servicers track a defunct
//! spacecraft from partial relative-position measurements: the `orbital` plant ([`servicing`],
//! ECI truth with J2 and drag), the `lb-dnn-servicing` agent ([`lbdnn_servicing`]: ρ-filter
//! observer (24)–(26), Lb-DNN controller (27), distributed adaptation (28)), the run analysis
//! (ζ̃ᵢ joined from truth and estimates, [`analysis`]) and the paper's Figs. 2–4 ([`figures`]).
//! Scenarios: `topologies/fig1*.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod config;
pub mod figures;
pub mod lbdnn_network;
pub mod lbdnn_servicing;
pub mod servicing;
pub mod sweep;
pub mod verdict;

use std::path::Path;

use cohort_host::{FigureSource, Metrics, PaperHost, RunView, SceneBody, ScenePosition, VerdictInput, VerdictLine};
use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind, Setup};
use cohort_runtime::record::TimelineEvent;

/// The paper: see the crate docs.
pub struct Fig1;

impl Paper for Fig1 {
    fn name(&self) -> &'static str {
        "fig1"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::OrbitalKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::LbDnnKind]
    }
}

/// Whether the run flies the paper's method (a coasting run of the orbital plant has no
/// estimates to join, so it gets the generic report only).
fn is_servicing(setup: &Setup) -> bool {
    setup.algorithm_as::<config::LbDnnSetup>().is_some() && setup.plant_as::<config::OrbitalSetup>().is_some()
}

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
    fn scene(&self, setup: &Setup) -> Vec<SceneBody> {
        if is_servicing(setup) { scene_bodies(setup) } else { Vec::new() }
    }
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, String> {
        if is_servicing(run.setup) { analysis::servicing(run.setup, run.dirs) } else { Ok(Metrics::new()) }
    }
    fn fault_effects(&self, run: &RunView<'_>, timeline: &[TimelineEvent]) -> Result<Metrics, String> {
        if is_servicing(run.setup) {
            analysis::fault_effects(run.setup, run.dirs, timeline)
        } else {
            Ok(Metrics::new())
        }
    }
    fn verdict(&self, input: &VerdictInput<'_>) -> Vec<VerdictLine> {
        if is_servicing(input.run.setup) { verdict::lines(input) } else { Vec::new() }
    }
    fn bench_scenarios(&self) -> Vec<&'static str> {
        vec!["topologies/fig1.toml"]
    }
    fn sweep_section(&self, _setup: &Setup, rows: &[(u64, Metrics)]) -> Option<String> {
        sweep::section(rows)
    }
    fn figures(&self, setup: &Setup, run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        // Only a run whose analysis wrote the joined series gets the paper's figures (and leaves
        // its per-body columns out of the generic ones).
        (is_servicing(setup) && cohort_report::table::resolve(&run_dir.join(figures::DERIVED_FILE)).is_file())
            .then(|| Box::new(figures::Fig1Figures) as Box<dyn FigureSource>)
    }
}
