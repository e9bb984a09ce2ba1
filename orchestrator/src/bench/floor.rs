//! The machine's wake floor: the consensus ring's lockstep wake graph among N + 1 processes that
//! do nothing else. The "plant" (this process) publishes step k to every agent and wakes it; each
//! agent publishes its share and wakes its two neighbours, waits for theirs, then counts its
//! control and wakes the plant; the plant waits for all N. No iceoryx2, no algorithm, no
//! telemetry, no clock: a word of shared memory per message and a futex per process, waiting
//! either by blocking at once (`FUTEX_WAIT`, as `run.wait = "event"`) or by yielding until the
//! word is there (`sched_yield`, as `poll`).
//!
//! The ring rows over this floor at the same N say how much of what the machine allows a
//! process-per-agent lockstep of that shape the runtime keeps; the floor itself says what no
//! runtime of that shape can beat here (a target above it is a target for another machine).
//!
//! The agents are `fork`ed children that touch only atomics in a shared anonymous mapping and
//! make only system calls (`futex`, `sched_yield`, `prctl`, `_exit`), which is what a child of a
//! multi-threaded process may do. Each dies with this thread (`PR_SET_PDEATHSIG`); the mapping
//! has no name, so nothing outlives the measurement.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::SeqCst};
use std::time::{Duration, Instant};

use serde::Serialize;

use super::report::{f0, f2, get, ns_of};
use super::types::{Aggregate, median};

/// How the floor's processes wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum FloorWait {
    /// Block in `FUTEX_WAIT` as soon as the word is not there.
    Block,
    /// `sched_yield` until the word is there.
    Spin,
}

/// One measurement: N agents, the wait, steps/s over the timed steps.
#[derive(Debug, Clone, Serialize)]
pub(super) struct FloorRow {
    pub(super) n: u32,
    pub(super) wait: FloorWait,
    pub(super) steps_per_s: f64,
}

/// A measurement that did not finish: a child could not be started or the steps did not end in
/// time (the children are killed and reaped either way).
#[derive(Debug, thiserror::Error)]
pub(super) enum FloorError {
    #[error("wake floor, N = {n}: cannot map {bytes} bytes of shared memory: {source}")]
    Map { n: u32, bytes: usize, source: std::io::Error },
    #[error("wake floor, N = {n}: cannot fork agent {i}: {source}")]
    Fork { n: u32, i: u32, source: std::io::Error },
    #[error("wake floor, N = {n}, {wait:?}: step {step} of {steps} not done after {after_s:.0} s")]
    Stuck { n: u32, wait: FloorWait, step: u64, steps: u64, after_s: f64 },
}

/// Steps for `n` agents: about 120 000 agent-steps, at least 200 steps; the first tenth are not
/// timed (start-up, page faults).
pub(super) fn steps_for(n: u32) -> u64 {
    (120_000 / u64::from(n.max(1))).max(200)
}

/// A whole measurement may take this long before it is called stuck.
const DEADLINE: Duration = Duration::from_secs(120);
/// A blocking wait re-checks its condition (and the deadline) at least this often.
const WAIT_SLICE_NS: i64 = 100_000_000;

/// A 64-byte line per process: its futex word (1: about to sleep), a ring counter, and the last
/// step of its message (agent i: its measurement from the plant, then its share). Slot 0 is the
/// plant's; the agents' controls are counted in `meas` of line N + 1 ([`Board::controls`]).
#[repr(C, align(64))]
struct Line {
    sleeping: AtomicU32,
    bell: AtomicU32,
    meas: AtomicU64,
    share: AtomicU64,
}

/// The shared mapping of N + 2 lines.
struct Board {
    lines: *const Line,
    len: usize,
    n: u32,
}

