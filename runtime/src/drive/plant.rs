//! The plant's side of every step: measurements out, every live agent's share in, commands
//! applied, the truth advanced; real-time pacing and the holds for process faults.

use std::time::{Duration, Instant};

use cohort_wire::msg::{
    CONTROL_DEAD, CONTROL_RESUME, Header, Measurement, PLANT_ID, Roster, STATUS_DONE, STATUS_HOLDING, STATUS_PROGRESS,
};
use cohort_wire::transport::{Proc, Transport, monotonic_ns};
use rand_chacha::ChaCha8Rng;
use std::sync::atomic::Ordering;

use super::error::{RunError, failed, io};
use super::files::plant_files;
use super::params::DriveParams;
use super::plant_inbox::{PlantInbox, PlantRoster};
use super::status::{new_report, report_ready, status};
use super::wait::Waiter;
use crate::links::on_plant::PlantLinks;
use crate::model::PlantModel;
use crate::record::{ProcessReport, TelemetryWriter, TimingWriter, reject_map};

/// The plant reports progress at most this often.
const PROGRESS_EVERY: Duration = Duration::from_millis(20);

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
    let result = plant_run(t, model, rng, n_agents, p, &mut report);
    (report.cpu_s, report.max_rss_kb) = crate::record::cpu_and_rss();
    report.pss_kb = crate::record::pss_kb();
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

/// Open the plant's files, wait for the start, run every step, and close (flushing the telemetry
/// also after an error).
fn plant_run<T: Transport + ?Sized>(
    t: &mut T,
    model: &mut dyn PlantModel,
    rng: &mut ChaCha8Rng,
    n_agents: u32,
    p: &DriveParams,
    report: &mut ProcessReport,
) -> Result<(), RunError> {
    let mut driver = PlantDriver::open(t, model, rng, n_agents, p, report)?;
    let result = driver.run(report);
    driver.finish(report, result)
}

/// The plant's loop, one method per phase of a step.
struct PlantDriver<'a, T: Transport + ?Sized> {
    w: Waiter<'a, T>,
    model: &'a mut dyn PlantModel,
    rng: &'a mut ChaCha8Rng,
    p: &'a DriveParams,
    n_agents: u32,
    tel: TelemetryWriter,
    timing: TimingWriter,
    inbox: PlantInbox,
    roster: PlantRoster,
    hold_steps: Vec<u64>,
    /// The command each agent's spacecraft flies: the newest valid one (held when a share is
    /// missing), zero once the agent is dead (its spacecraft coasts).
    commands: Vec<Vec<f64>>,
    /// Real time: when each agent last met its deadline (a silent agent is declared dead after
    /// the step timeout, as in lockstep).
    last_heard: Vec<Instant>,
    row: Vec<f64>,
    last_progress: Instant,
    sent: u64,
    paced_from: Instant,
    round_start: u64,
    loop_start: Instant,
    /// `[links]` model `geometric`: the link model and what it decided lately.
    links: Option<PlantLinks>,
}

impl<'a, T: Transport + ?Sized> PlantDriver<'a, T> {
    /// Create the telemetry and timing files, then wait at the start barrier: nothing is sent
    /// before every reader exists.
    fn open(
        t: &'a mut T,
        model: &'a mut dyn PlantModel,
        rng: &'a mut ChaCha8Rng,
        n_agents: u32,
        p: &'a DriveParams,
        report: &mut ProcessReport,
    ) -> Result<Self, RunError> {
        let mut columns = vec!["k".to_string(), "t_s".to_string()];
        columns.extend(model.columns());
        let links = p.links.as_ref().map(|l| PlantLinks::new(l, p.dt_s, n_agents as usize));
        if links.is_some() {
            columns.extend(crate::links::on_plant::COLUMNS.iter().map(|c| c.to_string()));
        }
        let (tel, timing) = plant_files(p, &columns)?;
        start_barrier(t, p)?;
        report.startup_s = p.process_start.elapsed().as_secs_f64();
        let loop_start = Instant::now();
        let n = n_agents as usize;
        let inbox = PlantInbox::new(p, n);
        let roster = PlantRoster {
            live: Roster::all(n_agents),
            lost_at_close: Roster::EMPTY,
            changes: Vec::new(),
            since: loop_start,
        };
        let hold_steps = p.faults.hold_steps();
        let commands: Vec<Vec<f64>> = vec![Vec::new(); n];
        let last_heard = vec![Instant::now(); n];
        let row = Vec::with_capacity(columns.len());
        let w = Waiter::new(t, p, PLANT_ID);
        let last_progress = Instant::now();
        let paced_from = Instant::now();
        Ok(PlantDriver {
            w,
            model,
            rng,
            p,
            n_agents,
            tel,
            timing,
            inbox,
            roster,
            hold_steps,
            commands,
            last_heard,
            row,
            last_progress,
            sent: 0,
            paced_from,
            round_start: 0,
            loop_start,
            links,
        })
    }

