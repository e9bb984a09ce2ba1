//! The campaign kit: run `N` independent in-process cases on `W` worker threads and get their rows
//! back in index order.
//!
//! Papers' commands and trainers fly many independent cases (Monte Carlo draws, training samples,
//! evaluation runs). Each used to carry its own `std::thread::scope` + `AtomicUsize` next-index
//! counter + `Mutex` of slots; this is that plumbing once, with the rules every caller relied on:
//!
//! - **Determinism**: a case is a closure of its index (`Fn(usize) -> …`); anything random is seeded
//!   by the caller from that index, so the rows never depend on `W` nor on which worker ran a case.
//!   Rows come back in index order.
//! - **Workers**: `W` defaults to [`std::thread::available_parallelism`]; it is clamped to `1..=N`
//!   (0 counts as 1). With `W = 1` the cases run one after another on the caller's thread; with more,
//!   `W` scoped threads take the next index from a shared counter (so cases start in index order).
//!   [`Campaign::map_with`] gives every worker its own scratch state (a solver log, an integrator's
//!   work space) made by an `init` closure on that worker's thread; rows must not depend on it.
//! - **Errors**: infallible cases go through [`Campaign::map`]. With [`Campaign::run`] a failing
//!   case stops the hand-out of further cases, the cases under way finish, and the error returned
//!   is the one of the lowest failing index, the same whatever `W`: cases start in index order, so
//!   every index below a failure has been started and runs to its end.
//! - **Stop**: [`Campaign::stop`] gives a callback ("has a signal come?") polled on the caller's
//!   thread before the first case, after every finished case and, with `W > 1`, at least every
//!   50 ms while cases run (with `W = 1` the caller's thread is busy flying the case). Once it
//!   says true no further case starts; the cases under way run to their end (a case is never
//!   interrupted), and unless every case had finished the result is [`CampaignError::Stopped`].
//! - **Progress**: [`Campaign::progress`] gives a callback called on the caller's thread with
//!   (cases done, N) after every finished case, in the order they finish.
//!
//! The callbacks run on the caller's thread, so they need not be `Sync`. A panicking case is a bug:
//! the other workers stop taking cases and the panic is resumed on the caller's thread.
//!
//! Writing the rows stays with each caller: their files share no shape (a resumable CSV under a
//! provenance line, several rows per case, summaries of many cases, `{}` or `{:?}` numbers), and
//! Markdown tables already have one home, `cohort_report::markdown::MdTable`.

use std::convert::Infallible;
use std::panic::resume_unwind;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

#[cfg(test)]
mod tests;

/// How often the caller's thread polls the stop callback while workers run.
const STOP_POLL: Duration = Duration::from_millis(50);

/// Case `index` failed with `source` (the lowest failing index of the campaign).
#[derive(Debug, thiserror::Error)]
#[error("case {index}: {source}")]
pub struct CaseFailed<E> {
    pub index: usize,
    pub source: E,
}

/// Why a stoppable campaign returned no rows.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError<E> {
    #[error(transparent)]
    Case(#[from] CaseFailed<E>),
    /// The stop callback said true before every case had finished.
    #[error("stopped after {done} of {total} cases")]
    Stopped { done: usize, total: usize },
}

/// `N` cases to run; see the module docs.
pub struct Campaign<'a> {
    count: usize,
    workers: usize,
    progress: Option<&'a dyn Fn(usize, usize)>,
}

/// A [`Campaign`] with a stop callback (its runs can end in [`CampaignError::Stopped`]).
pub struct Stoppable<'a> {
    campaign: Campaign<'a>,
    stop: &'a dyn Fn() -> bool,
}

impl<'a> Campaign<'a> {
    /// `count` cases on [`std::thread::available_parallelism`] workers.
    pub fn new(count: usize) -> Self {
        let workers = std::thread::available_parallelism().map_or(1, usize::from);
        Self { count, workers, progress: None }
    }

