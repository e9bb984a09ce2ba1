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
        AlgorithmConfig::TsnrFormation(c) => tsnr_formation(s, c, id),
    }
}

/// Seed 001: the method `algorithm.method` names. AEMC's tension forecast is chosen by
/// `algorithm.mpc.tension_forecast`.
fn tsnr_formation(s: &Scenario, c: &cohort_scenario::tsnr_formation::TsnrFormation, id: u32) -> Box<dyn Algorithm> {
    use algorithms::{tsnr_aemc::TsnrAemc, tsnr_dmpc::TsnrDmpc, tsnr_smc::TsnrSmc};
    let dt_s = s.scenario.dt_s;
    let model =
        cohort_scenario::tsnr_formation::TsnrModel::of(s).expect("validated: tsnr-formation needs the tsnr-net plant");
    match c.method.as_str() {
        "aemc" => {
            let m = c.mpc.as_ref().expect("validated: aemc needs [algorithm.mpc]");
            let forecast: Box<dyn cohort_tsnr::forecast::TensionForecast> = match m.tension_forecast.as_str() {
                "hold-measured" => Box::new(cohort_tsnr::forecast::HoldMeasured),
                other => unreachable!("validated: unknown tension forecast {other:?}"),
            };
            let graph = s.topology().neighbours;
            Box::new(TsnrAemc::new(c, &model, dt_s, s.run.link_delay_steps, id, &graph, forecast))
        }
        "dmpc" => Box::new(TsnrDmpc::new(c, &model, dt_s, id)),
        "smc" => Box::new(TsnrSmc::new(c, &model, id)),
        other => unreachable!("validated: unknown tsnr-formation method {other:?}"),
    }
}
