//! A run is its user's own (issue 18, finding 1): every shared-memory segment of a run is
//! owner-only, iceoryx2's management segment included; the run's files live under a per-user
//! directory nobody else can enter; the stale-run sweep removes only runs whose orchestrator is
//! provably gone (its flock is free), never a live one whatever files lie about.
//!
//! The second-user checks run a command as uid 65534 with `setpriv`; where that is not permitted
//! they print why and skip.

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::Path;
use std::process::Command;

use cohort_wire::transport::Topology;
use cohort_wire::transport::iox::{IoxData, IoxRun, IoxServices, check_private_dir, ensure_user_base, user_base};

fn fresh_run_id() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(1);
    (u64::from(std::process::id()) << 20) ^ 0xB0_0000_0000_0000 ^ N.fetch_add(1, Ordering::SeqCst)
}

fn segments(run: &IoxRun) -> Vec<std::path::PathBuf> {
    let prefix = run.prefix();
    std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .map(|e| e.path())
        .collect()
}

fn mode(p: &Path) -> u32 {
    std::fs::symlink_metadata(p).unwrap().permissions().mode() & 0o7777
}

/// Run `sh -c script` as uid/gid 65534; None (with the reason printed) where setpriv cannot.
fn as_nobody(script: &str) -> Option<std::process::Output> {
    let out = Command::new("setpriv")
        .args(["--reuid=65534", "--regid=65534", "--clear-groups", "--", "sh", "-c", script])
        .output();
    match out {
        Ok(o) if o.status.code() == Some(127) || String::from_utf8_lossy(&o.stderr).contains("setpriv:") => {
            eprintln!("skipped: setpriv cannot switch to uid 65534 here: {}", String::from_utf8_lossy(&o.stderr));
            None
        }
        Ok(o) => Some(o),
        Err(e) => {
            eprintln!("skipped: setpriv is not available: {e}");
            None
        }
    }
}

#[test]
fn every_segment_of_a_run_is_owner_only_and_its_directory_private() {
    let run = IoxRun::new(fresh_run_id());
    let claim = run.claim().unwrap();
    let topo = Topology { neighbours: vec![vec![2], vec![1]] };
    let services = IoxServices::create(&run, &topo, 0).unwrap();
    let plant = IoxData::open(&run, &topo, cohort_wire::transport::Proc::Plant).unwrap();
    let segs = segments(&run);
    assert!(segs.len() > 10, "{segs:?}");
    let mgmt: Vec<_> = segs.iter().filter(|p| p.to_string_lossy().ends_with("global_mgmt")).collect();
    assert_eq!(mgmt.len(), 1, "iceoryx2's management segment: {segs:?}");
    for p in &segs {
        assert_eq!(mode(p) & 0o077, 0, "{} is mode {:04o}", p.display(), mode(p));
    }
    let base = user_base();
    assert_eq!(mode(&base), 0o700, "{}", base.display());
    assert_eq!(std::fs::metadata(&base).unwrap().uid(), unsafe { libc::geteuid() });
    assert!(run.root_dir().starts_with(&base));
    // A second user can neither write the management segment nor look into the base directory.
    let script =
        format!("printf 'xxxxxxxxxxxxxxxx' > {} || exit 3; ls {} || exit 4; exit 0", mgmt[0].display(), base.display());
    if let Some(o) = as_nobody(&script) {
        assert_eq!(o.status.code(), Some(3), "uid 65534 wrote the management segment: {o:?}");
    }
    if let Some(o) = as_nobody(&format!("ls {} >/dev/null 2>&1 && exit 0; exit 4", base.display())) {
        assert_eq!(o.status.code(), Some(4), "uid 65534 listed {}", base.display());
    }
    drop(plant);
    drop(services);
    run.remove_all_resources();
    drop(claim);
    assert!(segments(&run).is_empty());
}

#[test]
fn the_sweep_removes_a_run_whose_orchestrator_is_gone_and_never_a_live_one() {
    let live = IoxRun::new(fresh_run_id());
    let live_claim = live.claim().unwrap();
    let topo = Topology { neighbours: vec![vec![2], vec![1]] };
    let live_services = IoxServices::create(&live, &topo, 0).unwrap();
    // A dead run: its lock file is there but nobody holds the lock (its orchestrator was
    // SIGKILLed: the kernel released the flock), its segments are still there.
    let dead = IoxRun::new(fresh_run_id());
    let dead_claim = dead.claim().unwrap();
    let dead_services = IoxServices::create(&dead, &topo, 0).unwrap();
    drop(dead_services);
    let lock = user_base().join(format!("{:016x}.lock", dead.run_id));
    // Dropping the claim removes its lock file; put an unlocked one back, as a killed
    // orchestrator leaves it.
    drop(dead_claim);
    std::fs::write(&lock, "").unwrap();
    let before = live.count_resources();
    assert!(!segments(&dead).is_empty());
    let swept = IoxRun::sweep_stale();
    assert!(swept.contains(&dead.run_id), "{swept:?}");
    assert!(!swept.contains(&live.run_id), "a live run was swept");
    assert!(segments(&dead).is_empty() && !dead.root_dir().exists() && !lock.exists());
    assert_eq!(live.count_resources(), before, "the live run lost resources");
    // A forged file cannot make a live run look dead: its lock is held.
    std::fs::write(user_base().join(format!("{:016x}.lock", live.run_id)), "1").ok();
    assert!(!IoxRun::sweep_stale().contains(&live.run_id));
    assert_eq!(live.count_resources(), before);
    drop(live_services);
    live.remove_all_resources();
    drop(live_claim);
}

#[test]
fn a_directory_someone_else_owns_or_can_enter_is_refused_with_the_reason() {
    let dir = std::env::temp_dir().join(format!("cohort-private-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    let e = check_private_dir(&dir).unwrap_err();
    assert!(e.contains("mode 0755") && e.contains("chmod 700"), "{e}");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
    assert_eq!(check_private_dir(&dir), Ok(()));
    let link = dir.with_extension("link");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&dir, &link).unwrap();
    assert!(check_private_dir(&link).unwrap_err().contains("symlink"));
    // SAFETY: chown of a directory this test created.
    let c = std::ffi::CString::new(dir.to_string_lossy().as_bytes()).unwrap();
    if unsafe { libc::chown(c.as_ptr(), 65534, 65534) } == 0 {
        let e = check_private_dir(&dir).unwrap_err();
        assert!(e.contains("belongs to uid 65534"), "{e}");
    } else {
        eprintln!("skipped the foreign-owner case: chown is not permitted here");
    }
    let _ = std::fs::remove_file(&link);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(ensure_user_base().is_ok());
    // Leave no empty base behind (a run in another test keeps it: rmdir refuses then).
    let _ = std::fs::remove_dir(user_base());
}
