//! Validation of a supervisor table ([`crate::automaton::table::Automaton`], Sec. 8 of "Explainable
//! AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"): every problem, each
//! naming the states and transitions (g(i,j)) it is about.
//!
//! - structure: indices in range, exactly one final state (s6), which has no exit;
//! - [`AutomatonError::Unreachable`]: a state no path of transitions reaches from Init;
//! - [`AutomatonError::NoExit`]: a state other than the final one without an outgoing
//!   transition (the mission would stop there);
//! - [`AutomatonError::Overlap`]: two exits of one state whose guards can hold at once (the
//!   supervisor would not be deterministic, as the paper's Sec. 9 claims it is). The test is
//!   syntactic and conservative: two guards are disjoint only when one atom of each contradicts
//!   one of the other (t ≥ x against t < x on the same clock and threshold, or constants with
//!   disjoint ranges; Id = a against Id = b ≠ a or Id ≠ a; formation against no formation);
//!   anything else is reported as a possible overlap;
//! - [`AutomatonError::ExitsAtEntry`]: an exit whose guard has no lower bound in time (no t ≥ x,
//!   no formation event) can hold the instant its state is entered — a zero dwell, which Sec. 9's
//!   non-Zeno argument ("guards that require strictly positive dwell times") rules out. This is
//!   what the printed g(3,4) `u3 ≥ t3` does.

use std::fmt;

use crate::automaton::table::{Atom, Automaton, StateIx, Threshold};

/// One thing wrong with a supervisor table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AutomatonError {
    NoStates,
    /// A transition or the initial/final state names a state that does not exist.
    UnknownState {
        what: String,
        index: StateIx,
    },
    /// A guard or reset names a clock that does not exist.
    UnknownClock {
        transition: String,
        index: usize,
    },
    /// The final state has an exit.
    FinalHasExit {
        state: String,
        transition: String,
    },
    Unreachable {
        state: String,
    },
    NoExit {
        state: String,
    },
    Overlap {
        state: String,
        a: String,
        b: String,
    },
    ExitsAtEntry {
        transition: String,
    },
}

impl fmt::Display for AutomatonError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoStates => write!(f, "the automaton has no states"),
            Self::UnknownState { what, index } => write!(f, "{what} names state #{index}, which does not exist"),
            Self::UnknownClock { transition, index } => {
                write!(f, "{transition} names clock #{index}, which does not exist")
            }
            Self::FinalHasExit { state, transition } => {
                write!(f, "the final state {state} has an exit, {transition}")
            }
            Self::Unreachable { state } => write!(f, "{state} is unreachable from the initial state"),
            Self::NoExit { state } => write!(f, "{state} has no exit and is not the final state"),
            Self::Overlap { state, a, b } => write!(f, "the guards {a} and {b} of {state} can hold at once"),
            Self::ExitsAtEntry { transition } => write!(
                f,
                "{transition} has no lower bound in time (no clock ≥ threshold, no formation event): it can \
                 hold the instant its state is entered (zero dwell)"
            ),
        }
    }
}

impl std::error::Error for AutomatonError {}

fn constant_range(a: &Atom) -> Option<(usize, u64, u64)> {
    // [lo, hi) of a clock constrained against a constant.
    match *a {
        Atom::AtLeast(c, Threshold::Ticks(n)) => Some((c, n, u64::MAX)),
        Atom::Below(c, Threshold::Ticks(n)) => Some((c, 0, n)),
        _ => None,
    }
}

/// Whether the two atoms can never hold together.
fn contradict(a: &Atom, b: &Atom) -> bool {
    use Atom::*;
    match (a, b) {
        (AtLeast(c1, t1), Below(c2, t2)) | (Below(c2, t2), AtLeast(c1, t1)) if c1 == c2 && t1 == t2 => true,
        (IdIs(x), IdIs(y)) => x != y,
        (IdIs(x), IdIsNot(y)) | (IdIsNot(y), IdIs(x)) => x == y,
        (Formation(x), Formation(y)) => x != y,
        _ => match (constant_range(a), constant_range(b)) {
            (Some((c1, lo1, hi1)), Some((c2, lo2, hi2))) => c1 == c2 && (hi1 <= lo2 || hi2 <= lo1),
            _ => false,
        },
    }
}

