//! What the `plant` and `agent` binaries share: the handshake checks, signals, opening the
//! run's transport (iceoryx2, UDP or zenoh), running the driver, writing the report, and the exit code.
//!
//! Exit codes (the orchestrator reads them):
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

use cohort_scenario::TransportKind;
use cohort_wire::auth::MacKey;
use cohort_wire::transport::iox::{IoxData, IoxRun};
use cohort_wire::transport::udp;
use cohort_wire::transport::zenoh::{ZenohData, ZenohRun};
use cohort_wire::transport::{Proc, Transport};

use tracing::{debug, error, info};

use crate::drive::DriveParams;
use crate::paper::{Paper, Setup};
use crate::record::{ErrorKind, ProcessError, ProcessReport, RunDirs};
use crate::recording::writer::{RecordMeta, Recording};

pub const EXIT_OK: u8 = 0;
pub const EXIT_RUN_FAILED: u8 = 1;
pub const EXIT_BAD_INPUT: u8 = 2;
pub const EXIT_BUILD_MISMATCH: u8 = 3;
pub const EXIT_STOPPED: u8 = 4;

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

/// Run one child process to its end. The run directory's resolved scenario is configured with
/// the kinds of `papers` (the registry's list); `run` builds the model and calls the driver.
pub fn child_main(
    spec: ChildSpec,
    papers: &[&'static dyn Paper],
    run: impl FnOnce(&Setup, &mut dyn Transport, &DriveParams) -> ProcessReport,
) -> ExitCode {
    let start = Instant::now();
    let me = spec.me;
    // Lines to this process's log (its stderr, a file under the run's logs/), with level, name
    // and run time; a failed write (a full disk) is ignored: the exit code and report say it.
    crate::logging::init_child(&me.name());
    let (run_id, scenario, key) = match checked_setup(&spec, papers) {
        Ok(x) => x,
        Err(code) => return ExitCode::from(code),
    };
    let terminate = match stop_signals() {
        Ok(t) => t,
        Err(code) => return ExitCode::from(code),
    };
    debug!(
        "scenario {:?}: {} agents, transport {:?}, run dir {} (CPU so far {:.1} ms)",
        scenario.scenario.name,
        scenario.n_agents(),
        scenario.run.transport,
        spec.run_dir.display(),
        crate::record::cpu_and_rss().0 * 1e3
    );
    let mut transport = match open_transport(&spec, &scenario, run_id, key, &terminate) {
        Ok(t) => t,
        Err(code) => return ExitCode::from(code),
    };
    debug!("the run's services are open (CPU so far {:.1} ms)", crate::record::cpu_and_rss().0 * 1e3);
    let dirs = RunDirs::new(&spec.run_dir);
    let mut params = DriveParams::from_setup(&scenario, run_id, dirs.clone(), terminate, start);
    params.key = key;
    info!("ready ({} steps of {} s)", params.n_steps, params.dt_s);
    let report = drive(&spec, &scenario, run_id, transport.as_mut(), &params, run);
    drop(transport); // release the ports before exiting
    if let Err(e) = report.write(&dirs) {
        error!("cannot write status/{}.json: {e}", me.name());
    }
    exit_code(&report)
}

/// The checks before anything is opened: the build id, the run id, the resolved scenario, the
/// agent's id, the run's key. Returns (run id, scenario, key), or the exit code, said in the log.
fn checked_setup(spec: &ChildSpec, papers: &[&'static dyn Paper]) -> Result<(u64, Setup, Option<MacKey>), u8> {
    let me = spec.me;
    if spec.build_id != cohort_wire::BUILD_ID {
        error!(
            "refusing to run: built from {} but the orchestrator is {} — rebuild the workspace (cargo build --release)",
            cohort_wire::BUILD_ID,
            spec.build_id
        );
        return Err(EXIT_BUILD_MISMATCH);
    }
    let Ok(run_id) = u64::from_str_radix(&spec.run_id, 16) else {
        error!("--run-id {:?}: not a hexadecimal run id", spec.run_id);
        return Err(EXIT_BAD_INPUT);
    };
    let overrides = cohort_scenario::Overrides { step_timeout_s: spec.step_timeout_s, ..Default::default() };
    crate::paper::skip_deep_checks();
    let scenario = match crate::paper::load(&spec.run_dir.join("scenario.toml"), &overrides, papers) {
        Ok(s) => s,
        Err(e) => {
            error!("{e}");
            return Err(EXIT_BAD_INPUT);
        }
    };
    if let Proc::Agent(id) = me
        && (id == 0 || id > scenario.n_agents())
    {
        error!("--id {id}: out of range, the scenario has agents 1..={}", scenario.n_agents());
        return Err(EXIT_BAD_INPUT);
    }
    let key = match (spec.key_fd, scenario.run.authenticate) {
        (Some(fd), _) => match MacKey::read_from_fd(fd) {
            Ok(k) => Some(k),
            Err(e) => {
                error!("--key-fd {fd}: cannot read the run's key: {e}");
                return Err(EXIT_BAD_INPUT);
            }
        },
        (None, true) => {
            error!("run.authenticate is on but no --key-fd was given: the orchestrator hands the key over");
            return Err(EXIT_BAD_INPUT);
        }
        (None, false) => None,
    };
    Ok((run_id, scenario, key))
}

/// Ctrl-C belongs to the orchestrator, which stops its children in order; SIGTERM (and SIGHUP,
/// a closed terminal) asks this process to stop at its next wait, flushing its telemetry. Returns
/// the flag they raise, or the exit code.
fn stop_signals() -> Result<Arc<AtomicBool>, u8> {
    let terminate = Arc::new(AtomicBool::new(false));
    // SAFETY: ignoring SIGINT installs no handler code.
    unsafe { libc_ignore_sigint() };
    for sig in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP] {
        if let Err(e) = signal_hook::flag::register(sig, Arc::clone(&terminate)) {
            error!("cannot install the handler of signal {sig}: {e}");
            return Err(EXIT_RUN_FAILED);
        }
    }
    Ok(terminate)
}

/// Open the run's transport (iceoryx2, UDP or zenoh); a stop while waiting for the peers, or a
/// failure, is the exit code.
fn open_transport(
    spec: &ChildSpec,
    scenario: &Setup,
    run_id: u64,
    key: Option<MacKey>,
    terminate: &Arc<AtomicBool>,
) -> Result<Box<dyn Transport>, u8> {
    let me = spec.me;
    let topo = scenario.topology();
    let iox_run = IoxRun::new(run_id).with_key(key);
    let opened: Result<Box<dyn Transport>, _> = match scenario.run.transport {
        TransportKind::Udp => {
            let timeout = Duration::from_secs_f64(scenario.run.startup_timeout_s);
            udp::open(&iox_run, &topo, me, &spec.run_dir.join("udp"), timeout).map(|t| Box::new(t) as _)
        }
        TransportKind::Iceoryx2 => IoxData::open(&iox_run, &topo, me).map(|t| Box::new(t) as _),
        TransportKind::Zenoh => {
            let timeout = Duration::from_secs_f64(scenario.run.startup_timeout_s);
            let run = ZenohRun::new(run_id).with_key(key);
            ZenohData::declare(&run, &topo, me, &spec.zenoh_listen, &spec.zenoh_connect)
                .and_then(|p| p.ready_unless(timeout, terminate))
                .map(|t| Box::new(t) as _)
        }
    };
    match opened {
        Ok(t) => Ok(t),
        Err(e @ cohort_wire::transport::TransportError::Stopped(_)) => {
            info!("{e}");
            Err(EXIT_STOPPED)
        }
        Err(e) => {
            error!("cannot open the run's services: {e}");
            Err(EXIT_RUN_FAILED)
        }
    }
}

/// Run the driver over `transport`; with `run.record`, an agent's messages go to
/// record/<proc>.mcap on the way (see `recording`).
fn drive(
    spec: &ChildSpec,
    scenario: &Setup,
    run_id: u64,
    transport: &mut dyn Transport,
    params: &DriveParams,
    run: impl FnOnce(&Setup, &mut dyn Transport, &DriveParams) -> ProcessReport,
) -> ProcessReport {
    let me = spec.me;
    if !(scenario.run.record && matches!(me, Proc::Agent(_))) {
        return run(scenario, transport, params);
    }
    let mut meta = RecordMeta::from_setup(scenario, run_id, me);
    meta.attachments = spec.record_attachments.clone();
    match Recording::start(transport, &spec.run_dir, meta) {
        Ok(mut rec) => {
            let mut report = run(scenario, &mut rec, params);
            if let Err(e) = rec.finish()
                && report.error.is_none()
            {
                report.error = Some(ProcessError::new(ErrorKind::Io, format!("recording {e}")));
            }
            report
        }
        Err(e) => {
            ProcessReport::failed_at_start(me.name(), ProcessError::new(ErrorKind::Io, format!("cannot record: {e}")))
        }
    }
}

/// The exit code of a report, its end said in the log.
fn exit_code(report: &ProcessReport) -> ExitCode {
    match &report.error {
        None => {
            info!("done: {} steps in {:.3} s", report.steps_completed, report.wall_s);
            ExitCode::from(EXIT_OK)
        }
        Some(e) if e.is_stop() => {
            info!("{e}");
            ExitCode::from(EXIT_STOPPED)
        }
        Some(e) => {
            error!("{e}");
            ExitCode::from(EXIT_RUN_FAILED)
        }
    }
}

unsafe fn libc_ignore_sigint() {
    // SAFETY: SIG_IGN is a valid disposition for SIGINT.
    unsafe {
        libc::signal(libc::SIGINT, libc::SIG_IGN);
    }
}
