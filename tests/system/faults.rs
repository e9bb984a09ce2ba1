//! Fault injection on seed 000's fig1 with real processes (issue 7): a killed servicer, a frozen
//! one, a relaunched one resuming from its checkpoint, dropped and corrupted shares — each run
//! completes, the survivors keep converging, every lost share is counted exactly, nothing is left
//! behind, and a fault run is as deterministic as a clean one. Heavy: serialised.

use std::path::Path;

use cohort::{
    describe_output, heavy_scratch, iceoryx2_leftovers, launch_scenario, processes_mentioning, scratch_dir, summary,
    telemetry_bits,
};
use serde_json::Value;

fn assert_clean(run: &Path) {
    let s = summary(run);
    let id = s["run_id"].as_str().unwrap();
    let needle = run.display().to_string();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !processes_mentioning(&needle).is_empty() {
        assert!(std::time::Instant::now() < deadline, "left running: {:?}", processes_mentioning(&needle));
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    assert!(iceoryx2_leftovers(id).is_empty(), "iceoryx2 leftovers: {:?}", iceoryx2_leftovers(id));
}

fn metric(s: &Value, key: &str) -> f64 {
    s["metrics"][key].as_f64().unwrap_or_else(|| panic!("no metric {key}"))
}

fn events<'a>(s: &'a Value, agent: u64, event: &str) -> Vec<&'a Value> {
    s["timeline"]
        .as_array()
        .map_or(Vec::new(), |t| t.iter().filter(|e| e["agent"] == agent && e["event"] == event).collect::<Vec<_>>())
}

fn process<'a>(s: &'a Value, name: &str) -> &'a Value {
    s["processes"].as_array().unwrap().iter().find(|p| p["process"] == name).unwrap_or_else(|| panic!("{name}"))
}

#[test]
fn fig1_survives_the_kill_of_servicer_3_and_the_other_five_keep_converging() {
    let (_g, dir) = heavy_scratch("fault-kill");
    let run = dir.join("run");
    let o = launch_scenario(Path::new("topologies/fig1.toml"), &run, &["--fault", "kill:agent=3@t=120"]);
    assert!(o.status.success(), "a planned kill is not a failure:\n{}", describe_output(&o));
    let s = summary(&run);
    assert_eq!(s["status"], "ok");
    assert_eq!(s["steps_completed"], 36_000);
    // Killed at the step boundary of t = 120 s, and marked dead from that very step.
    let kill = events(&s, 3, "kill");
    let dead = events(&s, 3, "dead");
    assert_eq!((kill.len(), dead.len()), (1, 1), "{}", s["timeline"]);
    assert_eq!((kill[0]["step"].as_u64(), dead[0]["step"].as_u64()), (Some(12_000), Some(12_000)));
    let detection_s = dead[0]["wall_s"].as_f64().unwrap() - kill[0]["wall_s"].as_f64().unwrap();
    assert!(detection_s <= 10.0, "detected {detection_s} s after the kill (run.step_timeout_s = 10)");
    // Its spacecraft coasts away; the five survivors stay converged (the clean run's steady
    // ‖eᵢ‖ is 0.4–2.4 m, see the note of issue 7).
    assert!(metric(&s, "servicer_3.e_norm_last10s_mean_m") > 20.0, "the dead servicer's spacecraft should drift");
    for i in [1, 2, 4, 5, 6] {
        let e = metric(&s, &format!("servicer_{i}.e_norm_last10s_mean_m"));
        assert!(e < 4.0, "survivor {i}: steady ‖e‖ = {e} m");
        assert_eq!(process(&s, &format!("agent-{i}"))["steps_completed"], 36_000);
    }
    assert_clean(&run);
}

/// Freeze servicer 2 for 5 s, later restart it after 2 s, and have servicers 1 and 4 lose and
/// garble shares: the same plan twice.
fn freeze_restart_drop_corrupt(run: &Path) -> Value {
    let o = launch_scenario(
        Path::new("topologies/fig1.toml"),
        run,
        &[
            "--step-timeout",
            "2",
            "--fault",
            "freeze:agent=2@t=100,for=5",
            "--fault",
            "restart:agent=2@t=200,for=2",
            "--fault",
            "drop:agent=1@t=50,p=0.2",
            "--fault",
            "corrupt:agent=4@t=50,p=0.2",
        ],
    );
    assert!(o.status.success(), "{}", describe_output(&o));
    summary(run)
}