/// Whether two guards are disjoint by the syntactic test of the module docs.
pub fn disjoint(g1: &[Atom], g2: &[Atom]) -> bool {
    g1.iter().any(|a| g2.iter().any(|b| contradict(a, b)))
}

fn has_time_lower_bound(g: &[Atom]) -> bool {
    g.iter().any(|a| matches!(a, Atom::AtLeast(_, th) if *th != Threshold::Ticks(0)) || *a == Atom::Formation(true))
}

impl Automaton {
    /// Every problem of the table (empty: valid).
    pub fn problems(&self) -> Vec<AutomatonError> {
        let mut out = Vec::new();
        let n = self.states.len();
        if n == 0 {
            return vec![AutomatonError::NoStates];
        }
        for (what, s) in [("the initial state", self.initial), ("the final state", self.final_state)] {
            if s >= n {
                out.push(AutomatonError::UnknownState { what: what.into(), index: s });
            }
        }
        for (i, t) in self.transitions.iter().enumerate() {
            let name = self.transition_name(i);
            for s in [t.from, t.to] {
                if s >= n {
                    out.push(AutomatonError::UnknownState { what: name.clone(), index: s });
                }
            }
            let guard_clocks = t.guard.iter().filter_map(|a| match a {
                Atom::AtLeast(c, _) | Atom::Below(c, _) => Some(*c),
                _ => None,
            });
            for c in guard_clocks.chain(t.reset.clocks.iter().copied()) {
                if c >= self.clocks.len() {
                    out.push(AutomatonError::UnknownClock { transition: name.clone(), index: c });
                }
            }
        }
        if !out.is_empty() {
            return out;
        }
        for (i, _) in self.outgoing(self.final_state) {
            out.push(AutomatonError::FinalHasExit {
                state: self.state_name(self.final_state),
                transition: self.transition_name(i),
            });
        }
        let reached = self.reachable();
        for s in 0..n {
            if !reached[s] {
                out.push(AutomatonError::Unreachable { state: self.state_name(s) });
            }
            if s != self.final_state && self.outgoing(s).next().is_none() {
                out.push(AutomatonError::NoExit { state: self.state_name(s) });
            }
            let exits: Vec<usize> = self.outgoing(s).map(|(i, _)| i).collect();
            for (k, &a) in exits.iter().enumerate() {
                for &b in &exits[k + 1..] {
                    if !disjoint(&self.transitions[a].guard, &self.transitions[b].guard) {
                        out.push(AutomatonError::Overlap {
                            state: self.state_name(s),
                            a: self.transition_name(a),
                            b: self.transition_name(b),
                        });
                    }
                }
            }
        }
        for (i, t) in self.transitions.iter().enumerate() {
            if !has_time_lower_bound(&t.guard) {
                out.push(AutomatonError::ExitsAtEntry { transition: self.transition_name(i) });
            }
        }
        out
    }

    /// Ok, or every problem.
    pub fn validate(&self) -> Result<(), Vec<AutomatonError>> {
        let p = self.problems();
        if p.is_empty() { Ok(()) } else { Err(p) }
    }

