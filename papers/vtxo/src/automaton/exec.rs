//! Running a supervisor table ([`crate::automaton::table`], Sec. 8 of "Explainable AI-Enhanced
//! Supervisory Control for High-Precision Spacecraft Formation") in integer ticks: the current
//! location, Id and clocks, how long until each exit's guard holds with the inputs held
//! ([`Supervisor::next`]), advancing the stopwatches, and firing a transition with its reset.
//! The same code serves a discrete-event run (jump to the next event) and a lockstep one (advance
//! one tick, fire what holds).

use crate::automaton::table::{Atom, Automaton, StateIx, Threshold};

/// The inputs i = {u1, u2, u3, u4} (and the science window), in ticks; u3 by Id (Table 6).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Inputs {
    pub u1: u64,
    pub u2: u64,
    pub u3: Vec<u64>,
    /// u4 read as a duration (the printed table only).
    pub u4: u64,
    pub window: u64,
    /// The formation-reached event (the corrected u4).
    pub formation: bool,
}

/// The automaton's state: location, Id, clocks (ticks).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Supervisor {
    pub state: StateIx,
    pub id: u32,
    pub clocks: Vec<u64>,
}

impl Supervisor {
    /// Init: s = s(0), every clock 0, Id = 0.
    pub fn new(a: &Automaton) -> Self {
        Self { state: a.initial, id: 0, clocks: vec![0; a.clocks.len()] }
    }

    fn value(&self, th: Threshold, i: &Inputs) -> u64 {
        match th {
            Threshold::U1 => i.u1,
            Threshold::U2 => i.u2,
            // Past the table (never with a validated configuration): never reached.
            Threshold::U3 => i.u3.get(self.id as usize).copied().unwrap_or(u64::MAX),
            Threshold::U4 => i.u4,
            Threshold::Window => i.window,
            Threshold::Ticks(n) => n,
        }
    }

    fn runs(&self, a: &Automaton, clock: usize) -> bool {
        a.clocks[clock].runs_in.contains(&self.state)
    }

    /// Ticks from now until `guard` holds if time passes in the current location with the inputs
    /// held, or None when it never does there.
    pub fn delay_to(&self, a: &Automaton, guard: &[Atom], i: &Inputs) -> Option<u64> {
        let (mut lo, mut hi) = (0u64, u64::MAX);
        for atom in guard {
            match *atom {
                Atom::AtLeast(c, th) => {
                    let (x, v) = (self.clocks[c], self.value(th, i));
                    if x < v {
                        if !self.runs(a, c) {
                            return None;
                        }
                        lo = lo.max(v - x);
                    }
                }
                Atom::Below(c, th) => {
                    let (x, v) = (self.clocks[c], self.value(th, i));
                    if x >= v {
                        return None;
                    }
                    if self.runs(a, c) {
                        hi = hi.min(v - x);
                    }
                }
                Atom::IdIs(n) if self.id != n => return None,
                Atom::IdIsNot(n) if self.id == n => return None,
                Atom::Formation(f) if i.formation != f => return None,
                _ => {}
            }
        }
        (lo < hi).then_some(lo)
    }

    /// Whether `guard` holds now.
    pub fn holds(&self, a: &Automaton, guard: &[Atom], i: &Inputs) -> bool {
        self.delay_to(a, guard, i) == Some(0)
    }

    /// The earliest exit of the current location: (ticks until it, transition index). Ties go to
    /// the first in the table (a validated table has disjoint guards, so a tie cannot happen).
    pub fn next(&self, a: &Automaton, i: &Inputs) -> Option<(u64, usize)> {
        a.outgoing(self.state)
            .filter_map(|(k, t)| self.delay_to(a, &t.guard, i).map(|d| (d, k)))
            .min_by_key(|&(d, k)| (d, k))
    }

    /// Let `ticks` pass in the current location.
    pub fn advance(&mut self, a: &Automaton, ticks: u64) {
        for c in 0..self.clocks.len() {
            if self.runs(a, c) {
                self.clocks[c] += ticks;
            }
        }
    }

