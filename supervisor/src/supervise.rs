//! Multi-process launch: create the run's services (iceoryx2's, or the zenoh session with its
//! host daemons), spawn one `plant` and one `agent` per agent (here, or through the daemon of the
//! host `[[hosts]]` places it on), release the start barrier once all are ready, watch them, and
//! on any exit path stop them in order and remove every resource of the run (for a multi-host
//! run: fetch each host's files, then have its daemon kill whatever is left and clean up).
//!
//! A process on another host is a [`Handle::Remote`]: its end comes as the daemon's exit report
//! (the raw `waitpid` status), signals go through the daemon. A host whose daemon disappears is
//! lost: its processes count as killed, the timeline names the host, and in degrade mode the
//! plant is told at once that its agents are dead.
//!
//! Shutdown ladder (dora-style), used on Ctrl-C, SIGTERM and any child's failure:
//! 1. publish a stop request on the run's control service and wait [`STOP_GRACE`];
//! 2. SIGTERM whoever is left (each child stops at its next wait, flushing its telemetry) and
//!    wait [`TERM_GRACE`];
//! 3. SIGKILL whoever is still left, and reap it.
//!
//! Children run in their own process group (a terminal's Ctrl-C reaches only the orchestrator,
//! which then stops them in order) and with `PR_SET_PDEATHSIG = SIGKILL` (each child sets it
//! first thing, `die_with_parent`), so even a SIGKILLed orchestrator leaves no orphan.

use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use cohort_runtime::exit::{BUILD_MISMATCH as EXIT_BUILD_MISMATCH, STOPPED as EXIT_STOPPED};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::{RunDirs, TimelineEvent};
pub use cohort_runtime::run_status::RunStatus;
use cohort_scenario::TransportKind;
use cohort_scenario::faults::FaultPlan;
use cohort_wire::auth::MacKey;
use cohort_wire::msg::{
    PLANT_ID, Roster, STATUS_ALIVE, STATUS_DEAD, STATUS_DONE, STATUS_HOLDING, STATUS_IDLE, STATUS_PROGRESS,
    STATUS_READY, STATUS_WAITING, Status,
};
use cohort_wire::transport::iox::{IoxRun, IoxServices, RunClaim};
use cohort_wire::transport::zenoh::{ZenohHub, ZenohRun};
use cohort_wire::transport::{ControlHub, Proc};
use cohort_wire::validate::Rejection;

use crate::gateway::Gateways;
use crate::hostproto::SpawnRequest;
use crate::remote::{HostLink, Remote};

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
    pub status: RunStatus,
    pub error: Option<String>,
    pub wall_s: f64,
    /// From the first spawn to the start signal (every process ready), s.
    pub startup_s: Option<f64>,
    /// Faults carried out and roster changes, in order.
    pub timeline: Vec<TimelineEvent>,
}

impl LaunchOutcome {
    /// Exit code for the orchestrator (see [`RunStatus::exit_code`]).
    pub fn exit_code(&self) -> u8 {
        self.status.exit_code()
    }
}

/// How the supervisor reaches one child: a process of its own, or one a host daemon started.
pub(crate) enum Handle {
    Local(Child),
    Remote { remote: Arc<Remote>, link: Arc<HostLink>, proc_name: String, pid: u32 },
}

impl Handle {
    fn id(&self) -> u32 {
        match self {
            Handle::Local(c) => c.id(),
            Handle::Remote { pid, .. } => *pid,
        }
    }
    fn is_local(&self) -> bool {
        matches!(self, Handle::Local(_))
    }
    /// Its end, once known (`waitpid` here, or the daemon's report).
    pub(crate) fn try_wait(&mut self) -> Option<ExitStatus> {
        match self {
            Handle::Local(c) => c.try_wait().ok().flatten(),
            Handle::Remote { link, proc_name, pid, .. } => link.exit_of(proc_name, *pid).map(ExitStatus::from_raw),
        }
    }
    pub(crate) fn signal(&self, sig: i32) {
        match self {
            // SAFETY: kill(2) on a pid we spawned and have not reaped.
            Handle::Local(c) => unsafe {
                libc::kill(c.id() as libc::pid_t, sig);
            },
            Handle::Remote { remote, link, proc_name, .. } => {
                if !link.daemon_lost() {
                    let _ = remote.signal(link, &[proc_name], sig);
                }
            }
        }
    }
    /// SIGKILL and reap (a remote one: until its daemon reports it, or its host is lost).
    pub(crate) fn kill_wait(&mut self) -> Option<ExitStatus> {
        if let Handle::Local(c) = self {
            let _ = c.kill();
            return c.wait().ok();
        }
        self.signal(libc::SIGKILL);
        let until = Instant::now() + TERM_GRACE + STOP_GRACE;
        while Instant::now() < until && self.lost_host().is_none() {
            if let Some(st) = self.try_wait() {
                return Some(st);
            }
            std::thread::sleep(TICK);
        }
        self.try_wait()
    }
    /// The host it ran on, when that host is lost.
    fn lost_host(&self) -> Option<&str> {
        match self {
            Handle::Remote { link, .. } if link.is_lost() => Some(&link.name),
            _ => None,
        }
    }
    /// Why its host was lost (see [`Self::lost_host`]).
    fn loss(&self) -> &'static str {
        match self {
            Handle::Remote { link, .. } => link.loss(),
            Handle::Local(_) => "",
        }
    }
    /// " on host b" for a remote process.
    fn on_host(&self) -> String {
        match self {
            Handle::Local(_) => String::new(),
            Handle::Remote { link, .. } => format!(" on host {}", link.name),
        }
    }
}

struct Kid {
    proc_: Proc,
    child: Handle,
    /// Its host was lost (its end is unknown: it counts as killed).
    lost_with: Option<String>,
    exit: Option<ExitStatus>,
    ready: bool,
    /// Ended by the fault plan (kill, or the kill half of a restart).
    planned_exit: bool,
    /// Stopped by a freeze.
    frozen: bool,
    /// The hold step at which it last reported being between steps.
    idle_at: Option<u64>,
    /// Reported to the plant as dead after an unplanned exit.
    reported_dead: bool,
    /// Reported its last step done (it then keeps its ports open until the stop request).
    finished: bool,
}

