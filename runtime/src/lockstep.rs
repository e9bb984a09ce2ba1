//! The in-process lockstep loop without a transport, for campaigns, studies and tests that fly
//! many runs or look inside the plant and the agents between the phases of a step.
//!
//! Step k, in the drivers' order ([`crate::drive`]): the plant's readings for every agent (agent
//! order, one generator: the plant process's, so the noise is the run's), every agent's `share`
//! (into an emptied `ShareOut`, as the agent driver gives it),
//! a look at the plant and the agents at tₖ after the shares (where the telemetry rows are taken),
//! every agent's `step` with its neighbours' shares of step k, the commands applied in agent
//! order, and the plant advanced by Δt. Each agent's wall time for share + step is kept (never
//! part of a deterministic output).
//!
//! What it is not: the reference run (`launch --reference`), which runs the same drivers as the
//! processes over the in-memory transport, with messages, validation, faults, degraded operation
//! and telemetry files. This loop has none of those: every agent is live at every step and hears
//! exactly the neighbours it is given.

use std::time::Instant;

use rand_chacha::ChaCha8Rng;

use crate::model::{AgentInput, Algorithm, Neighbour, PlantModel, ShareOut};
use crate::rng::process_rng;
use cohort_wire::transport::Proc;

/// What [`Lockstep::step`] shows after the shares of step k: k, the plant, the agents, their shares.
pub type Look<'l, P, A> = dyn FnMut(u64, &P, &[&mut A], &[ShareOut]) + 'l;

/// The loop's state between steps: the step, the plant's generator and the last shares.
pub struct Lockstep {
    /// The next step to fly.
    pub k: u64,
    pub dt_s: f64,
    rng: ChaCha8Rng,
    /// Agent index i hears the agents of these ids (id = index + 1), in this order.
    neighbours: Vec<Vec<u32>>,
    readings: Vec<Vec<f64>>,
    shares: Vec<ShareOut>,
    compute_s: Vec<f64>,
}

impl Lockstep {
    /// A loop of `neighbours.len()` agents; agent index i hears `neighbours[i]` (ids 1..=n, not
    /// itself). The plant's generator is the plant process's of `seed`.
    ///
    /// # Panics
    /// If a neighbour id is not an agent of the loop or is the agent itself (a caller's bug).
    pub fn new(neighbours: Vec<Vec<u32>>, dt_s: f64, seed: u64) -> Self {
        let n = neighbours.len();
        for (i, ns) in neighbours.iter().enumerate() {
            let bad = ns.iter().find(|&&j| j == 0 || j as usize > n || j as usize == i + 1);
            assert!(bad.is_none(), "agent {} cannot hear agent {:?} in a loop of {n}", i + 1, bad);
        }
        Self {
            k: 0,
            dt_s,
            rng: process_rng(seed, Proc::Plant),
            readings: vec![Vec::new(); n],
            shares: vec![ShareOut::default(); n],
            compute_s: vec![0.0; n],
            neighbours,
        }
    }

    /// `n` agents that hear no one.
    pub fn isolated(n: usize) -> Vec<Vec<u32>> {
        vec![Vec::new(); n]
    }

    /// `n` agents that each hear every other one, in id order.
    pub fn all_to_all(n: usize) -> Vec<Vec<u32>> {
        (1..=n as u32).map(|i| (1..=n as u32).filter(|j| *j != i).collect()).collect()
    }

    /// tₖ of the next step, s.
    pub fn t_s(&self) -> f64 {
        self.k as f64 * self.dt_s
    }

    /// The shares (command and values) of the last step, agent index i at i.
    pub fn shares(&self) -> &[ShareOut] {
        &self.shares
    }

    /// Each agent's wall time for the share and step of the last step, s.
    pub fn compute_s(&self) -> &[f64] {
        &self.compute_s
    }

    /// Fly step k of `plant` and `agents` (as many as the loop has, agent id = index + 1); `look`
    /// sees k, the plant, the agents and their shares after the shares of step k.
    pub fn step<P, A>(&mut self, plant: &mut P, agents: &mut [&mut A], look: &mut Look<'_, P, A>)
    where
        P: PlantModel + ?Sized,
        A: Algorithm + ?Sized,
    {
        assert_eq!(agents.len(), self.shares.len(), "a loop of {} agents given {}", self.shares.len(), agents.len());
        let (k, t_s) = (self.k, self.t_s());
        for (i, r) in self.readings.iter_mut().enumerate() {
            r.clear();
            plant.readings(i as u32 + 1, &mut self.rng, r);
        }
        for (i, a) in agents.iter_mut().enumerate() {
            // As the agent driver: each step's share starts empty.
            self.shares[i].command.clear();
            self.shares[i].values.clear();
            let started = Instant::now();
            a.share(&AgentInput { k, t_s, readings: &self.readings[i] }, &mut self.shares[i]);
            self.compute_s[i] = started.elapsed().as_secs_f64();
        }
        look(k, plant, agents, &self.shares);
        for (i, a) in agents.iter_mut().enumerate() {
            let heard: Vec<Neighbour<'_>> = self.neighbours[i]
                .iter()
                .map(|&id| Neighbour { id, values: &self.shares[id as usize - 1].values, age_steps: 0 })
                .collect();
            let started = Instant::now();
            a.step(self.dt_s, &heard);
            self.compute_s[i] += started.elapsed().as_secs_f64();
        }
        for (i, s) in self.shares.iter().enumerate() {
            plant.apply_command(i as u32 + 1, &s.command);
        }
        plant.advance(self.dt_s);
        self.k += 1;
    }
}
