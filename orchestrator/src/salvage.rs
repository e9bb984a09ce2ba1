//! `orchestrator salvage RUN_DIR`: what a launch does at the end of a run, for a run whose
//! orchestrator never got there (SIGKILLed, the machine lost): turn every `.rows` journal its
//! processes left into its telemetry or timing file, and write the missing `summary.json` from
//! what the processes left, so `report`, the papers' analyses and the Python loader can read the
//! run. A journal that cannot be turned (damaged) is named and left as it was; the others are
//! turned all the same.
//!
//! Exit codes: 0 every journal turned (or none left); 1 some could not be; 2 not a run directory.

use std::path::Path;
use std::process::ExitCode;

use cohort_runtime::record::RunDirs;
use cohort_runtime::run_status::RunStatus;
use cohort_scenario::Overrides;

use crate::{EXIT_FAILED, EXIT_INVALID, summary};

/// Run the command; prints what it wrote and returns its exit code.
pub fn command(run_dir: &Path) -> ExitCode {
    let file = run_dir.join("scenario.toml");
    if !file.is_file() {
        tracing::error!(
            "{}: missing: {} is not a run directory written by `launch`",
            file.display(),
            run_dir.display()
        );
        return ExitCode::from(EXIT_INVALID);
    }
    let dirs = RunDirs::new(run_dir);
    let mut failures = Vec::new();
    for d in [dirs.telemetry(), dirs.timing()] {
        let sealed = cohort_runtime::parquet_out::seal_dir(&d);
        for f in &sealed.files {
            outln!("{}", f.display());
        }
        failures.extend(sealed.failures);
    }
    for f in &failures {
        tracing::error!("cannot turn a journal into its file: {f}");
    }
    if !dirs.root.join("summary.json").exists() {
        write_summary(&file, &dirs);
    }
    if failures.is_empty() { ExitCode::SUCCESS } else { ExitCode::from(EXIT_FAILED) }
}

/// A summary of a run that ended without one: status `salvaged`, from the processes' reports and
/// telemetry (a process killed with its orchestrator left no report).
fn write_summary(file: &Path, dirs: &RunDirs) {
    let s = match crate::load(file, &Overrides::default()) {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("no summary.json written: the run's scenario does not load: {e}");
            return;
        }
    };
    let o = summary::Outcome {
        startup_s: None,
        mode: "multi-process",
        run_id: String::new(),
        status: RunStatus::Salvaged,
        error: Some(
            "the run ended without its orchestrator's summary (killed?); salvaged from what its processes left".into(),
        ),
        wall_s: 0.0,
        timeline: Vec::new(),
    };
    let built = summary::build(&s, dirs, o);
    match summary::write(dirs, &built) {
        Ok(()) => outln!(
            "{} (status salvaged, {} steps completed)",
            dirs.root.join("summary.json").display(),
            built.steps_completed
        ),
        Err(e) => tracing::error!("cannot write {}: {e}", dirs.root.join("summary.json").display()),
    }
}
