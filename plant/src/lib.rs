//! Cohort's plant: the truth models ([`models`]) and how a scenario selects one ([`build`]).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod models;

use cohort_runtime::model::PlantModel;
use cohort_scenario::{AlgorithmConfig, PlantConfig, Scenario};

/// The plant model a (validated) scenario asks for.
pub fn build(s: &Scenario) -> Box<dyn PlantModel> {
    match &s.plant {
        PlantConfig::DoubleIntegrator(p) => {
            let ids = 1..=s.n_agents();
            let r0 = ids.clone().map(|i| s.agent(i).r0_m.expect("validated")).collect();
            let v0 = ids.map(|i| s.agent(i).v0_mps.expect("validated")).collect();
            let slots = match &s.algorithm {
                AlgorithmConfig::ConsensusFormation(a) => {
                    (1..=s.n_agents()).map(|i| a.slot_m(i, s.n_agents())).collect()
                }
            };
            Box::new(models::double_integrator::DoubleIntegrator::new(r0, v0, p.position_noise_std_m, slots))
        }
    }
}
