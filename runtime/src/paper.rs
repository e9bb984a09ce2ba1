//! How a paper plugs into the runtime. The runtime knows no paper: a paper crate (under
//! `papers/<name>/`) declares the plant kinds and algorithm kinds it provides ([`Paper`]), and the
//! registry crate lists the papers. A scenario's `[plant]` and `[algorithm]` tables name a kind;
//! [`configure`] hands each table to the kind that registered it, which parses and validates it
//! (every problem with its key path, through the scenario crate's [`Checker`]) and returns a
//! configured object ([`PlantSetup`], [`AlgorithmSetup`]) that builds the models. The result, with
//! the generic part of the scenario, is a [`Setup`]: what every binary runs.
//!
//! Kinds compose across papers: a plant kind of one paper can run an algorithm kind of another
//! (a coasting agent flies any plant); an algorithm that needs a particular plant checks
//! `ctx.scenario.plant.kind` and downcasts the plant's setup (`dyn PlantSetup::downcast_ref`, trait upcasting to `Any`) to read its
//! typed configuration.

use std::any::Any;
use std::collections::BTreeMap;
use std::ops::Deref;
use std::path::Path;
use std::sync::Arc;

use cohort_scenario::{Checker, MessageSizes, Overrides, Problem, Scenario, ScenarioError};

use crate::model::{Algorithm, PlantModel};
use crate::record::RunDirs;

/// A paper (or a library of kinds shared by several): its name and the kinds it provides.
pub trait Paper: Sync {
    /// Short name: the folder under `papers/`, and the name of its orchestrator subcommand.
    fn name(&self) -> &'static str;
    /// The plant kinds this paper provides (`[plant] kind = ...`).
    fn plants(&self) -> &'static [&'static dyn PlantKind];
    /// The algorithm kinds this paper provides (`[algorithm] kind = ...`).
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind];
}

/// Whether kinds run the checks that cost a child process (importing a user's Python module):
/// on in `check`, `launch` and every tool that reads a scenario a user wrote; off in the plant and
/// agent processes, which read the run directory's resolved scenario that the orchestrator has
/// already checked (N agents would otherwise import each module N more times at start-up).
static DEEP_CHECKS: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(true);

/// Turn off the checks of [`deep_checks`] for this process (the child processes call it).
pub fn skip_deep_checks() {
    DEEP_CHECKS.store(false, std::sync::atomic::Ordering::Relaxed);
}

/// Whether a kind should run its costly checks (see [`skip_deep_checks`]).
pub fn deep_checks() -> bool {
    DEEP_CHECKS.load(std::sync::atomic::Ordering::Relaxed)
}

/// What a kind sees while it configures itself.
pub struct ConfigureCtx<'a> {
    /// The scenario with its paper sections raw (generic sections parsed, maybe invalid).
    pub scenario: &'a Scenario,
    /// Whether agent ids are exactly 1..=N, so `scenario.agent(id)` may be used.
    pub ids_ok: bool,
}

/// A plant kind: parses `[plant]` and every agent's per-agent keys.
pub trait PlantKind: Sync {
    /// The `kind` string.
    fn kind(&self) -> &'static str;
    /// Parse and validate `ctx.scenario.plant.body` and the agents' extra keys; every problem
    /// goes to `c` with its key path (`plant.…`, `agents[k].…`). None when it cannot be built.
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>>;
}

/// The frame of a plant's spacecraft positions, as the geometric link model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkFrame {
    /// No positions (attitude only, or no spacecraft): ideal links only.
    None,
    /// Positions in a frame whose origin is no body (a relative frame): no occultation.
    Relative,
    /// Positions about the centre of the body that can occult the links (the Earth, the Sun),
    /// with its name and mean equatorial radius, m.
    CentralBody(&'static str, f64),
}

