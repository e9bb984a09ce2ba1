//! The run directory: `runs/<scenario>-<UTC time>/` (or `--out DIR`) with `scenario.toml`,
//! `telemetry/`, `timing/`, `status/`, `logs/`, `summary.json` and, after `report`, `plots/`.

use std::path::{Path, PathBuf};

use cohort_runtime::record::RunDirs;

/// Create a fresh run directory. With `out`, that directory (which must be absent or empty);
/// otherwise `runs/<name>-<stamp>`, claimed atomically (a suffix is added if two runs start in
/// the same millisecond).
pub fn create(out: Option<&Path>, scenario_name: &str) -> Result<RunDirs, String> {
    let root = match out {
        Some(dir) => {
            if dir.exists() {
                let empty =
                    std::fs::read_dir(dir).map_err(|e| format!("--out {}: {e}", dir.display()))?.next().is_none();
                if !empty {
                    return Err(format!(
                        "--out {}: directory exists and is not empty (refusing to mix runs)",
                        dir.display()
                    ));
                }
            } else {
                std::fs::create_dir_all(dir).map_err(|e| format!("--out {}: cannot create: {e}", dir.display()))?;
            }
            dir.to_path_buf()
        }
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
