//! Kinds shared by every paper and the runtime's own scenarios (the consensus ring, the bench's
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

/// The `common` paper: see the crate docs.
pub struct Common;

impl Paper for Common {
    fn name(&self) -> &'static str {
        "common"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::DoubleIntegratorKind, &config::NullPlantKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::ConsensusFormationKind, &config::CoastKind, &config::NullAlgorithmKind]
    }
}

/// The shared kinds have no analysis, figures or commands of their own.
impl cohort_host::PaperHost for Common {}
