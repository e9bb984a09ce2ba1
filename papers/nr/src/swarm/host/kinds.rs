//! The swarm of "Neural-Rendezvous" (arXiv:2208.04883, Sec. 7.2) in the registry: the plant kind
//! `swarm` ([`crate::swarm::dynamics::plant`]) and the algorithm kind `nr-swarm` ([`crate::swarm::control::agent`]).
//!
//! Checks beyond the sections' own (`SwarmConfig::validate`, `SwarmAlgorithmConfig::validate`):
//!
//! - the agents carry no per-agent keys: the plant draws every start and goal from
//!   `plant.problem_seed` (absent: the scenario's seed, written into the resolved scenario), and a
//!   seed whose problem cannot be drawn for N vehicles is refused;
//! - `nr-swarm` flies only the `swarm` plant, and every agent must list at least the vehicles it
//!   could meet within R_comm (the rule of [`crate::swarm::dynamics::neighbours`] on the plant's
//!   problem; all-to-all passes): who is within R_comm changes as the vehicles move, so each vehicle
//!   subscribes to all it may meet and drops the shares from beyond R_comm itself;
//! - the roll-out horizon and the rebuild period are whole numbers of control intervals;
//! - a_max comes from the plant section (the policy clips to the plant's limit);
//! - `algorithm.weights` (policy `deep-set`), relative to the scenario file, is resolved while
//!   configuring (the resolved scenario carries it absolute), then loaded and checked
//!   ([`DeepSetPolicy::load`]); a file that does not load is a problem at `algorithm.weights`
//!   naming the file and the reason. The loaded policy is shared by every agent of the process.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, NoAgentKeys, PlantKind, PlantSetup, Setup,
    agent_keys, section_as, table_of,
};
use cohort_scenario::{Checker, Scenario};

use crate::swarm::config::{SwarmAlgorithmConfig, SwarmConfig, SwarmPolicyKind};
use crate::swarm::control::agent::{SwarmAgent, SwarmAgentParams};
use crate::swarm::control::obs::SwarmPolicy;
use crate::swarm::control::pd::PdPolicy;
use crate::swarm::control::policy::DeepSetPolicy;
use crate::swarm::dynamics::messages::{COMMAND_LEN, READINGS_LEN, SHARE_LEN};
use crate::swarm::dynamics::neighbours::{ESTIMATE_MARGIN_M, STRAY_M, neighbour_lists, reach_m};
use crate::swarm::dynamics::plant::{SwarmParams, SwarmPlant};
use crate::swarm::dynamics::setup::draw_in;

/// The plant kind's name.
pub const PLANT_KIND: &str = "swarm";
/// The algorithm kind's name.
pub const ALGORITHM_KIND: &str = "nr-swarm";

pub struct SwarmKind;

impl PlantKind for SwarmKind {
    fn kind(&self) -> &'static str {
        PLANT_KIND
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let p = section_as::<SwarmConfig>(&ctx.scenario.plant.body, "plant", c);
        let agents = agent_keys::<NoAgentKeys>(ctx.scenario, c);
        let mut p = p?;
        c.problems.extend(p.validate());
        agents?;
        let s = ctx.scenario;
        let seed = p.problem_seed(s.scenario.seed);
        // A bad cuboid is already a problem at plant.cuboid_m[a]; nothing to draw in.
        let drawable = p.cuboid_m.iter().all(|[lo, hi]| lo.is_finite() && hi.is_finite() && lo < hi);
        if drawable && let Err(e) = draw_in(s.n_agents() as usize, seed, &p.cuboid_m) {
            let path = if p.problem_seed.is_some() { "plant.problem_seed" } else { "scenario.seed" };
            c.fail(path, seed, format!("no swarm problem for {} agents: {e}", s.n_agents()));
        }
        p.problem_seed = Some(seed);
        Some(Arc::new(p))
    }
}

impl SwarmConfig {
    pub fn params(&self) -> SwarmParams {
        SwarmParams {
            a_max_mps2: self.a_max_mps2,
            disturbance_mps2: self.disturbance_mps2,
            pos_noise_m: self.pos_noise_m,
            vel_noise_mps: self.vel_noise_mps,
            substeps: self.substeps,
            t_reconfig_s: self.t_reconfig_s,
            cuboid_m: self.cuboid_m,
        }
    }
}

impl PlantSetup for SwarmConfig {
    fn kind(&self) -> &'static str {
        PLANT_KIND
    }
    fn link_frame(&self) -> cohort_runtime::paper::LinkFrame {
        cohort_runtime::paper::LinkFrame::Relative
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        READINGS_LEN
    }
    fn command_len(&self) -> usize {
        COMMAND_LEN
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        let seed = setup.scenario.seed;
        let plant = SwarmPlant::new(self.params(), setup.n_agents() as usize, self.problem_seed(seed), seed)
            .unwrap_or_else(|e| panic!("validated while configuring: {e}"));
        Box::new(plant)
    }
}

