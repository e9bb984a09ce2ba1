//! The orchestrator's side of a zenoh run: its session (which every plant and agent connects to),
//! and for a multi-host run the links to the host daemons of `[[hosts]]` — checked before
//! anything starts ([`preflight`]), then asked to start processes, relay signals, and at the end
//! to send the run's files back ([`Remote`]). Each daemon's liveliness token is watched: when it
//! goes, the host is lost, and the supervisor declares every process on it dead.

use std::collections::HashMap;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cohort_runtime::record::RunDirs;
use cohort_scenario::HostSpec;
use cohort_wire::transport::zenoh::{open_on_free_ports, session_config, tcp_endpoint};
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

use crate::hostproto::{
    self, ExitReport, Info, ProcRows, RowsRequest, RunRequest, SignalRequest, SpawnRequest, Spawned, request_key,
};

/// How long a daemon has to answer a request.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(20);
/// An answer-less end of a query sooner than this after asking means no queryable took it.
const UNROUTED: Duration = Duration::from_millis(500);
/// The pause before asking again then.
const ROUTE_RETRY: Duration = Duration::from_millis(50);
/// How long the pre-flight check waits for a daemon's connection and answer.
const PREFLIGHT_TIMEOUT: Duration = Duration::from_secs(4);

/// Whether a query asked at `asked` that ended now without a reply ended too soon to have reached
/// a daemon, with time left before `deadline` to ask again.
fn unrouted(asked: Instant, deadline: Instant) -> bool {
    asked.elapsed() < UNROUTED && Instant::now() + ROUTE_RETRY < deadline
}

/// The address of a `tcp/<address>:<port>` (or `tls/…`) endpoint that this process's security
/// settings allow (with TLS configured, only `tls/`).
fn endpoint_addr(endpoint: &str) -> Result<SocketAddr, String> {
    let security = cohort_wire::transport::zenoh_security::current().map_err(|e| e.to_string())?;
    if let Some(why) = security.endpoint_problem("endpoint", endpoint) {
        return Err(why);
    }
    let rest = endpoint
        .strip_prefix("tcp/")
        .or_else(|| endpoint.strip_prefix("tls/"))
        .ok_or_else(|| format!("{endpoint}: not a tcp/ or tls/ endpoint"))?;
    rest.to_socket_addrs()
        .map_err(|e| format!("{endpoint}: cannot resolve: {e}"))?
        .next()
        .ok_or_else(|| format!("{endpoint}: resolves to no address"))
}

/// This machine's address on the route to `to` (no packet is sent: a UDP socket is connected,
/// which only looks the route up).
fn local_addr_towards(to: SocketAddr) -> Result<std::net::IpAddr, String> {
    let bind = if to.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" };
    let s = UdpSocket::bind(bind).map_err(|e| format!("cannot look up the route to {to}: {e}"))?;
    s.connect(to).map_err(|e| format!("no route to {to}: {e}"))?;
    Ok(s.local_addr().map_err(|e| format!("route to {to}: {e}"))?.ip())
}

/// Why a host of the scenario is not ready for a run ([`preflight`]): the host, as
/// `hosts[k] (<name> at <endpoint>)`, and what is wrong with it.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{at}: {problem}")]
pub struct PreflightError {
    pub at: String,
    pub problem: PreflightProblem,
}

/// What [`preflight`] found wrong with one host.
#[derive(Debug, Clone, thiserror::Error)]
pub enum PreflightProblem {
    /// Its endpoint cannot be used (security settings, form, resolution).
    #[error("{0}")]
    Endpoint(String),
    /// The zenoh configuration to reach it cannot be made.
    #[error("{0}")]
    Config(String),
    #[error(
        "unreachable: {reason} (is `orchestrator host --listen {endpoint} --name {name}` running there, with the same --tls-*/--auth-file settings?)"
    )]
    Unreachable { reason: String, endpoint: String, name: String },
    #[error("cannot ask: {0}")]
    Ask(String),
    #[error("something listens there, but no daemon named {name:?} answers (start it with --name {name})")]
    NoDaemon { name: String },
    #[error(
        "the daemon (pid {pid}) was built from other sources ({theirs}) than this orchestrator ({ours}): rebuild both from one checkout"
    )]
    BuildMismatch { pid: u32, theirs: String, ours: &'static str },
}

