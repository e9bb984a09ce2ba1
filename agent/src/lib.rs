//! Cohort's agent: the algorithms ([`algorithms`]) and how a scenario selects one ([`build`]).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod algorithms;

use cohort_runtime::model::Algorithm;
use cohort_runtime::rng::process_rng;
use cohort_scenario::{AlgorithmConfig, Scenario};
use cohort_wire::transport::Proc;

/// Agent `id`'s algorithm as a (validated) scenario configures it. Its random draws (initial
/// weights) come from the agent's own seeded generator.
pub fn build(s: &Scenario, id: u32) -> Box<dyn Algorithm> {
    let a = s.agent(id);
    match &s.algorithm {
        AlgorithmConfig::ConsensusFormation(g) => Box::new(algorithms::consensus_formation::ConsensusFormation::new(
            g.clone(),
            id,
            s.n_agents(),
            &a.neighbours,
        )),
        AlgorithmConfig::LbDnnServicing(g) => {
            let mut rng = process_rng(s.scenario.seed, Proc::Agent(id));
            Box::new(algorithms::lbdnn_servicing::LbDnnServicing::new(
                g.clone(),
                a.output_matrix.clone().expect("validated: the orbital plant requires it"),
                a.b() == 1,
                a.neighbours.clone(),
                &mut rng,
            ))
        }
        AlgorithmConfig::Coast(_) => Box::new(algorithms::coast::Coast),
        AlgorithmConfig::Null(a) => Box::new(algorithms::null::Null { share_values: a.share_values }),
        AlgorithmConfig::DaiAttitude(c) => Box::new(algorithms::dai_attitude::DaiAttitudeAgent::new(c)),
    }
}
