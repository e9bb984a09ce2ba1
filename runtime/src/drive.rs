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

use cohort_wire::msg::{
    Header, Measurement, PLANT_ID, SCHEMA_VERSION, STATUS_DONE, STATUS_PROGRESS, STATUS_READY, STATUS_WAITING, Share,
    Status,
};
use cohort_wire::transport::{Incoming, Proc, Transport, TransportError, monotonic_ns};
use cohort_wire::validate::{Expect, RejectCounts, Rejection, validate_measurement, validate_share};
use rand_chacha::ChaCha8Rng;

use crate::model::{AgentInput, Algorithm, Neighbour, PlantModel, ShareOut};
use crate::record::{CsvWriter, ProcessReport, RunDirs, reject_map};

/// Longest single blocking wait before re-polling.
const POLL: Duration = Duration::from_millis(10);
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
    /// How a wait spins before it blocks on the event; see [`spin_budget`].
    pub spin: SpinPolicy,
    /// 1: agents advance with their neighbours' shares of the previous step (`run.link_delay_steps`).
    pub link_delay_steps: u32,
    /// `run.realtime_rate`: the plant paces steps by the wall clock.
    pub realtime_rate: Option<f64>,
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
    Adaptive,
}

/// Spin policy for `run.wait`.
pub fn spin_budget(run: &cohort_scenario::RunSettings) -> SpinPolicy {
    match run.wait.as_str() {
        "event" => SpinPolicy::Fixed(Duration::ZERO),
        "poll" => SpinPolicy::Fixed(Duration::from_secs_f64(run.step_timeout_s)),
        _ => match run.spin_us {
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
/// Weight of the newest wait in the running typical wait.
const ADAPTIVE_EWMA: f64 = 0.1;
/// Spin for up to this many typical waits.
const ADAPTIVE_MARGIN: f64 = 4.0;

impl DriveParams {
    fn t_s(&self, k: u64) -> f64 {
        // Sim time from the step index, never accumulated, so every process agrees exactly.
        k as f64 * self.dt_s
    }
}

/// What a process collects while it waits: it takes each incoming message, says when the wait
/// is over, and names whom it still lacks.
trait Inbox {
    fn take(&mut self, inc: Incoming<'_>);
    fn complete(&self) -> bool;
    /// (id, description) of the first peer still missing.
    fn missing(&self) -> (u32, String);
}

struct Waiter<'a, T: Transport + ?Sized> {
    t: &'a mut T,
    p: &'a DriveParams,
    me: u32,
    timeouts: u64,
    /// Running typical wait, µs, per kind of wait (measurement, share): adaptive spinning.
    typical_wait_us: [f64; 2],
}

impl<T: Transport + ?Sized> Waiter<'_, T> {
    /// Drain into `inbox`, check it, wait briefly; repeat until it is complete or the step
    /// timeout passes.
    fn spin_for(&self, kind: usize) -> Duration {
        let typical = self.typical_wait_us[kind];
        match self.p.spin {
            SpinPolicy::Fixed(d) => d,
            SpinPolicy::Adaptive if typical > ADAPTIVE_CAP_US => Duration::ZERO,
            SpinPolicy::Adaptive => {
                Duration::from_secs_f64((ADAPTIVE_MARGIN * typical).clamp(ADAPTIVE_FLOOR_US, ADAPTIVE_CAP_US) * 1e-6)
            }
        }
    }

    fn until(&mut self, step: u64, what: &'static str, inbox: &mut impl Inbox) -> Result<(), RunError> {
        let started = Instant::now();
        let kind = usize::from(what == "share");
        let spin = self.spin_for(kind);
        let mut reported = false;
        let mut spins = 0u32;
        loop {
            self.t.drain(&mut |inc| inbox.take(inc))?;
            if inbox.complete() {
                let w = started.elapsed().as_secs_f64() * 1e6;
                self.typical_wait_us[kind] += ADAPTIVE_EWMA * (w - self.typical_wait_us[kind]);
                return Ok(());
            }
            let waited = started.elapsed();
            if waited >= self.p.step_timeout {
                self.timeouts += 1;
                let (_, from) = inbox.missing();
                return Err(RunError::Timeout { step, from, what, after_s: waited.as_secs_f64() });
            }
            let spinning = waited < spin;
            spins = spins.wrapping_add(1);
            // While spinning, look at the control service only now and then: it is not free.
            if !spinning || spins.is_multiple_of(1024) {
                if self.t.stop_requested() {
                    return Err(RunError::Stopped { step, why: "orchestrator" });
                }
                if self.p.terminate.load(Ordering::Relaxed) {
                    return Err(RunError::Stopped { step, why: "SIGTERM" });
                }
                if !reported && waited >= REPORT_WAITING_AFTER {
                    reported = true;
                    let (id, _) = inbox.missing();
                    let s = status(self.p, self.me, STATUS_WAITING, step, id);
                    self.t.report(&s);
                }
            }
            if spinning {
                std::thread::yield_now();
            } else {
                self.t.wait(POLL.min(self.p.step_timeout - waited))?;
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
        solver: None,
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
        report.error = Some(e.to_string());
    } else {
        t.report(&status(p, PLANT_ID, STATUS_DONE, p.n_steps, 0));
    }
    report
}

/// The plant's inbox for step k: every agent's command.
struct PlantInbox {
    run_id: u64,
    k: u64,
    commands: Vec<Vec<f64>>,
    got: Vec<bool>,
    n_got: usize,
    latency_max_ns: u64,
    received: u64,
    rejects: RejectCounts,
}

impl PlantInbox {
    fn reset(&mut self, k: u64) {
        self.k = k;
        self.got.iter_mut().for_each(|g| *g = false);
        self.n_got = 0;
        self.latency_max_ns = 0;
    }
}

impl Inbox for PlantInbox {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        let Incoming::Share { from, share } = inc else {
            self.rejects.add(Rejection::Sender); // the plant reads no measurements
            return;
        };
        let e = Expect { run_id: self.run_id, sender: from, step_min: self.k, step_max: self.k };
        match validate_share(share, &e) {
            Ok(()) => {
                let idx = (from - 1) as usize;
                if !self.got[idx] {
                    self.got[idx] = true;
                    self.n_got += 1;
                    self.commands[idx].clear();
                    self.commands[idx].extend_from_slice(share.command());
                    let latency = monotonic_ns().saturating_sub(share.header.sent_wall_ns);
                    self.latency_max_ns = self.latency_max_ns.max(latency);
                }
            }
            Err(r) => self.rejects.add(r),
        }
    }
    fn complete(&self) -> bool {
        self.n_got == self.got.len()
    }
    fn missing(&self) -> (u32, String) {
        let id = self.got.iter().position(|g| !g).map_or(0, |i| i as u32 + 1);
        (id, format!("agent {id}"))
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
    let tel_path = p.dirs.telemetry().join("plant.csv");
    let mut tel = CsvWriter::create(&tel_path, &columns).map_err(io(tel_path.display().to_string()))?;
    let tim_path = p.dirs.timing().join("plant.csv");
    let mut timing = CsvWriter::create(&tim_path, &["k".into(), "round_ns".into(), "share_latency_max_ns".into()])
        .map_err(io(tim_path.display().to_string()))?;

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
    let mut inbox = PlantInbox {
        run_id: p.run_id,
        k: 0,
        commands: vec![Vec::new(); n],
        got: vec![false; n],
        n_got: 0,
        latency_max_ns: 0,
        received: 0,
        rejects: RejectCounts::default(),
    };
    let mut row = Vec::with_capacity(columns.len());
    let mut waiter = Waiter { t, p, me: PLANT_ID, timeouts: 0, typical_wait_us: [0.0; 2] };
    let mut last_progress = Instant::now();
    // Measurements of step k go out as soon as the truth reaches tₖ; the telemetry row of step
    // k-1 is formatted afterwards, while the agents compute, so it stays off the critical path.
    let send_measurements = |t: &mut T, model: &mut dyn PlantModel, rng: &mut ChaCha8Rng, k: u64| {
        let mut readings = Vec::with_capacity(64);
        for i in 1..=n_agents {
            readings.clear();
            model.readings(i, rng, &mut readings);
            if !readings.iter().all(|x| x.is_finite()) {
                let what = format!("reading for agent {i}");
                return Err(RunError::Diverged { step: k, t_s: p.t_s(k), who: "the plant model", what });
            }
            let m = Measurement::new(Header::new(p.run_id, PLANT_ID, k, p.t_s(k)), &readings);
            t.send_measurement(i, &m)?;
        }
        Ok::<(), RunError>(())
    };
    let paced_from = Instant::now();
    let result = (|| {
        let mut round_start = monotonic_ns();
        if p.n_steps > 0 {
            send_measurements(waiter.t, model, rng, 0)?;
        }
        for k in 0..p.n_steps {
            let t_s = p.t_s(k);
            inbox.reset(k);
            waiter.until(k, "share", &mut inbox)?;
            for (i, u) in inbox.commands.iter().enumerate() {
                model.apply_command(i as u32 + 1, u);
            }
            row.clear();
            row.push(t_s);
            model.row(&mut row);
            let round_ns = monotonic_ns() - round_start;
            model.advance(p.dt_s);
            if let Some(rate) = p.realtime_rate {
                // Real-time pacing: step k+1 starts no earlier than (k+1)·dt/rate after step 0.
                let due = paced_from + Duration::from_secs_f64((k + 1) as f64 * p.dt_s / rate);
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
            }
            round_start = monotonic_ns();
            if k + 1 < p.n_steps {
                send_measurements(waiter.t, model, rng, k + 1)?;
            }
            tel.row(k, &row).map_err(io("plant telemetry"))?;
            timing.row_u64(&[k, round_ns, inbox.latency_max_ns]).map_err(io("plant timing"))?;
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
    report.messages_received = inbox.received;
    report.messages_rejected = reject_map(&inbox.rejects);
    // Never lose telemetry: flush whatever was written, also after an error.
    let flushed = tel.flush().and_then(|_| timing.flush()).map_err(io("plant telemetry"));
    result.and(flushed)
}

/// Run agent `id`'s side of every step.
pub fn run_agent<T: Transport + ?Sized>(
    t: &mut T,
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    p: &DriveParams,
) -> ProcessReport {
    let me = Proc::Agent(id);
    let mut report = new_report(me, p);
    let started = Instant::now();
    let result = agent_loop(t, algo, id, neighbours, p, &mut report);
    report.wall_s = started.elapsed().as_secs_f64();
    report.solver = algo.solver_stats();
    (report.cpu_s, report.max_rss_kb) = crate::record::cpu_and_rss();
    if let Err(e) = result {
        report.error = Some(e.to_string());
    } else {
        t.report(&status(p, id, STATUS_DONE, p.n_steps, 0));
    }
    report
}

/// A neighbour's shares of step k and k+1 (it may be one step ahead), by step parity.
#[derive(Default, Clone)]
struct Slots {
    step: [Option<u64>; 2],
    values: [Vec<f64>; 2],
}

/// An agent's inbox for step k: the plant's measurement, then every neighbour's share.
struct AgentInbox<'a> {
    run_id: u64,
    k: u64,
    neighbours: &'a [u32],
    /// Waiting for the measurement of step k (true), or past it (false).
    want_measurement: bool,
    /// The neighbours' step whose shares complete this wait, if any.
    need_shares: Option<u64>,
    /// `run.link_delay_steps`.
    delay: u64,
    meas: Option<Box<Measurement>>,
    meas_latency_ns: u64,
    slots: Vec<Slots>,
    received: u64,
    rejects: RejectCounts,
}

impl Inbox for AgentInbox<'_> {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        match inc {
            Incoming::Measurement(m) => {
                // Once every share of step k is in, the plant may already send step k+1's
                // measurement while this agent still waits for a neighbour: keep it.
                let want = if self.want_measurement { self.k } else { self.k + 1 };
                let e = Expect { run_id: self.run_id, sender: PLANT_ID, step_min: want, step_max: want };
                match validate_measurement(m, &e) {
                    // A duplicate is harmless: the first one counts.
                    Ok(()) if self.meas.is_none() => {
                        self.meas_latency_ns = monotonic_ns().saturating_sub(m.header.sent_wall_ns);
                        self.meas = Some(Box::new(*m));
                    }
                    Ok(()) => {}
                    Err(r) => self.rejects.add(r),
                }
            }
            Incoming::Share { from, share } => {
                let Some(slot) = self.neighbours.iter().position(|&j| j == from) else {
                    self.rejects.add(Rejection::Sender);
                    return;
                };
                // A neighbour may be one step ahead; with a link delay, last step's share is
                // still wanted too.
                let e = Expect {
                    run_id: self.run_id,
                    sender: from,
                    step_min: self.k.saturating_sub(self.delay),
                    step_max: self.k + 1,
                };
                match validate_share(share, &e) {
                    Ok(()) => {
                        let s = &mut self.slots[slot];
                        let par = (share.header.step % 2) as usize;
                        if s.step[par] != Some(share.header.step) {
                            s.step[par] = Some(share.header.step);
                            s.values[par].clear();
                            s.values[par].extend_from_slice(share.values());
                        }
                    }
                    Err(r) => self.rejects.add(r),
                }
            }
        }
    }
    fn complete(&self) -> bool {
        let have = |u: u64| self.slots.iter().all(|s| s.step[(u % 2) as usize] == Some(u));
        (!self.want_measurement || self.meas.is_some()) && self.need_shares.is_none_or(have)
    }
    fn missing(&self) -> (u32, String) {
        if self.want_measurement && self.meas.is_none() {
            return (PLANT_ID, "the plant".into());
        }
        let u = self.need_shares.unwrap_or(self.k);
        let j = self.slots.iter().position(|s| s.step[(u % 2) as usize] != Some(u)).map_or(0, |i| self.neighbours[i]);
        (j, format!("neighbour agent {j}"))
    }
}

fn agent_loop<T: Transport + ?Sized>(
    t: &mut T,
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    p: &DriveParams,
    report: &mut ProcessReport,
) -> Result<(), RunError> {
    let name = Proc::Agent(id).name();
    let mut columns = vec!["k".to_string(), "t_s".to_string()];
    columns.extend(algo.columns());
    let tel_path = p.dirs.telemetry().join(format!("{name}.csv"));
    let mut tel = CsvWriter::create(&tel_path, &columns).map_err(io(tel_path.display().to_string()))?;
    let tim_path = p.dirs.timing().join(format!("{name}.csv"));
    let mut timing = CsvWriter::create(
        &tim_path,
        &["k".into(), "meas_latency_ns".into(), "neighbour_wait_ns".into(), "compute_ns".into()],
    )
    .map_err(io(tim_path.display().to_string()))?;

    let mut inbox = AgentInbox {
        run_id: p.run_id,
        k: 0,
        neighbours,
        want_measurement: true,
        need_shares: None,
        delay: u64::from(p.link_delay_steps),
        meas: None,
        meas_latency_ns: 0,
        slots: vec![Slots::default(); neighbours.len()],
        received: 0,
        rejects: RejectCounts::default(),
    };
    let mut out = ShareOut::default();
    let mut row = Vec::with_capacity(columns.len());
    let mut waiter = Waiter { t, p, me: id, timeouts: 0, typical_wait_us: [0.0; 2] };
    let result = (|| {
        for k in 0..p.n_steps {
            let t_s = p.t_s(k);
            inbox.k = k;
            inbox.want_measurement = true;
            // With a link delay the neighbours' shares of step k-1 were sent before the plant
            // could send measurement k: one wait, one wakeup.
            let used = k.checked_sub(inbox.delay);
            inbox.need_shares = if inbox.delay > 0 { used } else { None };
            waiter.until(k, "measurement", &mut inbox)?;

            let compute_start = monotonic_ns();
            let m = inbox.meas.take().expect("the wait completed");
            out.command.clear();
            out.values.clear();
            algo.share(&AgentInput { k, t_s, readings: m.readings() }, &mut out);
            if !out.command.iter().all(|x| x.is_finite()) {
                return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "command".into() });
            }
            if !out.values.iter().all(|x| x.is_finite()) {
                return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "share value".into() });
            }
            let share = Share::new(Header::new(p.run_id, id, k, t_s), &out.command, &out.values);
            waiter.t.send_share(&share)?;
            let mut compute_ns = monotonic_ns() - compute_start;
            // Formatting the row overlaps the wait for the neighbours' shares.
            row.clear();
            row.push(t_s);
            algo.row(&mut row);
            tel.row(k, &row).map_err(io("agent telemetry"))?;

            let wait_start = monotonic_ns();
            if inbox.delay == 0 {
                inbox.want_measurement = false;
                inbox.need_shares = Some(k);
                waiter.until(k, "share", &mut inbox)?;
            }
            let neighbour_wait_ns = monotonic_ns() - wait_start;

            let step_start = monotonic_ns();
            match used {
                Some(u) => {
                    let par = (u % 2) as usize;
                    let nb: Vec<Neighbour<'_>> = neighbours
                        .iter()
                        .zip(&inbox.slots)
                        .map(|(&j, s)| Neighbour { id: j, values: &s.values[par] })
                        .collect();
                    algo.step(p.dt_s, &nb);
                    drop(nb);
                    for s in &mut inbox.slots {
                        s.step[par] = None;
                    }
                }
                // Link delay, step 0: nothing has been heard yet.
                None => algo.step(p.dt_s, &[]),
            }
            compute_ns += monotonic_ns() - step_start;
            timing.row_u64(&[k, inbox.meas_latency_ns, neighbour_wait_ns, compute_ns]).map_err(io("agent timing"))?;
            report.steps_completed = k + 1;
        }
        Ok(())
    })();
    report.timeouts = waiter.timeouts;
    report.messages_received = inbox.received;
    report.messages_rejected = reject_map(&inbox.rejects);
    let flushed = tel.flush().and_then(|_| timing.flush()).map_err(io("agent telemetry"));
    result.and(flushed)
}

