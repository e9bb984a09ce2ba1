//! One run from a configured scenario to its summary (multi-process, reference, or a paper's
//! coupled mode), the papers' analyses folded in; the report of a run directory; and the
//! [`Launcher`] the papers' commands run scenarios through.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use cohort_host::{Launcher, Mode, PlotRunError, PrepareRunError, RunOptions, RunResult, RunView};
use cohort_runtime::paper::{CoupledCtx, Setup};
use cohort_runtime::record::RunDirs;
use cohort_scenario::{Overrides, Scenario, ScenarioError};
use cohort_supervisor::supervise::{self, LaunchOutcome, RunStatus, SIGNALLED};
use cohort_wire::auth::MacKey;
use cohort_wire::transport::iox::IoxRun;

use crate::{progress, reference, rundir, summary};

/// Read, validate and configure a scenario file with every registered paper.
pub fn load(file: &Path, o: &Overrides) -> Result<Setup, ScenarioError> {
    cohort_registry::load(file, o)
}

/// A fresh run id: random, so concurrent runs never share iceoryx2 resources.
pub(crate) fn new_run_id() -> u64 {
    let mut b = [0u8; 8];
    if std::fs::File::open("/dev/urandom").and_then(|mut f| std::io::Read::read_exact(&mut f, &mut b)).is_ok() {
        return u64::from_le_bytes(b);
    }
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    (t.as_nanos() as u64) ^ (u64::from(std::process::id()) << 32)
}

/// The signal that interrupted the orchestrator, if one did.
fn signalled() -> Option<i32> {
    match SIGNALLED.load(Ordering::SeqCst) {
        0 => None,
        sig => Some(sig as i32),
    }
}

/// A paper's coupled in-process run (see `AlgorithmSetup::coupled`), as a launch outcome with the
/// mode's name.
fn coupled(s: &Setup, dirs: &RunDirs, progress: &progress::Progress) -> Option<(LaunchOutcome, &'static str)> {
    let run = s.algorithm.coupled()?;
    let ctx = CoupledCtx { progress: &|k| progress.set(k), interrupted: &signalled };
    let out = run.run(s, dirs, &ctx);
    let status = match (out.interrupted, &out.error) {
        (Some(sig), _) => RunStatus::Interrupted(sig),
        (None, Some(_)) => RunStatus::Failed,
        (None, None) => RunStatus::Ok,
    };
    let outcome = LaunchOutcome { status, error: out.error, wall_s: out.wall_s, startup_s: None, timeline: Vec::new() };
    Some((outcome, run.name()))
}

/// One run, start to summary: the run directory must exist with its scenario.toml written.
/// Analysis warnings of a failed run are kept in the summary's `warnings` for the caller to print
/// after the run's error (the root cause first); a successful run's are printed here.
pub fn run_once(s: &Setup, dirs: &RunDirs, reference: bool, show_progress: bool) -> (LaunchOutcome, summary::Summary) {
    let how = if reference { How::Reference(reference::Threads::PerProcess) } else { How::Processes };
    run_once_as(s, dirs, how, show_progress)
}

/// How a run flies: as processes, or in-process (the reference run, its drivers on threads or on
/// one thread).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum How {
    Processes,
    Reference(reference::Threads),
}

impl How {
    /// In-process: on one thread when asked, except for Python kinds, whose interpreter keeps its
    /// own per-thread stack bounds (a coroutine's stack is not the thread's): their drivers get a
    /// thread each.
    pub fn in_process(s: &Setup, one_thread: bool) -> Self {
        let python = [&s.parsed.plant.kind, &s.parsed.algorithm.kind].iter().any(|k| k.as_str() == "python");
        if one_thread && python {
            tracing::info!("kind \"python\": the reference run's drivers get a thread each, not one thread");
        }
        let threads = if one_thread && !python { reference::Threads::One } else { reference::Threads::PerProcess };
        How::Reference(threads)
    }
}

