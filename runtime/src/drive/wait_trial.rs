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
//! at N = 50 against 1 751 spinning and 774 blocking.)
//!
//! Each half is measured by its median step, not its total: on this shared machine a step now
//! and then takes 30–70 ms (another program's burst) where its neighbours take 1 ms, and one or
//! two of those in a half decided a summed comparison. A 100-agent ring whose spinning half held
//! two 36 ms steps among 1.2 ms ones gave spinning up against blocking's 2.4 ms steps and blocked
//! for the rest of its 2 000 steps at 439 steps/s, where launches that chose spinning in the
//! same hour ran at 915–980.
//! Spinning is given up once half of its steps were no faster than blocking's median (its own
//! median cannot be faster then), once [`SPIN_LOSS_STEPS`] were twice as slow (where it is many
//! times slower), or once it has cost [`SPIN_COST_MAX`] blocking halves, so a trial costs at most
//! [`TRIAL_STEPS`] blocking steps and four times as long again: with [`PERIOD_STEPS`] = 8 192
//! and [`TRIAL_STEPS`] = 32, about 1 % of a run where spinning is three times as fast. The
//! blocking half is cut short too, after [`MIN_BLOCK_STEPS`], once its median step is
//! [`BLOCK_LOSS`] times that of the [`REF_STEPS`] steps before the trial (waited as the last
//! choice, or, before the first trial, spinning): at N = 6 on an idle machine blocking is four
//! times slower, and the first trial's 32 blocking steps cost ≈ 2.6 ms of the ≈ 9 ms by which
//! `adaptive` trailed `poll` in a 2 000-step bench run (0.87). The first trial's reference spins
//! rather than waiting as start-up does: at N = 1 000 start-up's steps are too long for its
//! spinning, so it waited as blocking does and the blocking half ran whole (32 steps at the
//! `event` rate, a quarter of a 200-step run) — unless that spinning is many times slower than
//! start-up was (two hogs: a hog's slice a step, [`REF_LOSS`]); then the rest of the reference
//! waits as start-up did, and the blocking half runs whole. Where blocking was chosen, or
//! spinning is slower (under contention), the blocking half is as fast as its reference or
//! faster, and runs whole.
//! Spinning is taken only when it is clearly faster ([`SPIN_GAIN`]): a paced run's steps take as
//! long either way, and blocking then leaves the cores idle. The first steps (start-up) wait as
//! [`super::wait::SpinPolicy::Adaptive`] always did, with its contention back-off; between the
//! first trial and the next, each process waits as its trial chose. Telemetry does not depend on
//! how a process waits.
//!
//! Where this trial is wrong: across hosts (fig1 through the gateways, an idle 2-core machine)
//! both ways measured in 32-step stretches beside each other favour spinning (the plant's
//! trial medians of six runs: blocking 706 µs a step (532–879) where steady blocking took 540
//! (498–620), spinning 569 (497–784) where steady spinning took 649 (591–760)), so the trial
//! chose spinning in most runs and `adaptive` ran at ≈ 0.85 of `event`. Turns of 4 steps
//! (block, spin, spin, block, …) were tried and not kept: the same choice across hosts, and under
//! two hogs one 100-agent run chose spinning on a trial that had blocking at 3 762 µs a step and
//! spinning at 1 393 where `event` ran 1.5 times as fast as `poll` (README, "Where a step across
//! hosts goes").

use std::time::Instant;

use super::wait::YIELD_STALL;

