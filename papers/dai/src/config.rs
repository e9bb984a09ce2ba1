//! The `rigid-body` plant and `dai-attitude` algorithm sections, their validation, and the
//! configured setups that build the models.

use std::collections::BTreeMap;
use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, CoupledRun, PlantKind, PlantSetup, Setup,
    agent_keys, section_as, table_of,
};
use cohort_scenario::{Checker, Problem, Scenario, fmt_f64};
use serde::{Deserialize, Serialize};

/// Readings per measurement of the rigid-body plant: the body rates ω, rad/s.
pub const READINGS: usize = 3;

/// Each agent's spacecraft: a rigid body, J ω̇ = τ − ω × Jω, q̇ = ½ q ⊗ (0, ω). Every agent's
/// spacecraft has the same inertia and initial state (the paper has one spacecraft).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidBodyPlant {
    /// True inertia about the centre of mass, body frame, kg·m² (symmetric, positive definite;
    /// the triangle inequality of a real body is not required, since the paper's J violates it).
    pub inertia_kg_m2: [[f64; 3]; 3],
    /// Initial body rates, rad/s.
    pub omega0_body_rad_s: [f64; 3],
    /// Initial attitude, scalar first, rotating body-frame vectors into the inertial frame.
    #[serde(default = "identity_quaternion")]
    pub q0_inertial_body: [f64; 4],
    /// Longest RK4 sub-step inside one control period, s: a period of dt_s is split into
    /// ceil(dt_s / max_step_s) equal sub-steps with the torque held (zero-order hold).
    #[serde(default = "default_plant_max_step_s")]
    pub max_step_s: f64,
    /// Standard deviation of the zero-mean Gaussian noise on each rate reading, rad/s.
    #[serde(default)]
    pub gyro_noise_std_rad_s: f64,
}

fn identity_quaternion() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}
fn default_plant_max_step_s() -> f64 {
    1e-4
}

impl RigidBodyPlant {
    /// RK4 sub-steps per control period of `dt_s`.
    pub fn substeps(&self, dt_s: f64) -> u32 {
        substeps(dt_s, self.max_step_s)
    }
}

/// ceil(dt_s / max_step_s), at least 1 (both validated positive and finite).
pub fn substeps(dt_s: f64, max_step_s: f64) -> u32 {
    // The 1e-9 keeps 1e-3 / 1e-4 from becoming 11 through rounding.
    ((dt_s / max_step_s) * (1.0 - 1e-9)).ceil().max(1.0) as u32
}

/// The learning law (`algorithm.law`; section numbers of the paper).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Law {
    /// (3): θ̂̇ = g Φᴴ(τ − Φθ̂) (Sec. 2.2).
    Original,
    /// (6): θ̂̇ = (A + B)ᵀ ϕθ̂ (Sec. 2.3), as in the appendix code.
    General,
    /// (10) with (13): θ̂̇ = −Kᵀω′ + R Φᴴ ϕθ̂ (Sec. 2.4).
    Specific,
}

impl Law {
    pub fn name(self) -> &'static str {
        match self {
            Law::Original => "original",
            Law::General => "general",
            Law::Specific => "specific",
        }
    }
}

/// The trajectory generator (14): I_ref ω̇_d + ω_d × I_ref ω_d = τ_test, τ_test switched off at
/// `torque_off_s`. The controller receives ω_d and ω̇_d; it never sees τ_test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaiReference {
    /// ω_d(0), rad/s.
    pub omega_d0_rad_s: [f64; 3],
    /// The generator's inertia, kg·m² (the paper uses the true inertia).
    pub inertia_kg_m2: [[f64; 3]; 3],
    /// τ_test, N·m.
    pub torque_n_m: [f64; 3],
    /// τ_test = 0 for t > torque_off_s, s.
    pub torque_off_s: f64,
}

/// Settings of the coupled continuous integration (`coupling = "continuous"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaiContinuous {
    /// The integrator; see [`Integrator`].
    #[serde(default = "default_method")]
    pub method: Integrator,
    /// Relative and absolute tolerances (the paper's ode45: 1e-10 both).
    #[serde(default = "default_tol")]
    pub rtol: f64,
    #[serde(default = "default_tol")]
    pub atol: f64,
}