    /// Which states a path of transitions reaches from the initial one (guards ignored).
    fn reachable(&self) -> Vec<bool> {
        let mut seen = vec![false; self.states.len()];
        let mut stack = vec![self.initial];
        while let Some(s) = stack.pop() {
            if std::mem::replace(&mut seen[s], true) {
                continue;
            }
            stack.extend(self.outgoing(s).map(|(_, t)| t.to));
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::automaton::table::*;

    #[test]
    fn the_corrected_table_is_valid() {
        assert_eq!(Automaton::vtxo(8).validate(), Ok(()));
    }

    #[test]
    fn the_printed_table_is_refused_for_its_overlaps_and_its_immediate_exit() {
        let p = Automaton::printed(0.01).problems();
        let s3 = "s3 (science)".to_string();
        assert!(p.contains(&AutomatonError::Overlap { state: s3.clone(), a: "g(3,4)".into(), b: "g(3,5)".into() }));
        assert!(p.contains(&AutomatonError::Overlap { state: s3, a: "g(3,1)".into(), b: "g(3,5)".into() }));
        assert!(p.contains(&AutomatonError::ExitsAtEntry { transition: "g(3,4)".into() }));
        // g(3,4) and g(3,1) are complementary: not an overlap, the immediate exit is their defect.
        assert_eq!(p.len(), 3, "{p:?}");
    }

    #[test]
    fn an_unreachable_state_is_named() {
        let mut a = Automaton::vtxo(8);
        // Without (3,1) nothing enters s1.
        a.transitions.retain(|t| !(t.from == S3 && t.to == S1));
        assert_eq!(a.problems(), vec![AutomatonError::Unreachable { state: "s1 (formation stabilisation)".into() }]);
    }

    #[test]
    fn a_state_without_an_exit_is_named() {
        let mut a = Automaton::vtxo(8);
        a.transitions.retain(|t| t.from != S5);
        assert_eq!(
            a.problems(),
            vec![
                AutomatonError::NoExit { state: "s5 (de-commissioning)".into() },
                AutomatonError::Unreachable { state: "s6 (end)".into() },
            ]
        );
    }

    #[test]
    fn overlapping_guards_are_named() {
        let mut a = Automaton::vtxo(8);
        // g(3,5) without its Id condition overlaps g(3,4).
        let i = a.transitions.iter().position(|t| t.from == S3 && t.to == S5).unwrap();
        a.transitions[i].guard = vec![Atom::AtLeast(S3, Threshold::U3)];
        assert_eq!(
            a.problems(),
            vec![AutomatonError::Overlap { state: "s3 (science)".into(), a: "g(3,4)".into(), b: "g(3,5)".into() }]
        );
    }

    #[test]
    fn constants_with_disjoint_ranges_do_not_overlap_and_touching_ones_do_not_either() {
        let at_least = |n| vec![Atom::AtLeast(0, Threshold::Ticks(n))];
        let below = |n| vec![Atom::Below(0, Threshold::Ticks(n))];
        assert!(disjoint(&at_least(10), &below(10)));
        assert!(disjoint(&at_least(11), &below(10)));
        assert!(!disjoint(&at_least(9), &below(10)));
        assert!(!disjoint(&at_least(9), &at_least(10)));
        // Different clocks never contradict.
        assert!(!disjoint(&at_least(10), &[Atom::Below(1, Threshold::Ticks(10))]));
    }

    #[test]
    fn structural_errors_are_named() {
        let mut a = Automaton::vtxo(8);
        a.transitions[0].to = 42;
        a.transitions[1].reset.clocks.push(9);
        assert_eq!(
            a.problems(),
            vec![
                AutomatonError::UnknownState { what: "g(0,42)".into(), index: 42 },
                AutomatonError::UnknownClock { transition: "g(1,2)".into(), index: 9 },
            ]
        );
        let mut a = Automaton::vtxo(8);
        a.transitions.push(a.transitions[0].clone());
        a.transitions.last_mut().unwrap().from = S6;
        let p = a.problems();
        assert!(p.contains(&AutomatonError::FinalHasExit { state: "s6 (end)".into(), transition: "g(6,4)".into() }));
        assert_eq!(Automaton { states: vec![], ..Automaton::vtxo(8) }.problems(), vec![AutomatonError::NoStates]);
    }

    #[test]
    fn errors_read_as_sentences_naming_what_they_are_about() {
        let e = AutomatonError::Overlap { state: "s3 (science)".into(), a: "g(3,4)".into(), b: "g(3,5)".into() };
        assert_eq!(e.to_string(), "the guards g(3,4) and g(3,5) of s3 (science) can hold at once");
    }
}
