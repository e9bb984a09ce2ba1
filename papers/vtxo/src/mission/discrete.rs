//! The whole VTXO mission, Id 0 → 9, as a discrete-event run of the supervisor of Sec. 8 of
//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! ([`crate::automaton::table`], the corrected Tables 6–8) with the dynamics abstracted: each phase
//! lasts what its timer says — u3(Id) of Table 6, u1 = orbit period − 10 h − 3 min (the plant's
//! 26.65 h, [`crate::mission::period`]; the print's 32.5 h gives 22.45 h), the 10 h science
//! window, u2 = T from the [`TransientPredictor`] of each spacecraft — and the formation event u4
//! comes `reach` after an orbit switch (entry to s4). Pure: no files, no transport.
//!
//! Both spacecraft run the automaton. The follower is the master: it evaluates the guards and
//! sends its location, Id, clocks, u2 and the formation flag ([`MasterShare`]); the leader adopts
//! them and acknowledges with its own transient prediction ([`LeaderShare`]); at each entry to s2
//! both predict (k1, k2, T) from their own measured state, and the master takes
//! u2 = max(T̂_L, T̂_F). Here the messages pass at the event's instant (no transport delay: the
//! lockstep runtime would add one step, 10 ms, to each hand-over, which this abstraction drops).
//!
//! Time is integer ticks of the scenario step, so every guard compares exactly and a run is
//! bit-identical for a seed. Why not the lockstep runtime: its steps are all of one length dt,
//! and the mission spans ≈ 1.3e7 s with phases from 48 s (a transient) to 60 days; at the 10 ms
//! that a transient needs that is 1.3e9 lockstep rounds (hours of wall time per run) for a
//! result the timers fix exactly. The runtime's coupled mode (`AlgorithmSetup::coupled`) runs
//! this in-process instead, with no generic change.

use rand_chacha::ChaCha8Rng;

use crate::automaton::check::AutomatonError;
use crate::automaton::exec::{Inputs, Supervisor};
use crate::automaton::share::{LeaderShare, MasterShare};
use crate::automaton::table::{Automaton, S2, S3, S4, StateIx};
use crate::learn::transient::gains::{TransientGains, TransientPredictor, draw_entry_state, u2_ticks};
use crate::mission::config::{VtxoMissionConfig, whole_ticks};

/// The mission's inputs in ticks.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MissionParams {
    pub tick_s: f64,
    pub u1: u64,
    pub u3: Vec<u64>,
    pub window: u64,
    pub reach: u64,
    pub last_object: u32,
    pub w: f64,
    pub t_min_s: f64,
    pub t_max_s: f64,
}

impl MissionParams {
    /// From a validated configuration (its period known). A value that is not whole ticks rounds
    /// to the nearest tick: u1 always may (the orbit period is the plant's), the others are
    /// validated whole.
    pub fn of(c: &VtxoMissionConfig, tick_s: f64) -> Self {
        let t = |x: f64| whole_ticks(x, tick_s).unwrap_or_else(|| (x / tick_s).round().max(1.0) as u64);
        Self {
            tick_s,
            u1: t(c.timers.u1_s()),
            u3: c.timers.u3_h.iter().map(|h| t(h * 3600.0)).collect(),
            window: t(c.timers.science_window_s),
            reach: t(c.formation.reach_s),
            last_object: c.timers.last_object(),
            w: c.transient.w,
            t_min_s: c.transient.t_min_s,
            t_max_s: c.transient.t_max_s,
        }
    }

    /// `ticks` in seconds: divided by the ticks per second when the tick divides a second (exact
    /// for whole-second values), else multiplied by the tick.
    pub fn seconds(&self, ticks: u64) -> f64 {
        let per_s = (1.0 / self.tick_s).round();
        if per_s >= 1.0 && (per_s * self.tick_s - 1.0).abs() < 1e-12 {
            ticks as f64 / per_s
        } else {
            ticks as f64 * self.tick_s
        }
    }

    /// The science windows the timers imply: Σ over the objects of ⌈u3(Id) / window⌉.
    pub fn science_windows_by_timers(&self) -> u64 {
        self.u3[1..self.u3.len() - 1].iter().map(|u| u.div_ceil(self.window)).sum()
    }
}

