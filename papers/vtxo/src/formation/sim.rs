//! An in-process lockstep loop for tests and studies, in the driver's order: for each step k,
//! the plant's readings for every agent (in agent order, one generator: the plant process's),
//! every agent's `share`, an optional observer (plant truth and agent state both at t_k, as in
//! the telemetry rows), every agent's `step` with the other agent's share of step k, the commands
//! applied, and the plant advanced.

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, PlantModel, ShareOut};
use cohort_runtime::rng::process_rng;
use cohort_scenario::Problem;
use cohort_wire::transport::Proc;
use rand_chacha::ChaCha8Rng;

use crate::flight::config::VtxoAlgorithmConfig;
use crate::model::config::VtxoPlantConfig;
use crate::model::plant::VtxoPlant;

/// What the loop shows an observer after the shares of step k: k, the plant, the agents.
pub type Observer<'a> = dyn FnMut(u64, &VtxoPlant, &[Box<dyn Algorithm>]) + 'a;

pub struct Sim {
    pub plant: VtxoPlant,
    /// Agent id i + 1 at index i.
    pub agents: Vec<Box<dyn Algorithm>>,
    pub dt_s: f64,
    pub k: u64,
    rng: ChaCha8Rng,
    shares: Vec<ShareOut>,
    readings: Vec<f64>,
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

    pub fn from_parts(plant: VtxoPlant, agents: Vec<Box<dyn Algorithm>>, dt_s: f64, seed: u64) -> Self {
        let n = agents.len();
        Self {
            plant,
            agents,
            dt_s,
            k: 0,
            rng: process_rng(seed, Proc::Plant),
            shares: vec![ShareOut::default(); n],
            readings: Vec::with_capacity(32),
        }
    }

    pub fn t_s(&self) -> f64 {
        self.k as f64 * self.dt_s
    }

    /// One lockstep step; `observe` sees the plant and the agents after the shares of step k.
    pub fn step_with(&mut self, observe: &mut Observer<'_>) {
        let t_s = self.t_s();
        for (i, agent) in self.agents.iter_mut().enumerate() {
            self.readings.clear();
            self.plant.readings(i as u32 + 1, &mut self.rng, &mut self.readings);
            agent.share(&AgentInput { k: self.k, t_s, readings: &self.readings }, &mut self.shares[i]);
        }
        observe(self.k, &self.plant, &self.agents);
        for (i, agent) in self.agents.iter_mut().enumerate() {
            let nb: Vec<Neighbour<'_>> = (0..self.shares.len())
                .filter(|&j| j != i)
                .map(|j| Neighbour { id: j as u32 + 1, values: &self.shares[j].values })
                .collect();
            agent.step(self.dt_s, &nb);
        }
        for (i, s) in self.shares.iter().enumerate() {
            self.plant.apply_command(i as u32 + 1, &s.command);
        }
        self.plant.advance(self.dt_s);
        self.k += 1;
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
        &self.shares
    }
}