/// Steps of each measurement of a mode.
pub(super) const TRIAL_STEPS: u64 = 32;
/// Steps from one trial to the next.
pub(super) const PERIOD_STEPS: u64 = 8192;
/// The first trial's first step (the steps before it: start-up).
pub(super) const FIRST_TRIAL: u64 = 16;
/// Spinning is chosen when its median step is below this share of blocking's.
const SPIN_GAIN: f64 = 0.95;
/// Steps before a trial whose median step is the blocking half's reference.
const REF_STEPS: u64 = 8;
/// The blocking half runs at least this many steps.
const MIN_BLOCK_STEPS: u64 = 8;
/// The blocking half is given up when its median step exceeds the reference's this many times.
const BLOCK_LOSS: f64 = 2.0;
/// The spinning half is given up when it has taken this many blocking halves (at blocking's
/// median step): a bound on what a trial costs where spinning is many times slower (a yield
/// behind another program's slice), which the count of slow steps alone would let run 16 steps.
const SPIN_COST_MAX: f64 = 4.0;
/// The spinning half is given up once this many of its steps took [`SPIN_LOSS`] times blocking's
/// median: where spinning is many times slower (two busy-loop hogs on two cores: 16×) it is given
/// up after four steps, while a burst of another program's (one or two steps in a row) does not
/// decide.
const SPIN_LOSS_STEPS: usize = 4;
/// How many times blocking's median a spinning step takes to count towards [`SPIN_LOSS_STEPS`].
const SPIN_LOSS: f64 = 2.0;
/// The first trial's reference stops spinning once this many of its steps took [`REF_LOSS`]
/// times the lower quartile of start-up's steps before it (which waited with the contention
/// back-off), and at least a stalled yield ([`YIELD_STALL`]: spinning loses to blocking by waiting
/// behind another program's slice). Under two hogs at N = 6 each of its 8 spinning steps took 3–8
/// ms, a hog's slice, against start-up's 0.1–0.4 ms: 35 of the 45–50 ms by which `adaptive`
/// trailed `event` in a 2 000-step run. Two steps, so that one burst of another program's does
/// not decide; the quartile, as start-up's own steps include its stalls (3–5 ms in 1–4 of its 8
/// steps under the hogs, whose median then missed a reference of 4 ms steps); a millisecond, so
/// that an idle machine's spread (20–800 µs a step at N = 6) does not.
const REF_LOSS_STEPS: usize = 2;
const REF_LOSS: f64 = 8.0;

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
    /// The period of the trial under way (or last ended).
    period: Option<u64>,
    /// The latest step seen, and when its first wait began: a step's time is known when the next
    /// one begins.
    last: Option<(u64, Instant)>,
    /// Seconds per step of start-up's steps before the first trial's reference, of the
    /// [`REF_STEPS`] steps before the trial, of its blocking half and of its spinning half.
    start: StepTimes,
    reference: StepTimes,
    block: StepTimes,
    spin: StepTimes,
    /// The first trial's reference stopped spinning ([`REF_LOSS`]).
    ref_gave_up: bool,
    /// Blocking was given up (it was [`BLOCK_LOSS`] times slower than the reference).
    block_gave_up: bool,
    /// Spinning was given up (it cannot be faster any more, or it cost [`SPIN_COST_MAX`]).
    gave_up: bool,
    /// This period's trial has ended.
    concluded: bool,
    /// Trials that ended choosing spinning, and blocking.
    pub(super) chose_spin: u64,
    pub(super) chose_block: u64,
    /// The last concluded trial's median steps, blocking and spinning, µs (spinning's none when
    /// it was given up).
    pub(super) last_medians_us: (Option<f64>, Option<f64>),
}

/// The times of up to [`TRIAL_STEPS`] steps, seconds each.
#[derive(Debug, Clone, Copy)]
struct StepTimes {
    s: [f64; TRIAL_STEPS as usize],
    n: usize,
}

impl StepTimes {
    const EMPTY: StepTimes = StepTimes { s: [0.0; TRIAL_STEPS as usize], n: 0 };

    fn push(&mut self, x: f64) {
        if let Some(slot) = self.s.get_mut(self.n) {
            *slot = x;
            self.n += 1;
        }
    }

    /// The median, the upper one of an even count (so that "half the steps at least `x`" means
    /// the median is at least `x`, which [`Trial::spinning_lost`] counts on); none when empty.
    fn median(&self) -> Option<f64> {
        self.at_rank(self.n / 2)
    }

    /// The lower quartile (the step at rank ⌊n/4⌋ from the fastest); none when empty.
    fn lower_quartile(&self) -> Option<f64> {
        self.at_rank(self.n / 4)
    }

    fn at_rank(&self, rank: usize) -> Option<f64> {
        let mut v = self.s;
        let v = &mut v[..self.n];
        v.sort_unstable_by(f64::total_cmp);
        v.get(rank).copied()
    }

    fn total(&self) -> f64 {
        self.s[..self.n].iter().sum()
    }

    /// How many took `x` or longer.
    fn at_least(&self, x: f64) -> usize {
        self.s[..self.n].iter().filter(|&&t| t >= x).count()
    }
}

