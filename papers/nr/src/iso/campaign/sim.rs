//! The in-process lockstep loop for tests and studies, in the drivers' order: for each step k,
//! the plant's readings for every agent (agent order, one generator: the plant's process
//! generator of the seed), every agent's `share`, every agent's `step`, the commands applied,
//! the plant advanced by Δt. Records each agent's compute time per step (share + step, wall
//! clock: never part of the deterministic outputs) and, if asked, every telemetry row.

use std::time::Instant;

use cohort_runtime::model::{AgentInput, Algorithm, PlantModel, ShareOut};
use cohort_runtime::rng::process_rng;
use cohort_wire::transport::Proc;

/// What a run leaves besides the plant and agents' final states.
#[derive(Debug, Clone, Default)]
pub struct SimRecord {
    /// compute_s[i][k]: agent i's wall time for step k, s.
    pub compute_s: Vec<Vec<f64>>,
    /// Per step: the plant row (before the step's commands) and each agent's row, if recorded.
    pub plant_rows: Vec<Vec<f64>>,
    pub agent_rows: Vec<Vec<Vec<f64>>>,
    /// Share values of every agent at every step, if recorded.
    pub shares: Vec<Vec<Vec<f64>>>,
}

/// Run `steps` control intervals of `dt_s`.
pub fn run<P: PlantModel + ?Sized, A: Algorithm>(
    plant: &mut P,
    agents: &mut [A],
    steps: u64,
    dt_s: f64,
    seed: u64,
    record: bool,
) -> SimRecord {
    let mut rng = process_rng(seed, Proc::Plant);
    let n = agents.len();
    let mut rec = SimRecord { compute_s: vec![Vec::with_capacity(steps as usize); n], ..SimRecord::default() };
    let mut readings = vec![Vec::new(); n];
    let mut outs = vec![ShareOut::default(); n];
    for k in 0..steps {
        let t_s = k as f64 * dt_s;
        for (i, r) in readings.iter_mut().enumerate() {
            r.clear();
            plant.readings(i as u32 + 1, &mut rng, r);
        }
        let mut times = vec![0.0; n];
        for (i, a) in agents.iter_mut().enumerate() {
            let started = Instant::now();
            a.share(&AgentInput { k, t_s, readings: &readings[i] }, &mut outs[i]);
            times[i] = started.elapsed().as_secs_f64();
        }
        if record {
            let mut row = Vec::new();
            plant.row(&mut row);
            rec.plant_rows.push(row);
            rec.agent_rows.push(
                agents
                    .iter()
                    .map(|a| {
                        let mut r = Vec::new();
                        a.row(&mut r);
                        r
                    })
                    .collect(),
            );
            rec.shares.push(outs.iter().map(|o| o.values.clone()).collect());
        }
        for (i, a) in agents.iter_mut().enumerate() {
            let started = Instant::now();
            a.step(dt_s, &[]);
            times[i] += started.elapsed().as_secs_f64();
            rec.compute_s[i].push(times[i]);
        }
        for (i, o) in outs.iter().enumerate() {
            plant.apply_command(i as u32 + 1, &o.command);
        }
        plant.advance(dt_s);
    }
    rec
}
