//! The generic kinds' scenario sections, their checks, and how each builds its model.

use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, agent_keys,
    section_as, table_of,
};
use cohort_scenario::{Checker, Problem, Scenario};
use serde::{Deserialize, Serialize};

// ---------------------------------------------------------------------------------------------
// Plant `double-integrator`

/// Each agent is a 3-D double integrator r̈ = u, r in metres; senses its own position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DoubleIntegratorPlant {
    /// Standard deviation of the zero-mean Gaussian noise on each position reading, m.
    pub position_noise_std_m: f64,
    /// The slots of the formation-error metric when the algorithm is not `consensus-formation`
    /// (which has its own): a regular polygon of this circumradius in the x–y plane, as that kind
    /// places them. Absent: every slot is the centre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub formation_radius_m: Option<f64>,
}

/// A double integrator's per-agent keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DoubleIntegratorAgent {
    /// Initial position, m.
    pub r0_m: Option<[f64; 3]>,
    /// Initial velocity, m/s.
    pub v0_mps: Option<[f64; 3]>,
}

pub struct DoubleIntegratorKind;

/// A configured `double-integrator` plant.
pub struct DoubleIntegratorSetup {
    pub config: DoubleIntegratorPlant,
    /// Per agent, in id order: initial position and velocity.
    pub r0_m: Vec<[f64; 3]>,
    pub v0_mps: Vec<[f64; 3]>,
}

/// `agents[k].<key>` missing although the plant kind needs it.
pub fn require(c: &mut Checker, k: usize, key: &str, present: bool, what: &str, kind: &str) {
    if !present {
        c.problems.push(Problem::new(
            format!("agents[{k}].{key}"),
            None,
            format!("required by plant.kind = \"{kind}\" ({what})"),
        ));
    }
}

/// Agent index (file order) of every id 1..=N, when ids are valid.
pub fn by_id(s: &Scenario) -> Vec<usize> {
    (1..=s.n_agents()).map(|id| s.agents.iter().position(|a| a.id == id).expect("validated: ids are 1..=N")).collect()
}

impl PlantKind for DoubleIntegratorKind {
    fn kind(&self) -> &'static str {
        "double-integrator"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let s = ctx.scenario;
        let config = section_as::<DoubleIntegratorPlant>(&s.plant.body, "plant", c);
        let agents = agent_keys::<DoubleIntegratorAgent>(s, c);
        if let Some(p) = &config {
            c.non_negative("plant.position_noise_std_m", p.position_noise_std_m);
            if let Some(r) = p.formation_radius_m {
                c.non_negative("plant.formation_radius_m", r);
            }
        }
        let agents = agents?;
        let kind = self.kind();
        for (k, a) in agents.iter().enumerate() {
            require(c, k, "r0_m", a.r0_m.is_some(), "initial position, m", kind);
            require(c, k, "v0_mps", a.v0_mps.is_some(), "initial velocity, m/s", kind);
            if let Some(r) = &a.r0_m {
                c.vec3(&format!("agents[{k}].r0_m"), r);
            }
            if let Some(v) = &a.v0_mps {
                c.vec3(&format!("agents[{k}].v0_mps"), v);
            }
        }
        let config = config?;
        if !ctx.ids_ok || agents.iter().any(|a| a.r0_m.is_none() || a.v0_mps.is_none()) {
            return None;
        }
        let order = by_id(s);
        Some(Arc::new(DoubleIntegratorSetup {
            config,
            r0_m: order.iter().map(|&k| agents[k].r0_m.expect("checked above")).collect(),
            v0_mps: order.iter().map(|&k| agents[k].v0_mps.expect("checked above")).collect(),
        }))
    }
}

