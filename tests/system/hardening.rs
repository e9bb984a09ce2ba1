//! Issue 18 as an adversarial user would probe it, one test per finding that launches real
//! processes: bad command-line values and signals never panic (exit 101), a closed stdout ends
//! quietly with the run's exit code, SIGHUP stops a run like SIGTERM, a scenario too large for the
//! open-file limit is refused up front in words, a full disk is reported first and leaves no empty
//! JSON behind, a run with `run.authenticate` gives the same telemetry, a second user can run
//! after root, and waiting survives two CPU hogs.
//!
//! Heavy tests are serialised by [`cohort::heavy`]; every wait is generous.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cohort::OutputWithin;
use cohort::{
    describe_output, heavy, heavy_scratch, iceoryx2_leftovers, orchestrator_command, repo_root, scratch_dir, summary,
    telemetry_bits,
};

fn ring() -> String {
    repo_root().join("topologies/consensus-ring.toml").display().to_string()
}

fn no_panic(what: &str, o: &Output) {
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_ne!(o.status.code(), Some(101), "{what}: exit 101\n{}", describe_output(o));
    assert!(!text.contains("panicked"), "{what}: panicked\n{}", describe_output(o));
}

fn assert_clean(run_dir: &Path) {
    let id = summary(run_dir)["run_id"].as_str().expect("run_id").to_string();
    assert!(iceoryx2_leftovers(&id).is_empty(), "leftovers of run {id}: {:?}", iceoryx2_leftovers(&id));
}

/// Findings 3 and 7: a table of bad values, each refused with exit 2 and a short message, never a
/// panic.
#[test]
fn bad_command_line_values_are_refused_without_a_panic() {
    let dir = scratch_dir("badargs");
    let out = |tag: &str| dir.join(tag).display().to_string();
    let ring = ring();
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let damaged = dir.join("damaged-run");
    std::fs::create_dir_all(damaged.join("telemetry")).unwrap();
    std::fs::write(damaged.join("telemetry/plant.parquet"), b"PAR1 cut short").unwrap();
    let table: Vec<(Vec<String>, i32, &str)> = vec![
        (vec!["launch", &ring, "--seed", "9223372036854775808"], 2, "2^63 − 1"),
        (vec!["launch", &ring, "--seed", "18446744073709551615"], 2, "2^63 − 1"),
        (vec!["launch", &ring, "--seed", "-1"], 2, "-1"),
        (vec!["soak", &ring, "--wall", "1s", "--seed", "18446744073709551615"], 2, "2^63 − 1"),
        (vec!["sweep", &ring, "--seeds", "0"], 2, "--seeds"),
        (vec!["sweep", &ring, "--first-seed", "9223372036854775807", "--seeds", "2"], 2, "passes 2^63 − 1"),
        (vec!["launch", &ring, "--step-timeout", "1e-300", "--out", &out("a")], 2, "must be at least 0.1 s"),
        (vec!["launch", &ring, "--step-timeout", "nan", "--out", &out("b")], 2, "finite"),
        (vec!["launch", &ring, "--step-timeout", "-1", "--out", &out("c")], 2, "-1"),
        (vec!["launch", &ring, "--duration", "1e300", "--out", &out("d")], 2, "duration_s"),
        (vec!["launch", &ring, "--duration", "0", "--out", &out("e")], 2, "duration_s"),
        (vec!["launch", &ring, "--link-delay", "5", "--out", &out("f")], 2, "link_delay_steps"),
        (vec!["launch", &ring, "--wait", "sometimes", "--out", &out("g")], 2, "run.wait"),
        (vec!["launch", &ring, "--transport", "pigeon", "--out", &out("h")], 2, "run.transport"),
        (vec!["launch", &ring, "--spin-us=-1", "--out", &out("i")], 2, "spin_us"),
        (vec!["launch", &ring, "--realtime", "--rate", "0", "--out", &out("j")], 2, "realtime_rate"),
        (vec!["launch", &ring, "--fault", "melt:agent=1@t=1"], 2, "--fault"),
        (vec!["launch", &ring, "--on-agent-loss", "maybe", "--out", &out("k")], 2, "on_agent_loss"),
        (vec!["launch", "/nonexistent/x.toml"], 2, "cannot read"),
        (vec!["launch", &ring, "--out", &file.display().to_string()], 2, "--out"),
        (vec!["launch", &ring, "--telemetry", "xml", "--out", &out("l")], 2, "run.telemetry"),
        (vec!["report", "/nonexistent/run"], 2, ""),
        (vec!["report", &damaged.display().to_string()], 2, "plant.parquet: not a readable telemetry Parquet file"),
        (
            vec!["check", &repo_root().join("tests/invalid/invalid-agent-id-out-of-range.toml").display().to_string()],
            2,
            "",
        ),
    ]
    .into_iter()
    .map(|(a, code, says)| (a.into_iter().map(String::from).collect(), code, says))
    .collect();
    for (args, code, says) in &table {
        let o = orchestrator_command().args(args).output_within(cohort::QUICK_LIMIT, "a refused command line");
        let what = args.join(" ");
        no_panic(&what, &o);
        assert_eq!(o.status.code(), Some(*code), "{what}\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{what}: expected {says:?}\n{err}");
        assert!(err.len() < 2000, "{what}: a {}-byte error", err.len());
    }
}

