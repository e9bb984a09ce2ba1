//! The runtime options that change speed but must never change results (waiting strategy,
//! transport), the one that changes the model deterministically (a one-step link delay),
//! real-time pacing, and `orchestrator bench --quick` end to end. Run with `scripts/test`.

use std::path::Path;
use std::process::Output;
use std::time::Instant;

use cohort::OutputWithin;
use cohort::{heavy_scratch, launch_scenario, orchestrator_command, scratch_dir};

fn orchestrator(args: &[&str]) -> Output {
    orchestrator_command().args(args).output_within(cohort::RUN_LIMIT, "the orchestrator")
}

fn launch(out: &Path, extra: &[&str]) -> Output {
    let o = launch_scenario(Path::new("topologies/consensus-ring.toml"), out, extra);
    assert!(
        o.status.success(),
        "launch {extra:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn telemetry(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("telemetry")).unwrap().flatten().map(|e| e.path()).collect();
    files.sort();
    files
        .into_iter()
        .map(|p| (p.file_name().unwrap().to_string_lossy().to_string(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn waiting_strategies_and_transports_never_change_the_telemetry() {
    let (_g, dir) = heavy_scratch("options");
    let base = dir.join("reference");
    launch(&base, &["--reference"]);
    let want = telemetry(&base);
    assert_eq!(want.len(), 7);
    for (name, extra) in [
        ("event", &["--wait", "event"][..]),
        ("poll", &["--wait", "poll"][..]),
        ("adaptive", &["--wait", "adaptive"][..]),
        ("spin50", &["--spin-us", "50"][..]),
        ("udp", &["--transport", "udp"][..]),
        ("udp-event", &["--transport", "udp", "--wait", "event"][..]),
    ] {
        let d = dir.join(name);
        launch(&d, extra);
        assert!(telemetry(&d) == want, "{name}: telemetry differs from the reference");
    }
}

#[test]
fn a_link_delay_is_deterministic_and_really_changes_the_model() {
    let (_g, dir) = heavy_scratch("linkdelay");
    let (mp, rf, none) = (dir.join("mp"), dir.join("ref"), dir.join("none"));
    launch(&mp, &["--link-delay", "1"]);
    launch(&rf, &["--link-delay", "1", "--reference"]);
    launch(&none, &["--reference"]);
    assert!(telemetry(&mp) == telemetry(&rf), "link delay: multi-process differs from reference");
    assert!(telemetry(&mp) != telemetry(&none), "a link delay should change what the agents compute");
    // Still converges: the delay is one 10 ms step.
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(mp.join("summary.json")).unwrap()).unwrap();
    let err = s["metrics"]["formation_error_final_m"].as_f64().unwrap();
    assert!(err < 0.05, "formation error {err} m with a one-step link delay");
}

/// With a link delay an agent's neighbours' last shares are never read. Lingering after its last
/// step (ports open until the orchestrator's stop), an agent must take what rang and nap, not
/// spin on it: a 100-agent ring's agents spun, the plant's telemetry writer finishing its file
/// behind them, and the run ended 14–121 s after its steps (the lingering's bound, two step
/// timeouts: 120 s); since, 1.0–1.2 s for the whole run on this machine.
#[test]
fn a_run_with_a_link_delay_ends_with_its_last_step() {
    let (_g, dir) = heavy_scratch("linkdelay-end");
    let ring = dir.join("ring100.toml");
    let o = orchestrator(&["generate", "ring", "--agents", "100", "--steps", "300", "--out", ring.to_str().unwrap()]);
    assert!(o.status.success(), "generate: {}", String::from_utf8_lossy(&o.stderr));
    let run = dir.join("run");
    let o = launch_scenario(&ring, &run, &["--link-delay", "1"]);
    assert!(o.status.success(), "launch: {}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    let (wall, startup) = (s["wall_s"].as_f64().unwrap(), s["startup_s"].as_f64().unwrap());
    assert!(
        wall - startup < 10.0,
        "{:.1} s from the start to the end of a 300-step run ({wall:.1} s in all)",
        wall - startup
    );
}

#[test]
fn realtime_pacing_follows_the_wall_clock() {
    let (_g, dir) = heavy_scratch("realtime");
    let started = Instant::now();
    // 1 s of sim time at 4× real time: at least 0.25 s of wall time.
    launch(&dir.join("rt"), &["--duration", "1", "--realtime", "--rate", "4"]);
    let took = started.elapsed().as_secs_f64();
    assert!(took >= 0.24, "paced run took only {took:.3} s");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("rt/summary.json")).unwrap()).unwrap();
    let sps = s["steps_per_s"].as_f64().unwrap();
    assert!(sps <= 100.0 * 4.0 * 1.05, "{sps} steps/s exceeds the pace (400/s)");
}

#[test]
fn bench_only_a_prefix_no_case_has_exits_2() {
    let dir = scratch_dir("bench-only");
    let o = orchestrator(&["bench", "--quick", "--only", "no-such-group", "--out", dir.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--only \"no-such-group\": no case key starts with it") && err.contains("headline/"), "{err}");
    assert!(!dir.join("results.md").exists());
}

#[test]
fn bench_quick_writes_its_results() {
    let (_g, dir) = heavy_scratch("bench");
    // The bench's own scratch files go under TMPDIR: it must leave nothing there.
    let tmp = scratch_dir("bench-tmpdir");
    std::fs::create_dir_all(&tmp).unwrap();
    let o = orchestrator_command()
        .args(["bench", "--quick", "--out", dir.to_str().unwrap()])
        .env("TMPDIR", &tmp)
        .output_within(cohort::RUN_LIMIT, "bench --quick");
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().map(|e| e.unwrap().file_name()).collect();
    let _ = std::fs::remove_dir_all(&tmp);
    assert!(left.iter().all(|n| !n.to_string_lossy().starts_with("cohort-bench")), "the bench left {left:?} in TMPDIR");
    let md = std::fs::read_to_string(dir.join("results.md")).unwrap();
    for section in ["## fig1", "waiting strategy", "iceoryx2 vs UDP", "paced at 10 Hz"] {
        assert!(md.contains(section), "results.md lacks {section:?}:\n{md}");
    }
    // A headline case whose agents solve a QP every step reports their solve times.
    assert!(md.contains("Solver time per agent") && md.contains("| multi-process |"), "{md}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let cases = json["cases"].as_array().unwrap();
    assert!(cases.len() >= 10);
    for c in cases {
        let sps = c["steps_per_s_median"].as_f64().unwrap_or(0.0);
        assert!(sps > 0.0, "{}: no steps/s", c["key"]);
    }
}
