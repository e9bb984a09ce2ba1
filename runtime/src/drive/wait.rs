//! How a process waits for its peers: drain, check, spin or block briefly, re-poll; adaptive
//! spinning that backs off under CPU contention; the timeout naming the silent peer.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use cohort_wire::msg::{PLANT_ID, RunControl, STATUS_WAITING};
use cohort_wire::transport::{Incoming, Transport};
use cohort_wire::validate::Rejection;

use super::error::RunError;
use super::params::DriveParams;
use super::status::status;
use super::wait_trial::{self, Mode, Trial};
use crate::record::WaitStats;

/// Longest single blocking wait before re-polling.
pub(super) const POLL: Duration = Duration::from_millis(10);
/// A long wait re-polls less often: every quarter of the time it has lasted, at most this. With a
/// thousand agent processes on two cores a step takes hundreds of ms at start-up or under load,
/// and each process re-polling every 10 ms (100 000 wakeups a second, each draining and looking
/// at the control service) was what made the steps that slow: 3.8 steps/s. A lost wakeup (rare)
/// then costs at most a quarter of the wait it interrupts.
const POLL_MAX: Duration = Duration::from_millis(100);
/// The same for an agent's wait for its first measurement, which lasts the whole start-up: the
/// plant's wakeup ends it, the poll only covers a lost one. With every ready agent re-polling
/// each 10 ms while the rest were spawned, start-up CPU grew as N² (a 256-agent ring: the late
/// agents' start-up cost 3× the early ones').
const POLL_BEFORE_START: Duration = Duration::from_millis(100);
/// How long a blocked wait sleeps before it looks again with nothing rung: every [`POLL`] at
/// first, then a quarter of the time it has waited (at most [`POLL_MAX`]), so a lost wakeup
/// costs a quarter of the wait; when the transport's wait also returns on every run-control
/// notice ([`DataPath::woken_by_control`]), nothing needs looking at sooner than [`POLL_MAX`]:
/// a wakeup is only ever lost when its sender died between its sample and its ring, and that
/// death brings the orchestrator's notice. The first measurement's wait, which lasts the whole
/// start-up, always sleeps [`POLL_BEFORE_START`].
///
/// [`DataPath::woken_by_control`]: cohort_wire::transport::DataPath::woken_by_control
pub(super) fn repoll_after<T: Transport + ?Sized>(t: &T, startup: bool, waited: Duration) -> Duration {
    if startup {
        POLL_BEFORE_START
    } else if t.woken_by_control() {
        POLL_MAX
    } else {
        (waited / 4).clamp(POLL, POLL_MAX)
    }
}

/// After this long in one wait, the process tells the orchestrator whom it is waiting for.
const REPORT_WAITING_AFTER: Duration = Duration::from_millis(200);

/// How a wait spins (draining and yielding the CPU) before it blocks on the event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpinPolicy {
    /// Spin for a fixed time ("event" = zero, "poll" = the step timeout, or `run.spin_us`).
    Fixed(Duration),
    /// Learn from this process's own waits: spin for up to four times the recent typical wait of
    /// the same kind (measurement or share) (at
    /// least [`ADAPTIVE_FLOOR_US`], at most [`ADAPTIVE_CAP_US`]); when waits are typically longer
    /// than the cap (a slow or paced plant), do not spin at all, so an idle process costs nothing.
    /// When spinning stops paying because the machine is contended (a yield comes back only after
    /// another program held the core for a scheduler slice, [`YIELD_STALL`]), block at once and
    /// skip spinning for a while ([`Contention`]). From step 16 on, the lockstep's own time per
    /// step decides instead: every 8 192 steps all processes block, then spin, for 32 steps each,
    /// and wait in the faster way until the next trial (`wait_trial`).
    Adaptive,
}

