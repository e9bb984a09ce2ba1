//! Timeline events as they happen, for an observer of the run (`launch --live`): the supervision
//! loop hands each event to [`emit`], which passes a copy to the observer [`watch`] installed, if
//! any. Without one it is a lock and a `None`: nothing is kept, no thread exists. The observer's
//! channel is unbounded and the observer drains it at its own pace; events are few (faults, roster
//! changes), so the supervision loop never waits.
//!
//! A multi-host run also lends the observer its host links ([`hosts`]): the telemetry of processes
//! on other machines is not in this machine's `telemetry/` until they end, so the observer asks
//! their daemons for it ([`remote_rows`]).

use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, Weak};
use std::time::Duration;

use cohort_runtime::record::TimelineEvent;

use crate::hostproto::ProcRows;
use crate::remote::Remote;

static OBSERVER: Mutex<Option<Sender<TimelineEvent>>> = Mutex::new(None);
/// Weak: the run's sessions (and the orchestrator's token the daemons watch) must end with the
/// run, whatever the observer does.
static REMOTE: Mutex<Option<Weak<Remote>>> = Mutex::new(None);

/// Send every later event to `tx` (replacing any earlier observer); `None` stops.
pub fn watch(tx: Option<Sender<TimelineEvent>>) {
    *OBSERVER.lock().unwrap_or_else(|p| p.into_inner()) = tx;
}

/// Pass one event to the observer, if there is one (a gone observer is forgotten).
pub fn emit(event: &TimelineEvent) {
    let mut o = OBSERVER.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(tx) = o.as_ref()
        && tx.send(event.clone()).is_err()
    {
        *o = None;
    }
}

/// The host links of the run under way (`None` at its end), set by the supervisor.
pub(crate) fn hosts(remote: Option<&Arc<Remote>>) {
    *REMOTE.lock().unwrap_or_else(|p| p.into_inner()) = remote.map(Arc::downgrade);
}

/// The new decimated telemetry rows of the processes on every other host of the run under way
/// (none when it has no hosts, or a host is lost or does not answer within `timeout`).
pub fn remote_rows(every: u64, max_rows: usize, timeout: Duration) -> Vec<ProcRows> {
    let Some(remote) = REMOTE.lock().unwrap_or_else(|p| p.into_inner()).as_ref().and_then(Weak::upgrade) else {
        return Vec::new();
    };
    let mut rows = Vec::new();
    for host in remote.hosts.iter().filter(|h| !h.daemon_lost()) {
        match remote.rows(host, every, max_rows, timeout) {
            Ok(r) => rows.extend(r),
            Err(e) => tracing::debug!("live rows: {e}"),
        }
    }
    rows
}