impl cohort_runtime::exit::ToExitCode for PreflightError {
    /// A host the scenario names is not usable: bad input, found before anything started.
    fn exit_code(&self) -> u8 {
        cohort_runtime::exit::INVALID
    }
}

/// Before anything starts: every host's daemon is reachable at its endpoint, answers to its name,
/// and was built from the same sources. The first problem, naming the host.
pub fn preflight(hosts: &[HostSpec]) -> Result<(), PreflightError> {
    daemon_infos(hosts).map(|_| ())
}

/// [`preflight`], keeping each daemon's answer (in the order of `hosts`).
pub(crate) fn daemon_infos(hosts: &[HostSpec]) -> Result<Vec<Info>, PreflightError> {
    let mut infos = Vec::with_capacity(hosts.len());
    for (k, h) in hosts.iter().enumerate() {
        let at = format!("hosts[{k}] ({} at {})", h.name, h.endpoint);
        let fail = |problem| PreflightError { at: at.clone(), problem };
        endpoint_addr(&h.endpoint).map_err(|e| fail(PreflightProblem::Endpoint(e)))?;
        let mut cfg = session_config(&[], std::slice::from_ref(&h.endpoint))
            .map_err(|e| fail(PreflightProblem::Config(e.to_string())))?;
        for (key, value) in [("connect/timeout_ms", "3000"), ("connect/exit_on_failure", "true")] {
            cfg.insert_json5(key, value)
                .map_err(|e| fail(PreflightProblem::Config(format!("zenoh config {key}: {e}"))))?;
        }
        let session = zenoh::open(cfg).wait().map_err(|e| {
            fail(PreflightProblem::Unreachable {
                reason: e.to_string(),
                endpoint: h.endpoint.clone(),
                name: h.name.clone(),
            })
        })?;
        let replies = session
            .get(request_key(&h.name, "info"))
            .timeout(PREFLIGHT_TIMEOUT)
            .wait()
            .map_err(|e| fail(PreflightProblem::Ask(e.to_string())))?;
        let info: Option<Info> = replies
            .recv()
            .ok()
            .and_then(|r| r.into_result().ok())
            .and_then(|s| serde_json::from_slice(&s.payload().to_bytes()).ok());
        let _ = session.close().wait();
        let Some(info) = info else {
            return Err(fail(PreflightProblem::NoDaemon { name: h.name.clone() }));
        };
        if info.build_id != cohort_wire::build_id() {
            return Err(fail(PreflightProblem::BuildMismatch {
                pid: info.pid,
                theirs: info.build_id,
                ours: cohort_wire::build_id(),
            }));
        }
        infos.push(info);
    }
    Ok(infos)
}

/// One host daemon of a run, as the supervisor sees it.
pub struct HostLink {
    pub name: String,
    pub endpoint: String,
    /// Where the orchestrator listens for this host's processes.
    pub connect: String,
    /// Where this host's processes listen (its address, port 0).
    pub listen: String,
    /// Exit reports received: process name → (pid, raw wait status).
    exits: Mutex<HashMap<String, (u32, i32)>>,
    /// Its liveliness token was withdrawn (the daemon died or its network went).
    lost: AtomicBool,
    /// Its token was seen at least once.
    seen: AtomicBool,
    /// Its gateway ended during the run (runs with gateways): its processes can reach no one.
    gateway_gone: AtomicBool,
}

impl HostLink {
    /// Lost to the run: its daemon disappeared, or its gateway ended.
    pub fn is_lost(&self) -> bool {
        self.daemon_lost() || self.gateway_gone.load(Ordering::SeqCst)
    }
    /// Its daemon disappeared (liveliness token withdrawn): nothing more can be asked of it.
    pub fn daemon_lost(&self) -> bool {
        self.lost.load(Ordering::SeqCst)
    }
    /// Its gateway ended: the host is lost to the run, its daemon still answers.
    pub fn gateway_ended(&self) {
        self.gateway_gone.store(true, Ordering::SeqCst);
    }
    /// Why it is lost, for the timeline.
    pub fn loss(&self) -> &'static str {
        if self.daemon_lost() { "its daemon disappeared (liveliness token withdrawn)" } else { "its gateway ended" }
    }
    /// The raw wait status of `proc_name` with pid `pid`, once reported.
    pub fn exit_of(&self, proc_name: &str, pid: u32) -> Option<i32> {
        let exits = self.exits.lock().unwrap_or_else(|p| p.into_inner());
        exits.get(proc_name).filter(|(p, _)| *p == pid).map(|(_, st)| *st)
    }
}