    /// Run on `workers` worker threads (clamped to `1..=N`; 1 runs on the caller's thread).
    pub fn workers(mut self, workers: usize) -> Self {
        self.workers = workers;
        self
    }

    /// Call `f(done, N)` on the caller's thread after every finished case.
    pub fn progress(mut self, f: &'a dyn Fn(usize, usize)) -> Self {
        self.progress = Some(f);
        self
    }

    /// Stop handing out cases once `stop` says true (see the module docs).
    pub fn stop(self, stop: &'a dyn Fn() -> bool) -> Stoppable<'a> {
        Stoppable { campaign: self, stop }
    }

    /// Every case's row, in index order.
    pub fn map<R: Send>(&self, case: impl Fn(usize) -> R + Sync) -> Vec<R> {
        self.map_with(|| (), |(), i| case(i))
    }

    /// [`Self::map`] with a scratch state per worker, made by `init` on the worker's thread.
    pub fn map_with<S, R: Send>(
        &self,
        init: impl Fn() -> S + Sync,
        case: impl Fn(&mut S, usize) -> R + Sync,
    ) -> Vec<R> {
        let run = self.drive(None, init, |s, i| Ok::<R, Infallible>(case(s, i)));
        rows(run).unwrap_or_else(|e| match e {
            CampaignError::Case(f) => match f.source {},
            CampaignError::Stopped { .. } => unreachable!("a campaign without a stop callback runs every case"),
        })
    }

    /// Every case's row in index order, or the failure of the lowest failing index.
    pub fn run<R: Send, E: Send>(&self, case: impl Fn(usize) -> Result<R, E> + Sync) -> Result<Vec<R>, CaseFailed<E>> {
        rows(self.drive(None, || (), |(), i| case(i))).map_err(|e| match e {
            CampaignError::Case(f) => f,
            CampaignError::Stopped { .. } => unreachable!("a campaign without a stop callback runs every case"),
        })
    }

    fn drive<S, R: Send, E: Send>(
        &self,
        stop: Option<&dyn Fn() -> bool>,
        init: impl Fn() -> S + Sync,
        case: impl Fn(&mut S, usize) -> Result<R, E> + Sync,
    ) -> Outcome<R, E> {
        let mut out = Outcome::new(self.count);
        if self.count == 0 {
            return out;
        }
        if stop.is_some_and(|f| f()) {
            out.stopped = true;
        } else if self.workers.clamp(1, self.count.max(1)) == 1 {
            self.serial(stop, &init, &case, &mut out);
        } else {
            self.parallel(stop, &init, &case, &mut out);
        }
        out
    }

    /// The cases one after another on the caller's thread.
    fn serial<S, R, E>(
        &self,
        stop: Option<&dyn Fn() -> bool>,
        init: &dyn Fn() -> S,
        case: &dyn Fn(&mut S, usize) -> Result<R, E>,
        out: &mut Outcome<R, E>,
    ) {
        let mut state = init();
        for i in 0..self.count {
            if out.record(i, case(&mut state, i)) {
                break;
            }
            self.report(out);
            if stop.is_some_and(|f| f()) {
                out.stopped = true;
                break;
            }
        }
    }

    /// The cases on `W` scoped workers; the caller's thread collects, reports and polls `stop`.
    fn parallel<S, R: Send, E: Send>(
        &self,
        stop: Option<&dyn Fn() -> bool>,
        init: &(dyn Fn() -> S + Sync),
        case: &(dyn Fn(&mut S, usize) -> Result<R, E> + Sync),
        out: &mut Outcome<R, E>,
    ) {
        let (next, halt) = (AtomicUsize::new(0), AtomicBool::new(false));
        let (tx, rx) = mpsc::channel();
        std::thread::scope(|s| {
            let handles: Vec<_> = (0..self.workers.min(self.count))
                .map(|_| {
                    let (tx, next, halt, count) = (tx.clone(), &next, &halt, self.count);
                    s.spawn(move || worker(count, next, halt, init, case, tx))
                })
                .collect();
            drop(tx);
            self.collect(&rx, stop, &halt, out);
            for h in handles {
                if let Err(panic) = h.join() {
                    resume_unwind(panic);
                }
            }
        });
    }

    /// Receive the workers' rows until every worker has ended; set `halt` on a failure or a stop.
    fn collect<R, E>(
        &self,
        rx: &Receiver<(usize, Result<R, E>)>,
        stop: Option<&dyn Fn() -> bool>,
        halt: &AtomicBool,
        out: &mut Outcome<R, E>,
    ) {
        loop {
            let got = match stop {
                Some(_) => rx.recv_timeout(STOP_POLL),
                None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
            };
            match got {
                Ok((i, r)) => {
                    if out.record(i, r) {
                        halt.store(true, Ordering::Relaxed);
                    }
                    self.report(out);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if !out.stopped && !halt.load(Ordering::Relaxed) && stop.is_some_and(|f| f()) {
                out.stopped = true;
                halt.store(true, Ordering::Relaxed);
            }
        }
    }

    fn report<R, E>(&self, out: &Outcome<R, E>) {
        if let Some(f) = self.progress {
            f(out.done, self.count);
        }
    }
}

impl Stoppable<'_> {
    /// Every case's row in index order; the failure of the lowest failing index; or
    /// [`CampaignError::Stopped`] when the stop callback ended the campaign early.
    pub fn run<R: Send, E: Send>(
        &self,
        case: impl Fn(usize) -> Result<R, E> + Sync,
    ) -> Result<Vec<R>, CampaignError<E>> {
        rows(self.campaign.drive(Some(self.stop), || (), |(), i| case(i)))
    }
}

/// One worker: take the next index until none is left or `halt` is set; send each result.
fn worker<S, R, E>(
    count: usize,
    next: &AtomicUsize,
    halt: &AtomicBool,
    init: &dyn Fn() -> S,
    case: &dyn Fn(&mut S, usize) -> Result<R, E>,
    tx: Sender<(usize, Result<R, E>)>,
) {
    let _guard = HaltOnPanic(halt);
    let mut state = init();
    while !halt.load(Ordering::Relaxed) {
        let i = next.fetch_add(1, Ordering::Relaxed);
        if i >= count || tx.send((i, case(&mut state, i))).is_err() {
            break;
        }
    }
}

/// Sets the halt flag when its worker unwinds, so the others stop taking cases.
struct HaltOnPanic<'a>(&'a AtomicBool);

impl Drop for HaltOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Relaxed);
        }
    }
}

