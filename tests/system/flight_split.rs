//! The flight binaries build only the flight side of each paper: `agent` and `plant` take the
//! registry without its `host` feature, so the training, plotting and command crates are not in
//! their dependency graph (the orchestrator's has them). `cargo tree` is the independent view.

use cohort::OutputWithin;
use std::process::Command;

/// The packages (names only) in the normal-dependency graph of `packages`, resolved as if only
/// they were built.
fn tree(packages: &[&str]) -> Vec<String> {
    let mut args = vec!["tree", "--offline", "-e", "normal", "--prefix", "none", "--format", "{p}"];
    for p in packages {
        args.extend(["-p", p]);
    }
    let out = Command::new(env!("CARGO"))
        .args(&args)
        .current_dir(cohort::repo_root())
        .output_within(cohort::QUICK_LIMIT, "cargo tree");
    assert!(out.status.success(), "cargo tree: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).lines().filter_map(|l| l.split_whitespace().next()).map(String::from).collect()
}

#[test]
fn the_flight_binaries_do_not_depend_on_the_host_side() {
    let host_only = ["candle-core", "candle-nn", "plotters", "cohort-host"];
    let flight = tree(&["agent", "plant"]);
    assert!(flight.iter().any(|p| p == "cohort-paper-nr"), "the papers' flight side is missing: {flight:?}");
    let leaked: Vec<&&str> = host_only.iter().filter(|h| flight.iter().any(|p| p == *h)).collect();
    assert!(leaked.is_empty(), "agent/plant depend on host-side crates {leaked:?}");
    let orchestrator = tree(&["orchestrator"]);
    let absent: Vec<&&str> = host_only.iter().filter(|h| !orchestrator.iter().any(|p| p == *h)).collect();
    assert!(absent.is_empty(), "the orchestrator lacks {absent:?}: the check names the wrong crates");
}