/// The run's zenoh session and its host links.
pub struct Remote {
    /// The run's session (the processes' side).
    pub session: Session,
    /// The daemons' session: requests, exit reports, logs, liveliness.
    control: Session,
    pub run_id: u64,
    pub hosts: Vec<Arc<HostLink>>,
    /// Where the orchestrator's own (local) processes connect and listen.
    pub local_connect: String,
    pub local_listen: String,
    _subs: Vec<Subscriber<()>>,
    /// The run's orchestrator token as the daemons see it (they kill the run's processes when
    /// it goes).
    _token: zenoh::liveliness::LivelinessToken,
}

impl Remote {
    /// Open the run's session: listen where every host (or, with none, this machine's own
    /// processes) can reach it, connect to every daemon, and watch their exits, logs and tokens.
    pub fn open(run_id: u64, hosts: &[HostSpec], dirs: &RunDirs) -> Result<Self, String> {
        let mut plan = Vec::new();
        for h in hosts {
            let to = endpoint_addr(&h.endpoint)?;
            plan.push((h, local_addr_towards(to)?, to.ip()));
        }
        let mut listen_ips: Vec<std::net::IpAddr> = plan.iter().map(|(_, mine, _)| *mine).collect();
        let loopback: std::net::IpAddr = std::net::Ipv4Addr::LOCALHOST.into();
        let local_ip = listen_ips.first().copied().unwrap_or(loopback);
        if listen_ips.is_empty() {
            listen_ips.push(loopback);
        }
        listen_ips.sort();
        listen_ips.dedup();
        let connect: Vec<String> = hosts.iter().map(|h| h.endpoint.clone()).collect();
        // Two sessions: the run's (listening; every plant and agent connects to it and gossip
        // introduces them to each other) and the daemons' (connecting to each daemon, no gossip).
        // On one session, gossip made the processes connect to the daemons too, and when they
        // ended the daemons' queryables could vanish from the orchestrator's routes (end-of-run
        // requests then went unanswered).
        let (session, listening) =
            open_on_free_ports(&listen_ips, &[]).map_err(|e| format!("cannot open the run's zenoh session: {e}"))?;
        let mut cfg = session_config(&[], &connect).map_err(|e| e.to_string())?;
        cfg.insert_json5("scouting/gossip/enabled", "false").map_err(|e| format!("zenoh config: {e}"))?;
        let control = zenoh::open(cfg).wait().map_err(|e| format!("cannot open the daemons' zenoh session: {e}"))?;
        let token = control
            .liveliness()
            .declare_token(cohort_wire::transport::zenoh::ZenohRun::new(run_id).orchestrator_token())
            .wait()
            .map_err(|e| format!("cannot declare the orchestrator's liveliness token: {e}"))?;
        let port_on = |ip: std::net::IpAddr| -> Result<String, String> {
            let k = listen_ips.iter().position(|&x| x == ip);
            k.map(|k| listening[k].clone())
                .ok_or_else(|| format!("the run's zenoh session does not listen on {ip} (it listens on {listening:?})"))
        };
        let mut links = Vec::new();
        for (h, mine, theirs) in &plan {
            links.push(Arc::new(HostLink {
                name: h.name.clone(),
                endpoint: h.endpoint.clone(),
                connect: port_on(*mine)?,
                listen: tcp_endpoint(*theirs, 0),
                exits: Mutex::new(HashMap::new()),
                lost: AtomicBool::new(false),
                seen: AtomicBool::new(false),
                gateway_gone: AtomicBool::new(false),
            }));
        }
        let mut subs = Vec::new();
        let exits = links.clone();
        subs.push(
            control
                .declare_subscriber(hostproto::all_exits_key(run_id))
                .callback(move |s| {
                    let host = s.key_expr().as_str().split('/').nth(3).unwrap_or("").to_string();
                    let Ok(r) = serde_json::from_slice::<ExitReport>(&s.payload().to_bytes()) else { return };
                    if let Some(l) = exits.iter().find(|l| l.name == host) {
                        l.exits.lock().unwrap_or_else(|p| p.into_inner()).insert(r.proc_name, (r.pid, r.wait_status));
                    }
                })
                .wait()
                .map_err(|e| format!("cannot subscribe to exit reports: {e}"))?,
        );
        let logs = dirs.logs();
        subs.push(
            control
                .declare_subscriber(hostproto::all_logs_key(run_id))
                .callback(move |s| append_log(&logs, s.key_expr().as_str(), &s.payload().to_bytes()))
                .wait()
                .map_err(|e| format!("cannot subscribe to logs: {e}"))?,
        );
        for l in &links {
            let link = Arc::clone(l);
            subs.push(
                control
                    .liveliness()
                    .declare_subscriber(hostproto::host_token(&l.name))
                    .history(true)
                    .callback(move |s| match s.kind() {
                        SampleKind::Put => link.seen.store(true, Ordering::SeqCst),
                        SampleKind::Delete => link.lost.store(true, Ordering::SeqCst),
                    })
                    .wait()
                    .map_err(|e| format!("cannot watch host {}: {e}", l.name))?,
            );
        }
        let local_connect = port_on(local_ip)?;
        let local_listen = tcp_endpoint(local_ip, 0);
        Ok(Self { session, control, run_id, hosts: links, local_connect, local_listen, _subs: subs, _token: token })
    }