/// One entry into a location.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    pub tick: u64,
    /// The master's automaton after the transition.
    pub sup: Supervisor,
    /// The transition taken ("g(3,1)"), or "init".
    pub via: String,
    pub u2_ticks: u64,
    pub formation: bool,
    /// The leader's acknowledgement (its location and Id, its prediction).
    pub leader: LeaderShare,
    /// The follower's prediction (in s2; zeros elsewhere).
    pub follower: TransientGains,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    pub events: Vec<Event>,
    /// Where the run stopped: the entry into s6, or the horizon.
    pub end_tick: u64,
    pub finished: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MissionError {
    Automaton(Vec<AutomatonError>),
    /// No exit can ever hold in this location (a table or input error).
    Deadlock {
        t_s: f64,
        state: String,
    },
    /// More transitions at one instant than there are locations.
    Zeno {
        t_s: f64,
        state: String,
    },
    /// The leader acknowledged another location or Id than the master's.
    LeaderDiverged {
        t_s: f64,
        master: (usize, u32),
        leader: (usize, u32),
    },
}

impl std::fmt::Display for MissionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Automaton(p) => {
                let p: Vec<String> = p.iter().map(ToString::to_string).collect();
                write!(f, "the supervisor table is invalid: {}", p.join("; "))
            }
            Self::Deadlock { t_s, state } => write!(f, "t = {t_s} s: no exit of {state} can ever hold (deadlock)"),
            Self::Zeno { t_s, state } => write!(f, "t = {t_s} s: transitions without end at one instant, in {state}"),
            Self::LeaderDiverged { t_s, master, leader } => write!(
                f,
                "t = {t_s} s: the leader acknowledged s{} Id {} but the master is in s{} Id {}",
                leader.0, leader.1, master.0, master.1
            ),
        }
    }
}

impl std::error::Error for MissionError {}

const NO_GAINS: TransientGains = TransientGains { k1: 0.0, k2: 0.0, t_s: 0.0 };

/// One spacecraft's side of the supervisor: its automaton copy, its draws, its predictor.
struct Side<'a> {
    sup: Supervisor,
    rng: ChaCha8Rng,
    predictor: &'a dyn TransientPredictor,
    gains: TransientGains,
}

impl Side<'_> {
    /// At an entry to s2: the measured state, then the prediction.
    fn predict(&mut self, w: f64) -> TransientGains {
        let x = draw_entry_state(&mut self.rng);
        self.gains = self.predictor.predict(&x, w);
        self.gains
    }
}

/// The draws of spacecraft `id` (1 leader, 2 follower): one stream per spacecraft and seed.
fn side_rng(seed: u64, id: u32) -> ChaCha8Rng {
    cohort_runtime::rng::setup_rng(seed, &format!("vtxo-mission-agent-{id}"))
}

