//! Scenario sections of the swarm (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): the
//! `swarm` plant and the `nr-swarm` algorithm, their defaults (our values where the paper's are
//! lost, see [`crate::swarm::dynamics::setup`] and the crate README's "Swarm" section) and their validation
//! with full key paths. Both sections reject unknown keys.

use std::path::PathBuf;

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::iso::config::{non_negative, positive};
use crate::swarm::control::nav::EstimatorConfig;
use crate::swarm::control::safety::SafetyConfig;
use crate::swarm::dynamics::setup::{A_MAX_MPS2, CUBOID_M, Cuboid, R_COMM_M, T_RECONFIG_S};

fn d_a_max() -> f64 {
    A_MAX_MPS2
}
fn d_pos_noise() -> f64 {
    1e-3
}
fn d_vel_noise() -> f64 {
    1e-2
}
fn d_substeps() -> u32 {
    10
}
fn d_t_reconfig() -> f64 {
    T_RECONFIG_S
}
fn d_cuboid() -> Cuboid {
    CUBOID_M
}
fn d_r_comm() -> f64 {
    R_COMM_M
}
fn d_omega() -> f64 {
    1.0
}
fn d_two() -> f64 {
    2.0
}
fn d_horizon() -> f64 {
    2.0
}
fn d_rebuild() -> f64 {
    0.5
}

/// `[plant]` of kind `swarm`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwarmConfig {
    /// Seed of the starts and goals (`swarm_setup::draw`). Absent: the scenario's seed.
    #[serde(default)]
    pub problem_seed: Option<u64>,
    /// Per-axis acceleration limit a_max, m/s² (commands are clipped to it).
    #[serde(default = "d_a_max")]
    pub a_max_mps2: f64,
    /// Bound d̄ of the disturbance acceleration, m/s²: each vehicle, each control interval, a
    /// constant acceleration of norm d̄ in a uniformly random direction (0: none).
    #[serde(default)]
    pub disturbance_mps2: f64,
    /// σ of the white position noise of the readings, m.
    #[serde(default = "d_pos_noise")]
    pub pos_noise_m: f64,
    /// σ of the white velocity noise of the readings, m/s.
    #[serde(default = "d_vel_noise")]
    pub vel_noise_mps: f64,
    /// Sub-steps per control interval at which the plant checks for collisions.
    #[serde(default = "d_substeps")]
    pub substeps: u32,
    /// Reconfiguration time T, s: the analysis reports every vehicle's distance to its goal at T
    /// and at the end of the run.
    #[serde(default = "d_t_reconfig")]
    pub t_reconfig_s: f64,
    /// The cuboid starts and goals are drawn in, `[[x_min, x_max], [y_min, y_max], [z_min,
    /// z_max]]`, m (default the paper's [−2, 2] × [−2, 2] × [0.5, 2]; `orchestrator generate
    /// swarm` scales it with N at swarm-20's density). Only the sampling and the
    /// `outside_cuboid_substeps` count read it: nothing keeps a vehicle inside.
    #[serde(default = "d_cuboid")]
    pub cuboid_m: Cuboid,
}

impl Default for SwarmConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

impl SwarmConfig {
    /// The seed of the starts and goals of a run with `seed`.
    pub fn problem_seed(&self, seed: u64) -> u64 {
        self.problem_seed.unwrap_or(seed)
    }

    /// Every problem, with its key path.
    pub fn validate(&self) -> Vec<Problem> {
        let mut p = Vec::new();
        positive(&mut p, "plant.a_max_mps2", self.a_max_mps2);
        non_negative(&mut p, "plant.disturbance_mps2", self.disturbance_mps2);
        non_negative(&mut p, "plant.pos_noise_m", self.pos_noise_m);
        non_negative(&mut p, "plant.vel_noise_mps", self.vel_noise_mps);
        positive(&mut p, "plant.t_reconfig_s", self.t_reconfig_s);
        if !(1..=1000).contains(&self.substeps) {
            p.push(Problem::new("plant.substeps", Some(self.substeps.to_string()), "must be 1 to 1000"));
        }
        for (a, [lo, hi]) in self.cuboid_m.iter().enumerate() {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                p.push(Problem::new(
                    format!("plant.cuboid_m[{a}]"),
                    Some(format!("[{lo}, {hi}]")),
                    "must be [min, max] in m, both finite, min < max",
                ));
            }
        }
        p
    }
}

