//! `orchestrator host --listen <zenoh endpoint> [--name NAME]`: the long-lived daemon of one
//! machine of a multi-host run. On the orchestrator's request (a zenoh queryable, see
//! [`crate::hostproto`]) it starts this machine's plant and agent processes from the binaries
//! beside its own executable, refusing a request from an orchestrator of another build; it
//! reports each child's end as `waitpid` saw it, relays signals (the fault plan's kill, freeze
//! and thaw, the shutdown ladder's SIGTERM), streams each child's output line by line, and at the
//! end sends the run's telemetry, timing, status and checkpoint files back. It also runs whole
//! campaign cases in its own process on a worker pool (`orchestrator campaign --hosts`, see
//! [`cases`]).
//!
//! Nothing outlives its run: the daemon watches the orchestrator's liveliness token of every run
//! it serves and kills that run's children when the token goes (the orchestrator ended, was
//! killed, or its network went), and the children run with `PR_SET_PDEATHSIG = SIGKILL`, so a
//! daemon that dies takes them with it. A run's files live under the user's own base directory
//! (`<base>/hosts/<name>/<run id>/`, 0700, as the orchestrator's runs) and are removed at the end;
//! the daemon's own `<name>/` when it stops.
//!
//! Trust: whoever reaches the daemon's endpoint can make it start this build's plant and agent
//! binaries (never anything else) with a scenario it sends; bind it to a network of your own, or
//! give it `--tls-*` (mutual TLS: only holders of a certificate of your CA get a session) and
//! `--auth-file` ([`cohort_wire::transport::zenoh_security`]). Its children inherit those settings.

use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cohort_runtime::record::RunDirs;
use cohort_runtime::tail::{Journal, journals_in};
use cohort_wire::transport::iox::IoxRun;
use cohort_wire::transport::zenoh::open_session;
use cohort_wire::transport::zenoh_security::SecurityConfigError;
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::query::{Query, Queryable};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

mod cases;
pub use cases::{CaseRunner, Cases};

use crate::hostproto::{
    self, COLLECTED, CaseRequest, ExitReport, Info, ProcRows, RowsRequest, RunRequest, SignalRequest, SpawnRequest,
    Spawned, chunk, request_key,
};
use crate::supervise::{KEY_FD, SIGNALLED, sibling_binary};

/// One child of a run on this host.
struct Kid {
    pid: u32,
    /// Set by its reaper once `waitpid` returned (the pid may then be reused: never signal it).
    done: Arc<AtomicBool>,
}

/// What this host keeps of one run.
struct RunState {
    dir: PathBuf,
    kids: HashMap<String, Kid>,
    /// Set when the orchestrator's liveliness token of the run is withdrawn.
    orphaned: Arc<AtomicBool>,
    /// The journals a live view follows through `rows` requests, by process.
    tails: HashMap<String, Journal>,
    /// The scenario text written to `dir` (with its digest), written again only when a request
    /// brings another: each of a run's processes brings it.
    scenario_written: Option<String>,
    _watch: Subscriber<()>,
}

struct Daemon {
    name: String,
    session: Session,
    base: PathBuf,
    runs: HashMap<u64, RunState>,
    /// Campaign cases (`case` requests).
    pool: cases::Pool,
    workers: usize,
}

/// This machine's host name, as a daemon name (letters, digits, '-' and '_').
fn default_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most buf.len() bytes into the buffer we own.
    let ok = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0;
    let raw = if ok {
        String::from_utf8_lossy(&buf[..buf.iter().position(|&b| b == 0).unwrap_or(0)]).to_string()
    } else {
        String::new()
    };
    let name: String =
        raw.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '-' }).take(64).collect();
    if name.is_empty() { "host".into() } else { name }
}

