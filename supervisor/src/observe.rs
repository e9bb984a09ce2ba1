//! Timeline events as they happen, for an observer of the run (`launch --live`): the supervision
//! loop hands each event to [`emit`], which passes a copy to the observer [`watch`] installed, if
//! any. Without one it is a lock and a `None`: nothing is kept, no thread exists. The observer's
//! channel is unbounded and the observer drains it at its own pace; events are few (faults, roster
//! changes), so the supervision loop never waits.

use std::sync::Mutex;
use std::sync::mpsc::Sender;

use cohort_runtime::record::TimelineEvent;

static OBSERVER: Mutex<Option<Sender<TimelineEvent>>> = Mutex::new(None);

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
