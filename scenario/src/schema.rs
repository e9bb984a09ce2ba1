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
    /// The fault plan (`[[faults]]`), see [`crate::faults`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<crate::faults::FaultSpec>,
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
    /// How a process waits for its next message: "adaptive" (spin with `sched_yield` for a
    /// budget sized from processes per core, then block on the event), "event" (block at once),
    /// or "poll" (spin with `sched_yield`, never block). Never changes results, only speed and CPU.
    #[serde(default = "default_wait")]
    pub wait: String,
    /// Overrides the adaptive spin budget, µs (for measurements).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spin_us: Option<f64>,
    /// 0: agents advance with their neighbours' shares of the same step (two wakeups per agent
    /// per step). 1: a one-step link delay — agents use their neighbours' shares of step k−1 at
    /// step k, which arrive with the measurement (one wakeup). A modelling choice: it changes the
    /// results (deterministically).
    #[serde(default)]
    pub link_delay_steps: u32,
    /// Data path between processes: "iceoryx2" (zero-copy shared memory) or "udp" (loopback
    /// datagrams, the comparison baseline). Run control always uses iceoryx2.
    #[serde(default = "default_transport")]
    pub transport: String,
    /// Wall-clock pacing: the plant starts step k no earlier than k·dt_s/rate after step 0
    /// (1.0 = real time). Lockstep still waits for every share; absent = as fast as possible.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub realtime_rate: Option<f64>,
    /// When an agent dies or goes silent past `step_timeout_s`: "degrade" (mark it dead, let its
    /// spacecraft coast, and go on with the live set) or "abort" (end the run with an error).
    #[serde(default = "default_on_agent_loss")]
    pub on_agent_loss: String,
    /// Every agent writes a checkpoint of its full state every this many steps (0: never). A
    /// restarted agent resumes from its latest one.
    #[serde(default = "default_checkpoint_every_steps")]
    pub checkpoint_every_steps: u64,
}

fn default_on_agent_loss() -> String {
    "degrade".into()
}

fn default_checkpoint_every_steps() -> u64 {
    500
}

fn default_transport() -> String {
    "iceoryx2".into()
}