    /// Take transition `k` (its guard is the caller's business): reset, Id, location.
    pub fn fire(&mut self, a: &Automaton, k: usize) {
        let t = &a.transitions[k];
        for &c in &t.reset.clocks {
            self.clocks[c] = 0;
        }
        if t.reset.next_id {
            self.id += 1;
        }
        self.state = t.to;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::automaton::table::*;

    fn inputs() -> Inputs {
        Inputs { u1: 100, u2: 5, u3: vec![50, 7, 25, 30], u4: 3, window: 10, formation: false }
    }

    /// Jump from event to event, the formation event raised 3 ticks into s4.
    fn run(a: &Automaton, i: &mut Inputs) -> Vec<(u64, StateIx, u32)> {
        let mut s = Supervisor::new(a);
        let (mut t, mut out) = (0, vec![(0, s.state, s.id)]);
        while s.state != a.final_state {
            i.formation = s.state == S4 && s.clocks[S4] >= 3;
            let env = (s.state == S4 && !i.formation).then(|| 3 - s.clocks[S4]);
            let (d, k) = s.next(a, i).map_or((u64::MAX, None), |(d, k)| (d, Some(k)));
            if let Some(e) = env.filter(|e| *e < d) {
                s.advance(a, e);
                t += e;
                continue;
            }
            s.advance(a, d);
            t += d;
            s.fire(a, k.expect("a validated table always has an exit"));
            out.push((t, s.state, s.id));
        }
        out
    }

    #[test]
    fn a_small_mission_runs_by_hand() {
        // u3 = [50 commissioning, 7 and 25 science, 30 de-commissioning], window 10, T 5,
        // u1 100, formation 3 ticks into s4: object 1 fits one window, object 2 needs three
        // (10 + 10 + 5).
        let a = Automaton::vtxo(2);
        let got = run(&a, &mut inputs());
        let want = vec![
            (0, S0, 0),
            (50, S4, 1),
            (53, S2, 1),
            (58, S3, 1),
            (65, S4, 2),
            (68, S2, 2),
            (73, S3, 2),
            (83, S1, 2),
            (183, S2, 2),
            (188, S3, 2),
            (198, S1, 2),
            (298, S2, 2),
            (303, S3, 2),
            (308, S5, 3),
            (338, S6, 3),
        ];
        assert_eq!(got, want);
    }

    #[test]
    fn a_window_ending_with_the_object_goes_to_the_next_mode() {
        // Object 1 needs exactly one window: t3 = u3 and tw = window at once → s4, not s1.
        let a = Automaton::vtxo(2);
        let mut i = Inputs { u3: vec![50, 10, 25, 30], ..inputs() };
        let got = run(&a, &mut i);
        assert_eq!(got[3..5], [(58, S3, 1), (68, S4, 2)]);
    }

    #[test]
    fn stopwatches_run_only_in_their_location() {
        let a = Automaton::vtxo(8);
        let mut s = Supervisor::new(&a);
        s.advance(&a, 7);
        assert_eq!(s.clocks, vec![7, 0, 0, 0, 0, 0, 0]);
        s.state = S3;
        s.advance(&a, 4);
        assert_eq!(s.clocks, vec![7, 0, 0, 4, 0, 0, 4]);
    }

    #[test]
    fn the_delay_respects_upper_bounds_and_frozen_clocks() {
        let a = Automaton::vtxo(2);
        let i = inputs();
        let mut s = Supervisor { state: S3, id: 2, clocks: vec![0, 0, 0, 20, 0, 0, 0] };
        // g(3,1): tw reaches 10 while t3 (20 → 30) stays < 25? No: t3 reaches 25 first → g(3,5).
        assert_eq!(s.next(&a, &i), Some((5, 5)));
        s.clocks[3] = 0;
        assert_eq!(s.next(&a, &i), Some((10, 3)));
        // A clock that does not run here never reaches its threshold.
        s.state = S1;
        assert_eq!(s.delay_to(&a, &[Atom::AtLeast(3, Threshold::Ticks(1))], &i), None);
    }
}