#[test]
fn fig1_freeze_restart_drop_and_corrupt_complete_count_exactly_and_repeat_bit_for_bit() {
    let (_g, dir) = heavy_scratch("fault-mix");
    let (a, b) = (dir.join("a"), dir.join("b"));
    let s = freeze_restart_drop_corrupt(&a);
    assert_eq!(s["status"], "ok");
    assert_eq!(s["steps_completed"], 36_000);

    // Freeze: silent past the step timeout → dead at the frozen step; back on the roster at 105 s.
    let freeze = events(&s, 2, "freeze");
    assert_eq!(freeze[0]["step"], 10_000);
    let dead = events(&s, 2, "dead");
    assert_eq!(dead[0]["step"], 10_000, "{}", s["timeline"]);
    let detection_s = dead[0]["wall_s"].as_f64().unwrap() - freeze[0]["wall_s"].as_f64().unwrap();
    assert!((1.5..12.0).contains(&detection_s), "freeze detected after {detection_s} s (timeout 2 s)");
    let alive = events(&s, 2, "alive");
    assert_eq!(alive[0]["step"], 10_500);
    // Restart: killed at 200 s, relaunched at 202 s from its latest checkpoint.
    assert_eq!(events(&s, 2, "kill")[0]["step"], 20_000);
    assert_eq!(events(&s, 2, "relaunch")[0]["step"], 20_200);
    assert_eq!(alive[1]["step"], 20_200);
    let a2 = process(&s, "agent-2");
    let every = 500; // run.checkpoint_every_steps in fig1.toml's default
    assert_eq!(a2["faults"]["restored_from_step"], 20_000 / every * every);
    assert_eq!(a2["steps_completed"], 36_000);
    // The relaunched process restored exactly the checkpointed state: the file it read and its
    // own state encoded again right after restoring are the same bytes.
    let ck = a.join("checkpoints");
    let loaded = std::fs::read(ck.join("agent-2.loaded.ckpt")).expect("the checkpoint it loaded");
    let restored = std::fs::read(ck.join("agent-2.restored.ckpt")).expect("its restored state");
    assert!(loaded.len() > 1000, "a real state, not an empty one: {} bytes", loaded.len());
    assert_eq!(loaded, restored, "the restored state differs from the checkpointed one");
    // Its telemetry goes on after the relaunch, with a gap where it was dead.
    let ks = cohort::telemetry_table(&a, "agent-2").k;
    assert!(ks.contains(&20_200) && ks.contains(&35_999) && !ks.contains(&20_100), "rows around the restart");

    // Drop and corrupt: every injected loss is counted, exactly, by every reader.
    let plant = process(&s, "plant");
    let dropped = process(&s, "agent-1")["faults"]["shares_dropped"].as_u64().unwrap();
    let corrupted = process(&s, "agent-4")["faults"]["shares_corrupted"].as_object().unwrap().clone();
    let n_corrupted: u64 = corrupted.values().map(|v| v.as_u64().unwrap()).sum();
    assert!((5_000..9_000).contains(&dropped), "p = 0.2 of 31 000 steps: {dropped}");
    assert!((5_000..9_000).contains(&n_corrupted), "{n_corrupted}");
    assert_eq!(plant["faults"]["held"]["agent-1"].as_u64(), Some(dropped));
    for reader in ["plant", "agent-3", "agent-5"] {
        for (why, n) in &corrupted {
            assert_eq!(&process(&s, reader)["messages_rejected"][why], n, "{reader} rejects {why}");
        }
    }
    assert_eq!(process(&s, "agent-6")["faults"]["held"]["agent-1"].as_u64(), Some(dropped));
    // No corrupted value reached any state: no NaN anywhere in the telemetry.
    for (file, line, col, bits) in telemetry_bits(&a) {
        assert!(!f64::from_bits(bits).is_nan(), "NaN in {file}:{line} column {col}");
    }
    for i in 1..=6 {
        let e = metric(&s, &format!("servicer_{i}.e_norm_last10s_mean_m"));
        assert!(e < 4.0, "servicer {i}: steady ‖e‖ = {e} m");
    }
    assert_clean(&a);

    // Lockstep with a fault plan is still deterministic.
    let s2 = freeze_restart_drop_corrupt(&b);
    assert_eq!(s2["status"], "ok");
    let (ta, tb) = (telemetry_bits(&a), telemetry_bits(&b));
    assert_eq!(ta.len(), tb.len());
    for (x, y) in ta.iter().zip(&tb) {
        assert_eq!(x, y, "fault runs differ (file, line, column, bits)");
    }
    assert_clean(&b);
}

