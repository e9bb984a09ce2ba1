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

use cohort::OutputWithin;
use cohort::{describe_output, heavy, heavy_scratch, orchestrator_command, repo_root, scratch_dir, summary};

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
    let (_g, dir) = heavy_scratch("race");
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
        let (a, b) = (
            cohort::finish_within(a, cohort::RUN_LIMIT, "the first launch into one --out"),
            cohort::finish_within(b, cohort::RUN_LIMIT, "the second launch into one --out"),
        );
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
}

/// Defect 3: a FIFO, a device and a file past the documented size are refused at once with exit 2
/// and a reason (before, `launch FIFO` waited for a writer ignoring SIGTERM, and `/dev/zero` was
/// read until memory ran out), by `launch`, `check` and `--hosts`.
#[test]
fn a_fifo_a_device_or_an_oversized_file_is_refused_at_once() {
    let dir = scratch_dir("input");
    let fifo = dir.join("scenario.fifo");
    let c = std::ffi::CString::new(fifo.display().to_string()).unwrap();
    // SAFETY: mkfifo on a path we own.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let big = dir.join("big.toml");
    let mut text = std::fs::read_to_string(ring()).unwrap();
    text.push_str(&format!("# {}\n", "x".repeat(5 << 20)));
    std::fs::write(&big, text).unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["launch".into(), fifo.display().to_string()], "a FIFO"),
        (vec!["check".into(), fifo.display().to_string()], "a FIFO"),
        (vec!["launch".into(), "/dev/zero".into()], "a device"),
        (vec!["check".into(), "/dev/zero".into()], "a device"),
        (vec!["launch".into(), big.display().to_string()], "more than the 4194304 bytes"),
        (vec!["launch".into(), ring().display().to_string(), "--hosts".into(), "/dev/zero".into()], "a device"),
        (vec!["launch".into(), dir.display().to_string()], "a directory"),
    ];
    for (args, says) in cases {
        let what = args.join(" ");
        let mut cmd = orchestrator_command();
        cmd.args(&args).args(["--no-plots"].iter().filter(|_| args[0] == "launch"));
        let o = cmd.output_within(Duration::from_secs(60), &what);
        assert_eq!(o.status.code(), Some(2), "{what}\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{what}: expected {says:?}\n{err}");
    }
}