/// Adaptive spinning: never less than this, µs.
pub const ADAPTIVE_FLOOR_US: f64 = 20.0;
/// Adaptive spinning: never more than this, µs; waits typically longer than it are not spun.
/// Measured on the 2-core machine (README, Performance): spinning with `sched_yield` for up to
/// 1 ms beat blocking at every N from 6 to 100 agent processes.
pub const ADAPTIVE_CAP_US: f64 = 2000.0;
/// A `sched_yield` that takes this long returned only after another runnable task held the core
/// for a whole scheduler slice (on this machine 1–5 ms with two CPU hogs, while with none 99.99 %
/// of yields take under 10 µs): the cores are contended, and a spinner then only takes CPU from
/// the peer it waits for. A peer's step that would end a spin is microseconds (a slower one makes
/// the typical wait exceed [`ADAPTIVE_CAP_US`], which stops spinning anyway).
pub const YIELD_STALL: Duration = Duration::from_millis(1);
/// After a stalled yield, the next waits block without spinning: at least this many, at most
/// [`BACKOFF_MAX`], growing by [`BACKOFF_GROWTH`] per stall and halving per clean spin
/// ([`Contention`]).
///
/// Every stall on the way to the maximum costs the whole lockstep run about a scheduler slice (the
/// yielding process waits behind the hog's slice, where a blocked one would have been woken
/// first), and each process learns on its own: the bench's loaded row counted ≈ 7 stalls per
/// process with 16 × 4ⁿ. Starting at 64 and growing 8× reaches the maximum in three.
pub(super) const BACKOFF_MIN: u32 = 64;
pub(super) const BACKOFF_MAX: u32 = 4096;
/// Growth of the back-off per stalled spin; a clean spin halves it, so spinning goes on being
/// tried often only while fewer than one spin in four stalls (8^f·2^(−(1−f)) < 1 ⇔ f < 1/4).
pub(super) const BACKOFF_GROWTH: u32 = 8;
/// How long a wait spins once a trial chose spinning (or tries it): as `poll`, but bounded, so a
/// peer that stalls for longer costs a wake-up rather than a spinning core. The typical-wait
/// budget of start-up let 700 of 130 000 waits of a 50-agent ring expire into a wake-up, and the
/// ring ran at 82 % of `poll`.
///
/// When the typical wait is longer (hundreds of agent processes on two cores: a step takes tens
/// of ms), the budget is [`ADAPTIVE_MARGIN`] typical waits, at most [`SPIN_MODE_MAX`]: with a
/// fixed 10 ms, a 1 000-agent ring's spins nearly all expired into wake-ups and ran at 4.5
/// steps/s where `poll` (spinning through) ran at 12.1.
pub(super) const SPIN_MODE_BUDGET: Duration = Duration::from_millis(10);
/// The longest spin of a wait once a trial chose spinning.
pub(super) const SPIN_MODE_MAX: Duration = Duration::from_secs(1);
/// The longest run of yields without a full pass of the wait loop (which drains, checks the
/// timeout and reports a long wait), when nobody rings.
const QUIET_SPIN_MAX: Duration = Duration::from_millis(10);
/// Yields between two looks at the clock (and at SIGTERM) in a spin that does not time its
/// yields. After a yield a process runs cache-cold among hundreds of others, and what it touches
/// costs: in a 1 000-agent ring waiting `poll`, the clock reads after each yield (`Instant::now`
/// and the vDSO's pages) were 12 % of the agents' CPU samples. A spin thus overruns its end by
/// at most this many yields.
const YIELDS_PER_CLOCK: u32 = 16;
/// Weight of the newest wait in the running typical wait.
const ADAPTIVE_EWMA: f64 = 0.1;
/// Spin for up to this many typical waits.
const ADAPTIVE_MARGIN: f64 = 4.0;
/// How long a wait spins once a trial chose spinning, for a typical wait of `typical_us`.
pub(super) fn spin_mode_budget(typical_us: f64) -> Duration {
    let margin = Duration::from_secs_f64((ADAPTIVE_MARGIN * typical_us).max(0.0) * 1e-6);
    margin.clamp(SPIN_MODE_BUDGET, SPIN_MODE_MAX)
}

