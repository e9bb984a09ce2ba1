//! What a process tells the orchestrator (its status messages) and the report it starts.

use cohort_wire::msg::{SCHEMA_VERSION, STATUS_READY, Status};
use cohort_wire::transport::{Proc, Transport};

use super::params::DriveParams;
use crate::record::ProcessReport;

pub(super) fn status(p: &DriveParams, me: u32, kind: u32, step: u64, waiting_for: u32) -> Status {
    Status {
        version: SCHEMA_VERSION,
        sender: me,
        run_id: p.run_id,
        kind,
        waiting_for,
        step,
        t_s: p.t_s(step),
        build_hash: cohort_wire::build_id_hash(),
        detail: 0,
        _pad: 0,
        mac: [0; 2],
    }
}

/// Tell the orchestrator this process's ports exist.
pub fn report_ready<T: Transport + ?Sized>(t: &mut T, p: &DriveParams, me: Proc) {
    t.report(&status(p, me.sender_id(), STATUS_READY, 0, 0));
}

pub(super) fn new_report(me: Proc, p: &DriveParams) -> ProcessReport {
    ProcessReport { startup_s: p.process_start.elapsed().as_secs_f64(), ..ProcessReport::new(me.name()) }
}
