//! What the `plant` and `agent` binaries share: the handshake checks, signals, opening the
//! run's transport (iceoryx2, UDP or zenoh), running the driver, writing the report, and the exit code.
//!
//! Exit codes (the orchestrator reads them; the constants and the mapping are [`crate::exit`]'s):
//! - 0: every step done;
//! - 1: the run failed (timeout, transport error, I/O error);
//! - 2: bad input (the resolved scenario in the run directory does not validate);
//! - 3: built from other sources than the orchestrator (build id mismatch);
//! - 4: stopped on request (stop message or SIGTERM) before the end.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use cohort_scenario::{ScenarioError, TransportKind};
use cohort_wire::auth::MacKey;
use cohort_wire::transport::iox::{IoxData, IoxRun};
use cohort_wire::transport::udp;
use cohort_wire::transport::zenoh::{ZenohData, ZenohRun};
use cohort_wire::transport::{Proc, Transport, TransportError};

use tracing::{debug, error, info};

use crate::drive::DriveParams;
use crate::exit::ToExitCode;
use crate::paper::{Paper, Setup};
use crate::record::{ErrorKind, ProcessError, ProcessReport, RunDirs};
use crate::recording::writer::{RecordMeta, Recording};

/// The command-line arguments every child takes (the agent adds `--id`).
#[derive(clap::Args, Debug)]
pub struct CommonArgs {
    /// Run directory (holds the resolved scenario.toml; telemetry goes there).
    #[arg(long)]
    pub run_dir: PathBuf,
    /// Run id, hexadecimal (names the run's iceoryx2 resources).
    #[arg(long)]
    pub run_id: String,
    /// Build id of the orchestrator; must equal this binary's.
    #[arg(long)]
    pub build_id: String,
    /// Override of run.step_timeout_s.
    #[arg(long)]
    pub step_timeout_s: Option<f64>,
    /// `run.authenticate`: the inherited descriptor to read the run's MAC key from (never the key
    /// itself: argv and the environment are readable by others).
    #[arg(long)]
    pub key_fd: Option<i32>,
    /// `run.transport = "zenoh"`: the orchestrator's zenoh endpoint to connect to.
    #[arg(long)]
    pub zenoh_connect: Vec<String>,
    /// `run.transport = "zenoh"`: the endpoint this process listens on for its peers (on its
    /// host's address, port 0).
    #[arg(long)]
    pub zenoh_listen: Vec<String>,
}

impl CommonArgs {
    pub fn into_spec(self, me: Proc) -> ChildSpec {
        ChildSpec {
            me,
            run_dir: self.run_dir,
            run_id: self.run_id,
            build_id: self.build_id,
            step_timeout_s: self.step_timeout_s,
            key_fd: self.key_fd,
            zenoh_connect: self.zenoh_connect,
            zenoh_listen: self.zenoh_listen,
            record_attachments: Vec::new(),
        }
    }
}

/// What the orchestrator passes every child on its command line.
pub struct ChildSpec {
    pub me: Proc,
    pub run_dir: PathBuf,
    /// Run id in hex (it names the run's iceoryx2 prefix).
    pub run_id: String,
    pub build_id: String,
    pub step_timeout_s: Option<f64>,
    pub key_fd: Option<i32>,
    pub zenoh_connect: Vec<String>,
    pub zenoh_listen: Vec<String>,
    /// With `run.record`: files the process's recording carries (a relaunched agent's: the
    /// checkpoint it resumes from, so that its replay can resume from the same state).
    pub record_attachments: Vec<crate::recording::walk::Attachment>,
}

