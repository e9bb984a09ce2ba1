//! Cooperative runs: the drivers of one run (the plant and every agent) as stackful coroutines
//! of a single thread, each handing the thread on where it would otherwise wait for its peers.
//!
//! The in-process reference run gives each driver a thread, as the processes have; the lockstep
//! then hands off between N + 1 threads every step, which on a small machine keeps every core
//! busy with one run. A campaign of many runs wants the opposite: one core per run, so W runs at
//! once take W cores. Here the same drivers (the same code, messages, checks and files as the
//! processes and the threads) run as tasks of [`run`]; a waiting driver calls [`pause`] (from
//! `drive::wait`) instead of spinning or blocking, and the next task runs. What a run computes
//! does not depend on who runs when (the lockstep protocol), so the telemetry is the threads'
//! and the processes', bit for bit.
//!
//! A task must not block the thread for long (it would hold up the others): the drivers only
//! wait in [`pause`], except real-time pacing, which sleeps (a paced run is not a campaign's).

use std::cell::Cell;

use corosensei::stack::DefaultStack;
use corosensei::{Coroutine, CoroutineResult, Yielder};

/// Each task's stack, bytes (mapped, touched only as used; a guard page below).
pub const STACK_BYTES: usize = 16 << 20;

thread_local! {
    /// The yielder of the task running on this thread, null outside a task.
    static CURRENT: Cell<*const Yielder<(), ()>> = const { Cell::new(std::ptr::null()) };
}

/// Whether the caller runs as a task of [`run`].
pub fn active() -> bool {
    CURRENT.with(|c| !c.get().is_null())
}

/// Hand the thread on to the other tasks of [`run`] until it is this task's turn again; false,
/// doing nothing, outside a task.
pub fn pause() -> bool {
    let y = CURRENT.with(|c| c.get());
    if y.is_null() {
        return false;
    }
    // SAFETY: `y` is the running task's own yielder, set by its body (below) from the reference
    // corosensei passes it, which is valid for as long as the task's coroutine runs — and it runs:
    // this is its code.
    unsafe { (*y).suspend(()) };
    CURRENT.with(|c| c.set(y));
    true
}

/// Run `tasks` to their ends as coroutines of this thread, in turn: each runs until it pauses or
/// ends, and after every round `between` runs (the caller's watch: progress, signals). The
/// results in the tasks' order; a task's panic is resumed here (the other tasks are unwound).
pub fn run<'a, R>(tasks: Vec<Box<dyn FnOnce() -> R + 'a>>, mut between: impl FnMut()) -> std::io::Result<Vec<R>> {
    let mut coroutines = Vec::with_capacity(tasks.len());
    // Declared after the coroutines, so dropped before them: once this returns or unwinds (a task's
    // panic), no finished task's yielder is current while the others are unwound; the caller's own
    // (a task running this) is current again.
    let _reset = Restore(CURRENT.with(|c| c.replace(std::ptr::null())));
    for task in tasks {
        let stack = DefaultStack::new(STACK_BYTES)?;
        let body = move |y: &Yielder<(), ()>, ()| {
            CURRENT.with(|c| c.set(std::ptr::from_ref(y)));
            let r = task();
            CURRENT.with(|c| c.set(std::ptr::null()));
            r
        };
        // SAFETY: every coroutine made here is either driven to its end or dropped (which unwinds
        // its stack) before this function returns, and none is forgotten, so what `task` borrows
        // for 'a outlives it — what `ScopedCoroutine` guarantees with a scope per coroutine.
        coroutines.push(unsafe { Coroutine::<(), (), R, DefaultStack>::with_stack_unchecked(stack, body) });
    }
    let mut out: Vec<Option<R>> = std::iter::repeat_with(|| None).take(coroutines.len()).collect();
    let mut left = coroutines.len();
    while left > 0 {
        for (co, slot) in coroutines.iter_mut().zip(out.iter_mut()).filter(|(_, s)| s.is_none()) {
            let r = co.resume(());
            CURRENT.with(|c| c.set(std::ptr::null()));
            // (`_reset` covers a resume that unwinds.)
            if let CoroutineResult::Return(r) = r {
                *slot = Some(r);
                left -= 1;
            }
        }
        between();
    }
    Ok(out.into_iter().flatten().collect())
}

/// Makes the yielder it holds current again when dropped (null outside any task).
struct Restore(*const Yielder<(), ()>);

impl Drop for Restore {
    fn drop(&mut self) {
        CURRENT.with(|c| c.set(self.0));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    #[test]
    fn tasks_take_turns_on_one_thread_and_return_in_order() {
        // Two tasks in lockstep through a shared counter: each waits (pauses) for the other's turn.
        let turn = AtomicU32::new(0);
        let thread = std::thread::current().id();
        let task = |me: u32| {
            let turn = &turn;
            Box::new(move || {
                let mut seen = Vec::new();
                for k in 0..5 {
                    while turn.load(Ordering::SeqCst) != 2 * k + me {
                        assert!(pause(), "a task pauses");
                    }
                    assert_eq!(std::thread::current().id(), thread);
                    seen.push(k);
                    turn.fetch_add(1, Ordering::SeqCst);
                }
                (me, seen)
            }) as Box<dyn FnOnce() -> (u32, Vec<u32>)>
        };
        let mut rounds = 0;
        let out = run(vec![task(1), task(0)], || rounds += 1).unwrap();
        assert_eq!(out, [(1, vec![0, 1, 2, 3, 4]), (0, vec![0, 1, 2, 3, 4])]);
        assert!(rounds >= 5);
        assert!(!active() && !pause());
    }

    #[test]
    fn a_task_panic_reaches_the_caller() {
        let r = std::panic::catch_unwind(|| {
            let tasks: Vec<Box<dyn FnOnce()>> = vec![Box::new(|| while pause() {}), Box::new(|| panic!("boom"))];
            run(tasks, || {})
        });
        assert!(r.is_err());
        assert!(!active());
    }
}
