//! The campaign: list the cases, keep those `--only` chooses, build the namespace lab when a
//! chosen case crosses it, run every case `reps` times interleaved, aggregate, and write
//! `results.json` and `results.md`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use cohort_supervisor::netlab::{Lab, Links};

use super::cases::cases;
use super::loaded::{Hogs, loaded_markdown};
use super::mac::{mac_markdown, mac_ns};
use super::report::{machine, markdown};
use super::sample::sample;
use super::types::{Aggregate, Case, Sample, median};
use super::zenoh::{Rtt, lab_rtts, measure_rtt, start_lab, zenoh_markdown};
use super::{campaign, floor, python};

/// A directory removed with everything in it when dropped.
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Why the bench did not run to the end.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The arguments select nothing (exit 2).
    #[error("{0}")]
    Invalid(String),
    /// A case could not be set up or run (exit 1).
    #[error("{0}")]
    Failed(String),
    /// The network lab could not be set up or changed (exit 1).
    #[error(transparent)]
    Lab(#[from] cohort_supervisor::netlab::LabError),
}

impl cohort_runtime::exit::ToExitCode for BenchError {
    fn exit_code(&self) -> u8 {
        match self {
            Self::Invalid(_) => cohort_runtime::exit::INVALID,
            Self::Failed(_) | Self::Lab(_) => cohort_runtime::exit::FAILED,
        }
    }
}

impl From<String> for BenchError {
    fn from(e: String) -> Self {
        Self::Failed(e)
    }
}