impl Kid {
    fn new(proc_: Proc, child: Handle) -> Self {
        Self {
            proc_,
            child,
            lost_with: None,
            exit: None,
            ready: false,
            planned_exit: false,
            frozen: false,
            idle_at: None,
            reported_dead: false,
            finished: false,
        }
    }
    fn signal(&self, sig: i32) {
        self.child.signal(sig);
    }
    /// Reap it if it ended (or its host was lost).
    fn reap(&mut self) {
        if self.exit.is_some() {
            return;
        }
        if let Some(st) = self.child.try_wait() {
            self.exit = Some(st);
        } else if let Some(h) = self.child.lost_host() {
            self.lost_with = Some(h.to_string());
            self.exit = Some(ExitStatus::from_raw(libc::SIGKILL));
        }
    }
    /// "agent-3 (pid 1234 on host b) was killed by signal 9 (SIGKILL)", or lost with its host.
    fn describe(&self) -> String {
        let head = format!("{} (pid {}{})", self.proc_.name(), self.child.id(), self.child.on_host());
        match (&self.lost_with, self.exit) {
            (Some(h), _) => format!("{head} was lost with host {h} ({})", self.child.loss()),
            (None, Some(st)) => format!("{head} {}", describe_exit(st)),
            (None, None) => format!("{head} is running"),
        }
    }
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
pub(crate) fn sibling_binary(name: &str) -> Result<PathBuf, String> {
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

/// The descriptor number a child reads the run's MAC key from (`--key-fd`).
pub(crate) const KEY_FD: i32 = 3;

/// A pipe holding the run's key, its read end for one child to inherit as [`KEY_FD`]. The key
/// never appears in argv or the environment, which other users can read.
pub(crate) fn key_pipe(key: &MacKey) -> Result<std::fs::File, String> {
    use std::io::Write;
    use std::os::fd::FromRawFd;
    let mut fds = [0i32; 2];
    // SAFETY: pipe2 into an array we own; both ends close on exec unless dup2'd.
    if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) } != 0 {
        return Err(format!("cannot create the key pipe: {}", std::io::Error::last_os_error()));
    }
    // SAFETY: the two descriptors were just created and are owned by these Files alone.
    let (read, mut write) = unsafe { (std::fs::File::from_raw_fd(fds[0]), std::fs::File::from_raw_fd(fds[1])) };
    // 32 bytes fit in any pipe buffer: this never blocks.
    write.write_all(key.bytes()).map_err(|e| format!("cannot write the key pipe: {e}"))?;
    Ok(read)
}