/// `algorithm.continuous.method`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Radau IIA 5 for the stiff general law, Dormand–Prince 5(4) otherwise.
    Auto,
    Dopri5,
    Radau5,
}

fn default_method() -> Integrator {
    Integrator::Auto
}
fn default_tol() -> f64 {
    1e-10
}

impl Default for DaiContinuous {
    fn default() -> Self {
        Self { method: default_method(), rtol: default_tol(), atol: default_tol() }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaiAttitude {
    /// The learning law; see [`Law`].
    pub law: Law,
    /// G = R = r·I₆ (general and specific laws).
    #[serde(default = "default_r")]
    pub r: f64,
    /// g of the original law θ̂̇ = g Φᴴ(τ − Φθ̂): 1 in (3), 1.5 in the appendix code.
    #[serde(default = "default_original_gain")]
    pub original_gain: f64,
    /// Torque of the specific law; see [`SpecificTorque`]. The other laws always use (2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub specific_torque: Option<SpecificTorque>,
    /// θ̂(0) = [Ixx, Ixy, Ixz, Iyy, Iyz, Izz], kg·m².
    pub inertia_estimate0_kg_m2: [f64; 6],
    /// How plant and learner are coupled; see [`Coupling`].
    #[serde(default = "default_coupling")]
    pub coupling: Coupling,
    /// Longest RK4 sub-step of the agent's own states (ω_d, θ̂) inside one control period, s
    /// (sampled coupling).
    #[serde(default = "default_agent_max_step_s")]
    pub max_step_s: f64,
    pub reference: DaiReference,
    /// Integrator settings, continuous coupling only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub continuous: Option<DaiContinuous>,
}

fn default_r() -> f64 {
    3.0
}
fn default_original_gain() -> f64 {
    1.0
}
/// `algorithm.specific_torque`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SpecificTorque {
    /// (8), τ = Îω̇_d + ω_d × Îω, which the specific law's Lyapunov proof (12) needs.
    Modified,
    /// (2), τ = Îω̇_d + ω_d × Îω_d, as the appendix code.
    Feedforward,
}

/// `algorithm.coupling`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Coupling {
    /// Plant and agent exchange messages every dt_s (zero-order hold on the torque),
    /// multi-process under `launch`.
    Sampled,
    /// Plant and learner integrated together as one ODE in the orchestrator's process (the
    /// paper's ode45 set-up); dt_s is then only the output grid.
    Continuous,
}

impl Coupling {
    pub fn name(self) -> &'static str {
        match self {
            Coupling::Sampled => "sampled",
            Coupling::Continuous => "continuous",
        }
    }
}

impl SpecificTorque {
    pub fn name(self) -> &'static str {
        match self {
            SpecificTorque::Modified => "modified",
            SpecificTorque::Feedforward => "feedforward",
        }
    }
}

fn default_coupling() -> Coupling {
    Coupling::Sampled
}
fn default_agent_max_step_s() -> f64 {
    1e-4
}

impl DaiAttitude {
    pub fn law(&self) -> Law {
        self.law
    }
    pub fn is_continuous(&self) -> bool {
        self.coupling == Coupling::Continuous
    }
    /// Whether the specific law uses the modified torque (8) (the default).
    pub fn modified_torque(&self) -> bool {
        self.law == Law::Specific
            && self.specific_torque.unwrap_or(SpecificTorque::Modified) == SpecificTorque::Modified
    }
    pub fn continuous_settings(&self) -> DaiContinuous {
        self.continuous.clone().unwrap_or_default()
    }
}