/// What a vehicle flies (`algorithm.method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SwarmMethod {
    /// The Neural-Rendezvous layer: roll the policy ahead, track the roll-out with the min-norm
    /// control about the policy's command.
    Nr,
    /// The policy alone.
    Policy,
}

impl SwarmMethod {
    pub fn name(self) -> &'static str {
        match self {
            SwarmMethod::Nr => "nr",
            SwarmMethod::Policy => "policy",
        }
    }
}

/// Which [`crate::swarm::control::obs::SwarmPolicy`] (`algorithm.policy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SwarmPolicyKind {
    /// The goal-seeking PD baseline (no avoidance), [`crate::swarm::control::pd`].
    Pd,
    /// The learned deep set of [`crate::swarm::control::policy`], read from `algorithm.weights`.
    DeepSet,
}

impl SwarmPolicyKind {
    pub fn name(self) -> &'static str {
        match self {
            SwarmPolicyKind::Pd => "pd",
            SwarmPolicyKind::DeepSet => "deep-set",
        }
    }
}

/// `[algorithm]` of kind `nr-swarm`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwarmAlgorithmConfig {
    pub method: SwarmMethod,
    pub policy: SwarmPolicyKind,
    /// The deep-set policy's weights file (safetensors, `swarm_policy`); required by
    /// `policy = "deep-set"`, refused with `pd`. A relative path is resolved against the scenario
    /// file while configuring (the resolved scenario carries it absolute).
    #[serde(default)]
    pub weights: Option<PathBuf>,
    /// Communication radius R_comm, m: shares of vehicles farther away are not read.
    #[serde(default = "d_r_comm")]
    pub r_comm_m: f64,
    /// The PD policy's natural frequency ω, 1/s (critically damped: a = ω²(g − p) − 2ωv).
    #[serde(default = "d_omega")]
    pub pd_omega_per_s: f64,
    /// Λ = λI of the composite variable s = v̂ − v_d + Λ(p̂ − p_d), 1/s.
    #[serde(default = "d_two")]
    pub lambda_per_s: f64,
    /// α of the stability condition sᵀ(u − ς) + α‖s‖² ≤ 0, 1/s.
    #[serde(default = "d_two")]
    pub alpha_per_s: f64,
    /// How far ahead the policy is rolled out, s.
    #[serde(default = "d_horizon")]
    pub horizon_s: f64,
    /// How often the roll-out is rebuilt, s (≤ horizon_s).
    #[serde(default = "d_rebuild")]
    pub rebuild_every_s: f64,
    /// `[algorithm.safety]`: the barrier filter on the final command ([`crate::swarm::control::safety`]).
    /// Absent: no filter (the paper's configuration gives none).
    #[serde(default)]
    pub safety: Option<SafetyConfig>,
    /// `[algorithm.estimator]`: the own-state Kalman filter ([`crate::swarm::control::nav`]). Absent: the
    /// vehicle flies (and shares) its raw readings.
    #[serde(default)]
    pub estimator: Option<EstimatorConfig>,
}

impl SwarmAlgorithmConfig {
    /// Every problem, with its key path (those that need the control interval: `validate_dt`).
    pub fn validate(&self) -> Vec<Problem> {
        let mut p = Vec::new();
        match (self.policy, &self.weights) {
            (SwarmPolicyKind::DeepSet, None) => {
                p.push(Problem::new("algorithm.weights", None, "policy \"deep-set\" needs its weights file"))
            }
            (SwarmPolicyKind::Pd, Some(w)) => p.push(Problem::new(
                "algorithm.weights",
                Some(format!("{:?}", w.display().to_string())),
                "policy \"pd\" has no weights: give it only with policy = \"deep-set\"",
            )),
            _ => {}
        }
        if let Some(e) = &self.estimator {
            p.extend(e.validate());
        }
        positive(&mut p, "algorithm.r_comm_m", self.r_comm_m);
        positive(&mut p, "algorithm.pd_omega_per_s", self.pd_omega_per_s);
        positive(&mut p, "algorithm.lambda_per_s", self.lambda_per_s);
        positive(&mut p, "algorithm.alpha_per_s", self.alpha_per_s);
        positive(&mut p, "algorithm.horizon_s", self.horizon_s);
        positive(&mut p, "algorithm.rebuild_every_s", self.rebuild_every_s);
        if self.rebuild_every_s > self.horizon_s {
            p.push(Problem::new(
                "algorithm.rebuild_every_s",
                Some(self.rebuild_every_s.to_string()),
                format!("longer than algorithm.horizon_s = {}: the roll-out would run out", self.horizon_s),
            ));
        }
        p
    }