/// Defect 6: a valid checkpoint of another run (seed 8's agent 2) copied over agent 2's own
/// before a restart fault is refused, naming the reason, and the agent stays off the roster
/// (before, it was restored from and the run ended 0).
#[test]
fn a_checkpoint_of_another_run_is_refused() {
    let (_g, dir) = heavy_scratch("foreign-ckpt");
    let other = dir.join("seed-8");
    let o = cohort::launch_scenario(&ring(), &other, &["--duration", "6", "--seed", "8"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let foreign = std::fs::read(other.join("checkpoints/agent-2.ckpt")).expect("seed 8's agent-2 checkpoint");
    let run = dir.join("seed-1");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watcher = {
        let (path, stop, foreign) = (run.join("checkpoints/agent-2.ckpt"), stop.clone(), foreign.clone());
        std::thread::spawn(move || {
            let mut swapped = 0;
            while !stop.load(std::sync::atomic::Ordering::SeqCst) {
                if std::fs::read(&path).is_ok_and(|b| b != foreign) && std::fs::write(&path, &foreign).is_ok() {
                    swapped += 1;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            swapped
        })
    };
    // Restart at 10 s (real time at rate 2: 5 s of wall time), relaunch 1 s later.
    let o = cohort::launch_scenario(
        &ring(),
        &run,
        &["--duration", "12", "--seed", "1", "--realtime", "--rate", "2", "--fault", "restart:agent=2@t=10,for=1"],
    );
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    assert!(watcher.join().unwrap() > 0, "the watcher never saw a checkpoint");
    assert_eq!(o.status.code(), Some(1), "a refused checkpoint fails the run:\n{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent-2") && err.contains("a checkpoint of another run"), "{err}");
    let s = summary(&run);
    let timeline = s["timeline"].as_array().unwrap();
    let of_2 = |ev: &str| timeline.iter().filter(|e| e["agent"] == 2 && e["event"] == ev).count();
    assert_eq!(of_2("restore-failed"), 1, "{}", s["timeline"]);
    assert_eq!(of_2("alive"), 0, "a foreign checkpoint must not bring the agent back");
}

/// Defect 7: another user owns the per-user base directory (here `$XDG_RUNTIME_DIR/cohort`, in a
/// scratch `XDG_RUNTIME_DIR`, so no other run on the machine is affected). The launch warns,
/// naming the owner and the fresh private directory it uses instead, and succeeds (before, it
/// exited 1: "belongs to uid 65534"); it leaves nothing there but the squatted directory.
#[test]
fn a_base_directory_squatted_by_another_user_is_replaced_by_a_private_one() {
    use std::os::unix::fs::PermissionsExt;
    let _g = heavy();
    // Short: a run's iceoryx2 root inside the base must stay within 42 bytes.
    let xdg = PathBuf::from(format!("/tmp/cq{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&xdg);
    std::fs::create_dir_all(xdg.join("cohort")).unwrap();
    std::fs::set_permissions(&xdg, std::fs::Permissions::from_mode(0o700)).unwrap();
    let squatted = xdg.join("cohort");
    let c = std::ffi::CString::new(squatted.display().to_string()).unwrap();
    // SAFETY: chown of a directory this test created.
    if unsafe { libc::chown(c.as_ptr(), 65534, 65534) } != 0 {
        eprintln!("skipped: chown to another user is not permitted here");
        let _ = std::fs::remove_dir_all(&xdg);
        return;
    }
    let dir = scratch_dir("squat");
    for round in 0..2 {
        let out = dir.join(format!("run{round}"));
        let o = orchestrator_command()
            .env("XDG_RUNTIME_DIR", &xdg)
            .args(["launch", "--duration", "2", "--no-plots", "--out"])
            .arg(&out)
            .arg(ring())
            .output_within(cohort::RUN_LIMIT, "a launch with a private XDG_RUNTIME_DIR");
        assert_eq!(o.status.code(), Some(0), "round {round}\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("belongs to uid 65534") && err.contains("this user's runs use"), "{err}");
        assert!(err.contains(&format!("{}-", squatted.display())), "names the fallback: {err}");
        let left: Vec<_> = std::fs::read_dir(&xdg).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("cohort")], "round {round}: left in {}", xdg.display());
    }
    let _ = std::fs::remove_dir_all(&xdg);
}

/// The pid of `parent`'s child process whose command name is `name`, if there is one.
fn child_named(parent: u32, name: &str) -> Option<i32> {
    for e in std::fs::read_dir("/proc").ok()?.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else { continue };
        let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else { continue };
        // "pid (comm) state ppid ...": comm may hold spaces, so split after its last ')'.
        let Some((head, rest)) = stat.rsplit_once(')') else { continue };
        let comm = head.split_once('(').map_or("", |(_, c)| c);
        let ppid: Option<u32> = rest.split_whitespace().nth(1).and_then(|p| p.parse().ok());
        if comm == name && ppid == Some(parent) {
            return Some(pid);
        }
    }
    None
}

/// `launch RING --out RUN ARGS…` started, with every process under way.
fn spawn_ring(run: &Path, args: &[&str], stdout: Stdio, stderr: Stdio) -> std::process::Child {
    let child = orchestrator_command()
        .arg("launch")
        .args(args)
        .arg("--out")
        .arg(run)
        .arg(ring())
        .stdout(stdout)
        .stderr(stderr)
        .spawn()
        .unwrap();
    wait_until_running(run, 7);
    child
}

/// Wait (generously) until `run` has its status directory and every process's log, the sign the
/// processes are under way.
fn wait_until_running(run: &Path, n_logs: usize) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while !run.join("status").exists() || std::fs::read_dir(run.join("logs")).map_or(0, |d| d.count()) < n_logs {
        assert!(Instant::now() < deadline, "waited 120 s for {} to start its {n_logs} processes", run.display());
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Defect 8: after the plant is SIGKILLed the summary's steps_completed is not 0 but a lower
/// bound from its telemetry and the agents' reports, and says so.
#[test]
fn a_killed_plant_still_gives_the_steps_the_run_completed() {
    let (_g, dir) = heavy_scratch("plant-kill");
    let run = dir.join("run");
    let child = spawn_ring(
        &run,
        &["--duration", "600", "--no-plots", "--realtime", "--rate", "20"],
        Stdio::null(),
        Stdio::piped(),
    );
    std::thread::sleep(Duration::from_secs(3));
    let plant = child_named(child.id(), "plant").expect("the plant process");
    // SAFETY: kill(2) on the run's plant.
    unsafe { libc::kill(plant, libc::SIGKILL) };
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run whose plant was killed");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let s = summary(&run);
    let done = s["steps_completed"].as_u64().unwrap();
    let agents: Vec<u64> = s["processes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["process"].as_str().is_some_and(|n| n.starts_with("agent-")))
        .map(|p| p["steps_completed"].as_u64().unwrap())
        .collect();
    let most = *agents.iter().max().expect("the agents' reports");
    assert!(most > 100, "the agents completed {agents:?} steps in 3 s at rate 20");
    assert!(done + 1 >= most && done <= most, "steps_completed {done}, agents {agents:?}");
    let warnings = s["warnings"].to_string();
    assert!(warnings.contains("lower bound"), "{warnings}");
}

/// Defect 8: a bad value given on the command line is cited by its flag, not by a line of the
/// scenario file it did not come from.
#[test]
fn a_bad_command_line_value_cites_its_flag() {
    let dir = scratch_dir("flag");
    for (args, flag) in [
        (vec!["--duration", "nan"], "--duration (command line): scenario.duration_s"),
        (vec!["--step-timeout", "0.01"], "--step-timeout (command line): run.step_timeout_s"),
        (vec!["--wait", "sometimes"], "--wait (command line): run.wait"),
    ] {
        let o = cohort::launch_scenario(&ring(), &dir.join("run"), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(flag), "{args:?}: expected {flag:?}\n{err}");
        let cites_a_line =
            err.split("consensus-ring.toml:").skip(1).any(|after| after.starts_with(|c: char| c.is_ascii_digit()));
        assert!(!cites_a_line, "{args:?}: cites a line of the file\n{err}");
    }
}

/// Defect 8: SIGTERM while the plots are drawn ends the orchestrator at once with 143 (before,
/// the drawing went on and the launch exited 0).
#[test]
fn sigterm_while_drawing_the_plots_exits_143() {
    let (_g, dir) = heavy_scratch("plot-term");
    let run = dir.join("run");
    let mut child = orchestrator_command()
        .args(["launch", "--duration", "600", "--out"])
        .arg(&run)
        .arg(ring())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The summary is written before the plots are drawn.
    let deadline = Instant::now() + Duration::from_secs(300);
    while !run.join("summary.json").exists() {
        assert!(Instant::now() < deadline, "waited 300 s for the run to finish");
        assert!(child.try_wait().unwrap().is_none(), "the launch ended before its summary");
        std::thread::sleep(Duration::from_millis(5));
    }
    // SAFETY: kill(2) on the child we spawned.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let started = Instant::now();
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the run sent SIGTERM while drawing its plots");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(143), "{}", describe_output(&o));
    assert!(err.contains("while drawing the plots"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(10), "took {:?} to stop", started.elapsed());
}

/// Defect 8: on a file system with room for the run directory's first files but not for a single
/// log line, every log stays empty: the error says the file system is full (the cause itself),
/// not "see logs/".
#[test]
fn on_a_full_disk_with_empty_logs_the_error_gives_the_cause() {
    let (_g, dir) = heavy_scratch("full-logs");
    let mnt = dir.join("mnt");
    std::fs::create_dir_all(&mnt).unwrap();
    let mounted = Command::new("mount").args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"]).arg(&mnt).output();
    if !mounted.as_ref().is_ok_and(|o| o.status.success()) {
        eprintln!("skipped: cannot mount a small tmpfs here ({mounted:?})");
        return;
    }
    // 15 of the 16 pages taken: the last one holds scenario.toml.
    std::fs::write(mnt.join("filler"), vec![0u8; 15 * 4096]).unwrap();
    let o = cohort::launch_scenario(&ring(), &mnt.join("run"), &["--duration", "2"]);
    let logs: Vec<u64> = std::fs::read_dir(mnt.join("run/logs"))
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.metadata().map_or(0, |m| m.len()))
        .collect();
    let _ = Command::new("umount").arg(&mnt).status();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    if logs.iter().any(|&n| n > 0) {
        eprintln!("skipped: a log got written ({logs:?}), so the case did not arise\n{err}");
        return;
    }
    let first = err.lines().find(|l| l.starts_with("error:")).unwrap_or("");
    assert!(first.contains("is full") && first.contains("No space left on device"), "{err}");
    assert!(!err.contains("see logs/"), "{err}");
}

/// `orchestrator replay RUN --agent 2`, within a generous limit.
fn replay_agent_2(run: &Path, what: &str) -> Output {
    let mut cmd = orchestrator_command();
    cmd.arg("replay").arg(run).args(["--agent", "2"]);
    cmd.output_within(Duration::from_secs(60), what)
}

/// Defect 4: 200 seeded one-byte flips of a recording — half anywhere, half in a chunk's header
/// or the start of its zstd frame, where the mcap crate allocated from the damaged length and the
/// replay aborted (exit 134) — each end with 0, 1 or 2, a refusal naming the file and the offset.
/// All 200 take well under a minute (each replay is a few ms here).
#[test]
fn replays_of_200_damaged_recordings_end_with_0_1_or_2() {
    let (_g, dir) = heavy_scratch("flips");
    let run = dir.join("run");
    let o = cohort::launch_scenario(&ring(), &run, &["--duration", "2", "--record"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let path = run.join("record/agent-2.mcap");
    let good = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&good).unwrap().expect("a summary");
    let chunks: Vec<usize> = summary.chunk_indexes.iter().map(|c| c.chunk_start_offset as usize).collect();
    let mut x: u64 = 36;
    let mut next = move || {
        x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        x >> 33
    };
    let started = Instant::now();
    let mut codes = std::collections::BTreeMap::new();
    for n in 0..200 {
        let at = if n % 2 == 0 {
            (next() % good.len() as u64) as usize
        } else {
            (chunks[(next() % chunks.len() as u64) as usize] + (next() % 96) as usize).min(good.len() - 1)
        };
        let mut bad = good.clone();
        bad[at] ^= 1 << (next() % 8);
        std::fs::write(&path, &bad).unwrap();
        let o = replay_agent_2(&run, &format!("flip {n} at byte {at}"));
        let code = o.status.code();
        assert!(matches!(code, Some(0..=2)), "flip {n} at byte {at}\n{}", describe_output(&o));
        if code == Some(2) {
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(err.contains("agent-2.mcap") && !err.contains("panicked"), "flip {n} at byte {at}\n{err}");
        }
        *codes.entry(code).or_insert(0) += 1;
    }
    assert!(started.elapsed() < Duration::from_secs(60), "200 replays took {:?}", started.elapsed());
    assert!(codes.get(&Some(2)).copied().unwrap_or(0) > 50, "exit codes: {codes:?}");
}

/// Defect 4: the recording of an agent SIGKILLed by a fault has no footer; its replay reads it up
/// to its last complete chunk, says so, and compares what is there (before: exit 2, "not a
/// readable MCAP file").
#[test]
fn a_killed_agents_recording_replays_up_to_its_last_complete_chunk() {
    let (_g, dir) = heavy_scratch("footerless");
    let run = dir.join("run");
    let o = cohort::launch_scenario(&ring(), &run, &["--duration", "30", "--record", "--fault", "kill:agent=2@t=25"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = replay_agent_2(&run, "replay of the killed agent");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    assert!(err.contains("no footer") && err.contains("agent-2.mcap"), "{err}");
    let said = String::from_utf8_lossy(&o.stdout);
    let steps: u64 = said
        .split("replayed ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    assert!(steps > 100 && steps <= 2500, "{said}");
}

/// Defect 5: the orchestrator SIGKILLed mid-run leaves only `.rows` journals (its children die
/// with it); `orchestrator salvage RUN_DIR` turns every intact one into its file, names the one
/// damaged here (exit 1) without stopping at it, and writes the missing summary; `report` then
/// draws the run.
#[test]
fn salvage_turns_a_killed_runs_journals_into_files_past_a_damaged_one() {
    let (_g, dir) = heavy_scratch("salvage");
    let run = dir.join("run");
    let mut child = spawn_ring(
        &run,
        &["--duration", "600", "--no-plots", "--realtime", "--rate", "20"],
        Stdio::null(),
        Stdio::null(),
    );
    std::thread::sleep(Duration::from_secs(3));
    child.kill().unwrap();
    child.wait().unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !cohort::processes_mentioning(&run.display().to_string()).is_empty() {
        assert!(Instant::now() < deadline, "the run's processes outlived their orchestrator by 60 s");
        std::thread::sleep(Duration::from_millis(100));
    }
    let tel = run.join("telemetry");
    assert!(tel.join("plant.rows").is_file() && !tel.join("plant.parquet").exists(), "only journals are left");
    std::fs::write(tel.join("agent-3.rows"), b"damaged").unwrap();
    let o = orchestrator_command()
        .arg("salvage")
        .arg(&run)
        .output_within(cohort::RUN_LIMIT, "salvage of an interrupted run");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent-3.rows"), "{err}");
    for p in ["plant", "agent-1", "agent-2", "agent-4", "agent-5", "agent-6"] {
        assert!(tel.join(format!("{p}.parquet")).is_file(), "{p}.parquet not written\n{}", describe_output(&o));
        assert!(run.join(format!("timing/{p}.parquet")).is_file(), "timing/{p}.parquet not written");
    }
    let s = summary(&run);
    assert_eq!(s["status"], "salvaged");
    assert!(s["steps_completed"].as_u64().unwrap() > 100, "{}", s["steps_completed"]);
    let rows = cohort::telemetry_table(&run, "plant").rows();
    assert!(rows > 100, "{rows} plant rows salvaged");
    let o =
        orchestrator_command().arg("report").arg(&run).output_within(cohort::QUICK_LIMIT, "report of a salvaged run");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
}

/// Defect 1: in real time, a plant stopped for longer than the step timeout (SIGSTOP 11 s, then
/// SIGCONT; timeout 10 s) drops no healthy agent: the stall is the clock's, not their silence
/// (before, all 6 were declared silent and the launch exited 1). The launch reports its deadline
/// misses.
#[test]
fn in_real_time_a_stalled_plant_drops_no_healthy_agent() {
    let (_g, dir) = heavy_scratch("plant-stall");
    let run = dir.join("run");
    let child = spawn_ring(&run, &["--realtime", "--no-plots"], Stdio::piped(), Stdio::piped());
    std::thread::sleep(Duration::from_secs(2));
    let plant = child_named(child.id(), "plant").expect("the plant process");
    // SAFETY: kill(2) on the run's plant.
    unsafe { libc::kill(plant, libc::SIGSTOP) };
    std::thread::sleep(Duration::from_secs(11));
    // SAFETY: as above.
    unsafe { libc::kill(plant, libc::SIGCONT) };
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the real-time run whose plant was stalled");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    let s = summary(&run);
    assert_eq!(s["status"], "ok", "{}", s["timeline"]);
    assert_eq!(s["steps_completed"], 2000);
    let lost: Vec<_> = s["timeline"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|e| e["event"] == "dead" || e["event"] == "silent")
        .collect();
    assert!(lost.is_empty(), "agents dropped: {lost:?}");
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("real time: "), "{said}");
    let log = std::fs::read_to_string(run.join("logs/plant.log")).unwrap();
    assert!(log.contains("behind its real-time schedule"), "{log}");
}

/// Issue 36, item 9.2: a soak's report has every run's latency figures, read from the run's
/// `timing/` histograms before the soak deletes that directory (its per-run latency plot read
/// them after, and so found nothing). The runs' samples add up to the links' over all runs.
#[test]
fn a_soak_report_has_each_runs_latency_figures_though_its_timing_dir_is_gone() {
    let (_g, dir) = heavy_scratch("soak-timing");
    let out = dir.join("soak");
    let o = orchestrator_command()
        .arg("soak")
        .arg(ring())
        .args(["--wall", "1s", "--seed", "7", "--out"])
        .arg(&out)
        .output_within(cohort::RUN_LIMIT, "a one-second soak of the ring");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    let report = cohort::read_json(&out.join("soak.json"));
    let runs = report["runs"].as_array().expect("soak.json: runs");
    assert!(!runs.is_empty(), "no run in {report}");
    let mut run_samples = 0;
    for r in runs {
        let l = &r["latency"];
        let samples = l["samples"].as_u64().unwrap_or_else(|| panic!("run {}: no latency figures: {r}", r["run"]));
        assert!(samples > 0 && l["p99_ns"].as_u64().is_some_and(|p| p > 0), "run {}: {l}", r["run"]);
        assert!(l["max_ns"].as_u64() >= l["p99_ns"].as_u64(), "run {}: {l}", r["run"]);
        assert!(!out.join(format!("run-{:03}", r["run"].as_u64().unwrap())).join("timing").exists());
        run_samples += samples;
    }
    let link_samples: u64 = report["links"].as_object().unwrap().values().map(|l| l["samples"].as_u64().unwrap()).sum();
    assert_eq!(run_samples, link_samples, "{report}");
    let md = std::fs::read_to_string(out.join("soak.md")).unwrap();
    assert!(md.contains("| latency p99 µs | latency max µs |"), "{md}");
}

/// Issue 36, item 9.3: `bench --only X` builds the network-namespace lab only when a chosen case
/// crosses it. A one-host ring case builds none (`lab_links` is null; as root, it was built for
/// every bench). Nor does it load the Python rows: here `import numpy` fails (a stand-in on
/// PYTHONPATH that raises ImportError), which failed every bench before. Under the network lab's
/// lock, as the other lab users are.
#[test]
fn bench_only_a_one_host_case_builds_no_network_lab() {
    let (_g, dir) = heavy_scratch("bench-nolab");
    let no_numpy = dir.join("no-numpy");
    std::fs::create_dir_all(no_numpy.join("numpy")).unwrap();
    std::fs::write(no_numpy.join("numpy/__init__.py"), "raise ImportError('no numpy in this test')\n").unwrap();
    let o = Command::new("flock")
        .env("PYTHONPATH", &no_numpy)
        .arg("/tmp/cohort-netlab.lock")
        .arg(cohort::bin_path("orchestrator"))
        .args(["bench", "--quick", "--only", "ring/N=6/event", "--out"])
        .arg(dir.join("bench"))
        .current_dir(repo_root())
        .output_within(cohort::RUN_LIMIT, "bench --only ring/N=6/event under the network lab's lock");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    let results = cohort::read_json(&dir.join("bench/results.json"));
    assert!(results["lab_links"].is_null(), "a lab was built for ring/N=6/event: {}", results["lab_links"]);
    let keys: Vec<&str> = results["cases"].as_array().unwrap().iter().map(|c| c["key"].as_str().unwrap()).collect();
    assert_eq!(keys, ["ring/N=6/event"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("not building it"), "{}", describe_output(&o));
}

/// Issue 36, item 9.6: SIGTERM while a zenoh process waits for its peers (`ZenohPending::ready`)
/// ends it at once with the stopped status (4), not after `run.startup_timeout_s` (here 300 s).
/// The agent's peers (the plant, its readers, the orchestrator) never come.
#[test]
fn sigterm_ends_a_zenoh_process_waiting_for_peers_that_never_come() {
    let (_g, dir) = heavy_scratch("zenoh-pending-term");
    let text = std::fs::read_to_string(ring()).unwrap().replace(
        "[run]\nstep_timeout_s = 10.0\n",
        "[run]\nstep_timeout_s = 10.0\ntransport = \"zenoh\"\nzenoh_links = \"peers\"\nstartup_timeout_s = 300.0\n",
    );
    assert!(text.contains("transport = \"zenoh\""), "the ring's [run] table moved: {text}");
    std::fs::write(dir.join("scenario.toml"), text).unwrap();
    let mut child = Command::new(cohort::bin_path("agent"))
        .args(["--id", "1", "--run-id", "0a5e", "--build-id", cohort_build_id::BUILD_ID])
        .args(["--zenoh-listen", "tcp/127.0.0.1:0"])
        .arg("--run-dir")
        .arg(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting an agent");
    // Let it declare its endpoint and enter the wait (a loaded machine: generous).
    std::thread::sleep(Duration::from_secs(3));
    assert!(child.try_wait().unwrap().is_none(), "the agent ended before it was signalled");
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let o =
        cohort::finish_within(child, Duration::from_secs(20), "the agent, sent SIGTERM while it waited for its peers");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "the stopped status: {err}");
    assert!(err.contains("stopped on request"), "{err}");
    assert!(cohort::processes_mentioning(&dir.display().to_string()).is_empty(), "an orphan is left");
}
