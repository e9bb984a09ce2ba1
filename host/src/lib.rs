//! The host side of a paper: what it adds to the orchestrator, and what the orchestrator offers it.
//! A paper implements [`PaperHost`] (on the same value that implements the runtime's `Paper`) to
//! declare the hooks of its runs on its kinds ([`hooks`]: summary metrics computed from a run's
//! telemetry, a verdict, figures, a live scene), its trainers, its scenario generators
//! (`orchestrator generate <shape>`) and its own subcommand
//! (`orchestrator <paper> …`: comparison tables, training, campaigns). Paper crates never import
//! the orchestrator: a command gets a [`Launcher`] that validates and runs scenarios for it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cohort_runtime::exit::{FAILED, INVALID, ToExitCode};
use cohort_runtime::paper::{Paper, Setup};
use cohort_scenario::{Overrides, Scenario, ScenarioError};

pub use cohort_report::{FigureSource, PaperFigure, ReportError};
pub use cohort_runtime::run_status::RunStatus;
pub use hooks::{AnalysisError, KindHooks, RunHooks, RunView};
pub use verdict::{Criterion, Verdict, VerdictInput, VerdictLine};

pub mod campaign;
pub mod hooks;
pub mod verdict;

/// Summary metrics by name (units in the names).
pub type Metrics = BTreeMap<String, f64>;

/// Three telemetry columns of one process that together are a position, m (`x`, `y`, `z`).
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePosition {
    /// The process whose telemetry holds them (`plant`, `agent-3`).
    pub process: String,
    pub columns: [String; 3],
}

/// One body of the live 3-D view (`launch --live`): where its truth is, and, where an algorithm
/// estimates it, where the estimate puts it, both read from telemetry columns (see
/// [`RunHooks::scene`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SceneBody {
    /// The entity's name in the scene (`b0`, `agent-3`).
    pub name: String,
    /// The agent id it belongs to (its node of the communication graph), if any.
    pub agent: Option<u32>,
    pub truth: ScenePosition,
    /// The position this body's algorithm estimates (its own, or the target it tracks, as the
    /// paper declares), as a sum of positions (a relative estimate plus its owner's truth, say);
    /// drawn as a ghost. Empty when there is none.
    pub estimate: Vec<ScenePosition>,
}

/// What a paper adds on the host side: the hooks of its runs ([`RunHooks`], declared on its
/// kinds), its trainers and its subcommand. Every method has a default that adds nothing, so a
/// paper implements only what it has.
pub trait PaperHost: Paper {
    /// The hooks of the runs of this paper's kinds (analysis, verdict, figures, scene, sweep
    /// criterion), each declared for the kinds it serves. Default: none.
    fn run_hooks(&self) -> Vec<KindHooks> {
        Vec::new()
    }
    /// Offline training jobs, `orchestrator train <trainer> …`: each a subcommand named for what
    /// it trains (unique across papers; the registry's test checks).
    fn trainers(&self) -> Vec<clap::Command> {
        Vec::new()
    }
    /// Environment variables trainer `name` wants set before it starts (each only when the user
    /// has not set it): e.g. the thread count of a library that reads it from the environment.
    /// The orchestrator sets them while it is still single-threaded, before
    /// [`PaperHost::run_trainer`].
    fn trainer_env(&self, _name: &str) -> Vec<(&'static str, &'static str)> {
        Vec::new()
    }
    /// Run trainer `name` (one of [`PaperHost::trainers`]) with its own `matches`. Returns what
    /// to print on stdout.
    fn run_trainer(&self, name: &str, _matches: &clap::ArgMatches) -> Result<String, CommandError> {
        Err(CommandError::invalid(format!("{} has no trainer {name:?}", self.name())))
    }
    /// Scenario generators, `orchestrator generate <shape> …`: each a subcommand named for the
    /// shape it writes (unique across papers and apart from the orchestrator's own `ring`; the
    /// registry's test checks). The orchestrator adds `--out` to each.
    fn generators(&self) -> Vec<clap::Command> {
        Vec::new()
    }
    /// The scenario text of generator `name` (one of [`PaperHost::generators`]) with its own
    /// `matches`; the orchestrator validates it before it writes it. A relative path in it is
    /// read against the directory of `--out`.
    fn run_generator(&self, name: &str, _matches: &clap::ArgMatches) -> Result<String, CommandError> {
        Err(CommandError::invalid(format!("{} has no generator {name:?}", self.name())))
    }
    /// Scenario files (relative to the repository root) that `orchestrator bench` measures
    /// multi-process against the in-process reference: the paper's headline case.
    fn bench_scenarios(&self) -> Vec<&'static str> {
        Vec::new()
    }
    /// The paper's subcommand, `orchestrator <name> …` (named [`Paper::name`]).
    fn command(&self) -> Option<clap::Command> {
        None
    }
    /// Run the subcommand; `matches` are the subcommand's own. Returns what to print on stdout.
    fn run_command(&self, _matches: &clap::ArgMatches, _launcher: &dyn Launcher) -> Result<String, CommandError> {
        Err(CommandError::invalid(format!("{} has no subcommand", self.name())))
    }
}

/// How a command failed (a paper's, or one of the orchestrator's own that has no error type of
/// its own): the message and the exit code (2 bad input, 1 failed, 128 + n interrupted by
/// signal n), which [`ToExitCode`] gives `main`.
#[derive(Debug, Clone)]
pub struct CommandError {
    pub message: String,
    pub exit_code: u8,
}

impl CommandError {
    /// Bad input (exit 2): a wrong argument, an invalid scenario.
    pub fn invalid(message: impl Into<String>) -> Self {
        Self { message: message.into(), exit_code: INVALID }
    }
    /// The work failed (exit 1).
    pub fn failed(message: impl Into<String>) -> Self {
        Self { message: message.into(), exit_code: FAILED }
    }
}