/// Why the daemon could not start: a bad argument or security setting (exit 2), or what it
/// cannot serve without (exit 1), each naming the flag, file or endpoint.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("--name {0:?}: must be 1 to 64 letters, digits, '-' or '_'")]
    Name(String),
    #[error("--listen {listen:?}: {why}")]
    Listen { listen: String, why: String },
    /// The `--tls-*`/`--auth-file` settings (or their environment variables).
    #[error(transparent)]
    Security(#[from] SecurityConfigError),
    /// `--listen` does not fit the security settings (the reason names the flag).
    #[error("{0}")]
    InsecureListen(String),
    /// No `plant` or `agent` binary beside this one (the reason names the path).
    #[error("{0}")]
    NoSibling(String),
    /// This user's base directory for run files cannot be made.
    #[error("{0}")]
    UserBase(cohort_wire::transport::TransportError),
    #[error("{}: {source}", dir.display())]
    BaseDir { dir: PathBuf, source: std::io::Error },
    #[error("cannot listen on {listen}: {reason}")]
    CannotListen { listen: String, reason: String },
    #[error("cannot declare the daemon's {what}: {reason}")]
    Declare { what: &'static str, reason: String },
}

impl cohort_runtime::exit::ToExitCode for DaemonError {
    fn exit_code(&self) -> u8 {
        use cohort_runtime::exit::{FAILED, INVALID};
        match self {
            Self::Name(_) | Self::Listen { .. } | Self::Security(_) | Self::InsecureListen(_) => INVALID,
            Self::NoSibling(_)
            | Self::UserBase(_)
            | Self::BaseDir { .. }
            | Self::CannotListen { .. }
            | Self::Declare { .. } => FAILED,
        }
    }
}

/// Run the daemon until SIGINT/SIGTERM/SIGHUP (the handlers of
/// [`crate::supervise::install_signal_handlers`]). An argument it refuses, or an endpoint it
/// cannot listen on, is a [`DaemonError`] naming it. `cases`: how campaign cases run here.
pub fn run(listen: &str, name: Option<String>, cases: Cases) -> Result<(), DaemonError> {
    let name = name.unwrap_or_else(default_name);
    if name.is_empty() || name.len() > 64 || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_') {
        return Err(DaemonError::Name(name));
    }
    if let Some(why) = cohort_scenario::hosts::endpoint_problem(listen) {
        return Err(DaemonError::Listen { listen: listen.to_string(), why });
    }
    let security = cohort_wire::transport::zenoh_security::current()?;
    if let Some(why) = security.endpoint_problem("--listen", listen) {
        return Err(DaemonError::InsecureListen(why));
    }
    for bin in ["plant", "agent"] {
        sibling_binary(bin).map_err(DaemonError::NoSibling)?;
    }
    let base = cohort_wire::transport::iox::ensure_user_files_base().map_err(DaemonError::UserBase)?.join(&name);
    std::fs::create_dir_all(&base).map_err(|source| DaemonError::BaseDir { dir: base.clone(), source })?;
    let session = open_session(&[listen.to_string()], &[])
        .map_err(|e| DaemonError::CannotListen { listen: listen.to_string(), reason: e.to_string() })?;
    let queryable: Queryable<FifoChannelHandler<Query>> = session
        .declare_queryable(request_key(&name, "*"))
        .wait()
        .map_err(|e| DaemonError::Declare { what: "queryable", reason: e.to_string() })?;
    let _token: LivelinessToken = session
        .liveliness()
        .declare_token(hostproto::host_token(&name))
        .wait()
        .map_err(|e| DaemonError::Declare { what: "liveliness token", reason: e.to_string() })?;
    tracing::info!(
        "host {name}: listening on {listen} (build {}), runs under {}, {} campaign worker(s)",
        cohort_wire::build_id(),
        base.display(),
        cases.workers
    );
    // What gateways of runs whose daemon was killed left of their hosts' iceoryx2 domains (a
    // killed gateway's lock is released, so such a domain is provably stale).
    for id in IoxRun::sweep_stale() {
        tracing::info!("host {name}: removed the iceoryx2 resources of run {id:016x}, whose gateway is gone");
    }
    // Cases a killed instance of this daemon left (a daemon's name is its machine's own).
    let left = base.join("cases");
    if std::fs::read_dir(&left).is_ok_and(|mut d| d.next().is_some()) && std::fs::remove_dir_all(&left).is_ok() {
        tracing::info!("host {name}: removed the campaign cases an earlier instance left");
    }
    let pool = cases::Pool::start(&name, &base, &cases);
    let mut d = Daemon { name, session, base, runs: HashMap::new(), pool, workers: cases.workers };
    loop {
        let sig = SIGNALLED.load(Ordering::SeqCst);
        if sig != 0 {
            tracing::info!("host {}: signal {sig}: stopping every child", d.name);
            let ids: Vec<u64> = d.runs.keys().copied().collect();
            for id in ids {
                d.end_run(id);
            }
            // Its cases see the signal: those running end interrupted, the queued ones unrun.
            d.pool.stop();
            let _ = std::fs::remove_dir(d.base.join("cases"));
            // Its per-host directory (and the per-user base, when no other daemon uses it) goes
            // with it: `remove_dir` removes only an empty directory, never another's files.
            let _ = std::fs::remove_dir(&d.base);
            if let Some(parent) = d.base.parent() {
                let _ = std::fs::remove_dir(parent);
            }
            return Ok(());
        }
        if let Ok(Some(q)) = queryable.recv_timeout(Duration::from_millis(50)) {
            d.answer(q);
        }
        let orphaned: Vec<u64> =
            d.runs.iter().filter(|(_, r)| r.orphaned.load(Ordering::SeqCst)).map(|(id, _)| *id).collect();
        for id in orphaned {
            tracing::warn!("host {}: run {id:016x}: its orchestrator is gone; killing its processes", d.name);
            d.end_run(id);
        }
    }
}

