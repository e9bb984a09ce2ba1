//! The scenario schema: what a `topologies/*.toml` file may say. This crate knows only what every
//! scenario has — `[scenario]`, `[run]`, `[[agents]]` (id and neighbours), `[[faults]]` — and
//! keeps `[plant]` and `[algorithm]` as `kind`-tagged raw tables ([`Section`]). Which kinds exist,
//! what their tables hold and the per-agent keys a plant reads belong to the papers (see
//! `papers/README.md`): the runtime hands each section to the paper that registered its kind.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub scenario: Meta,
    pub run: RunSettings,
    pub plant: Section,
    pub algorithm: Section,
    pub agents: Vec<AgentConfig>,
    /// The machines of a multi-host run (`[[hosts]]`, or `--hosts FILE`): each runs a host
    /// daemon (`orchestrator host`) the orchestrator asks to start that machine's processes.
    /// Empty: every process runs on the orchestrator's machine.
    pub hosts: Vec<HostSpec>,
    /// The fault plan (`[[faults]]`), see [`crate::faults`].
    pub faults: Vec<crate::faults::FaultSpec>,
    /// The inter-satellite links (`[links]`), see [`crate::links`].
    pub links: crate::links::Links,
    /// The directory of the scenario file: relative file paths inside paper sections (weights,
    /// tables) are relative to it.
    pub base_dir: PathBuf,
    /// The file's text, to give problems found later (by a paper) their line and column.
    pub source: std::sync::Arc<str>,
    /// How many of `faults` the file holds; the rest came from the command line (`--fault`).
    pub faults_in_file: usize,
    /// `scenario.duration_s` came from the command line (`--duration`), not the file: a paper
    /// may then drop what falls past the shortened end (with a note) instead of refusing it.
    pub duration_from_command_line: bool,
}

/// A `kind`-tagged table (`[plant]`, `[algorithm]`): the kind, and the rest of the table as
/// written. The paper that registered the kind parses the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    pub kind: String,
    pub body: toml::Table,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Meta {
    /// Used in run-directory names: letters, digits, `-` and `_`.
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Seeds every process's random generator (derived per process from this and its id).
    pub seed: u64,
    /// Lockstep step, s: the plant's and the agents' sample time.
    pub dt_s: f64,
    pub duration_s: f64,
    /// What a run of this scenario is meant to do: `"complete"` (the default), or `"diverge"`
    /// for a divergence study, whose run ends with the status `diverged`, the time and the last
    /// metrics, and exit code 0.
    #[serde(default, skip_serializing_if = "Expect::is_complete")]
    pub expect: Expect,
}

/// `scenario.expect`: see [`Meta::expect`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Expect {
    #[default]
    Complete,
    Diverge,
}

impl Expect {
    pub fn is_complete(&self) -> bool {
        *self == Expect::Complete
    }
}

/// How a process waits for its next message (`run.wait`). Never changes results, only speed
/// and CPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Wait {
    /// Spin with `sched_yield` for a budget learnt from the typical wait, then block on the event.
    Adaptive,
    /// Block at once.
    Event,
    /// Spin with `sched_yield`, never block.
    Poll,
}

/// The data path between processes (`run.transport`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransportKind {
    /// Zero-copy shared memory.
    Iceoryx2,
    /// Loopback datagrams (the comparison baseline); run control stays on iceoryx2.
    Udp,
    /// zenoh publish–subscribe over TCP, data and run control: processes may sit on several
    /// machines (`[[hosts]]`).
    Zenoh,
}

/// How the processes of a zenoh run reach each other (`run.zenoh_links`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZenohLinks {
    /// iceoryx2 inside each host, one gateway process per host carrying everything that crosses
    /// hosts over one zenoh session, a step's messages for one host batched together.
    #[default]
    Gateway,
    /// Every process its own zenoh peer, connected to every process it talks to.
    Peers,
}

/// One machine of a multi-host run (`[[hosts]]`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HostSpec {
    /// What agents' `host` and `run.plant_host` call it; the daemon's `--name`.
    pub name: String,
    /// Where its daemon listens: a zenoh TCP endpoint, `tcp/<address>:<port>`.
    pub endpoint: String,
}

/// The format of the telemetry files (`run.telemetry`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TelemetryFormat {
    /// Apache Parquet (`<process>.parquet`): compressed, typed, each column's unit in the schema.
    #[default]
    Parquet,
    /// Text (`<process>.csv`), numbers in their shortest exact form.
    Csv,
}

