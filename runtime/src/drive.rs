//! The lockstep step protocol (design.md "One step"), once for the plant and once for an agent,
//! generic over the transport. The multi-process binaries and the in-process reference run call
//! exactly these functions; only the `Transport` differs.
//!
//! For step k:
//! 1. plant → agent i: `Measurement{k}`;
//! 2. agent i: `Algorithm::share`, publishes `Share{k}` (command + values for neighbours);
//! 3. agent i waits for `Share{k}` of every neighbour, then `Algorithm::step` (tₖ → tₖ₊₁);
//! 4. plant waits for every `Share{k}`, applies the commands, integrates to tₖ₊₁.
//!
//! Every wait is a loop of short timed waits that re-polls (a wakeup can be lost under heavy
//! preemption) and ends with [`RunError::Timeout`] naming the silent peer after the step timeout.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cohort_scenario::faults::{Corruption, Fate, FaultPlan};
use cohort_wire::auth::MacKey;
use cohort_wire::msg::{
    CONTROL_DEAD, CONTROL_RESUME, Header, LINK_DATA, LINK_LOST, Measurement, PLANT_ID, Roster, RunControl,
    SCHEMA_VERSION, STATUS_ALIVE, STATUS_DEAD, STATUS_DONE, STATUS_HOLDING, STATUS_IDLE, STATUS_PROGRESS, STATUS_READY,
    STATUS_WAITING, Share, Status,
};
use cohort_wire::transport::{Incoming, Proc, Transport, TransportError, monotonic_ns};
use cohort_wire::validate::{Expect, RejectCounts, Rejection, validate_measurement, validate_share};
use rand_chacha::ChaCha8Rng;

use crate::checkpoint::{AgentState, Checkpoint};
use crate::model::{AgentInput, Algorithm, Neighbour, PlantModel, ShareOut};
use crate::record::{
    LatencyHist, ProcessReport, RosterChange, RunDirs, TelemetryWriter, TimingWriter, WaitStats, reject_map,
};