fn parse<T: serde::de::DeserializeOwned>(q: &Query) -> Result<T, String> {
    let bytes = q.payload().map(|p| p.to_bytes().to_vec()).unwrap_or_default();
    serde_json::from_slice(&bytes).map_err(|e| format!("malformed request: {e}"))
}

impl Daemon {
    fn answer(&mut self, q: Query) {
        let q = &q;
        let verb = q.key_expr().as_str().rsplit('/').next().unwrap_or("").to_string();
        let result: Result<Vec<u8>, String> = match verb.as_str() {
            "info" => serde_json::to_vec(&Info {
                name: self.name.clone(),
                build_id: cohort_wire::build_id().into(),
                pid: std::process::id(),
                workers: self.workers as u32,
            })
            .map_err(|e| e.to_string()),
            "spawn" => parse::<SpawnRequest>(q).and_then(|r| self.spawn(&r)),
            "signal" => parse::<SignalRequest>(q).and_then(|r| self.signal(&r)).map(|_| b"{}".to_vec()),
            "collect" => match parse::<RunRequest>(q) {
                Ok(r) => {
                    self.collect(q, r.run_id);
                    return;
                }
                Err(e) => Err(e),
            },
            "rows" => match parse::<RowsRequest>(q) {
                Ok(r) => {
                    self.rows(q, &r);
                    return;
                }
                Err(e) => Err(e),
            },
            "case" => match parse::<CaseRequest>(q) {
                Ok(r) => {
                    self.pool.submit(q.clone(), r);
                    return;
                }
                Err(e) => Err(e),
            },
            "end" => parse::<RunRequest>(q).map(|r| {
                self.end_run(r.run_id);
                b"{}".to_vec()
            }),
            other => Err(format!("unknown request {other:?}")),
        };
        let _ = match result {
            Ok(body) => q.reply(q.key_expr().clone(), body).wait(),
            Err(e) => {
                tracing::error!("host {}: {verb}: {e}", self.name);
                q.reply_err(e.into_bytes()).wait()
            }
        };
    }

