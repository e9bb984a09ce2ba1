//! The scenario schema: what a `topologies/*.toml` file may say. Every struct denies unknown keys.
//! `plant` and `algorithm` are tables tagged by `kind`; they are parsed in a second stage (see
//! `parse.rs`) so that an error inside them still names its full key path.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scenario {
    pub scenario: Meta,
    pub run: RunSettings,
    pub plant: PlantConfig,
    pub algorithm: AlgorithmConfig,
    pub agents: Vec<AgentConfig>,
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
}

fn default_step_timeout_s() -> f64 {
    10.0
}
fn default_startup_timeout_s() -> f64 {
    60.0
}

impl Default for RunSettings {
    fn default() -> Self {
        Self { step_timeout_s: default_step_timeout_s(), startup_timeout_s: default_startup_timeout_s() }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum PlantConfig {
    /// Each agent is a 3-D double integrator r̈ = u, r in metres; senses its own position.
    DoubleIntegrator(DoubleIntegratorPlant),
}

impl PlantConfig {
    pub const KINDS: &'static [&'static str] = &["double-integrator"];
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DoubleIntegratorPlant {
    /// Standard deviation of the zero-mean Gaussian noise on each position reading, m.
    pub position_noise_std_m: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum AlgorithmConfig {
    /// Formation keeping about the neighbours' published positions (the smoke scenario).
    ConsensusFormation(ConsensusFormation),
}

impl AlgorithmConfig {
    pub const KINDS: &'static [&'static str] = &["consensus-formation"];
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConsensusFormation {
    /// Agents take slots on a regular polygon of this circumradius in the x–y plane.
    pub formation_radius_m: f64,
    /// Relative-position gain, 1/s².
    pub kp_per_s2: f64,
    /// Velocity damping gain, 1/s.
    pub kd_per_s: f64,
    /// Observer gains on the position residual, 1/s and 1/s².
    pub observer_l1_per_s: f64,
    pub observer_l2_per_s2: f64,
}

impl ConsensusFormation {
    /// Agent `id`'s slot (of `n`) on the regular polygon, relative to the formation centre.
    pub fn slot_m(&self, id: u32, n: u32) -> [f64; 3] {
        let a = std::f64::consts::TAU * f64::from(id - 1) / f64::from(n);
        [self.formation_radius_m * a.cos(), self.formation_radius_m * a.sin(), 0.0]
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentConfig {
    /// 1..=N, each once.
    pub id: u32,
    /// The agents whose shares this one reads.
    pub neighbours: Vec<u32>,
    /// Initial position and velocity (double-integrator plant), m and m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub r0_m: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0_mps: Option<[f64; 3]>,
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
    /// The messaging graph.
    pub fn topology(&self) -> cohort_wire::transport::Topology {
        cohort_wire::transport::Topology {
            neighbours: (1..=self.n_agents()).map(|i| self.agent(i).neighbours.clone()).collect(),
        }
    }
    /// The resolved scenario as TOML (what `launch` writes into the run directory).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a validated scenario always serialises")
    }
}
