//! The supervisor of Sec. 8 of "Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation" as a lockstep [`Algorithm`]: what `AlgorithmSetup::build` gives for a
//! `vtxo-mission` scenario (the runtime's reference and agent processes build agents; `launch`
//! runs the scenario's discrete-event mode instead, [`crate::mission::discrete`]). One tick per step
//! (the scenario step), the same automaton ([`crate::automaton::exec`]), the same messages
//! ([`crate::automaton::share`]); it commands no torque and no thrust (the controllers switching
//! with the location are the hand-off's business).
//!
//! Step k: the follower (master) fires every transition whose guard holds at t_k (at an entry to
//! s2 it predicts T̂_F from its gyro and star-tracker readings, q̃ and ω̃) and shares its automaton;
//! the leader adopts the master's share of step k − 1 (one step of transport delay), predicts T̂_L
//! at its own entry to s2 and acknowledges; the master's u2 becomes max(T̂_L, T̂_F) when the
//! leader's answer arrives, one step after the entry. The formation event is abstracted as in
//! the discrete-event mission: `formation.reach_s` after an entry to s4.

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};
use serde::{Deserialize, Serialize};

use crate::automaton::exec::{Inputs, Supervisor};
use crate::automaton::share::{LeaderShare, MasterShare};
use crate::automaton::table::{Automaton, S2, S4};
use crate::flight::layout::{COMMAND_LEN, Readings};
use crate::learn::transient::gains::{FixedTransient, MeasuredState, TransientGains, TransientPredictor, u2_ticks};
use crate::mission::config::VtxoMissionConfig;
use crate::mission::discrete::MissionParams;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SupervisorAgent {
    pub master: bool,
    /// The mission's inputs in ticks, as the event-by-event run has them.
    pub p: MissionParams,
    /// The fixed predictor's answer (the DNN's place).
    pub gains: (f64, f64, f64),
    pub sup: Supervisor,
    pub u2: u64,
    /// This spacecraft's last prediction (zeros outside s2).
    pub t_hat_s: f64,
    /// The other's latest share.
    pub master_share: Option<Vec<f64>>,
    pub leader_t_hat_s: f64,
    /// This spacecraft's prediction (k1, k2, T) at its latest entry to s2.
    pub entry_gains: TransientGains,
}

impl SupervisorAgent {
    pub fn new(cfg: &VtxoMissionConfig, tick_s: f64, id: u32) -> Self {
        let p = MissionParams::of(cfg, tick_s);
        let a = Automaton::vtxo(p.last_object);
        let x = &cfg.transient;
        Self {
            master: id == 2,
            p,
            gains: (x.k1, x.k2, x.t_s),
            sup: Supervisor::new(&a),
            u2: 0,
            t_hat_s: 0.0,
            master_share: None,
            leader_t_hat_s: 0.0,
            entry_gains: TransientGains { k1: 0.0, k2: 0.0, t_s: 0.0 },
        }
    }

    /// What a spacecraft measured at t_k from its readings (q̃, ω̃); the identity at rest without.
    fn measured(r: Option<&Readings>) -> MeasuredState {
        r.map_or(MeasuredState { q_body_eci: [0.0, 0.0, 0.0, 1.0], omega_body_rad_s: [0.0; 3] }, |r| {
            let q = r.star_q_body_eci;
            let g = r.gyro_rad_s;
            MeasuredState { q_body_eci: [q[0], q[1], q[2], q[3]], omega_body_rad_s: [g[0], g[1], g[2]] }
        })
    }

    fn inputs(&self) -> Inputs {
        Inputs {
            u1: self.p.u1,
            u2: self.u2,
            u3: self.p.u3.clone(),
            u4: self.p.reach,
            window: self.p.window,
            formation: !(self.sup.state == S4 && self.sup.clocks[S4] < self.p.reach),
        }
    }

    /// The master's transitions at this instant (at most one per location, a bounded chain).
    fn master_fire(&mut self, x: &MeasuredState, pred: &dyn TransientPredictor) {
        let a = Automaton::vtxo(self.p.last_object);
        for _ in 0..a.states.len() {
            let i = self.inputs();
            let Some((0, k)) = self.sup.next(&a, &i) else { break };
            self.sup.fire(&a, k);
            if self.sup.state == S2 {
                self.entry_gains = pred.predict(x, self.p.w);
                self.t_hat_s = self.entry_gains.t_s;
                self.u2 = u2_ticks(self.t_hat_s, self.t_hat_s, self.p.t_min_s, self.p.t_max_s, self.p.tick_s);
            }
        }
    }
}

impl SupervisorAgent {
    /// The supervisor's part of step k's share (what [`Algorithm::share`] does, reusable by an
    /// agent that also flies): the master fires every transition whose guard holds at t_k, the
    /// leader adopts the master's share of step k − 1; each predicts (k1, k2, T) with `pred` from
    /// `x` (its state at t_k) at its own entry to s2 ([`SupervisorAgent::entry_gains`]). Appends
    /// the supervisor's share values to `out`.
    pub fn tick(&mut self, x: &MeasuredState, pred: &dyn TransientPredictor, out: &mut Vec<f64>) {
        if self.master {
            self.master_fire(x, pred);
            let formation = self.inputs().formation;
            MasterShare { sup: self.sup.clone(), u2_ticks: self.u2, formation, t_hat_follower_s: self.t_hat_s }
                .write(out);
            return;
        }
        let was = self.sup.state;
        if let Some(m) = self.master_share.as_deref().and_then(MasterShare::read) {
            self.sup = m.sup;
            self.u2 = m.u2_ticks;
        }
        // T̂_L from the entry to s2 until its end; nothing outside s2.
        let g = match (was == S2, self.sup.state == S2) {
            (false, true) => {
                self.entry_gains = pred.predict(x, self.p.w);
                self.entry_gains
            }
            (true, true) => self.entry_gains,
            _ => TransientGains { k1: 0.0, k2: 0.0, t_s: 0.0 },
        };
        self.t_hat_s = g.t_s;
        LeaderShare { ack_state: self.sup.state, ack_id: self.sup.id, t_hat_s: self.t_hat_s, k1: g.k1, k2: g.k2 }
            .write(out);
    }