/// Longest single blocking wait before re-polling.
const POLL: Duration = Duration::from_millis(10);
/// The same for an agent's wait for its first measurement, which lasts the whole start-up: the
/// plant's wakeup ends it, the poll only covers a lost one. With every ready agent re-polling
/// each 10 ms while the rest were spawned, start-up CPU grew as N² (a 256-agent ring: the late
/// agents' start-up cost 3× the early ones').
const POLL_BEFORE_START: Duration = Duration::from_millis(100);
/// After this long in one wait, the process tells the orchestrator whom it is waiting for.
const REPORT_WAITING_AFTER: Duration = Duration::from_millis(200);
/// The plant reports progress at most this often.
const PROGRESS_EVERY: Duration = Duration::from_millis(20);

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("timeout at step {step}: no {what} from {from} for {after_s:.1} s")]
    Timeout { step: u64, from: String, what: &'static str, after_s: f64 },
    #[error("stopped at step {step} on request ({why})")]
    Stopped { step: u64, why: &'static str },
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
    #[error("writing {what}: {source}")]
    Io { what: String, source: std::io::Error },
    /// The algorithm produced a non-finite number (it diverged). Sending it would only have it
    /// rejected by every reader and the run end later as a silent peer; fail here, naming it.
    #[error("{who} produced a non-finite {what} at step {step} (t = {t_s} s): it diverged")]
    Diverged { step: u64, t_s: f64, who: &'static str, what: String },
    /// The model's own code failed (a Python exception, a wrong return): see
    /// [`PlantModel::take_failure`].
    #[error("{who} failed at step {step} (t = {t_s} s): {what}")]
    Model { step: u64, t_s: f64, who: &'static str, what: String },
}

/// A model's failure since the driver last asked ([`PlantModel::take_failure`]), as the error
/// that ends the run at step `step`.
fn failed(what: Option<String>, who: &'static str, step: u64, t_s: f64) -> Result<(), RunError> {
    what.map_or(Ok(()), |what| Err(RunError::Model { step, t_s, who, what }))
}

impl RunError {
    /// The report's form of this error.
    pub fn to_report(&self) -> crate::record::ProcessError {
        use crate::record::ErrorKind;
        let kind = match self {
            RunError::Timeout { .. } => ErrorKind::Timeout,
            RunError::Stopped { .. } => ErrorKind::Stopped,
            RunError::Transport(_) => ErrorKind::Transport,
            RunError::Io { .. } => ErrorKind::Io,
            RunError::Diverged { .. } => ErrorKind::Diverged,
            RunError::Model { .. } => ErrorKind::Model,
        };
        let e = crate::record::ProcessError::new(kind, self.to_string());
        match self {
            RunError::Diverged { t_s, .. } | RunError::Model { t_s, .. } => e.at(*t_s),
            _ => e,
        }
    }
}

fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> RunError {
    let what = what.into();
    move |source| RunError::Io { what, source }
}

/// Settings shared by both drivers.
#[derive(Clone)]
pub struct DriveParams {
    pub run_id: u64,
    pub n_steps: u64,
    pub dt_s: f64,
    pub step_timeout: Duration,
    pub dirs: RunDirs,
    /// Set by SIGTERM (or by the reference run's supervisor): stop at the next wait.
    pub terminate: Arc<AtomicBool>,
    /// When the process started (for the start-up time in its report).
    pub process_start: Instant,
    /// How a wait spins (draining and yielding the CPU) before it blocks on the event; see [`spin_budget`].
    pub spin: SpinPolicy,
    /// 1: agents advance with their neighbours' shares of the previous step (`run.link_delay_steps`).
    pub link_delay_steps: u32,
    /// `run.realtime_rate`: the plant paces steps by the wall clock.
    pub realtime_rate: Option<f64>,
    /// The run's fault plan (empty: none), shared by every process.
    pub faults: Arc<FaultPlan>,
    /// `run.on_agent_loss = "degrade"`: a dead or silent agent is dropped from the roster and
    /// the run goes on; otherwise it ends the run.
    pub degrade: bool,
    /// `run.checkpoint_every_steps` (0: none).
    pub checkpoint_every: u64,
    /// `run.telemetry_every_steps` (≥ 1): see [`DriveParams::writes_row`].
    pub telemetry_every: u64,
    /// `run.telemetry`: the format of the telemetry files.
    pub telemetry: cohort_scenario::TelemetryFormat,
    /// The agent's algorithm kind (names checkpoints).
    pub algorithm_kind: String,
    /// How long a hold for the orchestrator (a process fault) may take, at most.
    pub hold_timeout: Duration,
    /// `run.authenticate`: the run's MAC key; every message sent is sealed with it and every
    /// message received must carry its tag.
    pub key: Option<MacKey>,
}

impl DriveParams {
    /// Plain settings for `n_steps` of `dt_s` with no faults (tests, benchmarks).
    pub fn basic(run_id: u64, n_steps: u64, dt_s: f64, step_timeout: Duration, dirs: RunDirs) -> Self {
        Self {
            run_id,
            n_steps,
            dt_s,
            step_timeout,
            dirs,
            terminate: Arc::new(AtomicBool::new(false)),
            process_start: Instant::now(),
            spin: SpinPolicy::Fixed(Duration::ZERO),
            link_delay_steps: 0,
            realtime_rate: None,
            faults: Arc::new(FaultPlan::default()),
            degrade: true,
            checkpoint_every: 0,
            telemetry_every: 1,
            telemetry: cohort_scenario::TelemetryFormat::default(),
            algorithm_kind: String::new(),
            hold_timeout: Duration::from_secs(60),
            key: None,
        }
    }

    /// The settings a configured scenario asks for.
    pub fn from_setup(
        setup: &crate::paper::Setup,
        run_id: u64,
        dirs: RunDirs,
        terminate: Arc<AtomicBool>,
        process_start: Instant,
    ) -> Self {
        let s = &setup.parsed;
        Self {
            run_id,
            n_steps: s.n_steps(),
            dt_s: s.scenario.dt_s,
            step_timeout: Duration::from_secs_f64(s.run.step_timeout_s),
            dirs,
            terminate,
            process_start,
            spin: spin_budget(&s.run),
            link_delay_steps: s.run.link_delay_steps,
            realtime_rate: s.run.realtime_rate,
            faults: Arc::new(FaultPlan::from_scenario(s)),
            degrade: s.run.on_agent_loss == cohort_scenario::OnAgentLoss::Degrade,
            checkpoint_every: s.run.checkpoint_every_steps,
            telemetry_every: s.run.telemetry_every_steps.max(1),
            telemetry: s.run.telemetry,
            algorithm_kind: setup.algorithm.kind().to_string(),
            hold_timeout: Duration::from_secs_f64(s.run.startup_timeout_s + 2.0 * s.run.step_timeout_s),
            key: None,
        }
    }
}

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
    /// skip spinning for a while ([`Contention`]).
    Adaptive,
}

/// Spin policy for `run.wait`.
pub fn spin_budget(run: &cohort_scenario::RunSettings) -> SpinPolicy {
    match run.wait {
        cohort_scenario::Wait::Event => SpinPolicy::Fixed(Duration::ZERO),
        cohort_scenario::Wait::Poll => SpinPolicy::Fixed(Duration::from_secs_f64(run.step_timeout_s)),
        cohort_scenario::Wait::Adaptive => match run.spin_us {
            Some(us) => SpinPolicy::Fixed(Duration::from_secs_f64(us * 1e-6)),
            None => SpinPolicy::Adaptive,
        },
    }
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
const BACKOFF_MIN: u32 = 64;
const BACKOFF_MAX: u32 = 4096;
/// Growth of the back-off per stalled spin; a clean spin halves it, so spinning goes on being
/// tried often only while fewer than one spin in four stalls (8^f·2^(−(1−f)) < 1 ⇔ f < 1/4).
const BACKOFF_GROWTH: u32 = 8;
/// Weight of the newest wait in the running typical wait.
const ADAPTIVE_EWMA: f64 = 0.1;
/// Spin for up to this many typical waits.
const ADAPTIVE_MARGIN: f64 = 4.0;

impl DriveParams {
    fn t_s(&self, k: u64) -> f64 {
        // Sim time from the step index, never accumulated, so every process agrees exactly.
        k as f64 * self.dt_s
    }

    /// Whether step k gets a telemetry row: every `telemetry_every`-th step from 0, and the last.
    pub fn writes_row(&self, k: u64) -> bool {
        k.is_multiple_of(self.telemetry_every.max(1)) || k + 1 == self.n_steps
    }
}

/// What a process collects while it waits: it takes each incoming message, says when the wait
/// is over, and names whom it still lacks.
trait Inbox {
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
fn rejected_note(r: Option<Rejection>) -> String {
    r.map_or(String::new(), |r| {
        format!(" (its latest message was rejected: {}, i.e. damaged in transit or not of this run)", r.name())
    })
}

struct Waiter<'a, T: Transport + ?Sized> {
    t: &'a mut T,
    p: &'a DriveParams,
    me: u32,
    timeouts: u64,
    /// Running typical wait, µs, per kind of wait (measurement, share): adaptive spinning.
    typical_wait_us: [f64; 2],
    contention: Contention,
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
    fn may_spin(&mut self) -> bool {
        if self.skip > 0 {
            self.skip -= 1;
            return false;
        }
        true
    }
    /// A spinning wait ended: `stalled` if one of its yields did.
    fn spun(&mut self, stalled: bool) {
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
    fn new(t: &'a mut T, p: &'a DriveParams, me: u32) -> Waiter<'a, T> {
        Waiter {
            t,
            p,
            me,
            timeouts: 0,
            typical_wait_us: [0.0; 2],
            contention: Contention::default(),
            stats: WaitStats::default(),
            events: Vec::new(),
        }
    }

    fn spin_for(&mut self, kind: usize) -> Duration {
        let typical = self.typical_wait_us[kind];
        match self.p.spin {
            SpinPolicy::Fixed(d) => d,
            SpinPolicy::Adaptive if typical > ADAPTIVE_CAP_US => Duration::ZERO,
            SpinPolicy::Adaptive if !self.contention.may_spin() => Duration::ZERO,
            SpinPolicy::Adaptive => {
                Duration::from_secs_f64((ADAPTIVE_MARGIN * typical).clamp(ADAPTIVE_FLOOR_US, ADAPTIVE_CAP_US) * 1e-6)
            }
        }
    }

    /// Drain into `inbox`, check it, wait briefly; repeat until it is complete or `limit` passes
    /// with nothing fresh.
    fn until(
        &mut self,
        step: u64,
        what: &'static str,
        inbox: &mut impl Inbox,
        limit: Duration,
    ) -> Result<(), RunError> {
        let started = Instant::now();
        let mut silent_since = started;
        let kind = usize::from(what == "share");
        let mut spin = self.spin_for(kind);
        let spun = spin > Duration::ZERO;
        let adaptive = self.p.spin == SpinPolicy::Adaptive;
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
                if spun && adaptive {
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
            // While spinning, look at the control service only now and then: it is not free.
            if !spinning || spins.is_multiple_of(1024) {
                if self.t.stop_requested() {
                    // What completes this wait may have come in with the stop (the run's last
                    // step): look once more before giving up.
                    self.t.drain(&mut |inc| inbox.take(inc))?;
                    if inbox.complete() {
                        return Ok(());
                    }
                    return Err(RunError::Stopped { step, why: "orchestrator" });
                }
                if self.p.terminate.load(Ordering::Relaxed) {
                    return Err(RunError::Stopped { step, why: "SIGTERM" });
                }
                self.t.control_events(&mut self.events);
                for e in self.events.drain(..) {
                    inbox.control(&e);
                }
                if inbox.complete() {
                    continue;
                }
                if !reported && waited >= REPORT_WAITING_AFTER {
                    reported = true;
                    let (id, _) = inbox.missing();
                    let mut s = status(self.p, self.me, STATUS_WAITING, step, id);
                    s.detail = inbox.rejected_from(id).map_or(0, |r| r as u32 + 1);
                    self.t.report(&s);
                }
            }
            if spinning {
                let y0 = Instant::now();
                std::thread::yield_now();
                if adaptive && y0.elapsed() >= YIELD_STALL {
                    // Contended: spinning only takes the CPU from whoever we wait for.
                    stalled = true;
                    spin = Duration::ZERO;
                }
            } else {
                let poll = if step == 0 && kind == 0 { POLL_BEFORE_START } else { POLL };
                self.t.wait(poll.min(limit.saturating_sub(waited)).max(Duration::from_micros(100)))?;
            }
        }
    }
}

fn status(p: &DriveParams, me: u32, kind: u32, step: u64, waiting_for: u32) -> Status {
    Status {
        version: SCHEMA_VERSION,
        sender: me,
        run_id: p.run_id,
        kind,
        waiting_for,
        step,
        t_s: p.t_s(step),
        build_hash: cohort_wire::build_id_hash(),
        detail: 0,
        _pad: 0,
        mac: [0; 2],
    }
}

/// Tell the orchestrator this process's ports exist.
pub fn report_ready<T: Transport + ?Sized>(t: &mut T, p: &DriveParams, me: Proc) {
    t.report(&status(p, me.sender_id(), STATUS_READY, 0, 0));
}

fn new_report(me: Proc, p: &DriveParams) -> ProcessReport {
    ProcessReport {
        process: me.name(),
        pid: std::process::id(),
        steps_completed: 0,
        wall_s: 0.0,
        messages_received: 0,
        messages_rejected: Default::default(),
        timeouts: 0,
        startup_s: p.process_start.elapsed().as_secs_f64(),
        cpu_s: 0.0,
        max_rss_kb: 0,
        metrics: Default::default(),
        error: None,
        faults: Default::default(),
        messages_sent: 0,
        received_from: Default::default(),
        latency_from_ns: Default::default(),
        solver: None,
        wait: Default::default(),
    }
}

/// Real time: a plant more than `timeout` behind its schedule (`due` passed that long ago) was
/// stalled itself (stopped, starved of CPU): that is not its agents' silence. As after a hold, the
/// schedule goes on from now (`paced_from` moves by the lag) and each agent's silence counts from
/// now.
fn rebase_if_stalled(paced_from: &mut Instant, last_heard: &mut [Instant], due: Instant, timeout: Duration, k: u64) {
    let now = Instant::now();
    let lag = now.saturating_duration_since(due);
    if lag > timeout {
        tracing::warn!(
            "step {k}: the plant fell {:.3} s behind its real-time schedule (stopped or starved); the schedule \
             goes on from here",
            lag.as_secs_f64()
        );
        *paced_from += lag;
        last_heard.iter_mut().for_each(|h| *h = now);
    }
}

/// Run the plant's side of every step. Returns its report (also on error, with `error` set);
/// telemetry written so far is flushed either way.
pub fn run_plant<T: Transport + ?Sized>(
    t: &mut T,
    model: &mut dyn PlantModel,
    rng: &mut ChaCha8Rng,
    n_agents: u32,
    p: &DriveParams,
) -> ProcessReport {
    let mut report = new_report(Proc::Plant, p);
    report_ready(t, p, Proc::Plant);
    let result = plant_loop(t, model, rng, n_agents, p, &mut report);
    (report.cpu_s, report.max_rss_kb) = crate::record::cpu_and_rss();
    report.metrics = model.metrics().into_iter().collect();
    let mut result = result;
    for (name, text) in model.extra_telemetry() {
        let path = p.dirs.snapshots().join(name);
        if let Err(e) = std::fs::create_dir_all(p.dirs.snapshots()).and_then(|_| std::fs::write(&path, text)) {
            result = result.and(Err(io(path.display().to_string())(e)));
        }
    }
    if let Err(e) = result {
        report.error = Some(e.to_report());
    } else {
        t.report(&status(p, PLANT_ID, STATUS_DONE, p.n_steps, 0));
    }
    report
}

/// The plant's inbox for step k: a step token from every live agent (its share of k, or a
/// `LINK_LOST` token when the link lost or delayed it), and the newest data share due by k (its
/// own share of k, or one delayed to arrive now).
struct PlantInbox {
    run_id: u64,
    k: u64,
    /// Oldest step accepted (k minus the longest link delay, or one more in real time).
    back: u64,
    plan: Arc<FaultPlan>,
    /// Per agent: step k's token still awaited.
    want: Vec<bool>,
    /// Per agent: the step of the newest data share taken, and its command (buffers reused:
    /// this is every share of every step).
    newest_step: Vec<Option<u64>>,
    newest_cmd: Vec<Vec<f64>>,
    /// Agents the orchestrator reported dead while the plant waited.
    died: Roster,
    latency_max_ns: u64,
    received: u64,
    /// Per agent: messages received (valid or not), and the latency of the valid ones.
    from: Vec<u64>,
    latency: Vec<LatencyHist>,
    /// Per agent: the newest step of a token, and tokens lost to a full queue (a gap in steps).
    last_token: Vec<Option<u64>>,
    overrun: Vec<u64>,
    late: u64,
    rejects: RejectCounts,
    /// Per agent: why its latest share was rejected, if it was.
    rejected: Vec<Option<Rejection>>,
    key: Option<MacKey>,
}

impl Inbox for PlantInbox {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        let Incoming::Share { from, share } = inc else {
            self.rejects.add(Rejection::Sender); // the plant reads no measurements
            return;
        };
        // `from` names the service (or socket) it came by; anything else is no agent of ours.
        if from == 0 || from as usize > self.want.len() {
            self.rejects.add(Rejection::Sender);
            return;
        }
        let idx = (from - 1) as usize;
        let e = Expect {
            run_id: self.run_id,
            sender: from,
            step_min: self.k.saturating_sub(self.back),
            step_max: self.k,
            key: self.key,
        };
        self.from[idx] += 1;
        match validate_share(share, &e) {
            Ok(()) => {
                self.rejected[idx] = None;
                self.latency[idx].record(monotonic_ns().saturating_sub(share.header.sent_wall_ns));
                let step = share.header.step;
                let on_time = share.link == LINK_LOST || self.plan.fate(from, step) == Fate::Deliver;
                if on_time {
                    if let Some(last) = self.last_token[idx]
                        && step > last + 1
                    {
                        self.overrun[idx] += step - last - 1;
                    }
                    self.last_token[idx] = Some(self.last_token[idx].map_or(step, |l| l.max(step)));
                }
                if step == self.k && on_time {
                    self.want[idx] = false;
                } else if on_time && share.link == LINK_DATA {
                    self.late += 1; // its step closed without it (real time)
                }
                if share.link == LINK_DATA && self.newest_step[idx].is_none_or(|s| s < step) {
                    self.newest_step[idx] = Some(step);
                    self.newest_cmd[idx].clear();
                    self.newest_cmd[idx].extend_from_slice(share.command());
                    let latency = monotonic_ns().saturating_sub(share.header.sent_wall_ns);
                    self.latency_max_ns = self.latency_max_ns.max(latency);
                }
            }
            Err(r) => {
                self.rejects.add(r);
                self.rejected[idx] = Some(r);
            }
        }
    }
    fn complete(&self) -> bool {
        self.want.iter().all(|w| !w)
    }
    fn missing(&self) -> (u32, String) {
        let id = self.want.iter().position(|w| *w).map_or(0, |i| i as u32 + 1);
        (id, format!("agent {id}{}", rejected_note(self.rejected_from(id))))
    }
    fn rejected_from(&self, id: u32) -> Option<Rejection> {
        self.rejected.get((id as usize).wrapping_sub(1)).copied().flatten()
    }
    fn control(&mut self, c: &RunControl) {
        if c.command == CONTROL_DEAD {
            let n = self.want.len();
            for id in c.dead.ids().filter(|&id| id as usize <= n) {
                self.died.set(id, true);
                self.want[id as usize - 1] = false;
            }
        }
    }
}

/// The plant's roster: who is live, and what changed (reported to the orchestrator and kept for
/// the report).
struct PlantRoster {
    live: Roster,
    lost_at_close: Roster,
    changes: Vec<RosterChange>,
    since: Instant,
}

impl PlantRoster {
    fn set<T: Transport + ?Sized>(&mut self, t: &mut T, p: &DriveParams, id: u32, live: bool, step: u64, why: &str) {
        if self.live.contains(id) == live {
            return;
        }
        self.live.set(id, live);
        let wall_s = self.since.elapsed().as_secs_f64();
        tracing::debug!("step {step}: agent {id} {} the roster ({why})", if live { "joins" } else { "leaves" });
        self.changes.push(RosterChange { step, agent: id, live, reason: why.into(), wall_s });
        t.report(&status(p, PLANT_ID, if live { STATUS_ALIVE } else { STATUS_DEAD }, step, id));
    }
}

fn plant_loop<T: Transport + ?Sized>(
    t: &mut T,
    model: &mut dyn PlantModel,
    rng: &mut ChaCha8Rng,
    n_agents: u32,
    p: &DriveParams,
    report: &mut ProcessReport,
) -> Result<(), RunError> {
    let mut columns = vec!["k".to_string(), "t_s".to_string()];
    columns.extend(model.columns());
    let tel_path = p.dirs.telemetry().join(format!("plant.{}", p.telemetry.extension()));
    let mut tel =
        TelemetryWriter::create(p.telemetry, &tel_path, &columns).map_err(io(tel_path.display().to_string()))?;
    // Timing in the telemetry's format (Parquet's journal and writer thread keep it off the step).
    let tim_path = p.dirs.timing().join(format!("plant.{}", p.telemetry.extension()));
    let timing_columns = ["k".into(), "round_ns".into(), "share_latency_max_ns".into()];
    let mut timing =
        TimingWriter::create(p.telemetry, &tim_path, &timing_columns).map_err(io(tim_path.display().to_string()))?;

    // Start barrier: nothing is sent before every reader exists.
    let barrier_start = Instant::now();
    let barrier_limit = p.step_timeout.max(Duration::from_secs(60));
    while !t.start_granted() {
        if t.stop_requested() || p.terminate.load(Ordering::Relaxed) {
            return Err(RunError::Stopped { step: 0, why: "before start" });
        }
        if barrier_start.elapsed() > barrier_limit {
            let after_s = barrier_limit.as_secs_f64();
            return Err(RunError::Timeout { step: 0, from: "the orchestrator".into(), what: "start signal", after_s });
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    report.startup_s = p.process_start.elapsed().as_secs_f64();
    let loop_start = Instant::now();

    let n = n_agents as usize;
    let realtime = p.realtime_rate.is_some();
    let mut inbox = PlantInbox {
        run_id: p.run_id,
        k: 0,
        back: u64::from(p.faults.max_delay()) + u64::from(realtime),
        plan: Arc::clone(&p.faults),
        want: vec![false; n],
        newest_step: vec![None; n],
        newest_cmd: vec![Vec::new(); n],
        died: Roster::EMPTY,
        latency_max_ns: 0,
        received: 0,
        from: vec![0; n],
        latency: (0..n).map(|_| LatencyHist::default()).collect(),
        last_token: vec![None; n],
        overrun: vec![0; n],
        late: 0,
        rejects: RejectCounts::default(),
        rejected: vec![None; n],
        key: p.key,
    };
    let mut roster = PlantRoster {
        live: Roster::all(n_agents),
        lost_at_close: Roster::EMPTY,
        changes: Vec::new(),
        since: loop_start,
    };
    let hold_steps = p.faults.hold_steps();
    // The command each agent's spacecraft flies: the newest valid one (held when a share is
    // missing), zero once the agent is dead (its spacecraft coasts).
    let mut commands: Vec<Vec<f64>> = vec![Vec::new(); n];
    // Real time: when each agent last met its deadline (a silent agent is declared dead after
    // the step timeout, as in lockstep).
    let mut last_heard = vec![Instant::now(); n];
    let mut row = Vec::with_capacity(columns.len());
    let mut waiter = Waiter::new(t, p, PLANT_ID);
    let mut last_progress = Instant::now();
    let sent = std::cell::Cell::new(0u64);
    // Measurements of step k go out as soon as the truth reaches tₖ; the telemetry row of step
    // k-1 is formatted afterwards, while the agents compute, so it stays off the critical path.
    let send_measurements =
        |t: &mut T, model: &mut dyn PlantModel, rng: &mut ChaCha8Rng, k: u64, roster: &mut PlantRoster| {
            let mut readings = Vec::with_capacity(64);
            for i in 1..=n_agents {
                readings.clear();
                model.readings(i, rng, &mut readings);
                failed(model.take_failure(), "the plant model", k, p.t_s(k))?;
                if !readings.iter().all(|x| x.is_finite()) {
                    let what = format!("reading for agent {i}");
                    return Err(RunError::Diverged { step: k, t_s: p.t_s(k), who: "the plant model", what });
                }
                let mut m = Measurement::new(Header::new(p.run_id, PLANT_ID, k, p.t_s(k)), &readings);
                m.live = roster.live;
                m.lost_at_close = roster.lost_at_close;
                if let Some(k) = &p.key {
                    k.seal_measurement(&mut m);
                }
                t.send_measurement(i, &m)?;
                sent.set(sent.get() + 1);
            }
            roster.lost_at_close = Roster::EMPTY;
            Ok::<(), RunError>(())
        };
    let mut paced_from = Instant::now();
    let result = (|| {
        let mut round_start = monotonic_ns();
        if p.n_steps > 0 {
            send_measurements(waiter.t, model, rng, 0, &mut roster)?;
        }
        for k in 0..p.n_steps {
            let t_s = p.t_s(k);
            tracing::trace!("step {k} (t = {t_s:.3} s)");
            inbox.k = k;
            inbox.latency_max_ns = 0;
            for j in 1..=n_agents {
                let idx = j as usize - 1;
                inbox.newest_step[idx] = None;
                inbox.want[idx] = roster.live.contains(j);
            }
            let limit = match p.realtime_rate {
                // Real time: a command is due by the end of its step.
                Some(rate) => {
                    let due = |from: Instant| from + Duration::from_secs_f64((k + 1) as f64 * p.dt_s / rate);
                    let was_due = due(paced_from);
                    rebase_if_stalled(&mut paced_from, &mut last_heard, was_due, p.step_timeout, k);
                    due(paced_from).saturating_duration_since(Instant::now())
                }
                None => p.step_timeout,
            };
            match waiter.until(k, "share", &mut inbox, limit) {
                Ok(()) => {}
                Err(RunError::Timeout { .. }) if realtime || p.degrade => {}
                Err(e) => return Err(e),
            }
            // Close step k: who delivered, who missed, who is gone.
            for j in 1..=n_agents {
                let idx = j as usize - 1;
                if inbox.died.contains(j) && roster.live.contains(j) {
                    roster.set(waiter.t, p, j, false, k, "died");
                    roster.lost_at_close.set(j, true);
                }
                if !roster.live.contains(j) {
                    commands[idx].iter_mut().for_each(|u| *u = 0.0);
                    continue;
                }
                let missed = inbox.want[idx];
                if missed && realtime {
                    report.faults.deadline_misses += 1;
                    if last_heard[idx].elapsed() >= p.step_timeout {
                        if !p.degrade {
                            let (from, after_s) = (format!("agent {j}"), p.step_timeout.as_secs_f64());
                            return Err(RunError::Timeout { step: k, from, what: "share", after_s });
                        }
                        roster.set(waiter.t, p, j, false, k, "silent");
                        roster.lost_at_close.set(j, true);
                        commands[idx].iter_mut().for_each(|u| *u = 0.0);
                        continue;
                    }
                } else if missed {
                    // Lockstep: waited the full step timeout (degrade mode, else it returned).
                    roster.set(waiter.t, p, j, false, k, "silent");
                    roster.lost_at_close.set(j, true);
                    commands[idx].iter_mut().for_each(|u| *u = 0.0);
                    continue;
                } else {
                    last_heard[idx] = Instant::now();
                }
                match inbox.newest_step[idx].take() {
                    Some(_) => std::mem::swap(&mut commands[idx], &mut inbox.newest_cmd[idx]),
                    None => *report.faults.held.entry(Proc::Agent(j).name()).or_default() += 1,
                }
            }
            inbox.died = Roster::EMPTY;
            for (i, u) in commands.iter().enumerate() {
                model.apply_command(i as u32 + 1, u);
            }
            let write_row = p.writes_row(k);
            if write_row {
                row.clear();
                row.push(t_s);
                model.row(&mut row);
            }
            let round_ns = monotonic_ns() - round_start;
            model.advance(p.dt_s);
            failed(model.take_failure(), "the plant model", k, t_s)?;
            if let Some(rate) = p.realtime_rate {
                // Real-time pacing: step k+1 starts no earlier than (k+1)·dt/rate after step 0.
                let due = paced_from + Duration::from_secs_f64((k + 1) as f64 * p.dt_s / rate);
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                } else {
                    rebase_if_stalled(&mut paced_from, &mut last_heard, due, p.step_timeout, k);
                }
            }
            if k + 1 < p.n_steps && hold_steps.binary_search(&(k + 1)).is_ok() {
                // Flush first: a process fault may be due to end this run.
                tel.flush().map_err(io("plant telemetry"))?;
                hold(&mut waiter, p, k + 1, &mut roster)?;
                // Nobody can answer while the plant holds, and an agent back on the roster (a
                // thaw, a relaunch) is heard from only now: its silence counts from here, not
                // from before it left (else, in real time, a hold that overran the next step's
                // deadline would have it declared dead again at its very return step).
                last_heard.iter_mut().for_each(|h| *h = Instant::now());
            }
            round_start = monotonic_ns();
            if k + 1 < p.n_steps {
                send_measurements(waiter.t, model, rng, k + 1, &mut roster)?;
            }
            if write_row {
                tel.row(k, &row).map_err(io("plant telemetry"))?;
            }
            timing.row(k, &[round_ns, inbox.latency_max_ns]).map_err(io("plant timing"))?;
            report.steps_completed = k + 1;
            if last_progress.elapsed() >= PROGRESS_EVERY {
                last_progress = Instant::now();
                waiter.t.report(&status(p, PLANT_ID, STATUS_PROGRESS, k + 1, 0));
            }
        }
        Ok(())
    })();
    report.wall_s = loop_start.elapsed().as_secs_f64();
    report.timeouts = waiter.timeouts;
    report.wait = waiter.stats;
    report.messages_received = inbox.received;
    report.messages_rejected = reject_map(&inbox.rejects);
    report.faults.late = inbox.late;
    report.faults.roster = std::mem::take(&mut roster.changes);
    report.messages_sent = sent.get();
    for (i, (n, h)) in inbox.from.iter().zip(&inbox.latency).enumerate() {
        let name = Proc::Agent(i as u32 + 1).name();
        report.received_from.insert(name.clone(), *n);
        report.faults.overrun.insert(name.clone(), inbox.overrun[i]);
        report.latency_from_ns.insert(name, h.buckets());
    }
    // Never lose telemetry: flush whatever was written, also after an error.
    let flushed = tel.finish().and_then(|_| timing.finish()).map_err(io("plant telemetry"));
    result.and(flushed)
}

/// Hold before the measurements of step `k` until the orchestrator has carried out the process
/// faults due then, and apply its roster changes.
fn hold<T: Transport + ?Sized>(
    w: &mut Waiter<'_, T>,
    p: &DriveParams,
    k: u64,
    roster: &mut PlantRoster,
) -> Result<(), RunError> {
    w.t.report(&status(p, PLANT_ID, STATUS_HOLDING, k, 0));
    let started = Instant::now();
    let mut events = Vec::new();
    loop {
        if w.t.stop_requested() {
            return Err(RunError::Stopped { step: k, why: "orchestrator" });
        }
        if p.terminate.load(Ordering::Relaxed) {
            return Err(RunError::Stopped { step: k, why: "SIGTERM" });
        }
        w.t.control_events(&mut events);
        for e in events.drain(..) {
            match e.command {
                CONTROL_RESUME if e.step == k => {
                    for id in e.dead.ids() {
                        roster.set(w.t, p, id, false, k, "fault");
                    }
                    for id in e.alive.ids() {
                        roster.set(w.t, p, id, true, k, "fault");
                    }
                    return Ok(());
                }
                CONTROL_DEAD => {
                    for id in e.dead.ids() {
                        roster.set(w.t, p, id, false, k, "died");
                    }
                }
                _ => {}
            }
        }
        if started.elapsed() > p.hold_timeout {
            return Err(RunError::Timeout {
                step: k,
                from: "the orchestrator".into(),
                what: "resume after a fault",
                after_s: started.elapsed().as_secs_f64(),
            });
        }
        std::thread::sleep(Duration::from_micros(200));
    }
}

/// Run agent `id`'s side of every step; `restore`: a relaunched agent's checkpoint, already
/// loaded into `algo`.
pub fn run_agent<T: Transport + ?Sized>(
    t: &mut T,
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    p: &DriveParams,
    restore: Option<&Checkpoint>,
) -> ProcessReport {
    let me = Proc::Agent(id);
    let mut report = new_report(me, p);
    report_ready(t, p, me);
    let started = Instant::now();
    let result = agent_loop(t, algo, id, neighbours, p, restore, &mut report);
    report.wall_s = started.elapsed().as_secs_f64();
    report.solver = algo.solver_stats();
    (report.cpu_s, report.max_rss_kb) = crate::record::cpu_and_rss();
    if let Err(e) = result {
        report.error = Some(e.to_report());
    } else {
        t.report(&status(p, id, STATUS_DONE, p.n_steps, 0));
        linger(t, p);
    }
    report
}

/// After an agent's last step, where the transport needs it, keep its ports open until the
/// orchestrator's stop request (sent once the plant has finished, so every last share was read)
/// or a signal. Bounded by two step timeouts, in which the plant finishes its last step or the
/// run fails anyway; leaving then loses nothing the run still needs.
fn linger<T: Transport + ?Sized>(t: &mut T, p: &DriveParams) {
    if !t.keeps_ports_until_stopped() {
        return;
    }
    let until = Instant::now().checked_add(p.step_timeout.saturating_mul(2));
    while until.is_none_or(|u| Instant::now() < u) && !t.stop_requested() && !p.terminate.load(Ordering::Relaxed) {
        // Nothing is awaited but the stop: a wakeup from a late share only shortens the nap.
        if t.wait(POLL).is_err() {
            std::thread::sleep(POLL);
        }
    }
}

/// Whether a roster history (first step, live) says live at step `u` (live before any entry).
fn live_at(hist: &[(u64, bool)], u: u64) -> bool {
    hist.iter().rev().find(|(s, _)| *s <= u).is_none_or(|e| e.1)
}

/// Fold measurement `m`'s roster into the history of agent `id`.
fn note_roster(hist: &mut Vec<(u64, bool)>, m: &Measurement, id: u32) {
    let step = m.header.step;
    let mut live = hist.last().is_none_or(|e| e.1);
    if live && m.lost_at_close.contains(id) {
        hist.push((step.saturating_sub(1), false));
        live = false;
    }
    let now = m.live.contains(id);
    if now != live {
        hist.push((step, now));
    }
}

/// An agent's view of one neighbour.
struct Peer {
    id: u32,
    /// Valid shares not yet used: (step, values).
    arrived: Vec<(u64, Vec<f64>)>,
    /// Value buffers to reuse for the next shares (a share arrives every step).
    spare: Vec<Vec<f64>>,
    /// The last share used (step, values): it stands in for one that does not arrive.
    held: Option<(u64, Vec<f64>)>,
    /// Roster history: (first step, live).
    hist: Vec<(u64, bool)>,
    /// Steps whose token (an on-time share, or a `LINK_LOST` token) has arrived.
    tokens: Vec<u64>,
    /// Messages received from it (valid or not), and the latency of the valid ones.
    received: u64,
    latency: LatencyHist,
    /// The newest step of a token from it, and tokens lost to a full queue (a gap in steps).
    last_token: Option<u64>,
    overrun: u64,
    /// Why its latest share was rejected, if it was.
    rejected: Option<Rejection>,
}

/// An agent's inbox: the plant's measurement, then the neighbours' shares.
struct AgentInbox {
    run_id: u64,
    me: u32,
    k: u64,
    /// Waiting for the measurement of step k (true), or past it (false).
    want_measurement: bool,
    /// The step whose neighbours' shares complete this wait, if any.
    need_shares: Option<u64>,
    /// Oldest share step accepted, behind k.
    back: u64,
    realtime: bool,
    /// The newest measurement of step ≥ k.
    meas: Option<Box<Measurement>>,
    meas_latency_ns: u64,
    from_plant: u64,
    latency_plant: LatencyHist,
    /// Measurements lost to a full queue (a gap in their steps).
    overrun_plant: u64,
    last_meas_step: Option<u64>,
    me_hist: Vec<(u64, bool)>,
    peers: Vec<Peer>,
    plan: Arc<FaultPlan>,
    /// A relaunched agent, before its first measurement: its neighbours may already be far
    /// ahead of its checkpoint (their shares of the return step can beat the plant's measurement
    /// to it), so shares up to the run's last step are accepted.
    relaunched_until: Option<u64>,
    fresh: bool,
    received: u64,
    rejects: RejectCounts,
    /// Why the plant's latest measurement was rejected, if it was.
    rejected_plant: Option<Rejection>,
    /// The run's last step: no message names a later one (a step read from a message is never
    /// trusted as a loop bound beyond it).
    last_step: u64,
    key: Option<MacKey>,
}

impl AgentInbox {
    fn i_am_live(&self) -> bool {
        self.last_meas_step.is_none_or(|s| live_at(&self.me_hist, s))
    }
}

impl Inbox for AgentInbox {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        match inc {
            Incoming::Measurement(m) => {
                // Once every share of step k is in, the plant may already send step k+1's
                // measurement while this agent still waits for a neighbour: keep it.
                let want = if self.want_measurement { self.k } else { self.k + 1 };
                let e = Expect {
                    run_id: self.run_id,
                    sender: PLANT_ID,
                    step_min: want,
                    step_max: self.last_step,
                    key: self.key,
                };
                self.from_plant += 1;
                match validate_measurement(m, &e) {
                    Ok(()) => {
                        self.rejected_plant = None;
                        self.latency_plant.record(monotonic_ns().saturating_sub(m.header.sent_wall_ns));
                        let step = m.header.step;
                        if self.last_meas_step.is_some_and(|s| s >= step) {
                            return; // a duplicate or an older one: the first, newest, counts
                        }
                        if let Some(last) = self.last_meas_step {
                            self.overrun_plant += step - last - 1;
                        }
                        self.last_meas_step = Some(step);
                        self.fresh = true;
                        note_roster(&mut self.me_hist, m, self.me);
                        for peer in &mut self.peers {
                            note_roster(&mut peer.hist, m, peer.id);
                        }
                        self.meas_latency_ns = monotonic_ns().saturating_sub(m.header.sent_wall_ns);
                        self.meas = Some(Box::new(*m));
                    }
                    Err(r) => {
                        self.rejects.add(r);
                        self.rejected_plant = Some(r);
                    }
                }
            }
            Incoming::Share { from, share } => {
                let Some(peer) = self.peers.iter_mut().find(|p| p.id == from) else {
                    self.rejects.add(Rejection::Sender);
                    return;
                };
                peer.received += 1;
                // A neighbour may be one step ahead (of this agent, or of the newest measurement
                // when this agent is catching up); a delayed share may be `back` steps old.
                let e = Expect {
                    run_id: self.run_id,
                    sender: from,
                    step_min: self.k.saturating_sub(self.back),
                    step_max: match (self.last_meas_step, self.relaunched_until) {
                        (None, Some(last)) => last,
                        (m, _) => self.k.max(m.unwrap_or(0)) + 1,
                    }
                    .min(self.last_step),
                    key: self.key,
                };
                match validate_share(share, &e) {
                    Ok(()) => {
                        peer.rejected = None;
                        peer.latency.record(monotonic_ns().saturating_sub(share.header.sent_wall_ns));
                        let step = share.header.step;
                        if share.link == LINK_LOST || self.plan.fate(from, step) == Fate::Deliver {
                            peer.tokens.push(step);
                            if let Some(last) = peer.last_token
                                && step > last + 1
                                && live_at(&peer.hist, step)
                            {
                                peer.overrun += step - last - 1;
                            }
                            peer.last_token = Some(peer.last_token.map_or(step, |l| l.max(step)));
                        }
                        if share.link == LINK_DATA && !peer.arrived.iter().any(|(s, _)| *s == step) {
                            let mut values = peer.spare.pop().unwrap_or_default();
                            values.clear();
                            values.extend_from_slice(share.values());
                            peer.arrived.push((step, values));
                        }
                    }
                    Err(r) => {
                        self.rejects.add(r);
                        peer.rejected = Some(r);
                    }
                }
            }
        }
    }
    fn complete(&self) -> bool {
        if self.want_measurement {
            // Off the roster (frozen, or relaunched before its return step): wait on.
            let Some(m) = &self.meas else { return false };
            if !live_at(&self.me_hist, m.header.step) {
                return false;
            }
        }
        let Some(u) = self.need_shares else { return true };
        // Declared dead while waiting (a late return from a freeze), or the step closed
        // without the share (real time): go on with what arrived.
        if !self.i_am_live() || (self.realtime && self.last_meas_step.is_some_and(|s| s > u)) {
            return true;
        }
        self.peers.iter().all(|p| !live_at(&p.hist, u) || p.tokens.contains(&u))
    }
    fn missing(&self) -> (u32, String) {
        if self.want_measurement && self.meas.is_none() {
            return (PLANT_ID, format!("the plant{}", rejected_note(self.rejected_plant)));
        }
        if self.want_measurement && !self.i_am_live() {
            return (PLANT_ID, "the plant (to be back on the roster)".into());
        }
        let u = self.need_shares.unwrap_or(self.k);
        let j = self.peers.iter().find(|p| live_at(&p.hist, u) && !p.tokens.contains(&u)).map_or(0, |p| p.id);
        (j, format!("neighbour agent {j}{}", rejected_note(self.rejected_from(j))))
    }
    fn rejected_from(&self, id: u32) -> Option<Rejection> {
        if id == PLANT_ID {
            return self.rejected_plant;
        }
        self.peers.iter().find(|p| p.id == id).and_then(|p| p.rejected)
    }
    fn fresh(&mut self) -> bool {
        std::mem::take(&mut self.fresh)
    }
}

/// Garble a share the way a `corrupt` fault says; every receiver's validation rejects it.
fn corrupt(s: &mut Share, how: Corruption) {
    match how {
        // Far outside any accepted window, in either direction.
        Corruption::WrongStep => s.header.step = s.header.step.wrapping_add(1 << 40),
        Corruption::WrongSender => s.header.sender = s.header.sender.wrapping_add(1000),
        Corruption::NonFinite => {
            s.command[0] = f64::NAN;
            s.values[0] = f64::NAN;
            s.command_len = s.command_len.max(1);
            s.values_len = s.values_len.max(1);
        }
    }
}

/// Send a share, sealed with the run's key when there is one (after a `corrupt` fault garbled
/// it: the fault models a sender that sends garbage, which its readers must reject by reason).
fn send_share<T: Transport + ?Sized>(t: &mut T, p: &DriveParams, s: &Share) -> Result<(), TransportError> {
    match &p.key {
        Some(k) => {
            let mut sealed = *s;
            k.seal_share(&mut sealed);
            t.send_share(&sealed)
        }
        None => t.send_share(s),
    }
}

fn agent_loop<T: Transport + ?Sized>(
    t: &mut T,
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    p: &DriveParams,
    restore: Option<&Checkpoint>,
    report: &mut ProcessReport,
) -> Result<(), RunError> {
    let name = Proc::Agent(id).name();
    let mut columns = vec!["k".to_string(), "t_s".to_string()];
    columns.extend(algo.columns());
    let tel_path = p.dirs.telemetry().join(format!("{name}.{}", p.telemetry.extension()));
    let tim_path = p.dirs.timing().join(format!("{name}.{}", p.telemetry.extension()));
    let timing_columns = ["k".into(), "meas_latency_ns".into(), "neighbour_wait_ns".into(), "compute_ns".into()];
    // A relaunched agent goes on with its predecessor's files.
    let (mut tel, mut timing) = if restore.is_some() {
        (
            TelemetryWriter::append(p.telemetry, &tel_path, &columns).map_err(io(tel_path.display().to_string()))?,
            TimingWriter::append(p.telemetry, &tim_path, &timing_columns)
                .map_err(io(tim_path.display().to_string()))?,
        )
    } else {
        (
            TelemetryWriter::create(p.telemetry, &tel_path, &columns).map_err(io(tel_path.display().to_string()))?,
            TimingWriter::create(p.telemetry, &tim_path, &timing_columns)
                .map_err(io(tim_path.display().to_string()))?,
        )
    };
    let plan = &*p.faults;
    let delay = u64::from(p.link_delay_steps);
    let mut inbox = AgentInbox {
        run_id: p.run_id,
        me: id,
        k: 0,
        want_measurement: true,
        need_shares: None,
        back: delay + u64::from(plan.max_delay()) + 1,
        realtime: p.realtime_rate.is_some(),
        meas: None,
        meas_latency_ns: 0,
        from_plant: 0,
        latency_plant: LatencyHist::default(),
        overrun_plant: 0,
        last_meas_step: None,
        me_hist: Vec::new(),
        peers: neighbours
            .iter()
            .map(|&j| Peer {
                id: j,
                arrived: Vec::new(),
                spare: Vec::new(),
                held: None,
                hist: Vec::new(),
                tokens: Vec::new(),
                received: 0,
                latency: LatencyHist::default(),
                last_token: None,
                overrun: 0,
                rejected: None,
            })
            .collect(),
        plan: Arc::clone(&p.faults),
        relaunched_until: restore.map(|_| p.n_steps),
        fresh: false,
        received: 0,
        rejects: RejectCounts::default(),
        rejected_plant: None,
        last_step: p.n_steps.saturating_sub(1),
        key: p.key,
    };
    let mut k = 0;
    if let Some(c) = restore {
        k = c.step;
        report.faults.restored_from_step = Some(c.step);
        for (j, step, values) in &c.state.held {
            if let Some(peer) = inbox.peers.iter_mut().find(|p| p.id == *j) {
                peer.held = Some((*step, values.clone()));
            }
        }
    }
    let hold_steps = plan.hold_steps();
    // The plant declares a silent agent dead after its step timeout (degrade mode), and only then
    // sends the next measurement or the roster that releases a wait on that agent's share: both
    // waits must outlast it, or a healthy agent times out in the same instant as the silent one.
    let degrade_limit = if p.degrade { 2 * p.step_timeout + Duration::from_secs(1) } else { p.step_timeout };
    let meas_limit = if plan.has_process_faults() { degrade_limit + p.hold_timeout } else { degrade_limit };
    let share_limit = degrade_limit;
    let mut pending: Vec<(u64, Box<Share>)> = Vec::new();
    let mut last_live: Option<Vec<bool>> = None;
    let mut live_now: Vec<bool> = Vec::with_capacity(neighbours.len());
    let mut out = ShareOut::default();
    let mut row = Vec::with_capacity(columns.len());
    let mut waiter = Waiter::new(t, p, id);

    // Step `algo` from `u`'s shares: for each neighbour live at u, the newest share that has
    // arrived by u, else its last valid one (held, its age recorded); a dead one is left out.
    let advance = |algo: &mut dyn Algorithm, inbox: &mut AgentInbox, u: Option<u64>, report: &mut ProcessReport| {
        let Some(u) = u else {
            algo.step(p.dt_s, &[]); // link delay, step 0: nothing heard yet
            return;
        };
        for peer in &mut inbox.peers {
            let live = live_at(&peer.hist, u);
            let Peer { id, arrived, spare, held, tokens, .. } = peer;
            let mut newest: Option<(u64, Vec<f64>)> = None;
            tokens.retain(|s| *s > u);
            arrived.retain_mut(|(s, v)| {
                let due = plan.arrival(*id, *s).is_some_and(|a| a <= u) || *s <= u.saturating_sub(inbox.back);
                if due {
                    let taken = (*s, std::mem::take(v));
                    let replaced = if live && newest.as_ref().is_none_or(|(n, _)| *n < *s) {
                        newest.replace(taken)
                    } else {
                        Some(taken)
                    };
                    spare.extend(replaced.map(|(_, v)| v));
                }
                !due
            });
            if !live {
                spare.extend(newest.map(|(_, v)| v));
                continue;
            }
            match newest {
                Some(n) if held.as_ref().is_none_or(|(h, _)| *h < n.0) => spare.extend(held.replace(n).map(|(_, v)| v)),
                other => {
                    spare.extend(other.map(|(_, v)| v));
                    *report.faults.held.entry(Proc::Agent(*id).name()).or_default() += 1;
                }
            }
            if let Some((s, _)) = &peer.held {
                report.faults.max_age_steps = report.faults.max_age_steps.max(u.saturating_sub(*s));
            }
        }
        let nb: Vec<Neighbour<'_>> = inbox
            .peers
            .iter()
            .filter(|peer| live_at(&peer.hist, u))
            .filter_map(|peer| peer.held.as_ref().map(|(_, v)| Neighbour { id: peer.id, values: v }))
            .collect();
        algo.step(p.dt_s, &nb);
    };
    let result = (|| {
        while k < p.n_steps {
            inbox.k = k;
            inbox.want_measurement = true;
            // With a link delay the neighbours' shares of step k-1 were sent before the plant
            // could send measurement k: one wait, one wakeup.
            let used = k.checked_sub(delay);
            inbox.need_shares = if delay > 0 { used } else { None };
            // The state at the start of step k (after step k−1), before any fault due at k.
            if p.checkpoint_every > 0 && k % p.checkpoint_every == 0 && restore.is_none_or(|c| c.step != k) {
                let ck = Checkpoint {
                    run_id: p.run_id,
                    agent: id,
                    step: k,
                    kind: p.algorithm_kind.clone(),
                    state: AgentState {
                        algorithm: algo.save_state(),
                        held: inbox
                            .peers
                            .iter()
                            .filter_map(|peer| peer.held.as_ref().map(|(s, v)| (peer.id, *s, v.clone())))
                            .collect(),
                    },
                };
                let path = crate::checkpoint::path_for(&p.dirs.root, id);
                ck.write(&path).map_err(io(path.display().to_string()))?;
                report.faults.checkpoints_written += 1;
                tracing::debug!("step {k}: checkpoint written ({})", path.display());
            }

            if hold_steps.binary_search(&k).is_ok() {
                // A process fault may be due now: be found between steps with every row on disk.
                tel.flush().and_then(|_| timing.flush()).map_err(io("agent telemetry"))?;
                waiter.t.report(&status(p, id, STATUS_IDLE, k, 0));
            }
            waiter.until(k, "measurement", &mut inbox, meas_limit)?;
            let m = inbox.meas.take().expect("the wait completed");
            if m.header.step > k {
                // Back on the roster after missing steps (thawed, or relaunched from a
                // checkpoint): propagate through them with the neighbours' last valid shares.
                let back_at = m.header.step;
                // Only what it had before it left: which of the shares sent meanwhile are still
                // queued depends on when it woke (a full queue keeps the newest), so using them
                // would make the run depend on timing.
                for peer in &mut inbox.peers {
                    peer.arrived.retain(|(s, _)| *s >= back_at);
                    peer.tokens.retain(|s| *s >= back_at);
                }
                for s in k..back_at {
                    advance(algo, &mut inbox, s.checked_sub(delay), report);
                    failed(algo.take_failure(), "the algorithm", s, p.t_s(s))?;
                }
                report.faults.steps_missed += back_at - k;
                k = back_at;
                inbox.k = k;
                let used = k.checked_sub(delay);
                inbox.need_shares = if delay > 0 { used } else { None };
                if delay > 0 {
                    inbox.want_measurement = false;
                    waiter.until(k, "share", &mut inbox, share_limit)?;
                }
            }
            let t_s = p.t_s(k);
            live_now.clear();
            live_now.extend(inbox.peers.iter().map(|peer| live_at(&peer.hist, k)));
            if last_live.as_ref() != Some(&live_now) {
                algo.roster(&live_now);
                last_live = Some(live_now.clone());
            }
            let compute_start = monotonic_ns();
            out.command.clear();
            out.values.clear();
            algo.share(&AgentInput { k, t_s, readings: m.readings() }, &mut out);
            failed(algo.take_failure(), "the algorithm", k, t_s)?;
            if !out.command.iter().all(|x| x.is_finite()) {
                return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "command".into() });
            }
            if !out.values.iter().all(|x| x.is_finite()) {
                return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "share value".into() });
            }
            // Late shares due now go out first; then this step's, as the fault plan says.
            let mut i = 0;
            while i < pending.len() {
                if pending[i].0 <= k {
                    let (_, s) = pending.swap_remove(i);
                    send_share(waiter.t, p, &s)?;
                    report.messages_sent += 1;
                } else {
                    i += 1;
                }
            }
            let share = Share::new(Header::new(p.run_id, id, k, t_s), &out.command, &out.values);
            let fate = plan.fate(id, k);
            match fate {
                Fate::Deliver => {
                    send_share(waiter.t, p, &share)?;
                    report.messages_sent += 1;
                }
                Fate::Delay(n) => {
                    report.faults.shares_delayed += 1;
                    pending.push((k + u64::from(n), Box::new(share)));
                }
                Fate::Drop => report.faults.shares_dropped += 1,
                Fate::Corrupt(how) => {
                    *report.faults.shares_corrupted.entry(how.name().to_string()).or_default() += 1;
                    let mut garbled = share;
                    corrupt(&mut garbled, how);
                    send_share(waiter.t, p, &garbled)?;
                    report.messages_sent += 1;
                }
            }
            if fate != Fate::Deliver {
                // The step token: lockstep goes on without the share (see `LINK_LOST`).
                let mut token = Share::new(share.header, &[], &[]);
                token.link = LINK_LOST;
                send_share(waiter.t, p, &token)?;
                report.messages_sent += 1;
            }
            let mut compute_ns = monotonic_ns() - compute_start;
            // Formatting the row overlaps the wait for the neighbours' shares.
            if p.writes_row(k) {
                row.clear();
                row.push(t_s);
                algo.row(&mut row);
                failed(algo.take_failure(), "the algorithm", k, t_s)?;
                tel.row(k, &row).map_err(io("agent telemetry"))?;
            }

            let wait_start = monotonic_ns();
            if delay == 0 {
                inbox.want_measurement = false;
                inbox.need_shares = Some(k);
                waiter.until(k, "share", &mut inbox, share_limit)?;
            }
            let neighbour_wait_ns = monotonic_ns() - wait_start;

            let step_start = monotonic_ns();
            advance(algo, &mut inbox, used, report);
            failed(algo.take_failure(), "the algorithm", k, t_s)?;
            compute_ns += monotonic_ns() - step_start;
            timing.row(k, &[inbox.meas_latency_ns, neighbour_wait_ns, compute_ns]).map_err(io("agent timing"))?;
            report.steps_completed = k + 1;
            k += 1;
        }
        Ok(())
    })();
    report.timeouts = waiter.timeouts;
    report.wait = waiter.stats;
    report.messages_received = inbox.received;
    report.messages_rejected = reject_map(&inbox.rejects);
    report.received_from.insert("plant".into(), inbox.from_plant);
    report.faults.overrun.insert("plant".into(), inbox.overrun_plant);
    report.latency_from_ns.insert("plant".into(), inbox.latency_plant.buckets());
    for peer in &inbox.peers {
        let name = Proc::Agent(peer.id).name();
        report.received_from.insert(name.clone(), peer.received);
        report.faults.overrun.insert(name.clone(), peer.overrun);
        report.latency_from_ns.insert(name, peer.latency.buckets());
    }
    let flushed = tel.finish().and_then(|_| timing.finish()).map_err(io("agent telemetry"));
    result.and(flushed)
}