/// A configured plant.
pub trait PlantSetup: Send + Sync + Any {
    fn kind(&self) -> &'static str;
    /// The section as resolved (defaults filled in, paths absolute), without `kind`: what the
    /// run directory's `scenario.toml` says, which the child processes read. Usually
    /// [`table_of`] the typed configuration.
    fn resolved(&self) -> Result<toml::Table, ConfigTableError>;
    /// Readings per measurement of agent `id`.
    fn readings(&self, s: &Scenario, id: u32) -> usize;
    /// Names of agent `id`'s readings, in order, each ending in its unit as telemetry columns do
    /// (`r_x_m`): what an algorithm written outside Rust is told about its measurement. The
    /// default numbers them (`reading_0_1`, unit unknown); a plant an algorithm of another kind
    /// may fly names them.
    fn reading_names(&self, s: &Scenario, id: u32) -> Vec<String> {
        (0..self.readings(s, id)).map(|i| format!("reading_{i}_1")).collect()
    }
    /// Names of the command's components with their units (default: numbered, unit unknown).
    fn command_names(&self) -> Vec<String> {
        (0..self.command_len()).map(|i| format!("command_{i}_1")).collect()
    }
    /// Components of every agent's command.
    fn command_len(&self) -> usize;
    /// What its model's positions (`PlantModel::positions_m`) are, for `[links]` model
    /// `geometric`: none (attitude only), or positions in a frame with or without an occulting
    /// body at its origin.
    fn link_frame(&self) -> LinkFrame {
        LinkFrame::None
    }
    /// The truth model (the plant process's, or the reference run's plant thread).
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel>;
    /// What the plant's paper needs of the live agents that no longer holds, in words (checked
    /// whenever the roster changes; the generic graph checks come on top).
    fn roster_warnings(&self, _s: &Scenario, _live: &[bool]) -> Vec<String> {
        Vec::new()
    }
}

impl dyn PlantSetup {
    /// This setup as the paper's own type `T`, when it is one (trait upcasting to `Any`).
    pub fn downcast_ref<T: Any>(&self) -> Option<&T> {
        (self as &dyn Any).downcast_ref()
    }
}

/// An algorithm kind: parses `[algorithm]`.
pub trait AlgorithmKind: Sync {
    fn kind(&self) -> &'static str;
    /// Parse and validate `ctx.scenario.algorithm.body` (and check that it can fly `plant`, the
    /// configured plant, absent when the plant section has problems of its own).
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>>;
}

/// A configured algorithm.
pub trait AlgorithmSetup: Send + Sync + Any {
    /// The `kind` string (it also names checkpoints).
    fn kind(&self) -> &'static str;
    /// The section as resolved, without `kind` (see [`PlantSetup::resolved`]).
    fn resolved(&self) -> Result<toml::Table, ConfigTableError>;
    /// Values per share.
    fn share_values(&self, s: &Scenario) -> usize;
    /// Agent `id`'s algorithm.
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm>;
    /// A mode that runs plant and agents as one coupled integration in the orchestrator's
    /// process, instead of the lockstep processes (None: the scenario runs in lockstep).
    fn coupled(&self) -> Option<&dyn CoupledRun> {
        None
    }
    /// Whether the agents need a connected communication graph (a decentralised method: the
    /// default). An algorithm whose agents never read a neighbour's share (independent
    /// spacecraft) says false: the graph's connectivity is then neither required by validation
    /// nor watched when the roster changes.
    fn needs_connected_graph(&self) -> bool {
        true
    }
    /// Non-numeric labels for the run's summary (e.g. which learning law ran).
    fn labels(&self) -> BTreeMap<String, String> {
        BTreeMap::new()
    }
}

impl dyn AlgorithmSetup {
    /// This setup as the paper's own type `T`, when it is one (trait upcasting to `Any`).
    pub fn downcast_ref<T: Any>(&self) -> Option<&T> {
        (self as &dyn Any).downcast_ref()
    }
}

