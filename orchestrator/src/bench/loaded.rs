//! The loaded rows: the ring with two busy-loop hogs the bench starts and stops around each run,
//! for every waiting strategy (goals: adaptive waiting under load within 1.2× the time of `event`
//! at N = 6; and, idle and loaded, adaptive within 10 % of the best of `event` and `poll`).

use std::fmt::Write as _;

use super::report::{f0, get, ns_of};
use super::types::{Aggregate, median};

/// Two threads that burn a core each until dropped: a machine busy with other work (the
/// "loaded" rows). As threads of the bench itself they end with it, whatever happens.
pub(super) struct Hogs {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hogs {
    pub(super) fn start() -> Self {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let threads = (0..2)
            .map(|_| {
                let stop = std::sync::Arc::clone(&stop);
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The loaded rows' section: steps/s and wall time with and without hogs, the adaptive/event
/// ratio against its goal, and every process's waits per repetition (empty without both rows).
pub(super) fn loaded_markdown(a: &[Aggregate]) -> String {
    let mut md = String::new();
    let wall = |k: &str| get(a, k).map_or(f64::NAN, |x| x.wall_s_median);
    let sps = |k: &str| get(a, k).map_or(f64::NAN, |x| x.steps_per_s_median);
    if let (Some(ev), Some(ad)) = (get(a, "loaded/N=6/event"), get(a, "loaded/N=6/adaptive")) {
        let ratios: Vec<f64> = ad.samples.iter().zip(&ev.samples).map(|(x, y)| x.wall_s / y.wall_s).collect();
        let ratio = median(&mut ratios.clone());
        let _ = writeln!(
            md,
            "\n## Loaded machine: consensus ring N = 6 with two busy-loop hogs\n\n| wait | steps/s | wall s |\n|---|---|---|\n\
             | event | {} | {:.2} |\n| adaptive (default) | {} | {:.2} |\n| adaptive, no hogs (ring row above) | {} | {:.2} |\n\n\
             Adaptive wall / event wall under load: median {ratio:.2} (per repetition: {}); goal ≤ 1.2: {}.",
            f0(ev.steps_per_s_median),
            ev.wall_s_median,
            f0(ad.steps_per_s_median),
            ad.wall_s_median,
            f0(sps("ring/N=6/adaptive")),
            wall("ring/N=6/adaptive"),
            ratios.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", "),
            if ratio <= 1.2 { "met" } else { "not met" }
        );
        md.push_str(
            "\nWaits of every process, summed, per repetition (a wait is one that did not find its messages at once):\n\n\
             | wait | waits | spun | stalled spins | expired spins | spinning s | wall s |\n|---|---|---|---|---|---|---|\n",
        );
        for (label, agg) in [("event", ev), ("adaptive", ad)] {
            for x in &agg.samples {
                let w = &x.wait;
                let _ = writeln!(
                    md,
                    "| {label} | {} | {} | {} | {} | {:.3} | {:.2} |",
                    w.waits, w.spun, w.spin_stalls, w.spin_expired, w.spin_s, x.wall_s
                );
            }
        }
    }
    md.push_str(&against_best_markdown(a));
    md
}

/// Adaptive steps/s over the best of event and poll, per repetition (the strategies of one
/// repetition ran one after another, so they met the same machine), without hogs (ring rows) and under
/// the hogs (loaded rows).
fn adaptive_over_best(a: &[Aggregate], group: &str, n: u32) -> Option<Vec<f64>> {
    let (ev, po, ad) = (
        get(a, &format!("{group}/N={n}/event"))?,
        get(a, &format!("{group}/N={n}/poll"))?,
        get(a, &format!("{group}/N={n}/adaptive"))?,
    );
    let ratios = ad.samples.iter().zip(&ev.samples).zip(&po.samples);
    Some(ratios.map(|((x, e), p)| x.steps_per_s / e.steps_per_s.max(p.steps_per_s)).collect())
}

/// The section holding the default wait against the best fixed one at every N with both rows.
fn against_best_markdown(a: &[Aggregate]) -> String {
    let ns = ns_of(a, &["ring", "loaded"]);
    let mut md = String::new();
    let mut rows = String::new();
    for n in ns {
        for (group, label) in [("ring", "no hogs"), ("loaded", "two hogs")] {
            let Some(r) = adaptive_over_best(a, group, n) else { continue };
            let sps = |w: &str| get(a, &format!("{group}/N={n}/{w}")).map_or(f64::NAN, |x| x.steps_per_s_median);
            let m = median(&mut r.clone());
            let _ = writeln!(
                rows,
                "| {n} | {label} | {} | {} | {} | {m:.2} ({}) | {} |",
                f0(sps("event")),
                f0(sps("poll")),
                f0(sps("adaptive")),
                r.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>().join(", "),
                if m >= 0.9 { "met" } else { "not met" }
            );
        }
    }
    if !rows.is_empty() {
        md.push_str(
            "\n## The default wait against the best fixed one\n\nAdaptive steps/s over the best of event and poll in the \
             same repetition (median, then per repetition); goal ≥ 0.90.\n\n\
             | N | machine | event | poll | adaptive | adaptive / best | goal |\n|---|---|---|---|---|---|---|\n",
        );
        md.push_str(&rows);
    }
    md
}