/// The configured `nr-swarm` section, the plant's acceleration limit and the loaded deep-set
/// policy (when the section names one).
pub struct SwarmSetup {
    pub config: SwarmAlgorithmConfig,
    pub a_max_mps2: f64,
    /// The plant's reconfiguration time T, s.
    pub t_reconfig_s: f64,
    pub deep_set: Option<Arc<DeepSetPolicy>>,
}

impl SwarmSetup {
    /// The agent parameters for control interval `dt_s`.
    pub fn params(&self, dt_s: f64) -> SwarmAgentParams {
        let c = &self.config;
        let (horizon_steps, rebuild_steps) = c.steps(dt_s);
        SwarmAgentParams {
            method: c.method,
            r_comm_m: c.r_comm_m,
            a_max_mps2: self.a_max_mps2,
            lambda_per_s: c.lambda_per_s,
            alpha_per_s: c.alpha_per_s,
            horizon_steps,
            rebuild_steps,
            t_reconfig_s: self.t_reconfig_s,
            safety: c.safety,
            estimator: c.estimator,
        }
    }

    /// The policy the configuration names (after validation: a deep-set setup holds its policy).
    pub fn policy(&self) -> Arc<dyn SwarmPolicy> {
        match self.config.policy {
            SwarmPolicyKind::Pd => {
                Arc::new(PdPolicy { omega_per_s: self.config.pd_omega_per_s, a_max_mps2: self.a_max_mps2 })
            }
            SwarmPolicyKind::DeepSet => self.deep_set.clone().expect("loaded while configuring"),
        }
    }
}

pub struct NrSwarmKind;

impl AlgorithmKind for NrSwarmKind {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<SwarmAlgorithmConfig>(&ctx.scenario.algorithm.body, "algorithm", c);
        let s = ctx.scenario;
        if s.plant.kind != PLANT_KIND {
            c.fail(
                "algorithm.kind",
                format!("{ALGORITHM_KIND:?}"),
                format!("needs plant.kind = {PLANT_KIND:?} (its readings and limits)"),
            );
        }
        let swarm = plant.and_then(|p| p.downcast_ref::<SwarmConfig>());
        let r_comm_m = a.as_ref().map_or(crate::swarm::dynamics::setup::R_COMM_M, |a| a.r_comm_m);
        // O(N²) draws and segment distances: the orchestrator's check before it spawns anything,
        // not every child's again at start-up (200 processes of a 200-vehicle swarm).
        if let Some(p) = swarm
            && cohort_runtime::paper::deep_checks()
        {
            check_neighbours(s, p, r_comm_m, c);
        }
        let mut config = a?;
        c.problems.extend(config.validate());
        c.problems.extend(config.validate_dt(s.scenario.dt_s));
        let a_max_mps2 = swarm.map_or(crate::swarm::dynamics::setup::A_MAX_MPS2, |p| p.a_max_mps2);
        let t_reconfig_s = swarm.map_or(crate::swarm::dynamics::setup::T_RECONFIG_S, |p| p.t_reconfig_s);
        if let Some(safety) = &config.safety {
            c.problems.extend(safety.validate(a_max_mps2));
        }
        if let Some(w) = &config.weights {
            config.weights = Some(PathBuf::from(s.resolve_path(&w.to_string_lossy())));
        }
        // Only a deep-set section loads (a pd one naming weights is refused by `validate`).
        let deep_set = match (config.policy, &config.weights) {
            (SwarmPolicyKind::DeepSet, Some(path)) => match DeepSetPolicy::load(path) {
                Ok(p) => Some(Arc::new(p)),
                Err(e) => {
                    c.fail("algorithm.weights", format!("{:?}", path.display().to_string()), e.problem.to_string());
                    None
                }
            },
            _ => None,
        };
        Some(Arc::new(SwarmSetup { config, a_max_mps2, t_reconfig_s, deep_set }))
    }
}

/// Every agent must list (at least) the vehicles the neighbour rule pairs it with on the plant's
/// problem ([`neighbour_lists`]): the others it could meet within R_comm. All-to-all lists pass.
/// Nothing to check when the problem cannot be drawn (the plant's problem already).
fn check_neighbours(s: &Scenario, plant: &SwarmConfig, r_comm_m: f64, c: &mut Checker) {
    let seed = plant.problem_seed(s.scenario.seed);
    let Ok((starts, goals)) = draw_in(s.n_agents() as usize, seed, &plant.cuboid_m) else { return };
    if !(r_comm_m.is_finite() && r_comm_m > 0.0) {
        return;
    }
    let need = neighbour_lists(&starts, &goals, r_comm_m);
    for (k, agent) in s.agents.iter().enumerate() {
        let Some(want) = need.get((agent.id as usize).wrapping_sub(1)) else { continue };
        let missing: Vec<u32> = want.iter().copied().filter(|j| !agent.neighbours.contains(j)).collect();
        if !missing.is_empty() {
            c.fail(
                format!("agents[{k}].neighbours"),
                format!("{:?}", agent.neighbours),
                format!(
                    "must also list {missing:?}: their start→goal segments come within {:.2} m of this one's \
                     (r_comm_m + 2 × {STRAY_M} m stray + {ESTIMATE_MARGIN_M} m), so they may meet within R_comm \
                     (problem seed {seed}; papers/nr/README.md, \"Neighbours\")",
                    reach_m(r_comm_m)
                ),
            );
        }
    }
}