/// A coupled in-process run (see [`AlgorithmSetup::coupled`]): it writes the same telemetry files
/// as a lockstep run would.
pub trait CoupledRun: Sync {
    /// The mode's name in the run's summary (`mode`), e.g. "continuous".
    fn name(&self) -> &'static str;
    /// One line for the launch banner: what runs, and where.
    fn describe(&self) -> &'static str;
    /// Run to the end (or until `ctx.interrupted` says a signal came) into the run directory.
    fn run(&self, setup: &Setup, dirs: &RunDirs, ctx: &CoupledCtx<'_>) -> CoupledOutcome;
}

/// What the orchestrator gives a coupled run.
pub struct CoupledCtx<'a> {
    /// Takes the steps done so far.
    pub progress: &'a dyn Fn(u64),
    /// The signal that asked the orchestrator to stop (Ctrl-C, SIGTERM), if one did.
    pub interrupted: &'a dyn Fn() -> Option<i32>,
}

/// How a coupled run ended.
#[derive(Debug, Clone)]
pub struct CoupledOutcome {
    /// None: every step was done.
    pub error: Option<String>,
    /// The signal it stopped on, if it was interrupted.
    pub interrupted: Option<i32>,
    pub wall_s: f64,
}

/// A scenario with its paper sections configured: what a run is made of.
#[derive(Clone)]
pub struct Setup {
    /// The scenario as parsed (its generic sections typed, the paper sections raw). `Setup`
    /// derefs to it, so `setup.scenario.seed`, `setup.run`, `setup.agents` read as in a file.
    pub parsed: Scenario,
    pub plant: Arc<dyn PlantSetup>,
    pub algorithm: Arc<dyn AlgorithmSetup>,
    /// Names of the papers whose kinds it uses (the plant's first), for the host side.
    pub papers: Vec<&'static str>,
    /// What configuring took differently from the file on purpose ([`Checker::note`]).
    pub notes: Vec<String>,
}

impl Deref for Setup {
    type Target = Scenario;
    fn deref(&self) -> &Scenario {
        &self.parsed
    }
}

impl std::fmt::Debug for Setup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Setup")
            .field("scenario", &self.parsed.scenario.name)
            .field("plant", &self.plant.kind())
            .field("algorithm", &self.algorithm.kind())
            .finish()
    }
}

impl Setup {
    /// Message sizes this setup needs.
    pub fn message_sizes(&self) -> MessageSizes {
        let s = &self.parsed;
        MessageSizes {
            readings: (1..=s.n_agents()).map(|i| self.plant.readings(s, i)).max().unwrap_or(0),
            command: self.plant.command_len(),
            share_values: self.algorithm.share_values(s),
        }
    }