    /// The other spacecraft's supervisor share of this step (`values` from its supervisor offset).
    pub fn receive(&mut self, neighbours: &[Neighbour<'_>]) {
        let other = if self.master { 1 } else { 2 };
        if let Some(n) = neighbours.iter().find(|n| n.id == other) {
            if self.master {
                if let Some(l) = LeaderShare::read(n.values).filter(|l| l.t_hat_s > 0.0 && self.sup.state == S2) {
                    self.leader_t_hat_s = l.t_hat_s;
                    self.u2 = u2_ticks(l.t_hat_s, self.t_hat_s, self.p.t_min_s, self.p.t_max_s, self.p.tick_s);
                }
            } else {
                self.master_share = Some(n.values.to_vec());
            }
        }
    }

    /// Let a step of `dt_s` pass (whole ticks) in the current location.
    pub fn advance(&mut self, dt_s: f64) {
        let a = Automaton::vtxo(self.p.last_object);
        let ticks = (dt_s / self.p.tick_s).round().max(0.0) as u64;
        self.sup.advance(&a, ticks);
    }
}

impl Algorithm for SupervisorAgent {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        ["state", "id", "t0_s", "t1_s", "t2_s", "t3_s", "t4_s", "t5_s", "tw_s", "u2_s", "t_hat_s"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.clear();
        out.values.clear();
        out.command.extend([0.0; COMMAND_LEN]);
        let x = Self::measured(Readings::parse(input.readings).as_ref());
        let (k1, k2, t_s) = self.gains;
        self.tick(&x, &FixedTransient(TransientGains { k1, k2, t_s }), &mut out.values);
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        self.receive(neighbours);
        self.advance(dt_s);
    }

    fn row(&self, out: &mut Vec<f64>) {
        out.extend([self.sup.state as f64, f64::from(self.sup.id)]);
        out.extend(self.sup.clocks.iter().map(|c| *c as f64 * self.p.tick_s));
        out.extend([self.u2 as f64 * self.p.tick_s, self.t_hat_s]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::discrete::run;

    /// A short mission in 1 s ticks: u3 = [50 s, 7 s, 25 s, 30 s], window 10 s, u1 = 100 s,
    /// formation 3 s after an orbit switch, T = 5 s.
    fn small() -> VtxoMissionConfig {
        let mut c = VtxoMissionConfig::default();
        c.timers.u3_h = [50.0, 7.0, 25.0, 30.0].iter().map(|s| s / 3600.0).collect();
        c.timers.science_window_s = 10.0;
        c.formation.reach_s = 3.0;
        c.transient.t_s = 5.0;
        c.transient.t_min_s = 1.0;
        c.transient.t_max_s = 5.0;
        c.timers.transient_max_s = 5.0;
        c.timers.orbit_period_s = Some(115.0);
        c
    }

    #[test]
    fn the_lockstep_master_enters_every_location_at_the_discrete_event_ticks() {
        let c = small();
        assert!(c.validate("algorithm", 1.0).is_empty(), "{:?}", c.validate("algorithm", 1.0));
        let p = MissionParams::of(&c, 1.0);
        let g = FixedTransient(TransientGains { k1: 0.085, k2: 0.25, t_s: 5.0 });
        let de = run(&p, &g, &g, 1, u64::MAX).unwrap();
        let want: Vec<(u64, usize, u32)> = de.events.iter().map(|e| (e.tick, e.sup.state, e.sup.id)).collect();
        let (mut leader, mut master) = (SupervisorAgent::new(&c, 1.0, 1), SupervisorAgent::new(&c, 1.0, 2));
        let (mut got, mut acks) = (vec![(0, 0, 0)], Vec::new());
        let (mut lo, mut mo) = (ShareOut::default(), ShareOut::default());
        for k in 0..=de.end_tick + 2 {
            let input = AgentInput { k, t_s: k as f64, readings: &[] };
            master.share(&input, &mut mo);
            leader.share(&input, &mut lo);
            let m = (k, master.sup.state, master.sup.id);
            if got.last().is_none_or(|g| (g.1, g.2) != (m.1, m.2)) {
                got.push(m);
            }
            acks.push((lo.values[0] as usize, lo.values[1] as u32));
            leader.step(1.0, &[Neighbour { id: 2, values: &mo.values, age_steps: 0 }]);
            master.step(1.0, &[Neighbour { id: 1, values: &lo.values, age_steps: 0 }]);
        }
        assert_eq!(got, want);
        // The leader acknowledges the master's location one step later.
        for (i, w) in got.windows(2).enumerate() {
            let k = w[1].0 as usize;
            assert_eq!(acks[k + 1], (w[1].1, w[1].2), "entry {i}");
        }
    }
}