impl PlantSetup for DoubleIntegratorSetup {
    fn kind(&self) -> &'static str {
        DoubleIntegratorKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        3
    }
    fn reading_names(&self, _s: &Scenario, _id: u32) -> Vec<String> {
        ["y_x_m", "y_y_m", "y_z_m"].map(String::from).to_vec()
    }
    fn command_len(&self) -> usize {
        3
    }
    fn command_names(&self) -> Vec<String> {
        ["u_x_mps2", "u_y_mps2", "u_z_mps2"].map(String::from).to_vec()
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        let n = setup.n_agents();
        // The formation-error metric needs the slots of a consensus formation; any other
        // algorithm has no formation, so every slot is the centre.
        let slots = match setup.algorithm_as::<ConsensusFormationSetup>() {
            Some(a) => (1..=n).map(|i| a.config.slot_m(i, n)).collect(),
            None => match self.config.formation_radius_m {
                Some(r) => (1..=n).map(|i| polygon_slot_m(r, i, n)).collect(),
                None => vec![[0.0; 3]; n as usize],
            },
        };
        Box::new(crate::double_integrator::DoubleIntegrator::new(
            self.r0_m.clone(),
            self.v0_mps.clone(),
            self.config.position_noise_std_m,
            slots,
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// Plant `null`

/// No dynamics: every agent gets `readings` zeros each step. With the `null` algorithm it
/// measures what the messaging alone costs (`orchestrator bench`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullPlant {
    /// Readings per measurement.
    pub readings: usize,
}

pub struct NullPlantKind;

impl PlantKind for NullPlantKind {
    fn kind(&self) -> &'static str {
        "null"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let config = section_as::<NullPlant>(&ctx.scenario.plant.body, "plant", c);
        agent_keys::<cohort_runtime::paper::NoAgentKeys>(ctx.scenario, c)?;
        Some(Arc::new(config?))
    }
}

impl PlantSetup for NullPlant {
    fn kind(&self) -> &'static str {
        NullPlantKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        self.readings
    }
    fn command_len(&self) -> usize {
        3
    }
    fn build(&self, _setup: &Setup) -> Box<dyn PlantModel> {
        Box::new(crate::null_plant::NullPlant { readings: self.readings })
    }
}

// ---------------------------------------------------------------------------------------------
// Algorithm `consensus-formation`

/// Formation keeping about the neighbours' published positions (the smoke scenario).
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
        polygon_slot_m(self.formation_radius_m, id, n)
    }
}

/// Slot `id` of `n` on a regular polygon of circumradius `radius_m` in the x–y plane.
pub fn polygon_slot_m(radius_m: f64, id: u32, n: u32) -> [f64; 3] {
    let a = std::f64::consts::TAU * f64::from(id - 1) / f64::from(n);
    [radius_m * a.cos(), radius_m * a.sin(), 0.0]
}

pub struct ConsensusFormationKind;

pub struct ConsensusFormationSetup {
    pub config: ConsensusFormation,
}

impl AlgorithmKind for ConsensusFormationKind {
    fn kind(&self) -> &'static str {
        "consensus-formation"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<ConsensusFormation>(&ctx.scenario.algorithm.body, "algorithm", c);
        // It flies any plant whose agents read their own 3-D position and take a 3-D
        // acceleration: the double integrator, or a user's (a Python plant) that says so.
        if let Some(p) = plant {
            let s = ctx.scenario;
            let reads_three = !ctx.ids_ok || (1..=s.n_agents()).all(|id| p.readings(s, id) == 3);
            if !reads_three || p.command_len() != 3 {
                c.fail(
                    "algorithm.kind",
                    "\"consensus-formation\"",
                    format!(
                        "needs a plant whose agents read their 3-D position and take a 3-D acceleration \
                         (as plant.kind = \"double-integrator\"), but plant.kind = {:?} does not",
                        p.kind()
                    ),
                );
            }
        }
        let a = a?;
        c.non_negative("algorithm.formation_radius_m", a.formation_radius_m);
        c.positive("algorithm.kp_per_s2", a.kp_per_s2);
        c.non_negative("algorithm.kd_per_s", a.kd_per_s);
        c.positive("algorithm.observer_l1_per_s", a.observer_l1_per_s);
        c.positive("algorithm.observer_l2_per_s2", a.observer_l2_per_s2);
        Some(Arc::new(ConsensusFormationSetup { config: a }))
    }
}

