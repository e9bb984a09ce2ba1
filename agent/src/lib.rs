//! Cohort's agent: the algorithms ([`algorithms`]) and how a scenario selects one ([`build`]).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod algorithms;

use cohort_runtime::model::Algorithm;
use cohort_scenario::{AlgorithmConfig, Scenario};

/// Agent `id`'s algorithm as a (validated) scenario configures it.
pub fn build(s: &Scenario, id: u32) -> Box<dyn Algorithm> {
    let neighbours = &s.agent(id).neighbours;
    match &s.algorithm {
        AlgorithmConfig::ConsensusFormation(g) => {
            Box::new(algorithms::consensus_formation::ConsensusFormation::new(g.clone(), id, s.n_agents(), neighbours))
        }
    }
}
