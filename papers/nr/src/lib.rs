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
// The flight build (`agent`, `plant`: no `host` feature) leaves out the host side, so items only
// the host side reads are unused there.

#[cfg(feature = "host")]
mod host;
pub mod iso;
pub mod nn;
#[cfg(feature = "host")]
mod plots;
pub mod swarm;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

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
