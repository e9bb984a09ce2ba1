//! The daemon's campaign worker pool: `case` requests ([`CaseRequest`]) queue here and
//! `--workers` threads run them, each through the runner the daemon was started with (the
//! orchestrator's: it knows scenarios and papers, the daemon does not), in a scratch directory
//! of the daemon's own 0700 base that is removed when the case ends. The reply goes back on the
//! request's query when the case has ended, however long it ran.
//!
//! A stopping daemon (SIGINT/SIGTERM/SIGHUP) answers every case it has not started with
//! [`CaseReply::Stopping`], and so does a runner whose case the signal interrupted: the
//! orchestrator gives those cases to other hosts. An orchestrator that goes away mid-campaign
//! leaves at most `--workers` cases running here; they end, their replies go nowhere and their
//! scratch directories are removed (threads of the daemon, no process outlives them).

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use zenoh::Wait;
use zenoh::query::Query;

use crate::hostproto::{CaseReply, CaseRequest};
use crate::supervise::SIGNALLED;

/// What runs one case: the request and the scratch directory it may use (made, 0700, and removed
/// after) to the reply.
pub type CaseRunner = Arc<dyn Fn(&CaseRequest, &Path) -> CaseReply + Send + Sync>;

/// The cases a daemon serves: how many at once, and what runs each.
#[derive(Clone)]
pub struct Cases {
    pub workers: usize,
    pub runner: CaseRunner,
}

/// The running pool.
pub(super) struct Pool {
    queue: Option<Sender<(Query, CaseRequest)>>,
    threads: Vec<JoinHandle<()>>,
}

impl Pool {
    /// `cases.workers` threads taking requests in arrival order; scratch directories under
    /// `base/cases/`.
    pub(super) fn start(host: &str, base: &Path, cases: &Cases) -> Self {
        let (queue, rx) = channel::<(Query, CaseRequest)>();
        let rx = Arc::new(Mutex::new(rx));
        let threads = (0..cases.workers.max(1))
            .map(|w| {
                let (rx, runner) = (Arc::clone(&rx), Arc::clone(&cases.runner));
                let (host, scratch) = (host.to_string(), base.join("cases"));
                std::thread::Builder::new()
                    .name(format!("case-worker-{w}"))
                    .spawn(move || serve(&rx, &runner, &host, &scratch))
                    .expect("a thread for a case worker")
            })
            .collect();
        Self { queue: Some(queue), threads }
    }

    pub(super) fn submit(&self, q: Query, r: CaseRequest) {
        if let Some(tx) = &self.queue {
            // The receivers live as long as the pool: a send fails only while it stops.
            if let Err(e) = tx.send((q, r)) {
                let (q, _) = e.0;
                reply(&q, &CaseReply::Stopping);
            }
        }
    }

    /// Stop taking cases and wait for the workers (the queued cases are answered `Stopping`).
    pub(super) fn stop(mut self) {
        self.queue = None;
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn serve(rx: &Mutex<Receiver<(Query, CaseRequest)>>, runner: &CaseRunner, host: &str, scratch: &Path) {
    loop {
        let next = rx.lock().unwrap_or_else(|p| p.into_inner()).recv();
        let Ok((q, r)) = next else { return };
        let answer = if SIGNALLED.load(Ordering::SeqCst) != 0 {
            CaseReply::Stopping
        } else {
            run_one(&r, runner, host, scratch)
        };
        reply(&q, &answer);
    }
}

fn run_one(r: &CaseRequest, runner: &CaseRunner, host: &str, scratch: &Path) -> CaseReply {
    if r.build_id != cohort_wire::build_id() {
        return CaseReply::Failed(format!(
            "host {host} was built from other sources ({}) than the orchestrator ({}): rebuild both from one checkout",
            cohort_wire::build_id(),
            r.build_id
        ));
    }
    let dir = case_dir(scratch, r);
    if let Err(e) = make_private(&dir) {
        return CaseReply::Failed(format!("host {host}: {}: {e}", dir.display()));
    }
    tracing::debug!("host {host}: case {} of campaign {:016x}", r.case, r.campaign_id);
    let answer = runner(r, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    // The per-campaign parent goes once no case of it is left (remove_dir removes only an empty one).
    if let Some(parent) = dir.parent() {
        let _ = std::fs::remove_dir(parent);
    }
    answer
}

/// A case's scratch directory: `<scratch>/<campaign id>/case-NNNNNN`.
fn case_dir(scratch: &Path, r: &CaseRequest) -> PathBuf {
    scratch.join(format!("{:016x}", r.campaign_id)).join(format!("case-{:06}", r.case))
}

fn make_private(dir: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::DirBuilderExt;
    if dir.exists() {
        std::fs::remove_dir_all(dir)?;
    }
    std::fs::DirBuilder::new().recursive(true).mode(0o700).create(dir)
}

fn reply(q: &Query, answer: &CaseReply) {
    match serde_json::to_vec(answer) {
        Ok(body) => {
            let _ = q.reply(q.key_expr().clone(), body).wait();
        }
        Err(e) => {
            let _ = q.reply_err(format!("cannot encode the case's reply: {e}").into_bytes()).wait();
        }
    }
}
