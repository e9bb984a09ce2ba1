//! The Python rows (`kind = "python"`, kinds/python): the consensus ring with its algorithm in
//! Python (`examples/python/consensus.py`, bit-identical to the Rust kind) against the Rust kind at
//! N = 6 and 50 (goal: ≥ 0.5× the Rust steps/s at N = 6); the null round with a Python null agent
//! against the Rust `null` kind (what crossing into Python costs per agent-step, goal ≤ 15 µs); and
//! a compute-bound Python agent (≈ 1 ms of numpy per step, N = 4) as processes against the
//! in-process reference, where the agents share one interpreter and its GIL (goal: multi-process
//! wall ≤ 0.6× the reference's).

use std::fmt::Write as _;
use std::path::Path;

use super::report::get;
use super::ring::{RING, RingRun, ring};
use super::types::{Aggregate, Case, median};

/// What the rows' ratios are taken of.
fn case(key: String, n: u32, variant: &str, scenario: cohort_runtime::paper::Setup, reference: bool) -> Case {
    Case {
        key,
        group: "python",
        n,
        variant: variant.into(),
        label: "python".into(),
        scenario,
        reference,
        hogs: false,
        lab: None,
        live: None,
    }
}

/// A `[algorithm] kind = "python"` section.
fn section(module: &Path, class: &str, share_values: usize, params: &str) -> String {
    format!(
        "[algorithm]\nkind = \"python\"\nmodule = {:?}\nclass = \"{class}\"\nshare_values = {share_values}\n\n\
         [algorithm.params]\n{params}",
        module.display().to_string()
    )
}

/// How every Python row's key starts.
pub(super) const KEY_PREFIX: &str = "python/";

/// Whether `--only prefix` may choose a Python row.
pub(super) fn may_choose(prefix: &str) -> bool {
    prefix.starts_with(KEY_PREFIX) || KEY_PREFIX.starts_with(prefix)
}

pub(super) fn cases(quick: bool, repo: &Path, scratch: &Path) -> Result<Vec<Case>, String> {
    let dir = scratch.join("python");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).map(|_| p.clone()).map_err(|e| format!("{}: {e}", p.display()))
    };
    let null_py = write("null.py", include_str!("null.py"))?;
    let busy_py = write("busy.py", include_str!("busy.py"))?;
    let consensus_py = repo.join("examples/python/consensus.py");
    let steps = if quick { 500 } else { 4000 };
    let mut out = Vec::new();
    for n in if quick { &[6u32][..] } else { &[6u32, 50][..] } {
        let n = *n;
        let gains = format!(
            "formation_radius_m = {:?}\nkp_per_s2 = 0.5\nkd_per_s = 1.5\nobserver_l1_per_s = 6.0\nobserver_l2_per_s2 = 9.0\n",
            2.0 * f64::from(n)
        );
        let py = section(&consensus_py, "ConsensusFormation", 6, &gains);
        out.push(case(format!("python/consensus/N={n}/rust"), n, "rust", ring(n, steps, RING)?, false));
        let s = ring(n, steps, RingRun { algorithm: Some(&py), ..RING })?;
        out.push(case(format!("python/consensus/N={n}/python"), n, "python", s, false));
    }
    let null = RingRun { null: true, ..RING };
    out.push(case("python/null/N=6/rust".into(), 6, "rust", ring(6, steps, null)?, false));
    let py = section(&null_py, "Null", 6, "");
    out.push(case(
        "python/null/N=6/python".into(),
        6,
        "python",
        ring(6, steps, RingRun { algorithm: Some(&py), ..null })?,
        false,
    ));
    // Each ≈ 1 ms per step on this project's machines (numpy: 500 iterations; floats: 2 500).
    let busy_steps = if quick { 100 } else { 500 };
    for (work, iterations) in [("numpy", 500), ("python", 2500)] {
        let busy = section(&busy_py, "Busy", 6, &format!("iterations = {iterations}\nwork = \"{work}\"\n"));
        let s = ring(4, busy_steps, RingRun { algorithm: Some(&busy), ..RING })?;
        out.push(case(format!("python/busy-{work}/N=4/multi-process"), 4, "multi-process", s.clone(), false));
        out.push(case(format!("python/busy-{work}/N=4/reference"), 4, "reference", s, true));
    }
    Ok(out)
}

/// Per repetition, a / b of `f` (the ratios of one run each, taken in the same repetition).
fn ratios(a: &Aggregate, b: &Aggregate, f: impl Fn(&super::types::Sample) -> f64) -> Vec<f64> {
    a.samples.iter().zip(&b.samples).map(|(x, y)| f(x) / f(y)).collect()
}

fn compute(a: &Aggregate) -> f64 {
    a.median_of(|s| s.agent_compute_us).unwrap_or(f64::NAN)
}

pub(super) fn markdown(a: &[Aggregate]) -> String {
    let mut md = String::new();
    let pairs: Vec<(String, u32)> = [("consensus", 6), ("consensus", 50), ("null", 6)]
        .iter()
        .filter(|(what, n)| get(a, &format!("python/{what}/N={n}/python")).is_some())
        .map(|(w, n)| (w.to_string(), *n))
        .collect();
    if !pairs.is_empty() {
        md.push_str(
            "\n## Python agents (`kind = \"python\"`) against the Rust kinds\n\nThe same ring with the Rust \
             kind and with its Python twin (`examples/python/consensus.py`; the null round's `bench/null.py`). \
             Compute: an agent's own share + step per step (timing/), median over agents; added: Python's \
             minus Rust's.\n\n| round | N | Rust steps/s | Python steps/s | Python / Rust | compute Rust µs | \
             compute Python µs | added µs per agent-step |\n|---|---|---|---|---|---|---|---|\n",
        );
    }
    for (what, n) in pairs {
        let (Some(r), Some(p)) =
            (get(a, &format!("python/{what}/N={n}/rust")), get(a, &format!("python/{what}/N={n}/python")))
        else {
            continue;
        };
        let ratio = median(&mut ratios(p, r, |s| s.steps_per_s));
        let (cr, cp) = (compute(r), compute(p));
        let _ = writeln!(
            md,
            "| {what} | {n} | {:.0} | {:.0} | {ratio:.2} | {cr:.1} | {cp:.1} | {:.1} |",
            r.steps_per_s_median,
            p.steps_per_s_median,
            cp - cr
        );
    }
    let busy: Vec<&str> = ["numpy", "python"]
        .into_iter()
        .filter(|w| get(a, &format!("python/busy-{w}/N=4/reference")).is_some())
        .collect();
    if !busy.is_empty() {
        md.push_str(
            "\n## A compute-bound Python agent (N = 4, ≈ 1 ms of work per step)\n\nMulti-process: four interpreters; \
             the in-process reference: one interpreter, one GIL. Compute: an agent's share + step per step.\n\n\
             | work | multi-process wall s | reference wall s | multi-process / reference (goal ≤ 0.6) | compute µs, \
             multi-process | compute µs, reference |\n|---|---|---|---|---|---|\n",
        );
    }
    for w in busy {
        let (Some(mp), Some(rf)) =
            (get(a, &format!("python/busy-{w}/N=4/multi-process")), get(a, &format!("python/busy-{w}/N=4/reference")))
        else {
            continue;
        };
        let ratio = median(&mut ratios(mp, rf, |s| s.wall_s));
        let _ = writeln!(
            md,
            "| {w} | {:.2} | {:.2} | {ratio:.2} | {:.0} | {:.0} |",
            mp.wall_s_median,
            rf.wall_s_median,
            compute(mp),
            compute(rf)
        );
    }
    md
}
