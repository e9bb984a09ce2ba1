//! An agent's side of every step: its measurement in, its share out (as the fault plan says),
//! its neighbours' shares in, its algorithm stepped; checkpoints, catching up after a freeze or
//! a relaunch, and the step tokens that keep lockstep going without a lost share.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use cohort_scenario::faults::{Corruption, Fate};
use cohort_wire::msg::{Header, LINK_LOST, Measurement, STATUS_DONE, STATUS_IDLE, Share};
use cohort_wire::transport::{Proc, Transport, TransportError, monotonic_ns};

use super::agent_inbox::{AgentInbox, live_at};
use super::checkpoint_writer::{CheckpointWriter, stagger};
use super::error::{RunError, failed, io};
use super::files::agent_files;
use super::params::DriveParams;
use super::status::{new_report, report_ready, status};
use super::wait::{Waiter, repoll_after};
use crate::checkpoint::{AgentState, Checkpoint};
use crate::model::{AgentInput, Algorithm, ShareOut};
use crate::record::{ProcessReport, TelemetryWriter, TimingWriter, reject_map};

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
    let result = agent_run(t, algo, id, neighbours, p, restore, &mut report);
    if report.wall_s == 0.0 {
        // Its files could not be opened: no step ran.
        report.wall_s = started.elapsed().as_secs_f64();
    }
    report.solver = algo.solver_stats();
    (report.cpu_s, report.max_rss_kb) = crate::record::cpu_and_rss();
    report.pss_kb = crate::record::pss_kb();
    if let Err(e) = result {
        report.error = Some(e.to_report());
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
        // Nothing is awaited but the stop: a wakeup from a late share only shortens the nap. What
        // rang is taken and dropped, or every later wait returns at once: with a link delay the
        // neighbours' last shares are never read, and a 100-agent ring's lingering agents kept
        // both cores busy, the plant's telemetry writer (nice 19) finishing its file behind them,
        // until their bound ran out 120 s later.
        let _ = t.drain(&mut |_| {});
        let nap = repoll_after(&*t, false, Duration::ZERO);
        if t.wait(nap).is_err() {
            std::thread::sleep(nap);
        }
    }
}

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

/// Open the agent's files, run every step, report done and linger ([`linger`]), and close
/// (flushing the telemetry also after an error).
fn agent_run<T: Transport + ?Sized>(
    t: &mut T,
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    p: &DriveParams,
    restore: Option<&Checkpoint>,
    report: &mut ProcessReport,
) -> Result<(), RunError> {
    let started = Instant::now();
    let mut driver = AgentDriver::open(t, algo, id, neighbours, p, restore, report)?;
    let result = driver.run(report);
    // The steps' wall time: not the linger, which waits for the plant's end.
    report.wall_s = started.elapsed().as_secs_f64();
    if result.is_ok() {
        // The files are finished after the linger, not before: finishing them right after the
        // last control (a hundred writer threads encoding at once, which the scheduler runs
        // before the spinning processes still on that step) made the last step among a 100-agent
        // ring's slowest (up to 101 ms against a median of 1 ms).
        driver.w.t.report(&status(p, id, STATUS_DONE, p.n_steps, 0));
        linger(driver.w.t, p);
    }
    driver.finish(report, result)
}

/// An agent's loop, one method per phase of a step.
struct AgentDriver<'a, T: Transport + ?Sized> {
    w: Waiter<'a, T>,
    algo: &'a mut dyn Algorithm,
    id: u32,
    p: &'a DriveParams,
    restore: Option<&'a Checkpoint>,
    tel: TelemetryWriter,
    timing: TimingWriter,
    checkpoints: CheckpointWriter,
    inbox: AgentInbox,
    /// The step this agent is at.
    k: u64,
    /// `run.link_delay_steps`.
    delay: u64,
    hold_steps: Vec<u64>,
    meas_limit: Duration,
    /// Whether the first measurement has come: before it, the wait also covers the rest of the
    /// run's start-up (the plant sends step 0 only once every process is ready, up to
    /// `run.startup_timeout_s` after the launch). With the step timeout alone, the first 64
    /// agents of a 200-vehicle swarm, ready early, timed out at step 0 while the others started.
    measured: bool,
    share_limit: Duration,
    /// Delayed shares and the step they go out at.
    pending: Vec<(u64, Box<Share>)>,
    /// The neighbours' liveness last told to the algorithm, and now.
    last_live: Option<Vec<bool>>,
    live_now: Vec<bool>,
    out: ShareOut,
    row: Vec<f64>,
}

