//! A host daemon's side of `campaign --hosts`: the runner `orchestrator host` hands the daemon
//! ([`cohort_supervisor::daemon::Cases`]), which turns a case request into the case's outcome by
//! the same path a campaign's own workers take ([`super::fly`]), in-process on one thread.

use std::path::Path;
use std::sync::Arc;

use cohort_scenario::Overrides;
use cohort_supervisor::daemon::CaseRunner;
use cohort_supervisor::farm::{CaseReply, CaseRequest};

use super::CaseError;
use super::row::Outcome;
use crate::launcher::How;

/// What `orchestrator host` runs a campaign's case with.
pub fn runner() -> CaseRunner {
    Arc::new(run)
}

fn run(r: &CaseRequest, scratch: &Path) -> CaseReply {
    let overrides = Overrides { duration_s: r.duration_s, ..Default::default() };
    let setup = match cohort_registry::load_text(&r.scenario_text, Path::new(&r.file), &overrides) {
        Ok(s) => s,
        Err(e) => return CaseReply::Failed(format!("case {}: {e}", r.case)),
    };
    // The orchestrator refused these before any case ran; a request from elsewhere is refused too.
    if let Some(why) = crate::reference_refusal(&setup, "cases on hosts run in-process") {
        return CaseReply::Failed(format!("case {}: {why}", r.case));
    }
    let dir = scratch.join("run");
    match super::fly::fly(&setup, &dir, How::in_process(&setup, true), false) {
        Ok(outcome) => {
            // The run's summary travels with its row, so the case's directory on the
            // orchestrator's machine holds what a local case's does but the logs.
            let summary = std::fs::read_to_string(dir.join("summary.json")).ok();
            match serde_json::to_value(Done { outcome, summary }) {
                Ok(v) => CaseReply::Done(v),
                Err(e) => CaseReply::Failed(format!("case {}: cannot encode its outcome: {e}", r.case)),
            }
        }
        Err(CaseError::Interrupted) => CaseReply::Stopping,
        Err(e) => CaseReply::Failed(format!("case {}: {e}", r.case)),
    }
}

/// A case's reply from a host: its outcome and its run's `summary.json`.
#[derive(serde::Serialize, serde::Deserialize)]
pub(super) struct Done {
    pub outcome: Outcome,
    pub summary: Option<String>,
}