/// Finding 3: `launch … | true` and `> /dev/full` end quietly with the run's exit code.
#[test]
fn a_closed_or_full_stdout_ends_quietly_with_the_runs_exit_code() {
    let (_g, dir) = heavy_scratch("stdout");
    // stdout a pipe whose read end is closed before the run prints anything.
    let mut child = orchestrator_command()
        .args(["launch", &ring(), "--duration", "2", "--no-plots", "--out"])
        .arg(dir.join("pipe"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "a launch whose stdout was closed");
    let (st, err) = (o.status, String::from_utf8_lossy(&o.stderr));
    assert_eq!(st.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_clean(&dir.join("pipe"));
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = orchestrator_command()
        .args(["launch", &ring(), "--duration", "2", "--no-plots", "--out"])
        .arg(dir.join("full"))
        .stdout(full)
        .output()
        .unwrap();
    no_panic("> /dev/full", &o);
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
}

/// Finding 4: SIGHUP (a closed terminal) stops the run like SIGTERM: 128 + 1, a summary, and no
/// iceoryx2 resource left. SIGTERM likewise.
#[test]
fn sighup_and_sigterm_stop_a_run_in_order() {
    let (_g, dir) = heavy_scratch("hup");
    for (sig, code) in [(libc::SIGHUP, 129), (libc::SIGTERM, 143)] {
        let out = dir.join(format!("sig{sig}"));
        let child = orchestrator_command()
            .args(["launch", &ring(), "--duration", "600", "--no-plots", "--wait", "event", "--out"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Signal once the run is under way (its plant reports progress).
        let deadline = Instant::now() + Duration::from_secs(60);
        while !out.join("status").exists() || std::fs::read_dir(out.join("logs")).map_or(0, |d| d.count()) < 7 {
            assert!(Instant::now() < deadline, "the run never started");
            std::thread::sleep(Duration::from_millis(50));
        }
        std::thread::sleep(Duration::from_millis(1500));
        // SAFETY: kill(2) on the child we spawned.
        unsafe { libc::kill(child.id() as i32, sig) };
        let o = cohort::finish_within(child, cohort::RUN_LIMIT, &format!("the run sent signal {sig}"));
        let (st, err) = (o.status, String::from_utf8_lossy(&o.stderr));
        assert_eq!(st.code(), Some(code), "signal {sig}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(summary(&out)["status"], "interrupted", "signal {sig}");
        assert_clean(&out);
    }
}

/// Finding 5: a scenario the open-file limit cannot hold is refused up front in words.
#[test]
fn a_run_too_large_for_the_open_file_limit_is_refused_up_front() {
    let (_g, dir) = heavy_scratch("nofile");
    let file = dir.join("ring60.toml");
    std::fs::write(&file, null_ring(60)).unwrap();
    let mut cmd = orchestrator_command();
    cmd.args(["launch", &file.display().to_string(), "--no-plots", "--out"]).arg(dir.join("run"));
    // SAFETY: setrlimit between fork and exec, on the child only.
    unsafe {
        cmd.pre_exec(|| {
            let r = libc::rlimit { rlim_cur: 512, rlim_max: 512 };
            libc::setrlimit(libc::RLIMIT_NOFILE, &r);
            Ok(())
        });
    }
    let started = Instant::now();
    let o = cmd.output_within(cohort::RUN_LIMIT, "a launch under ulimit -n 512");
    no_panic("ulimit -n 512", &o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    assert!(err.contains("open files, the limit is 512; raise it with ulimit -n"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(20), "not refused up front");
}

/// iceoryx2's event sockets live in the run's root directory, and a unix socket path has at most
/// 107 bytes: a long `XDG_RUNTIME_DIR` made large runs fail with a bare `ResourceCreationFailed`.
/// A root of 42 bytes (the longest allowed) runs 60 agents; a longer one is refused up front,
/// naming the variable to change.
#[test]
fn a_long_runtime_dir_runs_or_is_refused_with_the_reason() {
    let _g = heavy();
    if !Path::new("/dev/shm").is_dir() {
        eprintln!("skipped: no /dev/shm");
        return;
    }
    let dir = scratch_dir("xdg");
    let file = dir.join("ring60.toml");
    std::fs::write(&file, null_ring(60)).unwrap();
    let pid = std::process::id() % 10_000_000;
    // `<xdg>/cohort/<16 hex>`: 18 + 7 + 17 = 42 bytes; then 30 + 24 = 54.
    for (xdg, runs) in [(format!("/dev/shm/cx{pid:07}"), true), (format!("/dev/shm/cohort-xdg-test{pid:07}"), false)] {
        std::fs::create_dir_all(&xdg).unwrap();
        std::fs::set_permissions(&xdg, std::os::unix::fs::PermissionsExt::from_mode(0o700)).unwrap();
        let run = dir.join(if runs { "runs" } else { "refused" });
        let o = orchestrator_command()
            .args(["launch", &file.display().to_string(), "--no-plots", "--out"])
            .arg(&run)
            .env("XDG_RUNTIME_DIR", &xdg)
            .output_within(cohort::RUN_LIMIT, "a launch with a private XDG_RUNTIME_DIR");
        no_panic(&xdg, &o);
        if runs {
            assert!(o.status.success(), "XDG_RUNTIME_DIR={xdg}: {}", describe_output(&o));
            assert_clean(&run);
        } else {
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
            assert!(err.contains("bytes long") && err.contains("set XDG_RUNTIME_DIR to a shorter"), "{err}");
        }
        let _ = std::fs::remove_dir_all(&xdg);
    }
}

/// A one-step run: each agent's only share is also the plant's first sample from it, and an
/// agent that left at once took that sample's iceoryx2 segment with it before the plant mapped it
/// (the run degraded: "agent 2 went silent: no share of step 0"). Agents now keep their ports
/// until the orchestrator's stop, sent when the plant is done.
#[test]
fn a_one_step_run_loses_no_share() {
    let (_g, dir) = heavy_scratch("onestep");
    let file = dir.join("ring50.toml");
    std::fs::write(&file, null_ring(50).replace("duration_s = 0.1", "duration_s = 0.01")).unwrap();
    for i in 0..2 {
        let run = dir.join(format!("run{i}"));
        let o = orchestrator_command()
            .args(["launch", &file.display().to_string(), "--no-plots", "--step-timeout", "20", "--out"])
            .arg(&run)
            .output_within(cohort::RUN_LIMIT, "one of the back-to-back launches");
        no_panic("one step", &o);
        assert!(o.status.success(), "{}", describe_output(&o));
        let s = summary(&run);
        assert_eq!(s["status"], "ok", "{}", s["error"]);
        assert_eq!(s["steps_completed"], 1);
        assert_clean(&run);
    }
}

/// A ring of `n` agents with the null plant and algorithm, 10 steps (`duration_s = 0.1`).
fn null_ring(n: u32) -> String {
    let mut text = format!(
        "[scenario]\nname = \"ring{n}\"\nseed = 3\ndt_s = 0.01\nduration_s = 0.1\n\n[plant]\nkind = \"null\"\n\
         readings = 3\n\n[algorithm]\nkind = \"null\"\nshare_values = 6\n",
    );
    for i in 1..=n {
        text.push_str(&format!("\n[[agents]]\nid = {i}\nneighbours = [{}, {}]\n", (i + n - 2) % n + 1, i % n + 1));
    }
    text
}

/// Finding 7: on a full disk the cause comes first, and no summary or status file is left empty.
#[test]
fn a_full_disk_is_reported_first_and_leaves_no_empty_json() {
    let (_g, dir) = heavy_scratch("full");
    let mnt = dir.join("mnt");
    std::fs::create_dir_all(&mnt).unwrap();
    let mounted = Command::new("mount").args(["-t", "tmpfs", "-o", "size=256k", "tmpfs"]).arg(&mnt).output();
    if !mounted.as_ref().is_ok_and(|o| o.status.success()) {
        eprintln!("skipped: cannot mount a small tmpfs here ({mounted:?})");
        return;
    }
    let o = orchestrator_command()
        .args(["launch", &repo_root().join("topologies/fig1-fixed.toml").display().to_string(), "--duration", "30"])
        .args(["--no-plots", "--out"])
        .arg(mnt.join("run"))
        .output_within(cohort::RUN_LIMIT, "a launch onto a full file system");
    let mut empty = Vec::new();
    for d in [mnt.join("run"), mnt.join("run/status")] {
        for f in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let name = f.file_name().to_string_lossy().to_string();
            if name.ends_with(".json") && f.metadata().is_ok_and(|m| m.len() == 0) {
                empty.push(f.path());
            }
        }
    }
    let _ = Command::new("umount").arg(&mnt).status();
    assert!(empty.is_empty(), "0-byte JSON left: {empty:?}");
    no_panic("full disk", &o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let first = err.lines().find(|l| l.starts_with("error:") || l.starts_with("warning:")).unwrap_or("");
    assert!(first.starts_with("error:") && first.contains("No space left on device"), "first: {first}\n{err}");
}

/// Finding 6: a run with `--authenticate` has the telemetry of one without, and rejects nothing.
#[test]
fn an_authenticated_run_has_the_same_telemetry_and_rejects_nothing() {
    let (_g, dir) = heavy_scratch("auth");
    let run = |tag: &str, extra: &[&str]| -> PathBuf {
        let out = dir.join(tag);
        let o = orchestrator_command()
            .args(["launch", &ring(), "--duration", "5", "--no-plots", "--out"])
            .arg(&out)
            .args(extra)
            .output_within(cohort::RUN_LIMIT, "a ring launch");
        assert!(o.status.success(), "{}", describe_output(&o));
        out
    };
    let plain = run("plain", &[]);
    let sealed = run("sealed", &["--authenticate"]);
    assert_eq!(telemetry_bits(&plain), telemetry_bits(&sealed));
    let s = summary(&sealed);
    assert_eq!(s["messages_rejected"].as_object().map(|m| m.values().filter_map(|v| v.as_u64()).sum::<u64>()), Some(0));
    assert_clean(&sealed);
}

/// Finding 1: after root has run, a second user runs too (each user has its own iceoryx2
/// directory), and its run's resources are its own.
#[test]
fn a_second_user_can_run_after_root() {
    let _g = heavy();
    // SAFETY: geteuid cannot fail.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("skipped: not root, so no second user to switch to");
        return;
    }
    let dir = std::env::temp_dir().join(format!("cohort-nobody-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let c = std::ffi::CString::new(dir.to_string_lossy().as_bytes()).unwrap();
    // SAFETY: chown of a directory this test created.
    assert_eq!(unsafe { libc::chown(c.as_ptr(), 65534, 65534) }, 0);
    let bin = cohort::bin_path("orchestrator");
    let o = Command::new("setpriv")
        .args(["--reuid=65534", "--regid=65534", "--clear-groups", "--"])
        .arg(&bin)
        .args(["launch", &ring(), "--duration", "1", "--no-plots", "--out"])
        .arg(dir.join("run"))
        .env_remove("XDG_RUNTIME_DIR")
        .current_dir(&dir)
        .output();
    let o = match o {
        Ok(o) if String::from_utf8_lossy(&o.stderr).starts_with("setpriv:") => {
            eprintln!("skipped: setpriv cannot switch to uid 65534: {}", String::from_utf8_lossy(&o.stderr));
            return;
        }
        Ok(o) => o,
        Err(e) => {
            eprintln!("skipped: setpriv is not available: {e}");
            return;
        }
    };
    no_panic("uid 65534", &o);
    assert!(o.status.success(), "{}", describe_output(&o));
    let leftover: Vec<_> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .filter(|e| std::os::unix::fs::MetadataExt::uid(&e.metadata().unwrap()) == 65534)
        .filter(|e| e.file_name().to_string_lossy().starts_with("cohort_"))
        .map(|e| e.path())
        .collect();
    assert!(leftover.is_empty(), "{leftover:?}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all("/dev/shm/cohort-65534");
    let _ = std::fs::remove_dir_all("/tmp/cohort-65534");
}

/// Finding 2: with two busy-loop hogs on the machine, the default waiting takes no more than
/// twice the time of blocking waits (before: 5× on this machine, `--wait adaptive` 15.9 s against
/// `event` 3.2 s). The bench's loaded row measures the same with the 1.2× goal.
#[test]
fn waiting_survives_two_cpu_hogs() {
    let (_g, dir) = heavy_scratch("loaded");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let hogs: Vec<_> = (0..2)
        .map(|_| {
            let stop = std::sync::Arc::clone(&stop);
            std::thread::spawn(move || {
                let mut x = 0u64;
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    x = std::hint::black_box(x.wrapping_add(1));
                }
            })
        })
        .collect();
    let wall = |wait: &str| {
        let out = dir.join(wait);
        let o = orchestrator_command()
            .args(["launch", &ring(), "--duration", "5", "--no-plots", "--wait", wait, "--out"])
            .arg(&out)
            .output_within(cohort::RUN_LIMIT, "a launch with a --wait strategy");
        assert!(o.status.success(), "{}", describe_output(&o));
        summary(&out)["wall_s"].as_f64().unwrap()
    };
    let (event, adaptive) = (wall("event"), wall("adaptive"));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    for h in hogs {
        h.join().unwrap();
    }
    assert!(adaptive <= 2.0 * event + 0.5, "under load: adaptive {adaptive:.2} s, event {event:.2} s");
}