/// Run the mission from Init until s6 or `horizon` ticks.
pub fn run(
    p: &MissionParams,
    leader: &dyn TransientPredictor,
    follower: &dyn TransientPredictor,
    seed: u64,
    horizon: u64,
) -> Result<Mission, MissionError> {
    let a = Automaton::vtxo(p.last_object);
    a.validate().map_err(MissionError::Automaton)?;
    let mut inputs = Inputs { u1: p.u1, u2: 0, u3: p.u3.clone(), u4: p.reach, window: p.window, formation: false };
    let mut lead = Side { sup: Supervisor::new(&a), rng: side_rng(seed, 1), predictor: leader, gains: NO_GAINS };
    let mut fol = Side { sup: Supervisor::new(&a), rng: side_rng(seed, 2), predictor: follower, gains: NO_GAINS };
    let t_s = |tick: u64| p.seconds(tick);
    let ack0 = LeaderShare { ack_state: lead.sup.state, ack_id: lead.sup.id, t_hat_s: 0.0, k1: 0.0, k2: 0.0 };
    let mut events = vec![Event {
        tick: 0,
        sup: fol.sup.clone(),
        via: "init".into(),
        u2_ticks: 0,
        formation: false,
        leader: ack0,
        follower: NO_GAINS,
    }];
    let (mut now, mut same_instant) = (0u64, 0usize);
    while fol.sup.state != a.final_state {
        // The abstracted relative dynamics: the formation is lost at an orbit switch (s4) and
        // reached `reach` later.
        let in_s4 = fol.sup.state == S4;
        inputs.formation = !(in_s4 && fol.sup.clocks[S4] < p.reach);
        let env = (in_s4 && !inputs.formation).then(|| p.reach - fol.sup.clocks[S4]);
        let next = fol.sup.next(&a, &inputs);
        let d = match (next, env) {
            (Some((d, _)), Some(e)) => d.min(e),
            (Some((d, _)), None) => d,
            (None, Some(e)) => e,
            (None, None) => return Err(MissionError::Deadlock { t_s: t_s(now), state: a.state_name(fol.sup.state) }),
        };
        if d > horizon - now {
            let rest = horizon - now;
            fol.sup.advance(&a, rest);
            lead.sup.advance(&a, rest);
            return Ok(Mission { events, end_tick: horizon, finished: false });
        }
        fol.sup.advance(&a, d);
        lead.sup.advance(&a, d);
        now += d;
        same_instant = if d == 0 { same_instant + 1 } else { 0 };
        if same_instant > a.states.len() {
            return Err(MissionError::Zeno { t_s: t_s(now), state: a.state_name(fol.sup.state) });
        }
        // An environment event (the formation reached) comes first: evaluate the guards again.
        let Some((_, k)) = next.filter(|(dn, _)| *dn == d) else { continue };
        fol.sup.fire(&a, k);
        let entering_s2 = fol.sup.state == S2;
        fol.gains = if entering_s2 { fol.predict(p.w) } else { NO_GAINS };
        // Master → leader (the u2 of the previous transient until the leader's answer is in).
        let share = MasterShare {
            sup: fol.sup.clone(),
            u2_ticks: inputs.u2,
            formation: inputs.formation,
            t_hat_follower_s: fol.gains.t_s,
        };
        let ack = leader_on_master(&mut lead, &share, p.w);
        if (ack.ack_state, ack.ack_id) != (fol.sup.state, fol.sup.id) {
            return Err(MissionError::LeaderDiverged {
                t_s: t_s(now),
                master: (fol.sup.state, fol.sup.id),
                leader: (ack.ack_state, ack.ack_id),
            });
        }
        if entering_s2 {
            inputs.u2 = u2_ticks(ack.t_hat_s, fol.gains.t_s, p.t_min_s, p.t_max_s, p.tick_s);
        }
        events.push(Event {
            tick: now,
            sup: fol.sup.clone(),
            via: a.transition_name(k),
            u2_ticks: inputs.u2,
            formation: inputs.formation,
            leader: ack,
            follower: fol.gains,
        });
    }
    Ok(Mission { events, end_tick: now, finished: true })
}

/// The leader's side of one master share: adopt the automaton's state; at an entry to s2,
/// predict; acknowledge.
fn leader_on_master(lead: &mut Side<'_>, m: &MasterShare, w: f64) -> LeaderShare {
    let was = lead.sup.state;
    lead.sup = m.sup.clone();
    let g = if lead.sup.state == S2 && was != S2 { lead.predict(w) } else { NO_GAINS };
    LeaderShare { ack_state: lead.sup.state, ack_id: lead.sup.id, t_hat_s: g.t_s, k1: g.k1, k2: g.k2 }
}

impl Mission {
    /// Entries into s3.
    pub fn science_windows(&self) -> u64 {
        self.events.iter().filter(|e| e.sup.state == S3).count() as u64
    }

    /// How long each entry lasted (the last one up to the end), ticks.
    pub fn dwells(&self) -> Vec<u64> {
        let mut out: Vec<u64> = self.events.windows(2).map(|w| w[1].tick - w[0].tick).collect();
        if let Some(last) = self.events.last() {
            out.push(self.end_tick - last.tick);
        }
        out
    }

    /// Total time spent in `s`, ticks (the last entry counted up to the end; s6 counts 0).
    pub fn time_in(&self, s: StateIx) -> u64 {
        self.events.iter().zip(self.dwells()).filter(|(e, _)| e.sup.state == s).map(|(_, d)| d).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::automaton::table::{S0, S1, S5, S6};
    use crate::learn::transient::gains::FixedTransient;

    fn fixed(t_s: f64) -> FixedTransient {
        FixedTransient(TransientGains { k1: 0.085, k2: 0.25, t_s })
    }

    /// Table 6 and the defaults on the default plant's orbit (Table D.9, 26.65 h), 10 ms ticks.
    fn paper() -> MissionParams {
        let mut c = VtxoMissionConfig::default();
        assert!(c.timers.follow_plant("algorithm", &crate::model::config::VtxoPlantConfig::default()).is_none());
        MissionParams::of(&c, 0.01)
    }

    /// u1 = 95 952.939 436 s (2π√(a³/μ) by hand, see mission_period) − 10 h − 3 min
    /// = 59 772.939 436 s, to the nearest 10 ms tick.
    const U1_TICKS: u64 = 5_977_294;

    #[test]
    fn the_paper_mission_reaches_s6_through_ids_0_to_9_without_a_zero_dwell() {
        let p = paper();
        let m = run(&p, &fixed(48.0), &fixed(48.0), 1, u64::MAX).unwrap();
        assert!(m.finished);
        let last = m.events.last().unwrap();
        assert_eq!((last.sup.state, last.sup.id), (S6, 9));
        // Id goes 0, 1, …, 9 in order, one step at a time.
        let ids: Vec<u32> = m.events.iter().map(|e| e.sup.id).collect();
        assert!(ids.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1), "{ids:?}");
        assert_eq!((ids[0], *ids.last().unwrap()), (0, 9));
        let dwells = m.dwells();
        assert!(dwells[..dwells.len() - 1].iter().all(|d| *d > 0), "a zero dwell: {dwells:?}");
    }

