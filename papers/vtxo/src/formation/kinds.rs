//! The registry's view of seed 002: the `vtxo` plant kind (the whole truth of both spacecraft,
//! [`crate::model::plant::VtxoPlant`]) and the `vtxo-formation` algorithm kind (agent 1 the leader,
//! agent 2 the follower, [`crate::flight::leader`], [`crate::flight::follower`]). Each parses its section with the
//! typed configuration of [`crate::model::config`] / [`crate::flight::config`] and reports every
//! problem with its key path; the pair is checked where both name a target
//! ([`crate::config::check_pair`]).
//!
//! Scenario-level rules of the paper: exactly two agents (the runtime checks the ids are 1 and 2),
//! no per-agent keys (the roles are fixed by id, both spacecraft alike, App. E), and each agent
//! reads the other's shares (Sec. 2.10: the follower needs û_L, r̂_L, v̂_L and ã_L; the leader
//! û_F, r̂_rel, v̂_rel for (70)).

use std::collections::BTreeMap;
use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, agent_keys,
    section_as, table_of,
};
use cohort_scenario::{Checker, Scenario};

use crate::flight::config::{LeaderControl, Phase, RelativeController, ScienceAttitude, VtxoAlgorithmConfig};
use crate::flight::layout::{COMMAND_LEN, READINGS_LEN};
use crate::flight::mekf::MekfVariant;
use crate::flight::relative_control::Switching;
use crate::flight::share::{FOLLOWER_SHARE_LEN, LEADER_SHARE_LEN};
use crate::model::config::{AGENTS_REASON, VtxoPlantConfig};

pub const PLANT_KIND: &str = "vtxo";
pub const ALGORITHM_KIND: &str = "vtxo-formation";

pub struct VtxoPlantKind;

impl PlantKind for VtxoPlantKind {
    fn kind(&self) -> &'static str {
        PLANT_KIND
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let p = section_as::<VtxoPlantConfig>(&ctx.scenario.plant.body, "plant", c);
        let agents = agent_keys::<cohort_runtime::paper::NoAgentKeys>(ctx.scenario, c);
        let n = ctx.scenario.agents.len();
        if n != 2 {
            c.fail("agents", format!("{n} entries"), AGENTS_REASON);
        }
        let p = p?;
        c.problems.extend(p.validate_section("plant"));
        agents?;
        Some(Arc::new(p))
    }
}

impl PlantSetup for VtxoPlantConfig {
    fn kind(&self) -> &'static str {
        PLANT_KIND
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
        Box::new(crate::model::plant::VtxoPlant::new(self, setup.scenario.dt_s, setup.scenario.seed))
    }
}

pub struct VtxoFormationKind;

/// Each of the two agents must read the other's shares.
/// The checks every pair-of-spacecraft algorithm kind makes: the plant is `vtxo`, and each agent
/// lists the other, because `what` passes between them.
pub(crate) fn check_pair_kind(s: &Scenario, kind: &str, what: &str, c: &mut Checker) {
    if s.plant.kind != PLANT_KIND {
        c.fail("algorithm.kind", format!("{kind:?}"), format!("needs plant.kind = {PLANT_KIND:?}"));
    }
    for (k, ag) in s.agents.iter().enumerate() {
        let other = if ag.id == 1 { 2 } else { 1 };
        if !ag.neighbours.contains(&other) {
            c.fail(
                format!("agents[{k}].neighbours"),
                format!("{:?}", ag.neighbours),
                format!("agent {} must list agent {other}: {what}", ag.id),
            );
        }
    }
}

fn check_links(s: &Scenario, c: &mut Checker) {
    for (k, a) in s.agents.iter().enumerate() {
        let other = match a.id {
            1 => 2,
            2 => 1,
            _ => continue,
        };
        if !a.neighbours.contains(&other) {
            let (me, what) = if a.id == 1 {
                ("the leader", "û_F, r̂_rel and v̂_rel (Sec. 2.10, (70))")
            } else {
                ("the follower", "û_L, r̂_L, v̂_L and ã_L ((64)–(66), its v̂_rel)")
            };
            c.fail(
                format!("agents[{k}].neighbours"),
                format!("{:?}", a.neighbours),
                format!("{me} (agent {}) reads agent {other}'s shares, {what}: must list {other}", a.id),
            );
        }
    }
}

impl AlgorithmKind for VtxoFormationKind {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<VtxoAlgorithmConfig>(&ctx.scenario.algorithm.body, "algorithm", c);
        if ctx.scenario.plant.kind != PLANT_KIND {
            c.fail("algorithm.kind", format!("{ALGORITHM_KIND:?}"), format!("needs plant.kind = {PLANT_KIND:?}"));
        }
        check_links(ctx.scenario, c);
        let a = a?;
        c.problems.extend(a.validate("algorithm"));
        if let Some(p) = plant.and_then(|p| p.downcast_ref::<VtxoPlantConfig>()) {
            c.problems.extend(crate::config::check_pair(p, &a));
        }
        Some(Arc::new(a))
    }
}

impl AlgorithmSetup for VtxoAlgorithmConfig {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        LEADER_SHARE_LEN.max(FOLLOWER_SHARE_LEN)
    }
    fn build(&self, _setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        // Validated: the ids are 1 and 2.
        match id {
            1 => Box::new(crate::formation::build_leader(self)),
            _ => Box::new(crate::formation::build_follower(self)),
        }
    }
    fn labels(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        let phase = match self.phase {
            Phase::Transient => "transient",
            Phase::Science => "science",
        };
        m.insert("phase".into(), phase.into());
        let attitude = match (self.phase, self.attitude.science) {
            (Phase::Transient, _) => "lyapunov",
            (Phase::Science, ScienceAttitude::Pd) => "pd",
            (Phase::Science, ScienceAttitude::Smc) => "smc",
        };
        m.insert("attitude_law".into(), attitude.into());
        let relative = match (self.relative.controller, self.relative.switching) {
            (RelativeController::Smc, Switching::Sign) => "smc-sign",
            (RelativeController::Smc, Switching::Sat) => "smc-sat",
            (RelativeController::Pd, _) => "pd",
            (RelativeController::Off, _) => "off",
        };
        m.insert("relative_law".into(), relative.into());
        let leader = match self.leader.control {
            LeaderControl::Drift => "drift",
            LeaderControl::Smc => "smc",
        };
        m.insert("leader_control".into(), leader.into());
        let mekf = match self.mekf.variant {
            MekfVariant::ModelReplacement => "model-replacement",
            MekfVariant::Full => "full",
        };
        m.insert("mekf".into(), mekf.into());
        m
    }
}