    /// The problems that depend on the control interval `dt_s`: the horizon must hold at least
    /// one interval, and a rebuild falls on a step only if its period is a whole number of them.
    pub fn validate_dt(&self, dt_s: f64) -> Vec<Problem> {
        let mut p = Vec::new();
        if !dt_s.is_finite() || dt_s <= 0.0 {
            return p;
        }
        for (path, v) in [("algorithm.horizon_s", self.horizon_s), ("algorithm.rebuild_every_s", self.rebuild_every_s)]
        {
            let n = (v / dt_s).round();
            if v.is_finite() && v > 0.0 && (n < 1.0 || (n * dt_s - v).abs() > 1e-9 * v) {
                p.push(Problem::new(
                    path,
                    Some(v.to_string()),
                    format!("must be a whole number (≥ 1) of control intervals (scenario.dt_s = {dt_s})"),
                ));
            }
        }
        p
    }

    /// Control intervals per roll-out and per rebuild (after validation).
    pub fn steps(&self, dt_s: f64) -> (usize, usize) {
        ((self.horizon_s / dt_s).round() as usize, (self.rebuild_every_s / dt_s).round() as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_bad_values_are_named() {
        assert!(SwarmConfig::default().validate().is_empty());
        let a: SwarmAlgorithmConfig = toml::from_str("method = \"nr\"\npolicy = \"pd\"").unwrap();
        assert!(a.validate().is_empty() && a.validate_dt(0.1).is_empty());
        assert_eq!(a.steps(0.1), (20, 5));
        assert_eq!(SwarmConfig::default().cuboid_m, [[-2.0, 2.0], [-2.0, 2.0], [0.5, 2.0]]);
        let cuboid_m = [[-2.0, 2.0], [2.0, -2.0], [0.5, f64::NAN]];
        let bad =
            SwarmConfig { a_max_mps2: 0.0, disturbance_mps2: -1.0, substeps: 0, cuboid_m, ..SwarmConfig::default() };
        let paths: Vec<String> = bad.validate().iter().map(|p| p.to_string()).collect();
        assert!(!paths.iter().any(|p| p.contains("plant.cuboid_m[0]")), "{paths:?}");
        for want in [
            "plant.a_max_mps2",
            "plant.disturbance_mps2",
            "plant.substeps",
            "plant.cuboid_m[1] = [2, -2]",
            "plant.cuboid_m[2] = [0.5, NaN]",
        ] {
            assert!(paths.iter().any(|p| p.contains(want)), "{want} not in {paths:?}");
        }
        let b = SwarmAlgorithmConfig { rebuild_every_s: 3.0, horizon_s: 0.25, ..a };
        assert!(b.validate().iter().any(|p| p.to_string().contains("algorithm.rebuild_every_s")));
        assert!(b.validate_dt(0.1).iter().any(|p| p.to_string().contains("algorithm.horizon_s")));
        // deep-set needs its weights; pd refuses them.
        let d: SwarmAlgorithmConfig = toml::from_str("method = \"nr\"\npolicy = \"deep-set\"").unwrap();
        let e: Vec<String> = d.validate().iter().map(|p| p.to_string()).collect();
        assert!(e.len() == 1 && e[0].contains("algorithm.weights") && e[0].contains("needs"), "{e:?}");
        let w = SwarmAlgorithmConfig { weights: Some("w.safetensors".into()), ..d.clone() };
        assert!(w.validate().is_empty());
        let e: Vec<String> = SwarmAlgorithmConfig { policy: SwarmPolicyKind::Pd, ..w }
            .validate()
            .iter()
            .map(|p| p.to_string())
            .collect();
        assert!(e.len() == 1 && e[0].contains("algorithm.weights") && e[0].contains("w.safetensors"), "{e:?}");
        assert!(toml::from_str::<SwarmAlgorithmConfig>("method = \"nr\"\npolicy = \"glas\"").is_err());
        assert!(toml::from_str::<SwarmConfig>("radius = 1.0").is_err());
    }
}
