//! Launches of real processes: determinism across transports, concurrent runs, and clean exits
//! when an agent is SIGKILLed or the orchestrator gets Ctrl-C.
//!
//! Heavy tests are serialised by [`cohort::heavy`] (each launch already puts 7 processes on 2 cores) and
//! every wait is generous: these must not be flaky on a loaded machine. Run with
//! `cargo test --workspace --release`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use cohort::OutputWithin;
use cohort::{
    bin_path, describe_output, heavy_scratch, iceoryx2_leftovers, launch_scenario, orchestrator_command,
    processes_mentioning, repo_root, scratch_dir, summary, telemetry_bits,
};

fn orchestrator() -> Command {
    orchestrator_command()
}

fn ring() -> PathBuf {
    repo_root().join("topologies/consensus-ring.toml")
}

fn launch(out: &Path, extra: &[&str]) -> Output {
    launch_scenario(&ring(), out, extra)
}

fn run_id(run_dir: &Path) -> String {
    summary(run_dir)["run_id"].as_str().expect("run_id").to_string()
}

/// Assert the telemetry directories hold the same files with the same bytes.
fn assert_same_telemetry(a: &Path, b: &Path) {
    let list = |d: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(d.join("telemetry"))
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().to_string())
            .collect();
        v.sort();
        v
    };
    let (fa, fb) = (list(a), list(b));
    assert_eq!(fa, fb, "telemetry files differ");
    assert_eq!(fa.len(), 7, "plant + 6 agents: {fa:?}");
    for f in &fa {
        let x = std::fs::read(a.join("telemetry").join(f)).unwrap();
        let y = std::fs::read(b.join("telemetry").join(f)).unwrap();
        assert!(x == y, "telemetry/{f} differs between {} and {}", a.display(), b.display());
    }
}

fn assert_clean(run_dir: &Path, id: &str) {
    let needle = run_dir.display().to_string();
    // Children are reaped before the orchestrator exits; allow the kernel a moment anyway.
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let left = processes_mentioning(&needle);
        if left.is_empty() {
            break;
        }
        assert!(Instant::now() < deadline, "processes of the run are still alive: {left:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let shm = iceoryx2_leftovers(id);
    assert!(shm.is_empty(), "iceoryx2 resources of run {id} remain: {shm:?}");
}

#[test]
fn multi_process_and_reference_telemetry_are_bit_identical() {
    let (_g, dir) = heavy_scratch("determinism");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = launch(&mp, &[]);
    assert!(o.status.success(), "multi-process launch failed:\n{}", describe_output(&o));
    let o = launch(&rf, &["--reference"]);
    assert!(o.status.success(), "reference launch failed:\n{}", describe_output(&o));
    assert_same_telemetry(&mp, &rf);

    // Beyond bytes: every value parses, and the parsed values agree bit for bit.
    let (a, b) = (telemetry_bits(&mp), telemetry_bits(&rf));
    assert_eq!(a.len(), b.len());
    assert!(a.len() > 7 * 2000 * 10, "too few values: {}", a.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x, y, "value differs (file, line, column, bits)");
    }
    // The run did what the scenario is for: the formation converged.
    let s = summary(&mp);
    assert_eq!(s["status"], "ok");
    assert_eq!(s["steps_completed"], 2000);
    let err = s["metrics"]["formation_error_final_m"].as_f64().unwrap();
    assert!(err < 0.05, "formation error {err} m after 20 s");
    assert_eq!(s["messages_rejected"].as_object().unwrap().values().map(|v| v.as_u64().unwrap()).sum::<u64>(), 0);
    assert_eq!(s["mode"], "multi-process");
    assert_eq!(summary(&rf)["mode"], "reference");
    for d in ["timing", "logs", "status"] {
        assert!(mp.join(d).is_dir() && rf.join(d).is_dir(), "{d}/ missing");
    }
    assert!(mp.join("scenario.toml").is_file());
    // What the processes read the scenario from (bit-identical to the reference above).
    assert!(mp.join("scenario.digest").is_file());
    assert_clean(&mp, &run_id(&mp));
}

