//! Building seed 002's plant and agents from validated scenario sections ("Explainable
//! AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation", Sec. 7): the plant
//! of both spacecraft, agent 1 the leader and agent 2 the follower, each with its attitude
//! control system (MEKF and attitude law) and relative law.

use cohort_runtime::model::Algorithm;
use cohort_scenario::Problem;

use crate::flight::acs::Acs;
use crate::flight::config::VtxoAlgorithmConfig;
use crate::flight::{follower, leader};
use crate::model::config::VtxoPlantConfig;
use crate::model::quaternion::{Quat, V3};
use crate::model::{orbit, plant};

/// The plant of a scenario, or every problem with its key path.
pub fn build_plant(
    cfg: &VtxoPlantConfig,
    n_agents: u32,
    dt_s: f64,
    seed: u64,
) -> Result<plant::VtxoPlant, Vec<Problem>> {
    let problems = cfg.validate("plant", n_agents, dt_s);
    if !problems.is_empty() {
        return Err(problems);
    }
    Ok(plant::VtxoPlant::new(cfg, dt_s, seed))
}

/// Agent `id`'s algorithm (1 leader, 2 follower), or every problem with its key path.
pub fn build_agent(cfg: &VtxoAlgorithmConfig, id: u32) -> Result<Box<dyn Algorithm>, Vec<Problem>> {
    let mut problems = cfg.validate("algorithm");
    if id != 1 && id != 2 {
        problems.push(Problem::new(
            "agents[].id",
            Some(id.to_string()),
            "vtxo has agent 1 (leader) and agent 2 (follower)",
        ));
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    Ok(match id {
        1 => Box::new(build_leader(cfg)),
        _ => Box::new(build_follower(cfg)),
    })
}

fn acs_of(cfg: &VtxoAlgorithmConfig, id: u32) -> Acs {
    Acs::new(
        cfg.mekf.variant,
        cfg.mekf.model(id, cfg.inertia_kg_m2),
        cfg.attitude_law(),
        Quat::from(cfg.attitude.q_target_body_eci),
    )
}

/// The leader of a validated configuration.
pub fn build_leader(cfg: &VtxoAlgorithmConfig) -> leader::Leader {
    let r = &cfg.relative;
    leader::Leader::new(
        acs_of(cfg, 1),
        cfg.leader_law(),
        cfg.mass_kg,
        orbit::MU_EARTH_M3PS2,
        V3::from(r.r_target_eci_m),
        V3::from(r.v_target_eci_mps),
    )
}

/// The follower of a validated configuration.
pub fn build_follower(cfg: &VtxoAlgorithmConfig) -> follower::Follower {
    let r = &cfg.relative;
    follower::Follower::new(
        acs_of(cfg, 2),
        cfg.relative_law(),
        cfg.mass_kg,
        orbit::MU_EARTH_M3PS2,
        V3::from(r.r_target_eci_m),
        V3::from(r.v_target_eci_mps),
        cfg.relative_filter(),
    )
}