    pub fn host(&self, name: &str) -> Option<&Arc<HostLink>> {
        self.hosts.iter().find(|h| h.name == name)
    }

    /// One request to `host`'s daemon and its answer. A query that no queryable matches ends at
    /// once with no reply: on a slow or lossy link the daemon's queryable may reach this session's
    /// routing after the first request does (our reading of a spawn request to a host behind 2 ms
    /// of delay and 1 % loss that once ended unanswered: one lost segment holds a declaration back
    /// by a TCP retransmission). So while the host is
    /// not lost (its token not withdrawn) such an empty answer is asked again, until
    /// [`REQUEST_TIMEOUT`]; a daemon that got the request always answers it, so nothing is done twice.
    fn ask(&self, host: &HostLink, verb: &str, body: Vec<u8>) -> Result<Vec<u8>, String> {
        let deadline = Instant::now() + REQUEST_TIMEOUT;
        loop {
            let asked = Instant::now();
            let replies = self
                .control
                .get(request_key(&host.name, verb))
                .payload(body.clone())
                .timeout(deadline.saturating_duration_since(asked))
                .wait()
                .map_err(|e| format!("host {}: {verb}: {e}", host.name))?;
            match replies.recv() {
                Ok(r) => {
                    return match r.into_result() {
                        Ok(s) => Ok(s.payload().to_bytes().to_vec()),
                        Err(e) => {
                            Err(format!("host {}: {}", host.name, String::from_utf8_lossy(&e.payload().to_bytes())))
                        }
                    };
                }
                Err(_) if unrouted(asked, deadline) && !host.daemon_lost() => std::thread::sleep(ROUTE_RETRY),
                Err(_) => {
                    return Err(format!("host {} ({}) did not answer its {verb} request", host.name, host.endpoint));
                }
            }
        }
    }

    /// Ask `host` to start a process; its pid.
    pub fn spawn(&self, host: &HostLink, req: &SpawnRequest) -> Result<u32, String> {
        let body = serde_json::to_vec(req).map_err(|e| e.to_string())?;
        let reply = self.ask(host, "spawn", body)?;
        let s: Spawned = serde_json::from_slice(&reply).map_err(|e| format!("host {}: bad reply: {e}", host.name))?;
        Ok(s.pid)
    }

    /// Signal processes of `host`, all in one request.
    pub fn signal(&self, host: &HostLink, proc_names: &[&str], signal: i32) -> Result<(), String> {
        let proc_names = proc_names.iter().map(|n| n.to_string()).collect();
        let req = SignalRequest { run_id: self.run_id, proc_names, signal };
        self.ask(host, "signal", serde_json::to_vec(&req).map_err(|e| e.to_string())?).map(|_| ())
    }

