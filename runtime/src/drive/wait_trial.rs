//! Adaptive waiting's trial of spinning against blocking, measured on the lockstep itself.
//!
//! Whether spinning pays depends on more than one process can see: with 50 agent processes on
//! 2 cores, a spinner's `sched_yield` comes back late because its own peers (woken from blocking
//! waits, so favoured by the scheduler) ran first — not because another program holds the core —
//! and the back-off of [`super::wait::Contention`] then made 95 % of the waits block: 610 steps/s
//! where spinning everywhere gave 1 836 and blocking everywhere 797 (`orchestrator bench --only
//! ring/N=50`, one run, the machine loaded by two builds). A process cannot tell its peers from
//! another program, but it can measure what each mode gives the whole lockstep: the time per step.
//!
//! So every [`PERIOD_STEPS`] steps, from step [`FIRST_TRIAL`] on, every process blocks for
//! [`TRIAL_STEPS`] steps, then spins for up to [`TRIAL_STEPS`] steps, both by the step index,
//! which every process of the lockstep shares: all of them wait the same way at the same steps,
//! and each one's time per step is the lockstep's under that way of waiting. (When some processes
//! spun while others blocked — a choice made by each from its own evidence, as the back-off did,
//! or a trial started from each one's own choice — the run was slower than either: 790 steps/s
//! at N = 50 against 1 751 spinning and 774 blocking.) Spinning is given up as soon as it has
//! taken as long as the whole blocking half (it is then slower), so a trial costs at most
//! [`TRIAL_STEPS`] blocking steps and as long again: with [`PERIOD_STEPS`] = 8 192 and
//! [`TRIAL_STEPS`] = 32, about 1 % of a run where spinning is three times as fast. Spinning is taken
//! only when it is clearly faster ([`SPIN_GAIN`]): a paced run's steps take as long either way,
//! and blocking then leaves the cores idle. The first steps (start-up) wait as
//! [`super::wait::SpinPolicy::Adaptive`] always did, with its contention back-off; between the
//! first trial and the next, each process waits as its trial chose. Telemetry does not depend on
//! how a process waits.

use std::time::Instant;

/// Steps of each measurement of a mode.
pub(super) const TRIAL_STEPS: u64 = 32;
/// Steps from one trial to the next.
pub(super) const PERIOD_STEPS: u64 = 8192;
/// The first trial's first step (the steps before it: start-up).
pub(super) const FIRST_TRIAL: u64 = 16;
/// Spinning is chosen when its time per step is below this share of blocking's.
const SPIN_GAIN: f64 = 0.95;

/// How a wait is to go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Mode {
    /// Start-up: adaptive spinning with its contention back-off.
    Learning,
    /// Spin (10 ms or four typical waits, at most 1 s; without the back-off, and through late
    /// yields: with more processes than cores a yield comes back late because the peers ran,
    /// which is what spinning is for), then block.
    Spin,
    /// Block at once.
    Block,
}

/// The trials' state of one process.
#[derive(Debug)]
pub(super) struct Trial {
    /// The mode it waits in between trials.
    choice: Mode,
    /// The trial under way: its period, and the step and time each half began.
    period: Option<u64>,
    first: Option<(u64, Instant)>,
    second: Option<(u64, Instant)>,
    /// Seconds per step of the first half (blocking).
    first_s: Option<f64>,
    /// Spinning was given up (it had taken longer than the blocking half).
    gave_up: bool,
    /// Trials that ended choosing spinning, and blocking.
    pub(super) chose_spin: u64,
    pub(super) chose_block: u64,
}

impl Trial {
    pub(super) fn new() -> Self {
        Trial {
            choice: Mode::Spin,
            period: None,
            first: None,
            second: None,
            first_s: None,
            gave_up: false,
            chose_spin: 0,
            chose_block: 0,
        }
    }

    /// The mode of a wait for step `k`.
    pub(super) fn mode(&mut self, k: u64) -> Mode {
        self.mode_at(k, Instant::now())
    }

    /// The same, at time `now`.
    fn mode_at(&mut self, k: u64, now: Instant) -> Mode {
        let Some(since) = k.checked_sub(FIRST_TRIAL) else { return Mode::Learning };
        let (period, pos) = (since / PERIOD_STEPS, since % PERIOD_STEPS);
        if self.period != Some(period) {
            self.conclude(k, now);
            *self = Trial { period: Some(period), ..Trial::new_keeping(self) };
        }
        if pos < TRIAL_STEPS {
            self.first.get_or_insert((k, now));
            return Mode::Block;
        }
        if pos < 2 * TRIAL_STEPS {
            if self.second.is_none()
                && let Some((k0, t0)) = self.first
                && k > k0
            {
                self.first_s = Some((now - t0).as_secs_f64() / (k - k0) as f64);
                self.second = Some((k, now));
            }
            let (Some(first_s), Some((_, t1))) = (self.first_s, self.second) else { return Mode::Block };
            if self.gave_up || (now - t1).as_secs_f64() > first_s * TRIAL_STEPS as f64 {
                self.gave_up = true;
                self.choice = Mode::Block;
                return Mode::Block;
            }
            return Mode::Spin;
        }
        self.conclude(k, now);
        self.choice
    }