/// An inertia Euler's equations accept: finite, symmetric, positive definite.
fn inertia(c: &mut Checker, path: &str, m: &[[f64; 3]; 3]) {
    {
        let mut ok = true;
        for (i, row) in m.iter().enumerate() {
            ok &= c.all_finite(&format!("{path}[{i}]"), row);
        }
        if !ok {
            return;
        }
        for (i, j) in [(0, 1), (0, 2), (1, 2)] {
            let (a, b) = (m[i][j], m[j][i]);
            if (a - b).abs() > 1e-12 * a.abs().max(b.abs()).max(1e-300) {
                c.fail(
                    format!("{path}[{i}][{j}]"),
                    fmt_f64(a),
                    format!("the inertia must be symmetric, but {path}[{j}][{i}] = {}", fmt_f64(b)),
                );
                return;
            }
        }
        let j = nalgebra::Matrix3::from_fn(|r, c| m[r][c]);
        let mut eig: Vec<f64> = j.symmetric_eigenvalues().iter().copied().collect();
        eig.sort_by(f64::total_cmp);
        let shown = format!("principal moments {:.6e}, {:.6e}, {:.6e} kg·m²", eig[0], eig[1], eig[2]);
        // Positive definite is what Euler's equations need. The triangle inequality of a real body
        // (largest principal moment ≤ sum of the other two) is deliberately not enforced: the
        // paper's J (principal moments 0.68, 1.11, 2.21 kg·m²) violates it.
        if eig[0] <= 0.0 {
            c.fail(path, format!("{m:?}"), format!("must be positive definite ({shown})"));
        }
    }
}

fn validate_plant(c: &mut Checker, s: &Scenario, p: &RigidBodyPlant) {
    inertia(c, "plant.inertia_kg_m2", &p.inertia_kg_m2);
    c.all_finite("plant.omega0_body_rad_s", &p.omega0_body_rad_s);
    if c.all_finite("plant.q0_inertial_body", &p.q0_inertial_body) {
        let n = p.q0_inertial_body.iter().map(|x| x * x).sum::<f64>().sqrt();
        if (n - 1.0).abs() > 1e-9 {
            c.fail(
                "plant.q0_inertial_body",
                format!("{:?}", p.q0_inertial_body),
                format!("must be a unit quaternion (norm {n})"),
            );
        }
    }
    if c.positive("plant.max_step_s", p.max_step_s)
        && s.scenario.dt_s.is_finite()
        && s.scenario.dt_s > 0.0
        && p.substeps(s.scenario.dt_s) > 1_000_000
    {
        c.fail("plant.max_step_s", fmt_f64(p.max_step_s), "more than 1e6 sub-steps per scenario.dt_s");
    }
    if c.finite("plant.gyro_noise_std_rad_s", p.gyro_noise_std_rad_s) && p.gyro_noise_std_rad_s < 0.0 {
        c.fail("plant.gyro_noise_std_rad_s", fmt_f64(p.gyro_noise_std_rad_s), "must be ≥ 0");
    }
}