    /// Start one process of a run (see [`SpawnRequest`]).
    fn spawn(&mut self, r: &SpawnRequest) -> Result<Vec<u8>, String> {
        if r.build_id != cohort_wire::build_id() {
            return Err(format!(
                "host {} was built from other sources ({}) than the orchestrator ({}): rebuild both from one checkout",
                self.name,
                cohort_wire::build_id(),
                r.build_id
            ));
        }
        let gateway = crate::gateway::host_of_name(&r.proc_name);
        let bin_name = if r.proc_name == "plant" {
            "plant"
        } else if r.proc_name.strip_prefix("agent-").and_then(|i| i.parse::<u32>().ok()).is_some_and(|i| i > 0) {
            "agent"
        } else if gateway.is_some() {
            // A host's gateway is this binary's `gateway` command.
            "orchestrator"
        } else {
            return Err(format!("no process {:?}", r.proc_name));
        };
        let bin = sibling_binary(bin_name)?;
        let run_id = r.run_id;
        if !self.runs.contains_key(&run_id) {
            let state = self.open_run(run_id)?;
            self.runs.insert(run_id, state);
        }
        let state = self.runs.get_mut(&run_id).expect("inserted above");
        let dirs = RunDirs::new(&state.dir);
        dirs.create_all().map_err(|e| format!("{}: {e}", dirs.root.display()))?;
        if state.scenario_written.as_deref() != Some(r.scenario_toml.as_str()) {
            dirs.write_scenario(&r.scenario_toml).map_err(|e| e.to_string())?;
            state.scenario_written = Some(r.scenario_toml.clone());
        }
        let key = match &r.key_hex {
            Some(h) => Some(crate::supervise::key_pipe(&parse_key(h)?)?),
            None => None,
        };
        let (reader, writer) = std::io::pipe().map_err(|e| format!("output pipe: {e}"))?;
        let writer2 = writer.try_clone().map_err(|e| format!("output pipe: {e}"))?;
        let mut cmd = Command::new(&bin);
        // The child's sessions use this daemon's TLS and authentication settings.
        cmd.envs(cohort_wire::transport::zenoh_security::current().map_err(|e| e.to_string())?.to_env());
        if let Some(k) = gateway {
            cmd.arg("gateway").arg("--host-index").arg(k.to_string());
        }
        if let Some(id) = r.proc_name.strip_prefix("agent-") {
            cmd.arg("--id").arg(id);
        }
        if let Some(k) = r.restore_at {
            cmd.arg("--restore-at").arg(k.to_string());
        }
        if key.is_some() {
            cmd.arg("--key-fd").arg(KEY_FD.to_string());
        }
        for e in &r.connect {
            cmd.arg("--zenoh-connect").arg(e);
        }
        for e in &r.listen {
            cmd.arg("--zenoh-listen").arg(e);
        }
        cmd.arg("--run-dir")
            .arg(&dirs.root)
            .arg("--run-id")
            .arg(format!("{run_id:016x}"))
            .arg("--build-id")
            .arg(cohort_wire::build_id());
        if gateway.is_none() {
            cmd.arg("--step-timeout-s").arg(format!("{:?}", r.step_timeout_s));
        }
        cmd.stdin(Stdio::null()).stdout(Stdio::from(writer)).stderr(Stdio::from(writer2));
        if let Some(log) = &r.log {
            log.apply(&mut cmd);
        }
        crate::supervise::child_setup(&mut cmd, key.as_ref().map(std::os::fd::AsRawFd::as_raw_fd));
        let mut child = cmd.spawn().map_err(|e| format!("cannot start {}: {e}", bin.display()))?;
        drop(cmd); // our copies of the pipe's write end, so the reader sees EOF when the child ends
        drop(key);
        let pid = child.id();
        let done = Arc::new(AtomicBool::new(false));
        let log_path = dirs.logs().join(format!("{}.log", r.proc_name));
        let logger = {
            let (session, key) = (self.session.clone(), hostproto::log_key(run_id, &self.name, &r.proc_name));
            std::thread::spawn(move || forward_output(reader, &log_path, &session, &key))
        };
        {
            let (session, done) = (self.session.clone(), Arc::clone(&done));
            let (key, proc_name) = (hostproto::exit_key(run_id, &self.name), r.proc_name.clone());
            std::thread::spawn(move || {
                let status = child.wait().map(|s| s.into_raw()).unwrap_or(libc::SIGKILL);
                let _ = logger.join(); // every line out before the exit report
                done.store(true, Ordering::SeqCst);
                let report = ExitReport { proc_name, pid, wait_status: status };
                if let Ok(body) = serde_json::to_vec(&report) {
                    let _ = session.put(key, body).congestion_control(CongestionControl::Block).wait();
                }
            });
        }
        state.kids.insert(r.proc_name.clone(), Kid { pid, done: Arc::clone(&done) });
        if let Some(k) = gateway {
            let ended = || done.load(Ordering::SeqCst).then(|| "see its log".to_string());
            crate::gateway::wait_until_ready(run_id, k, GATEWAY_READY, ended)?;
        }
        serde_json::to_vec(&Spawned { pid }).map_err(|e| e.to_string())
    }