/// Why a child process could not get to its first step; each names the argument or setting
/// at fault. [`ToExitCode`] gives its exit code.
#[derive(Debug, thiserror::Error)]
pub enum ChildStartError {
    #[error(
        "refusing to run: built from {ours} but the orchestrator is {theirs} — rebuild the workspace (cargo build --release)"
    )]
    BuildMismatch { ours: &'static str, theirs: String },
    #[error("--run-id {0:?}: not a hexadecimal run id")]
    RunId(String),
    #[error("{0}")]
    Scenario(#[from] ScenarioError),
    #[error("--id {id}: out of range, the scenario has agents 1..={n_agents}")]
    AgentId { id: u32, n_agents: u32 },
    #[error("--key-fd {fd}: cannot read the run's key: {source}")]
    KeyFd { fd: i32, source: std::io::Error },
    #[error("run.authenticate is on but no --key-fd was given: the orchestrator hands the key over")]
    NoKeyFd,
    #[error("cannot install the handler of signal {signal}: {source}")]
    SignalHandler { signal: i32, source: std::io::Error },
    /// Stopped on request while the transport was being opened.
    #[error("{0}")]
    Stopped(TransportError),
    #[error("cannot open the run's services: {0}")]
    Transport(TransportError),
}

impl ToExitCode for ChildStartError {
    fn exit_code(&self) -> u8 {
        use crate::exit::{BUILD_MISMATCH, FAILED, INVALID, STOPPED};
        match self {
            Self::BuildMismatch { .. } => BUILD_MISMATCH,
            Self::RunId(_) | Self::Scenario(_) | Self::AgentId { .. } | Self::KeyFd { .. } | Self::NoKeyFd => INVALID,
            Self::SignalHandler { .. } | Self::Transport(_) => FAILED,
            Self::Stopped(_) => STOPPED,
        }
    }
}

/// What a child has once it is ready for its first step.
struct Started {
    scenario: Setup,
    transport: Box<dyn Transport>,
    params: DriveParams,
}

/// The environment variable naming the pid of the process that started this child of a run.
pub const PARENT_PID_ENV: &str = "COHORT_PARENT_PID";

/// Die with the process that started this one: `PR_SET_PDEATHSIG = SIGKILL`, then, if that
/// process already ended (the child was adopted before the call), exit. A child of a run calls it
/// first thing; outside a run (no [`PARENT_PID_ENV`]) it does nothing.
///
/// The child does this itself, not its parent between fork and exec, so the parent can start it
/// with `posix_spawn` (a `vfork`) instead of a `fork` that copies the parent's page tables: with a
/// thousand agents the orchestrator maps thousands of iceoryx2 segments, and its forks were a
/// sixth of a thousand-agent start-up's CPU, one after another.
pub fn die_with_parent() {
    let Some(parent) = std::env::var(PARENT_PID_ENV).ok().and_then(|v| v.parse::<libc::pid_t>().ok()) else {
        return;
    };
    // SAFETY: prctl and getppid have no memory effects.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong, 0, 0, 0);
        if libc::getppid() != parent {
            libc::_exit(1);
        }
    }
}