/// Where step `k` stands in the trials: the reference before one, its halves, or neither.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Zone {
    Reference,
    BlockHalf,
    SpinHalf,
    Between,
}

fn zone(k: u64) -> Zone {
    let Some(since) = k.checked_sub(FIRST_TRIAL) else {
        return if k + REF_STEPS >= FIRST_TRIAL { Zone::Reference } else { Zone::Between };
    };
    match since % PERIOD_STEPS {
        pos if pos < TRIAL_STEPS => Zone::BlockHalf,
        pos if pos < 2 * TRIAL_STEPS => Zone::SpinHalf,
        pos if pos + REF_STEPS >= PERIOD_STEPS => Zone::Reference,
        _ => Zone::Between,
    }
}

impl Trial {
    pub(super) fn new() -> Self {
        Trial {
            choice: Mode::Spin,
            period: None,
            last: None,
            start: StepTimes::EMPTY,
            reference: StepTimes::EMPTY,
            ref_gave_up: false,
            block: StepTimes::EMPTY,
            spin: StepTimes::EMPTY,
            block_gave_up: false,
            gave_up: false,
            concluded: false,
            chose_spin: 0,
            chose_block: 0,
            last_medians_us: (None, None),
        }
    }

    /// The mode of a wait for step `k` that began at `now` (the wait's own start: one clock
    /// read serves both).
    pub(super) fn mode_at(&mut self, k: u64, now: Instant) -> Mode {
        self.clock(k, now);
        // The last REF_STEPS steps before a trial are its reference. Before the first trial,
        // they spin: start-up's own waiting is as slow as blocking where its steps are too long
        // for its spinning (a thousand agents), and the first trial's blocking half then ran
        // whole at the blocking rate. Unless spinning is many times slower than start-up was.
        let Some(since) = k.checked_sub(FIRST_TRIAL) else {
            return if zone(k) == Zone::Reference && !self.reference_lost() { Mode::Spin } else { Mode::Learning };
        };
        let period = since / PERIOD_STEPS;
        if self.period != Some(period) {
            self.conclude();
            self.period = Some(period);
            (self.block, self.spin, self.block_gave_up, self.gave_up, self.concluded) =
                (StepTimes::EMPTY, StepTimes::EMPTY, false, false, false);
        }
        match zone(k) {
            Zone::BlockHalf if self.blocking_lost() => Mode::Spin,
            Zone::BlockHalf => Mode::Block,
            Zone::SpinHalf if self.spinning_lost() => Mode::Block,
            Zone::SpinHalf => Mode::Spin,
            z => {
                self.conclude();
                if z == Zone::Between {
                    // The next trial's reference is the steps just before it.
                    self.reference.n = 0;
                }
                self.choice
            }
        }
    }

    /// Step `k` begins at `now`: the step before it ended, and its time goes where it belongs.
    fn clock(&mut self, k: u64, now: Instant) {
        match self.last {
            Some((k0, _)) if k <= k0 => return,
            Some((k0, t0)) => {
                let s = per_step(k0, t0, k, now);
                match zone(k0) {
                    Zone::Between if k0 < FIRST_TRIAL => self.start.push(s),
                    // The rest of a first reference given up waits as start-up does: not
                    // spinning's measure either.
                    Zone::Reference if !self.ref_gave_up => self.reference.push(s),
                    // The rest of a blocking half given up spins, and is no one's measure.
                    Zone::BlockHalf if !self.block_gave_up => self.block.push(s),
                    Zone::SpinHalf if !self.gave_up => self.spin.push(s),
                    _ => {}
                }
            }
            None => {}
        }
        self.last = Some((k, now));
    }

    /// The choice of the trial that ended before step `k`, as advice for the host
    /// ([`advice`]); none during a trial or before the first.
    pub(super) fn advice(&self, k: u64) -> Option<u64> {
        advice(k, self.choice)
    }

