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
                "dnn" => {
                    let path = m.tension_weights.as_deref().expect("validated: dnn needs tension_weights");
                    // Validation loaded this file already; it can only fail here if it changed since.
                    let predictor = cohort_tsnr::predictor::TensionPredictor::load(std::path::Path::new(path))
                        .unwrap_or_else(|e| panic!("{e}"));
                    Box::new(cohort_tsnr::dnn_forecast::DnnForecast::new(std::sync::Arc::new(predictor), id))
                }
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

#[cfg(test)]
mod tests {
    //! Checkpoints of every algorithm kind: restoring a saved state into a freshly built agent
    //! gives back the same state, bit for bit, and the same behaviour afterwards.

    use super::*;
    use cohort_runtime::model::{AgentInput, Neighbour, ShareOut};

    fn scenario(file: &str) -> Scenario {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../topologies").join(file);
        cohort_scenario::load(&path, &Default::default()).unwrap()
    }

    /// Run `steps` steps with made-up readings and neighbour values.
    fn drive(a: &mut dyn Algorithm, n_readings: usize, from: u64, steps: u64, out: &mut Vec<f64>) {
        let mut share = ShareOut::default();
        for k in from..from + steps {
            let readings: Vec<f64> = (0..n_readings).map(|r| ((k * 7 + r as u64) % 13) as f64 * 0.1 - 0.6).collect();
            share.command.clear();
            share.values.clear();
            a.share(&AgentInput { k, t_s: k as f64 * 0.01, readings: &readings }, &mut share);
            out.extend(&share.command);
            out.extend(&share.values);
            let nb_values = share.values.clone();
            a.step(0.01, &[Neighbour { id: 2, values: &nb_values }]);
        }
    }

    #[test]
    fn every_algorithm_restores_its_checkpoint_exactly() {
        for (file, id, n_readings) in [("fig1.toml", 1, 7), ("consensus-ring.toml", 1, 3), ("dai.toml", 1, 3)] {
            let s = scenario(file);
            let mut a = build(&s, id);
            let mut trace = Vec::new();
            drive(a.as_mut(), n_readings, 0, 20, &mut trace);
            let saved = a.save_state();
            let mut b = build(&s, id);
            assert_ne!(b.save_state(), saved, "{file}: a fresh agent already equals the stepped one");
            b.restore_state(&saved).unwrap();
            assert_eq!(b.save_state(), saved, "{file}: restored state differs");
            let (mut ta, mut tb) = (Vec::new(), Vec::new());
            drive(a.as_mut(), n_readings, 20, 10, &mut ta);
            drive(b.as_mut(), n_readings, 20, 10, &mut tb);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&ta), bits(&tb), "{file}: behaviour after the restore differs");
            assert!(b.restore_state(&saved[..saved.len() / 2]).is_err(), "{file}: half a state must be refused");
        }
    }
}