impl Board {
    fn map(n: u32) -> Result<Self, FloorError> {
        let len = (n as usize + 2) * std::mem::size_of::<Line>();
        // SAFETY: a fresh anonymous shared mapping, zeroed by the kernel (all-zero atomics are
        // valid), page-aligned and so aligned for `Line`.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return Err(FloorError::Map { n, bytes: len, source: std::io::Error::last_os_error() });
        }
        Ok(Self { lines: base.cast(), len, n })
    }
    fn line(&self, k: u32) -> &Line {
        assert!(k <= self.n + 1);
        // SAFETY: k < n + 2 lines, inside the mapping, which lives as long as `self`.
        unsafe { &*self.lines.add(k as usize) }
    }
    fn controls(&self) -> &AtomicU64 {
        &self.line(self.n + 1).meas
    }
    /// Wake process `k` (after publishing what it waits for): a system call only when it sleeps.
    fn ring(&self, k: u32) {
        let l = self.line(k);
        l.bell.fetch_add(1, SeqCst);
        if l.sleeping.load(SeqCst) == 1 && l.sleeping.swap(0, SeqCst) == 1 {
            // SAFETY: FUTEX_WAKE on a word of the shared mapping.
            unsafe { libc::syscall(libc::SYS_futex, &l.bell as *const AtomicU32, libc::FUTEX_WAKE, 1) };
        }
    }
    /// Wait as process `k` until `ready()`, or until `deadline` (false).
    fn wait(&self, k: u32, how: FloorWait, deadline: Option<Instant>, ready: impl Fn() -> bool) -> bool {
        let l = self.line(k);
        while !ready() {
            if how == FloorWait::Spin {
                // SAFETY: no preconditions.
                unsafe { libc::sched_yield() };
            } else {
                let bell = l.bell.load(SeqCst);
                l.sleeping.store(1, SeqCst);
                if !ready() {
                    let slice = libc::timespec { tv_sec: 0, tv_nsec: WAIT_SLICE_NS };
                    // SAFETY: FUTEX_WAIT on a word of the shared mapping with a valid timeout; it
                    // returns at once if a ring changed the word since it was read.
                    unsafe {
                        libc::syscall(
                            libc::SYS_futex,
                            &l.bell as *const AtomicU32,
                            libc::FUTEX_WAIT,
                            bell,
                            &slice as *const libc::timespec,
                        )
                    };
                }
                l.sleeping.store(0, SeqCst);
            }
            // Only the plant has a deadline (its clock read is off the agents' path).
            if deadline.is_some_and(|d| Instant::now() > d) {
                return false;
            }
        }
        true
    }
    /// Agent i's life in a child: the steps, then `_exit`.
    fn agent(&self, i: u32, how: FloorWait, steps: u64) -> ! {
        let (left, right) = (if i == 1 { self.n } else { i - 1 }, if i == self.n { 1 } else { i + 1 });
        let me = self.line(i);
        for k in 1..=steps {
            self.wait(i, how, None, || me.meas.load(SeqCst) >= k);
            me.share.store(k, SeqCst);
            self.ring(left);
            self.ring(right);
            let (l, r) = (self.line(left), self.line(right));
            self.wait(i, how, None, || l.share.load(SeqCst) >= k && r.share.load(SeqCst) >= k);
            self.controls().fetch_add(1, SeqCst);
            self.ring(0);
        }
        // SAFETY: ends the child without running anything of the parent's (no destructors, no
        // atexit handlers).
        unsafe { libc::_exit(0) }
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `map`, unmapped once.
        unsafe { libc::munmap(self.lines as *mut libc::c_void, self.len) };
    }
}

/// Fork agent `i`: the child sets its death signal, checks its parent is still there, and runs.
fn fork_agent(board: &Board, i: u32, how: FloorWait, steps: u64) -> Result<libc::pid_t, FloorError> {
    // SAFETY: getpid has no preconditions.
    let parent = unsafe { libc::getpid() };
    // SAFETY: the child only runs `Board::agent` (atomics and system calls, no allocation or lock)
    // and ends in `_exit`.
    match unsafe { libc::fork() } {
        -1 => Err(FloorError::Fork { n: board.n, i, source: std::io::Error::last_os_error() }),
        0 => {
            // SAFETY: prctl and getppid have no memory preconditions.
            unsafe {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                if libc::getppid() != parent {
                    libc::_exit(1);
                }
            }
            board.agent(i, how, steps)
        }
        pid => Ok(pid),
    }
}

/// Kill (when asked) and reap every child.
fn reap(pids: &[libc::pid_t], kill: bool) {
    for &pid in pids {
        // SAFETY: our own children's pids, not yet reaped.
        unsafe {
            if kill {
                libc::kill(pid, libc::SIGKILL);
            }
            libc::waitpid(pid, std::ptr::null_mut(), 0);
        }
    }
}