/// What a child needs between fork and exec: the key pipe's read end as [`KEY_FD`], its own
/// process group (a terminal's Ctrl-C reaches only us), and death with its parent.
pub(crate) fn child_setup(cmd: &mut Command, key_raw: Option<i32>) {
    // The base directory this process resolved (its fallback, if the usual one is another
    // user's): the children must find the run's iceoryx2 files where it made them.
    cmd.env(cohort_wire::transport::iox::BASE_ENV, cohort_wire::transport::iox::user_base());
    // The child dies with this process (`die_with_parent`, its first call) and runs in a process
    // group of its own: neither needs code between fork and exec, so the standard library starts
    // it with posix_spawn, not a fork of this process's address space.
    cmd.env(cohort_runtime::process::PARENT_PID_ENV, std::process::id().to_string());
    cmd.process_group(0);
    if let Some(fd) = key_raw {
        // SAFETY: only dup2, async-signal-safe, between fork and exec. (Only an authenticated
        // run's children fork: the standard library has no way to place a descriptor.)
        unsafe {
            cmd.pre_exec(move || {
                // The key pipe's read end becomes KEY_FD, without close-on-exec (dup2 clears it).
                if libc::dup2(fd, KEY_FD) < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
}

/// Start a child on this machine; `zenoh`: its (connect, listen) endpoints.
fn spawn(
    bin: &Path,
    p: Proc,
    dirs: &RunDirs,
    run: &IoxRun,
    step_timeout_s: f64,
    restore_at: Option<u64>,
    zenoh: Option<(&str, &str)>,
) -> Result<Child, String> {
    let mut args = Vec::new();
    if let Proc::Agent(id) = p {
        args.extend(["--id".to_string(), id.to_string()]);
    }
    if let Some(k) = restore_at {
        args.extend(["--restore-at".to_string(), k.to_string()]);
    }
    let tail = ["--step-timeout-s".to_string(), format!("{step_timeout_s:?}")];
    // A relaunched agent's log goes on after its predecessor's.
    spawn_child(bin, &p.name(), (&args, &tail), dirs, run, zenoh, restore_at.is_some())
}

/// Start `bin` on this machine as the run's process `name` with `args` (before and after the
/// common ones, in the order the children have always been given them) and what every child of
/// the run gets: the run directory, id and build id, the key pipe, the zenoh endpoints (`zenoh`:
/// connect, listen) and security settings, its log (`logs/<name>.log`, appended to when
/// `append_log`), its own process group and death with this process.
pub(crate) fn spawn_child(
    bin: &Path,
    name: &str,
    args: (&[String], &[String]),
    dirs: &RunDirs,
    run: &IoxRun,
    zenoh: Option<(&str, &str)>,
    append_log: bool,
) -> Result<Child, String> {
    let log_path = dirs.logs().join(format!("{name}.log"));
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(append_log)
        .write(true)
        .truncate(!append_log)
        .open(&log_path)
        .map_err(|e| format!("{}: {e}", log_path.display()))?;
    let log2 = log.try_clone().map_err(|e| format!("{}: {e}", log_path.display()))?;
    let mut cmd = Command::new(bin);
    // Its zenoh sessions use this orchestrator's TLS and authentication settings.
    cmd.envs(cohort_wire::transport::zenoh_security::current().map_err(|e| e.to_string())?.to_env());
    cmd.args(args.0);
    let key_read = run.key.as_ref().map(key_pipe).transpose()?;
    if key_read.is_some() {
        cmd.arg("--key-fd").arg(KEY_FD.to_string());
    }
    if let Some((connect, listen)) = zenoh {
        cmd.arg("--zenoh-connect").arg(connect).arg("--zenoh-listen").arg(listen);
    }
    let key_raw = key_read.as_ref().map(std::os::fd::AsRawFd::as_raw_fd);
    cmd.arg("--run-dir")
        .arg(&dirs.root)
        .arg("--run-id")
        .arg(format!("{:016x}", run.run_id))
        .arg("--build-id")
        .arg(cohort_wire::build_id())
        .args(args.1)
        .stdin(Stdio::null())
        .stdout(Stdio::from(log))
        .stderr(Stdio::from(log2));
    cohort_runtime::logging::ChildLog::current().apply(&mut cmd);
    child_setup(&mut cmd, key_raw);
    let child = cmd.spawn().map_err(|e| format!("cannot start {}: {e}", bin.display()));
    drop(key_read); // the child has its own copy of the read end
    child
}

/// Refuse up front a run whose busiest process would run out of descriptors (iceoryx2 would fail
/// half-way through start-up with an opaque internal failure). The soft limit was raised to the
/// hard one at start.
fn check_descriptors(n_agents: u32, spare: usize) -> Result<(), String> {
    let need = cohort_wire::limits::descriptors_needed(n_agents, spare as u32);
    let (soft, hard) = cohort_wire::limits::nofile_limit();
    if need > soft {
        return Err(format!(
            "{n_agents} agents: the plant process needs ≈ {need} open files, the limit is {soft}; raise it with \
             ulimit -n (e.g. ulimit -n {}; the hard limit is {hard})",
            need.next_multiple_of(1024)
        ));
    }
    Ok(())
}

/// The run's messaging resources, held by the orchestrator for the run's life.
enum Resources {
    /// iceoryx2 (also run control of the UDP baseline): the services and the run's claim.
    Iox { services: IoxServices, claim: RunClaim },
    /// zenoh: the run-control hub on the run's session, with the host daemons' links, and each
    /// host's gateway (`run.zenoh_links = "gateway"`).
    Zenoh { hub: ZenohHub, remote: Arc<Remote>, gateways: Option<Gateways> },
}

impl Resources {
    fn hub(&self) -> &dyn ControlHub {
        match self {
            Resources::Iox { services, .. } => services,
            Resources::Zenoh { hub, .. } => hub,
        }
    }
    fn remote(&self) -> Option<&Arc<Remote>> {
        match self {
            Resources::Iox { .. } => None,
            Resources::Zenoh { remote, .. } => Some(remote),
        }
    }
    fn gateways(&self) -> Option<&Gateways> {
        match self {
            Resources::Zenoh { gateways, .. } => gateways.as_ref(),
            Resources::Iox { .. } => None,
        }
    }
    /// Create them; `spare`: agent relaunches the fault plan needs; `scenario_toml`: the run's
    /// scenario text, which the gateways' hosts are sent.
    fn create(s: &Setup, dirs: &RunDirs, run: &IoxRun, spare: usize, scenario_toml: &str) -> Result<Self, String> {
        if s.run.transport == TransportKind::Zenoh {
            let remote = Remote::open(run.run_id, &s.hosts, dirs)?;
            let zrun = ZenohRun::new(run.run_id).with_key(run.key);
            let hub = ZenohHub::create(&zrun, &remote.session).map_err(|e| e.to_string())?;
            let remote = Arc::new(remote);
            if s.uses_gateways() && s.host_of(Proc::Plant).is_none() {
                // This machine's plant opens iceoryx2 ports for every agent.
                check_descriptors(s.n_agents(), spare)?;
            }
            let gateways =
                if s.uses_gateways() { Some(Gateways::start(s, dirs, run, &remote, scenario_toml)?) } else { None };
            if !remote.hosts.is_empty() {
                crate::observe::hosts(Some(&remote));
            }
            return Ok(Resources::Zenoh { hub, remote, gateways });
        }
        check_descriptors(s.n_agents(), spare)?;
        for id in IoxRun::sweep_stale() {
            tracing::info!("removed the iceoryx2 resources of run {id:016x}, whose orchestrator is gone");
        }
        let claim =
            run.claim().map_err(|e| format!("cannot claim the run's directory {}: {e}", run.root_dir().display()))?;
        if let Some(note) = cohort_wire::transport::iox::user_base_note() {
            static SAID: std::sync::Once = std::sync::Once::new();
            SAID.call_once(|| tracing::warn!("{note}"));
        }
        match IoxServices::create(run, &s.topology(), spare) {
            Ok(services) => Ok(Resources::Iox { services, claim }),
            Err(e) => {
                run.remove_all_resources();
                Err(format!("cannot create the run's iceoryx2 services: {e}"))
            }
        }
    }
    /// Release them: remove iceoryx2's resources; or fetch every live host's files (its
    /// processes are gone by now), then have its daemon clean up. Problems, as warnings.
    fn finish(self, run: &IoxRun, dirs: &RunDirs) -> Vec<CleanupWarning> {
        let mut warnings = Vec::new();
        match self {
            Resources::Iox { services, claim } => {
                drop(services);
                run.remove_all_resources();
                drop(claim);
            }
            Resources::Zenoh { hub, remote, gateways } => {
                crate::observe::hosts(None);
                // Every process is gone by now: the gateways go next, before the files are fetched.
                if let Some(g) = &gateways {
                    g.stop();
                }
                for link in &remote.hosts {
                    let host = link.name.clone();
                    if link.daemon_lost() {
                        warnings.push(CleanupWarning::HostLost { host });
                        continue;
                    }
                    if let Err(reason) = remote.collect(link, dirs) {
                        warnings.push(CleanupWarning::Fetch { host: host.clone(), reason });
                    }
                    if let Err(reason) = remote.end(link) {
                        warnings.push(CleanupWarning::End { host, reason });
                    }
                }
                drop(hub);
            }
        }
        warnings
    }
}

/// A problem met while a run's resources are released ([`Resources::finish`]): logged as a
/// warning; whether it also fails a run that otherwise completed is its kind's.
#[derive(Debug, thiserror::Error)]
pub(crate) enum CleanupWarning {
    /// The host was lost during the run (already reported then): its files are missing, which
    /// does not fail the run by itself.
    #[error("host {host} was lost: the files of its processes are not in the run directory")]
    HostLost { host: String },
    /// A live host's files could not be fetched: the run directory is incomplete.
    #[error("cannot fetch host {host}'s files: {reason}")]
    Fetch { host: String, reason: String },
    /// A live host's daemon could not be told to clean up: the run left resources there.
    #[error("cannot end the run on host {host}: {reason}")]
    End { host: String, reason: String },
}

impl CleanupWarning {
    /// Whether a run that completed otherwise fails with this as its error.
    fn fails_run(&self) -> bool {
        !matches!(self, Self::HostLost { .. })
    }
}

/// Starts processes where the scenario places them.
struct Spawner<'a> {
    s: &'a Setup,
    dirs: &'a RunDirs,
    run: &'a IoxRun,
    bins: (PathBuf, PathBuf),
    remote: Option<Arc<Remote>>,
    scenario_toml: String,
}

impl Spawner<'_> {
    fn spawn(&self, p: Proc, restore_at: Option<u64>) -> Result<Handle, String> {
        let bin = if p == Proc::Plant { &self.bins.0 } else { &self.bins.1 };
        let step_timeout_s = self.s.run.step_timeout_s;
        let Some(remote) = &self.remote else {
            return spawn(bin, p, self.dirs, self.run, step_timeout_s, restore_at, None).map(Handle::Local);
        };
        let Some(host) = self.s.host_of(p) else {
            // Through this machine's gateway a local process needs no zenoh session of its own.
            let zenoh =
                (!self.s.uses_gateways()).then_some((remote.local_connect.as_str(), remote.local_listen.as_str()));
            return spawn(bin, p, self.dirs, self.run, step_timeout_s, restore_at, zenoh).map(Handle::Local);
        };
        let link = remote.host(&host.name).ok_or_else(|| format!("host {} has no link", host.name))?;
        if link.is_lost() {
            return Err(format!("cannot start {} on host {}: the host is lost", p.name(), host.name));
        }
        let req = SpawnRequest {
            run_id: self.run.run_id,
            build_id: cohort_wire::build_id().into(),
            proc_name: p.name(),
            restore_at,
            step_timeout_s,
            scenario_toml: self.scenario_toml.clone(),
            key_hex: self.run.key.map(|k| k.bytes().iter().map(|b| format!("{b:02x}")).collect()),
            connect: vec![link.connect.clone()],
            listen: vec![link.listen.clone()],
            log: Some(cohort_runtime::logging::ChildLog::current()),
        };
        let pid = remote.spawn(link, &req)?;
        Ok(Handle::Remote { remote: Arc::clone(remote), link: Arc::clone(link), proc_name: p.name(), pid })
    }
}

/// Launch and supervise one multi-process run. `on_step` is told the plant's step as it advances
/// (the caller's progress bar), and `s.n_steps()` once the run is done.
pub fn launch(s: &Setup, dirs: &RunDirs, run: &IoxRun, on_step: &dyn Fn(u64)) -> LaunchOutcome {
    let started = Instant::now();
    let failed = |error: String| LaunchOutcome {
        status: RunStatus::Failed,
        error: Some(error),
        wall_s: 0.0,
        startup_s: None,
        timeline: Vec::new(),
    };
    let bins = match (sibling_binary("plant"), sibling_binary("agent")) {
        (Ok(p), Ok(a)) => (p, a),
        (Err(e), _) | (_, Err(e)) => return failed(e),
    };
    let scenario_toml = match std::fs::read_to_string(dirs.scenario()) {
        Ok(t) => t,
        Err(e) => return failed(format!("{}: {e}", dirs.scenario().display())),
    };
    let plan = FaultPlan::from_scenario(s);
    let spare = plan.faults.iter().filter(|f| f.spec.kind == "restart").count();
    let resources = match Resources::create(s, dirs, run, spare, &scenario_toml) {
        Ok(r) => r,
        Err(e) => return failed(e),
    };
    let spawner = Spawner { s, dirs, run, bins, remote: resources.remote().cloned(), scenario_toml };
    let (mut kids, failure) = spawn_all(s, &spawner);
    let mut sup = Supervisor {
        s,
        dirs,
        services: resources.hub(),
        gateways: resources.gateways(),
        spawner: &spawner,
        plan,
        started,
        timeline: Vec::new(),
        unplanned: Vec::new(),
        waiting: Vec::new(),
        hosts_lost: Vec::new(),
        full_disk_reported: false,
    };
    let mut startup_s = None;
    let outcome = if failure.is_none() { sup.supervise(&mut kids, on_step, &mut startup_s) } else { (failure, None) };
    let (mut failure, signal) = outcome;
    // Thaw whoever is still frozen, so that the stop request reaches it.
    for k in kids.iter_mut().filter(|k| k.frozen && k.exit.is_none()) {
        k.signal(libc::SIGCONT);
        k.frozen = false;
    }
    let timeline = std::mem::take(&mut sup.timeline);
    let unplanned = std::mem::take(&mut sup.unplanned);
    drop(sup);
    let any_alive = kids.iter().any(|k| k.exit.is_none());
    if any_alive {
        shut_down(resources.hub(), &mut kids);
    }
    drop(spawner);
    for w in resources.finish(run, dirs) {
        tracing::warn!("{w}");
        if failure.is_none() && signal.is_none() && w.fails_run() {
            failure = Some(w.to_string());
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    if !timeline.is_empty()
        && let Ok(text) = serde_json::to_string_pretty(&timeline)
    {
        let _ = cohort_runtime::record::write_atomic(&dirs.root.join("timeline.json"), text.as_bytes());
    }
    launch_outcome(signal, failure, &unplanned, wall_s, startup_s, timeline)
}

/// Spawn the plant, then every agent, in order; the first that cannot be spawned ends it (its
/// error returned beside the children spawned so far).
fn spawn_all(s: &Setup, spawner: &Spawner<'_>) -> (Vec<Kid>, Option<String>) {
    let mut kids: Vec<Kid> = Vec::new();
    let mut failure: Option<String> = None;
    for p in std::iter::once(Proc::Plant).chain((1..=s.n_agents()).map(Proc::Agent)) {
        match spawner.spawn(p, None) {
            Ok(child) => kids.push(Kid::new(p, child)),
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    (kids, failure)
}

/// How the launch ended: interrupted by `signal`, failed with `failure`, degraded by the
/// `unplanned` losses, or ok.
fn launch_outcome(
    signal: Option<usize>,
    failure: Option<String>,
    unplanned: &[String],
    wall_s: f64,
    startup_s: Option<f64>,
    timeline: Vec<TimelineEvent>,
) -> LaunchOutcome {
    match (signal, failure) {
        (Some(sig), _) => LaunchOutcome {
            status: RunStatus::Interrupted(sig as i32),
            error: Some(format!("interrupted by signal {sig}; every child was stopped")),
            wall_s,
            startup_s,
            timeline,
        },
        (None, Some(e)) => LaunchOutcome { status: RunStatus::Failed, error: Some(e), wall_s, startup_s, timeline },
        (None, None) if !unplanned.is_empty() => LaunchOutcome {
            status: RunStatus::Degraded,
            error: Some(format!(
                "{}; the run went on without it and completed (run.on_agent_loss = \"degrade\")",
                unplanned.join("; ")
            )),
            wall_s,
            startup_s,
            timeline,
        },
        (None, None) => LaunchOutcome { status: RunStatus::Ok, error: None, wall_s, startup_s, timeline },
    }
}

/// What the supervision loop needs besides the children.
struct Supervisor<'a> {
    s: &'a Setup,
    dirs: &'a RunDirs,
    services: &'a dyn ControlHub,
    /// The run's gateways, watched every tick.
    gateways: Option<&'a Gateways>,
    spawner: &'a Spawner<'a>,
    plan: FaultPlan,
    started: Instant,
    timeline: Vec<TimelineEvent>,
    /// Agents lost outside the fault plan (degrade mode), described.
    unplanned: Vec<String>,
    /// Each process's latest waiting report (index 0 the plant).
    waiting: Vec<Option<Waiting>>,
    /// Hosts found lost so far.
    hosts_lost: Vec<String>,
    /// A full disk has been reported (once per run).
    full_disk_reported: bool,
}

/// A hold of the plant for the process faults due at `step`.
struct Hold {
    step: u64,
    since: Instant,
    /// The signals have been sent; now waiting for relaunched agents to be ready.
    acted: bool,
    relaunching: Vec<u32>,
    dead: Roster,
    alive: Roster,
}

/// How the supervision loop ends: the failure message and the signal, if any.
type Ending = (Option<String>, Option<usize>);

/// The supervision loop's state from one tick to the next.
struct Watch {
    /// run.on_agent_loss = "degrade".
    degrade: bool,
    startup_limit: Duration,
    /// The build id every child's handshake must carry.
    my_hash: u64,
    start_granted: bool,
    stop_sent: bool,
    /// When the plant was first seen done.
    plant_done_at: Option<Instant>,
    /// The plant's step, as it last reported it.
    plant_step: u64,
    /// Latest "waiting for X at step k" per sender.
    waiting: Vec<Option<Waiting>>,
    /// When a process was first seen failed.
    failed_since: Option<Instant>,
    hold: Option<Hold>,
    /// The plant's roster, as it reported it.
    off_roster: Vec<bool>,
    /// Graph conditions that stopped holding (warned once until they hold again).
    warned: Vec<String>,
}

impl Watch {
    fn new(s: &Setup) -> Self {
        Self {
            degrade: s.run.on_agent_loss == cohort_scenario::OnAgentLoss::Degrade,
            startup_limit: Duration::from_secs_f64(s.run.startup_timeout_s),
            my_hash: cohort_wire::build_id_hash(),
            start_granted: false,
            stop_sent: false,
            plant_done_at: None,
            plant_step: 0,
            waiting: vec![None; s.n_agents() as usize + 1],
            failed_since: None,
            hold: None,
            off_roster: vec![false; s.n_agents() as usize + 1],
            warned: Vec::new(),
        }
    }
}

impl Supervisor<'_> {
    fn event(&mut self, step: u64, agent: u32, event: &str, detail: String) {
        self.timeline.push(TimelineEvent {
            wall_s: self.started.elapsed().as_secs_f64(),
            step,
            t_s: step as f64 * self.s.scenario.dt_s,
            agent,
            event: event.into(),
            detail,
        });
        // The live view's copy (nothing without `--live`).
        crate::observe::emit(self.timeline.last().expect("just pushed"));
    }

    /// Whether a process fault of `agent` covers `step` (its loss then is planned).
    fn planned_loss(&self, agent: u32, step: u64) -> bool {
        self.plan
            .faults
            .iter()
            .any(|f| f.agent == agent && f.spec.is_process_fault() && f.start <= step && step < f.end)
    }

    /// Carry out a hold: once every agent a fault starts for is between steps, signal; relaunch;
    /// once the relaunched are ready, let the plant go on. Returns true when the hold is over.
    fn advance_hold(&mut self, h: &mut Hold, kids: &mut [Kid]) -> Result<bool, String> {
        let k = h.step;
        let starting: Vec<_> =
            self.plan.faults.iter().filter(|f| f.spec.is_process_fault() && f.start == k).cloned().collect();
        let ending: Vec<_> =
            self.plan.faults.iter().filter(|f| f.spec.is_process_fault() && f.end == k).cloned().collect();
        if !h.acted {
            let between_steps = |kid: &Kid| kid.exit.is_some() || kid.frozen || kid.idle_at == Some(k);
            let all_idle = starting.iter().all(|f| between_steps(&kids[f.agent as usize]));
            // A target that never reports (it is stuck) is signalled anyway after a step timeout.
            if !all_idle && h.since.elapsed().as_secs_f64() < self.s.run.step_timeout_s {
                return Ok(false);
            }
            for f in &starting {
                let kid = &mut kids[f.agent as usize];
                if kid.exit.is_some() {
                    let detail = format!("{} of agent {} skipped: its process had already ended", f.spec.kind, f.agent);
                    self.event(k, f.agent, "skipped", detail);
                    continue;
                }
                let pid = format!("{}{}", kid.child.id(), kid.child.on_host());
                match f.spec.kind.as_str() {
                    "kill" | "restart" => {
                        kid.exit = kid.child.kill_wait();
                        if kid.exit.is_none() {
                            kid.lost_with = kid.child.lost_host().map(str::to_string);
                            kid.exit = Some(ExitStatus::from_raw(libc::SIGKILL));
                        }
                        kid.planned_exit = true;
                        h.dead.set(f.agent, true);
                        self.event(k, f.agent, "kill", format!("SIGKILL to pid {pid} (faults[{}])", f.index));
                    }
                    "freeze" => {
                        kid.signal(libc::SIGSTOP);
                        kid.frozen = true;
                        self.event(k, f.agent, "freeze", format!("SIGSTOP to pid {pid} (faults[{}])", f.index));
                    }
                    _ => unreachable!("process faults are kill, freeze and restart"),
                }
            }
            for f in &ending {
                let idx = f.agent as usize;
                match f.spec.kind.as_str() {
                    "freeze" if kids[idx].frozen => {
                        kids[idx].signal(libc::SIGCONT);
                        kids[idx].frozen = false;
                        h.alive.set(f.agent, true);
                        let detail = format!("SIGCONT to pid {} (faults[{}])", kids[idx].child.id(), f.index);
                        self.event(k, f.agent, "thaw", detail);
                    }
                    "restart" if kids[idx].exit.is_some() => {
                        let child = self.spawner.spawn(Proc::Agent(f.agent), Some(k))?;
                        let detail =
                            format!("pid {} resumes from its latest checkpoint (faults[{}])", child.id(), f.index);
                        kids[idx] = Kid::new(Proc::Agent(f.agent), child);
                        h.relaunching.push(f.agent);
                        self.event(k, f.agent, "relaunch", detail);
                    }
                    _ => {}
                }
            }
            h.acted = true;
        }
        let mut i = 0;
        while i < h.relaunching.len() {
            let a = h.relaunching[i];
            let kid = &mut kids[a as usize];
            if kid.ready {
                h.alive.set(a, true);
                h.relaunching.swap_remove(i);
            } else if let Some(st) = {
                kid.reap();
                kid.exit
            } {
                kid.planned_exit = true; // it never joined; the plant keeps it dead
                let why = last_log_line(&self.dirs.logs().join(format!("agent-{a}.log"))).unwrap_or_default();
                self.event(k, a, "restore-failed", format!("the relaunched agent {}: {why}", describe_exit(st)));
                self.unplanned.push(format!("the relaunch of agent-{a} at step {k} failed: {why}"));
                h.relaunching.swap_remove(i);
            } else {
                i += 1;
            }
        }
        if !h.relaunching.is_empty() {
            if h.since.elapsed().as_secs_f64() > self.s.run.startup_timeout_s + self.s.run.step_timeout_s {
                return Err(format!(
                    "relaunched agent(s) {:?} not ready after {:.0} s (run.startup_timeout_s)",
                    h.relaunching, self.s.run.startup_timeout_s
                ));
            }
            return Ok(false);
        }
        self.services.resume(k, h.dead, h.alive).map_err(|e| format!("cannot resume the plant: {e}"))?;
        Ok(true)
    }

    /// Watch until every child has finished, one fails, or a signal arrives. Returns the failure
    /// message and the signal, if any. Each tick: read the statuses, the handshake, the faults,
    /// the end.
    fn supervise(&mut self, kids: &mut [Kid], on_step: &dyn Fn(u64), startup_s: &mut Option<f64>) -> Ending {
        let mut w = Watch::new(self.s);
        loop {
            let sig = SIGNALLED.load(Ordering::SeqCst);
            if sig != 0 {
                return (None, Some(sig));
            }
            let mismatch = self.poll(&mut w, kids);
            if let Some(e) = self.gateways.and_then(Gateways::check) {
                return (Some(e), None);
            }
            if let Err(e) = self.handshake(&mut w, kids, mismatch, startup_s) {
                return (Some(e), None);
            }
            if let Err(e) = self.faults(&mut w, kids) {
                return (Some(e), None);
            }
            if let Some(end) = self.end(&mut w, kids, on_step) {
                return end;
            }
            std::thread::sleep(TICK);
        }
    }

    /// Read the statuses the children sent since the last tick. Returns a child whose handshake
    /// build id differs from the orchestrator's.
    fn poll(&mut self, w: &mut Watch, kids: &mut [Kid]) -> Option<usize> {
        let mut mismatch = None;
        let mut statuses = Vec::new();
        let _ = self.services.poll_status(&mut |st| statuses.push(*st));
        for st in statuses {
            let idx = st.sender as usize;
            if idx >= kids.len() {
                continue;
            }
            match st.kind {
                STATUS_READY => {
                    if st.build_hash != w.my_hash {
                        mismatch = Some(idx);
                    }
                    kids[idx].ready = true;
                }
                STATUS_PROGRESS if st.sender == PLANT_ID => w.plant_step = st.step,
                STATUS_WAITING => {
                    let rejected = (st.detail as usize).checked_sub(1).and_then(|r| Rejection::ALL.get(r));
                    w.waiting[idx] = Some(Waiting { step: st.step, who: st.waiting_for, rejected: rejected.copied() });
                    self.waiting = w.waiting.clone();
                }
                STATUS_IDLE => kids[idx].idle_at = Some(st.step),
                STATUS_DONE => kids[idx].finished = true,
                STATUS_HOLDING if st.sender == PLANT_ID => {
                    w.plant_step = st.step;
                    w.hold = Some(Hold {
                        step: st.step,
                        since: Instant::now(),
                        acted: false,
                        relaunching: Vec::new(),
                        dead: Roster::EMPTY,
                        alive: Roster::EMPTY,
                    });
                }
                STATUS_DEAD | STATUS_ALIVE if st.sender == PLANT_ID => self.roster_change(w, kids, &st),
                _ => {}
            }
        }
        mismatch
    }

    /// The plant took an agent off its roster or back on: the timeline, the warnings about what
    /// the survivors' graph no longer satisfies, and an unplanned loss named.
    fn roster_change(&mut self, w: &mut Watch, kids: &[Kid], st: &Status) {
        let s = self.s;
        let a = st.waiting_for;
        let dead = st.kind == STATUS_DEAD;
        if let Some(slot) = w.off_roster.get_mut(a as usize) {
            *slot = dead;
        }
        let detail = if dead { self.dead_detail(a, st.step) } else { "back on the roster".to_string() };
        self.event(st.step, a, if dead { "dead" } else { "alive" }, detail);
        if dead && !self.planned_loss(a, st.step) {
            self.report_full_disk(a);
        }
        // What the survivors' graph still satisfies.
        let live: Vec<bool> = w.off_roster.iter().skip(1).map(|off| !off).collect();
        let now = s.roster_warnings(&live);
        for warning in now.iter().filter(|x| !w.warned.contains(*x)) {
            tracing::warn!("from step {} (t = {:.3} s): {warning}", st.step, st.step as f64 * s.scenario.dt_s);
            self.event(st.step, 0, "warning", warning.clone());
        }
        w.warned = now;
        let known = (1..kids.len()).contains(&(a as usize));
        if dead && known && !self.planned_loss(a, st.step) && !kids[a as usize].reported_dead {
            let alive = kids[a as usize].exit.is_none();
            let why = silence_of(s, a, st.step, &self.waiting, alive);
            self.unplanned.push(format!("{why}; it was marked dead"));
        }
    }

    /// The start barrier: a build mismatch fails the run; once every child is ready, grant the
    /// start (and note the start-up time); no start within run.startup_timeout_s fails the run.
    fn handshake(
        &mut self,
        w: &mut Watch,
        kids: &[Kid],
        mismatch: Option<usize>,
        startup_s: &mut Option<f64>,
    ) -> Result<(), String> {
        if let Some(idx) = mismatch {
            let name = kids[idx].proc_.name();
            return Err(format!(
                "{name} was built from other sources than the orchestrator (handshake build id differs): rebuild the workspace"
            ));
        }
        if !w.start_granted && kids.iter().all(|k| k.ready) {
            if let Err(e) = self.services.grant_start() {
                return Err(format!("cannot send the start signal: {e}"));
            }
            w.start_granted = true;
            *startup_s = Some(self.started.elapsed().as_secs_f64());
        }
        if !w.start_granted && self.started.elapsed() > w.startup_limit {
            let slow: Vec<String> = kids.iter().filter(|k| !k.ready).map(|k| k.proc_.name()).collect();
            return Err(format!(
                "start-up timeout: {} not ready after {:.0} s (run.startup_timeout_s)",
                slow.join(", "),
                w.startup_limit.as_secs_f64()
            ));
        }
        Ok(())
    }

    /// Reap the children, note lost hosts, carry the plant's hold for process faults on, and in
    /// degrade mode report an agent that ended outside the plan to the plant at once.
    fn faults(&mut self, w: &mut Watch, kids: &mut [Kid]) -> Result<(), String> {
        let s = self.s;
        // One system call instead of one per local child (a 1 000-agent run spent 87 000 `wait4`
        // a second of the orchestrator's time on this loop): a local child needs reaping only
        // when one has ended.
        let local_ended = a_child_has_ended();
        for k in kids.iter_mut().filter(|k| local_ended || !k.child.is_local()) {
            k.reap();
        }
        self.note_lost_hosts(kids, w.plant_step);
        if let Some(h) = &mut w.hold
            && self.advance_hold(h, kids)?
        {
            w.hold = None;
        }
        if w.degrade {
            let plant_step = w.plant_step;
            for i in 1..kids.len() {
                let k = &kids[i];
                let unplanned = k.exit.is_some_and(|st| !st.success()) && !k.planned_exit && !k.reported_dead;
                if unplanned && !w.off_roster[i] && kids[0].exit.is_none() {
                    let mut r = Roster::EMPTY;
                    r.set(i as u32, true);
                    let _ = self.services.report_dead(r);
                    let msg = format!(
                        "{} at or after step {plant_step} (t = {:.3} s)",
                        self.describe_kid(&kids[i]),
                        plant_step as f64 * s.scenario.dt_s
                    );
                    self.event(plant_step, i as u32, "died", msg.clone());
                    self.unplanned.push(msg);
                    kids[i].reported_dead = true;
                }
            }
        }
        Ok(())
    }

    /// Progress; the stop request once the plant is done; the end when every agent on its roster
    /// is done too, or (after a short window to see who failed first) when a process failed.
    /// None: go on.
    fn end(&mut self, w: &mut Watch, kids: &[Kid], on_step: &dyn Fn(u64)) -> Option<Ending> {
        let s = self.s;
        on_step(w.plant_step);
        let plant_ok = kids[0].exit.is_some_and(|st| st.success());
        // Every last share the plant needed has been read; the agents' last shares to each other
        // may still be on their way (behind a slower link than the plant's), so the stop that
        // lets the agents keeping their ports open leave (see `keeps_ports_until_stopped`) waits
        // until every agent on the roster has said it finished — or a step timeout, should a
        // best-effort status be lost.
        let since = plant_ok.then(|| *w.plant_done_at.get_or_insert_with(Instant::now));
        let settled = |(i, k): (usize, &Kid)| k.finished || k.exit.is_some() || w.off_roster[i];
        if let Some(since) = since
            && !w.stop_sent
            && (kids.iter().enumerate().skip(1).all(settled)
                || since.elapsed() >= Duration::from_secs_f64(s.run.step_timeout_s))
        {
            let _ = self.services.request_stop();
            w.stop_sent = true;
        }
        // Done when the plant is, and every agent on its roster has finished.
        let agents_done =
            kids.iter().enumerate().skip(1).all(|(i, k)| k.exit.is_some_and(|st| st.success()) || w.off_roster[i]);
        if plant_ok && agents_done {
            on_step(s.n_steps());
            return Some((None, None));
        }
        // Stopped before its last step was done, after the plant's end: the run cannot complete.
        if plant_ok && w.stop_sent && kids.iter().all(|k| k.exit.is_some()) {
            let short: Vec<String> = kids
                .iter()
                .enumerate()
                .skip(1)
                .filter(|(i, k)| !w.off_roster[*i] && !k.exit.is_some_and(|st| st.success()))
                .map(|(_, k)| self.describe_kid(k))
                .collect();
            return Some((Some(format!("the run ended before every agent finished: {}", short.join("; "))), None));
        }
        let failed_kid = |k: &Kid| k.exit.is_some_and(|st| !st.success()) && !k.planned_exit;
        let failing =
            if w.degrade { kids[0].exit.is_some_and(|st| !st.success()) } else { kids.iter().any(failed_kid) };
        if failing {
            // When one process fails the others usually follow within moments (everyone times
            // out waiting for the same silent peer). Collect for a short window, then name the
            // root cause rather than whichever consequence exited first.
            let since = *w.failed_since.get_or_insert_with(Instant::now);
            if since.elapsed() >= BLAME_WAIT {
                return Some((Some(blame(s, self.dirs, kids, &w.waiting, w.plant_step)), None));
            }
        }
        None
    }

    fn dead_detail(&self, agent: u32, step: u64) -> String {
        // How long after the fault that caused it, when one did.
        let cause = self
            .timeline
            .iter()
            .rev()
            .find(|e| e.agent == agent && matches!(e.event.as_str(), "kill" | "freeze" | "died"));
        match cause {
            Some(c) => format!(
                "marked dead from step {step}, {:.3} s (wall) after the {} was seen",
                self.started.elapsed().as_secs_f64() - c.wall_s,
                c.event
            ),
            None => format!("marked dead from step {step}"),
        }
    }

    /// An agent that died because the disk is full: say so at once, before the warnings its loss
    /// brings (a full disk dooms the run, and its cause must come first, not after them).
    fn report_full_disk(&mut self, a: u32) {
        let Some(line) = last_log_line(&self.dirs.logs().join(format!("agent-{a}.log"))) else { return };
        if !self.full_disk_reported && (line.contains("No space left on device") || line.contains("os error 28")) {
            tracing::error!("agent-{a} stopped: {line}");
            self.full_disk_reported = true;
        }
    }

    /// A host found lost: the timeline names it and the processes it took.
    fn note_lost_hosts(&mut self, kids: &[Kid], plant_step: u64) {
        let mut lost: Vec<String> = kids.iter().filter_map(|k| k.lost_with.clone()).collect();
        lost.dedup();
        for h in lost {
            if self.hosts_lost.contains(&h) {
                continue;
            }
            let on: Vec<&Kid> = kids.iter().filter(|k| k.lost_with.as_deref() == Some(h.as_str())).collect();
            let why = on.first().map_or("", |k| k.child.loss());
            let names: Vec<String> = on.iter().map(|k| k.proc_.name()).collect();
            let msg =
                format!("host {h} lost at or after step {plant_step}: {why}, taking {} with it", names.join(", "));
            tracing::warn!("{msg}");
            self.event(plant_step, 0, "host-lost", msg);
            self.hosts_lost.push(h);
        }
    }

    fn describe_kid(&self, k: &Kid) -> String {
        let st = k.exit.expect("exited");
        let mut m = k.describe();
        if st.signal().is_none()
            && let Some(line) = last_log_line(&self.dirs.logs().join(format!("{}.log", k.proc_.name())))
        {
            m.push_str(&format!(" [log: {line}]"));
        }
        m
    }
}

/// The failure message: a process killed by a signal if there is one, else the agent the plant
/// was stuck waiting for, else the first failed process; each with the step and its log's last
/// line, followed by the other failures.
/// A process's latest "waiting for `who` in `step`" report, and why `who`'s latest message was
/// rejected if it was.
#[derive(Debug, Clone, Copy)]
struct Waiting {
    step: u64,
    who: u32,
    rejected: Option<Rejection>,
}

/// Why agent `who` sent the plant nothing for `step`: silence, unless a rejected message explains
/// it — the plant rejected its share, or it rejected the plant's measurement and waited for a
/// valid one. The process whose message was rejected is named, not the one that waited.
fn silence_of(s: &Setup, who: u32, step: u64, waiting: &[Option<Waiting>], alive: bool) -> String {
    let t = step as f64 * s.scenario.dt_s;
    let timeout = s.run.step_timeout_s;
    let plant = waiting.first().copied().flatten().filter(|w| w.who == who);
    let agent = waiting.get(who as usize).copied().flatten().filter(|w| w.who == PLANT_ID);
    if let Some(r) = plant.and_then(|w| w.rejected) {
        return format!(
            "the plant rejected agent {who}'s share of step {step} (t = {t:.3} s) as {} (damaged in transit or \
             not of this run) and no valid one came within run.step_timeout_s = {timeout:?} s",
            r.name()
        );
    }
    if let Some(w) = agent.filter(|w| w.rejected.is_some()) {
        return format!(
            "agent {who} rejected the plant's measurement of step {} as {} (damaged in transit or not of this run) \
             and waited for a valid one, so no share of step {step} (t = {t:.3} s) reached the plant within \
             run.step_timeout_s = {timeout:?} s",
            w.step,
            w.rejected.map_or("", |r| r.name())
        );
    }
    let state = if alive { " (its process is alive but silent)" } else { "" };
    format!(
        "agent {who} went silent{state}: no share of step {step} (t = {t:.3} s) reached the plant within \
         run.step_timeout_s = {timeout:?} s"
    )
}

fn blame(s: &Setup, dirs: &RunDirs, kids: &[Kid], waiting: &[Option<Waiting>], plant_step: u64) -> String {
    let plant_waiting = waiting.first().copied().flatten().map(|w| (w.step, w.who));
    let failed: Vec<&Kid> = kids.iter().filter(|k| k.exit.is_some_and(|st| !st.success())).collect();
    let t = |step: u64| step as f64 * s.scenario.dt_s;
    let describe = |k: &Kid| {
        let st = k.exit.expect("failed kids have exited");
        let mut m = k.describe();
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
            first_names(&refused, NAMES_SHOWN),
            cohort_wire::build_id()
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
        if k.proc_ == Proc::Plant {
            m.push_str("; the plant is the run's clock, so the run cannot go on without it");
        }
        m
    } else if let Some((step, who)) = plant_waiting.filter(|(_, who)| *who != 0) {
        let alive = kids.iter().find(|k| k.proc_ == Proc::Agent(who)).is_some_and(|k| k.exit.is_none());
        silence_of(s, who, step, waiting, alive)
    } else {
        describe(failed[0])
    };
    // The others, briefly: they usually failed because of the primary.
    let others: Vec<String> =
        failed.iter().filter(|k| primary.is_none_or(|p| p.proc_ != k.proc_)).map(|k| describe(k)).collect();
    let logs_empty = kids.iter().all(|k| last_log_line(&dirs.logs().join(format!("{}.log", k.proc_.name()))).is_none());
    const SHOWN: usize = 3;
    if !others.is_empty() {
        msg.push_str(&format!("; then: {}", others[..others.len().min(SHOWN)].join("; ")));
        if others.len() > SHOWN {
            let more = others.len() - SHOWN;
            msg.push_str(&if logs_empty {
                format!("; and {more} more")
            } else {
                format!("; and {more} more (see logs/)")
            });
        }
    }
    match free_bytes(&dirs.root) {
        // Nothing in any log, and no room left: that is the cause, and no log will say it.
        Some(free) if logs_empty && free < FULL_BELOW_BYTES => format!(
            "the file system of {} is full ({free} bytes free; No space left on device): its processes could \
             write neither logs nor reports; {msg}",
            dirs.root.display()
        ),
        _ => msg,
    }
}

/// How many process names a message lists before it counts the rest.
const NAMES_SHOWN: usize = 6;

/// `names` joined, the first `shown` of a longer list and how many more: a thousand-agent run
/// whose children all refuse gets one line, not a thousand names.
fn first_names(names: &[String], shown: usize) -> String {
    if names.len() <= shown + 1 {
        return names.join(", ");
    }
    format!("{} and {} more ({} processes)", names[..shown].join(", "), names.len() - shown, names.len())
}

/// Below this many free bytes a file system counts as full: a process's first log line or report
/// no longer fits.
const FULL_BELOW_BYTES: u64 = 64 << 10;

/// Bytes an unprivileged process may still write on the file system holding `dir`.
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt as _;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: statvfs fills the struct we own from a NUL-terminated path.
    (unsafe { libc::statvfs(c.as_ptr(), &mut st) } == 0).then(|| st.f_bavail as u64 * st.f_frsize as u64)
}

/// Stop every live child: stop request, then SIGTERM, then SIGKILL (see the module docs).
fn shut_down(services: &dyn ControlHub, kids: &mut [Kid]) {
    let _ = services.request_stop();
    wait_all(kids, STOP_GRACE);
    signal_all(kids.iter().filter(|k| k.exit.is_none()).map(|k| &k.child), libc::SIGTERM);
    wait_all(kids, TERM_GRACE);
    signal_all(kids.iter().filter(|k| k.exit.is_none()).map(|k| &k.child), libc::SIGKILL);
    wait_all(kids, TERM_GRACE + STOP_GRACE);
    // Local ones are reaped (a SIGKILLed child ends); a remote one whose daemon never reported
    // it stays unknown, as its host's end takes it.
    for k in kids.iter_mut().filter(|k| k.exit.is_none() && matches!(k.child, Handle::Local(_))) {
        k.exit = k.child.kill_wait();
        k.reap();
    }
}

/// Send `sig` to every one of `children`: a local one at once, the remote ones in one request per
/// host (a thousand processes on an unresponsive host cost one request timeout, not a thousand).
pub(crate) fn signal_all<'a>(children: impl Iterator<Item = &'a Handle>, sig: i32) {
    let mut by_host: Vec<(&Arc<Remote>, &Arc<HostLink>, Vec<&str>)> = Vec::new();
    for c in children {
        match c {
            Handle::Local(_) => c.signal(sig),
            Handle::Remote { remote, link, proc_name, .. } => {
                match by_host.iter_mut().find(|(_, l, _)| Arc::ptr_eq(l, link)) {
                    Some((_, _, names)) => names.push(proc_name),
                    None => by_host.push((remote, link, vec![proc_name])),
                }
            }
        }
    }
    for (remote, link, names) in by_host.into_iter().filter(|(_, l, _)| !l.daemon_lost()) {
        if let Err(e) = remote.signal(link, &names, sig) {
            tracing::warn!("signal {sig} to {} process(es) on host {}: {e}", names.len(), link.name);
        }
    }
}

/// Whether any child of this process has ended and is not reaped yet (it stays unreaped:
/// `WNOWAIT`). True also when that cannot be told, so the caller looks at each child.
fn a_child_has_ended() -> bool {
    // SAFETY: waitid writes only into the siginfo we own; WNOWAIT leaves the child to be reaped.
    unsafe {
        let mut info: libc::siginfo_t = std::mem::zeroed();
        let r = libc::waitid(libc::P_ALL, 0, &mut info, libc::WEXITED | libc::WNOHANG | libc::WNOWAIT);
        // No child at all (ECHILD) means none ended; any other failure: look at each.
        if r != 0 {
            return std::io::Error::last_os_error().raw_os_error() != Some(libc::ECHILD);
        }
        info.si_pid() != 0
    }
}

fn wait_all(kids: &mut [Kid], grace: Duration) {
    let until = Instant::now() + grace;
    while Instant::now() < until {
        for k in kids.iter_mut() {
            k.reap();
        }
        if kids.iter().all(|k| k.exit.is_some()) {
            return;
        }
        std::thread::sleep(TICK);
    }
}

/// Install SIGINT, SIGTERM and SIGHUP (a closed terminal) handlers that record the signal in
/// [`SIGNALLED`]: the run is then stopped in order, its summary written and its resources removed.
pub fn install_signal_handlers() -> Result<(), SignalHandlerError> {
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        unsafe {
            signal_hook::low_level::register(sig, move || {
                SIGNALLED.store(sig as usize, Ordering::SeqCst);
            })
        }
        .map_err(|source| SignalHandlerError { signal: sig, source })?;
    }
    Ok(())
}

/// A signal handler [`install_signal_handlers`] could not install (exit 1).
#[derive(Debug, thiserror::Error)]
#[error("cannot install a handler for signal {signal}: {source}")]
pub struct SignalHandlerError {
    pub signal: i32,
    pub source: std::io::Error,
}

impl cohort_runtime::exit::ToExitCode for SignalHandlerError {
    fn exit_code(&self) -> u8 {
        cohort_runtime::exit::FAILED
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_list_of_names_is_cut_and_counted() {
        let names: Vec<String> =
            std::iter::once("plant".to_string()).chain((1..=1000).map(|i| Proc::Agent(i).name())).collect();
        assert_eq!(first_names(&names, 3), "plant, agent-1, agent-2 and 998 more (1001 processes)");
        assert_eq!(first_names(&names[..4], 3), "plant, agent-1, agent-2, agent-3");
        assert_eq!(first_names(&names[..1], 3), "plant");
    }
}
