//! The in-process lockstep loop for tests and studies: the runtime's
//! [`cohort_runtime::lockstep::Lockstep`] (the drivers' order: every agent's readings from the
//! plant process's generator of the seed, every `share`, every `step`, the commands applied, the
//! plant advanced by Δt), the spacecraft hearing no one. Records each agent's compute time per
//! step (share + step, wall clock: never part of the deterministic outputs) and, if asked, every
//! telemetry row.

use cohort_runtime::lockstep::Lockstep;
use cohort_runtime::model::{Algorithm, PlantModel};

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
    let n = agents.len();
    let mut rec = SimRecord { compute_s: vec![Vec::with_capacity(steps as usize); n], ..SimRecord::default() };
    let mut lockstep = Lockstep::new(Lockstep::isolated(n), dt_s, seed);
    let mut agents: Vec<&mut A> = agents.iter_mut().collect();
    for _ in 0..steps {
        lockstep.step(plant, &mut agents, &mut |_, plant, agents, shares| {
            if !record {
                return;
            }
            let row = |f: &dyn Fn(&mut Vec<f64>)| {
                let mut r = Vec::new();
                f(&mut r);
                r
            };
            rec.plant_rows.push(row(&|r| plant.row(r)));
            rec.agent_rows.push(agents.iter().map(|a| row(&|r| a.row(r))).collect());
            rec.shares.push(shares.iter().map(|o| o.values.clone()).collect());
        });
        for (c, t) in rec.compute_s.iter_mut().zip(lockstep.compute_s()) {
            c.push(*t);
        }
    }
    rec
}
