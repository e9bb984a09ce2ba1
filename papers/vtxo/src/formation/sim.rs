//! An in-process lockstep loop for tests and studies: the runtime's
//! [`cohort_runtime::lockstep::Lockstep`] over the VTXO plant and its two agents, each hearing the
//! other, with an optional observer of the plant truth and the agent states both at tₖ (after the
//! shares of step k, as in the telemetry rows).

use cohort_runtime::lockstep::Lockstep;
use cohort_runtime::model::{Algorithm, ShareOut};
use cohort_scenario::Problem;

use crate::flight::config::VtxoAlgorithmConfig;
use crate::model::config::VtxoPlantConfig;
use crate::model::plant::VtxoPlant;

/// What the loop shows an observer after the shares of step k: k, the plant, the agents.
pub type Observer<'a> = dyn FnMut(u64, &VtxoPlant, &[&mut (dyn Algorithm + 'static)]) + 'a;

pub struct Sim {
    pub plant: VtxoPlant,
    /// Agent id i + 1 at index i.
    pub agents: Vec<Box<dyn Algorithm>>,
    lockstep: Lockstep,
}

impl Sim {
    pub fn new(
        plant: &VtxoPlantConfig,
        algorithm: &VtxoAlgorithmConfig,
        dt_s: f64,
        seed: u64,
    ) -> Result<Self, Vec<Problem>> {
        let mut problems = crate::config::check_pair(plant, algorithm);
        let p = crate::formation::build_plant(plant, 2, dt_s, seed);
        let a1 = crate::formation::build_agent(algorithm, 1);
        let a2 = crate::formation::build_agent(algorithm, 2);
        for r in [p.as_ref().err(), a1.as_ref().err()].into_iter().flatten() {
            problems.extend(r.iter().cloned());
        }
        if !problems.is_empty() {
            return Err(problems);
        }
        let (Ok(plant), Ok(a1), Ok(a2)) = (p, a1, a2) else { unreachable!("every error was returned above") };
        Ok(Self::from_parts(plant, vec![a1, a2], dt_s, seed))
    }

    /// The loop of `plant` and `agents` (agent id i + 1 at index i, each hearing every other).
    pub fn from_parts(plant: VtxoPlant, agents: Vec<Box<dyn Algorithm>>, dt_s: f64, seed: u64) -> Self {
        let lockstep = Lockstep::new(Lockstep::all_to_all(agents.len()), dt_s, seed);
        Self { plant, agents, lockstep }
    }

    /// The next step to fly.
    pub fn k(&self) -> u64 {
        self.lockstep.k
    }

    pub fn t_s(&self) -> f64 {
        self.lockstep.t_s()
    }

    /// One lockstep step; `observe` sees the plant and the agents after the shares of step k.
    pub fn step_with(&mut self, observe: &mut Observer<'_>) {
        let mut agents: Vec<&mut (dyn Algorithm + 'static)> = self.agents.iter_mut().map(|a| a.as_mut()).collect();
        self.lockstep.step(&mut self.plant, &mut agents, &mut |k, plant, agents, _| observe(k, plant, agents));
    }

    pub fn step(&mut self) {
        self.step_with(&mut |_, _, _| {});
    }

    /// `n` steps with an observer.
    pub fn run_with(&mut self, n: u64, observe: &mut Observer<'_>) {
        for _ in 0..n {
            self.step_with(observe);
        }
    }

    pub fn run(&mut self, n: u64) {
        self.run_with(n, &mut |_, _, _| {});
    }

    /// The shares (command and values) of the last step, agent i + 1 at index i.
    pub fn last_shares(&self) -> &[ShareOut] {
        self.lockstep.shares()
    }
}
