use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use super::*;

/// A case whose row is a chain of floating-point operations seeded by its index (so any mix-up of
/// indices, or of one case's state with another's, changes bits), taking a little varying time
/// so that workers finish out of order.
fn row(i: usize) -> (usize, f64) {
    let mut x = 1.0 + i as f64 * 0.1;
    for k in 0..(200 + (i * 7919) % 500) {
        x = (x * 1.000_1 + (k as f64).sin()).sqrt() + 0.5;
    }
    std::thread::sleep(Duration::from_micros(((i * 31) % 7) as u64 * 100));
    (i, x)
}

fn bits(rows: &[(usize, f64)]) -> Vec<(usize, u64)> {
    rows.iter().map(|(i, x)| (*i, x.to_bits())).collect()
}

#[test]
fn rows_are_the_same_on_1_2_and_7_workers_and_come_in_index_order() {
    let one = Campaign::new(40).workers(1).map(row);
    assert_eq!(one.iter().map(|r| r.0).collect::<Vec<_>>(), (0..40).collect::<Vec<_>>());
    for w in [2, 7] {
        assert_eq!(bits(&Campaign::new(40).workers(w).map(row)), bits(&one), "{w} workers");
        let ok: Result<Vec<_>, CaseFailed<String>> = Campaign::new(40).workers(w).run(|i| Ok(row(i)));
        assert_eq!(bits(&ok.expect("no case fails")), bits(&one), "{w} workers, run");
    }
    assert!(Campaign::new(0).workers(3).map(row).is_empty());
}

#[test]
fn one_worker_runs_on_the_callers_thread_and_each_worker_has_its_own_state() {
    let caller = std::thread::current().id();
    let threads = Campaign::new(5).workers(1).map(|_| std::thread::current().id());
    assert!(threads.iter().all(|t| *t == caller));
    // The state counts the cases its worker ran: with 3 workers the counts sum per worker.
    let inits = AtomicUsize::new(0);
    let seen = Campaign::new(30).workers(3).map_with(
        || {
            inits.fetch_add(1, Ordering::Relaxed);
            0usize
        },
        |n, _| {
            *n += 1;
            (std::thread::current().id(), *n)
        },
    );
    assert_eq!(inits.load(Ordering::Relaxed), 3);
    assert!(seen.iter().all(|(t, _)| *t != caller));
    let mut per_thread = std::collections::HashMap::new();
    for (t, n) in seen {
        let m = per_thread.entry(t).or_insert(0);
        assert!(n > *m, "a worker's own count only grows");
        *m = n;
    }
    assert_eq!(per_thread.values().sum::<usize>(), 30);
}

#[test]
fn the_error_is_the_lowest_failing_index_whatever_the_workers() {
    // Cases 5, 11 and 17 fail; 5 is slow so that later failures come back first.
    let case = |i: usize| -> Result<usize, String> {
        if i == 5 {
            std::thread::sleep(Duration::from_millis(30));
        }
        if [5, 11, 17].contains(&i) { Err(format!("bad {i}")) } else { Ok(i) }
    };
    for w in [1, 2, 7] {
        let e = Campaign::new(25).workers(w).run(case).expect_err("cases fail");
        assert_eq!((e.index, e.source.as_str()), (5, "bad 5"), "{w} workers");
        assert_eq!(e.to_string(), "case 5: bad 5");
    }
}

#[test]
fn a_stop_ends_the_hand_out_and_the_cases_under_way_finish() {
    for w in [1, 3] {
        // Cases 0–3 finish at once; the later ones wait until the stop has been seen (and a
        // little more), so exactly the cases under way at the stop (at most W) finish after it.
        let (started, seen) = (AtomicUsize::new(0), std::sync::atomic::AtomicBool::new(false));
        let finished = Cell::new(0);
        let progress = |done: usize, total: usize| {
            assert_eq!(total, 100);
            finished.set(done);
        };
        let stop = || {
            let now = finished.get() >= 4;
            seen.store(now, Ordering::SeqCst);
            now
        };
        let r = Campaign::new(100).workers(w).progress(&progress).stop(&stop).run(|i| {
            started.fetch_add(1, Ordering::SeqCst);
            while i >= 4 && !seen.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(1));
            }
            if i >= 4 {
                std::thread::sleep(Duration::from_millis(20));
            }
            Ok::<_, String>(i)
        });
        let started = started.load(Ordering::SeqCst);
        match r {
            Err(CampaignError::Stopped { done, total }) => {
                assert_eq!(total, 100);
                assert_eq!(done, started, "{w} workers: every started case ran to its end");
                assert!((4..=4 + w).contains(&done), "{w} workers: {done} done");
            }
            other => panic!("{w} workers: expected a stop, got {other:?}"),
        }
    }
    let never = Campaign::new(3).workers(2).stop(&|| true).run(Ok::<_, String>);
    assert!(matches!(never, Err(CampaignError::Stopped { done: 0, total: 3 })), "{never:?}");
    let late = Campaign::new(3).workers(2).stop(&|| false).run(Ok::<_, String>);
    assert_eq!(late.expect("not stopped"), [0, 1, 2]);
}

#[test]
fn progress_counts_every_case_once_up_to_n() {
    for w in [1, 4] {
        let seen = Mutex::new(Vec::new());
        let progress = |done: usize, total: usize| seen.lock().expect("test lock").push((done, total));
        Campaign::new(12).workers(w).progress(&progress).map(row);
        assert_eq!(seen.into_inner().expect("test lock"), (1..=12).map(|d| (d, 12)).collect::<Vec<_>>());
    }
}

#[test]
fn a_panicking_case_panics_the_caller() {
    let r = std::panic::catch_unwind(|| {
        Campaign::new(50).workers(3).map(|i| {
            assert!(i != 7, "case 7 panics");
            i
        })
    });
    let payload = r.expect_err("the panic reaches the caller");
    let msg = payload.downcast_ref::<&str>().copied().or(payload.downcast_ref::<String>().map(String::as_str));
    let msg = msg.unwrap_or("(not a text)");
    assert!(msg.contains("case 7 panics"), "{msg:?}");
}