/// Measure the floor for `n` agents waiting `how`, over `steps` steps (at least 10).
pub(super) fn measure(n: u32, how: FloorWait, steps: u64) -> Result<FloorRow, FloorError> {
    let board = Board::map(n)?;
    let steps = steps.max(10);
    let mut pids = Vec::with_capacity(n as usize);
    for i in 1..=n {
        match fork_agent(&board, i, how, steps) {
            Ok(pid) => pids.push(pid),
            Err(e) => {
                reap(&pids, true);
                return Err(e);
            }
        }
    }
    let deadline = Instant::now() + DEADLINE;
    let timed_from = steps / 10;
    let mut t0 = Instant::now();
    for k in 1..=steps {
        if k == timed_from + 1 {
            t0 = Instant::now();
        }
        for i in 1..=n {
            board.line(i).meas.store(k, SeqCst);
            board.ring(i);
        }
        let controls = board.controls();
        let all = k * u64::from(n);
        if !board.wait(0, how, Some(deadline), || controls.load(SeqCst) >= all) {
            reap(&pids, true);
            return Err(FloorError::Stuck { n, wait: how, step: k, steps, after_s: DEADLINE.as_secs_f64() });
        }
    }
    let steps_per_s = (steps - timed_from) as f64 / t0.elapsed().as_secs_f64();
    reap(&pids, false);
    Ok(FloorRow { n, wait: how, steps_per_s })
}

/// The floor at every N of the run's idle ring and scale rows, `reps` times interleaved (both
/// waits each time), medians. None at all when no such row ran.
pub(super) fn measure_for(a: &[Aggregate], reps: u32) -> Result<Vec<FloorRow>, FloorError> {
    let mut out = Vec::new();
    for n in ns_of(a, &["ring", "scale"]) {
        for how in [FloorWait::Block, FloorWait::Spin] {
            let mut rates = Vec::new();
            for _ in 0..reps.max(1) {
                rates.push(measure(n, how, steps_for(n))?.steps_per_s);
            }
            out.push(FloorRow { n, wait: how, steps_per_s: median(&mut rates) });
        }
    }
    Ok(out)
}

/// The floor's section: per N the floor both ways, the runtime's ring with each wait, and the
/// ring over the floor: `event` over blocking, `poll` over yielding, the default over the better.
pub(super) fn markdown(a: &[Aggregate], rows: &[FloorRow]) -> String {
    use std::fmt::Write as _;
    if rows.is_empty() {
        return String::new();
    }
    let mut md = String::from(
        "\n## The machine's wake floor: the ring's wake graph and nothing else\n\n\
         N + 1 processes pass the ring's lockstep (plant → every agent → its two neighbours → \
         plant) through a word of shared memory and a futex each, blocking or yielding; no \
         iceoryx2, no algorithm, no telemetry (medians over the repetitions, measured after the \
         cases). Against it, the ring's steps/s at the same N:\n\n\
         | N | floor, blocking | floor, yielding | ring event | ring poll | ring adaptive | event ÷ blocking | poll ÷ yielding | adaptive ÷ better floor |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let mut ns: Vec<u32> = rows.iter().map(|r| r.n).collect();
    ns.dedup();
    for n in ns {
        let floor = |w| rows.iter().find(|r| r.n == n && r.wait == w).map_or(f64::NAN, |r| r.steps_per_s);
        let ring = |v: &str| {
            get(a, &format!("ring/N={n}/{v}"))
                .or_else(|| get(a, &format!("scale/N={n}/{v}")))
                .map_or(f64::NAN, |x| x.steps_per_s_median)
        };
        let (fb, fs) = (floor(FloorWait::Block), floor(FloorWait::Spin));
        let (ev, po, ad) = (ring("event"), ring("poll"), ring("adaptive"));
        let _ = writeln!(
            md,
            "| {n} | {} | {} | {} | {} | {} | {} | {} | {} |",
            f0(fb),
            f0(fs),
            f0(ev),
            f0(po),
            f0(ad),
            f2(ev / fb),
            f2(po / fs),
            f2(ad / fb.max(fs))
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both waits run the lockstep to its end (`measure` reaps every child it forked), at a rate
    /// no run could reach if the floor lost wake-ups (a lost wake-up would stall a blocking step for a
    /// whole 100 ms slice: ≤ 10 steps/s).
    #[test]
    fn the_floor_runs_to_the_end_both_ways() {
        for how in [FloorWait::Block, FloorWait::Spin] {
            let row = measure(3, how, 2_000).unwrap();
            assert_eq!((row.n, row.wait), (3, how));
            assert!(row.steps_per_s.is_finite() && row.steps_per_s > 10.0, "{row:?}");
        }
    }
}
