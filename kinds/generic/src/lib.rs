//! The generic kinds — no paper's, so they live in `kinds/` beside the Python-hosted ones: kinds
//! shared by every paper and the runtime's own scenarios (the consensus ring, the bench's
//! null round): the `double-integrator` and `null` plants, the `consensus-formation`, `coast` and
//! `null` algorithms. `coast` flies any plant whose command has three components, so a paper's
//! plant can be checked on its own.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod coast;
pub mod config;
pub mod consensus_formation;
pub mod double_integrator;
pub mod null_algorithm;
pub mod null_plant;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

/// The generic kinds (registered like a paper, though they belong to none): see the crate docs.
pub struct Generic;

impl Paper for Generic {
    fn name(&self) -> &'static str {
        "generic"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::DoubleIntegratorKind, &config::NullPlantKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::ConsensusFormationKind, &config::CoastKind, &config::NullAlgorithmKind]
    }
}

/// The shared kinds have no analysis, figures or commands of their own.
#[cfg(feature = "host")]
impl cohort_host::PaperHost for Generic {}