    #[test]
    fn the_science_windows_and_the_end_are_what_the_timers_give_by_hand() {
        let p = paper();
        let m = run(&p, &fixed(48.0), &fixed(30.0), 1, u64::MAX).unwrap();
        // ⌈u3/10 h⌉ per object: 0.2, 1.5, 4.2, 4.9, 5.4 h → 1 each; 19 h → 2; 146 h → 15;
        // 452 h → 46: 5 + 2 + 15 + 46 = 68.
        assert_eq!(m.science_windows(), 68);
        assert_eq!(p.science_windows_by_timers(), 68);
        // One stabilisation per window that does not finish its object: 68 − 8 = 60.
        assert_eq!(m.events.iter().filter(|e| e.sup.state == S1).count(), 60);
        // 60 d + 8 formations of 9 001 s + 68 transients of max(48, 30) s + 633.2 h of science
        // + 60 × u1 + 5 d.
        assert_eq!(p.u1, U1_TICKS);
        let want_s = 5_184_000 + 8 * 9_001 + 68 * 48 + 2_279_520 + 432_000;
        assert_eq!(m.end_tick, want_s * 100 + 60 * U1_TICKS);
        // Each stabilisation lasts u1.
        for w in m.events.windows(2).filter(|w| w[0].sup.state == S1) {
            assert_eq!(w[1].tick - w[0].tick, U1_TICKS);
        }
        assert_eq!(m.time_in(S3), 2_279_520 * 100);
        assert_eq!(m.time_in(S0), 5_184_000 * 100);
        assert_eq!(m.time_in(S5), 432_000 * 100);
        assert!(m.events.iter().filter(|e| e.sup.state == S2).all(|e| e.u2_ticks == 4800));
    }

    #[test]
    fn the_leader_follows_and_u2_is_the_larger_prediction_from_the_measured_state() {
        // A predictor that reads the state: T grows with |ω₀| (clamped to [7.2, 72] s).
        let by_rate = |x: &crate::learn::transient::gains::MeasuredState, _w: f64| TransientGains {
            k1: 0.1,
            k2: 0.3,
            t_s: 10.0 + 20.0 * x.omega_body_rad_s.iter().map(|w| w * w).sum::<f64>().sqrt(),
        };
        let m = run(&paper(), &by_rate, &by_rate, 3, u64::MAX).unwrap();
        let transients: Vec<&Event> = m.events.iter().filter(|e| e.sup.state == S2).collect();
        assert_eq!(transients.len(), 68);
        for e in &transients {
            let want = u2_ticks(e.leader.t_hat_s, e.follower.t_s, 7.2, 72.0, 0.01);
            assert_eq!(e.u2_ticks, want);
            assert!(e.leader.t_hat_s != e.follower.t_s, "each spacecraft draws its own state");
        }
        // The transients last u2 each.
        for w in m.events.windows(2).filter(|w| w[0].sup.state == S2) {
            assert_eq!(w[1].tick - w[0].tick, w[0].u2_ticks);
        }
        assert!(m.events.iter().all(|e| (e.leader.ack_state, e.leader.ack_id) == (e.sup.state, e.sup.id)));
        // Same seed, same run; another seed, other predictions.
        assert_eq!(run(&paper(), &by_rate, &by_rate, 3, u64::MAX).unwrap(), m);
        assert_ne!(run(&paper(), &by_rate, &by_rate, 4, u64::MAX).unwrap().end_tick, m.end_tick);
    }

    #[test]
    fn a_horizon_stops_the_run_where_it_is() {
        let m = run(&paper(), &fixed(48.0), &fixed(48.0), 1, 1000).unwrap();
        assert!(!m.finished);
        assert_eq!(m.end_tick, 1000);
        assert_eq!(m.events.len(), 1);
        assert_eq!(m.events[0].sup.state, S0);
    }
}
