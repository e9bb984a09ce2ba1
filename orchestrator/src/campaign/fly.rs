//! One case flown to its [`Outcome`] — on this machine (a worker of the campaign) or on a host
//! daemon's (`campaign --hosts`, through [`super::serve`]): the same function either way, so a
//! case's row does not depend on where it ran.

use std::path::Path;

use cohort_runtime::paper::Setup;

use super::CaseError;
use super::row::{Outcome, VerdictCell};
use crate::launcher::How;

/// Fly `setup` in the run directory `dir` (made here; a leftover of an interrupted try is removed
/// first) and keep its telemetry only if asked.
pub fn fly(setup: &Setup, dir: &Path, how: How, keep_telemetry: bool) -> Result<Outcome, CaseError> {
    fly_with_summary(setup, dir, how, keep_telemetry).map(|(outcome, _)| outcome)
}

/// [`fly`], with the run's summary (what `summary.json` holds) for a caller that reads more of it.
pub fn fly_with_summary(
    setup: &Setup,
    dir: &Path,
    how: How,
    keep_telemetry: bool,
) -> Result<(Outcome, crate::summary::Summary), CaseError> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(|e| CaseError::Io(format!("{}: {e}", dir.display())))?;
    }
    let dirs = crate::prepare(setup, Some(dir)).map_err(|e| CaseError::Io(e.to_string()))?;
    let (outcome, summary) = crate::launcher::run_once_as(setup, &dirs, how, false);
    if outcome.status.is_interrupted() {
        return Err(CaseError::Interrupted);
    }
    if !keep_telemetry {
        dirs.remove_bulk();
    }
    let verdict = summary
        .verdict
        .iter()
        .map(|v| VerdictCell {
            name: v.name.clone(),
            verdict: serde_json::to_value(v.verdict)
                .ok()
                .and_then(|j| j.as_str().map(String::from))
                .unwrap_or_default(),
            ours: v.ours.map(f64::to_bits),
            unit: v.unit.clone(),
        })
        .collect();
    let outcome = Outcome {
        status: summary.status.as_str().to_string(),
        error: outcome.error.clone(),
        metrics: summary.metrics.iter().map(|(k, v)| (k.clone(), v.to_bits())).collect(),
        verdict,
        verdict_overall: summary.verdict_overall.unwrap_or("n/a").to_string(),
        wall_s: outcome.wall_s,
    };
    Ok((outcome, summary))
}
