//! Issue 36 (the reliability round) as an adversarial user would probe it, one test per defect
//! that launches real processes: launches racing into one run directory, signals and unbounded
//! input before the run, foreign checkpoints, a squatted per-user base directory, and the
//! smaller findings.
//!
//! Heavy tests are serialised by [`cohort::heavy`]; every wait is generous (a loaded 2-core
//! machine).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cohort::{describe_output, heavy, orchestrator_command, repo_root, scratch_dir, summary};

fn ring() -> PathBuf {
    repo_root().join("topologies/consensus-ring.toml")
}

/// The seed a run directory's resolved scenario.toml holds.
fn scenario_seed(run_dir: &Path) -> u64 {
    let text = std::fs::read_to_string(run_dir.join("scenario.toml")).unwrap();
    let line = text.lines().find(|l| l.starts_with("seed = ")).unwrap_or_else(|| panic!("no seed in\n{text}"));
    line["seed = ".len()..].trim().parse().unwrap()
}

/// Defect 2: two launches into one `--out` at once. Exactly one runs (exit 0) and its directory
/// is wholly its own (the scenario.toml's seed is its summary's); the other is refused with exit
/// 2 naming the directory, before it writes anything.
#[test]
fn of_two_launches_into_one_out_one_runs_and_the_other_is_refused() {
    let _g = heavy();
    let dir = scratch_dir("race");
    for round in 0..8 {
        let out = dir.join(format!("r{round}"));
        let spawn = |seed: u64| -> std::process::Child {
            orchestrator_command()
                .args(["launch", "--reference", "--duration", "1", "--no-plots", "--seed", &seed.to_string(), "--out"])
                .arg(&out)
                .arg(ring())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (spawn(1), spawn(8));
        let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
        let codes = [a.status.code(), b.status.code()];
        let (winner, loser) = match codes {
            [Some(0), Some(2)] => (&a, &b),
            [Some(2), Some(0)] => (&b, &a),
            _ => panic!("round {round}: exits {codes:?}\n{}\n{}", describe_output(&a), describe_output(&b)),
        };
        let err = String::from_utf8_lossy(&loser.stderr);
        assert!(err.contains(&out.display().to_string()), "round {round}: {err}");
        assert!(err.contains("already claimed") || err.contains("not empty"), "round {round}: {err}");
        let seed = summary(&out)["seed"].as_u64().unwrap();
        assert_eq!(scenario_seed(&out), seed, "round {round}: scenario.toml and summary disagree");
        let said = String::from_utf8_lossy(&winner.stdout);
        assert!(said.contains("done"), "round {round}: {said}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