    /// Whether the first trial's reference stops spinning: once [`REF_LOSS_STEPS`] of its steps
    /// took [`REF_LOSS`] times start-up's lower quartile and at least [`YIELD_STALL`]. The blocking
    /// half is then held against those few spinning steps, which it beats, and runs whole.
    fn reference_lost(&mut self) -> bool {
        if !self.ref_gave_up
            && let Some(start) = self.start.lower_quartile()
        {
            let slow = (REF_LOSS * start).max(YIELD_STALL.as_secs_f64());
            self.ref_gave_up = self.reference.at_least(slow) >= REF_LOSS_STEPS;
            if self.ref_gave_up {
                tracing::debug!(
                    "wait trial: the first reference's spinning steps took {REF_LOSS_STEPS} times over {:.0} µs \
                     (start-up's lower quartile {:.0} µs): it waits as start-up did",
                    slow * 1e6,
                    start * 1e6
                );
            }
        }
        self.ref_gave_up
    }

    /// Whether the blocking half is given up: once its median step over at least
    /// [`MIN_BLOCK_STEPS`] took [`BLOCK_LOSS`] times the reference's median.
    fn blocking_lost(&mut self) -> bool {
        if !self.block_gave_up
            && self.block.n >= MIN_BLOCK_STEPS as usize
            && let (Some(reference), Some(block)) = (self.reference.median(), self.block.median())
        {
            self.block_gave_up = block > BLOCK_LOSS * reference;
        }
        self.block_gave_up
    }

    /// Whether the spinning half is given up: once so many of its steps took at least
    /// [`SPIN_GAIN`] times blocking's median that its own median cannot be below that, once
    /// [`SPIN_LOSS_STEPS`] took [`SPIN_LOSS`] times it, or once it has cost [`SPIN_COST_MAX`]
    /// blocking halves. Blocking is then the choice.
    fn spinning_lost(&mut self) -> bool {
        let Some(block) = self.block.median() else { return true };
        let slower = self.spin.at_least(SPIN_GAIN * block);
        let much_slower = self.spin.at_least(SPIN_LOSS * block);
        let half = TRIAL_STEPS as usize;
        if slower >= half - half / 2
            || much_slower >= SPIN_LOSS_STEPS
            || self.spin.total() > SPIN_COST_MAX * block * TRIAL_STEPS as f64
        {
            self.gave_up = true;
        }
        self.gave_up
    }

    /// End this period's trial (once): spinning when its median step is below [`SPIN_GAIN`]
    /// times blocking's, else blocking.
    fn conclude(&mut self) {
        if self.concluded || self.period.is_none() {
            return;
        }
        self.concluded = true;
        let Some(block) = self.block.median() else { return };
        let spin = self.spin.median().filter(|_| !self.gave_up);
        if let Some(spin) = spin {
            self.choice = if spin < SPIN_GAIN * block { Mode::Spin } else { Mode::Block };
        } else if self.gave_up {
            self.choice = Mode::Block;
        }
        self.last_medians_us = (Some(block * 1e6), spin.map(|s| s * 1e6));
        tracing::debug!(
            "wait trial: blocking {:.0} µs a step (median of {}), spinning {} (of {}): {:?} until the next",
            block * 1e6,
            self.block.n,
            spin.map_or("given up".to_string(), |s| format!("{:.0} µs", s * 1e6)),
            self.spin.n,
            self.choice
        );
        if self.choice == Mode::Spin {
            self.chose_spin += 1;
        } else {
            self.chose_block += 1;
        }
    }
}

/// Seconds per step from step `k0` at `t0` to step `k` (> `k0`) at `now`.
fn per_step(k0: u64, t0: Instant, k: u64, now: Instant) -> f64 {
    (now - t0).as_secs_f64() / (k - k0) as f64
}

/// Whether step `k` is in a trial (either half).
fn in_trial(k: u64) -> bool {
    k.checked_sub(FIRST_TRIAL).is_some_and(|d| d % PERIOD_STEPS < 2 * TRIAL_STEPS)
}

/// The trial period of step `k` (none before the first trial).
fn period_of(k: u64) -> Option<u64> {
    k.checked_sub(FIRST_TRIAL).map(|d| d / PERIOD_STEPS)
}

/// Between trials, every process waits as the plant's trial chose (the plant publishes it,
/// `DataPath::wait_advice`, in its host's doorbell file; the gateways carry it to the other
/// hosts' with their batches, per-process zenoh peers do not): each process measures the same
/// lockstep, but
/// over its own step boundaries, and near a tie their verdicts split — in one launch of a
/// thousand-agent ring 529 agents chose spinning and 472 blocking, a mixture slower than either.
/// Encoded as (period + 1) · 2 + (1 for spinning); 0 is none.
pub(super) fn advice(k: u64, choice: Mode) -> Option<u64> {
    let period = period_of(k).filter(|_| !in_trial(k))?;
    Some((period + 1) * 2 + u64::from(choice == Mode::Spin))
}

