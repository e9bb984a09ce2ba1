//! Multi-process launch: create the run's iceoryx2 services, spawn one `plant` and one `agent`
//! per agent, release the start barrier once all are ready, watch them, and on any exit path
//! stop them in order and remove every iceoryx2 resource of the run.
//!
//! Shutdown ladder (dora-style), used on Ctrl-C, SIGTERM and any child's failure:
//! 1. publish a stop request on the run's control service and wait [`STOP_GRACE`];
//! 2. SIGTERM whoever is left (each child stops at its next wait, flushing its telemetry) and
//!    wait [`TERM_GRACE`];
//! 3. SIGKILL whoever is still left, and reap it.
//!
//! Children run in their own process group (a terminal's Ctrl-C reaches only the orchestrator,
//! which then stops them in order) and with `PR_SET_PDEATHSIG = SIGKILL`, so even a SIGKILLed
//! orchestrator leaves no orphan.

use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use cohort_runtime::process::{EXIT_BUILD_MISMATCH, EXIT_STOPPED};
use cohort_runtime::record::RunDirs;
use cohort_scenario::Scenario;
use cohort_wire::msg::{PLANT_ID, STATUS_PROGRESS, STATUS_READY, STATUS_WAITING};
use cohort_wire::transport::Proc;
use cohort_wire::transport::iox::{IoxRun, IoxServices};

use crate::progress::Progress;

/// After the stop request, how long children get to exit on their own.
pub const STOP_GRACE: Duration = Duration::from_secs(3);
/// After SIGTERM, how long before SIGKILL.
pub const TERM_GRACE: Duration = Duration::from_secs(2);
/// How often the supervision loop looks at children and status messages.
const TICK: Duration = Duration::from_millis(5);
/// After a child dies, how long to wait for the plant to say which step it is stuck in.
const BLAME_WAIT: Duration = Duration::from_millis(600);

/// Which signal stopped the orchestrator, if any (set from the signal handlers).
pub static SIGNALLED: AtomicUsize = AtomicUsize::new(0);

pub struct LaunchOutcome {
    pub status: &'static str,
    pub error: Option<String>,
    pub wall_s: f64,
    /// From the first spawn to the start signal (every process ready), s.
    pub startup_s: Option<f64>,
    /// Exit code for the orchestrator.
    pub exit_code: u8,
}

struct Kid {
    proc_: Proc,
    child: Child,
    exit: Option<ExitStatus>,
    ready: bool,
}

fn describe_exit(st: ExitStatus) -> String {
    if let Some(sig) = st.signal() {
        let name = match sig {
            libc::SIGKILL => "SIGKILL",
            libc::SIGTERM => "SIGTERM",
            libc::SIGSEGV => "SIGSEGV",
            libc::SIGABRT => "SIGABRT",
            libc::SIGINT => "SIGINT",
            _ => "signal",
        };
        format!("was killed by signal {sig} ({name})")
    } else {
        format!("exited with code {}", st.code().unwrap_or(-1))
    }
}

/// The last meaningful line of a child's log, to quote in an error.
fn last_log_line(path: &Path) -> Option<String> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines().rev().find(|l| !l.trim().is_empty()).map(|l| l.trim().to_string())
}

/// Find `plant` and `agent` beside the orchestrator's own executable.
pub fn sibling_binary(name: &str) -> Result<PathBuf, String> {
    let me = std::env::current_exe().map_err(|e| format!("cannot locate the orchestrator executable: {e}"))?;
    let dir = me.parent().ok_or("the orchestrator executable has no parent directory")?;
    let path = dir.join(name);
    if !path.is_file() {
        return Err(format!(
            "the `{name}` binary is missing: expected {} beside the orchestrator. Build the whole workspace \
             (`cargo build --release`, or `cargo run --release -p orchestrator -- ...` from the workspace root, \
             which builds every default member)",
            path.display()
        ));
    }
    Ok(path)
}