    /// Every step, the measurements of step 0 first.
    fn run(&mut self, report: &mut ProcessReport) -> Result<(), RunError> {
        self.round_start = monotonic_ns();
        if self.p.n_steps > 0 {
            self.send_measurements(0)?;
        }
        for k in 0..self.p.n_steps {
            self.step(k, report)?;
        }
        Ok(())
    }

    /// Step k: wait for the shares, close the step, advance the truth, pace and hold, send the
    /// measurements of k+1, then write step k's rows (measurements of step k go out as soon as
    /// the truth reaches tₖ; the telemetry row of step k-1 is written afterwards, while the agents
    /// compute, so it stays off the critical path).
    fn step(&mut self, k: u64, report: &mut ProcessReport) -> Result<(), RunError> {
        self.begin(k);
        self.await_shares(k)?;
        self.close(k, report)?;
        let round_ns = self.advance(k)?;
        self.pace(k);
        self.hold_if_due(k)?;
        self.round_start = monotonic_ns();
        if k + 1 < self.p.n_steps {
            self.send_measurements(k + 1)?;
        }
        self.write_rows(k, round_ns, report)
    }

    /// Send the measurements of step k to every agent, with the roster.
    fn send_measurements(&mut self, k: u64) -> Result<(), RunError> {
        let p = self.p;
        self.decide_links(k)?;
        let mut readings = Vec::with_capacity(64);
        for i in 1..=self.n_agents {
            readings.clear();
            self.model.readings(i, self.rng, &mut readings);
            failed(self.model.take_failure(), "the plant model", k, p.t_s(k))?;
            if !readings.iter().all(|x| x.is_finite()) {
                let what = format!("reading for agent {i}");
                return Err(RunError::Diverged { step: k, t_s: p.t_s(k), who: "the plant model", what });
            }
            let mut m = Measurement::new(Header::new(p.run_id, PLANT_ID, k, p.t_s(k)), &readings);
            m.live = self.roster.live;
            m.lost_at_close = self.roster.lost_at_close;
            if let Some(l) = &self.links {
                m.set_links(l.codes(i));
            }
            if let Some(k) = &p.key {
                k.seal_measurement(&mut m);
            }
            self.w.t.send_measurement(i, &m)?;
            self.sent += 1;
        }
        self.roster.lost_at_close = Roster::EMPTY;
        Ok(())
    }

    /// Geometric links: what becomes of every share of step k, from the truth at tₖ.
    fn decide_links(&mut self, k: u64) -> Result<(), RunError> {
        let Some(l) = &mut self.links else { return Ok(()) };
        if !l.read_positions(|out| self.model.positions_m(out)) {
            let what = "positions for the link model (links.model = \"geometric\")".to_string();
            return Err(RunError::Diverged { step: k, t_s: self.p.t_s(k), who: "the plant model", what });
        }
        l.decide(k, &self.inbox.share_bits);
        Ok(())
    }

    /// Await a step token from every live agent.
    fn begin(&mut self, k: u64) {
        tracing::trace!("step {k} (t = {:.3} s)", self.p.t_s(k));
        self.inbox.k = k;
        self.inbox.latency_max_ns = 0;
        for j in 1..=self.n_agents {
            let idx = j as usize - 1;
            self.inbox.newest_step[idx] = None;
            self.inbox.want[idx] = self.roster.live.contains(j);
        }
    }