    /// The resolved scenario as TOML (what `launch` writes into the run directory): every section
    /// with its defaults, paper sections as their kinds resolved them.
    pub fn to_toml(&self) -> Result<String, ScenarioToTomlError> {
        use ScenarioToTomlError as E;
        let s = &self.parsed;
        let mut t = toml::Table::new();
        let ser = |section: &'static str, v: Result<toml::Table, toml::ser::Error>| {
            v.map_err(|source| E::Section { section, source })
        };
        t.insert("scenario".into(), ser("scenario", toml::Table::try_from(&s.scenario))?.into());
        t.insert("run".into(), ser("run", toml::Table::try_from(&s.run))?.into());
        let plant = self.plant.resolved().map_err(|source| E::Config { section: "plant", source })?;
        t.insert("plant".into(), cohort_scenario::section_table(self.plant.kind(), plant).into());
        let algorithm = self.algorithm.resolved().map_err(|source| E::Config { section: "algorithm", source })?;
        t.insert("algorithm".into(), cohort_scenario::section_table(self.algorithm.kind(), algorithm).into());
        let agents: Vec<toml::Value> = s
            .agents
            .iter()
            .map(|a| ser("agents", toml::Table::try_from(a)).map(toml::Value::Table))
            .collect::<Result<_, _>>()?;
        t.insert("agents".into(), toml::Value::Array(agents));
        if !s.hosts.is_empty() {
            let hosts: Vec<toml::Value> = s
                .hosts
                .iter()
                .map(|h| ser("hosts", toml::Table::try_from(h)).map(toml::Value::Table))
                .collect::<Result<_, _>>()?;
            t.insert("hosts".into(), toml::Value::Array(hosts));
        }
        if !s.faults.is_empty() {
            let faults: Vec<toml::Value> = s
                .faults
                .iter()
                .map(|f| ser("faults", toml::Table::try_from(f)).map(toml::Value::Table))
                .collect::<Result<_, _>>()?;
            t.insert("faults".into(), toml::Value::Array(faults));
        }
        if s.links != cohort_scenario::links::Links::default() {
            t.insert("links".into(), ser("links", toml::Table::try_from(&s.links))?.into());
        }
        toml::to_string(&t).map_err(E::Document)
    }

    /// The plant's typed setup, when it is a `T`.
    pub fn plant_as<T: 'static>(&self) -> Option<&T> {
        self.plant.downcast_ref()
    }
    /// The algorithm's typed setup, when it is a `T`.
    pub fn algorithm_as<T: 'static>(&self) -> Option<&T> {
        self.algorithm.downcast_ref()
    }
    /// Every roster warning: the graph's (if the algorithm needs it connected), then the plant's.
    pub fn roster_warnings(&self, live: &[bool]) -> Vec<String> {
        let mut w = if self.algorithm.needs_connected_graph() {
            cohort_scenario::live_graph::warnings(&self.parsed.agents, live)
        } else {
            Vec::new()
        };
        w.extend(self.plant.roster_warnings(&self.parsed, live));
        w
    }
}

/// A typed configuration as a TOML table (for [`PlantSetup::resolved`]).
pub fn table_of<T: serde::Serialize>(config: &T) -> Result<toml::Table, ConfigTableError> {
    toml::Table::try_from(config).map_err(ConfigTableError)
}

/// Why a typed configuration is no TOML table ([`table_of`], [`PlantSetup::resolved`],
/// [`AlgorithmSetup::resolved`]): serde's reason, which names the field.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ConfigTableError(#[from] pub toml::ser::Error);

