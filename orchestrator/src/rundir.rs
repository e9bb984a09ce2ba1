//! The run directory: `runs/<scenario>-<UTC time>/` (or `--out DIR`) with `scenario.toml`,
//! `telemetry/`, `timing/`, `status/`, `logs/`, `summary.json` and, after `report`, `plots/`.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use cohort_runtime::record::RunDirs;

/// `YYYYMMDDTHHMMSS.mmmZ` for the current UTC time.
pub fn utc_stamp() -> String {
    let d = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
    let secs = d.as_secs() as i64;
    let (days, sod) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}{month:02}{day:02}T{:02}{:02}{:02}.{:03}Z",
        sod / 3600,
        (sod / 60) % 60,
        sod % 60,
        d.subsec_millis()
    )
}

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
            let base = format!("runs/{scenario_name}-{}", utc_stamp());
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
