//! `orchestrator check FILE...` against every scenario in `topologies/` and every test fixture.
//!
//! - The fixtures live where their tests live: `papers/<name>/tests/invalid/*.toml` for the
//!   paper whose kinds or sections they exercise, `tests/invalid/*.toml` for the generic ones
//!   (see [`fixture_dirs`]). Each holds one defect and must be rejected with exit code 2, and
//!   stderr must name the file and the expected key path. The path comes from the file's first
//!   line `# expect: <text>`, or from [`NO_EXPECT_LINE`] for files that cannot hold a comment.
//! - Every `topologies/*.toml` is a scenario a user runs: it must pass (exit code 0, `ok: FILE` on
//!   stdout), hold no fixture (`invalid-*`), and be listed in `topologies/README.md`.
//! - No input may make `check` panic.
//!
//! Run with `scripts/test`, which builds the release binaries first and then runs the tests (see
//! [`cohort::bin_path`]).

use std::path::PathBuf;
use std::process::{Command, Output};

use cohort::OutputWithin;
use cohort::{bin_path, repo_root, tomls_in};

/// Invalid files with no `# expect:` line, mapped to the text their error must contain.
const NO_EXPECT_LINE: &[(&str, &str)] = &[
    // 0 bytes: there is nowhere to put a comment. `scenario` is the first required key it lacks.
    ("invalid-empty.toml", "scenario: required key is missing"),
];

/// At least this many invalid cases must exist, so that a bad glob cannot pass vacuously.
const MIN_INVALID_FILES: usize = 12;