/// Run every case (or only those whose key starts with `only`), `reps` times interleaved; each
/// run's directory kept under `keep` when given.
pub fn run(
    quick: bool,
    reps: u32,
    only: Option<&str>,
    out_dir: &Path,
    keep: Option<&Path>,
) -> Result<String, BenchError> {
    let repo = std::env::current_dir().map_err(|e| e.to_string())?;
    let scratch = std::env::temp_dir().join(format!("cohort-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    // Declared before the lab, so dropped after it (the lab writes under the scratch directory
    // until it is torn down), whichever way this function returns.
    let _scratch_guard = RemoveOnDrop(scratch.clone());
    // The cases are listed as if the lab were there, so that `--only` decides whether it is
    // built at all (it takes root, namespaces and seconds): only when a chosen case crosses it.
    let lab_dir = scratch.join("lab");
    let campaign_rows = match only {
        Some(p) if !campaign::may_choose(p) => Vec::new(),
        _ => campaign::measure(quick, reps, only, &scratch)?,
    };
    if campaign::only_these(only) {
        let md = format!("# Cohort bench (--only {})\n{}", only.unwrap_or(""), campaign::markdown(&campaign_rows));
        write_results(out_dir, &serde_json::json!({ "machine": machine(), "campaign": campaign_rows }), &md)?;
        return Ok(md);
    }
    let cases = choose(cases(quick, &repo, Some(lab_dir.as_path()), &scratch, only)?, only)?;
    let runs = RunsDir::new(keep, &scratch)?;
    let (cases, lab, rtts) = lab_and_rtts(cases, only)?;
    let started = Instant::now();
    let aggregates = measure(&cases, reps, &runs, lab.as_ref(), started)?;
    let links = lab.as_ref().map(|l| l.links());
    drop(lab);
    let floor = floor::measure_for(&aggregates, reps).map_err(|e| BenchError::Failed(e.to_string()))?;
    let mac = [6usize, 106, 512].map(|v| (v, mac_ns(v)));
    let mut md = markdown(&aggregates, quick, reps, only, started.elapsed().as_secs_f64());
    md.push_str(&loaded_markdown(&aggregates));
    md.push_str(&floor::markdown(&aggregates, &floor));
    md.push_str(&mac_markdown(&aggregates, &mac));
    md.push_str(&zenoh_markdown(&aggregates, &rtts, links));
    md.push_str(&python::markdown(&aggregates));
    md.push_str(&super::live::markdown(&aggregates));
    md.push_str(&campaign::markdown(&campaign_rows));
    let mut json = results_json(quick, reps, &aggregates, &rtts, links, &mac);
    json["campaign"] = serde_json::json!(campaign_rows);
    json["wake_floor"] = serde_json::json!(floor);
    write_results(out_dir, &json, &md)?;
    Ok(md)
}

/// The cases whose key starts with `only` (all without it); none is invalid input.
fn choose(mut cases: Vec<Case>, only: Option<&str>) -> Result<Vec<Case>, BenchError> {
    if let Some(prefix) = only {
        let mut all: Vec<String> = cases.iter().map(|c| c.key.clone()).collect();
        if !python::may_choose(prefix) {
            all.push(format!("{}…", python::KEY_PREFIX));
        }
        all.push(format!("{}…", campaign::KEY_PREFIX));
        cases.retain(|c| c.key.starts_with(prefix));
        if cases.is_empty() {
            return Err(BenchError::Invalid(format!(
                "--only {prefix:?}: no case key starts with it (keys: {})",
                all.join(", ")
            )));
        }
    }
    Ok(cases)
}

/// The cases left to run, the namespace lab (if built) and the round trips measured.
type CasesAndLab = (Vec<Case>, Option<Lab>, Vec<Rtt>);

/// The namespace lab when a chosen case crosses it (the cases that cross it dropped when none
/// can be made here), and the round trips measured before the runs.
fn lab_and_rtts(mut cases: Vec<Case>, only: Option<&str>) -> Result<CasesAndLab, BenchError> {
    let wants_lab = cases.iter().any(|c| c.lab.is_some());
    let (lab, veth_rtt) = if wants_lab {
        start_lab()
    } else {
        tracing::info!("no chosen case crosses the network-namespace lab: not building it");
        (None, None)
    };
    if lab.is_none() && wants_lab {
        cases.retain(|c| c.lab.is_none());
        if cases.is_empty() {
            return Err(BenchError::Failed(format!(
                "--only {:?}: every chosen case crosses the network-namespace lab, which cannot be made here",
                only.unwrap_or("")
            )));
        }
    }
    let mut rtts = vec![measure_rtt(None, "one host (TCP loopback)", Some("zenoh"))?];
    rtts.extend(veth_rtt);
    if let Some(l) = &lab {
        rtts.extend(lab_rtts(l)?);
    }
    Ok((cases, lab, rtts))
}

/// Where the runs' directories go: the scratch directory (each removed once measured), or the
/// directory `--keep-runs` names (created owner-only if missing; each kept).
struct RunsDir {
    root: PathBuf,
    keep: bool,
}

impl RunsDir {
    fn new(keep: Option<&Path>, scratch: &Path) -> Result<Self, BenchError> {
        let Some(dir) = keep else { return Ok(Self { root: scratch.to_path_buf(), keep: false }) };
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(dir)
            .map_err(|e| BenchError::Invalid(format!("--keep-runs {}: {e}", dir.display())))?;
        Ok(Self { root: dir.to_path_buf(), keep: true })
    }
    fn for_run(&self, key: &str, rep: u32) -> PathBuf {
        self.root.join(format!("{}-{rep}", key.replace(['/', '='], "_")))
    }
    fn done(&self, dir: &Path) {
        if self.keep {
            tracing::info!("kept: {}", dir.display());
        } else {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// Every case once per repetition (interleaved, so slow phases of a shared machine hit all),
/// each run's directory removed after it unless kept; the aggregates in the cases' order.
fn measure(
    cases: &[Case],
    reps: u32,
    runs: &RunsDir,
    lab: Option<&Lab>,
    started: Instant,
) -> Result<Vec<Aggregate>, BenchError> {
    let mut samples: BTreeMap<String, Vec<Sample>> = BTreeMap::new();
    for rep in 0..reps {
        for c in cases {
            let dir = runs.for_run(&c.key, rep);
            let smp = run_case(c, rep, &dir, lab)?;
            tracing::info!(
                "[{:6.1} s] rep {}/{reps} {:32} {:9.0} steps/s  round p50 {:8.1} µs  max {:7.2} ms",
                started.elapsed().as_secs_f64(),
                rep + 1,
                c.key,
                smp.steps_per_s,
                smp.round_p50_us,
                smp.round_max_ms
            );
            samples.entry(c.key.clone()).or_default().push(smp);
            runs.done(&dir);
        }
    }
    Ok(cases.iter().map(|c| aggregate(c, samples.remove(&c.key).unwrap_or_default())).collect())
}

/// One run of a case in `dir`: with hogs for the loaded rows, with the lab's delay set for a
/// lab row (and cleared after it).
fn run_case(c: &Case, rep: u32, dir: &Path, lab: Option<&Lab>) -> Result<Sample, BenchError> {
    let dirs = crate::prepare(&c.scenario, Some(dir)).map_err(|_| format!("{}: cannot prepare", dir.display()))?;
    let hogs = c.hogs.then(Hogs::start);
    if let (Some(l), Some(delay)) = (lab, c.lab) {
        l.set_delay(delay)?;
    }
    let clients = super::live::clients(c.live)?;
    let (outcome, summary) = crate::run_once(&c.scenario, &dirs, c.reference, false);
    for client in clients {
        client.stop();
    }
    if let (Some(l), Some(_)) = (lab, c.lab) {
        l.set_delay(Duration::ZERO)?;
    }
    drop(hogs);
    if let Some(e) = outcome.error {
        return Err(BenchError::Failed(format!("{} (repetition {}): {e}", c.key, rep + 1)));
    }
    Ok(sample(&c.scenario, dir, &summary, outcome.wall_s))
}

/// A case's samples with their median, least and greatest steps/s and median wall time.
fn aggregate(c: &Case, s: Vec<Sample>) -> Aggregate {
    let mut sps: Vec<f64> = s.iter().map(|x| x.steps_per_s).collect();
    let mut wall: Vec<f64> = s.iter().map(|x| x.wall_s).collect();
    Aggregate {
        key: c.key.clone(),
        group: c.group.into(),
        label: c.label.clone(),
        n: c.n,
        variant: c.variant.clone(),
        steps_per_s_median: median(&mut sps.clone()),
        steps_per_s_min: sps.iter().cloned().fold(f64::INFINITY, f64::min),
        steps_per_s_max: {
            sps.sort_by(f64::total_cmp);
            sps.last().copied().unwrap_or(f64::NAN)
        },
        wall_s_median: median(&mut wall),
        samples: s,
    }
}

/// What `results.json` holds: the machine, every sample, the round trips, the lab's links, the
/// MAC costs and the adaptive spin bounds.
fn results_json(
    quick: bool,
    reps: u32,
    aggregates: &[Aggregate],
    rtts: &[Rtt],
    links: Option<Links>,
    mac: &[(usize, (f64, f64))],
) -> serde_json::Value {
    serde_json::json!({
        "machine": machine(),
        "quick": quick,
        "repetitions": reps,
        "cases": aggregates,
        "zenoh_rtt": rtts,
        "lab_links": links.map(|l| l.describe()),
        "mac_seal_check_ns": mac.iter().map(|(v, (s, c))| serde_json::json!({"values": v, "seal_ns": s, "check_ns": c})).collect::<Vec<_>>(),
        "adaptive_spin_floor_us": cohort_runtime::drive::ADAPTIVE_FLOOR_US,
        "adaptive_spin_cap_us": cohort_runtime::drive::ADAPTIVE_CAP_US,
    })
}

/// `results.json` and `results.md` in `out_dir`.
fn write_results(out_dir: &Path, json: &serde_json::Value, md: &str) -> Result<(), String> {
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let write = |name: &str, text: String| -> Result<PathBuf, String> {
        let p = out_dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        Ok(p)
    };
    write("results.json", serde_json::to_string_pretty(json).map_err(|e| e.to_string())? + "\n")?;
    write("results.md", md.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::PermissionsExt;

    use super::*;

    #[test]
    fn a_runs_directory_is_removed_once_measured_unless_kept_owner_only() {
        let base = std::env::temp_dir().join(format!("cohort-bench-runs-test-{}", std::process::id()));
        let _clean = RemoveOnDrop(base.clone());
        let scratch = base.join("scratch");
        let removed = RunsDir::new(None, &scratch).unwrap();
        let dir = removed.for_run("zenoh/fig1/N=6/zenoh-3ns", 1);
        assert_eq!(dir, scratch.join("zenoh_fig1_N_6_zenoh-3ns-1"));
        std::fs::create_dir_all(dir.join("timing")).unwrap();
        removed.done(&dir);
        assert!(!dir.exists());
        let keep = base.join("kept/runs");
        let kept = RunsDir::new(Some(&keep), &scratch).unwrap();
        assert_eq!(std::fs::metadata(&keep).unwrap().permissions().mode() & 0o777, 0o700);
        let dir = kept.for_run("ring/N=6/poll", 0);
        std::fs::create_dir_all(dir.join("timing")).unwrap();
        kept.done(&dir);
        assert!(dir.join("timing").is_dir());
        // A --keep-runs path that cannot be a directory is invalid input, named.
        std::fs::write(base.join("file"), b"").unwrap();
        let e = RunsDir::new(Some(&base.join("file")), &scratch).err().expect("a file is no directory");
        assert!(matches!(&e, BenchError::Invalid(m) if m.contains("--keep-runs") && m.contains("file")), "{e}");
    }
}