/// Why a configured scenario does not serialise ([`Setup::to_toml`]): the section, and why.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioToTomlError {
    /// A generic section (`scenario`, `run`, `agents`, `hosts`, `faults`).
    #[error("{section}: {source}")]
    Section { section: &'static str, source: toml::ser::Error },
    /// The `plant` or `algorithm` section as its kind resolved it.
    #[error("{section}: {source}")]
    Config { section: &'static str, source: ConfigTableError },
    /// The document as a whole.
    #[error("{0}")]
    Document(toml::ser::Error),
}

/// The per-agent keys of a kind that reads none: `agent_keys::<NoAgentKeys>` rejects any key
/// of an `[[agents]]` entry beyond `id` and `neighbours`, each at its key path.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoAgentKeys {}

/// Deserialise every agent's per-agent keys (`[[agents]]` beyond `id` and `neighbours`) as a `T`,
/// in file order, each problem at `agents[k].…`. None if any agent's keys do not parse.
pub fn agent_keys<T: serde::de::DeserializeOwned>(s: &Scenario, c: &mut Checker) -> Option<Vec<T>> {
    let mut out = Vec::with_capacity(s.agents.len());
    let mut ok = true;
    for (k, a) in s.agents.iter().enumerate() {
        match cohort_scenario::section_of::<T>(&a.extra, || format!("agents[{k}]"), &mut c.problems) {
            Some(t) => out.push(t),
            None => ok = false,
        }
    }
    ok.then_some(out)
}

/// Deserialise a paper section's body as a `T` at key path `path` (`plant`, `algorithm`).
pub fn section_as<T: serde::de::DeserializeOwned>(body: &toml::Table, path: &str, c: &mut Checker) -> Option<T> {
    cohort_scenario::section_of::<T>(body, || path.to_string(), &mut c.problems)
}

/// Every plant kind and algorithm kind of `papers`, with the paper providing it.
fn plant_kinds(papers: &[&'static dyn Paper]) -> Vec<(&'static str, &'static dyn PlantKind)> {
    papers.iter().flat_map(|p| p.plants().iter().map(move |k| (p.name(), *k))).collect()
}

fn algorithm_kinds(papers: &[&'static dyn Paper]) -> Vec<(&'static str, &'static dyn AlgorithmKind)> {
    papers.iter().flat_map(|p| p.algorithms().iter().map(move |k| (p.name(), *k))).collect()
}

/// Two papers registering the same kind, or one name twice (the registry's own test calls it).
pub fn registry_problems(papers: &[&'static dyn Paper]) -> Vec<String> {
    let mut out = Vec::new();
    let mut seen = std::collections::BTreeMap::new();
    for p in papers {
        if let Some(other) = seen.insert(format!("paper {}", p.name()), p.name()) {
            out.push(format!("paper name {} registered twice ({other})", p.name()));
        }
    }
    let mut kinds = std::collections::BTreeMap::new();
    for (paper, k) in plant_kinds(papers) {
        if let Some(other) = kinds.insert(format!("plant kind {:?}", k.kind()), paper) {
            out.push(format!("plant kind {:?} registered by {other} and {paper}", k.kind()));
        }
    }
    for (paper, k) in algorithm_kinds(papers) {
        if let Some(other) = kinds.insert(format!("algorithm kind {:?}", k.kind()), paper) {
            out.push(format!("algorithm kind {:?} registered by {other} and {paper}", k.kind()));
        }
    }
    out
}

/// Validate a parsed scenario and configure its paper sections with the kinds of `papers`:
/// every problem of the file at once (generic, plant, algorithm, message bounds).
pub fn configure(scenario: Scenario, papers: &[&'static dyn Paper]) -> Result<Setup, Vec<Problem>> {
    let (ids_ok, generic) = cohort_scenario::validate::validate(&scenario);
    let mut c = Checker::new();
    c.problems = generic;
    let ctx = ConfigureCtx { scenario: &scenario, ids_ok };
    let plants = plant_kinds(papers);
    let algorithms = algorithm_kinds(papers);
    let plant_kind = plants.iter().find(|(_, k)| k.kind() == scenario.plant.kind);
    let algorithm_kind = algorithms.iter().find(|(_, k)| k.kind() == scenario.algorithm.kind);
    let list = |kinds: Vec<&str>| {
        let mut kinds = kinds;
        kinds.sort_unstable();
        kinds.join(", ")
    };
    if plant_kind.is_none() {
        c.fail(
            "plant.kind",
            format!("{:?}", scenario.plant.kind),
            format!("unknown kind (expected one of: {})", list(plants.iter().map(|(_, k)| k.kind()).collect())),
        );
    }
    if algorithm_kind.is_none() {
        c.fail(
            "algorithm.kind",
            format!("{:?}", scenario.algorithm.kind),
            format!("unknown kind (expected one of: {})", list(algorithms.iter().map(|(_, k)| k.kind()).collect())),
        );
    }
    let plant = plant_kind.and_then(|(_, k)| k.configure(&ctx, &mut c));
    let algorithm = algorithm_kind.and_then(|(_, k)| k.configure(&ctx, plant.as_deref(), &mut c));
    // Checked unless the (configured) algorithm's agents never talk.
    if algorithm.as_ref().is_none_or(|a| a.needs_connected_graph()) {
        cohort_scenario::validate::connectivity(&mut c, &scenario.agents);
    }
    if let Some(p) = plant.as_deref().filter(|_| scenario.links.is_geometric()) {
        check_link_frame(&mut c, p, &scenario.links);
    }
    let (Some(plant), Some(algorithm)) = (plant, algorithm) else {
        return Err(c.problems);
    };
    let mut names = vec![plant_kind.map_or("", |(p, _)| *p)];
    let algorithm_paper = algorithm_kind.map_or("", |(p, _)| *p);
    if !names.contains(&algorithm_paper) {
        names.push(algorithm_paper);
    }
    let notes = std::mem::take(&mut c.notes);
    let setup = Setup { parsed: scenario, plant, algorithm, papers: names, notes };
    if ids_ok {
        setup.message_sizes().check(&mut c);
    }
    if c.problems.is_empty() { Ok(setup) } else { Err(c.problems) }
}

/// Geometric links need positions, and an occulting body only where the frame has one.
fn check_link_frame(c: &mut Checker, p: &dyn PlantSetup, links: &cohort_scenario::links::Links) {
    match p.link_frame() {
        LinkFrame::None => c.fail(
            "links.model",
            "\"geometric\"",
            format!("plant kind {:?} gives no spacecraft positions for the link model: only ideal links", p.kind()),
        ),
        LinkFrame::Relative => {
            if let Some(r) = links.occulting_radius_m {
                let why = format!(
                    "plant kind {:?} gives positions in a relative frame, with no body at its origin",
                    p.kind()
                );
                c.fail("links.occulting_radius_m", r, why);
            }
        }
        LinkFrame::CentralBody(..) => {}
    }
}

/// Read, parse, validate and configure a scenario file.
pub fn load(file: &Path, overrides: &Overrides, papers: &[&'static dyn Paper]) -> Result<Setup, ScenarioError> {
    let (scenario, problems) = cohort_scenario::load_all(file, overrides)?;
    finish_load(file, scenario, problems, overrides, papers)
}

/// [`load`] of a run's scenario ([`RunDirs::scenario`]) for one of the run's processes: its
/// table from the run's digest when it has one made from the file's text
/// ([`cohort_scenario::digest`]); why the digest was not used is logged (a warning unless the run
/// has none, as one prepared by hand). The text is kept only to locate problems found while
/// loading, so the setup keeps none (a thousand-agent scenario's is 123 kB in each process).
pub fn load_run(dirs: &RunDirs, overrides: &Overrides, papers: &[&'static dyn Paper]) -> Result<Setup, ScenarioError> {
    use cohort_scenario::digest::DigestError;
    let file = dirs.scenario();
    let ((scenario, problems), unused) = cohort_scenario::load_all_digested(&file, overrides)?;
    match unused {
        None => tracing::debug!("scenario read from its digest"),
        Some(DigestError::Read { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            tracing::debug!("scenario parsed: the run has no digest of it")
        }
        Some(e) => tracing::warn!("scenario parsed, its digest not used: {e}"),
    }
    let mut setup = finish_load(&file, scenario, problems, overrides, papers)?;
    setup.parsed.source = "".into();
    Ok(setup)
}

/// [`load`] of scenario text standing for `file` (a campaign's drawn case: its relative paths
/// resolve beside `file`, its problems name it).
pub fn load_text(
    text: &str,
    file: &Path,
    overrides: &Overrides,
    papers: &[&'static dyn Paper],
) -> Result<Setup, ScenarioError> {
    let (scenario, problems) = cohort_scenario::parse_all(text, file, overrides)?;
    finish_load(file, scenario, problems, overrides, papers)
}

fn finish_load(
    file: &Path,
    scenario: Scenario,
    mut problems: Vec<cohort_scenario::Problem>,
    overrides: &Overrides,
    papers: &[&'static dyn Paper],
) -> Result<Setup, ScenarioError> {
    let source = scenario.source.clone();
    match configure(scenario, papers) {
        Ok(setup) if problems.is_empty() => Ok(setup),
        Ok(_) => Err(ScenarioError { file: file.to_path_buf(), problems }.located(&source)),
        Err(more) => {
            problems.extend(more);
            overrides.mark(&mut problems);
            Err(ScenarioError { file: file.to_path_buf(), problems }.located(&source))
        }
    }
}