impl TelemetryFormat {
    /// The file extension of this format.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Parquet => "parquet",
            Self::Csv => "csv",
        }
    }
}

/// What a dead or silent agent does to the run (`run.on_agent_loss`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnAgentLoss {
    /// Mark it dead, let its spacecraft coast, and go on with the live set.
    Degrade,
    /// End the run with an error.
    Abort,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSettings {
    /// A peer silent for this long (wall time) ends the run with an error naming it.
    #[serde(default = "default_step_timeout_s")]
    pub step_timeout_s: f64,
    /// Time allowed from spawning the processes to all of them being ready.
    #[serde(default = "default_startup_timeout_s")]
    pub startup_timeout_s: f64,
    /// How a process waits for its next message; see [`Wait`].
    #[serde(default = "default_wait")]
    pub wait: Wait,
    /// Overrides the adaptive spin budget, µs (for measurements).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spin_us: Option<f64>,
    /// 0: agents advance with their neighbours' shares of the same step (two wakeups per agent
    /// per step). 1: a one-step link delay — agents use their neighbours' shares of step k−1 at
    /// step k, which arrive with the measurement (one wakeup). A modelling choice: it changes the
    /// results (deterministically).
    #[serde(default)]
    pub link_delay_steps: u32,
    /// Data path between processes; see [`TransportKind`].
    #[serde(default = "default_transport")]
    pub transport: TransportKind,
    /// With `transport = "zenoh"`: per-host gateways (default) or every process a peer; see
    /// [`ZenohLinks`].
    #[serde(default, skip_serializing_if = "is_gateway")]
    pub zenoh_links: ZenohLinks,
    /// Wall-clock pacing: the plant starts step k no earlier than k·dt_s/rate after step 0
    /// (1.0 = real time). Lockstep still waits for every share; absent = as fast as possible.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub realtime_rate: Option<f64>,
    /// When an agent dies or goes silent past `step_timeout_s`; see [`OnAgentLoss`].
    #[serde(default = "default_on_agent_loss")]
    pub on_agent_loss: OnAgentLoss,
    /// Every agent writes a checkpoint of its full state every this many steps (0: never). A
    /// restarted agent resumes from its latest one.
    #[serde(default = "default_checkpoint_every_steps")]
    pub checkpoint_every_steps: u64,
    /// Seal every message with a keyed MAC (a per-run random key the orchestrator hands each
    /// process through an inherited descriptor) and reject any without a valid tag. Off by
    /// default: a run's shared memory is owner-only already; this guards against processes of
    /// the same user, at a cost measured by `orchestrator bench`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub authenticate: bool,
    /// The plant and every agent write a telemetry row at every this-many-th step (k = 0, n,
    /// 2n, …) and at the last step; 1: every step. A long run at a short step (millions of steps)
    /// would otherwise write gigabytes. Only the telemetry files: timing, checkpoints and the
    /// plant's own metrics still see every step.
    #[serde(default = "default_telemetry_every_steps", skip_serializing_if = "is_one")]
    pub telemetry_every_steps: u64,
    /// Every agent process writes each measurement and share it receives or sends, as its exact
    /// wire bytes, to `record/agent-<i>.mcap` (`launch --record`; `orchestrator replay` reads it).
    /// Changes no result.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub record: bool,
    /// Multi-host runs: the `[[hosts]]` entry the plant runs on (absent: the orchestrator's
    /// machine).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant_host: Option<String>,
    /// Format of the telemetry files: `parquet` (default) or `csv`.
    #[serde(default, skip_serializing_if = "is_parquet")]
    pub telemetry: TelemetryFormat,
}

fn is_gateway(l: &ZenohLinks) -> bool {
    *l == ZenohLinks::Gateway
}

fn is_parquet(f: &TelemetryFormat) -> bool {
    *f == TelemetryFormat::Parquet
}

fn default_telemetry_every_steps() -> u64 {
    1
}

fn is_one(x: &u64) -> bool {
    *x == 1
}

fn default_on_agent_loss() -> OnAgentLoss {
    OnAgentLoss::Degrade
}

fn default_checkpoint_every_steps() -> u64 {
    500
}

fn default_transport() -> TransportKind {
    TransportKind::Iceoryx2
}

fn default_wait() -> Wait {
    Wait::Adaptive
}

fn default_step_timeout_s() -> f64 {
    10.0
}
fn default_startup_timeout_s() -> f64 {
    60.0
}