fn default_wait() -> String {
    "adaptive".into()
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
            realtime_rate: None,
            on_agent_loss: default_on_agent_loss(),
            checkpoint_every_steps: default_checkpoint_every_steps(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum PlantConfig {
    /// Each agent is a 3-D double integrator r̈ = u, r in metres; senses its own position.
    DoubleIntegrator(DoubleIntegratorPlant),
    /// Servicers and a defunct spacecraft in Earth orbit (seed 000): ECI truth with two-body +
    /// J2 + drag; agents sense yᵢ = Cᵢ(q₀ − qᵢ) and dᵢⱼ = qⱼ − qᵢ in the LVLH frame of a reference
    /// point on the defunct's initial osculating Keplerian orbit.
    Orbital(OrbitalPlant),
    /// No dynamics: every agent gets `readings` zeros each step. With the `null` algorithm it
    /// measures what the messaging alone costs (`orchestrator bench`).
    Null(NullPlant),
    /// Seed 004: each agent's spacecraft is a rigid body (Euler's equations with the true inertia
    /// and attitude quaternion); the agent senses its body rates and commands a body torque.
    RigidBody(crate::dai::RigidBodyPlant),
    /// Seed 001: the tethered space net robot's net (spring–damper mesh) and its four MUs (the
    /// corners) under CW relative motion; agent i senses MU i's state and the net tension on it
    /// and commands its thrust.
    TsnrNet(crate::tsnr_net::TsnrNetPlant),
}

impl PlantConfig {
    pub const KINDS: &'static [&'static str] = &["double-integrator", "orbital", "null", "rigid-body", "tsnr-net"];
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullPlant {
    /// Readings per measurement.
    pub readings: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrbitalPlant {
    /// Standard deviation of the zero-mean Gaussian noise on every component of yᵢ and dᵢⱼ, m.
    pub noise_std_m: f64,
    /// RK4 sub-steps per lockstep step.
    #[serde(default = "one")]
    pub substeps: u32,
    #[serde(default = "default_true")]
    pub j2: bool,
    #[serde(default = "default_true")]
    pub drag: bool,
    /// Drag coefficient C_D of every body.
    #[serde(default = "default_cd")]
    pub drag_coeff: f64,
    /// "step": density evaluated once per RK4 step and held over its stages (Basilisk's
    /// convention); "stage": at every stage.
    #[serde(default = "default_density_hold")]
    pub density_hold: String,
    pub defunct: DefunctConfig,
    /// Random initial offsets of the servicers (Sec. 6 of seed 000), drawn from the seed; when
    /// absent, every agent gives `offset_lvlh_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random_offsets: Option<RandomOffsets>,
}

fn one() -> u32 {
    1
}
fn default_true() -> bool {
    true
}
fn default_cd() -> f64 {
    2.2
}
fn default_density_hold() -> String {
    "step".into()
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefunctConfig {
    pub periapsis_alt_m: f64,
    pub apoapsis_alt_m: f64,
    pub inclination_rad: f64,
    #[serde(default)]
    pub raan_rad: f64,
    #[serde(default)]
    pub arg_periapsis_rad: f64,
    pub mass_kg: f64,
    pub area_m2: f64,
}

/// Servicer start: range U(range_m), azimuth γ U(azimuth_rad), elevation φ U(elevation_rad) in
/// the defunct's LVLH frame: x = σ cos φ cos γ, y = σ cos φ sin γ, z = σ sin φ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomOffsets {
    pub range_m: [f64; 2],
    pub azimuth_rad: [f64; 2],
    pub elevation_rad: [f64; 2],
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
    /// Seed 000: ρ-filter observer (24)–(26), Lb-DNN controller (27), distributed adaptation (28).
    LbDnnServicing(LbDnnServicing),
    /// Zero command, nothing shared: lets the plant be checked on its own.
    Coast(Coast),
    /// Zero command and `share_values` zeros shared, no computation (`orchestrator bench`).
    Null(NullAlgorithm),
    /// Seed 004: deterministic-AI attitude-rate control, feedforward (2) with the estimated
    /// inertia and one of the learning laws original (3), general (6) or specific (10), (13).
    DaiAttitude(crate::dai::DaiAttitude),
    /// Seed 001: tethered-space-net-robot formation control along desired quintic trajectories,
    /// by AEMC (cooperative-game DMPC with tension prediction), DMPC or SMC (`method`).
    TsnrFormation(crate::tsnr_formation::TsnrFormation),
}

impl AlgorithmConfig {
    pub const KINDS: &'static [&'static str] =
        &["consensus-formation", "lb-dnn-servicing", "coast", "null", "dai-attitude", "tsnr-formation"];

    /// The `kind` tag of this algorithm (names its checkpoints).
    pub fn kind(&self) -> &'static str {
        match self {
            AlgorithmConfig::ConsensusFormation(_) => "consensus-formation",
            AlgorithmConfig::LbDnnServicing(_) => "lb-dnn-servicing",
            AlgorithmConfig::Coast(_) => "coast",
            AlgorithmConfig::Null(_) => "null",
            AlgorithmConfig::DaiAttitude(_) => "dai-attitude",
            AlgorithmConfig::TsnrFormation(_) => "tsnr-formation",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullAlgorithm {
    /// Values per share.
    pub share_values: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coast {}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LbDnnServicing {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    pub k4: f64,
    pub k5: f64,
    /// Forgetting rate of the distributed adaptation.
    pub k6: f64,
    /// Learning rate: Γᵢ = gamma · I_p.
    pub gamma: f64,
    /// Projection bound: ‖θ̂ᵢ‖ ≤ theta_bar always.
    pub theta_bar: f64,
    /// Hidden-layer widths of the Lb-DNN (input 6 = [ηᵢ; ζ̂ᵢ], output 3).
    #[serde(default = "default_hidden")]
    pub hidden_layers: Vec<usize>,
    /// Width of the smooth projection's transition band, as a fraction of theta_bar: the
    /// projection starts acting at (1 − band)·theta_bar and removes the whole outward component
    /// at theta_bar.
    #[serde(default = "default_band")]
    pub projection_band: f64,
    /// Observer start: "zero" (η̂ᵢ(0) = 0, the paper's prose) or "measured" (η̂ᵢ(0) = ηᵢ(0)).
    #[serde(default = "default_observer_init")]
    pub observer_init: String,
    /// Optional per-axis thrust-acceleration limit (a variant; the paper has none), m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thrust_limit_mps2: Option<f64>,
}

fn default_hidden() -> Vec<usize> {
    vec![4, 4, 4, 4]
}
fn default_band() -> f64 {
    0.1
}
fn default_observer_init() -> String {
    "zero".into()
}

impl LbDnnServicing {
    /// Layer sizes of the network: 6 inputs, the hidden layers, 3 outputs.
    pub fn layers(&self) -> Vec<usize> {
        std::iter::once(6).chain(self.hidden_layers.iter().copied()).chain(std::iter::once(3)).collect()
    }
    /// Number of weights p (biases included, as in (2)).
    pub fn n_weights(&self) -> usize {
        self.layers().windows(2).map(|w| (w[0] + 1) * w[1]).sum()
    }
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
    /// Initial position and velocity, m and m/s (double-integrator plant; tsnr-net plant: the
    /// MU's state in the target's LVLH frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub r0_m: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0_mps: Option<[f64; 3]>,
    /// Orbital plant: start offset from the defunct in its LVLH frame, m (unless random).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_lvlh_m: Option<[f64; 3]>,
    /// Orbital plant: spacecraft mass, kg, and drag cross-section, m².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area_m2: Option<f64>,
    /// Orbital plant: output matrix Cᵢ (1–4 rows of 3) of yᵢ = Cᵢ(q₀ − qᵢ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_matrix: Option<Vec<[f64; 3]>>,
    /// Whether this agent senses the defunct (bᵢ ∈ {0, 1}).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub b: Option<u8>,
}

impl AgentConfig {
    /// bᵢ, 1 unless the scenario says 0.
    pub fn b(&self) -> u8 {
        self.b.unwrap_or(1)
    }
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
    /// Every file path the scenario names (relative ones are resolved against the scenario file
    /// when it is parsed).
    pub fn file_paths_mut(&mut self) -> impl Iterator<Item = &mut String> {
        let weights = match &mut self.algorithm {
            AlgorithmConfig::TsnrFormation(a) => a.mpc.as_mut().and_then(|m| m.tension_weights.as_mut()),
            _ => None,
        };
        weights.into_iter()
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