#[cfg(test)]
mod tests {
    //! The drivers over the in-memory transport with toy models: two runs agree bit for bit with
    //! each other and with the values the models held in memory, and a silent agent is a timeout
    //! naming it, never a hang.

    use super::*;
    use crate::model::{AgentInput, Neighbour};
    use crate::rng::process_rng;
    use cohort_wire::transport::Topology;
    use cohort_wire::transport::memory::MemoryBus;
    use rand::Rng;
    use std::sync::Mutex;

    /// 1-D integrators ẋ = u, read with uniform noise.
    struct ToyPlant {
        x: Vec<f64>,
        u: Vec<f64>,
    }
    impl PlantModel for ToyPlant {
        fn columns(&self) -> Vec<String> {
            (1..=self.x.len()).map(|i| format!("x{i}")).collect()
        }
        fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
            out.push(self.x[agent as usize - 1] + rng.random::<f64>() * 1e-3);
        }
        fn apply_command(&mut self, agent: u32, command: &[f64]) {
            self.u[agent as usize - 1] = command[0];
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
    }

    fn params(dir: &std::path::Path, n_steps: u64, timeout: Duration) -> DriveParams {
        let dirs = RunDirs::new(dir);
        dirs.create_all().unwrap();
        DriveParams {
            run_id: 99,
            n_steps,
            dt_s: 0.1,
            step_timeout: timeout,
            dirs,
            terminate: Arc::new(AtomicBool::new(false)),
            process_start: Instant::now(),
            spin: SpinPolicy::Fixed(Duration::ZERO),
            link_delay_steps: 0,
            realtime_rate: None,
        }
    }