impl<'a, T: Transport + ?Sized> AgentDriver<'a, T> {
    /// Create (or, relaunched, append to) the telemetry and timing files and set up the inbox,
    /// restoring the held shares of a checkpoint.
    fn open(
        t: &'a mut T,
        algo: &'a mut dyn Algorithm,
        id: u32,
        neighbours: &[u32],
        p: &'a DriveParams,
        restore: Option<&'a Checkpoint>,
        report: &mut ProcessReport,
    ) -> Result<Self, RunError> {
        let mut columns = vec!["k".to_string(), "t_s".to_string()];
        columns.extend(algo.columns());
        // A relaunched agent goes on with its predecessor's files.
        let (tel, timing) = agent_files(p, &Proc::Agent(id).name(), &columns, restore.is_some())?;
        let checkpoints = CheckpointWriter::new(&Proc::Agent(id).name(), crate::checkpoint::path_for(&p.dirs.root, id))
            .map_err(io("agent checkpoint writer"))?;
        let plan = &*p.faults;
        let delay = u64::from(p.link_delay_steps);
        let mut inbox = AgentInbox::new(p, id, neighbours, delay + u64::from(plan.max_delay()) + 1);
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
        // The plant declares a silent agent dead after its step timeout (degrade mode), and only
        // then sends the next measurement or the roster that releases a wait on that agent's
        // share: both waits must outlast it, or a healthy agent times out in the same instant as
        // the silent one.
        let degrade_limit = if p.degrade { 2 * p.step_timeout + Duration::from_secs(1) } else { p.step_timeout };
        let meas_limit = if plan.has_process_faults() { degrade_limit + p.hold_timeout } else { degrade_limit };
        Ok(AgentDriver {
            w: Waiter::new(t, p, id),
            algo,
            id,
            p,
            restore,
            tel,
            timing,
            checkpoints,
            inbox,
            k,
            delay,
            hold_steps,
            meas_limit,
            measured: false,
            share_limit: degrade_limit,
            pending: Vec::new(),
            last_live: None,
            live_now: Vec::with_capacity(neighbours.len()),
            out: ShareOut::default(),
            row: Vec::with_capacity(columns.len()),
        })
    }

    /// Every step from the first (or the checkpoint's).
    fn run(&mut self, report: &mut ProcessReport) -> Result<(), RunError> {
        while self.k < self.p.n_steps {
            self.step(report)?;
        }
        Ok(())
    }

    /// Step k: checkpoint, measurement (catching up when it is ahead), share out, row, the
    /// neighbours' shares, the algorithm's step, the timing row.
    fn step(&mut self, report: &mut ProcessReport) -> Result<(), RunError> {
        // With a link delay the neighbours' shares of step k-1 were sent before the plant could
        // send measurement k: one wait, one wakeup. (`used` stays the step's first k's, also
        // after a catch-up.)
        let used = self.begin();
        self.checkpoint_if_due(report)?;
        self.idle_if_hold()?;
        let m = self.await_measurement(report)?;
        let k = self.k;
        self.tell_roster();
        let compute_start = monotonic_ns();
        self.compute_share(&m)?;
        self.send_shares(report)?;
        let mut compute_ns = monotonic_ns() - compute_start;
        // Formatting the row overlaps the wait for the neighbours' shares.
        self.write_row()?;
        let wait_start = monotonic_ns();
        if self.delay == 0 {
            self.inbox.want_measurement = false;
            self.inbox.need_shares = Some(k);
            self.w.until(k, "share", &mut self.inbox, self.share_limit)?;
        }
        let neighbour_wait_ns = monotonic_ns() - wait_start;
        let step_start = monotonic_ns();
        self.inbox.advance(self.algo, used, self.p.dt_s, report);
        failed(self.algo.take_failure(), "the algorithm", k, self.p.t_s(k))?;
        compute_ns += monotonic_ns() - step_start;
        let timing_row = [self.inbox.meas_latency_ns, neighbour_wait_ns, compute_ns];
        self.timing.row(k, &timing_row).map_err(io("agent timing"))?;
        report.steps_completed = k + 1;
        self.k += 1;
        Ok(())
    }