impl ToExitCode for CommandError {
    fn exit_code(&self) -> u8 {
        self.exit_code
    }
}

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl From<ScenarioError> for CommandError {
    fn from(e: ScenarioError) -> Self {
        Self::invalid(e.to_string())
    }
}

/// Where a run's processes run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// One process per plant and agent (or a coupled run, for scenarios that have one).
    MultiProcess,
    /// Threads of the orchestrator over the in-memory transport (bit-identical, faster).
    Reference,
}

/// How a paper command wants a run made.
#[derive(Debug, Clone, Copy)]
pub struct RunOptions {
    pub mode: Mode,
    /// Draw the run's plots after a successful run.
    pub plots: bool,
}

/// A run's outcome, as a paper command sees it.
#[derive(Debug, Clone)]
pub struct RunResult {
    pub dir: PathBuf,
    /// How the run ended (its name in `summary.json`: "ok", "degraded", "diverged", "failed",
    /// "interrupted" or "salvaged").
    pub status: RunStatus,
    /// How the run was made: "multi-process", "reference" or a coupled mode's name.
    pub mode: String,
    pub error: Option<String>,
    pub wall_s: f64,
    pub steps_completed: u64,
    pub metrics: Metrics,
    /// Messages rejected by every reader, by reason.
    pub messages_rejected: BTreeMap<String, u64>,
}

/// Why a run directory could not be prepared, so that nothing was run (the orchestrator's
/// `launch`, and [`Launcher::run`]'s only error).
#[derive(Debug, thiserror::Error)]
pub enum PrepareRunError {
    /// The directory cannot be created or claimed (the reason names it).
    #[error("{reason}")]
    Directory { reason: String },
    /// The resolved scenario does not serialise into `path`.
    #[error("{}: the resolved scenario does not serialise: {source}", path.display())]
    Serialise { path: PathBuf, source: cohort_runtime::paper::ScenarioToTomlError },
    /// The resolved scenario cannot be written to `path`.
    #[error("{}: {source}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
}

impl ToExitCode for PrepareRunError {
    fn exit_code(&self) -> u8 {
        match self {
            Self::Directory { .. } | Self::Serialise { .. } => INVALID,
            Self::Write { .. } => FAILED,
        }
    }
}

impl RunResult {
    /// The orchestrator's exit code for this run (see [`RunStatus::exit_code`]).
    pub fn exit_code(&self) -> u8 {
        self.status.exit_code()
    }
    /// A metric, NaN when the run did not produce it.
    pub fn metric(&self, name: &str) -> f64 {
        self.metrics.get(name).copied().unwrap_or(f64::NAN)
    }
}

/// Why a run directory's plots were not drawn ([`Launcher::report`], `orchestrator report`).
#[derive(Debug, thiserror::Error)]
pub enum PlotRunError {
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The telemetry is still in journals: the run's orchestrator was killed before it sealed them.
    #[error(
        "{source} (its telemetry/ holds .rows journals: the run's orchestrator was killed before it turned them \
         into files; `orchestrator salvage {}` does)",
        run_dir.display()
    )]
    Unsealed { run_dir: PathBuf, source: ReportError },
    /// The plotting library panicked (the orchestrator draws on a thread and catches it).
    #[error("drawing the plots panicked")]
    Panicked,
}

/// What the orchestrator does for a paper command.
pub trait Launcher {
    /// Read, validate and configure a scenario file with every registered paper.
    fn load(&self, file: &Path, overrides: &Overrides) -> Result<Setup, ScenarioError>;
    /// Validate and configure a scenario a command built or edited (its sections raw, e.g. an
    /// algorithm table replaced with `table_of` a changed typed configuration); `name` stands in
    /// for the file in messages.
    fn configure(&self, scenario: Scenario, name: &str) -> Result<Setup, ScenarioError>;
    /// Run a configured scenario into `dir` (absent or empty), write its summary, and return it.
    /// Err only when nothing could be run (the directory); a run that failed is an Ok with an
    /// error.
    fn run(&self, setup: &Setup, dir: &Path, options: RunOptions) -> Result<RunResult, PrepareRunError>;
    /// Draw a run directory's plots.
    fn report(&self, run_dir: &Path) -> Result<Vec<PathBuf>, PlotRunError>;
    /// The signal that interrupted the orchestrator (Ctrl-C, SIGTERM), if one did: a long command
    /// stops between runs.
    fn interrupted(&self) -> Option<i32>;
}

/// A command's output directory: `out`, or `runs/<default_name>-<UTC time>/`, created; like a run
/// directory it must be absent or empty, so an earlier command's files are never mixed in.
pub fn fresh_out_dir(out: Option<&Path>, default_name: &str) -> Result<PathBuf, CommandError> {
    let root =
        out.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(format!("runs/{default_name}-{}", utc_stamp())));
    if std::fs::read_dir(&root).is_ok_and(|mut d| d.next().is_some()) {
        return Err(CommandError::invalid(format!(
            "--out {}: directory exists and is not empty (refusing to mix runs)",
            root.display()
        )));
    }
    std::fs::create_dir_all(&root)
        .map_err(|e| CommandError::invalid(format!("{}: cannot create: {e}", root.display())))?;
    Ok(root)
}

/// `YYYYMMDDTHHMMSS.mmmZ` for the current UTC time (names default output directories).
pub fn utc_stamp() -> String {
    use std::time::{SystemTime, UNIX_EPOCH};
    let d = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
    let secs = d.as_secs() as i64;
    let (days, sod) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}{month:02}{day:02}T{:02}{:02}{:02}.{:03}Z",
        sod / 3600,
        (sod / 60) % 60,
        sod % 60,
        d.subsec_millis()
    )
}
