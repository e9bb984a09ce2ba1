//! The telemetry and timing files each driver writes, in the run's telemetry format (Parquet's
//! journal and writer thread keep the writing off the step).

use super::error::{RunError, io};
use super::params::DriveParams;
use crate::record::{TelemetryWriter, TimingWriter};

/// The plant's telemetry (`columns`) and timing files, created.
pub(super) fn plant_files(p: &DriveParams, columns: &[String]) -> Result<(TelemetryWriter, TimingWriter), RunError> {
    crate::parquet_out::defer_budget(p.processes);
    let tel_path = p.dirs.telemetry().join(format!("plant.{}", p.telemetry.extension()));
    let tel = TelemetryWriter::create(p.telemetry, &tel_path, columns).map_err(io(tel_path.display().to_string()))?;
    let tim_path = p.dirs.timing().join(format!("plant.{}", p.telemetry.extension()));
    let timing_columns = ["k".into(), "round_ns".into(), "share_latency_max_ns".into()];
    let timing =
        TimingWriter::create(p.telemetry, &tim_path, &timing_columns).map_err(io(tim_path.display().to_string()))?;
    Ok((tel, timing))
}

/// Agent `name`'s telemetry (`columns`) and timing files: created, or appended to by a relaunched
/// agent (it goes on with its predecessor's files).
pub(super) fn agent_files(
    p: &DriveParams,
    name: &str,
    columns: &[String],
    append: bool,
) -> Result<(TelemetryWriter, TimingWriter), RunError> {
    crate::parquet_out::defer_budget(p.processes);
    let tel_path = p.dirs.telemetry().join(format!("{name}.{}", p.telemetry.extension()));
    let tim_path = p.dirs.timing().join(format!("{name}.{}", p.telemetry.extension()));
    let timing_columns = ["k".into(), "meas_latency_ns".into(), "neighbour_wait_ns".into(), "compute_ns".into()];
    Ok(if append {
        (
            TelemetryWriter::append(p.telemetry, &tel_path, columns).map_err(io(tel_path.display().to_string()))?,
            TimingWriter::append(p.telemetry, &tim_path, &timing_columns)
                .map_err(io(tim_path.display().to_string()))?,
        )
    } else {
        (
            TelemetryWriter::create(p.telemetry, &tel_path, columns).map_err(io(tel_path.display().to_string()))?,
            TimingWriter::create(p.telemetry, &tim_path, &timing_columns)
                .map_err(io(tim_path.display().to_string()))?,
        )
    })
}
