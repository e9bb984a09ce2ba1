//! Seed 001: *An active energy management distributed formation control for tethered space net
//! robot via cooperative game theory* (Ma, Zhang, Liu, Huang, Zhang; Acta Astronautica 2024). Four
//! manoeuvring units at the corners of a spring–damper net: the `tsnr-net` plant ([`net`],
//! [`net_plant`]), Clohessy–Wiltshire relative motion ([`cw`]), desired capture trajectories
//! ([`trajectory`]), the DNN tension predictor (7)–(11) ([`predictor`], trained by
//! `orchestrator train tsnr-tension`, [`train`]), and the `tsnr-formation` agents AEMC, DMPC and
//! SMC ([`agents`]); the run analysis ([`host::analysis`]), the paper's figures ([`host::figures`]) and the
//! Tables 1–2 analogue (`orchestrator tsnr compare`, [`host::compare`]), the ablation campaign
//! (`orchestrator tsnr ablation`, [`host::ablation`]) with the oracle forecast ([`oracle_forecast`]). Scenarios:
//! `topologies/tsnr-case*.toml`, `net-coast.toml`.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]
// The flight build (`agent`, `plant`: no `host` feature) leaves out the host side, so items only
// the host side reads are unused there.

pub mod agents;
pub mod config;
pub mod cw;
pub mod dnn_forecast;
pub mod forecast;
#[cfg(feature = "host")]
pub mod host;
pub mod net;
pub mod net_plant;
pub mod oracle_forecast;
pub mod predictor;
#[cfg(feature = "host")]
pub mod train;
pub mod trajectory;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

/// The paper: see the crate docs.
pub struct Tsnr;

impl Paper for Tsnr {
    fn name(&self) -> &'static str {
        "tsnr"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::net_plant::TsnrNetKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::formation::TsnrFormationKind]
    }
}