#[test]
fn a_different_seed_changes_the_telemetry() {
    // Guards the determinism test against passing vacuously (e.g. noise not applied).
    let (_g, dir) = heavy_scratch("seed");
    let o = launch(&dir.join("a"), &["--reference", "--duration", "1"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = launch(&dir.join("b"), &["--reference", "--duration", "1", "--seed", "8"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let a = std::fs::read(dir.join("a/telemetry/plant.parquet")).unwrap();
    let b = std::fs::read(dir.join("b/telemetry/plant.parquet")).unwrap();
    assert_ne!(a, b, "seed 7 and seed 8 gave the same plant telemetry");
}

#[test]
fn two_concurrent_launches_both_succeed_and_match() {
    let (_g, dir) = heavy_scratch("concurrent");
    let spawn = |out: &Path| -> Child {
        orchestrator()
            .arg("launch")
            .arg(ring())
            .arg("--out")
            .arg(out)
            .arg("--no-plots")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawning the orchestrator")
    };
    let (a, b) = (dir.join("a"), dir.join("b"));
    let ca = spawn(&a);
    let cb = spawn(&b);
    let oa = cohort::finish_within(ca, cohort::RUN_LIMIT, "the first of two concurrent launches");
    let ob = cohort::finish_within(cb, cohort::RUN_LIMIT, "the second of two concurrent launches");
    assert!(oa.status.success(), "first run failed:\n{}", describe_output(&oa));
    assert!(ob.status.success(), "second run failed:\n{}", describe_output(&ob));
    assert_ne!(run_id(&a), run_id(&b), "the two runs shared a run id");
    assert_same_telemetry(&a, &b);
    assert_clean(&a, &run_id(&a));
    assert_clean(&b, &run_id(&b));
}

/// Start a long multi-process run and wait until its plant is stepping.
fn start_long_run(out: &Path, step_timeout_s: &str, on_loss: &str, duration_s: &str) -> Child {
    let child = orchestrator()
        .arg("launch")
        .arg(ring())
        .arg("--out")
        .arg(out)
        .arg("--no-plots")
        .args(["--duration", duration_s, "--step-timeout", step_timeout_s, "--on-agent-loss", on_loss])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawning the orchestrator");
    let deadline = Instant::now() + Duration::from_secs(60);
    // The plant writes its first timing rows once stepping (buffered: wait for some bytes), to
    // `plant.csv` or, with Parquet (the default), to its journal `plant.rows` while it runs.
    let timing_bytes = || {
        ["timing/plant.csv", "timing/plant.rows"]
            .iter()
            .filter_map(|f| std::fs::metadata(out.join(f)).ok())
            .map(|m| m.len())
            .max()
            .unwrap_or(0)
    };
    while timing_bytes() < 70_000 {
        assert!(Instant::now() < deadline, "the run did not start stepping within 60 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

fn pid_of(out: &Path, what: &str) -> u32 {
    let needle = out.display().to_string();
    let found = processes_mentioning(&needle);
    found
        .iter()
        .find(|(_, cmd)| cmd.contains(what))
        .unwrap_or_else(|| panic!("no process matching {what:?} among {found:?}"))
        .0
}

#[test]
fn in_abort_mode_sigkill_of_an_agent_ends_the_run_cleanly_naming_it_and_the_step() {
    let (_g, dir) = heavy_scratch("sigkill");
    let out = dir.join("run");
    let step_timeout_s = 10.0;
    // Abort mode: an agent's death ends the run. Long enough that the kill lands mid-run.
    let child = start_long_run(&out, "10", "abort", "3000");
    // Every process is visible under its own name, with its id in its arguments.
    let agent3 = pid_of(&out, "agent --id 3 ");
    let _plant = pid_of(&out, "plant --run-dir");
    let killed_at = Instant::now();
    // SAFETY: kill(2) on a pid read from /proc just now.
    assert_eq!(unsafe { libc::kill(agent3 as i32, libc::SIGKILL) }, 0);
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run whose agent was SIGKILLed (abort mode)");
    let took = killed_at.elapsed().as_secs_f64();
    // Detection (≤ step timeout) plus the shutdown ladder's grace (stop 3 s + term 2 s) + margin.
    assert!(took < step_timeout_s + 5.0 + 10.0, "took {took:.1} s to end the run");
    assert!(!o.status.success(), "the run should fail:\n{}", describe_output(&o));
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent-3"), "the message must name the agent:\n{err}");
    assert!(err.contains("SIGKILL"), "the message must say how it died:\n{err}");
    assert!(err.contains("step "), "the message must name the step:\n{err}");
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
    assert!(s["error"].as_str().unwrap().contains("agent-3"));
    // Telemetry written before the failure is kept (flushed), not lost.
    let plant_rows = cohort::telemetry_table(&out, "plant").rows();
    assert!(plant_rows > 100, "plant telemetry lost: {plant_rows} rows");
    assert_clean(&out, &run_id(&out));
}

#[test]
fn sigint_to_the_orchestrator_stops_everything_with_130() {
    let (_g, dir) = heavy_scratch("sigint");
    let out = dir.join("run");
    let child = start_long_run(&out, "10", "abort", "3000");
    // SAFETY: kill(2) on our own child.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let sent = Instant::now();
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run sent SIGINT");
    assert!(sent.elapsed() < Duration::from_secs(20), "took {:?} to stop", sent.elapsed());
    assert_eq!(o.status.code(), Some(130), "{}", describe_output(&o));
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    assert_clean(&out, &run_id(&out));
}

#[test]
fn a_child_built_from_other_sources_refuses_to_run() {
    let dir = scratch_dir("buildid");
    let o = Command::new(bin_path("agent"))
        .args(["--id", "1", "--run-id", "00ff", "--build-id", "0.0.0-someotherbuild"])
        .arg("--run-dir")
        .arg(&dir)
        .output_within(cohort::QUICK_LIMIT, "an agent of another build");
    assert_eq!(o.status.code(), Some(3), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("rebuild"), "{}", describe_output(&o));
}

#[test]
fn a_missing_child_binary_is_refused_with_a_clear_message() {
    let dir = scratch_dir("missingbin");
    let lonely = dir.join("orchestrator");
    std::fs::copy(bin_path("orchestrator"), &lonely).unwrap();
    let o = Command::new(&lonely)
        .current_dir(repo_root())
        .arg("launch")
        .arg(ring())
        .arg("--out")
        .arg(dir.join("run"))
        .output_within(cohort::RUN_LIMIT, "a launch");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("binary is missing") && err.contains("plant"), "{err}");
}

#[test]
fn in_abort_mode_a_frozen_agent_ends_the_run_at_the_step_timeout_naming_it() {
    let (_g, dir) = heavy_scratch("freeze");
    let out = dir.join("run");
    let step_timeout_s = 2.0;
    let child = start_long_run(&out, "2", "abort", "3000");
    let agent5 = pid_of(&out, "agent --id 5 ");
    // SAFETY: kill(2) on a pid read from /proc just now.
    assert_eq!(unsafe { libc::kill(agent5 as i32, libc::SIGSTOP) }, 0);
    let frozen_at = Instant::now();
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run with a frozen agent (abort mode)");
    let took = frozen_at.elapsed().as_secs_f64();
    assert!(took >= step_timeout_s * 0.9, "ended after {took:.2} s, before the step timeout");
    assert!(took < step_timeout_s + 5.0 + 15.0, "took {took:.1} s");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    // Whoever timed out first (the plant, or a neighbour of agent 5) names agent 5 and the step.
    assert!(err.contains("timeout at step"), "{err}");
    assert!(err.contains("agent 5"), "the silent agent must be named:\n{err}");
    // The frozen process was stopped by the shutdown ladder (SIGKILL reaches a stopped process).
    assert_clean(&out, &run_id(&out));
}

#[test]
fn a_killed_orchestrator_leaves_no_orphan_and_the_next_launch_sweeps_its_resources() {
    let (_g, dir) = heavy_scratch("orchkill");
    let out = dir.join("run");
    let mut child = start_long_run(&out, "10", "degrade", "3000");
    let plant = processes_mentioning(&out.display().to_string())
        .into_iter()
        .find(|(_, c)| c.contains("plant --run-dir"))
        .expect("plant process");
    let id = plant.1.split("--run-id ").nth(1).and_then(|r| r.split_whitespace().next()).unwrap().to_string();
    child.kill().unwrap(); // SIGKILL: no chance to clean up
    child.wait().unwrap();
    // PR_SET_PDEATHSIG takes the children down with it.
    let deadline = Instant::now() + Duration::from_secs(10);
    while !processes_mentioning(&out.display().to_string()).is_empty() {
        assert!(Instant::now() < deadline, "orphans: {:?}", processes_mentioning(&out.display().to_string()));
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(!iceoryx2_leftovers(&id).is_empty(), "expected the killed run's resources to remain for the sweep");
    let o = launch(&dir.join("next"), &["--duration", "0.1"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(&id),
        "the sweep should say what it removed:\n{}",
        describe_output(&o)
    );
    assert!(iceoryx2_leftovers(&id).is_empty(), "stale resources remain: {:?}", iceoryx2_leftovers(&id));
}

#[test]
fn thirty_agents_run_multi_process_past_the_default_service_limits() {
    // iceoryx2's defaults (8 subscribers, 16 notifiers, 20/36 nodes) break past ~15 agents; the
    // services are sized from the scenario. A dense graph (each agent hears 6 others) also
    // exercises wide fan-out.
    let (_g, dir) = heavy_scratch("thirty");
    let n = 30u32;
    let mut toml = String::from(
        "[scenario]\nname = \"ring30\"\nseed = 3\ndt_s = 0.01\nduration_s = 1.0\n\n[run]\nstep_timeout_s = 20.0\n\n\
         [plant]\nkind = \"double-integrator\"\nposition_noise_std_m = 0.05\n\n\
         [algorithm]\nkind = \"consensus-formation\"\nformation_radius_m = 30.0\nkp_per_s2 = 0.2\nkd_per_s = 1.0\n\
         observer_l1_per_s = 6.0\nobserver_l2_per_s2 = 9.0\n",
    );
    for i in 1..=n {
        let nb: Vec<String> = [1, 2, 3]
            .iter()
            .flat_map(|d| [(i + d - 1) % n + 1, (i + n - d - 1) % n + 1])
            .map(|j| j.to_string())
            .collect();
        toml.push_str(&format!(
            "\n[[agents]]\nid = {i}\nneighbours = [{}]\nr0_m = [{}.0, {}.0, 0.0]\nv0_mps = [0.0, 0.0, 0.0]\n",
            nb.join(", "),
            i * 3,
            (i * 7) % 11
        ));
    }
    let file = dir.join("ring30.toml");
    std::fs::write(&file, toml).unwrap();
    let run = |out: &Path, extra: &[&str]| {
        orchestrator()
            .arg("launch")
            .arg(&file)
            .arg("--out")
            .arg(out)
            .arg("--no-plots")
            .args(extra)
            .output_within(cohort::RUN_LIMIT, "a 30-agent ring launch")
    };
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = run(&mp, &[]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = run(&rf, &["--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    for i in 0..=n {
        let f = if i == 0 { "plant.parquet".to_string() } else { format!("agent-{i}.parquet") };
        let a = std::fs::read(mp.join("telemetry").join(&f)).unwrap();
        let b = std::fs::read(rf.join("telemetry").join(&f)).unwrap();
        assert!(a == b, "{f} differs");
    }
    assert_clean(&mp, &run_id(&mp));
}

/// The scale CI can afford (issue: formations of hundreds): `orchestrator generate ring` writes a
/// 200-agent ring, which runs as 201 processes bit-identical to `--reference`, reports every
/// process's PSS, and leaves nothing behind.
#[test]
fn a_generated_two_hundred_agent_ring_runs_multi_process_bit_identical_to_the_reference() {
    let (_g, dir) = heavy_scratch("ring200");
    let file = dir.join("ring200.toml");
    let o = orchestrator()
        .args(["generate", "ring", "--agents", "200", "--steps", "40", "--out"])
        .arg(&file)
        .output_within(cohort::QUICK_LIMIT, "orchestrator generate ring");
    assert!(o.status.success(), "{}", describe_output(&o));
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = launch_scenario(&file, &mp, &[]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = launch_scenario(&file, &rf, &["--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let bits = cohort::telemetry_bits(&mp);
    let files: std::collections::BTreeSet<&str> = bits.iter().map(|b| b.0.as_str()).collect();
    assert_eq!(files.len(), 201, "plant + 200 agents: {files:?}");
    assert_eq!(bits, cohort::telemetry_bits(&rf), "200-agent ring: multi-process differs from the reference");
    let s = summary(&mp);
    let processes = s["processes"].as_array().unwrap();
    assert_eq!(processes.len(), 201);
    assert!(processes.iter().all(|p| p["pss_kb"].as_u64().unwrap_or(0) > 0), "a process reported no PSS");
    let total: u64 = processes.iter().map(|p| p["pss_kb"].as_u64().unwrap()).sum();
    assert_eq!(s["pss_total_kb"].as_u64(), Some(total));
    assert_clean(&mp, &run_id(&mp));
}

#[test]
fn in_degrade_mode_an_unplanned_sigkill_is_survived_named_and_fails_the_exit_code() {
    let (_g, dir) = heavy_scratch("degrade-kill");
    let out = dir.join("run");
    let child = start_long_run(&out, "10", "degrade", "600");
    let agent3 = pid_of(&out, "agent --id 3 ");
    // SAFETY: kill(2) on a pid read from /proc just now.
    assert_eq!(unsafe { libc::kill(agent3 as i32, libc::SIGKILL) }, 0);
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run whose agent was SIGKILLed (degrade mode)");
    assert_eq!(o.status.code(), Some(1), "an unplanned loss must fail the exit code:\n{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent-3") && err.contains("SIGKILL"), "{err}");
    assert!(err.contains("went on without it"), "{err}");
    let s = summary(&out);
    assert_eq!(s["status"], "degraded");
    // The run went on to the end: every survivor finished every step.
    assert_eq!(s["steps_completed"], 60_000);
    for p in s["processes"].as_array().unwrap() {
        if p["process"] != "agent-3" {
            assert_eq!(p["steps_completed"], 60_000, "{p}");
        }
    }
    let tl = s["timeline"].as_array().expect("a timeline");
    let died = tl.iter().find(|e| e["event"] == "died" && e["agent"] == 3).expect("the death is on the timeline");
    let dead = tl.iter().find(|e| e["event"] == "dead" && e["agent"] == 3).expect("the roster change too");
    // The orchestrator reaped it and told the plant: marked dead well within the step timeout.
    let lag = dead["wall_s"].as_f64().unwrap() - died["wall_s"].as_f64().unwrap();
    assert!(lag < 10.0, "detected {lag} s after the death");
    assert_clean(&out, &run_id(&out));
}

#[test]
fn killing_the_plant_ends_the_run_cleanly_naming_it() {
    let (_g, dir) = heavy_scratch("plant-kill");
    let out = dir.join("run");
    let child = start_long_run(&out, "5", "degrade", "3000");
    let plant = pid_of(&out, "plant --run-dir");
    // SAFETY: kill(2) on a pid read from /proc just now.
    assert_eq!(unsafe { libc::kill(plant as i32, libc::SIGKILL) }, 0);
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run whose plant was killed");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("plant") && err.contains("SIGKILL"), "the plant (the clock) must be named:\n{err}");
    assert_eq!(summary(&out)["status"], "failed");
    assert_clean(&out, &run_id(&out));
}