/// The result of one `orchestrator check` run, with what is needed to explain a failure.
struct Run {
    cmd: String,
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Run {
    fn report(&self) -> String {
        format!(
            "command: {}\nexit code: {}\n--- stdout ---\n{}--- stderr ---\n{}--------------",
            self.cmd,
            self.code.map_or("none (killed by a signal)".to_string(), |c| c.to_string()),
            with_newline(&self.stdout),
            with_newline(&self.stderr),
        )
    }
    fn panicked(&self) -> bool {
        self.stdout.contains("panicked") || self.stderr.contains("panicked") || self.code == Some(101)
    }
}

fn with_newline(s: &str) -> String {
    if s.is_empty() || s.ends_with('\n') { s.to_string() } else { format!("{s}\n") }
}

/// Run `orchestrator check ARGS...` from the repository root (so relative paths in messages look
/// like `topologies/x.toml`).
fn check(args: &[&str]) -> Run {
    let bin = bin_path("orchestrator");
    assert!(
        bin.is_file(),
        "orchestrator binary not found at {}\n\
         run the tests with scripts/test (it builds the binaries first)",
        bin.display()
    );
    let out: Output = Command::new(&bin)
        .arg("check")
        .args(args)
        .current_dir(repo_root())
        .output_within(cohort::QUICK_LIMIT, "orchestrator check");
    Run {
        cmd: format!("(cd {} && {} check {})", repo_root().display(), bin.display(), args.join(" ")),
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Where the `# expect:` fixtures live, relative to the repository root: `tests/invalid` (the
/// generic ones), `papers/<name>/tests/invalid` for every paper (required: each paper has
/// configuration checks of its own), and `kinds/<name>/tests/invalid` where one exists.
fn fixture_dirs() -> Vec<String> {
    let mut dirs = vec!["tests/invalid".to_string()];
    for (parent, required) in [("papers", true), ("kinds", false)] {
        let dir = repo_root().join(parent);
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
            .map(|e| e.expect("readable directory entry").path())
            .filter(|p| p.join("Cargo.toml").is_file())
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            // The registry holds no section of its own.
            .filter(|n| !(parent == "papers" && n == "registry"))
            .collect();
        names.sort();
        for n in names {
            let rel = format!("{parent}/{n}/tests/invalid");
            if required || repo_root().join(&rel).is_dir() {
                dirs.push(rel);
            }
        }
    }
    dirs
}

/// (valid scenarios `topologies/*.toml`, invalid fixtures of every [`fixture_dirs`] folder), each
/// as a path relative to the repository root.
fn topology_files() -> (Vec<String>, Vec<String>) {
    let valid = tomls_in("topologies").into_iter().map(|n| format!("topologies/{n}")).collect();
    let invalid =
        fixture_dirs().iter().flat_map(|d| tomls_in(d).into_iter().map(move |n| format!("{d}/{n}"))).collect();
    (valid, invalid)
}

/// The file name of a relative path (what stderr must name).
fn base(rel: &str) -> &str {
    rel.rsplit('/').next().unwrap_or(rel)
}

fn abs(rel: &str) -> PathBuf {
    repo_root().join(rel)
}

/// What `rel`'s error must contain: its `# expect:` line, else its [`NO_EXPECT_LINE`] entry.
fn expectation(rel: &str) -> String {
    let bytes = std::fs::read(abs(rel)).unwrap_or_else(|e| panic!("cannot read {rel}: {e}"));
    // Lossy: one case is deliberately not UTF-8 (after its first line).
    let text = String::from_utf8_lossy(&bytes);
    let first = text.lines().next().unwrap_or("");
    if let Some(want) = first.strip_prefix("# expect:") {
        let want = want.trim();
        assert!(!want.is_empty(), "{rel}: the `# expect:` line is empty");
        return want.to_string();
    }
    match NO_EXPECT_LINE.iter().find(|(n, _)| *n == base(rel)) {
        Some((_, want)) => want.to_string(),
        None => panic!(
            "{rel}: the first line must be `# expect: <key path>` (or add the file to NO_EXPECT_LINE in tests/system/check.rs)"
        ),
    }
}

/// Every fixture folder exists and holds at least one fixture, every fixture is named
/// `invalid-*.toml`, and `topologies/` holds none.
#[test]
fn every_fixture_folder_holds_fixtures_and_topologies_none() {
    let mut problems = Vec::new();
    for d in fixture_dirs() {
        if !repo_root().join(&d).is_dir() {
            problems.push(format!("{d}: missing (every paper keeps its `# expect:` fixtures there)"));
            continue;
        }
        let names = tomls_in(&d);
        if names.is_empty() {
            problems.push(format!("{d}: holds no fixture"));
        }
        problems.extend(
            names.iter().filter(|n| !n.starts_with("invalid-")).map(|n| format!("{d}/{n}: not named invalid-*.toml")),
        );
    }
    problems.extend(
        tomls_in("topologies")
            .iter()
            .filter(|n| n.starts_with("invalid-"))
            .map(|n| format!("topologies/{n}: a fixture in the users' scenario folder (move it to tests/invalid or papers/<name>/tests/invalid)")),
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// `topologies/README.md`'s table under "## Files here" lists every scenario of the folder (its
/// first cell names each in backticks) and names none that is not there.
#[test]
fn topologies_readme_lists_every_scenario_and_no_other() {
    let readme = std::fs::read_to_string(repo_root().join("topologies/README.md")).unwrap();
    let files = tomls_in("topologies");
    let table = readme
        .lines()
        .skip_while(|l| l.trim() != "## Files here")
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'));
    let listed: std::collections::BTreeSet<String> = table
        .filter(|l| l.starts_with("| `"))
        .filter_map(|l| l.split('|').nth(1))
        .flat_map(|cell| cell.split('`').skip(1).step_by(2).map(str::to_string).collect::<Vec<_>>())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    let mut problems: Vec<String> = files
        .iter()
        .filter(|n| !listed.contains(*n))
        .map(|n| format!("topologies/{n}: not listed in topologies/README.md"))
        .collect();
    problems.extend(
        listed
            .iter()
            .filter(|n| !files.contains(*n))
            .map(|n| format!("topologies/README.md lists {n}, which is not in topologies/")),
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_invalid_file_is_rejected_naming_the_file_and_key() {
    let (_, invalid) = topology_files();
    assert!(
        invalid.len() >= MIN_INVALID_FILES,
        "expected at least {MIN_INVALID_FILES} invalid-*.toml fixtures in {:?}, found {}: {invalid:?}",
        fixture_dirs(),
        invalid.len()
    );
    let mut failures = Vec::new();
    for path in &invalid {
        let (want, name) = (expectation(path), base(path));
        let run = check(&[path]);
        let mut why = Vec::new();
        if run.code != Some(2) {
            why.push("exit code is not 2".to_string());
        }
        if !run.stderr.contains(name) {
            why.push(format!("stderr does not name the file {name:?}"));
        }
        // The expected text must be on a problem line that also names the file.
        if !run.stderr.lines().any(|l| l.contains(name) && l.contains(&want)) {
            why.push(format!("no stderr line names both {name:?} and the expected {want:?}"));
        }
        if run.stdout.lines().any(|l| l.starts_with("ok:")) {
            why.push("stdout says `ok:`".to_string());
        }
        if run.panicked() {
            why.push("it panicked".to_string());
        }
        if !why.is_empty() {
            failures.push(format!("{path}: {}\n{}", why.join("; "), run.report()));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} invalid scenarios were not rejected as expected:\n\n{}",
        failures.len(),
        invalid.len(),
        failures.join("\n\n")
    );
}

#[test]
fn every_valid_file_passes() {
    let (valid, _) = topology_files();
    assert!(
        valid.iter().any(|n| n == "topologies/consensus-ring.toml"),
        "topologies/consensus-ring.toml is missing; found {valid:?}"
    );
    let mut failures = Vec::new();
    for name in &valid {
        let run = check(&[name]);
        let says_ok = run.stdout.lines().any(|l| l.starts_with("ok:") && l.contains(name.as_str()));
        if run.code != Some(0) || !says_ok || run.panicked() {
            failures.push(format!("{name}: expected exit code 0 and `ok: {name}` on stdout\n{}", run.report()));
        }
    }
    assert!(failures.is_empty(), "valid scenarios were not accepted:\n\n{}", failures.join("\n\n"));
}

#[test]
fn a_missing_file_is_rejected_naming_it() {
    let name = "does-not-exist.toml";
    let run = check(&[&format!("topologies/{name}")]);
    assert!(
        run.code == Some(2) && run.stderr.contains(name) && !run.panicked(),
        "expected exit code 2 and stderr naming {name:?}\n{}",
        run.report()
    );
}

/// All files in one call: the exit code is 2 as one is invalid, yet every file is checked and
/// reported (`ok:` for the valid ones, an error naming each invalid one).
#[test]
fn checking_many_files_reports_each() {
    let (valid, invalid) = topology_files();
    let args: Vec<&str> = valid.iter().chain(&invalid).map(String::as_str).collect();
    let run = check(&args);
    let mut why = Vec::new();
    if run.code != Some(2) {
        why.push("exit code is not 2".to_string());
    }
    for name in &valid {
        if !run.stdout.lines().any(|l| l.starts_with("ok:") && l.contains(name.as_str())) {
            why.push(format!("stdout has no `ok:` line for {name}"));
        }
    }
    for name in &invalid {
        if !run.stderr.contains(base(name)) {
            why.push(format!("stderr does not name {name}"));
        }
    }
    if run.panicked() {
        why.push("it panicked".to_string());
    }
    assert!(why.is_empty(), "{}\n{}", why.join("\n"), run.report());
}

/// No input, however odd, makes `check` panic (a panic is a bug: every bad input has a message).
#[test]
fn check_never_panics() {
    let (valid, invalid) = topology_files();
    let mut cases: Vec<Vec<String>> = valid.iter().chain(&invalid).map(|n| vec![n.clone()]).collect();
    cases.extend([
        vec![],                         // no files at all
        vec![String::new()],            // an empty path
        vec!["topologies".to_string()], // a directory
        vec!["topologies/does-not-exist.toml".to_string()],
        vec![abs("topologies/consensus-ring.toml").display().to_string()], // an absolute path
    ]);
    if std::path::Path::new("/dev/null").exists() {
        cases.push(vec!["/dev/null".to_string()]); // empty, and not a regular file
    }
    let mut failures = Vec::new();
    for args in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let run = check(&args);
        if run.panicked() {
            failures.push(run.report());
        }
    }
    assert!(failures.is_empty(), "`orchestrator check` panicked:\n\n{}", failures.join("\n\n"));
}

/// Three independent defects of one file — a misspelt key and a value of the wrong type in the
/// same table, and a paper-section value out of range — are all reported in one pass, each at its
/// line and column, the misspelling with a suggestion.
#[test]
fn every_problem_of_a_file_is_reported_in_one_pass_at_its_place() {
    let dir = cohort::scratch_dir("check-three");
    let text = std::fs::read_to_string(abs("topologies/consensus-ring.toml"))
        .unwrap()
        .replace("step_timeout_s = 10.0", "step_timout_s = 10.0\nlink_delay_steps = \"one\"")
        .replace("kp_per_s2 = 0.5", "kp_per_s2 = -0.5");
    let file = dir.join("three.toml");
    std::fs::write(&file, &text).unwrap();
    let run = check(&[&file.display().to_string()]);
    assert_eq!(run.code, Some(2), "{}", run.report());
    let line_of = |text_in: &str| -> usize {
        text.lines().position(|l| l.contains(text_in)).expect("the defect is in the file") + 1
    };
    for (path, line) in [
        ("run.step_timout_s: unknown key (did you mean \"step_timeout_s\"?)", line_of("step_timout_s")),
        ("run.link_delay_steps: invalid type: string \"one\", expected an integer", line_of("link_delay_steps")),
        ("algorithm.kp_per_s2 = -0.5: must be > 0", line_of("kp_per_s2")),
    ] {
        let want = format!("three.toml:{line}:");
        assert!(
            run.stderr.lines().any(|l| l.contains(&want) && l.contains(path)),
            "no line with {want:?} and {path:?}\n{}",
            run.report()
        );
    }
    assert!(run.stderr.contains("(3 problems)"), "{}", run.report());
}
