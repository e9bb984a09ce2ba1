//! Seed 002: "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft
//! Formation" (R. Pirayeshshirazinezhad, arXiv:2509.13331) — the Virtual Telescope for X-ray
//! Observation (VTXO): a leader (Outer Satellite, agent 1) and a follower (Inner Satellite,
//! agent 2) 1 km apart in a highly elliptical orbit.
//!
//! The paper's kinds are the `vtxo` plant and the `vtxo-formation` algorithm
//! ([`formation::kinds`]), the `vtxo-mission` discrete-event mission ([`mission::kind`]) and the
//! `vtxo-handoff` scenario ([`handoff::kind`]); [`Vtxo`] is its registry entry. Scenarios:
//! `topologies/vtxo*.toml`. The modules, one per sub-system:
//! - [`model`]: the truth, [`model::plant::VtxoPlant`] (orbits, attitude, actuators,
//!   disturbances, sensors; Sec. 2, Apps. C–E), its telemetry row and summary metrics, and the
//!   `[plant]` section;
//! - [`flight`]: the agents, [`flight::leader::Leader`] and [`flight::follower::Follower`] (MEKF,
//!   attitude laws, relative navigation and the relative-position laws; Secs. 2.10–2.11), the
//!   message layouts they exchange every step, and the `[algorithm]` section;
//! - [`formation`]: the formation kinds, the builders of plant and agents, and an in-process
//!   lockstep loop for tests and studies (Sec. 7);
//! - [`automaton`]: the Sec. 8 supervisor's timed automaton as data, checked and run in ticks;
//! - [`mission`]: the whole mission, Id 0 → 9, as a discrete-event run of the automaton;
//! - [`handoff`]: s1 → s2 → s3 with the full dynamics, the controllers switching with the
//!   automaton's location;
//! - [`learn`]: the Sec. 3.2.1 transient gain search with its DNN and the Sec. 3.2.2 science
//!   Pareto search with its DNN, and their weights files;
//! - [`host`]: analysis, figures, verdict and the Sec. 7 table (`orchestrator vtxo …`);
//! - [`config`]: the validation helpers both scenario sections use and their pair check.

// Axis loops (`for i in 0..3`) read like the equations they implement.
#![allow(clippy::needless_range_loop)]
// The flight build (`agent`, `plant`: no `host` feature) leaves out the host side, so items only
// the host side reads are unused there.

pub mod automaton;
pub(crate) mod config;
pub mod flight;
pub mod formation;
pub(crate) mod handoff;
#[cfg(feature = "host")]
pub(crate) mod host;
pub mod learn;
pub mod mission;
pub mod model;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

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