/// What a campaign produced: a slot per case, the lowest failure, and whether it was stopped.
struct Outcome<R, E> {
    rows: Vec<Option<R>>,
    failed: Option<CaseFailed<E>>,
    done: usize,
    stopped: bool,
}

impl<R, E> Outcome<R, E> {
    fn new(count: usize) -> Self {
        Self { rows: std::iter::repeat_with(|| None).take(count).collect(), failed: None, done: 0, stopped: false }
    }

    /// Keep case `index`'s result; true when it failed (no further case should start).
    fn record(&mut self, index: usize, r: Result<R, E>) -> bool {
        self.done += 1;
        match r {
            Ok(row) => {
                self.rows[index] = Some(row);
                false
            }
            Err(source) => {
                if self.failed.as_ref().is_none_or(|f| index < f.index) {
                    self.failed = Some(CaseFailed { index, source });
                }
                true
            }
        }
    }
}

/// The rows in index order, or why not.
fn rows<R, E>(o: Outcome<R, E>) -> Result<Vec<R>, CampaignError<E>> {
    if let Some(f) = o.failed {
        return Err(f.into());
    }
    let total = o.rows.len();
    o.rows.into_iter().collect::<Option<Vec<R>>>().ok_or(CampaignError::Stopped { done: o.done, total })
}