fn validate_algorithm(c: &mut Checker, s: &Scenario, plant: Option<&RigidBodyPlant>, a: &DaiAttitude) {
    c.positive("algorithm.r", a.r);
    c.positive("algorithm.original_gain", a.original_gain);
    if let Some(t) = a.specific_torque
        && a.law != Law::Specific
    {
        c.fail(
            "algorithm.specific_torque",
            format!("{:?}", t.name()),
            format!("only the specific law has a choice of torque (algorithm.law = {:?})", a.law.name()),
        );
    }
    // Any finite estimate: the controller only multiplies by it (and learning may leave the
    // positive-definite cone anyway).
    c.all_finite("algorithm.inertia_estimate0_kg_m2", &a.inertia_estimate0_kg_m2);
    c.positive("algorithm.max_step_s", a.max_step_s);
    let r = &a.reference;
    c.all_finite("algorithm.reference.omega_d0_rad_s", &r.omega_d0_rad_s);
    inertia(c, "algorithm.reference.inertia_kg_m2", &r.inertia_kg_m2);
    c.all_finite("algorithm.reference.torque_n_m", &r.torque_n_m);
    c.finite("algorithm.reference.torque_off_s", r.torque_off_s);
    match (&a.continuous, a.is_continuous()) {
        (Some(_), false) => c.problems.push(Problem::new(
            "algorithm.continuous",
            None,
            format!("integrator settings need algorithm.coupling = \"continuous\" (it is {:?})", a.coupling.name()),
        )),
        (Some(k), true) => {
            for (key, tol) in [("rtol", k.rtol), ("atol", k.atol)] {
                let path = format!("algorithm.continuous.{key}");
                if c.positive(&path, tol) && !(1e-14..=1e-2).contains(&tol) {
                    c.fail(path, fmt_f64(tol), "must be in [1e-14, 1e-2]");
                }
            }
        }
        _ => {}
    }
    if a.is_continuous() {
        // The coupled ODE has one body, exact rates and no sensor model.
        if s.agents.len() != 1 {
            c.fail(
                "agents",
                format!("{} entries", s.agents.len()),
                "algorithm.coupling = \"continuous\" integrates one spacecraft with its learner: exactly one agent",
            );
        }
        if let Some(p) = plant
            && p.gyro_noise_std_rad_s != 0.0
        {
            c.fail(
                "plant.gyro_noise_std_rad_s",
                fmt_f64(p.gyro_noise_std_rad_s),
                "must be 0 with algorithm.coupling = \"continuous\" (the coupled ODE has no sensor model)",
            );
        }
        if s.run.link_delay_steps != 0 {
            c.fail(
                "run.link_delay_steps",
                s.run.link_delay_steps,
                "must be 0 with algorithm.coupling = \"continuous\"",
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Kinds and setups

pub struct RigidBodyKind;

impl PlantKind for RigidBodyKind {
    fn kind(&self) -> &'static str {
        "rigid-body"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let p = section_as::<RigidBodyPlant>(&ctx.scenario.plant.body, "plant", c);
        let agents = agent_keys::<cohort_runtime::paper::NoAgentKeys>(ctx.scenario, c);
        let p = p?;
        validate_plant(c, ctx.scenario, &p);
        agents?;
        Some(Arc::new(p))
    }
}

impl PlantSetup for RigidBodyPlant {
    fn kind(&self) -> &'static str {
        RigidBodyKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        READINGS
    }
    fn command_len(&self) -> usize {
        3
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        Box::new(crate::rigid_body::RigidBodyPlant::new(
            &self.inertia_kg_m2,
            self.omega0_body_rad_s,
            self.q0_inertial_body,
            setup.n_agents() as usize,
            self.substeps(setup.scenario.dt_s),
            self.gyro_noise_std_rad_s,
        ))
    }
}

pub struct DaiAttitudeKind;

impl AlgorithmKind for DaiAttitudeKind {
    fn kind(&self) -> &'static str {
        "dai-attitude"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<DaiAttitude>(&ctx.scenario.algorithm.body, "algorithm", c);
        if ctx.scenario.plant.kind != RigidBodyKind.kind() {
            c.fail("algorithm.kind", "\"dai-attitude\"", "needs plant.kind = \"rigid-body\"");
        }
        let a = a?;
        let plant = plant.and_then(|p| p.downcast_ref::<RigidBodyPlant>());
        validate_algorithm(c, ctx.scenario, plant, &a);
        Some(Arc::new(a))
    }
}

impl AlgorithmSetup for DaiAttitude {
    fn kind(&self) -> &'static str {
        DaiAttitudeKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        0
    }
    fn build(&self, _setup: &Setup, _id: u32) -> Box<dyn Algorithm> {
        Box::new(crate::attitude::DaiAttitudeAgent::new(self))
    }
    fn coupled(&self) -> Option<&dyn CoupledRun> {
        self.is_continuous().then_some(&crate::continuous::Continuous as &dyn CoupledRun)
    }
    fn labels(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        m.insert("law".into(), self.law.name().into());
        m.insert("r".into(), format!("{}", self.r));
        m.insert("coupling".into(), self.coupling.name().into());
        if self.law == Law::Specific {
            m.insert("specific_torque".into(), self.specific_torque.unwrap_or(SpecificTorque::Modified).name().into());
        }
        m
    }
}
