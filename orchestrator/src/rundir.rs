//! The run directory: `runs/<scenario>-<UTC time>/` (or `--out DIR`) with `scenario.toml`,
//! `telemetry/`, `timing/`, `status/`, `logs/`, `summary.json` and, after `report`, `plots/`.
//!
//! A run claims its directory before writing anything into it: `--out DIR` by creating
//! [`CLAIM`] inside it with `O_EXCL`, so of two launches into one directory exactly one gets it
//! and the other is refused (exit 2) before it has written a byte.

use std::path::{Path, PathBuf};

use cohort_runtime::record::RunDirs;

/// The file that marks a run directory as taken: created exclusively by the launch that claims
/// the directory; it stays (the directory is that run's from then on). Empty, so that on a nearly
/// full disk it costs no block and the disk's error comes where it did before.
pub const CLAIM: &str = ".cohort-run";

/// Create a fresh run directory. With `out`, that directory (which must be absent or empty and
/// is claimed atomically); otherwise `runs/<name>-<stamp>`, created atomically (a suffix is added
/// if two runs start in the same millisecond).
pub fn create(out: Option<&Path>, scenario_name: &str) -> Result<RunDirs, String> {
    let root = match out {
        Some(dir) => claim(dir)?,
        None => {
            std::fs::create_dir_all("runs").map_err(|e| format!("runs/: cannot create: {e}"))?;
            let base = format!("runs/{scenario_name}-{}", cohort_host::utc_stamp());
            let mut n = 0;
            loop {
                let candidate = if n == 0 { PathBuf::from(&base) } else { PathBuf::from(format!("{base}-{n}")) };
                match std::fs::create_dir(&candidate) {
                    Ok(()) => break candidate,
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 1000 => n += 1,
                    Err(e) => return Err(format!("{}: cannot create: {e}", candidate.display())),
                }
            }
        }
    };
    let dirs = RunDirs::new(root);
    dirs.create_all().map_err(|e| format!("{}: cannot create subdirectories: {e}", dirs.root.display()))?;
    Ok(dirs)
}

/// `--out DIR`: create it if missing, then take it by creating its claim file exclusively. The
/// emptiness check comes after the claim, so a launch that lost the race never reaches it, and
/// one that claimed a directory holding something else gives the claim back.
fn claim(dir: &Path) -> Result<PathBuf, String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!("--out {}: exists and is not a directory", dir.display()));
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("--out {}: cannot create: {e}", dir.display()))?;
    let claim = dir.join(CLAIM);
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&claim) {
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(format!(
                "--out {}: already claimed by another launch ({} exists); refusing to mix runs (give another --out)",
                dir.display(),
                CLAIM
            ));
        }
        Err(e) => return Err(format!("--out {}: cannot claim ({}): {e}", dir.display(), claim.display())),
    }
    let others = std::fs::read_dir(dir)
        .map_err(|e| format!("--out {}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .any(|e| e.file_name() != CLAIM);
    if others {
        let _ = std::fs::remove_file(&claim);
        return Err(format!("--out {}: directory exists and is not empty (refusing to mix runs)", dir.display()));
    }
    Ok(dir.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Of launches that claim one directory at the same instant, exactly one gets it, every time
    /// (before the claim, all of them passed the emptiness check together and shared the directory).
    #[test]
    fn of_simultaneous_claims_of_one_directory_exactly_one_wins() {
        let base = std::env::temp_dir().join(format!("cohort-rundir-claim-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        for round in 0..200 {
            let dir = base.join(format!("r{round}"));
            let barrier = std::sync::Barrier::new(4);
            let won: usize = std::thread::scope(|s| {
                let hs: Vec<_> = (0..4)
                    .map(|_| {
                        s.spawn(|| {
                            barrier.wait();
                            create(Some(&dir), "x").is_ok()
                        })
                    })
                    .collect();
                hs.into_iter().map(|h| usize::from(h.join().unwrap())).sum()
            });
            assert_eq!(won, 1, "round {round}: {won} launches got {}", dir.display());
        }
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_directory_holding_something_else_is_refused_and_left_unclaimed() {
        let dir = std::env::temp_dir().join(format!("cohort-rundir-full-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let e = create(Some(&dir), "x").unwrap_err();
        assert!(e.contains("not empty"), "{e}");
        assert!(!dir.join(CLAIM).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