    /// A run's directory and the watch on its orchestrator's liveliness token.
    fn open_run(&self, run_id: u64) -> Result<RunState, String> {
        use std::os::unix::fs::DirBuilderExt;
        let dir = self.base.join(format!("{run_id:016x}"));
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(&dir)
            .map_err(|e| format!("{}: {e}", dir.display()))?;
        let orphaned = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&orphaned);
        let token = cohort_wire::transport::zenoh::ZenohRun::new(run_id).orchestrator_token();
        let watch = self
            .session
            .liveliness()
            .declare_subscriber(token)
            .history(true)
            .callback(move |s| {
                if s.kind() == SampleKind::Delete {
                    flag.store(true, Ordering::SeqCst);
                }
            })
            .wait()
            .map_err(|e| format!("cannot watch the orchestrator: {e}"))?;
        Ok(RunState {
            dir,
            kids: HashMap::new(),
            orphaned,
            tails: HashMap::new(),
            scenario_written: None,
            _watch: watch,
        })
    }

    fn signal(&self, r: &SignalRequest) -> Result<(), String> {
        let run = self.runs.get(&r.run_id).ok_or_else(|| format!("run {:016x} has nothing here", r.run_id))?;
        // Every known one is signalled before an unknown name is reported.
        let mut unknown = Vec::new();
        for name in &r.proc_names {
            match run.kids.get(name) {
                // SAFETY: kill(2) on a child of ours that its reaper has not reaped yet.
                Some(kid) if !kid.done.load(Ordering::SeqCst) => unsafe {
                    libc::kill(kid.pid as libc::pid_t, r.signal);
                },
                Some(_) => {}
                None => unknown.push(name.as_str()),
            }
        }
        if unknown.is_empty() {
            Ok(())
        } else {
            Err(format!("run {:016x} has no {} here", r.run_id, unknown.join(", ")))
        }
    }

    /// Reply with every file of the run's data subdirectories, in pieces.
    fn collect(&self, q: &Query, run_id: u64) {
        let Some(state) = self.runs.get(&run_id) else {
            let _ = q.reply_err(format!("run {run_id:016x} has nothing here").into_bytes()).wait();
            return;
        };
        for sub in COLLECTED {
            for path in files_under(&state.dir.join(sub)) {
                let Ok(rel) = path.strip_prefix(&state.dir) else { continue };
                let rel = rel.to_string_lossy().to_string();
                let Ok(bytes) = std::fs::read(&path) else { continue };
                let mut offset = 0usize;
                loop {
                    let end = (offset + hostproto::CHUNK_BYTES).min(bytes.len());
                    let piece = chunk(&rel, offset as u64, &bytes[offset..end]);
                    if q.reply(q.key_expr().clone(), piece).wait().is_err() {
                        return;
                    }
                    offset = end;
                    if offset >= bytes.len() {
                        break;
                    }
                }
            }
        }
    }

    /// Reply with each process's new decimated telemetry rows (see [`RowsRequest`]), one reply a
    /// process (a host of many agents answers in many small messages, not one large one).
    fn rows(&mut self, q: &Query, r: &RowsRequest) {
        let Some(state) = self.runs.get_mut(&r.run_id) else {
            let _ = q.reply_err(format!("run {:016x} has nothing here", r.run_id).into_bytes()).wait();
            return;
        };
        let every = r.every.max(1);
        for (name, path) in journals_in(&RunDirs::new(&state.dir).telemetry()) {
            let journal = state.tails.entry(name.clone()).or_insert_with(|| Journal::new(&path));
            let mut rows = journal.poll(|k| k % every == 0);
            let rows = rows.split_off(rows.len().saturating_sub(r.max_rows));
            if journal.columns().is_empty() {
                continue;
            }
            let piece = ProcRows {
                proc_name: name,
                columns: journal.columns().to_vec(),
                rows: rows.into_iter().map(|(k, v)| (k, v.iter().map(|x| x.to_bits()).collect())).collect(),
            };
            let Ok(body) = serde_json::to_vec(&piece) else { continue };
            if q.reply(q.key_expr().clone(), body).wait().is_err() {
                return;
            }
        }
    }

    /// Kill whatever of the run is left, wait for its reapers, remove its directory.
    fn end_run(&mut self, run_id: u64) {
        let Some(state) = self.runs.remove(&run_id) else { return };
        for k in state.kids.values().filter(|k| !k.done.load(Ordering::SeqCst)) {
            // SAFETY: kill(2) on the process group of a child of ours (it made its own group).
            unsafe { libc::kill(-(k.pid as libc::pid_t), libc::SIGKILL) };
        }
        let until = Instant::now() + Duration::from_secs(5);
        while Instant::now() < until && state.kids.values().any(|k| !k.done.load(Ordering::SeqCst)) {
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = std::fs::remove_dir_all(&state.dir);
        // What a gateway killed above left of its host's iceoryx2 domain (its lock is released
        // with it, which makes the domain provably stale).
        if state.kids.keys().any(|n| crate::gateway::host_of_name(n).is_some()) {
            IoxRun::sweep_stale();
        }
    }
}

