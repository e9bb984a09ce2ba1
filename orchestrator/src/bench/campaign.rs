//! The campaign rows: cases per second of `orchestrator campaign` on the headline fig1 scenario
//! (its own `[[dispersions]]`, whole 360 s cases; `--quick`: 20 s), in-process and as processes, on 1 and 2 workers,
//! interleaved repetitions; the 2-worker / 1-worker ratio of each (goal ≥ 1.8 on 2 cores); and
//! spread over three host daemons of the network lab (`--hosts`, each daemon 2 workers: three
//! namespaces of this one machine, so the row measures what the farm costs against the local
//! 2 workers, not more cores). Each run is this binary's own `campaign` command in a child
//! process, as a user runs it.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use cohort_supervisor::netlab::{CASE_WORKERS, Lab};

use super::types::median;

pub(super) const KEY_PREFIX: &str = "campaign/";
/// The mode of the rows spread over the lab's daemons.
const HOSTS: &str = "3-namespaces";
/// The lab's daemons the rows use: three (the lab has four; the rows measured since the
/// campaign farm was built used three, and a fourth would only add workers on the same cores).
const LAB_HOSTS: usize = 3;
/// Their workers together.
const LAB_WORKERS: u32 = LAB_HOSTS as u32 * CASE_WORKERS;
const SCENARIO: &str = "topologies/fig1.toml";

/// Whether `--only prefix` may choose a campaign row.
pub(super) fn may_choose(prefix: &str) -> bool {
    prefix.starts_with(KEY_PREFIX) || KEY_PREFIX.starts_with(prefix)
}

/// Whether `--only prefix` chooses campaign rows and nothing else.
pub(super) fn only_these(prefix: Option<&str>) -> bool {
    prefix.is_some_and(|p| p.starts_with(KEY_PREFIX))
}

#[derive(Debug, serde::Serialize)]
pub(super) struct Row {
    pub key: String,
    pub mode: &'static str,
    pub workers: u32,
    pub cases: u32,
    /// The cases' length, s (None: the scenario's own).
    pub duration_s: Option<f64>,
    /// One per repetition.
    pub cases_per_s: Vec<f64>,
}

/// Every row, `reps` times interleaved, each campaign's directory under `scratch` removed after it.
pub(super) fn measure(quick: bool, reps: u32, only: Option<&str>, scratch: &Path) -> Result<Vec<Row>, String> {
    let (cases, duration_s) = if quick { (4, Some(20.0)) } else { (4, None) };
    let mut rows: Vec<Row> = Vec::new();
    for mode in ["reference", "multi-process", HOSTS] {
        for workers in if mode == HOSTS { [LAB_WORKERS].as_slice() } else { [1, 2].as_slice() } {
            let key = format!("{KEY_PREFIX}fig1/{mode}/W={workers}");
            if only.is_none_or(|p| key.starts_with(p)) {
                let cases = if mode == HOSTS { 2 * cases } else { cases };
                rows.push(Row { key, mode, workers: *workers, cases, duration_s, cases_per_s: Vec::new() });
            }
        }
    }
    // The lab needs root (network namespaces): without it the row is left out, saying why.
    let lab = if rows.iter().any(|r| r.mode == HOSTS) {
        match Lab::start().and_then(|lab| Lab::bare_hosts_file(scratch, LAB_HOSTS).map(|f| (lab, f))) {
            Ok(l) => Some(l),
            Err(e) => {
                tracing::warn!("campaign over three namespaces left out: the network lab: {e}");
                rows.retain(|r| r.mode != HOSTS);
                None
            }
        }
    } else {
        None
    };
    let exe = std::env::current_exe().map_err(|e| format!("the orchestrator's own path: {e}"))?;
    for rep in 0..reps {
        for r in &mut rows {
            let out = scratch.join(format!("campaign-{}-{rep}", r.key.replace(['/', '='], "_")));
            let mut cmd = std::process::Command::new(&exe);
            cmd.args(["-q", "campaign", SCENARIO, "--no-plots", "--cases", &r.cases.to_string()]);
            if let Some(d) = r.duration_s {
                cmd.args(["--duration", &d.to_string()]);
            }
            match (&lab, r.mode) {
                (Some((_, hosts)), HOSTS) => cmd.arg("--hosts").arg(hosts),
                _ => cmd.args(["--workers", &r.workers.to_string()]),
            };
            cmd.arg("--out").arg(&out);
            if r.mode == "multi-process" {
                cmd.arg("--multi-process");
            }
            let started = Instant::now();
            let o = cmd.output().map_err(|e| format!("{}: {e}", r.key))?;
            let wall_s = started.elapsed().as_secs_f64();
            let _ = std::fs::remove_dir_all(&out);
            if !o.status.success() {
                return Err(format!(
                    "{} (repetition {}): {}",
                    r.key,
                    rep + 1,
                    String::from_utf8_lossy(&o.stderr).trim()
                ));
            }
            r.cases_per_s.push(f64::from(r.cases) / wall_s);
            tracing::info!("rep {}/{reps} {:32} {:7.2} cases/s", rep + 1, r.key, f64::from(r.cases) / wall_s);
        }
    }
    Ok(rows)
}

/// The rows' section: cases/s per mode and workers, and the 2 / 1 worker ratio per repetition.
pub(super) fn markdown(rows: &[Row]) -> String {
    let Some(first) = rows.first() else { return String::new() };
    let mut md = format!(
        "\n## Monte Carlo campaign: fig1, cases of {}, cases per second\n\n| mode | workers | cases | cases/s (median) | min – max |\n|---|---|---|---|---|\n",
        first.duration_s.map_or("360 s (the scenario's)".to_string(), |d| format!("{d} s"))
    );
    for r in rows {
        let lo = r.cases_per_s.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = r.cases_per_s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} | {lo:.3} – {hi:.3} |",
            r.mode,
            r.workers,
            r.cases,
            median(&mut r.cases_per_s.clone())
        );
    }
    for mode in ["reference", "multi-process"] {
        let of = |w: u32| rows.iter().find(|r| r.mode == mode && r.workers == w);
        if let (Some(one), Some(two)) = (of(1), of(2)) {
            let ratios: Vec<f64> = two.cases_per_s.iter().zip(&one.cases_per_s).map(|(b, a)| b / a).collect();
            let m = median(&mut ratios.clone());
            let _ = writeln!(
                md,
                "\n{mode}: 2 workers / 1 worker, median {m:.2} (per repetition: {}); goal ≥ 1.8: {}.",
                ratios.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", "),
                if m >= 1.8 { "met" } else { "not met" }
            );
        }
    }
    let local = rows.iter().find(|r| r.mode == "reference" && r.workers == 2);
    if let (Some(local), Some(lab)) = (local, rows.iter().find(|r| r.mode == HOSTS)) {
        let ratios: Vec<f64> = lab.cases_per_s.iter().zip(&local.cases_per_s).map(|(b, a)| b / a).collect();
        let _ = writeln!(
            md,
            "\n{HOSTS} ({} daemons of {} workers on this machine's cores) / reference on 2 workers: median {:.2} \
             (per repetition: {}); the cost of sending cases to daemons, not a speed-up (one machine).",
            LAB_HOSTS,
            CASE_WORKERS,
            median(&mut ratios.clone()),
            ratios.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", ")
        );
    }
    md
}