/// The mode `advice` gives step `k`: only between trials, and only the advice of `k`'s period.
pub(super) fn follow(advice: u64, k: u64) -> Option<Mode> {
    let period = (advice / 2).checked_sub(1)?;
    if in_trial(k) || period_of(k) != Some(period) {
        return None;
    }
    Some(if advice % 2 == 1 { Mode::Spin } else { Mode::Block })
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

    /// The plant's advice holds between the trials of its own period only: not during a trial,
    /// not in the next period, not before the first trial; none is given during a trial.
    #[test]
    fn advice_holds_between_the_trials_of_its_period() {
        let after = FIRST_TRIAL + 2 * TRIAL_STEPS;
        assert_eq!(advice(FIRST_TRIAL + 3, Mode::Spin), None, "no advice during a trial");
        assert_eq!(advice(FIRST_TRIAL - 1, Mode::Spin), None, "nor before the first");
        let spin = advice(after, Mode::Spin).unwrap();
        let block = advice(after + 100, Mode::Block).unwrap();
        assert_eq!(follow(spin, after + 1), Some(Mode::Spin));
        assert_eq!(follow(block, after + 1), Some(Mode::Block));
        assert_eq!(follow(spin, FIRST_TRIAL + PERIOD_STEPS - 1), Some(Mode::Spin), "until the next trial");
        assert_eq!(follow(spin, FIRST_TRIAL + PERIOD_STEPS), None, "the next trial is every process's own");
        let next = FIRST_TRIAL + PERIOD_STEPS + 2 * TRIAL_STEPS;
        assert_eq!(follow(spin, next), None, "last period's advice is stale");
        assert_eq!(follow(advice(next, Mode::Block).unwrap(), next), Some(Mode::Block));
        assert_eq!(follow(0, after), None, "none published");
        assert_eq!(follow(1, after), None, "no period");
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
        // What the choice was made on, as the status reports it.
        let (block, spin) = t.last_medians_us;
        assert!(block.is_some_and(|b| (b - 400.0).abs() < 1.0), "{block:?}");
        assert!(spin.is_some_and(|s| (s - 50.0).abs() < 1.0), "{spin:?}");
    }

    #[test]
    fn it_turns_to_blocking_when_spinning_is_slower_and_back() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (fast, slow) = (Duration::from_micros(50), Duration::from_micros(400));
        let end = FIRST_TRIAL + 2 * TRIAL_STEPS;
        let modes = run(&mut t, FIRST_TRIAL..end + 1, slow, fast, &mut clock);
        // Blocking's median step is 50 µs: four spinning steps of 400 µs give spinning up.
        assert_eq!(modes.iter().filter(|&&m| m == Mode::Spin).count(), SPIN_LOSS_STEPS, "{modes:?}");
        assert_eq!(t.mode_at(end + 1, clock), Mode::Block);
        assert_eq!((t.chose_spin, t.chose_block), (0, 1));
        // Spinning given up: no median of it is reported.
        assert!(t.last_medians_us.0.is_some_and(|b| (b - 50.0).abs() < 1.0) && t.last_medians_us.1.is_none());
        // Next period: spinning became faster.
        let next = FIRST_TRIAL + PERIOD_STEPS;
        run(&mut t, next..next + 2 * TRIAL_STEPS + 1, fast, slow, &mut clock);
        assert_eq!(t.mode_at(next + 2 * TRIAL_STEPS + 1, clock), Mode::Spin);
        assert_eq!((t.chose_spin, t.chose_block), (1, 1));
    }

    /// Where spinning is many times slower (a yield behind another program's slice), it is given
    /// up after [`SPIN_LOSS_STEPS`] steps: here 1 ms steps against blocking's 50 µs.
    #[test]
    fn a_much_slower_spin_is_given_up_after_a_few_steps() {
        assert_eq!(spun_choosing_block(Duration::from_millis(1), Duration::from_micros(50)), SPIN_LOSS_STEPS);
    }

    /// Spinning a little slower than blocking (1.5×, never twice as slow) is given up once half
    /// the spinning half (16 steps) was slower than blocking's median: its median cannot win.
    #[test]
    fn a_slightly_slower_spin_is_given_up_when_its_median_cannot_win() {
        assert_eq!(spun_choosing_block(Duration::from_micros(150), Duration::from_micros(100)), 16);
    }

    /// One trial in which every spinning step takes `spin` and every blocking one `block`: how
    /// many steps spun, once it is checked that blocking was chosen.
    fn spun_choosing_block(spin: Duration, block: Duration) -> usize {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let modes = run(&mut t, FIRST_TRIAL..FIRST_TRIAL + 2 * TRIAL_STEPS + 1, spin, block, &mut clock);
        assert_eq!((t.chose_spin, t.chose_block), (0, 1), "{modes:?}");
        modes.iter().filter(|&&m| m == Mode::Spin).count()
    }

    /// Two steps of 36 ms among spinning steps of 1.2 ms (another program's burst; a 100-agent
    /// ring showed such pairs) against blocking's 2.4 ms: spinning is still chosen. Summed, the
    /// spinning half (≈ 110 ms) took longer than the blocking half (77 ms), and a 100-agent
    /// launch blocked for the rest of its run at 0.48 of the speed it had spinning.
    #[test]
    fn a_few_outlying_steps_do_not_decide_the_trial() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (spin, block, burst) =
            (Duration::from_micros(1200), Duration::from_micros(2400), Duration::from_millis(36));
        let end = FIRST_TRIAL + 2 * TRIAL_STEPS;
        let modes: Vec<Mode> = (FIRST_TRIAL..end + 1)
            .map(|k| {
                let m = t.mode_at(k, clock);
                let outlier = k == end - 20 || k == end - 19;
                clock += if outlier {
                    burst
                } else if m == Mode::Block {
                    block
                } else {
                    spin
                };
                m
            })
            .collect();
        assert!(modes[TRIAL_STEPS as usize..].iter().all(|&m| m == Mode::Spin), "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (1, 0));
        // An outlier in the blocking half does not make blocking look slow either.
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (spin, block) = (Duration::from_micros(1000), Duration::from_micros(1000));
        for k in FIRST_TRIAL..end + 1 {
            let m = t.mode_at(k, clock);
            clock += if k == FIRST_TRIAL + 2 {
                burst
            } else if m == Mode::Block {
                block
            } else {
                spin
            };
        }
        assert_eq!((t.chose_spin, t.chose_block), (0, 1), "a tie blocks");
    }

    #[test]
    fn blocking_is_cut_short_when_much_slower_than_the_steps_before() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (fast, slow) = (Duration::from_micros(30), Duration::from_micros(120));
        // Start-up spins (30 µs a step), blocking takes 120 µs: after 8 steps it has lost.
        let end = FIRST_TRIAL + 2 * TRIAL_STEPS;
        let modes = run(&mut t, 0..end + 1, fast, slow, &mut clock);
        let blocked = modes.iter().filter(|&&m| m == Mode::Block).count() as u64;
        assert_eq!(blocked, MIN_BLOCK_STEPS, "{modes:?}");
        assert!(modes[(FIRST_TRIAL + MIN_BLOCK_STEPS) as usize..].iter().all(|&m| m != Mode::Block), "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (1, 0));
        // The next trial's reference: the 8 steps before it, spun as chosen.
        let next = FIRST_TRIAL + PERIOD_STEPS;
        let modes = run(&mut t, next - REF_STEPS..next + 2 * TRIAL_STEPS + 1, fast, slow, &mut clock);
        assert_eq!(modes.iter().filter(|&&m| m == Mode::Block).count() as u64, MIN_BLOCK_STEPS, "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (2, 0));
    }

    #[test]
    fn blocking_runs_its_whole_half_when_the_steps_before_were_as_slow() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (block, spin) = (Duration::from_micros(100), Duration::from_micros(400));
        // Two hogs: spinning is the slower. Start-up learns; its last REF_STEPS steps spin, as
        // the first trial's reference.
        let modes = run(&mut t, 0..FIRST_TRIAL, spin, block, &mut clock);
        let learning = (FIRST_TRIAL - REF_STEPS) as usize;
        assert!(modes[..learning].iter().all(|&m| m == Mode::Learning), "{modes:?}");
        assert!(modes[learning..].iter().all(|&m| m == Mode::Spin), "{modes:?}");
        let modes = run(&mut t, FIRST_TRIAL..FIRST_TRIAL + TRIAL_STEPS, spin, block, &mut clock);
        assert!(modes.iter().all(|&m| m == Mode::Block), "{modes:?}");
        // Blocking as slow as that reference (a paced run: every step takes as long) runs whole too.
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let modes = run(&mut t, 0..FIRST_TRIAL + TRIAL_STEPS, block, block, &mut clock);
        assert!(modes[FIRST_TRIAL as usize..].iter().all(|&m| m == Mode::Block), "{modes:?}");
    }

    /// The first trial's reference spins even where start-up's waits were as slow as blocking (a
    /// thousand agents: steps too long for start-up's spinning), so blocking that is much slower
    /// than spinning is cut short at the first trial too.
    #[test]
    fn the_first_trials_reference_spins_whatever_start_up_did() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (spin, block) = (Duration::from_millis(60), Duration::from_millis(200));
        // Start-up's waits (Learning) take as long as blocking.
        let modes: Vec<Mode> = (0..FIRST_TRIAL + 2 * TRIAL_STEPS + 1)
            .map(|k| {
                let m = t.mode_at(k, clock);
                clock += if m == Mode::Spin { spin } else { block };
                m
            })
            .collect();
        assert_eq!(modes.iter().filter(|&&m| m == Mode::Block).count() as u64, MIN_BLOCK_STEPS, "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (1, 0));
    }

    /// Two hogs: start-up waited with the contention back-off (0.2 ms a step, but half of its
    /// steps stalled behind a hog: 4 ms), spinning through a yield takes a hog's slice (4 ms),
    /// blocking 0.15 ms. The first trial's reference gives spinning up after two steps, and the
    /// blocking half, held against those, runs whole.
    #[test]
    fn the_first_reference_stops_spinning_when_far_slower_than_start_up() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let (learning, spin, block) =
            (Duration::from_micros(200), Duration::from_millis(4), Duration::from_micros(150));
        let modes: Vec<Mode> = (0..FIRST_TRIAL + 2 * TRIAL_STEPS + 1)
            .map(|k| {
                let m = t.mode_at(k, clock);
                clock += match m {
                    Mode::Learning if k < FIRST_TRIAL - REF_STEPS && k % 2 == 1 => spin,
                    Mode::Learning => learning,
                    Mode::Spin => spin,
                    Mode::Block => block,
                };
                m
            })
            .collect();
        let reference = &modes[(FIRST_TRIAL - REF_STEPS) as usize..FIRST_TRIAL as usize];
        assert_eq!(reference.iter().filter(|&&m| m == Mode::Spin).count(), REF_LOSS_STEPS, "{modes:?}");
        assert!(reference[REF_LOSS_STEPS..].iter().all(|&m| m == Mode::Learning), "{modes:?}");
        let trial = &modes[FIRST_TRIAL as usize..];
        assert!(trial[..TRIAL_STEPS as usize].iter().all(|&m| m == Mode::Block), "{modes:?}");
        assert_eq!((t.chose_spin, t.chose_block), (0, 1));
        // Spinning three times as slow as start-up (a yield behind peers, not a hog) keeps the
        // whole reference spinning.
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let modes: Vec<Mode> = (0..FIRST_TRIAL)
            .map(|k| {
                let m = t.mode_at(k, clock);
                clock += if m == Mode::Spin { learning * 3 } else { learning };
                m
            })
            .collect();
        assert!(modes[(FIRST_TRIAL - REF_STEPS) as usize..].iter().all(|&m| m == Mode::Spin), "{modes:?}");
    }

    #[test]
    fn a_near_tie_blocks() {
        let (mut t, mut clock) = (Trial::new(), Instant::now());
        let same = Duration::from_micros(200);
        run(&mut t, FIRST_TRIAL..FIRST_TRIAL + 2 * TRIAL_STEPS + 1, same, same, &mut clock);
        assert_eq!(t.mode_at(FIRST_TRIAL + 2 * TRIAL_STEPS + 1, clock), Mode::Block);
    }
}
