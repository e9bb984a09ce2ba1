//! The reference run (`launch --reference`): the plant and every agent as threads of this process
//! over the in-memory transport, through the same drivers as the multi-process run. Its
//! telemetry must equal the multi-process run's byte for byte. Its drivers run as a thread each
//! (`launch --reference`) or as coroutines of one thread ([`Threads::One`]: a campaign's cases).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cohort_runtime::drive::{DriveParams, run_agent, run_plant};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::{ErrorKind, ProcessError, ProcessReport, RunDirs};
use cohort_runtime::recording::writer::{RecordMeta, Recording};
use cohort_runtime::rng::process_rng;
use cohort_supervisor::supervise::{LaunchOutcome, RunStatus, SIGNALLED};
use cohort_wire::msg::{PLANT_ID, STATUS_PROGRESS};
use cohort_wire::transport::Proc;
use cohort_wire::transport::memory::MemoryBus;

use crate::progress::Progress;

fn run_one(s: &Setup, bus: &Arc<MemoryBus>, p: Proc, params: &DriveParams) -> ProcessReport {
    let mut t = bus.endpoint(p);
    let report = match p {
        Proc::Plant => {
            let mut model = s.plant.build(s);
            let mut rng = process_rng(s.scenario.seed, Proc::Plant);
            run_plant(&mut t, model.as_mut(), &mut rng, s.n_agents(), params)
        }
        Proc::Agent(id) if s.run.record => {
            // `run.record`: the same file an agent process writes.
            let mut algo = s.algorithm.build(s, id);
            let meta = RecordMeta::from_setup(s, params.run_id, p);
            match Recording::start(&mut t, &params.dirs.root, meta) {
                Ok(mut rec) => {
                    let mut report = run_agent(&mut rec, algo.as_mut(), id, &s.agent(id).neighbours, params, None);
                    if let Err(e) = rec.finish()
                        && report.error.is_none()
                    {
                        report.error = Some(ProcessError::new(ErrorKind::Io, format!("recording {e}")));
                    }
                    report
                }
                Err(e) => ProcessReport::failed_at_start(
                    p.name(),
                    ProcessError::new(ErrorKind::Io, format!("cannot record: {e}")),
                ),
            }
        }
        Proc::Agent(id) => {
            let mut algo = s.algorithm.build(s, id);
            run_agent(&mut t, algo.as_mut(), id, &s.agent(id).neighbours, params, None)
        }
    };
    if report.error.is_some() {
        // Let every other thread stop at its next wait instead of timing out.
        bus.request_stop();
    }
    // The format of a child's log line (level, name, run time), as a thread of this process.
    let (name, t_s) = (p.name(), cohort_runtime::logging::run_time_s());
    let log = match &report.error {
        None => cohort_runtime::logging::child_line(
            tracing::Level::INFO,
            &name,
            t_s,
            format!("done (reference thread): {} steps in {:.3} s", report.steps_completed, report.wall_s),
        ),
        Some(e) => {
            cohort_runtime::logging::child_line(tracing::Level::ERROR, &name, t_s, format!("(reference thread) {e}"))
        }
    };
    let _ = std::fs::write(params.dirs.logs().join(format!("{}.log", p.name())), log);
    let _ = report.write(&params.dirs);
    report
}

/// How the reference run places its drivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threads {
    /// A thread per process, as the processes have a core each when the machine has them.
    PerProcess,
    /// Every driver a coroutine of the calling thread (`cohort_runtime::coop`): one core per
    /// run, for campaigns that run many at once.
    One,
}

pub fn launch(
    s: &Setup,
    dirs: &RunDirs,
    run_id: u64,
    key: Option<cohort_wire::auth::MacKey>,
    progress: &Progress,
    threads: Threads,
) -> LaunchOutcome {
    let started = Instant::now();
    let bus = MemoryBus::new(s.topology());
    let terminate = Arc::new(AtomicBool::new(false));
    // Threads of one process: spinning is as good (or bad) as between processes.
    let mut params = DriveParams::from_setup(s, run_id, dirs.clone(), Arc::clone(&terminate), started);
    params.key = key;
    let mut signal = 0usize;
    // Progress and signals, between the drivers' turns (one thread) or every 10 ms (threads).
    let mut watch = || {
        for st in bus.take_status() {
            if st.sender == PLANT_ID && st.kind == STATUS_PROGRESS {
                progress.set(st.step);
            }
        }
        let sig = SIGNALLED.load(Ordering::SeqCst);
        if sig != 0 && signal == 0 {
            signal = sig;
            terminate.store(true, Ordering::SeqCst);
            bus.request_stop();
        }
    };
    let reports = drive(s, &bus, &params, threads, &mut watch);
    let wall_s = started.elapsed().as_secs_f64();
    if signal != 0 {
        return ended(RunStatus::Interrupted(signal as i32), Some(format!("interrupted by signal {signal}")), wall_s);
    }
    let reports = match reports {
        Ok(r) => r,
        Err(e) => return ended(RunStatus::Failed, Some(format!("cannot map the drivers' stacks: {e}")), wall_s),
    };
    // The first genuine failure (others merely stopped because of it).
    let failure = reports
        .iter()
        .filter_map(|r| r.error.as_ref().map(|e| (r, e)))
        .find(|(_, e)| !e.is_stop())
        .or_else(|| reports.iter().filter_map(|r| r.error.as_ref().map(|e| (r, e))).next());
    match failure {
        Some((r, e)) => ended(RunStatus::Failed, Some(format!("{}: {e}", r.process)), wall_s),
        None => {
            progress.set(s.n_steps());
            ended(RunStatus::Ok, None, wall_s)
        }
    }
}

/// The plant and every agent run to their ends, placed as `threads` says, `watch` called while
/// they run; their reports in process order (an error only when one thread's stacks cannot be
/// mapped).
fn drive(
    s: &Setup,
    bus: &Arc<MemoryBus>,
    params: &DriveParams,
    threads: Threads,
    watch: &mut dyn FnMut(),
) -> std::io::Result<Vec<ProcessReport>> {
    let procs: Vec<Proc> = std::iter::once(Proc::Plant).chain((1..=s.n_agents()).map(Proc::Agent)).collect();
    match threads {
        Threads::PerProcess => Ok(std::thread::scope(|sc| {
            let handles: Vec<_> = procs
                .iter()
                .map(|&p| {
                    std::thread::Builder::new()
                        .name(p.name())
                        .spawn_scoped(sc, move || run_one(s, bus, p, params))
                        .expect("spawning a thread")
                })
                .collect();
            while !handles.iter().all(|h| h.is_finished()) {
                watch();
                std::thread::sleep(Duration::from_millis(10));
            }
            handles.into_iter().map(|h| h.join().expect("a reference thread panicked")).collect()
        })),
        Threads::One => {
            let tasks = procs
                .iter()
                .map(|&p| Box::new(move || run_one(s, bus, p, params)) as Box<dyn FnOnce() -> ProcessReport>)
                .collect();
            cohort_runtime::coop::run(tasks, watch)
        }
    }
}

/// A reference run's outcome (no start-up time, no fault timeline: neither exists in-process).
fn ended(status: RunStatus, error: Option<String>, wall_s: f64) -> LaunchOutcome {
    LaunchOutcome { status, error, wall_s, startup_s: None, timeline: Vec::new() }
}
