//! What the tables and the readings study share: one measured run ([`Run`]), the scenario
//! variants they run ([`variant`], [`edited`]), and the published Table 4 values both compare with.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cohort_host::{Launcher, Mode, RunOptions};
use cohort_runtime::paper::{Setup, table_of};

use crate::config::{DaiAttitude, Law};

/// Table 4 (Sec. 3.3): original, then specific at r = 0.5, 1, 2, 4.
pub(crate) const T4_R: [f64; 4] = [0.5, 1.0, 2.0, 4.0];
pub(crate) const T4_PARAM_MEAN: [f64; 5] = [0.0247, 0.0351, 0.0348, 0.0345, 0.0341];
pub(crate) const T4_PARAM_DEV: [f64; 5] = [0.0124, 0.0306, 0.0272, 0.0239, 0.0217];
pub(crate) const T4_TRACK_MEAN: [f64; 5] = [-0.0401, -0.0033, -0.0033, -0.0033, -0.0034];
pub(crate) const T4_TRACK_DEV: [f64; 5] = [0.1761, 0.0296, 0.0246, 0.0189, 0.0143];
/// One measured run.
#[derive(Clone)]
pub(crate) struct Run {
    pub(crate) label: String,
    pub(crate) law: String,
    pub(crate) r: f64,
    pub(crate) period_s: Option<f64>,
    pub(crate) dir: PathBuf,
    pub(crate) metrics: BTreeMap<String, f64>,
    pub(crate) wall_s: f64,
    /// Why the run ended early (a diverged sampled-data loop sends a non-finite command, which
    /// the plant rejects; the run then ends on the step timeout). Metrics cover the rows written.
    pub(crate) failed: Option<String>,
}

impl Run {
    pub(crate) fn m(&self, k: &str) -> f64 {
        self.metrics.get(k).copied().unwrap_or(f64::NAN)
    }
}

pub(crate) fn variant(
    launcher: &dyn Launcher,
    base: &Setup,
    name: &str,
    law: Law,
    r: f64,
    dt_s: Option<f64>,
) -> Result<Setup, String> {
    let mut a = base
        .algorithm_as::<DaiAttitude>()
        .ok_or(format!("{}: not a dai-attitude scenario", base.scenario.name))?
        .clone();
    a.law = law;
    a.r = r;
    if law != Law::Specific {
        a.specific_torque = None;
    }
    edited(launcher, base, name, &a, dt_s)
}

/// `base` with algorithm `a` (and step `dt_s`), named `name`, validated like a file.
pub(crate) fn edited(
    launcher: &dyn Launcher,
    base: &Setup,
    name: &str,
    a: &DaiAttitude,
    dt_s: Option<f64>,
) -> Result<Setup, String> {
    let mut s = base.parsed.clone();
    s.scenario.name = name.to_string();
    if let Some(dt) = dt_s {
        s.scenario.dt_s = dt;
    }
    s.algorithm.body = table_of(a).map_err(|e| e.to_string())?;
    // A diverged loop ends on the step timeout: keep that short.
    s.run.step_timeout_s = s.run.step_timeout_s.min(2.0);
    // Whether a variant diverges is what the tables measure, not what its run expects.
    s.scenario.expect = cohort_scenario::Expect::Complete;
    launcher.configure(s, name).map_err(|e| e.to_string())
}

pub(crate) fn run(
    launcher: &dyn Launcher,
    s: &Setup,
    root: &Path,
    label: &str,
    multi_process: bool,
) -> Result<Run, String> {
    let dir = root.join("runs").join(&s.scenario.name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let mode = if multi_process { Mode::MultiProcess } else { Mode::Reference };
    let outcome = launcher.run(s, &dir, RunOptions { mode, plots: false }).map_err(|e| e.to_string())?;
    if outcome.status.is_interrupted() {
        return Err(format!("{label}: interrupted"));
    }
    let failed = outcome.error.as_ref().map(|e| {
        let t = outcome.metric("final_time_s");
        let rejected = outcome.messages_rejected.get("non_finite").copied().unwrap_or(0);
        if rejected > 0 {
            format!("diverged: non-finite command after t = {t:.3} s")
        } else {
            format!("failed after t = {t:.3} s: {e}")
        }
    });
    if failed.is_some() && !outcome.metrics.contains_key("tracking_error_dev") {
        return Err(format!(
            "{label}: {} (run directory {})",
            outcome.error.clone().unwrap_or_default(),
            dir.display()
        ));
    }
    let a = s.algorithm_as::<DaiAttitude>().ok_or("checked by variant")?;
    tracing::info!(
        "  {label}: {:.2} s wall ({}){}",
        outcome.wall_s,
        outcome.mode,
        failed.as_ref().map(|f| format!(" — {f}")).unwrap_or_default()
    );
    Ok(Run {
        label: label.to_string(),
        law: a.law.name().to_string(),
        r: a.r,
        period_s: (!a.is_continuous()).then_some(s.scenario.dt_s),
        dir,
        metrics: outcome.metrics,
        wall_s: outcome.wall_s,
        failed,
    })
}

pub(crate) fn g(x: f64) -> String {
    if x.is_nan() {
        "—".into()
    } else if x == 0.0 {
        "0".into()
    } else if x.abs() >= 1e-3 && x.abs() < 1e3 {
        format!("{x:.4}")
    } else {
        format!("{x:.3e}")
    }
}

/// "+12 %" relative difference of measured to published.
pub(crate) fn rel(measured: f64, published: f64) -> String {
    if published == 0.0 || !measured.is_finite() {
        return "—".into();
    }
    format!("{:+.0} %", 100.0 * (measured - published) / published.abs())
}