fn spawn(bin: &Path, p: Proc, dirs: &RunDirs, run: &IoxRun, step_timeout_s: f64) -> Result<Child, String> {
    let log_path = dirs.logs().join(format!("{}.log", p.name()));
    let log = std::fs::File::create(&log_path).map_err(|e| format!("{}: {e}", log_path.display()))?;
    let log2 = log.try_clone().map_err(|e| format!("{}: {e}", log_path.display()))?;
    let mut cmd = Command::new(bin);
    if let Proc::Agent(id) = p {
        cmd.arg("--id").arg(id.to_string());
    }
    cmd.arg("--run-dir")
        .arg(&dirs.root)
        .arg("--run-id")
        .arg(format!("{:016x}", run.run_id))
        .arg("--build-id")
        .arg(cohort_wire::BUILD_ID)
        .arg("--step-timeout-s")
        .arg(format!("{step_timeout_s:?}"))
        .stdin(Stdio::null())
        .stdout(Stdio::from(log))
        .stderr(Stdio::from(log2));
    // SAFETY: only async-signal-safe calls (setpgid, prctl, getppid) between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            libc::setpgid(0, 0);
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong, 0, 0, 0);
            // The orchestrator may have died between fork and prctl.
            if libc::getppid() == 1 {
                libc::_exit(1);
            }
            Ok(())
        });
    }
    cmd.spawn().map_err(|e| format!("cannot start {}: {e}", bin.display()))
}

