//! The hooks of an ISO-encounter run (the `iso-encounter` plant): the analysis of Sec. 6's
//! metrics from the telemetry, the verdict of a Neural-Rendezvous run, and the figures.

use std::path::Path;

use cohort_host::{AnalysisError, FigureSource, Metrics, RunHooks, RunView, VerdictInput, VerdictLine};
use cohort_runtime::paper::Setup;

use super::{analysis, figures, verdict};

/// See the module docs.
pub(crate) struct IsoRun;

impl RunHooks for IsoRun {
    fn analyse(&self, run: &RunView<'_>) -> Result<Metrics, AnalysisError> {
        Ok(analysis::analyse(run.setup, run.dirs)?)
    }
    fn verdict(&self, input: &VerdictInput<'_>) -> Vec<VerdictLine> {
        verdict::lines(input)
    }
    fn figures(&self, setup: &Setup, _run_dir: &Path) -> Option<Box<dyn FigureSource>> {
        figures::NrFigures::of(setup).map(|f| Box::new(f) as Box<dyn FigureSource>)
    }
}