#[test]
fn a_damaged_checkpoint_is_refused_and_the_agent_stays_off_the_roster() {
    let (_g, dir) = heavy_scratch("fault-badckpt");
    let run = dir.join("run");
    // Agent 2 of the consensus ring is restarted at 10 s; its latest checkpoint (step 500, 5 s)
    // is damaged by a watcher thread long before (real time at rate 2: 2.5 s of wall time).
    let run2 = run.clone();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = std::sync::Arc::clone(&stop);
    let watcher = std::thread::spawn(move || {
        let path = run2.join("checkpoints/agent-2.ckpt");
        let mut damaged = 0;
        while !stop2.load(std::sync::atomic::Ordering::SeqCst) {
            if let Ok(mut bytes) = std::fs::read(&path)
                && bytes.len() > 40
                && bytes[30] != 0xAA
            {
                bytes[30] = 0xAA;
                if std::fs::write(&path, &bytes).is_ok() {
                    damaged += 1;
                }
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        damaged
    });
    let o = launch_scenario(
        Path::new("topologies/consensus-ring.toml"),
        &run,
        &["--duration", "12", "--realtime", "--rate", "2", "--fault", "restart:agent=2@t=10,for=1"],
    );
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    assert!(watcher.join().unwrap() > 0, "the watcher never saw a checkpoint");
    assert_eq!(o.status.code(), Some(1), "a failed relaunch fails the run's exit code:\n{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent-2") && err.contains("checksum mismatch"), "{err}");
    let s = summary(&run);
    assert_eq!(s["status"], "degraded");
    assert_eq!(events(&s, 2, "restore-failed").len(), 1, "{}", s["timeline"]);
    assert!(events(&s, 2, "alive").is_empty(), "a refused checkpoint must not bring the agent back");
    assert_eq!(s["steps_completed"], 1200);
    assert_clean(&run);
}

#[test]
fn bad_fault_arguments_are_refused_before_anything_runs() {
    let dir = scratch_dir("fault-args");
    for (args, says) in [
        (vec!["--fault", "kill:agent=x@t=1"], "--fault (#1)"),
        (vec!["--fault", "kill:agent=2@t=1", "--fault", "drop:agent=2@t=1,p=2"], "--fault #2.p = 2.0"),
        (vec!["--fault", "kill:agent=2@t=1", "--reference"], "--reference"),
        (vec!["--on-agent-loss", "maybe"], "run.on_agent_loss"),
    ] {
        let o = launch_scenario(Path::new("topologies/consensus-ring.toml"), &dir.join("run"), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}:\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{args:?}: expected {says:?} in:\n{err}");
        assert!(!dir.join("run").exists(), "{args:?}: a run directory was created");
    }
}

#[test]
fn in_real_time_a_frozen_agent_costs_deadline_misses_until_it_is_declared_dead() {
    let (_g, dir) = heavy_scratch("fault-realtime");
    let run = dir.join("run");
    // Ring at 100 Hz in real time; agent 2 frozen at 2 s for 3 s, step timeout 1 s: the plant
    // misses agent 2's command at every step's deadline (and flies the last one) until a second
    // of silence has passed, then declares it dead; it is back on the roster at 5 s.
    let o = launch_scenario(
        Path::new("topologies/consensus-ring.toml"),
        &run,
        &["--duration", "6", "--realtime", "--step-timeout", "1", "--fault", "freeze:agent=2@t=2,for=3"],
    );
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&run);
    let plant = process(&s, "plant");
    let misses = plant["faults"]["deadline_misses"].as_u64().unwrap();
    let held = plant["faults"]["held"]["agent-2"].as_u64().unwrap_or(0);
    // About one second of 10-ms steps (more on a loaded machine, where others miss too).
    assert!((60..=400).contains(&misses), "{misses} deadline misses");
    assert!(held >= 60, "agent 2's last command stood in {held} times");
    let dead = events(&s, 2, "dead");
    assert_eq!(dead.len(), 1, "{}", s["timeline"]);
    let step = dead[0]["step"].as_u64().unwrap();
    assert!((250..=340).contains(&step), "declared dead at step {step} (frozen at 200, timeout 1 s)");
    assert_eq!(events(&s, 2, "alive")[0]["step"], 500);
    assert_eq!(s["steps_completed"], 600);
    assert_clean(&run);
}

/// Rows agent `id` has journalled so far in a running run (see `parquet_out`: a header of three
/// lines, magic, value type and columns, then rows of 8-byte numbers).
fn rows_journalled(run: &Path, id: u32) -> u64 {
    let Ok(bytes) = std::fs::read(run.join(format!("telemetry/agent-{id}.rows"))) else { return 0 };
    let Some(header) = bytes.iter().enumerate().filter(|(_, b)| **b == b'\n').nth(2).map(|(i, _)| i + 1) else {
        return 0;
    };
    let width = bytes[..header].iter().filter(|b| **b == b',').count() as u64 + 1;
    (bytes.len() - header) as u64 / (8 * width)
}

