//! Logging (issue 17, item 5): `RUST_LOG`, `-v` and `-q` choose the orchestrator's and the
//! children's log lines; every child log line carries its run time, level and process name; a
//! bad `RUST_LOG` is named and ignored, never a panic; `-v`/`-q` typed on the command line win
//! over `RUST_LOG` (issue 36, item 9.1). Short consensus-ring runs (1 s of sim time,
//! 100 steps), serialised by [`cohort::heavy`].

use std::path::Path;
use std::process::Output;

use cohort::OutputWithin;
use cohort::{describe_output, heavy_scratch, orchestrator_command, repo_root};

/// `orchestrator [FLAGS] launch consensus-ring --duration 1` into `out`, with `RUST_LOG` set to
/// `rust_log` (or removed).
fn launch(out: &Path, flags: &[&str], rust_log: Option<&str>) -> Output {
    let mut c = orchestrator_command();
    c.args(flags)
        .arg("launch")
        .arg(repo_root().join("topologies/consensus-ring.toml"))
        .args(["--duration", "1", "--no-plots", "--out"])
        .arg(out);
    match rust_log {
        Some(v) => c.env("RUST_LOG", v),
        None => c.env_remove("RUST_LOG"),
    };
    let o = c.output_within(cohort::RUN_LIMIT, "a launch with a log level");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"), "{}", describe_output(&o));
    o
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn log(run: &Path, proc_name: &str) -> String {
    let path = run.join("logs").join(format!("{proc_name}.log"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Every non-empty line is `[<seconds> s] <LEVEL> <name>: <message>`; returns the levels.
fn child_levels(text: &str, name: &str) -> Vec<String> {
    let mut levels = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let rest = line.strip_prefix('[').unwrap_or_else(|| panic!("no time: {line:?}"));
        let (t, rest) = rest.split_once(" s] ").unwrap_or_else(|| panic!("no time: {line:?}"));
        let t: f64 = t.trim().parse().unwrap_or_else(|_| panic!("bad time: {line:?}"));
        assert!((0.0..600.0).contains(&t), "a run-relative time: {line:?}");
        let (level, rest) = rest.split_once(' ').unwrap_or_else(|| panic!("no level: {line:?}"));
        assert!(["ERROR", "WARN", "INFO", "DEBUG", "TRACE"].contains(&level), "level {level:?}: {line:?}");
        assert!(rest.trim_start().starts_with(&format!("{name}: ")), "process name {name}: {line:?}");
        levels.push(level.to_string());
    }
    levels
}

#[test]
fn a_default_run_logs_info_and_every_child_line_has_time_level_and_name() {
    let (_g, dir) = heavy_scratch("log-default");
    let run = dir.join("run");
    let o = launch(&run, &[], None);
    let err = stderr(&o);
    assert!(err.lines().any(|l| l.starts_with("info: launching ")), "{err}");
    assert!(!err.lines().any(|l| l.starts_with("debug:")), "{err}");
    // The end-of-run text stays on stdout.
    assert!(String::from_utf8_lossy(&o.stdout).contains("done: 100 steps"), "{}", describe_output(&o));
    for name in ["plant", "agent-1", "agent-3", "agent-6"] {
        let levels = child_levels(&log(&run, name), name);
        assert!(levels.iter().any(|l| l == "INFO"), "{name}: {levels:?}");
        assert!(!levels.iter().any(|l| l == "DEBUG" || l == "TRACE"), "{name}: {levels:?}");
    }
}

#[test]
fn rust_log_debug_and_v_show_debug_lines_in_the_orchestrator_and_every_child() {
    let (_g, dir) = heavy_scratch("log-debug");
    for (tag, flags, env) in [("env", &[][..], Some("debug")), ("v", &["-v"][..], None)] {
        let run = dir.join(tag);
        let o = launch(&run, flags, env);
        let err = stderr(&o);
        assert!(err.lines().any(|l| l.starts_with("debug: run ")), "{tag}: {err}");
        for name in ["plant", "agent-2"] {
            let levels = child_levels(&log(&run, name), name);
            assert!(levels.iter().any(|l| l == "DEBUG"), "{tag}: {name}: {levels:?}");
        }
    }
}

#[test]
fn q_keeps_warnings_and_errors_only_and_the_output() {
    let (_g, dir) = heavy_scratch("log-quiet");
    let run = dir.join("run");
    let o = launch(&run, &["-q"], None);
    let err = stderr(&o);
    assert!(!err.lines().any(|l| l.starts_with("info:") || l.starts_with("debug:")), "{err}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("done: 100 steps"), "{}", describe_output(&o));
    let levels = child_levels(&log(&run, "agent-4"), "agent-4");
    assert!(levels.iter().all(|l| l == "WARN" || l == "ERROR"), "the children are quiet too: {levels:?}");
}

#[test]
fn a_bad_rust_log_is_named_and_ignored() {
    let (_g, dir) = heavy_scratch("log-bad");
    let run = dir.join("run");
    let o = launch(&run, &[], Some("agent=loudest"));
    let err = stderr(&o);
    let first = err.lines().next().unwrap_or("");
    assert!(
        first.starts_with("warning: RUST_LOG=\"agent=loudest\" is not a valid filter") && first.contains("ignoring it"),
        "{err}"
    );
    assert!(err.lines().any(|l| l.starts_with("info: launching ")), "the fallback is info: {err}");
    // The children log at the fallback level, without a warning of their own.
    let levels = child_levels(&log(&run, "plant"), "plant");
    assert!(levels.iter().any(|l| l == "INFO") && !levels.iter().any(|l| l == "WARN"), "{levels:?}");
}

#[test]
fn v_and_q_typed_on_the_command_line_win_over_rust_log() {
    let (_g, dir) = heavy_scratch("log-flags-win");
    // `-v` over `RUST_LOG=warn`: debug lines, in the orchestrator and the children.
    let run = dir.join("v");
    let o = launch(&run, &["-v"], Some("warn"));
    let err = stderr(&o);
    assert!(err.lines().any(|l| l.starts_with("debug: run ")), "-v over RUST_LOG=warn: {err}");
    let levels = child_levels(&log(&run, "agent-2"), "agent-2");
    assert!(levels.iter().any(|l| l == "DEBUG"), "-v over RUST_LOG=warn, agent-2: {levels:?}");
    // `-q` over `RUST_LOG=debug`: warnings and errors only.
    let run = dir.join("q");
    let o = launch(&run, &["-q"], Some("debug"));
    let err = stderr(&o);
    assert!(!err.lines().any(|l| l.starts_with("info:") || l.starts_with("debug:")), "-q over RUST_LOG=debug: {err}");
    let levels = child_levels(&log(&run, "plant"), "plant");
    assert!(levels.iter().all(|l| l == "WARN" || l == "ERROR"), "-q over RUST_LOG=debug, plant: {levels:?}");
    // Without a flag, `RUST_LOG` still decides.
    let run = dir.join("env");
    let o = launch(&run, &[], Some("warn"));
    let err = stderr(&o);
    assert!(!err.lines().any(|l| l.starts_with("info:")), "RUST_LOG=warn alone: {err}");
}
