//! The command line around the runs: `--version` names the commit and the build, `--help` lists
//! the exit codes, `completions` and `man` write what a shell and `man` need.
//!
//! Run with `scripts/test`, which builds the release binaries first.

use cohort::OutputWithin;
use cohort::{describe_output, orchestrator_command, scratch_dir};

fn stdout_of(args: &[&str]) -> String {
    let o = orchestrator_command().args(args).output_within(cohort::QUICK_LIMIT, "the orchestrator's command line");
    assert!(o.status.success(), "{args:?}: {}", describe_output(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn version_names_the_commit_and_the_build_id() {
    let v = stdout_of(&["--version"]);
    assert!(v.contains(&format!("build {}", cohort_build_id::BUILD_ID)), "{v}");
    let commit = v.split("commit ").nth(1).and_then(|r| r.split(',').next()).unwrap_or("");
    assert!(commit == "unknown" || (commit.len() == 12 && commit.chars().all(|c| c.is_ascii_hexdigit())), "{v}");
}

#[test]
fn help_lists_the_exit_codes() {
    let h = stdout_of(&["--help"]);
    for want in ["Exit codes:", "  0 ", "  1 ", "  2 ", "128 + N"] {
        assert!(h.contains(want), "{want:?} not in --help:\n{h}");
    }
}

#[test]
fn completions_and_man_pages_cover_every_command() {
    let bash = stdout_of(&["completions", "bash"]);
    for cmd in ["launch", "check", "soak", "train", "report"] {
        assert!(bash.contains(cmd), "bash completion lacks {cmd}");
    }
    let o = orchestrator_command()
        .args(["completions", "no-such-shell"])
        .output_within(cohort::QUICK_LIMIT, "completions for an unknown shell");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    let dir = scratch_dir("man-pages");
    stdout_of(&["man", "--out", dir.to_str().unwrap()]);
    for page in ["orchestrator.1", "orchestrator-launch.1", "orchestrator-train.1"] {
        let text = std::fs::read_to_string(dir.join(page)).unwrap_or_else(|e| panic!("{page}: {e}"));
        assert!(text.starts_with(".ie") || text.contains(".TH"), "{page} is not a man page:\n{text}");
    }
}
