//! The hooks of a swarm run (the `swarm` plant): the analysis of Sec. 7.2's metrics from the
//! telemetry and the figures.

use std::path::Path;

use cohort_host::{AnalysisError, FigureSource, Metrics, RunHooks, RunView};
use cohort_runtime::paper::Setup;

use super::{analysis, figures};

/// See the module docs.
pub(crate) struct SwarmRun;

impl RunHooks for SwarmRun {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::analyse(run.setup, run.dirs)?)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        figures::SwarmFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>)
    }
}
