//! The mission supervisor of Sec. 8 of "Explainable AI-Enhanced Supervisory Control for
//! High-Precision Spacecraft Formation" (arXiv:2509.13331) as data: a timed automaton
//! TA = {s, t, i, k, Init} (92) — locations s0 commissioning, s1 formation stabilisation, s2
//! transient, s3 science, s4 next operational mode (Id++), s5 de-commissioning, s6 end; clocks
//! t0..t5; inputs u1..u4; transitions k_ij = {s_i, g(i, j), reset(i, j), s_j} with the guards of
//! Table 8 and the resets of Table 7; u3(Id) of Table 6. Pure: no transport, no time source.
//! [`crate::automaton::check`] validates a table, [`crate::automaton::exec`] runs one.
//!
//! Semantics (the paper's words made precise):
//! - Clocks are stopwatches: "the local timer shows the amount of time that the system has spent
//!   in each state", so clock tᵢ runs only in sᵢ ([`ClockDef::runs_in`]). Time is integer ticks
//!   (the scenario's step), so guards compare exactly.
//! - Transitions are urgent: one fires the instant its guard holds (the print has no
//!   invariants). A printed strict guard `u < t` is taken as `t ≥ u` (fired at the boundary, the
//!   infimum of the instants where it holds); a printed `u ≥ t` as `t < u`.
//! - Id is a variable of the automaton; a reset may increment it ([`Reset::next_id`]).
//!
//! Where [`Automaton::vtxo`] departs from the print ([`Automaton::printed`] is the print, which
//! validation refuses):
//! 1. g(3,4) `u3 ≥ t3` and g(3,1) `u3 < t3` are inverted and complementary: s3 would leave at
//!    once to s4. Fixed with the science window the paper describes in words (Sec. 2.5 "a 10-hour
//!    observation in the apogee", u1 = 32.5 h − 10 h − 3 min) but never puts in a guard: a window
//!    clock tw (runs in s3, reset on entry by reset(2,3)) and input `window` (10 h).
//!    g(3,1) = tw ≥ window ∧ t3 < u3(Id): the window ended, the object needs more time → s1;
//!    g(3,4) = t3 ≥ u3(Id) ∧ Id ≠ last object: the object is done → s4.
//! 2. g(3,5) `452 h ≤ t3` overlaps g(3,4) (u3(8) = 452 h): g(3,5) = t3 ≥ u3(Id) ∧ Id = last
//!    object (8 with Table 6), which is the printed condition made exclusive.
//! 3. reset(3,4) and reset(4,2) name t1 (which s1 resets itself); they mean t3 (science time is
//!    per object: t3 accumulates over the windows of one object and restarts with the next) and
//!    t4. reset(3,5) resets t3 as printed.
//! 4. g(4,2) `u4 < t4` reads u4 as a duration; u4 is the event "formation reached":
//!    |r_rel − r_f| < 1 m and transverse error < 1 mm (Sec. 2.3) — atom [`Atom::Formation`].
//! 5. (3,5) also increments Id (8 → 9) so that g(5,6) `u3 < t5` reads u3(9) = 5 days, the
//!    de-commissioning row of Table 6; the print increments Id only in s4.
//! 6. The print lists s = {s0..s5} and t = {t1, t2, t3} but uses s6 and t0..t5: all are here.

use std::fmt;

/// A location: an index into [`Automaton::states`].
pub type StateIx = usize;
/// A clock: an index into [`Automaton::clocks`].
pub type ClockIx = usize;

pub const S0: StateIx = 0;
pub const S1: StateIx = 1;
pub const S2: StateIx = 2;
pub const S3: StateIx = 3;
pub const S4: StateIx = 4;
pub const S5: StateIx = 5;
pub const S6: StateIx = 6;
/// Clocks t0..t5 have the index of their state; the science-window clock comes after them.
pub const TW: ClockIx = 6;

/// What a clock is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threshold {
    /// u1, the formation-stabilisation rule.
    U1,
    /// u2 = T, the transient duration (max of both spacecraft's predictions).
    U2,
    /// u3(Id), Table 6.
    U3,
    /// u4 read as a duration (the print only; the corrected table uses [`Atom::Formation`]).
    U4,
    /// The science window (10 h; not an input of the print, see the module docs).
    Window,
    /// A constant number of ticks.
    Ticks(u64),
}

/// One condition of a guard (a guard is their conjunction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Atom {
    /// clock ≥ threshold.
    AtLeast(ClockIx, Threshold),
    /// clock < threshold.
    Below(ClockIx, Threshold),
    IdIs(u32),
    IdIsNot(u32),
    /// The formation-reached event (u4) is (true) or is not (false) present.
    Formation(bool),
}