impl Default for RunSettings {
    fn default() -> Self {
        Self {
            step_timeout_s: default_step_timeout_s(),
            startup_timeout_s: default_startup_timeout_s(),
            wait: default_wait(),
            spin_us: None,
            link_delay_steps: 0,
            transport: default_transport(),
            zenoh_links: ZenohLinks::Gateway,
            realtime_rate: None,
            on_agent_loss: default_on_agent_loss(),
            checkpoint_every_steps: default_checkpoint_every_steps(),
            authenticate: false,
            telemetry_every_steps: default_telemetry_every_steps(),
            record: false,
            plant_host: None,
            telemetry: TelemetryFormat::Parquet,
        }
    }
}

/// One `[[agents]]` entry. `id` and `neighbours` are the runtime's; every other key belongs to
/// the plant kind (initial state, mass, sensor matrix, …), which parses and checks [`extra`].
///
/// [`extra`]: AgentConfig::extra
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentConfig {
    /// 1..=N, each once.
    pub id: u32,
    /// The agents whose shares this one reads.
    pub neighbours: Vec<u32>,
    /// Multi-host runs: the `[[hosts]]` entry this agent's process runs on (required when the
    /// scenario has hosts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// The plant's per-agent keys, as written.
    #[serde(flatten)]
    pub extra: toml::Table,
}

impl Scenario {
    /// Number of lockstep steps (validated to be a whole number ≥ 1).
    pub fn n_steps(&self) -> u64 {
        (self.scenario.duration_s / self.scenario.dt_s).round() as u64
    }
    pub fn n_agents(&self) -> u32 {
        self.agents.len() as u32
    }
    /// Agent config by id (ids are validated to be 1..=N, each once).
    pub fn agent(&self, id: u32) -> &AgentConfig {
        self.agents.iter().find(|a| a.id == id).expect("validated: ids are 1..=N")
    }
    /// The host a process runs on (None: the orchestrator's machine).
    pub fn host_of(&self, p: cohort_wire::transport::Proc) -> Option<&HostSpec> {
        let name = match p {
            cohort_wire::transport::Proc::Plant => self.run.plant_host.as_deref(),
            cohort_wire::transport::Proc::Agent(id) => self.agents.iter().find(|a| a.id == id)?.host.as_deref(),
        };
        name.and_then(|n| self.hosts.iter().find(|h| h.name == n))
    }
    /// Where each process runs, as host indices (0: the orchestrator's machine, k: `hosts[k-1]`).
    pub fn placement(&self) -> cohort_wire::transport::gateway::Placement {
        let index = |name: Option<&str>| {
            name.and_then(|n| self.hosts.iter().position(|h| h.name == n)).map_or(0, |k| k as u16 + 1)
        };
        // One pass over the agents (every child computes this at start-up: no search per id).
        let mut host_of = vec![0; self.n_agents() as usize + 1];
        host_of[0] = index(self.run.plant_host.as_deref());
        for a in &self.agents {
            if let Some(slot) = host_of.get_mut(a.id as usize) {
                *slot = index(a.host.as_deref());
            }
        }
        cohort_wire::transport::gateway::Placement::new(host_of)
    }
    /// Whether this run's processes talk through per-host gateways.
    pub fn uses_gateways(&self) -> bool {
        self.run.transport == TransportKind::Zenoh && self.run.zenoh_links == ZenohLinks::Gateway
    }
    /// The messaging graph.
    pub fn topology(&self) -> cohort_wire::transport::Topology {
        cohort_wire::transport::Topology {
            neighbours: (1..=self.n_agents()).map(|i| self.agent(i).neighbours.clone()).collect(),
        }
    }
    /// A path a paper section names, resolved against the scenario file's directory when it is
    /// relative (canonicalised when it exists, so the resolved scenario the child processes read
    /// from the run directory carries it absolute).
    pub fn resolve_path(&self, path: &str) -> String {
        let p = std::path::Path::new(path);
        if p.is_relative() {
            let joined = self.base_dir.join(p);
            std::fs::canonicalize(&joined).unwrap_or(joined).display().to_string()
        } else {
            path.to_string()
        }
    }
}

/// Serialises a section table for the resolved scenario: `kind` first, then the rest.
pub fn section_table(kind: &str, body: toml::Table) -> toml::Table {
    let mut t = toml::Table::new();
    t.insert("kind".into(), toml::Value::String(kind.into()));
    t.extend(body);
    t
}