    /// Fetch every data file the host's processes wrote into `dirs`. Returns how many bytes.
    pub fn collect(&self, host: &HostLink, dirs: &RunDirs) -> Result<u64, String> {
        use std::io::{Seek, SeekFrom, Write};
        let req = serde_json::to_vec(&RunRequest { run_id: self.run_id }).map_err(|e| e.to_string())?;
        let replies = self
            .control
            .get(request_key(&host.name, "collect"))
            // Every piece is a reply on the same key: keep them all, in order.
            .consolidation(zenoh::query::ConsolidationMode::None)
            .payload(req)
            .timeout(Duration::from_secs(300))
            .wait()
            .map_err(|e| format!("host {}: collect: {e}", host.name))?;
        let mut total = 0u64;
        let mut open: HashMap<String, std::fs::File> = HashMap::new();
        while let Ok(r) = replies.recv() {
            let sample = r.into_result().map_err(|e| {
                format!("host {}: collect: {}", host.name, String::from_utf8_lossy(&e.payload().to_bytes()))
            })?;
            let bytes = sample.payload().to_bytes();
            let (path, offset, data) = hostproto::unchunk(&bytes).map_err(|e| format!("host {}: {e}", host.name))?;
            let full = dirs.root.join(&path);
            if !open.contains_key(&path) {
                if let Some(parent) = full.parent() {
                    std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
                }
                let f = std::fs::File::create(&full).map_err(|e| format!("{}: {e}", full.display()))?;
                open.insert(path.clone(), f);
            }
            let f = open.get_mut(&path).expect("inserted above");
            f.seek(SeekFrom::Start(offset))
                .and_then(|_| f.write_all(data))
                .map_err(|e| format!("{}: {e}", full.display()))?;
            total += data.len() as u64;
        }
        Ok(total)
    }

    /// The new decimated telemetry rows of `host`'s processes (see [`RowsRequest`]), for the live
    /// view: one try, within `timeout` (a slow or lost host shows nothing new, and the view does
    /// not wait for it longer).
    pub fn rows(
        &self,
        host: &HostLink,
        every: u64,
        max_rows: usize,
        timeout: Duration,
    ) -> Result<Vec<ProcRows>, String> {
        let req = RowsRequest { run_id: self.run_id, every, max_rows };
        let replies = self
            .control
            .get(request_key(&host.name, "rows"))
            .consolidation(zenoh::query::ConsolidationMode::None)
            .payload(serde_json::to_vec(&req).map_err(|e| e.to_string())?)
            .timeout(timeout)
            .wait()
            .map_err(|e| format!("host {}: rows: {e}", host.name))?;
        let mut out = Vec::new();
        while let Ok(r) = replies.recv() {
            let sample = r.into_result().map_err(|e| {
                format!("host {}: rows: {}", host.name, String::from_utf8_lossy(&e.payload().to_bytes()))
            })?;
            let piece: ProcRows = serde_json::from_slice(&sample.payload().to_bytes())
                .map_err(|e| format!("host {}: rows: bad reply: {e}", host.name))?;
            out.push(piece);
        }
        Ok(out)
    }

    /// Tell `host` the run is over: it kills whatever is left and removes its copy.
    pub fn end(&self, host: &HostLink) -> Result<(), String> {
        let req = serde_json::to_vec(&RunRequest { run_id: self.run_id }).map_err(|e| e.to_string())?;
        self.ask(host, "end", req).map(|_| ())
    }
}

/// Append one line of a remote child's output to its log (`cohort/<run>/host/<h>/log/<proc>`).
fn append_log(logs: &std::path::Path, key: &str, line: &[u8]) {
    use std::io::Write;
    let Some(name) = key.rsplit('/').next().filter(|n| {
        *n == "plant"
            || n.strip_prefix("agent-").is_some_and(|i| i.parse::<u32>().is_ok())
            || crate::gateway::host_of_name(n).is_some()
    }) else {
        return;
    };
    let path = logs.join(format!("{name}.log"));
    if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(path) {
        let _ = f.write_all(line);
    }
}