/// [`run_once`], choosing how the reference run places its drivers.
pub fn run_once_as(s: &Setup, dirs: &RunDirs, how: How, show_progress: bool) -> (LaunchOutcome, summary::Summary) {
    let reference = how != How::Processes;
    let run_id = new_run_id();
    // The children's log times count from here.
    cohort_runtime::logging::start_run();
    tracing::debug!(
        "run {run_id:016x} ({}) in {}",
        if reference { "reference" } else { "multi-process" },
        dirs.root.display()
    );
    let progress = progress::Progress::new(s.n_steps(), s.scenario.dt_s, &s.scenario.name, show_progress);
    // run.authenticate: a fresh key per run, from the kernel's generator.
    let key = match s.run.authenticate.then(MacKey::generate).transpose() {
        Ok(k) => k,
        Err(e) => {
            let outcome = LaunchOutcome {
                status: RunStatus::Failed,
                error: Some(format!("run.authenticate: cannot draw a key from /dev/urandom: {e}")),
                wall_s: 0.0,
                startup_s: None,
                timeline: Vec::new(),
            };
            let o = summary::Outcome {
                startup_s: None,
                mode: "multi-process",
                run_id: format!("{run_id:016x}"),
                status: outcome.status,
                error: outcome.error.clone(),
                wall_s: 0.0,
                timeline: Vec::new(),
            };
            return (outcome, summary::build(s, dirs, o));
        }
    };
    // `--live`: its thread follows this run (nothing without the flag).
    let live = crate::live::LiveRun::start(s, dirs);
    let (mut outcome, mode) = match coupled(s, dirs, &progress) {
        Some(o) => o,
        None => match how {
            How::Reference(threads) => (reference::launch(s, dirs, run_id, key, &progress, threads), "reference"),
            How::Processes => (
                supervise::launch(s, dirs, &IoxRun::new(run_id).with_key(key), &|step| progress.set(step)),
                "multi-process",
            ),
        },
    };
    progress.finish();
    if let Some(live) = live {
        live.stop();
    }
    // A process killed while running (a fault, a crash) left its Parquet telemetry's and
    // timing's journals: turn them into their files, as its own clean exit would have. A failure
    // is a warning of the summary, printed after the run's error (on a full disk that error is
    // the cause).
    let unsealed: Vec<summary::Warning> = [dirs.telemetry(), dirs.timing()]
        .iter()
        .flat_map(|d| cohort_runtime::parquet_out::seal_dir(d).failures)
        .map(summary::Warning::UnsealedJournal)
        .collect();
    let mut summary = summary::build(
        s,
        dirs,
        summary::Outcome {
            startup_s: outcome.startup_s,
            mode,
            run_id: format!("{run_id:016x}"),
            status: outcome.status,
            error: outcome.error.clone(),
            wall_s: outcome.wall_s,
            timeline: outcome.timeline.clone(),
        },
    );
    summary.warnings.extend(unsealed);
    mark_divergence(s, &mut outcome, &mut summary);
    // Derived quantities come from the telemetry alone, so a partial run gets them too.
    let view = RunView { setup: s, dirs };
    let hooks = cohort_registry::hooks_of(s);
    for (paper, h) in &hooks {
        match h.analyse(&view) {
            Ok(extra) => summary.metrics.extend(extra),
            Err(e) => summary
                .warnings
                .push(summary::Warning::AnalysisSkipped { paper: paper.to_string(), reason: e.to_string() }),
        }
        if !outcome.timeline.is_empty() {
            match h.fault_effects(&view, &outcome.timeline) {
                Ok(extra) => summary.metrics.extend(extra),
                Err(e) => summary
                    .warnings
                    .push(summary::Warning::FaultEffectsSkipped { paper: paper.to_string(), reason: e.to_string() }),
            }
        }
    }
    let input = cohort_host::VerdictInput {
        run: &view,
        metrics: &summary.metrics,
        status: summary.status,
        faulted: !s.faults.is_empty() || !outcome.timeline.is_empty(),
    };
    let verdict: Vec<_> = hooks.iter().flat_map(|(_, h)| h.verdict(&input)).collect();
    summary.verdict_overall = cohort_host::verdict::overall(&verdict);
    summary.verdict = verdict;
    if outcome.error.is_none() {
        for w in &summary.warnings {
            tracing::warn!("{w}");
        }
    }
    if let Err(e) = summary::write(dirs, &summary) {
        summary
            .warnings
            .push(summary::Warning::SummaryNotWritten { path: dirs.root.join("summary.json"), reason: e.to_string() });
        if outcome.error.is_none() {
            tracing::error!("cannot write {}: {e}", dirs.root.join("summary.json").display());
        }
    }
    (outcome, summary)
}

