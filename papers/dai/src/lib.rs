//! Seed 004: *Novel learning for control of nonlinear spacecraft dynamics* (Huang, Sands).
//! Deterministic-AI attitude-rate control: the `rigid-body` plant ([`rigid_body`]), the
//! `dai-attitude` agent with the feedforward (2) and the original (3), general (6) and specific
//! (10), (13) learning laws ([`attitude`]), the paper's own coupling of plant and learner as one
//! ODE ([`continuous`]), the run analysis ([`host::analysis`]) and the measured Tables 2 and 4 with the
//! sampled-data study (`orchestrator dai tables`, [`host::tables`], [`host::readings`]). Scenarios:
//! `topologies/dai*.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]
// The flight build (`agent`, `plant`: no `host` feature) leaves out the host side, so items only
// the host side reads are unused there.

pub mod attitude;
pub mod config;
pub mod continuous;
#[cfg(feature = "host")]
pub mod host;
pub mod rigid_body;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

/// The paper: see the crate docs.
pub struct Dai;

impl Paper for Dai {
    fn name(&self) -> &'static str {
        "dai"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::RigidBodyKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::DaiAttitudeKind]
    }
}
