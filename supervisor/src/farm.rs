//! The orchestrator's side of a campaign spread over host daemons (`orchestrator campaign
//! --hosts FILE`): a session to every daemon, one slot per worker of each (the daemon's
//! `--workers`, from its `info`), and [`Farm::run`], which sends one case to a free slot and
//! waits for its reply. Each daemon's liveliness token is watched: a host that goes (killed, its
//! network cut, or stopping) loses its slots, and a case it had not answered is sent again to
//! another host — the same request, so the same row. The farm knows nothing of what a case is:
//! the request carries a scenario, the reply the runner's outcome.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use cohort_scenario::HostSpec;
use cohort_wire::transport::zenoh::session_config;
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

use crate::hostproto::{self, request_key};
pub use crate::hostproto::{CaseReply, CaseRequest};
use crate::remote::{PreflightError, daemon_infos};

/// A case's reply may take this long (a whole case runs before it comes): past it the host
/// counts as lost for that case.
const CASE_TIMEOUT: Duration = Duration::from_secs(24 * 3600);
/// How often a waiting case looks at its host's token and at the stop flag.
const POLL: Duration = Duration::from_millis(100);
/// An answer-less end of a query sooner than this after asking means no queryable took it yet
/// (the daemon's declaration still on its way, as in [`crate::remote`]): ask again.
const UNROUTED: Duration = Duration::from_millis(500);
const ROUTE_RETRY: Duration = Duration::from_millis(50);

/// Why the farm could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum FarmOpenError {
    /// A daemon is unreachable, another build, or not the host named (exit 2, nothing ran).
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    #[error("cannot open the daemons' zenoh session: {0}")]
    Session(String),
    /// Its liveliness token cannot be watched.
    #[error("host {host}: {reason}")]
    Watch { host: String, reason: String },
}

impl cohort_runtime::exit::ToExitCode for FarmOpenError {
    fn exit_code(&self) -> u8 {
        match self {
            Self::Preflight(_) => cohort_runtime::exit::INVALID,
            Self::Session(_) | Self::Watch { .. } => cohort_runtime::exit::FAILED,
        }
    }
}

/// Why a case got no outcome.
#[derive(Debug, thiserror::Error)]
pub enum FarmCaseError {
    /// The stop flag was raised while the case waited.
    #[error("interrupted")]
    Interrupted,
    #[error("every host is lost ({0}); the same command continues the campaign once they are back")]
    AllLost(String),
    /// A host could not run the case (its reason).
    #[error("host {host}: {reason}")]
    Failed { host: String, reason: String },
}

/// One daemon of the farm.
struct Host {
    name: String,
    endpoint: String,
    workers: usize,
    lost: AtomicBool,
}

/// The daemons' session, their slots and tokens.
pub struct Farm {
    session: Session,
    hosts: Vec<Arc<Host>>,
    /// Free slots, by host index; a lost host's are dropped as they are taken.
    free: Mutex<Vec<usize>>,
    freed: Condvar,
    _watch: Vec<Subscriber<()>>,
}

impl Farm {
    /// Check every daemon (reachable, named, this build), connect to them all and learn their
    /// worker counts.
    pub fn open(specs: &[HostSpec]) -> Result<Self, FarmOpenError> {
        let infos = daemon_infos(specs)?;
        let connect: Vec<String> = specs.iter().map(|h| h.endpoint.clone()).collect();
        let mut cfg = session_config(&[], &connect).map_err(|e| FarmOpenError::Session(e.to_string()))?;
        cfg.insert_json5("scouting/gossip/enabled", "false").map_err(|e| FarmOpenError::Session(e.to_string()))?;
        let session = zenoh::open(cfg).wait().map_err(|e| FarmOpenError::Session(e.to_string()))?;
        let mut hosts = Vec::new();
        let mut watch = Vec::new();
        for (h, info) in specs.iter().zip(&infos) {
            let host = Arc::new(Host {
                name: h.name.clone(),
                endpoint: h.endpoint.clone(),
                workers: info.workers.max(1) as usize,
                lost: AtomicBool::new(false),
            });
            let flag = Arc::clone(&host);
            let sub = session
                .liveliness()
                .declare_subscriber(hostproto::host_token(&h.name))
                .history(true)
                .callback(move |s| {
                    if s.kind() == SampleKind::Delete && !flag.lost.swap(true, Ordering::SeqCst) {
                        tracing::warn!("host {} lost (its daemon or its network went)", flag.name);
                    }
                })
                .wait()
                .map_err(|e| FarmOpenError::Watch { host: h.name.clone(), reason: format!("cannot watch it: {e}") })?;
            watch.push(sub);
            hosts.push(host);
        }
        // Slots interleaved across hosts, so that the first cases spread over every host.
        let most = hosts.iter().map(|h| h.workers).max().unwrap_or(0);
        let free = (0..most).flat_map(|w| hosts.iter().enumerate().filter(move |(_, h)| w < h.workers).map(|(k, _)| k));
        let free: Vec<usize> = free.collect();
        Ok(Self { session, hosts, free: Mutex::new(free), freed: Condvar::new(), _watch: watch })
    }