/// Whether a wait of `kind` at `step` is an agent's wait for its first measurement, which lasts
/// the rest of the run's start-up.
fn is_startup_wait(step: u64, kind: usize) -> bool {
    step == 0 && kind == 0
}

/// What a process collects while it waits: it takes each incoming message, says when the wait
/// is over, and names whom it still lacks.
pub(super) trait Inbox {
    fn take(&mut self, inc: Incoming<'_>);
    fn complete(&self) -> bool;
    /// (id, description) of the first peer still missing.
    fn missing(&self) -> (u32, String);
    /// A notice from the orchestrator (the plant's inbox only).
    fn control(&mut self, _c: &RunControl) {}
    /// Whether something arrived since the last call that shows the peer is alive though the
    /// wait is not over (a newer measurement while off the roster): it restarts the silence clock.
    fn fresh(&mut self) -> bool {
        false
    }
    /// Why the latest message from process `id` was rejected, if it was (a valid one since
    /// clears it): a wait that times out names that, not silence.
    fn rejected_from(&self, id: u32) -> Option<Rejection>;
}

/// How a missing peer is described when its latest message was rejected.
pub(super) fn rejected_note(r: Option<Rejection>) -> String {
    r.map_or(String::new(), |r| {
        format!(" (its latest message was rejected: {}, i.e. damaged in transit or not of this run)", r.name())
    })
}

pub(super) struct Waiter<'a, T: Transport + ?Sized> {
    pub(super) t: &'a mut T,
    p: &'a DriveParams,
    me: u32,
    pub(super) timeouts: u64,
    /// Running typical wait, µs, per kind of wait (measurement, share): adaptive spinning.
    typical_wait_us: [f64; 2],
    contention: Contention,
    /// Adaptive waiting's trials of spinning against blocking (see `wait_trial`).
    trial: Trial,
    stats: WaitStats,
    events: Vec<RunControl>,
}

/// Adaptive waiting's view of CPU contention: whether spinning pays on this machine right now.
///
/// A stalled spin costs a scheduler slice (milliseconds); a spin that pays saves a wake-up
/// (tens of µs). So spinning is worth trying again only when stalls are rare: each stalled spin
/// multiplies the number of waits that block before the next try by [`BACKOFF_GROWTH`] (from
/// [`BACKOFF_MIN`] up to [`BACKOFF_MAX`]), each clean one only halves it. Under sustained
/// contention, where even one spin in four stalls, the gap grows to its maximum and the process
/// waits as `event` would, trying a spin once in [`BACKOFF_MAX`] waits; on an idle machine a lone
/// stall (another user's burst) is forgotten after a few clean spins.
#[derive(Debug, Default, Clone, Copy)]
pub struct Contention {
    /// Waits to block between two spinning waits: the back-off's memory of recent stalls.
    gap: u32,
    /// Waits left to block without spinning.
    skip: u32,
    /// Stalled spins so far.
    pub stalls: u64,
}

impl Contention {
    /// Whether this wait may spin (and count it against the back-off).
    pub(super) fn may_spin(&mut self) -> bool {
        if self.skip > 0 {
            self.skip -= 1;
            return false;
        }
        true
    }
    /// A spinning wait ended: `stalled` if one of its yields did.
    pub(super) fn spun(&mut self, stalled: bool) {
        if stalled {
            self.stalls += 1;
            self.gap = self.gap.saturating_mul(BACKOFF_GROWTH).clamp(BACKOFF_MIN, BACKOFF_MAX);
            self.skip = self.gap;
        } else {
            self.gap /= 2;
        }
    }
}