/// What a transition resets: these clocks to 0, and Id += 1 when `next_id`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Reset {
    pub clocks: Vec<ClockIx>,
    pub next_id: bool,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transition {
    pub from: StateIx,
    pub to: StateIx,
    /// Conjunction; empty = always true.
    pub guard: Vec<Atom>,
    pub reset: Reset,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StateDef {
    /// "s3".
    pub label: String,
    /// "science".
    pub name: String,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClockDef {
    pub name: String,
    /// The locations where the clock advances (a stopwatch elsewhere).
    pub runs_in: Vec<StateIx>,
}

/// A timed automaton as a table. Build one, then [`Automaton::validate`] it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Automaton {
    pub states: Vec<StateDef>,
    pub clocks: Vec<ClockDef>,
    pub transitions: Vec<Transition>,
    pub initial: StateIx,
    /// The one location without an exit (s6).
    pub final_state: StateIx,
}

fn state(label: &str, name: &str) -> StateDef {
    StateDef { label: label.into(), name: name.into() }
}

fn tr(from: StateIx, to: StateIx, guard: Vec<Atom>, clocks: Vec<ClockIx>, next_id: bool) -> Transition {
    Transition { from, to, guard, reset: Reset { clocks, next_id } }
}

impl Automaton {
    fn vtxo_locations() -> (Vec<StateDef>, Vec<ClockDef>) {
        let states = vec![
            state("s0", "commissioning"),
            state("s1", "formation stabilisation"),
            state("s2", "transient"),
            state("s3", "science"),
            state("s4", "next operational mode"),
            state("s5", "de-commissioning"),
            state("s6", "end"),
        ];
        let mut clocks: Vec<ClockDef> = (0..6).map(|i| ClockDef { name: format!("t{i}"), runs_in: vec![i] }).collect();
        clocks.push(ClockDef { name: "tw".into(), runs_in: vec![S3] });
        (states, clocks)
    }

    /// The corrected supervisor (see the module docs); `last_object` is the Id of the last
    /// science object (8 with Table 6: Id 9 is the de-commissioning).
    pub fn vtxo(last_object: u32) -> Self {
        use Atom::*;
        use Threshold::*;
        let (states, clocks) = Self::vtxo_locations();
        let transitions = vec![
            tr(S0, S4, vec![AtLeast(0, U3)], vec![0], true),
            tr(S1, S2, vec![AtLeast(1, U1)], vec![1], false),
            tr(S2, S3, vec![AtLeast(2, U2)], vec![2, TW], false),
            tr(S3, S1, vec![AtLeast(TW, Window), Below(3, U3)], vec![], false),
            tr(S3, S4, vec![AtLeast(3, U3), IdIsNot(last_object)], vec![3], true),
            tr(S3, S5, vec![AtLeast(3, U3), IdIs(last_object)], vec![3], true),
            tr(S4, S2, vec![Formation(true)], vec![4], false),
            tr(S5, S6, vec![AtLeast(5, U3)], vec![5], false),
        ];
        Self { states, clocks, transitions, initial: S0, final_state: S6 }
    }

    /// Tables 7 and 8 as printed (the science-window clock exists but nothing reads it), with
    /// the tick length `tick_s` for g(3,5)'s constant 452 h. [`Automaton::validate`] refuses it.
    pub fn printed(tick_s: f64) -> Self {
        use Atom::*;
        use Threshold::*;
        let (states, clocks) = Self::vtxo_locations();
        let h452 = (452.0 * 3600.0 / tick_s).round() as u64;
        let transitions = vec![
            tr(S0, S4, vec![AtLeast(0, U3)], vec![0], true),
            tr(S1, S2, vec![AtLeast(1, U1)], vec![1], false),
            tr(S2, S3, vec![AtLeast(2, U2)], vec![2], false),
            tr(S3, S4, vec![Below(3, U3)], vec![1], true),
            tr(S3, S1, vec![AtLeast(3, U3)], vec![], false),
            tr(S3, S5, vec![AtLeast(3, Ticks(h452))], vec![3], false),
            tr(S4, S2, vec![AtLeast(4, U4)], vec![1], false),
            tr(S5, S6, vec![AtLeast(5, U3)], vec![5], false),
        ];
        Self { states, clocks, transitions, initial: S0, final_state: S6 }
    }

    /// "g(3,4)": the paper's name of transition `i`.
    pub fn transition_name(&self, i: usize) -> String {
        let t = &self.transitions[i];
        let num =
            |s: StateIx| self.states.get(s).map_or(s.to_string(), |d| d.label.trim_start_matches('s').to_string());
        format!("g({},{})", num(t.from), num(t.to))
    }

    /// "s3 (science)".
    pub fn state_name(&self, s: StateIx) -> String {
        self.states.get(s).map_or(format!("state #{s}"), |d| format!("{} ({})", d.label, d.name))
    }

    pub fn outgoing(&self, s: StateIx) -> impl Iterator<Item = (usize, &Transition)> {
        self.transitions.iter().enumerate().filter(move |(_, t)| t.from == s)
    }
}

impl fmt::Display for Threshold {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Threshold::U1 => write!(f, "u1"),
            Threshold::U2 => write!(f, "u2"),
            Threshold::U3 => write!(f, "u3(Id)"),
            Threshold::U4 => write!(f, "u4"),
            Threshold::Window => write!(f, "window"),
            Threshold::Ticks(n) => write!(f, "{n} ticks"),
        }
    }
}
