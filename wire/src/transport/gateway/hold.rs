//! Holding what goes to a remote host until the step's last of it: one batch a step.
//!
//! This host's agents finish a step one after another, and the out thread, woken by each share,
//! sent each in a batch of its own: across three hosts (fig1, three servicers on each of two
//! hosts) 6 140–11 450 batches carried 12 000 shares in 2 000 steps where 4 000 would do, and
//! every extra batch is a zenoh put here and a delivery and a wake-up there. Nothing on the
//! step's path waits for an early share: the plant (and every reader) needs all of a step's
//! shares before the next step. So a destination's shares are held until every local sender read
//! there has shared the newest step held — every sender still live: one that did not share the
//! step before (dead, frozen, not started) is not waited for — or for at most [`HOLD_MAX`]. The
//! plant's measurements are held the same way, per agent they are for (the plant publishes a
//! step's one after another and rings after each: the out thread, woken by the first, sent the
//! rest in a second batch in up to half of the steps).

use std::time::{Duration, Instant};

/// The longest a share is held waiting for the rest of its step's: a bound for what the rule
/// cannot see (a sender that died or froze after sharing the step before, or one whose share a
/// fault delays), each costing it once; not a pace. Longer than a live sender of a busy host
/// takes after its peers (sixty agents on two cores: a few ms), so that those steps still go as
/// one batch.
pub(super) const HOLD_MAX: Duration = Duration::from_millis(5);

/// Per sender (per agent a measurement is for) the newest step it sent; per destination the
/// senders read there and what is held for it.
#[derive(Debug)]
pub(super) struct StepHold {
    /// Indexed by agent id.
    last: Vec<Option<u64>>,
    /// Per destination: the local agents whose shares go there.
    senders: Vec<Vec<u32>>,
    /// Per destination: the newest step held, and since when anything is held.
    newest: Vec<Option<u64>>,
    since: Vec<Option<Instant>>,
}

impl StepHold {
    /// `senders[d]`: the local agents (ids up to `n_agents`) read at destination `d`.
    pub(super) fn new(n_agents: usize, senders: Vec<Vec<u32>>) -> Self {
        let n_dest = senders.len();
        StepHold { last: vec![None; n_agents + 1], senders, newest: vec![None; n_dest], since: vec![None; n_dest] }
    }

    /// Agent `j` shared `step`, now held for destinations `to`.
    pub(super) fn shared(&mut self, j: u32, step: u64, to: &[usize], now: Instant) {
        // The latest, not the greatest: one sender's messages come in order, and a step garbled
        // in transit (a `corrupt` fault) is then forgotten at its next message.
        if let Some(last) = self.last.get_mut(j as usize) {
            *last = Some(step);
        }
        for &d in to {
            self.newest[d] = Some(self.newest[d].map_or(step, |s| s.max(step)));
            self.since[d].get_or_insert(now);
        }
    }

    /// Whether what is held for `d` may go: every live sender read there has shared the newest
    /// step held, or it has been held for [`HOLD_MAX`].
    pub(super) fn ready(&self, d: usize, now: Instant) -> bool {
        let Some(k) = self.newest[d] else { return true };
        if self.since[d].is_some_and(|t| now.duration_since(t) >= HOLD_MAX) {
            return true;
        }
        self.senders[d].iter().all(|&j| match self.last.get(j as usize).copied().flatten() {
            // Up to date, or not live: it did not share the step before.
            Some(s) => s >= k || s.saturating_add(1) < k,
            // Never shared: awaited at step 0 only.
            None => k > 0,
        })
    }

    /// What was held for `d` went out.
    pub(super) fn sent(&mut self, d: usize) {
        self.newest[d] = None;
        self.since[d] = None;
    }

    /// How long the out thread may sleep before a hold runs out (none when nothing is held).
    pub(super) fn until_due(&self, now: Instant) -> Option<Duration> {
        self.since.iter().flatten().map(|&t| HOLD_MAX.saturating_sub(now.duration_since(t))).min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Agents 1, 2, 3 here, all read at destination 0; agent 3 also at destination 1.
    fn hold() -> StepHold {
        StepHold::new(3, vec![vec![1, 2, 3], vec![3]])
    }

    /// Every agent shared step 0, and it went.
    fn after_step_0() -> (StepHold, Instant) {
        let (mut h, t) = (hold(), Instant::now());
        step(&mut h, 0, &[1, 2, 3], t);
        h.sent(0);
        (h, t)
    }

    /// Agents `who` share `k`, for destination 0 (agent 3 also for 1).
    fn step(h: &mut StepHold, k: u64, who: &[u32], t: Instant) {
        for &j in who {
            h.shared(j, k, if j == 3 { &[0, 1] } else { &[0] }, t);
        }
    }

    #[test]
    fn a_destinations_shares_go_once_every_sender_has_shared_the_step() {
        let (mut h, t) = (hold(), Instant::now());
        assert!(h.ready(0, t), "nothing held");
        h.shared(1, 0, &[0], t);
        h.shared(2, 0, &[0], t);
        assert!(!h.ready(0, t), "agent 3's share of step 0 is still to come");
        h.shared(3, 0, &[0, 1], t);
        assert!(h.ready(0, t) && h.ready(1, t));
        h.sent(0);
        h.sent(1);
        h.shared(2, 1, &[0], t);
        assert!(!h.ready(0, t));
        h.shared(1, 1, &[0], t);
        h.shared(3, 1, &[0, 1], t);
        assert!(h.ready(0, t));
    }

    /// A sender that did not share the step before (dead or frozen) is not waited for; once it
    /// shares again it is.
    #[test]
    fn a_sender_silent_since_the_step_before_is_not_waited_for() {
        let (mut h, t) = after_step_0();
        step(&mut h, 1, &[1, 2], t);
        assert!(!h.ready(0, t), "agent 3 shared step 0: it is awaited at step 1");
        h.sent(0);
        step(&mut h, 2, &[1, 2], t);
        assert!(h.ready(0, t), "agent 3 missed step 1: not awaited at step 2");
        h.sent(0);
        h.shared(3, 3, &[0, 1], t);
        h.shared(1, 3, &[0], t);
        assert!(!h.ready(0, t), "back: agent 2 is awaited at step 3");
        h.shared(2, 3, &[0], t);
        assert!(h.ready(0, t));
    }

    /// A garbled step (far ahead) lets what is held go, and is forgotten at the sender's next
    /// message: it is awaited again.
    #[test]
    fn a_garbled_step_is_forgotten_at_the_next_message() {
        let (mut h, t) = after_step_0();
        h.shared(3, 1 << 40, &[0, 1], t);
        assert!(h.ready(0, t), "the others look silent since the step before");
        h.sent(0);
        step(&mut h, 1, &[1, 2, 3], t);
        h.sent(0);
        step(&mut h, 2, &[1, 2], t);
        assert!(!h.ready(0, t), "agent 3 shared step 1: it is awaited at step 2");
    }

    #[test]
    fn nothing_is_held_longer_than_the_bound() {
        let (mut h, t) = (hold(), Instant::now());
        h.shared(1, 0, &[0], t);
        assert!(!h.ready(0, t + HOLD_MAX / 2));
        assert_eq!(h.until_due(t + HOLD_MAX / 4), Some(HOLD_MAX * 3 / 4));
        assert!(h.ready(0, t + HOLD_MAX));
        assert_eq!(h.until_due(t + 2 * HOLD_MAX), Some(Duration::ZERO));
        h.sent(0);
        assert_eq!(h.until_due(t), None);
    }
}