#[cfg(test)]
pub(crate) mod tests {
    //! The drivers over the in-memory transport with toy models: two runs agree bit for bit with
    //! each other and with the values the models held in memory, and a silent agent is a timeout
    //! naming it, never a hang.

    use super::*;
    use crate::model::{AgentInput, Neighbour};
    use crate::rng::process_rng;
    use cohort_wire::transport::memory::MemoryBus;
    use cohort_wire::transport::{DataPath, Topology};
    use rand::Rng;
    use std::sync::Mutex;

    /// 1-D integrators ẋ = u, read with uniform noise (also the recording tests' plant).
    pub(crate) struct ToyPlant {
        pub(crate) x: Vec<f64>,
        pub(crate) u: Vec<f64>,
    }
    impl PlantModel for ToyPlant {
        fn columns(&self) -> Vec<String> {
            (1..=self.x.len()).map(|i| format!("x{i}")).collect()
        }
        fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
            out.push(self.x[agent as usize - 1] + rng.random::<f64>() * 1e-3);
        }
        fn apply_command(&mut self, agent: u32, command: &[f64]) {
            self.u[agent as usize - 1] = command.first().copied().unwrap_or(0.0);
        }
        fn advance(&mut self, dt_s: f64) {
            for (x, u) in self.x.iter_mut().zip(&self.u) {
                *x += u * dt_s;
            }
        }
        fn row(&self, out: &mut Vec<f64>) {
            out.extend_from_slice(&self.x);
        }
        fn metrics(&self) -> Vec<(String, f64)> {
            vec![]
        }
    }

    /// Average consensus: u = Σ (x̂ⱼ − y). Records every value it shares.
    struct ToyAgent {
        y: f64,
        nbr: Vec<f64>,
        shared: Arc<Mutex<Vec<f64>>>,
    }
    impl Algorithm for ToyAgent {
        fn columns(&self) -> Vec<String> {
            vec!["y".into(), "u".into()]
        }
        fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
            self.y = input.readings[0];
            let u: f64 = self.nbr.iter().map(|x| x - self.y).sum::<f64>() * 0.7;
            out.command.push(u);
            out.values.push(self.y);
            self.shared.lock().unwrap().extend([self.y, u]);
        }
        fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
            self.nbr = neighbours.iter().map(|n| n.values[0]).collect();
        }
        fn row(&self, out: &mut Vec<f64>) {
            let u: f64 = self.nbr.iter().map(|x| x - self.y).sum::<f64>() * 0.7;
            out.extend([self.y, u]);
        }
        fn save_state(&self) -> Vec<u8> {
            crate::checkpoint::encode_state(&(self.y, &self.nbr))
        }
        fn restore_state(&mut self, bytes: &[u8]) -> Result<(), String> {
            (self.y, self.nbr) = crate::checkpoint::decode_state(bytes)?;
            Ok(())
        }
    }

    fn params(dir: &std::path::Path, n_steps: u64, timeout: Duration) -> DriveParams {
        let dirs = RunDirs::new(dir);
        dirs.create_all().unwrap();
        DriveParams::basic(99, n_steps, 0.1, timeout, dirs)
    }

    #[derive(Default)]
    struct Setup {
        silent: Option<u32>,
        abort: bool,
        faults: Vec<cohort_scenario::faults::FaultSpec>,
        /// run.authenticate: the run's key, and a process (0: the plant) whose messages carry
        /// another one (as if damaged in place, or forged).
        key: Option<MacKey>,
        wrong_key: Option<u32>,
        /// A measurement to slip into agent 1's inbox before the run starts.
        inject: Option<Measurement>,
        /// `run.telemetry_every_steps` (0 taken as 1).
        telemetry_every: u64,
    }

    /// Run 4 agents on a ring; returns (plant report, agent reports, in-memory shared values).
    fn run(dir: &std::path::Path, setup: Setup) -> (ProcessReport, Vec<ProcessReport>, Vec<Vec<f64>>) {
        let topo = Topology { neighbours: vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]] };
        let bus = MemoryBus::new(topo.clone());
        let silent = setup.silent;
        let quick = silent.is_some() || setup.wrong_key.is_some();
        let mut p = params(dir, 50, Duration::from_millis(if quick { 300 } else { 20_000 }));
        p.degrade = !setup.abort;
        // These tests read the rows as text; the Parquet writer has its own tests.
        p.telemetry = cohort_scenario::TelemetryFormat::Csv;
        p.faults = Arc::new(FaultPlan::new(&setup.faults, 11, p.dt_s));
        p.key = setup.key;
        let mut forged = p.clone();
        forged.key = Some(MacKey::from_bytes([0xEE; 32]));
        if let Some(m) = &setup.inject {
            bus.endpoint(Proc::Plant).send_measurement(1, m).unwrap();
        }
        p.telemetry_every = setup.telemetry_every.max(1);
        let shared: Vec<Arc<Mutex<Vec<f64>>>> = (0..4).map(|_| Arc::new(Mutex::new(Vec::new()))).collect();
        std::thread::scope(|sc| {
            let plant = {
                let p = if setup.wrong_key == Some(0) { &forged } else { &p };
                let bus = &bus;
                sc.spawn(move || {
                    let mut t = bus.endpoint(Proc::Plant);
                    let mut m = ToyPlant { x: vec![1.0, -2.0, 3.5, 0.25], u: vec![0.0; 4] };
                    let mut rng = process_rng(5, Proc::Plant);
                    let r = run_plant(&mut t, &mut m, &mut rng, 4, p);
                    if r.error.is_some() {
                        // As the reference run does: the others stop at their next wait.
                        bus.request_stop();
                    }
                    r
                })
            };
            let agents: Vec<_> = (1..=4u32)
                .filter(|&i| Some(i) != silent)
                .map(|i| {
                    let p = if setup.wrong_key == Some(i) { &forged } else { &p };
                    let (bus, topo, sh) = (&bus, &topo, Arc::clone(&shared[i as usize - 1]));
                    sc.spawn(move || {
                        let mut t = bus.endpoint(Proc::Agent(i));
                        let mut a = ToyAgent { y: 0.0, nbr: vec![], shared: sh };
                        run_agent(&mut t, &mut a, i, topo.neighbours_of(i), p, None)
                    })
                })
                .collect();
            let pr = plant.join().unwrap();
            let ars = agents.into_iter().map(|h| h.join().unwrap()).collect();
            (pr, ars, shared.iter().map(|s| s.lock().unwrap().clone()).collect())
        })
    }

    #[test]
    fn two_in_memory_runs_agree_bit_for_bit_with_memory_and_with_each_other() {
        let base = std::env::temp_dir().join(format!("cohort-drive-{}", std::process::id()));
        let (a, b) = (base.join("a"), base.join("b"));
        let (pa, ra, sa) = run(&a, Setup::default());
        let (pb, _, sb) = run(&b, Setup::default());
        assert!(pa.error.is_none() && pb.error.is_none(), "{:?} {:?}", pa.error, pb.error);
        assert!(ra.iter().all(|r| r.error.is_none() && r.steps_completed == 50));
        // The values each agent held in memory are exactly what its telemetry says.
        for i in 1..=4usize {
            let text = std::fs::read_to_string(a.join(format!("telemetry/agent-{i}.csv"))).unwrap();
            let from_csv: Vec<u64> = text
                .lines()
                .skip(1)
                .flat_map(|l| l.split(',').skip(2).map(|v| v.parse::<f64>().unwrap().to_bits()).collect::<Vec<_>>())
                .collect();
            let in_memory: Vec<u64> = sa[i - 1].iter().map(|x| x.to_bits()).collect();
            assert_eq!(from_csv, in_memory, "agent {i}");
            assert_eq!(
                sa[i - 1].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                sb[i - 1].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                "agent {i}: runs differ"
            );
        }
        let pa_csv = std::fs::read(a.join("telemetry/plant.csv")).unwrap();
        let pb_csv = std::fs::read(b.join("telemetry/plant.csv")).unwrap();
        assert_eq!(pa_csv, pb_csv);
        // The consensus actually ran (values moved toward each other), so equality is not vacuous.
        let last = String::from_utf8(pa_csv).unwrap().lines().last().unwrap().to_string();
        let xs: Vec<f64> = last.split(',').skip(2).map(|v| v.parse().unwrap()).collect();
        let spread = xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread < 1.0, "spread {spread} (started at 5.5)");
        let _ = std::fs::remove_dir_all(&base);
    }

    /// `run.telemetry_every_steps`: rows at k = 0, n, 2n, … and the last step, each equal to
    /// the same step's row of a run that writes every step (the models run every step either way).
    #[test]
    fn a_telemetry_stride_keeps_every_nth_row_and_the_last_unchanged() {
        let base = std::env::temp_dir().join(format!("cohort-drive-stride-{}", std::process::id()));
        let (all, every7) = (base.join("all"), base.join("every7"));
        let (pa, _, _) = run(&all, Setup::default());
        let (pb, rb, _) = run(&every7, Setup { telemetry_every: 7, ..Default::default() });
        assert!(pa.error.is_none() && pb.error.is_none() && rb.iter().all(|r| r.error.is_none()));
        for f in ["plant.csv", "agent-1.csv", "agent-4.csv"] {
            let full = std::fs::read_to_string(all.join("telemetry").join(f)).unwrap();
            let strided = std::fs::read_to_string(every7.join("telemetry").join(f)).unwrap();
            let (mut full, mut strided) = (full.lines(), strided.lines());
            assert_eq!(full.next(), strided.next(), "{f}: header");
            let want: Vec<&str> = full
                .filter(|l| l.split(',').next().unwrap().parse::<u64>().unwrap() % 7 == 0 || l.starts_with("49,"))
                .collect();
            let got: Vec<&str> = strided.collect();
            let ks: Vec<&str> = got.iter().map(|l| l.split(',').next().unwrap()).collect();
            assert_eq!(ks, ["0", "7", "14", "21", "28", "35", "42", "49"], "{f}");
            assert_eq!(got, want, "{f}");
        }
        // Timing keeps every step.
        let timing = std::fs::read_to_string(every7.join("timing/plant.csv")).unwrap();
        assert_eq!(timing.lines().count(), 51);
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_silent_agent_is_a_timeout_naming_it_not_a_hang() {
        let base = std::env::temp_dir().join(format!("cohort-drive-silent-{}", std::process::id()));
        let started = Instant::now();
        let (pr, _, _) = run(&base, Setup { silent: Some(3), abort: true, ..Default::default() });
        let err = pr.error.expect("the plant must fail").message;
        assert!(err.contains("timeout at step 0") && err.contains("agent 3"), "{err}");
        assert!(started.elapsed() < Duration::from_secs(30));
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn degrade_mode_marks_a_silent_agent_dead_and_finishes_without_it() {
        let base = std::env::temp_dir().join(format!("cohort-drive-degrade-{}", std::process::id()));
        let (pr, ars, _) = run(&base, Setup { silent: Some(3), ..Default::default() });
        assert!(pr.error.is_none(), "{:?}", pr.error);
        assert_eq!(pr.steps_completed, 50);
        assert_eq!(pr.faults.roster.len(), 1, "{:?}", pr.faults.roster);
        let c = &pr.faults.roster[0];
        assert_eq!((c.step, c.agent, c.live, c.reason.as_str()), (0, 3, false, "silent"));
        assert!(ars.iter().all(|r| r.error.is_none() && r.steps_completed == 50), "{ars:?}");
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn an_authenticated_run_is_bit_identical_and_a_wrongly_keyed_plant_is_named_as_rejected() {
        // Issue 18, finding 6: a message that fails its MAC is counted, the wait goes on, and the
        // run's error names the process whose message was rejected (not "went silent").
        let base = std::env::temp_dir().join(format!("cohort-drive-mac-{}", std::process::id()));
        let key = Some(MacKey::from_bytes([5; 32]));
        let (plain, _, sp) = run(&base.join("plain"), Setup::default());
        let (sealed, ra, ss) = run(&base.join("sealed"), Setup { key, ..Default::default() });
        assert!(plain.error.is_none() && sealed.error.is_none(), "{:?}", sealed.error);
        let bits = |v: &Vec<Vec<f64>>| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&sp), bits(&ss), "the MAC changed the results");
        assert!(ra.iter().chain([&sealed]).all(|r| r.messages_rejected.values().sum::<u64>() == 0));
        // Every measurement fails its tag: each agent counts it, waits on, and ends naming the
        // plant's rejected message as the reason it got nothing.
        let (pr, ars, _) = run(&base.join("forged"), Setup { key, wrong_key: Some(0), ..Default::default() });
        assert!(pr.error.is_none(), "degrade mode: the plant goes on without the agents: {:?}", pr.error);
        for a in &ars {
            let err = &a.error.as_ref().expect("the agent must time out").message;
            assert!(err.contains("from the plant (its latest message was rejected: mac"), "{err}");
            assert!(a.messages_rejected.get("mac").copied().unwrap_or(0) >= 1, "{:?}", a.messages_rejected);
        }
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_measurement_naming_a_step_past_the_run_is_rejected_not_propagated_through() {
        // Issue 18, finding 6: a step read from a message was trusted as a loop bound (an agent
        // would have propagated through 2^40 steps).
        let base = std::env::temp_dir().join(format!("cohort-drive-far-{}", std::process::id()));
        let far = Measurement::new(Header::new(99, PLANT_ID, 1 << 40, 1e9), &[0.0]);
        let (pr, ars, _) = run(&base, Setup { inject: Some(far), ..Default::default() });
        assert!(pr.error.is_none() && ars.iter().all(|r| r.error.is_none()), "{pr:?} {ars:?}");
        assert_eq!(ars[0].steps_completed, 50);
        assert_eq!(ars[0].messages_rejected.get("step"), Some(&1), "{:?}", ars[0].messages_rejected);
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn contention_backs_off_while_stalls_are_common_and_forgets_a_lone_one() {
        let blocked = |c: &mut Contention| (0..10_000).take_while(|_| !c.may_spin()).count();
        let mut c = Contention::default();
        assert!(c.may_spin());
        c.spun(true);
        assert_eq!(blocked(&mut c), BACKOFF_MIN as usize);
        c.spun(true);
        assert_eq!(blocked(&mut c), (BACKOFF_GROWTH * BACKOFF_MIN) as usize);
        // Sustained contention where every other spin stalls still grows the gap to its maximum.
        for _ in 0..20 {
            c.spun(false);
            c.spun(true);
        }
        assert_eq!(blocked(&mut c), BACKOFF_MAX as usize);
        // A lone stall on an idle machine: a few clean spins forget it.
        let mut c = Contention::default();
        c.spun(true);
        for _ in 0..5 {
            c.spun(false);
        }
        c.spun(true);
        assert_eq!(blocked(&mut c), BACKOFF_MIN as usize);
        assert_eq!(c.stalls, 2);
    }

    #[test]
    fn wait_stats_count_spins_stalls_and_expiries() {
        let mut w = WaitStats::default();
        w.count(false, false, false, Duration::ZERO);
        w.count(true, false, false, Duration::from_micros(30));
        w.count(true, true, true, Duration::from_millis(2));
        w.count(true, false, true, Duration::from_micros(80));
        assert_eq!((w.waits, w.spun, w.spin_stalls, w.spin_expired), (4, 3, 1, 1));
        assert!((w.spin_s - 2.11e-3).abs() < 1e-12, "{}", w.spin_s);
    }

    fn fault(kind: &str, agent: u32, t_s: f64) -> cohort_scenario::faults::FaultSpec {
        cohort_scenario::faults::FaultSpec { kind: kind.into(), agent, t_s, for_s: None, p: None, delay_steps: None }
    }

    #[test]
    fn link_faults_are_deterministic_and_every_lost_share_is_counted() {
        let base = std::env::temp_dir().join(format!("cohort-drive-links-{}", std::process::id()));
        let faults = || {
            let mut drop = fault("drop", 2, 0.5);
            drop.p = Some(0.3);
            let mut corrupt = fault("corrupt", 4, 0.0);
            corrupt.p = Some(0.3);
            let mut delay = fault("delay", 1, 1.0);
            (delay.delay_steps, delay.for_s) = (Some(2), Some(2.0));
            vec![drop, corrupt, delay]
        };
        let (pa, ra, sa) = run(&base.join("a"), Setup { faults: faults(), ..Default::default() });
        let (pb, _, sb) = run(&base.join("b"), Setup { faults: faults(), ..Default::default() });
        assert!(pa.error.is_none() && ra.iter().all(|r| r.error.is_none()), "{pa:?} {ra:?}");
        let bits = |v: &Vec<Vec<f64>>| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&sa), bits(&sb), "two runs with the same plan differ");
        assert_eq!(pa.faults, pb.faults);
        let by = |id: u32| &ra[id as usize - 1].faults;
        let dropped = by(2).shares_dropped;
        let corrupted: u64 = by(4).shares_corrupted.values().sum();
        assert!(dropped > 3 && corrupted > 3, "too few faults drawn: {dropped} {corrupted}");
        assert_eq!(by(1).shares_delayed, 20);
        // The plant holds a command for every lost share, and for the two steps at the start of
        // the delay window when nothing of agent 1 arrives.
        assert_eq!(pa.faults.held.get("agent-2"), Some(&dropped));
        assert_eq!(pa.faults.held.get("agent-4"), Some(&corrupted));
        assert_eq!(pa.faults.held.get("agent-1"), Some(&2));
        // Every garbled share was rejected, for the reason it was garbled, by each of its readers.
        for reader in [&pa, &ra[0], &ra[2]] {
            for (why, n) in &by(4).shares_corrupted {
                assert_eq!(reader.messages_rejected.get(why), Some(n), "{} rejects {why}", reader.process);
            }
        }
        assert_eq!(pa.messages_rejected.values().sum::<u64>(), corrupted);
        // The other agents used agent 2's last valid share in place of each dropped one.
        assert_eq!(ra[0].faults.held.get("agent-2"), Some(&dropped));
        assert_eq!(ra[2].faults.held.get("agent-2"), Some(&dropped));
        assert_eq!(ra[1].faults.max_age_steps, 2, "agent 2 used agent 1's shares 2 steps late");
        let _ = std::fs::remove_dir_all(&base);
    }
}