    /// Await the measurement of step k (and, with a link delay, the shares it uses); returns the
    /// step whose shares the algorithm steps with.
    fn begin(&mut self) -> Option<u64> {
        self.inbox.k = self.k;
        self.inbox.want_measurement = true;
        let used = self.k.checked_sub(self.delay);
        self.inbox.need_shares = if self.delay > 0 { used } else { None };
        used
    }

    /// The state at the start of step k (after step k−1), before any fault due at k.
    fn checkpoint_if_due(&mut self, report: &mut ProcessReport) -> Result<(), RunError> {
        let (p, k, id) = (self.p, self.k, self.id);
        self.checkpoints.release_due(k).map_err(io("agent checkpoint"))?;
        if p.checkpoint_every > 0 && k % p.checkpoint_every == 0 && self.restore.is_none_or(|c| c.step != k) {
            let ck = Checkpoint {
                run_id: p.run_id,
                agent: id,
                step: k,
                kind: p.algorithm_kind.clone(),
                state: AgentState {
                    algorithm: self.algo.save_state(),
                    held: self
                        .inbox
                        .peers
                        .iter()
                        .filter_map(|peer| peer.held.as_ref().map(|(s, v)| (peer.id, *s, v.clone())))
                        .collect(),
                },
            };
            // Encoded now (the state of this step), written by the writer's thread a few steps
            // later (`stagger`); a failed write's error names the file.
            let at = k + stagger(id, p.checkpoint_every);
            self.checkpoints.hold(ck.encode(), at).map_err(io("agent checkpoint"))?;
            report.faults.checkpoints_written += 1;
            tracing::debug!("step {k}: checkpoint encoded, handed to its writer at step {at}");
        }
        Ok(())
    }

    /// A process fault may be due now: be found between steps with every row on disk.
    fn idle_if_hold(&mut self) -> Result<(), RunError> {
        if self.hold_steps.binary_search(&self.k).is_ok() {
            self.tel.flush().and_then(|_| self.timing.flush()).map_err(io("agent telemetry"))?;
            // A relaunch after this fault reads the newest checkpoint.
            self.checkpoints.wait().map_err(io("agent checkpoint"))?;
            self.w.t.report(&status(self.p, self.id, STATUS_IDLE, self.k, 0));
        }
        Ok(())
    }

    /// Wait for the measurement of step k; when it names a later step, catch up to it first.
    fn await_measurement(&mut self, report: &mut ProcessReport) -> Result<Box<Measurement>, RunError> {
        let limit = if self.measured { self.meas_limit } else { self.meas_limit + self.p.hold_timeout };
        self.w.until(self.k, "measurement", &mut self.inbox, limit)?;
        self.measured = true;
        let m = self.inbox.meas.take().expect("the wait completed");
        if m.header.step > self.k {
            self.catch_up(m.header.step, report)?;
        }
        Ok(m)
    }

    /// Back on the roster at `back_at` after missing steps (thawed, or relaunched from a
    /// checkpoint): propagate through them with the neighbours' last valid shares.
    fn catch_up(&mut self, back_at: u64, report: &mut ProcessReport) -> Result<(), RunError> {
        let (p, delay) = (self.p, self.delay);
        // Only what it had before it left: which of the shares sent meanwhile are still queued
        // depends on when it woke (a full queue keeps the newest), so using them would make the
        // run depend on timing.
        for peer in &mut self.inbox.peers {
            peer.arrived.retain(|(s, _)| *s >= back_at);
            peer.tokens.retain(|s| *s >= back_at);
        }
        for s in self.k..back_at {
            self.inbox.advance(self.algo, s.checked_sub(delay), p.dt_s, report);
            failed(self.algo.take_failure(), "the algorithm", s, p.t_s(s))?;
        }
        report.faults.steps_missed += back_at - self.k;
        self.k = back_at;
        self.inbox.k = back_at;
        let used = back_at.checked_sub(delay);
        self.inbox.need_shares = if delay > 0 { used } else { None };
        if delay > 0 {
            self.inbox.want_measurement = false;
            self.w.until(back_at, "share", &mut self.inbox, self.share_limit)?;
        }
        Ok(())
    }