    /// A fresh trial's state that keeps the choice and the counts.
    fn new_keeping(t: &Trial) -> Trial {
        Trial { choice: t.choice, chose_spin: t.chose_spin, chose_block: t.chose_block, ..Trial::new() }
    }

    /// End the trial under way at step `k` (once): the faster mode, blocking on a near tie.
    fn conclude(&mut self, k: u64, now: Instant) {
        let Some(block_s) = self.first_s.take() else { return };
        if let Some((k1, t1)) = self.second.take()
            && !self.gave_up
            && k > k1
        {
            let spin_s = (now - t1).as_secs_f64() / (k - k1) as f64;
            self.choice = if spin_s < SPIN_GAIN * block_s { Mode::Spin } else { Mode::Block };
        }
        if self.choice == Mode::Spin {
            self.chose_spin += 1;
        } else {
            self.chose_block += 1;
        }
    }
}

/// Whether step `k` is in a trial (either half).
#[cfg(test)]
fn in_trial(k: u64) -> bool {
    k.checked_sub(FIRST_TRIAL).is_some_and(|d| d % PERIOD_STEPS < 2 * TRIAL_STEPS)
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    /// Run steps `ks` on a clock of its own, each taking `spin` in spinning mode and `block` in
    /// blocking mode; the modes, and the clock after.
    fn run(t: &mut Trial, ks: std::ops::Range<u64>, spin: Duration, block: Duration, clock: &mut Instant) -> Vec<Mode> {
        ks.map(|k| {
            let m = t.mode_at(k, *clock);
            *clock += if m == Mode::Block { block } else { spin };
            m
        })
        .collect()
    }

    #[test]
    fn every_process_tries_at_the_same_steps() {
        assert!(!in_trial(0) && !in_trial(FIRST_TRIAL - 1));
        assert!(in_trial(FIRST_TRIAL) && in_trial(FIRST_TRIAL + 2 * TRIAL_STEPS - 1));
        assert!(!in_trial(FIRST_TRIAL + 2 * TRIAL_STEPS));
        assert!(in_trial(FIRST_TRIAL + PERIOD_STEPS));
    }

    #[test]
    fn it_keeps_spinning_when_spinning_is_faster() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (fast, slow) = (Duration::from_micros(50), Duration::from_micros(400));
        assert_eq!(t.mode_at(0, clock), Mode::Learning);
        let modes = run(&mut t, FIRST_TRIAL..FIRST_TRIAL + 2 * TRIAL_STEPS + 1, fast, slow, &mut clock);
        let n = TRIAL_STEPS as usize;
        assert!(modes[..n].iter().all(|&m| m == Mode::Block), "{modes:?}");
        assert!(modes[n..].iter().all(|&m| m == Mode::Spin), "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (1, 0));
    }

    #[test]
    fn it_turns_to_blocking_when_spinning_is_slower_and_back() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (fast, slow) = (Duration::from_micros(50), Duration::from_micros(400));
        let end = FIRST_TRIAL + 2 * TRIAL_STEPS;
        let modes = run(&mut t, FIRST_TRIAL..end + 1, slow, fast, &mut clock);
        // 32 blocking steps took 1.6 ms: spinning is given up after 4 steps of 0.4 ms and one more.
        assert_eq!(modes.iter().filter(|&&m| m == Mode::Spin).count(), 5, "{modes:?}");
        assert_eq!(t.mode_at(end + 1, clock), Mode::Block);
        assert_eq!((t.chose_spin, t.chose_block), (0, 1));
        // Next period: spinning became faster.
        let next = FIRST_TRIAL + PERIOD_STEPS;
        run(&mut t, next..next + 2 * TRIAL_STEPS + 1, fast, slow, &mut clock);
        assert_eq!(t.mode_at(next + 2 * TRIAL_STEPS + 1, clock), Mode::Spin);
        assert_eq!((t.chose_spin, t.chose_block), (1, 1));
    }

    #[test]
    fn a_near_tie_blocks() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let same = Duration::from_micros(200);
        run(&mut t, FIRST_TRIAL..FIRST_TRIAL + 2 * TRIAL_STEPS + 1, same, same, &mut clock);
        assert_eq!(t.mode_at(FIRST_TRIAL + 2 * TRIAL_STEPS + 1, clock), Mode::Block);
    }
}