/// Run one child process to its end. The run directory's resolved scenario is configured with
/// the kinds of `papers` (the registry's list); `run` builds the model and calls the driver.
pub fn child_main(
    spec: ChildSpec,
    papers: &[&'static dyn Paper],
    run: impl FnOnce(&Setup, &mut dyn Transport, &DriveParams) -> ProcessReport,
) -> ExitCode {
    die_with_parent();
    let start = Instant::now();
    let me = spec.me;
    limit_malloc_arenas();
    // Lines to this process's log (its stderr, a file under the run's logs/), with level, name
    // and run time; a failed write (a full disk) is ignored: the exit code and report say it.
    crate::logging::init_child(&me.name());
    let Started { scenario, mut transport, params } = match start_child(&spec, papers, start) {
        Ok(s) => s,
        Err(e) => {
            if matches!(e, ChildStartError::Stopped(_)) {
                info!("{e}");
            } else {
                error!("{e}");
            }
            return e.to_exit();
        }
    };
    let dirs = params.dirs.clone();
    release_freed_heap();
    info!("ready ({} steps of {} s)", params.n_steps, params.dt_s);
    let report = if scenario.run.record && matches!(me, Proc::Agent(_)) {
        // `run.record`: this agent's messages to record/<proc>.mcap (see `recording`).
        let mut meta = RecordMeta::from_setup(&scenario, params.run_id, me);
        meta.attachments = spec.record_attachments.clone();
        match Recording::start(transport.as_mut(), &spec.run_dir, meta) {
            Ok(mut rec) => {
                let mut report = run(&scenario, &mut rec, &params);
                if let Err(e) = rec.finish()
                    && report.error.is_none()
                {
                    report.error = Some(ProcessError::new(ErrorKind::Io, format!("recording {e}")));
                }
                report
            }
            Err(e) => ProcessReport::failed_at_start(
                me.name(),
                ProcessError::new(ErrorKind::Io, format!("cannot record: {e}")),
            ),
        }
    } else {
        run(&scenario, transport.as_mut(), &params)
    };
    drop(transport); // release the ports before exiting
    if let Err(e) = report.write(&dirs) {
        error!("cannot write status/{}.json: {e}", me.name());
    }
    match &report.error {
        None => {
            info!("done: {} steps in {:.3} s", report.steps_completed, report.wall_s);
            ExitCode::from(crate::exit::OK)
        }
        Some(e) if e.is_stop() => {
            info!("{e}");
            e.to_exit()
        }
        Some(e) => {
            error!("{e}");
            e.to_exit()
        }
    }
}

/// From the command line to the first step: the handshake checks, the resolved scenario, the
/// run's key, the signal handlers and the run's transport.
fn start_child(spec: &ChildSpec, papers: &[&'static dyn Paper], start: Instant) -> Result<Started, ChildStartError> {
    let me = spec.me;
    if spec.build_id != cohort_wire::build_id() {
        return Err(ChildStartError::BuildMismatch { ours: cohort_wire::build_id(), theirs: spec.build_id.clone() });
    }
    let run_id = u64::from_str_radix(&spec.run_id, 16).map_err(|_| ChildStartError::RunId(spec.run_id.clone()))?;
    let dirs = RunDirs::new(&spec.run_dir);
    let overrides = cohort_scenario::Overrides { step_timeout_s: spec.step_timeout_s, ..Default::default() };
    crate::paper::skip_deep_checks();
    let scenario = crate::paper::load_run(&dirs, &overrides, papers)?;
    if let Proc::Agent(id) = me
        && (id == 0 || id > scenario.n_agents())
    {
        return Err(ChildStartError::AgentId { id, n_agents: scenario.n_agents() });
    }
    let key = match (spec.key_fd, scenario.run.authenticate) {
        (Some(fd), _) => Some(MacKey::read_from_fd(fd).map_err(|source| ChildStartError::KeyFd { fd, source })?),
        (None, true) => return Err(ChildStartError::NoKeyFd),
        (None, false) => None,
    };
    // Ctrl-C belongs to the orchestrator, which stops its children in order; SIGTERM (and SIGHUP,
    // a closed terminal) asks this process to stop at its next wait, flushing its telemetry.
    let terminate = Arc::new(AtomicBool::new(false));
    // SAFETY: ignoring SIGINT installs no handler code.
    unsafe { libc_ignore_sigint() };
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP] {
        signal_hook::flag::register(signal, Arc::clone(&terminate))
            .map_err(|source| ChildStartError::SignalHandler { signal, source })?;
    }
    debug!(
        "scenario {:?}: {} agents, transport {:?}, run dir {} (CPU so far {:.1} ms)",
        scenario.scenario.name,
        scenario.n_agents(),
        scenario.run.transport,
        spec.run_dir.display(),
        crate::record::cpu_and_rss().0 * 1e3
    );
    let topo = scenario.topology();
    let iox_run = IoxRun::new(run_id).with_key(key);
    let opened: Result<Box<dyn Transport>, _> = match scenario.run.transport {
        TransportKind::Udp => {
            let timeout = Duration::from_secs_f64(scenario.run.startup_timeout_s);
            udp::open(&iox_run, &topo, me, &spec.run_dir.join("udp"), timeout).map(|t| Box::new(t) as _)
        }
        TransportKind::Iceoryx2 => IoxData::open(&iox_run, &topo, me).map(|t| Box::new(t) as _),
        // Through this host's gateway: iceoryx2 in the host's domain, which the gateway created
        // before this process was started.
        TransportKind::Zenoh if scenario.uses_gateways() => {
            let placement = Arc::new(scenario.placement());
            let here = placement.host(me);
            IoxData::open(&iox_run.clone().in_domain(placement, here), &topo, me).map(|t| Box::new(t) as _)
        }
        TransportKind::Zenoh => {
            let timeout = Duration::from_secs_f64(scenario.run.startup_timeout_s);
            let run = ZenohRun::new(run_id).with_key(key);
            ZenohData::declare(&run, &topo, me, &spec.zenoh_listen, &spec.zenoh_connect)
                .and_then(|p| p.ready_unless(timeout, &terminate))
                .map(|t| Box::new(t) as _)
        }
    };
    let transport = opened.map_err(|e| match e {
        TransportError::Stopped(_) => ChildStartError::Stopped(e),
        e => ChildStartError::Transport(e),
    })?;
    debug!("the run's services are open (CPU so far {:.1} ms)", crate::record::cpu_and_rss().0 * 1e3);
    let mut params = DriveParams::from_setup(&scenario, run_id, dirs, terminate, start);
    params.key = key;
    Ok(Started { scenario, transport, params })
}

/// At most two malloc arenas: glibc gives each thread that allocates an arena of its own (up to
/// eight per core), and a 1 000-agent plant's writer threads held eleven of them, 101 MB. Our
/// threads hand rows over channels, so they seldom allocate at once.
fn limit_malloc_arenas() {
    // SAFETY: mallopt only sets an allocator parameter; called before this process starts any
    // thread of its own.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 2);
    }
}

/// Give back to the system what start-up allocated and freed (a 1 000-agent scenario's parse
/// tree: ~5 MB of an agent's 10), which the heap would otherwise keep for the whole run.
fn release_freed_heap() {
    // SAFETY: malloc_trim only returns free heap pages; it touches no live allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}

unsafe fn libc_ignore_sigint() {
    // SAFETY: SIG_IGN is a valid disposition for SIGINT.
    unsafe {
        libc::signal(libc::SIGINT, libc::SIG_IGN);
    }
}