impl AlgorithmSetup for SwarmSetup {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        SHARE_LEN
    }
    fn build(&self, setup: &Setup, _id: u32) -> Box<dyn Algorithm> {
        let dt_s = setup.scenario.dt_s;
        Box::new(SwarmAgent::new(self.params(dt_s), dt_s, self.policy()))
    }
    fn labels(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("method".to_string(), self.config.method.name().to_string()),
            ("policy".to_string(), self.config.policy.name().to_string()),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::host::kinds::tests::{configured, file};
    use crate::swarm::config::SwarmMethod;

    #[test]
    fn the_shipped_swarms_configure_and_resolve_their_problem_seed() {
        for (name, n) in [("swarm-8.toml", 8), ("swarm-20.toml", 20), ("swarm-20-disturbed.toml", 20)] {
            let s = configured(&file(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(s.n_agents(), n);
            assert_eq!(s.plant_as::<SwarmConfig>().unwrap().problem_seed, Some(s.scenario.seed));
            let a = s.algorithm_as::<SwarmSetup>().unwrap();
            assert_eq!((a.a_max_mps2, a.params(0.1).horizon_steps, a.params(0.1).rebuild_steps), (2.0, 20, 5));
            // The paper's configuration: NR over the committed deep set, its path resolved.
            assert_eq!((a.config.method, a.config.policy), (SwarmMethod::Nr, SwarmPolicyKind::DeepSet));
            assert!(a.config.weights.as_ref().unwrap().is_absolute() && a.deep_set.is_some());
            let again = configured(&s.to_toml().unwrap()).unwrap();
            assert_eq!(again.to_toml().unwrap(), s.to_toml().unwrap());
        }
    }

    #[test]
    fn every_bad_key_is_reported_with_its_path() {
        let base = file("swarm-8.toml");
        let e = configured(&base.replace("neighbours = [1, 2, 3, 4, 5, 6, 7]", "neighbours = [1, 2]")).unwrap_err();
        assert!(e.contains("agents[7].neighbours") && e.contains("must also list [3, 4, 5, 6, 7]"), "{e}");
        assert!(e.contains("3.05 m") && e.contains("problem seed 1"), "{e}");
        let e = configured(&base.replace("rebuild_every_s = 0.5", "rebuild_every_s = 0.55")).unwrap_err();
        assert!(e.contains("algorithm.rebuild_every_s"), "{e}");
        let weights = "weights = \"../papers/nr/weights/swarm.safetensors\"\n";
        // The PD baseline stays selectable (without weights), and refuses them.
        let pd =
            configured(&base.replace("policy = \"deep-set\"\n", "policy = \"pd\"\n").replace(weights, "")).unwrap();
        let a = pd.algorithm_as::<SwarmSetup>().unwrap();
        assert!(a.config.policy == SwarmPolicyKind::Pd && a.deep_set.is_none() && a.config.weights.is_none());
        let e = configured(&base.replace("policy = \"deep-set\"\n", "policy = \"pd\"\n")).unwrap_err();
        assert!(e.contains("algorithm.weights") && e.contains("swarm.safetensors") && e.contains("\"pd\""), "{e}");
        let e = configured(&base.replace(weights, "")).unwrap_err();
        assert!(e.contains("algorithm.weights") && e.contains("needs its weights file"), "{e}");
        // A missing file, and a file that is not a swarm policy (the ISO network), are refused
        // naming the key, the file and the reason.
        let e = configured(&base.replace("swarm.safetensors", "none.safetensors")).unwrap_err();
        assert!(e.contains("algorithm.weights") && e.contains("none.safetensors") && e.contains("cannot read"), "{e}");
        let e = configured(&base.replace("swarm.safetensors", "sn-dnn.safetensors")).unwrap_err();
        assert!(
            e.contains("algorithm.weights") && e.contains("sn-dnn.safetensors") && e.contains("cohort_swarm_policy"),
            "{e}"
        );
        let e = configured(&base.replace("substeps = 10", "substeps = 0\nradius = 2")).unwrap_err();
        assert!(e.contains("plant"), "{e}");
        let e = configured(&base.replace("kind = \"swarm\"", "kind = \"iso-encounter\"")).unwrap_err();
        assert!(e.contains("algorithm.kind"), "{e}");
    }
}