    /// Every slot of every host: how many cases run at once.
    pub fn slots(&self) -> usize {
        self.hosts.iter().map(|h| h.workers).sum()
    }

    /// `name (endpoint, N workers)` of each host, for the log.
    pub fn describe(&self) -> String {
        let each = self.hosts.iter().map(|h| format!("{} ({}, {} worker(s))", h.name, h.endpoint, h.workers));
        each.collect::<Vec<_>>().join(", ")
    }

    /// Run `req` on a free slot of a live host, again on another host while the one it was sent
    /// to is lost before it answers. The outcome and the host that ran it.
    pub fn run(
        &self,
        req: &CaseRequest,
        stop: &dyn Fn() -> bool,
    ) -> Result<(serde_json::Value, String), FarmCaseError> {
        let body = serde_json::to_vec(req)
            .map_err(|e| FarmCaseError::Failed { host: "(none)".into(), reason: format!("cannot encode: {e}") })?;
        loop {
            let k = self.acquire(stop)?;
            let host = &self.hosts[k];
            tracing::debug!("case {} sent to host {}", req.case, host.name);
            let answer = self.ask(host, &body, stop);
            self.release(k);
            match answer {
                Asked::Reply(CaseReply::Done(v)) => return Ok((v, host.name.clone())),
                Asked::Reply(CaseReply::Failed(reason)) => {
                    return Err(FarmCaseError::Failed { host: host.name.clone(), reason });
                }
                Asked::Reply(CaseReply::Stopping) | Asked::Lost => {
                    if !host.lost.swap(true, Ordering::SeqCst) {
                        tracing::warn!("host {} lost (it stopped, or did not answer case {})", host.name, req.case);
                    }
                    tracing::warn!("case {} was on host {}: it goes to another host", req.case, host.name);
                }
                Asked::Interrupted => return Err(FarmCaseError::Interrupted),
            }
        }
    }

    /// A free slot of a live host (waiting for one), or why there will be none.
    fn acquire(&self, stop: &dyn Fn() -> bool) -> Result<usize, FarmCaseError> {
        let mut free = self.free.lock().unwrap_or_else(|p| p.into_inner());
        loop {
            free.retain(|&k| !self.hosts[k].lost.load(Ordering::SeqCst));
            if let Some(k) = free.first().copied() {
                free.remove(0);
                return Ok(k);
            }
            if self.hosts.iter().all(|h| h.lost.load(Ordering::SeqCst)) {
                let names: Vec<&str> = self.hosts.iter().map(|h| h.name.as_str()).collect();
                return Err(FarmCaseError::AllLost(names.join(", ")));
            }
            if stop() {
                return Err(FarmCaseError::Interrupted);
            }
            free = self.freed.wait_timeout(free, POLL).unwrap_or_else(|p| p.into_inner()).0;
        }
    }

    fn release(&self, k: usize) {
        self.free.lock().unwrap_or_else(|p| p.into_inner()).push(k);
        self.freed.notify_one();
    }

    /// One case to `host` and its reply, watching the host's token and the stop flag meanwhile.
    fn ask(&self, host: &Host, body: &[u8], stop: &dyn Fn() -> bool) -> Asked {
        loop {
            let asked = Instant::now();
            let Ok(replies) =
                self.session.get(request_key(&host.name, "case")).payload(body.to_vec()).timeout(CASE_TIMEOUT).wait()
            else {
                return Asked::Lost;
            };
            loop {
                match replies.recv_timeout(POLL) {
                    Ok(Some(r)) => {
                        let sample = match r.into_result() {
                            Ok(s) => s,
                            Err(e) => {
                                let why = String::from_utf8_lossy(&e.payload().to_bytes()).to_string();
                                return Asked::Reply(CaseReply::Failed(why));
                            }
                        };
                        return match serde_json::from_slice::<CaseReply>(&sample.payload().to_bytes()) {
                            Ok(reply) => Asked::Reply(reply),
                            Err(e) => Asked::Reply(CaseReply::Failed(format!("a reply that is not a case's: {e}"))),
                        };
                    }
                    Ok(None) if host.lost.load(Ordering::SeqCst) => return Asked::Lost,
                    Ok(None) if stop() => return Asked::Interrupted,
                    Ok(None) => {}
                    // Ended with no reply: too soon to have reached the daemon, or it went.
                    Err(_) if asked.elapsed() < UNROUTED && !host.lost.load(Ordering::SeqCst) => {
                        std::thread::sleep(ROUTE_RETRY);
                        break;
                    }
                    Err(_) => return Asked::Lost,
                }
            }
        }
    }
}

/// What asking one host for a case came to.
enum Asked {
    Reply(CaseReply),
    /// The host went (or its query ended unanswered) before it replied.
    Lost,
    Interrupted,
}
