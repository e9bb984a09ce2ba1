//! Every runnable scenario in `topologies/` runs to completion: each `topologies/*.toml` (the
//! folder holds no test fixture: `check.rs`) is launched for at most 10 s of simulated time, or ten steps when its step is
//! longer than a second (`--duration` when the file is longer; a shorter file runs whole), in-process (`--reference`, the fastest mode; each
//! paper's own tests compare it with the multi-process run bit for bit), then again with its drivers
//! on one thread (`--one-thread`, how a campaign runs its cases), whose telemetry must be the
//! same bit for bit. A run must exit 0 with the
//! status `ok` — or, for a divergence study (`scenario.expect = "diverge"`), with `diverged`, the
//! time and the metrics up to it.
//!
//! Run with `scripts/test`, which builds the release binaries first.

use std::path::Path;

use cohort::{describe_output, heavy, launch_scenario, repo_root, scratch_dir, summary, telemetry_bits, tomls_in};
use cohort_scenario::{Expect, Overrides};

/// The longest stretch of simulated time a scenario is run for here, s (or this many steps).
const MAX_DURATION_S: f64 = 10.0;

/// Launch `name` as described above; a description of what went wrong, if anything did.
fn launch_one(name: &str, out: &Path) -> Option<String> {
    let file = repo_root().join("topologies").join(name);
    let s = match cohort_scenario::load(&file, &Overrides::default()) {
        Ok(s) => s,
        Err(e) => return Some(format!("does not parse: {e}")),
    };
    let max_s = MAX_DURATION_S * s.scenario.dt_s.max(1.0);
    let shorten = s.scenario.duration_s > max_s;
    let duration = max_s.to_string();
    let mut extra = vec!["--reference"];
    if shorten {
        extra.extend(["--duration", duration.as_str()]);
    }
    let o = launch_scenario(&file, out, &extra);
    let expect_status = match s.scenario.expect {
        Expect::Complete => "ok",
        Expect::Diverge => "diverged",
    };
    if !o.status.success() {
        return Some(format!("{extra:?}: not exit 0\n{}", describe_output(&o)));
    }
    let sum = summary(out);
    let status = sum["status"].as_str().unwrap_or("?");
    if status != expect_status {
        return Some(format!("{extra:?}: status {status:?}, expected {expect_status:?}\n{}", describe_output(&o)));
    }
    if s.scenario.expect == Expect::Diverge && sum["metrics"]["diverged_at_s"].as_f64().is_none() {
        return Some(format!("{extra:?}: diverged, but the summary has no diverged_at_s"));
    }
    // The same drivers as coroutines of one thread (a campaign's cases): the same telemetry.
    let one = out.with_extension("one-thread");
    extra.push("--one-thread");
    let o = launch_scenario(&file, &one, &extra);
    if !o.status.success() {
        return Some(format!("{extra:?}: not exit 0\n{}", describe_output(&o)));
    }
    let (a, b) = (telemetry_bits(out), telemetry_bits(&one));
    if a != b {
        let first = a.iter().zip(&b).find(|(x, y)| x != y);
        return Some(format!(
            "{extra:?}: telemetry differs from the threads' ({} against {} values; first: {first:?})",
            b.len(),
            a.len()
        ));
    }
    None
}

#[test]
fn every_runnable_scenario_completes_shortened_to_ten_seconds() {
    let _g = heavy();
    let names = tomls_in("topologies");
    assert!(names.len() >= 20, "expected the shipped scenarios in topologies/, found {names:?}");
    let root = scratch_dir("every-scenario");
    let failures: Vec<String> = names
        .iter()
        .filter_map(|n| launch_one(n, &root.join(n.trim_end_matches(".toml"))).map(|why| format!("{n}: {why}")))
        .collect();
    let _ = std::fs::remove_dir_all(&root);
    assert!(
        failures.is_empty(),
        "{} of {} scenarios did not run as expected:\n\n{}",
        failures.len(),
        names.len(),
        failures.join("\n\n")
    );
}