    /// Wait for the shares of step k: up to the step timeout, or in real time until the step's
    /// deadline. A timeout ends the run unless the run degrades or runs in real time.
    fn await_shares(&mut self, k: u64) -> Result<(), RunError> {
        let p = self.p;
        let limit = match p.realtime_rate {
            // Real time: a command is due by the end of its step.
            Some(rate) => {
                let due = |from: Instant| from + Duration::from_secs_f64((k + 1) as f64 * p.dt_s / rate);
                let was_due = due(self.paced_from);
                rebase_if_stalled(&mut self.paced_from, &mut self.last_heard, was_due, p.step_timeout, k);
                due(self.paced_from).saturating_duration_since(Instant::now())
            }
            None => p.step_timeout,
        };
        match self.w.until(k, "share", &mut self.inbox, limit) {
            Ok(()) => Ok(()),
            Err(RunError::Timeout { .. }) if p.realtime_rate.is_some() || p.degrade => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Close step k: who delivered, who missed, who is gone; the command each agent flies.
    fn close(&mut self, k: u64, report: &mut ProcessReport) -> Result<(), RunError> {
        let p = self.p;
        let realtime = p.realtime_rate.is_some();
        for j in 1..=self.n_agents {
            let idx = j as usize - 1;
            if self.inbox.died.contains(j) && self.roster.live.contains(j) {
                self.roster.set(self.w.t, p, j, false, k, "died");
                self.roster.lost_at_close.set(j, true);
            }
            if !self.roster.live.contains(j) {
                self.commands[idx].iter_mut().for_each(|u| *u = 0.0);
                continue;
            }
            let missed = self.inbox.want[idx];
            if missed && realtime {
                report.faults.deadline_misses += 1;
                if self.last_heard[idx].elapsed() >= p.step_timeout {
                    if !p.degrade {
                        let (from, after_s) = (format!("agent {j}"), p.step_timeout.as_secs_f64());
                        return Err(RunError::Timeout { step: k, from, what: "share", after_s });
                    }
                    self.drop_silent(j, k);
                    continue;
                }
            } else if missed {
                // Lockstep: waited the full step timeout (degrade mode, else it returned).
                self.drop_silent(j, k);
                continue;
            } else {
                self.last_heard[idx] = Instant::now();
            }
            match self.inbox.newest_step[idx].take() {
                Some(_) => std::mem::swap(&mut self.commands[idx], &mut self.inbox.newest_cmd[idx]),
                None => *report.faults.held.entry(Proc::Agent(j).name()).or_default() += 1,
            }
        }
        self.inbox.died = Roster::EMPTY;
        Ok(())
    }

    /// Agent j missed step k's deadline: off the roster, its spacecraft coasts.
    fn drop_silent(&mut self, j: u32, k: u64) {
        self.roster.set(self.w.t, self.p, j, false, k, "silent");
        self.roster.lost_at_close.set(j, true);
        self.commands[j as usize - 1].iter_mut().for_each(|u| *u = 0.0);
    }

    /// Apply the commands, take step k's row, integrate to tₖ₊₁; returns the round's time, ns.
    fn advance(&mut self, k: u64) -> Result<u64, RunError> {
        let t_s = self.p.t_s(k);
        for (i, u) in self.commands.iter().enumerate() {
            self.model.apply_command(i as u32 + 1, u);
        }
        if self.p.writes_row(k) {
            self.row.clear();
            self.row.push(t_s);
            self.model.row(&mut self.row);
            if let Some(l) = &self.links {
                self.row.extend_from_slice(&l.row(k));
            }
        }
        let round_ns = monotonic_ns() - self.round_start;
        self.model.advance(self.p.dt_s);
        failed(self.model.take_failure(), "the plant model", k, t_s)?;
        Ok(round_ns)
    }

    /// Real-time pacing: step k+1 starts no earlier than (k+1)·dt/rate after step 0.
    fn pace(&mut self, k: u64) {
        let p = self.p;
        if let Some(rate) = p.realtime_rate {
            let due = self.paced_from + Duration::from_secs_f64((k + 1) as f64 * p.dt_s / rate);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            } else {
                rebase_if_stalled(&mut self.paced_from, &mut self.last_heard, due, p.step_timeout, k);
            }
        }
    }

    /// Hold before step k+1 when a process fault may be due then.
    fn hold_if_due(&mut self, k: u64) -> Result<(), RunError> {
        if k + 1 < self.p.n_steps && self.hold_steps.binary_search(&(k + 1)).is_ok() {
            // Flush first: a process fault may be due to end this run.
            self.tel.flush().map_err(io("plant telemetry"))?;
            hold(&mut self.w, self.p, k + 1, &mut self.roster)?;
            // Nobody can answer while the plant holds, and an agent back on the roster (a
            // thaw, a relaunch) is heard from only now: its silence counts from here, not
            // from before it left (else, in real time, a hold that overran the next step's
            // deadline would have it declared dead again at its very return step).
            self.last_heard.iter_mut().for_each(|h| *h = Instant::now());
        }
        Ok(())
    }

    /// Step k's telemetry and timing rows, and progress now and then.
    fn write_rows(&mut self, k: u64, round_ns: u64, report: &mut ProcessReport) -> Result<(), RunError> {
        if self.p.writes_row(k) {
            self.tel.row(k, &self.row).map_err(io("plant telemetry"))?;
        }
        self.timing.row(k, &[round_ns, self.inbox.latency_max_ns]).map_err(io("plant timing"))?;
        report.steps_completed = k + 1;
        if self.last_progress.elapsed() >= PROGRESS_EVERY {
            self.last_progress = Instant::now();
            self.w.t.report(&status(self.p, PLANT_ID, STATUS_PROGRESS, k + 1, 0));
        }
        Ok(())
    }

    /// Fill the report from the loop's counters and close the files: never lose telemetry, flush
    /// whatever was written, also after an error.
    fn finish(mut self, report: &mut ProcessReport, result: Result<(), RunError>) -> Result<(), RunError> {
        report.wall_s = self.loop_start.elapsed().as_secs_f64();
        report.timeouts = self.w.timeouts;
        report.wait = self.w.stats();
        report.messages_received = self.inbox.received;
        report.messages_rejected = reject_map(&self.inbox.rejects);
        report.faults.late = self.inbox.late;
        report.faults.roster = std::mem::take(&mut self.roster.changes);
        report.messages_sent = self.sent;
        report.links = self.links.as_ref().map_or(Vec::new(), |l| l.stats());
        for (i, (n, h)) in self.inbox.from.iter().zip(&self.inbox.latency).enumerate() {
            let name = Proc::Agent(i as u32 + 1).name();
            report.received_from.insert(name.clone(), *n);
            report.faults.overrun.insert(name.clone(), self.inbox.overrun[i]);
            report.latency_from_ns.insert(name, h.buckets());
        }
        let flushed = self.tel.finish().and_then(|_| self.timing.finish()).map_err(io("plant telemetry"));
        result.and(flushed)
    }
}

/// Start barrier: wait for the orchestrator's start signal (every reader exists).
fn start_barrier<T: Transport + ?Sized>(t: &mut T, p: &DriveParams) -> Result<(), RunError> {
    let barrier_start = Instant::now();
    // As long as the orchestrator waits for the run's start-up (`hold_timeout` covers
    // `run.startup_timeout_s`): a thousand agent processes take tens of seconds to become ready,
    // and a plant that gave up after the step timeout ended a start-up still within its limit.
    let barrier_limit = p.hold_timeout.max(p.step_timeout).max(Duration::from_secs(60));
    while !t.start_granted() {
        if t.stop_requested() || p.terminate.load(Ordering::Relaxed) {
            return Err(RunError::Stopped { step: 0, why: "before start", waiting: String::new() });
        }
        if barrier_start.elapsed() > barrier_limit {
            let after_s = barrier_limit.as_secs_f64();
            return Err(RunError::Timeout { step: 0, from: "the orchestrator".into(), what: "start signal", after_s });
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Ok(())
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
            return Err(RunError::Stopped { step: k, why: "orchestrator", waiting: String::new() });
        }
        if p.terminate.load(Ordering::Relaxed) {
            return Err(RunError::Stopped { step: k, why: "SIGTERM", waiting: String::new() });
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