impl<'a, T: Transport + ?Sized> Waiter<'a, T> {
    pub(super) fn new(t: &'a mut T, p: &'a DriveParams, me: u32) -> Waiter<'a, T> {
        Waiter {
            t,
            p,
            me,
            timeouts: 0,
            typical_wait_us: [0.0; 2],
            contention: Contention::default(),
            trial: Trial::new(),
            stats: WaitStats::default(),
            events: Vec::new(),
        }
    }

    /// The waits' statistics, with the trials' choices.
    pub(super) fn stats(&self) -> WaitStats {
        let (trial_block_step_us, trial_spin_step_us) = self.trial.last_medians_us;
        WaitStats {
            chose_spin: self.trial.chose_spin,
            chose_block: self.trial.chose_block,
            trial_block_step_us,
            trial_spin_step_us,
            ..self.stats
        }
    }

    /// How long a wait of `kind` for step `step`, begun at `started`, may spin, and whether it
    /// learns from contention (only before the first trial ended: see `wait_trial`).
    fn spin_for(&mut self, kind: usize, step: u64, started: Instant) -> (Duration, bool) {
        // Spinning through the start-up (`poll` spins for the step timeout) only takes the CPU
        // from the processes still being started; a thousand-agent ring with `wait = "poll"`
        // never finished starting.
        if is_startup_wait(step, kind) {
            return (Duration::ZERO, false);
        }
        let typical = self.typical_wait_us[kind];
        let mode = match self.p.spin {
            SpinPolicy::Fixed(d) => return (d, false),
            SpinPolicy::Adaptive => self.adaptive_mode(step, started),
        };
        let budget =
            || Duration::from_secs_f64((ADAPTIVE_MARGIN * typical).clamp(ADAPTIVE_FLOOR_US, ADAPTIVE_CAP_US) * 1e-6);
        // Spinning (a trial of it, or its choice) spins even when the typical wait, measured
        // while blocking, is longer than the cap: blocking's wake-ups are what made it long.
        match mode {
            Mode::Block => (Duration::ZERO, false),
            Mode::Spin => (spin_mode_budget(typical), false),
            _ if typical > ADAPTIVE_CAP_US => (Duration::ZERO, true),
            Mode::Learning if !self.contention.may_spin() => (Duration::ZERO, true),
            Mode::Learning => (budget(), true),
        }
    }

    /// Adaptive waiting's mode for `step`: this process's trial's; between trials, the plant's
    /// choice where its host's processes can read it ([`wait_trial::advice`]).
    fn adaptive_mode(&mut self, step: u64, now: Instant) -> Mode {
        let own = self.trial.mode_at(step, now);
        if self.me == PLANT_ID {
            if let Some(a) = self.trial.advice(step) {
                self.t.set_wait_advice(a);
            }
            return own;
        }
        match wait_trial::follow(self.t.wait_advice(), step) {
            Some(mode) => {
                self.stats.advised += 1;
                mode
            }
            None => own,
        }
    }

    /// Yield until a peer rings ([`DataPath::rung`]), `end` passes, SIGTERM comes or, when
    /// `learning`, a yield stalls ([`YIELD_STALL`]; then `true`), looking at nothing but this
    /// process's doorbell line and the clock. With hundreds of processes a core every pass runs
    /// cache-cold; a thousand-agent ring waiting `poll` ran at an eighth of the steps/s of a bare
    /// futex-and-yield lockstep of as many processes (the bench's wake floor), and passes that
    /// found nothing yet drained (a receive on iceoryx2's shared state) and read the clock three
    /// times; without that, ≈ 10 % faster there. Transports without doorbells say they are
    /// always rung: one yield a pass, as before.
    ///
    /// Only a learning spin times each yield; otherwise the clock and SIGTERM are looked at every
    /// [`YIELDS_PER_CLOCK`] yields, the doorbell after each.
    ///
    /// [`DataPath::rung`]: cohort_wire::transport::DataPath::rung
    fn spin_quietly(&mut self, end: Instant, learning: bool) -> bool {
        if !learning {
            loop {
                for _ in 0..YIELDS_PER_CLOCK {
                    std::thread::yield_now();
                    if self.t.rung() {
                        return false;
                    }
                }
                if Instant::now() >= end || self.p.terminate.load(Ordering::Relaxed) {
                    return false;
                }
            }
        }
        let mut before = Instant::now();
        loop {
            std::thread::yield_now();
            let now = Instant::now();
            if now - before >= YIELD_STALL {
                return true;
            }
            if now >= end || self.t.rung() || self.p.terminate.load(Ordering::Relaxed) {
                return false;
            }
            before = now;
        }
    }

    /// Drain into `inbox`, check it, wait briefly; repeat until it is complete or `limit` passes
    /// with nothing fresh.
    pub(super) fn until(
        &mut self,
        step: u64,
        what: &'static str,
        inbox: &mut impl Inbox,
        limit: Duration,
    ) -> Result<(), RunError> {
        let started = Instant::now();
        let mut silent_since = started;
        let kind = usize::from(what == "share");
        let (mut spin, learning) = self.spin_for(kind, step, started);
        let spun = spin > Duration::ZERO;
        let mut stalled = false;
        let mut reported = false;
        let mut spins = 0u32;
        let mut first = true;
        let mut spin_ended: Option<Instant> = None;
        loop {
            self.t.drain(&mut |inc| inbox.take(inc))?;
            if inbox.complete() {
                let w = started.elapsed().as_secs_f64() * 1e6;
                self.typical_wait_us[kind] += ADAPTIVE_EWMA * (w - self.typical_wait_us[kind]);
                if spun && learning {
                    self.contention.spun(stalled);
                }
                if !first {
                    self.stats.count(
                        spun,
                        stalled,
                        spin_ended.is_some(),
                        spin_ended.unwrap_or_else(Instant::now) - started,
                    );
                }
                return Ok(());
            }
            first = false;
            if inbox.fresh() {
                silent_since = Instant::now();
            }
            let waited = silent_since.elapsed();
            if waited >= limit {
                self.timeouts += 1;
                let (_, from) = inbox.missing();
                return Err(RunError::Timeout { step, from, what, after_s: waited.as_secs_f64() });
            }
            let spinning = started.elapsed() < spin;
            if spun && !spinning && spin_ended.is_none() {
                spin_ended = Some(Instant::now());
            }
            spins = spins.wrapping_add(1);
            // While spinning, look at the control service only now and then: it is not free —
            // unless the transport knows whether run control rang (a flag, then).
            if !spinning || spins.is_multiple_of(1024) || self.t.woken_by_control() {
                // Nor, when the transport knows, while run control has sent nothing new.
                let control = self.t.control_rung();
                let why = if control && self.t.stop_requested() {
                    // What completes this wait may have come in with the stop (the run's last
                    // step): look once more before giving up.
                    self.t.drain(&mut |inc| inbox.take(inc))?;
                    if inbox.complete() {
                        return Ok(());
                    }
                    Some("orchestrator")
                } else {
                    self.p.terminate.load(Ordering::Relaxed).then_some("SIGTERM")
                };
                if let Some(why) = why {
                    let waiting = format!(" while waiting for the {what} of {}", inbox.missing().1);
                    return Err(RunError::Stopped { step, why, waiting });
                }
                if control {
                    self.t.control_events(&mut self.events);
                    for e in self.events.drain(..) {
                        inbox.control(&e);
                    }
                    if inbox.complete() {
                        continue;
                    }
                }
                if !reported && waited >= REPORT_WAITING_AFTER {
                    reported = true;
                    let (id, _) = inbox.missing();
                    let mut s = status(self.p, self.me, STATUS_WAITING, step, id);
                    s.detail = inbox.rejected_from(id).map_or(0, |r| r as u32 + 1);
                    self.t.report(&s);
                }
            }
            if crate::coop::pause() {
                // A task of a cooperative run: the peers run now, on this thread.
            } else if spinning {
                let end = (started + spin).min(Instant::now() + QUIET_SPIN_MAX);
                if self.spin_quietly(end, learning) {
                    // Contended: spinning only takes the CPU from whoever we wait for.
                    stalled = true;
                    spin = Duration::ZERO;
                }
            } else {
                let poll = repoll_after(&*self.t, is_startup_wait(step, kind), waited);
                self.t.wait(poll.min(limit.saturating_sub(waited)).max(Duration::from_micros(100)))?;
            }
        }
    }
}