    /// Run 4 agents on a ring; returns (plant report, agent reports, in-memory shared values).
    fn run(dir: &std::path::Path, silent: Option<u32>) -> (ProcessReport, Vec<ProcessReport>, Vec<Vec<f64>>) {
        let topo = Topology { neighbours: vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]] };
        let bus = MemoryBus::new(topo.clone());
        let p = params(dir, 50, Duration::from_millis(if silent.is_some() { 300 } else { 20_000 }));
        let shared: Vec<Arc<Mutex<Vec<f64>>>> = (0..4).map(|_| Arc::new(Mutex::new(Vec::new()))).collect();
        std::thread::scope(|sc| {
            let plant = {
                let (bus, p) = (&bus, &p);
                sc.spawn(move || {
                    let mut t = bus.endpoint(Proc::Plant);
                    let mut m = ToyPlant { x: vec![1.0, -2.0, 3.5, 0.25], u: vec![0.0; 4] };
                    let mut rng = process_rng(5, Proc::Plant);
                    let r = run_plant(&mut t, &mut m, &mut rng, 4, p);
                    bus.request_stop();
                    r
                })
            };
            let agents: Vec<_> = (1..=4u32)
                .filter(|&i| Some(i) != silent)
                .map(|i| {
                    let (bus, p, topo, sh) = (&bus, &p, &topo, Arc::clone(&shared[i as usize - 1]));
                    sc.spawn(move || {
                        let mut t = bus.endpoint(Proc::Agent(i));
                        let mut a = ToyAgent { y: 0.0, nbr: vec![], shared: sh };
                        run_agent(&mut t, &mut a, i, topo.neighbours_of(i), p)
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
        let (pa, ra, sa) = run(&a, None);
        let (pb, _, sb) = run(&b, None);
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

    #[test]
    fn a_silent_agent_is_a_timeout_naming_it_not_a_hang() {
        let base = std::env::temp_dir().join(format!("cohort-drive-silent-{}", std::process::id()));
        let started = Instant::now();
        let (pr, _, _) = run(&base, Some(3));
        let err = pr.error.expect("the plant must fail");
        assert!(err.contains("timeout at step 0") && err.contains("agent 3"), "{err}");
        assert!(started.elapsed() < Duration::from_secs(30));
        let _ = std::fs::remove_dir_all(&base);
    }
}