impl AlgorithmSetup for ConsensusFormationSetup {
    fn kind(&self) -> &'static str {
        ConsensusFormationKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        6
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        Box::new(crate::consensus_formation::ConsensusFormation::new(
            self.config.clone(),
            id,
            setup.n_agents(),
            &setup.agent(id).neighbours,
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// Algorithms `coast` and `null`

/// Zero command, nothing shared: lets a plant be checked on its own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coast {}

pub struct CoastKind;

/// Both algorithms command three zeros: the plant must take a three-component command.
fn needs_three_axes(kind: &str, plant: Option<&dyn PlantSetup>, c: &mut Checker) {
    if let Some(p) = plant
        && p.command_len() != 3
    {
        c.fail(
            "algorithm.kind",
            format!("{kind:?}"),
            format!("commands 3 components, but plant.kind = {:?} takes {}", p.kind(), p.command_len()),
        );
    }
}

impl AlgorithmKind for CoastKind {
    fn kind(&self) -> &'static str {
        "coast"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<Coast>(&ctx.scenario.algorithm.body, "algorithm", c);
        needs_three_axes(self.kind(), plant, c);
        Some(Arc::new(a?))
    }
}

impl AlgorithmSetup for Coast {
    fn kind(&self) -> &'static str {
        CoastKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        0
    }
    fn build(&self, _setup: &Setup, _id: u32) -> Box<dyn Algorithm> {
        Box::new(crate::coast::Coast)
    }
}

/// Zero command and `share_values` zeros shared, no computation (`orchestrator bench`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NullAlgorithm {
    /// Values per share.
    pub share_values: usize,
}

pub struct NullAlgorithmKind;

impl AlgorithmKind for NullAlgorithmKind {
    fn kind(&self) -> &'static str {
        "null"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<NullAlgorithm>(&ctx.scenario.algorithm.body, "algorithm", c);
        needs_three_axes(self.kind(), plant, c);
        Some(Arc::new(a?))
    }
}

impl AlgorithmSetup for NullAlgorithm {
    fn kind(&self) -> &'static str {
        NullAlgorithmKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        self.share_values
    }
    fn build(&self, _setup: &Setup, _id: u32) -> Box<dyn Algorithm> {
        Box::new(crate::null_algorithm::Null { share_values: self.share_values })
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    const PAPERS: &[&dyn Paper] = &[&crate::Generic];

    fn ring() -> String {
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../topologies/consensus-ring.toml")).unwrap()
    }

    fn problems(text: &str) -> Vec<String> {
        let s = parse(text, Path::new("x.toml"), &Overrides::default()).unwrap();
        configure(s, PAPERS).err().unwrap_or_default().iter().map(|p| p.to_string()).collect()
    }

    #[test]
    fn errors_name_the_key_path_inside_the_paper_sections() {
        let e = problems(&ring().replace("kp_per_s2 = 0.5", "kp_per_s2 = 0.5\ngain = 3"));
        assert!(e.iter().any(|p| p.contains("algorithm.gain")), "{e:?}");
        let e = problems(&ring().replace("r0_m = [4.0, -3.0, 1.0]", "r0_m = [4.0, -3.0]"));
        assert!(e.iter().any(|p| p.contains("agents[0].r0_m")), "{e:?}");
        let e = problems(&ring().replace("v0_mps = [0.0, 0.0, 0.0]\n", "mass_kg = 3.0\nv0_mps = [0.0, 0.0, 0.0]\n"));
        assert!(e.iter().any(|p| p.contains("agents[0].mass_kg: unknown key")), "{e:?}");
    }

    #[test]
    fn every_problem_is_reported_at_once() {
        let e = problems(&ring().replace("dt_s = 0.01", "dt_s = -0.01").replace("kp_per_s2 = 0.5", "kp_per_s2 = 0.0"));
        assert_eq!(e.len(), 2, "{e:?}");
    }

    #[test]
    fn the_consensus_ring_round_trips() {
        let s = configure(parse(&ring(), Path::new("ring.toml"), &Overrides::default()).unwrap(), PAPERS).unwrap();
        assert_eq!(s.n_agents(), 6);
        let again =
            configure(parse(&s.to_toml().unwrap(), Path::new("resolved.toml"), &Overrides::default()).unwrap(), PAPERS)
                .unwrap();
        assert_eq!(s.to_toml().unwrap(), again.to_toml().unwrap());
        assert_eq!(s.parsed.agents, again.parsed.agents);
    }
}