/// Never lost telemetry, also for an unplanned SIGKILL (no flush before it, unlike a planned
/// `kill` fault): a Parquet file is unreadable without its footer, so the writer journals every
/// ≤ 16 KiB of rows as raw numbers, and the orchestrator turns a killed process's journal into
/// its file. The killed agent's telemetry is read back, every step from 0 up to at most one
/// journal batch (plus the detection delay) short of the step the plant saw it die at.
#[test]
fn an_agent_killed_by_surprise_keeps_its_parquet_telemetry_up_to_a_step_close_to_the_kill() {
    let (_g, dir) = heavy_scratch("fault-sigkill");
    let run = dir.join("run");
    // In real time (100 steps/s), so that the kill lands mid-run whatever the machine's speed.
    let child = cohort::orchestrator_command()
        .arg("launch")
        .arg("topologies/consensus-ring.toml")
        .arg("--out")
        .arg(&run)
        .args(["--no-plots", "--duration", "14", "--realtime"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("running the orchestrator");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while rows_journalled(&run, 3) < 500 {
        assert!(std::time::Instant::now() < deadline, "agent 3 journalled no telemetry");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let needle = run.display().to_string();
    let agent3: Vec<u32> = processes_mentioning(&needle)
        .into_iter()
        .filter(|(_, cmd)| cmd.split(' ').next().is_some_and(|b| b.ends_with("/agent")) && cmd.contains(" --id 3 "))
        .map(|(pid, _)| pid)
        .collect();
    assert_eq!(agent3.len(), 1, "agent 3's process: {:?}", processes_mentioning(&needle));
    // SAFETY: a plain kill(2) of the agent process this test's run started.
    assert_eq!(unsafe { libc::kill(agent3[0] as i32, libc::SIGKILL) }, 0);
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run whose agent was killed by surprise");
    let s = summary(&run);
    assert_eq!(s["status"], "degraded", "{}", describe_output(&o));
    assert_eq!(s["steps_completed"], 1400);
    let died = events(&s, 3, "died");
    assert_eq!(died.len(), 1, "{}", s["timeline"]);
    let died_at = died[0]["step"].as_u64().unwrap();
    // The orchestrator turned the journal into the one file; nothing else is left.
    let tel = run.join("telemetry");
    let mut left: Vec<String> =
        std::fs::read_dir(&tel).unwrap().flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
    left.sort();
    let want: Vec<String> = (1..=6).map(|i| format!("agent-{i}.parquet")).chain(["plant.parquet".into()]).collect();
    assert_eq!(left, want);
    let t = cohort::telemetry_table(&run, "agent-3");
    assert!(t.k.len() >= 500, "{} rows", t.k.len());
    // In real time a process that falls behind skips steps (no rows then), as with CSV — the
    // first ones too, when the loaded machine starts the agent late (CI saw its rows begin at 1).
    assert!(t.k[0] < 200 && t.k.windows(2).all(|w| w[0] < w[1]), "steps in order from near 0: {:?}", t.k);
    assert!(t.columns.iter().all(|c| c.values.iter().all(|v| v.is_finite())));
    let last = *t.k.last().unwrap();
    let batch_rows = 16 * 1024 / (8 * (t.columns.len() as u64 + 2));
    // The plant hears of the death within a few steps (the orchestrator polls its children), and
    // an agent may be a step or two ahead of the step at which the plant records it dead; at most
    // one batch of rows was still in memory.
    assert!(
        last <= died_at + 2 && died_at.saturating_sub(last) <= batch_rows + 100,
        "rows up to step {last}, died at step {died_at}"
    );
    // The survivors' files are whole.
    assert_eq!(cohort::telemetry_table(&run, "agent-2").k.last(), Some(&1399));
    // Its timing journal, too, was turned into its Parquet file (no histograms: it never exited).
    let timing = run.join("timing");
    let mut left: Vec<String> =
        std::fs::read_dir(&timing).unwrap().flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
    left.sort();
    assert!(left.contains(&"agent-3.parquet".to_string()) && !left.contains(&"agent-3.hlog".to_string()), "{left:?}");
    assert!(!left.iter().any(|f| f.ends_with(".rows") || f.starts_with('.')), "{left:?}");
    let k = cohort_runtime::record::timing_column(&timing, "agent-3", "k");
    assert!(k.len() >= 500 && k.windows(2).all(|w| w[0] < w[1]), "{} timing rows", k.len());
    assert_clean(&run);
}
