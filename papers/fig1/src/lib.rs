//! Seed 000: *Collaborative Spacecraft Servicing under Partial Feedback using Lyapunov-based Deep
//! Neural Networks* (Nino, Patil, Petersen, Phillips, Dixon). N servicers track a defunct
//! spacecraft from partial relative-position measurements: the `orbital` plant ([`servicing`],
//! ECI truth with J2 and drag), the `lb-dnn-servicing` agent ([`lbdnn_servicing`]: ρ-filter
//! observer (24)–(26), Lb-DNN controller (27), distributed adaptation (28)), the run analysis
//! (ζ̃ᵢ joined from truth and estimates, [`host::analysis`]) and the paper's Figs. 2–4 ([`host::figures`]).
//! Scenarios: `topologies/fig1*.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]
// The flight build (`agent`, `plant`: no `host` feature) leaves out the host side, so items only
// the host side reads are unused there.

pub mod config;
#[cfg(feature = "host")]
pub mod host;
pub mod lbdnn_network;
pub mod lbdnn_servicing;
pub mod servicing;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

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