/// A failed run whose cause is a process's model going non-finite has diverged: its status says
/// so and `diverged_at_s` gives the time. A divergence study (`scenario.expect = "diverge"`)
/// ends so by design: exit code 0.
fn mark_divergence(s: &Setup, outcome: &mut LaunchOutcome, summary: &mut summary::Summary) {
    use cohort_runtime::record::ErrorKind;
    if outcome.status != RunStatus::Failed {
        return;
    }
    let Some(e) = summary.processes.iter().filter_map(|p| p.error.as_ref()).find(|e| e.kind == ErrorKind::Diverged)
    else {
        return;
    };
    if let Some(t) = e.t_s {
        summary.metrics.insert("diverged_at_s".into(), t);
    }
    let status = RunStatus::Diverged { expected: s.scenario.expect == cohort_scenario::Expect::Diverge };
    outcome.status = status;
    summary.status = status;
}

/// Create the run directory and write the resolved scenario into it. The error is logged here
/// (callers that only need to stop may drop it).
pub fn prepare(s: &Setup, out: Option<&Path>) -> Result<RunDirs, PrepareRunError> {
    let logged = |e: PrepareRunError| {
        tracing::error!("{e}");
        e
    };
    let dirs = rundir::create(out, &s.scenario.name).map_err(|reason| logged(PrepareRunError::Directory { reason }))?;
    let path = dirs.scenario();
    let text = s.to_toml().map_err(|source| logged(PrepareRunError::Serialise { path, source }))?;
    dirs.write_scenario(&text).map_err(|e| logged(PrepareRunError::Write { path: e.path, source: e.source }))?;
    Ok(dirs)
}

/// The plots of a run directory: the papers' figures of its scenario, then the generic ones. A
/// run directory whose scenario no longer validates (an older version's) gets the generic ones.
pub fn report(run_dir: &Path) -> Result<Vec<PathBuf>, PlotRunError> {
    let setup = match load(&run_dir.join("scenario.toml"), &Overrides::default()) {
        Ok(s) => Some(s),
        Err(e) => {
            tracing::warn!("the run's scenario does not load, so only the generic figures are drawn: {e}");
            None
        }
    };
    let sources: Vec<Box<dyn cohort_host::FigureSource>> = setup
        .as_ref()
        .map(|s| cohort_registry::hooks_of(s).into_iter().filter_map(|(_, h)| h.figures(s, run_dir)).collect())
        .unwrap_or_default();
    let refs: Vec<&dyn cohort_host::FigureSource> = sources.iter().map(|b| b.as_ref()).collect();
    cohort_report::report(run_dir, &refs).map_err(|e| {
        let journals = std::fs::read_dir(run_dir.join("telemetry"))
            .into_iter()
            .flatten()
            .flatten()
            .any(|f| f.path().extension().is_some_and(|x| x == "rows"));
        if journals { PlotRunError::Unsealed { run_dir: run_dir.to_path_buf(), source: e } } else { e.into() }
    })
}

/// The [`Launcher`] of the papers' commands.
pub struct Orchestrator;

impl Launcher for Orchestrator {
    fn load(&self, file: &Path, overrides: &Overrides) -> Result<Setup, ScenarioError> {
        load(file, overrides)
    }
    fn configure(&self, scenario: Scenario, name: &str) -> Result<Setup, ScenarioError> {
        cohort_runtime::paper::configure(scenario, cohort_registry::PAPERS)
            .map_err(|problems| ScenarioError { file: PathBuf::from(name), problems })
    }
    fn run(&self, setup: &Setup, dir: &Path, options: RunOptions) -> Result<RunResult, PrepareRunError> {
        let dirs = prepare(setup, Some(dir))?;
        let (outcome, summary) = run_once(setup, &dirs, options.mode == Mode::Reference, false);
        if options.plots
            && outcome.error.is_none()
            && let Err(e) = report(&dirs.root)
        {
            tracing::warn!("{}: plots not drawn: {e}", dirs.root.display());
        }
        Ok(RunResult {
            dir: dirs.root.clone(),
            status: summary.status,
            mode: summary.mode.to_string(),
            error: outcome.error,
            wall_s: outcome.wall_s,
            steps_completed: summary.steps_completed,
            metrics: summary.metrics,
            messages_rejected: summary.messages_rejected,
        })
    }
    fn report(&self, run_dir: &Path) -> Result<Vec<PathBuf>, PlotRunError> {
        report(run_dir)
    }
    fn interrupted(&self) -> Option<i32> {
        signalled()
    }
}