    /// Tell the algorithm which neighbours are live at step k when that changed.
    fn tell_roster(&mut self) {
        let k = self.k;
        self.live_now.clear();
        self.live_now.extend(self.inbox.peers.iter().map(|peer| live_at(&peer.hist, k)));
        if self.last_live.as_ref() != Some(&self.live_now) {
            self.algo.roster(&self.live_now);
            self.last_live = Some(self.live_now.clone());
        }
    }

    /// The algorithm's command and share values for step k, which must be finite.
    fn compute_share(&mut self, m: &Measurement) -> Result<(), RunError> {
        let (k, t_s) = (self.k, self.p.t_s(self.k));
        self.out.command.clear();
        self.out.values.clear();
        self.algo.share(&AgentInput { k, t_s, readings: m.readings() }, &mut self.out);
        failed(self.algo.take_failure(), "the algorithm", k, t_s)?;
        if !self.out.command.iter().all(|x| x.is_finite()) {
            return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "command".into() });
        }
        if !self.out.values.iter().all(|x| x.is_finite()) {
            return Err(RunError::Diverged { step: k, t_s, who: "the algorithm", what: "share value".into() });
        }
        Ok(())
    }

    /// Late shares due now go out first; then this step's, as the fault plan says, and the step
    /// token when the share itself does not go out on time.
    fn send_shares(&mut self, report: &mut ProcessReport) -> Result<(), RunError> {
        let (p, k, id) = (self.p, self.k, self.id);
        let t_s = p.t_s(k);
        let mut i = 0;
        while i < self.pending.len() {
            if self.pending[i].0 <= k {
                let (_, s) = self.pending.swap_remove(i);
                send_share(self.w.t, p, &s)?;
                report.messages_sent += 1;
            } else {
                i += 1;
            }
        }
        let share = Share::new(Header::new(p.run_id, id, k, t_s), &self.out.command, &self.out.values);
        let fate = p.faults.fate(id, k);
        match fate {
            Fate::Deliver => {
                send_share(self.w.t, p, &share)?;
                report.messages_sent += 1;
            }
            Fate::Delay(n) => {
                report.faults.shares_delayed += 1;
                self.pending.push((k + u64::from(n), Box::new(share)));
            }
            Fate::Drop => report.faults.shares_dropped += 1,
            Fate::Corrupt(how) => {
                *report.faults.shares_corrupted.entry(how.name().to_string()).or_default() += 1;
                let mut garbled = share;
                corrupt(&mut garbled, how);
                send_share(self.w.t, p, &garbled)?;
                report.messages_sent += 1;
            }
        }
        if fate != Fate::Deliver {
            // The step token: lockstep goes on without the share (see `LINK_LOST`).
            let mut token = Share::new(share.header, &[], &[]);
            token.link = LINK_LOST;
            send_share(self.w.t, p, &token)?;
            report.messages_sent += 1;
        }
        Ok(())
    }

    /// Step k's telemetry row, when it gets one.
    fn write_row(&mut self) -> Result<(), RunError> {
        let (k, t_s) = (self.k, self.p.t_s(self.k));
        if self.p.writes_row(k) {
            self.row.clear();
            self.row.push(t_s);
            self.algo.row(&mut self.row);
            failed(self.algo.take_failure(), "the algorithm", k, t_s)?;
            self.tel.row(k, &self.row).map_err(io("agent telemetry"))?;
        }
        Ok(())
    }

    /// Fill the report from the loop's counters and close the files, also after an error.
    fn finish(mut self, report: &mut ProcessReport, result: Result<(), RunError>) -> Result<(), RunError> {
        report.timeouts = self.w.timeouts;
        report.wait = self.w.stats();
        let inbox = &self.inbox;
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
        let flushed = self.tel.finish().and_then(|_| self.timing.finish()).map_err(io("agent telemetry"));
        let written = self.checkpoints.finish().map_err(io("agent checkpoint"));
        result.and(flushed).and(written)
    }
}