/// How long a daemon waits for a gateway it started to make its domain's services.
const GATEWAY_READY: Duration = Duration::from_secs(15);

fn parse_key(hex: &str) -> Result<cohort_wire::auth::MacKey, String> {
    let bytes: Vec<u8> = (0..hex.len())
        .step_by(2)
        .map(|i| hex.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok()))
        .collect::<Option<_>>()
        .ok_or("malformed key")?;
    let arr: [u8; 32] = bytes.try_into().map_err(|_| "the key must be 32 bytes")?;
    Ok(cohort_wire::auth::MacKey::from_bytes(arr))
}

/// Every regular file under `dir`, recursively, in name order.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut entries: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    let mut out = Vec::new();
    for p in entries {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.is_dir() => out.extend(files_under(&p)),
            Ok(m) if m.is_file() => out.push(p),
            _ => {}
        }
    }
    out
}

/// Copy a child's output to its local log and, line by line, to the orchestrator.
fn forward_output(reader: std::io::PipeReader, log_path: &Path, session: &Session, key: &str) {
    let mut log = std::fs::OpenOptions::new().create(true).append(true).open(log_path).ok();
    let mut lines = std::io::BufReader::new(reader);
    let mut line = Vec::new();
    while lines.read_until(b'\n', &mut line).is_ok_and(|n| n > 0) {
        if let Some(f) = log.as_mut() {
            let _ = f.write_all(&line);
        }
        let _ = session.put(key, line.clone()).congestion_control(CongestionControl::Block).wait();
        line.clear();
    }
}
