//! What the orchestrator asks of one run — its analysis, the effect of its faults, its verdict, its
//! figures, its live scene, a sweep's criterion — declared on the kinds the run is made of.
//!
//! A paper lists [`KindHooks`]: "runs of plant kind `vtxo` flying algorithm kind `vtxo-handoff`
//! are served by these hooks". The registry picks every entry that serves a run by its kind names
//! ([`KindHooks::serves`]), so no paper looks at a setup's types to find out which of its
//! sub-systems a run belongs to; each [`RunHooks`] reads the typed configuration it was declared
//! for.

use std::path::Path;

use cohort_report::FigureSource;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::{RunDirs, TimelineEvent};

use crate::verdict::{VerdictInput, VerdictLine};
use crate::{Metrics, SceneBody};

/// A finished (or partial) run as a paper's analysis sees it.
pub struct RunView<'a> {
    pub setup: &'a Setup,
    pub dirs: &'a RunDirs,
}

/// Why a run's analysis could not be made from its telemetry (a file, column or row missing, steps
/// that do not line up): the paper's reason, which the summary carries as a warning.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct AnalysisError(pub String);

impl From<String> for AnalysisError {
    fn from(reason: String) -> Self {
        Self(reason)
    }
}

/// The host side of the runs of some kinds. Every method has a default that adds nothing.
pub trait RunHooks: Sync {
    /// Summary metrics computed after a run from its telemetry alone (so they are the same for
    /// the multi-process and the reference run); may also write joined series to `derived/`.
    /// Called also after a failed run, on what was written.
    fn analyse(&self, _run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(Metrics::new())
    }
    /// The effect of each fault of `timeline` on the paper's headline metric (called after
    /// [`RunHooks::analyse`], only when faults were carried out).
    fn fault_effects(&self, _run: &RunView<'_>, _timeline: &[TimelineEvent]) -> Result<Metrics, AnalysisError> {
        Ok(Metrics::new())
    }
    /// The run against the paper: one line per published bound or value the run speaks to (the
    /// paper's number, ours from `input.metrics`, pass / fail / n/a), called after the analysis.
    fn verdict(&self, _input: &VerdictInput<'_>) -> Vec<VerdictLine> {
        Vec::new()
    }
    /// The paper's figures of the run of `setup` in `run_dir` (drawn before the generic ones).
    fn figures(&self, _setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        None
    }
    /// The bodies of a live 3-D view of a run of `setup` (`launch --live`): which telemetry
    /// columns place each one. None: the live view has telemetry, roster and progress only.
    fn scene(&self, _setup: &Setup) -> Vec<SceneBody> {
        Vec::new()
    }
    /// A section of `orchestrator sweep`'s Markdown: the paper's published criterion checked on
    /// each seed's summary metrics (`rows`: seed, metrics, in the order run), appended after the
    /// sweep's generic tables.
    fn sweep_section(&self, _setup: &Setup, _rows: &[(u64, Metrics)]) -> Option<String> {
        None
    }
}

/// Which runs a [`RunHooks`] serves: those whose plant kind is `plant` (when set) and whose
/// algorithm kind is `algorithm` (when set). At least one is set (the registry's test checks).
pub struct KindHooks {
    pub plant: Option<&'static str>,
    pub algorithm: Option<&'static str>,
    pub hooks: &'static dyn RunHooks,
}

impl KindHooks {
    /// Hooks for runs of plant kind `plant`, whatever flies it.
    pub const fn plant(plant: &'static str, hooks: &'static dyn RunHooks) -> Self {
        Self { plant: Some(plant), algorithm: None, hooks }
    }
    /// Hooks for runs of plant kind `plant` flown by algorithm kind `algorithm`.
    pub const fn pair(plant: &'static str, algorithm: &'static str, hooks: &'static dyn RunHooks) -> Self {
        Self { plant: Some(plant), algorithm: Some(algorithm), hooks }
    }
    /// Whether a run of `setup` is one of these hooks' runs.
    pub fn serves(&self, setup: &Setup) -> bool {
        self.plant.is_none_or(|k| k == setup.plant.kind())
            && self.algorithm.is_none_or(|k| k == setup.algorithm.kind())
            && (self.plant.is_some() || self.algorithm.is_some())
    }
}