/// Launch and supervise one multi-process run.
pub fn launch(s: &Scenario, dirs: &RunDirs, run: &IoxRun, progress: &Progress) -> LaunchOutcome {
    let started = Instant::now();
    let bins = match (sibling_binary("plant"), sibling_binary("agent")) {
        (Ok(p), Ok(a)) => (p, a),
        (Err(e), _) | (_, Err(e)) => {
            return LaunchOutcome { status: "failed", error: Some(e), wall_s: 0.0, startup_s: None, exit_code: 1 };
        }
    };
    for id in IoxRun::sweep_stale() {
        eprintln!("removed the iceoryx2 resources of run {id:016x}, whose orchestrator is gone");
    }
    if let Err(e) = run.claim() {
        let error = Some(format!("cannot create {}: {e}", run.root_dir().display()));
        return LaunchOutcome { status: "failed", error, wall_s: 0.0, startup_s: None, exit_code: 1 };
    }
    let services = match IoxServices::create(run, &s.topology()) {
        Ok(sv) => sv,
        Err(e) => {
            run.remove_all_resources();
            let error = Some(format!("cannot create the run's iceoryx2 services: {e}"));
            return LaunchOutcome { status: "failed", error, wall_s: 0.0, startup_s: None, exit_code: 1 };
        }
    };
    let mut kids: Vec<Kid> = Vec::new();
    let mut failure: Option<String> = None;
    for p in std::iter::once(Proc::Plant).chain((1..=s.n_agents()).map(Proc::Agent)) {
        let bin = if p == Proc::Plant { &bins.0 } else { &bins.1 };
        match spawn(bin, p, dirs, run, s.run.step_timeout_s) {
            Ok(child) => kids.push(Kid { proc_: p, child, exit: None, ready: false }),
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    let mut startup_s = None;
    let outcome = if failure.is_none() {
        supervise(s, dirs, &services, &mut kids, progress, started, &mut startup_s)
    } else {
        (failure, None)
    };
    let (failure, signal) = outcome;
    let any_alive = kids.iter().any(|k| k.exit.is_none());
    if any_alive {
        shut_down(&services, &mut kids);
    }
    drop(services);
    run.remove_all_resources();
    let wall_s = started.elapsed().as_secs_f64();
    match (signal, failure) {
        (Some(sig), _) => LaunchOutcome {
            status: "interrupted",
            error: Some(format!("interrupted by signal {sig}; every child was stopped")),
            wall_s,
            startup_s,
            exit_code: 128 + sig as u8,
        },
        (None, Some(e)) => LaunchOutcome { status: "failed", error: Some(e), wall_s, startup_s, exit_code: 1 },
        (None, None) => LaunchOutcome { status: "ok", error: None, wall_s, startup_s, exit_code: 0 },
    }
}

/// Watch until every child has finished, one fails, or a signal arrives. Returns the failure
/// message and the signal, if any.
fn supervise(
    s: &Scenario,
    dirs: &RunDirs,
    services: &IoxServices,
    kids: &mut [Kid],
    progress: &Progress,
    started: Instant,
    startup_s: &mut Option<f64>,
) -> (Option<String>, Option<usize>) {
    let startup_limit = Duration::from_secs_f64(s.run.startup_timeout_s);
    let my_hash = cohort_wire::build_id_hash();
    let mut start_granted = false;
    let mut plant_step = 0u64;
    // Latest "waiting for X at step k" per sender.
    let mut waiting: Vec<Option<(u64, u32)>> = vec![None; s.n_agents() as usize + 1];
    let mut failed_since: Option<Instant> = None;
    loop {
        let sig = SIGNALLED.load(Ordering::SeqCst);
        if sig != 0 {
            return (None, Some(sig));
        }
        let mut mismatch = None;
        let _ = services.poll_status(|st| {
            let idx = st.sender as usize;
            if idx >= kids.len() {
                return;
            }
            match st.kind {
                STATUS_READY => {
                    if st.build_hash != my_hash {
                        mismatch = Some(idx);
                    }
                    kids[idx].ready = true;
                }
                STATUS_PROGRESS if st.sender == PLANT_ID => plant_step = st.step,
                STATUS_WAITING => waiting[idx] = Some((st.step, st.waiting_for)),
                _ => {}
            }
        });
        if let Some(idx) = mismatch {
            let name = kids[idx].proc_.name();
            return (
                Some(format!(
                    "{name} was built from other sources than the orchestrator (handshake build id differs): rebuild the workspace"
                )),
                None,
            );
        }
        if !start_granted && kids.iter().all(|k| k.ready) {
            if let Err(e) = services.grant_start() {
                return (Some(format!("cannot send the start signal: {e}")), None);
            }
            start_granted = true;
            *startup_s = Some(started.elapsed().as_secs_f64());
        }
        if !start_granted && started.elapsed() > startup_limit {
            let slow: Vec<String> = kids.iter().filter(|k| !k.ready).map(|k| k.proc_.name()).collect();
            return (
                Some(format!(
                    "start-up timeout: {} not ready after {:.0} s (run.startup_timeout_s)",
                    slow.join(", "),
                    startup_limit.as_secs_f64()
                )),
                None,
            );
        }
        // Reap.
        for k in kids.iter_mut().filter(|k| k.exit.is_none()) {
            if let Ok(Some(st)) = k.child.try_wait() {
                k.exit = Some(st);
            }
        }
        progress.set(plant_step);
        if kids.iter().all(|k| k.exit.is_some_and(|st| st.success())) {
            progress.set(s.n_steps());
            return (None, None);
        }
        if kids.iter().any(|k| k.exit.is_some_and(|st| !st.success())) {
            // When one process fails the others usually follow within moments (everyone times
            // out waiting for the same silent peer). Collect for a short window, then name the
            // root cause rather than whichever consequence exited first.
            let since = *failed_since.get_or_insert_with(Instant::now);
            if since.elapsed() < BLAME_WAIT {
                std::thread::sleep(TICK);
                continue;
            }
            return (Some(blame(s, dirs, kids, waiting[0], plant_step)), None);
        }
        std::thread::sleep(TICK);
    }
}

/// The failure message: a process killed by a signal if there is one, else the agent the plant
/// was stuck waiting for, else the first failed process; each with the step and its log's last
/// line, followed by the other failures.
fn blame(s: &Scenario, dirs: &RunDirs, kids: &[Kid], plant_waiting: Option<(u64, u32)>, plant_step: u64) -> String {
    let failed: Vec<&Kid> = kids.iter().filter(|k| k.exit.is_some_and(|st| !st.success())).collect();
    let t = |step: u64| step as f64 * s.scenario.dt_s;
    let describe = |k: &Kid| {
        let st = k.exit.expect("failed kids have exited");
        let mut m = format!("{} (pid {}) {}", k.proc_.name(), k.child.id(), describe_exit(st));
        if st.code() == Some(i32::from(EXIT_STOPPED)) {
            m.push_str(" (it was stopped)");
        }
        if st.signal().is_none()
            && let Some(line) = last_log_line(&dirs.logs().join(format!("{}.log", k.proc_.name())))
        {
            m.push_str(&format!(" [log: {line}]"));
        }
        m
    };
    let waited_for = |k: &Kid| plant_waiting.filter(|(_, who)| k.proc_ != Proc::Plant && *who == k.proc_.sender_id());
    let refused: Vec<String> = failed
        .iter()
        .filter(|k| k.exit.is_some_and(|st| st.code() == Some(i32::from(EXIT_BUILD_MISMATCH))))
        .map(|k| k.proc_.name())
        .collect();
    if !refused.is_empty() {
        return format!(
            "{} refused to run: built from other sources than this orchestrator ({}). Rebuild the whole \
             workspace: cargo build --release",
            refused.join(", "),
            cohort_wire::BUILD_ID
        );
    }
    let killed = failed.iter().find(|k| k.exit.is_some_and(|st| st.signal().is_some()));
    let silent_agent = plant_waiting.is_some_and(|(_, who)| who != 0);
    let primary = killed.copied().or(if silent_agent { None } else { Some(failed[0]) });
    let mut msg = if let Some(k) = killed {
        let mut m = describe(k);
        match waited_for(k) {
            Some((step, _)) => m.push_str(&format!(
                " during step {step} (t = {:.3} s): the plant was waiting for its share of that step",
                t(step)
            )),
            None => m.push_str(&format!(" at or after step {plant_step} (t = {:.3} s)", t(plant_step))),
        }
        m
    } else if let Some((step, who)) = plant_waiting.filter(|(_, who)| *who != 0) {
        let state = kids
            .iter()
            .find(|k| k.proc_ == Proc::Agent(who))
            .map_or("", |k| if k.exit.is_none() { " (its process is alive but silent)" } else { "" });
        format!(
            "agent {who} went silent{state}: no share of step {step} (t = {:.3} s) reached the plant within \
             run.step_timeout_s = {} s",
            t(step),
            s.run.step_timeout_s
        )
    } else {
        describe(failed[0])
    };
    // The others, briefly: they usually failed because of the primary.
    let others: Vec<String> =
        failed.iter().filter(|k| primary.is_none_or(|p| p.proc_ != k.proc_)).map(|k| describe(k)).collect();
    const SHOWN: usize = 3;
    if !others.is_empty() {
        msg.push_str(&format!("; then: {}", others[..others.len().min(SHOWN)].join("; ")));
        if others.len() > SHOWN {
            msg.push_str(&format!("; and {} more (see logs/)", others.len() - SHOWN));
        }
    }
    msg
}

/// Stop every live child: stop request, then SIGTERM, then SIGKILL (see the module docs).
fn shut_down(services: &IoxServices, kids: &mut [Kid]) {
    let _ = services.request_stop();
    wait_all(kids, STOP_GRACE);
    for k in kids.iter().filter(|k| k.exit.is_none()) {
        // SAFETY: kill(2) on a pid we spawned and have not reaped.
        unsafe { libc::kill(k.child.id() as libc::pid_t, libc::SIGTERM) };
    }
    wait_all(kids, TERM_GRACE);
    for k in kids.iter_mut().filter(|k| k.exit.is_none()) {
        let _ = k.child.kill();
        k.exit = k.child.wait().ok();
    }
}

fn wait_all(kids: &mut [Kid], grace: Duration) {
    let until = Instant::now() + grace;
    while Instant::now() < until {
        for k in kids.iter_mut().filter(|k| k.exit.is_none()) {
            if let Ok(Some(st)) = k.child.try_wait() {
                k.exit = Some(st);
            }
        }
        if kids.iter().all(|k| k.exit.is_some()) {
            return;
        }
        std::thread::sleep(TICK);
    }
}

/// Install SIGINT and SIGTERM handlers that record the signal in [`SIGNALLED`].
pub fn install_signal_handlers() -> Result<(), String> {
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        unsafe {
            signal_hook::low_level::register(sig, move || {
                SIGNALLED.store(sig as usize, Ordering::SeqCst);
            })
        }
        .map_err(|e| format!("cannot install a handler for signal {sig}: {e}"))?;
    }
    Ok(())
}
