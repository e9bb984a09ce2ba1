//! The algorithm section (`[algorithm]`, kind "vtxo") of a seed-002 scenario, shared by the
//! leader (agent 1) and the follower (agent 2). Defaults: Sec. 7 (relative SMC, k = Z = 1, sign),
//! Table 4 (science attitude gains), the mode of Table 2 for the Lyapunov gains (Sec. 4: "gains …
//! using the mode of data set"), and Tables E.10–E.12 for what the MEKF assumes.

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::config::Checker;
use crate::flight::attitude_control::AttitudeLaw;
use crate::flight::mekf::{FilterModel, MekfVariant};
use crate::flight::relative_control::{RelativeLaw, Switching};
use crate::flight::relative_filter::RelativeFilterConfig;
use crate::model::config::StarTrackerConfig;

/// The ACS phase (Sec. 2.1): which attitude law flies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Lyapunov (57).
    Transient,
    /// `attitude.science` (PD (54) or SMC (58)–(60)).
    Science,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScienceAttitude {
    Pd,
    Smc,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RelativeController {
    Smc,
    Pd,
    Off,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LeaderControl {
    /// û_L = 0 (Sec. 7).
    #[default]
    Drift,
    /// (70) with the follower's previous-step command.
    Smc,
}

/// `[algorithm]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VtxoAlgorithmConfig {
    pub phase: Phase,
    /// The mass the agents assume (force = mass × commanded acceleration), kg.
    pub mass_kg: f64,
    /// J̄ the agents assume (E.1), kg·m².
    pub inertia_kg_m2: [f64; 3],
    pub mekf: MekfConfig,
    pub attitude: AttitudeControlConfig,
    pub relative: RelativeControlConfig,
    pub leader: LeaderConfig,
}

impl Default for VtxoAlgorithmConfig {
    fn default() -> Self {
        Self {
            phase: Phase::Science,
            mass_kg: 10.2,
            inertia_kg_m2: [0.1383, 0.1577, 0.1039],
            mekf: MekfConfig::default(),
            attitude: AttitudeControlConfig::default(),
            relative: RelativeControlConfig::default(),
            leader: LeaderConfig::default(),
        }
    }
}

/// `[algorithm.mekf]`: the filter and the sensor statistics it assumes (3σ).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MekfConfig {
    /// "model-replacement" (46, 9 states) or "full" (45, 12 states).
    #[serde(default = "model_replacement")]
    pub variant: MekfVariant,
    #[serde(default = "gyro_noise")]
    pub gyro_noise_3sigma_rad_s: f64,
    #[serde(default = "gyro_bias")]
    pub gyro_bias_3sigma_rad_s: f64,
    #[serde(default = "hour_s")]
    pub gyro_bias_tau_s: f64,
    #[serde(default = "star_leader")]
    pub star_tracker_leader: StarTrackerConfig,
    #[serde(default = "star_follower")]
    pub star_tracker_follower: StarTrackerConfig,
    /// White torque per step the filter expects: w_ω and w_τ (1 mN·m each) together.
    #[serde(default = "torque_noise")]
    pub torque_noise_3sigma_n_m: f64,
    /// The wheel bias b_τ (full filter only).
    #[serde(default = "torque_bias")]
    pub torque_bias_3sigma_n_m: f64,
}

fn model_replacement() -> MekfVariant {
    MekfVariant::ModelReplacement
}
fn gyro_noise() -> f64 {
    22.5e-6
}
fn gyro_bias() -> f64 {
    3f64.to_radians() / 3600.0
}
fn hour_s() -> f64 {
    3600.0
}
fn star_leader() -> StarTrackerConfig {
    crate::model::config::SensorsConfig::default().star_tracker_leader
}
fn star_follower() -> StarTrackerConfig {
    crate::model::config::SensorsConfig::default().star_tracker_follower
}
fn torque_noise() -> f64 {
    2f64.sqrt() * 1e-3
}
fn torque_bias() -> f64 {
    1e-3
}

impl Default for MekfConfig {
    fn default() -> Self {
        Self {
            variant: model_replacement(),
            gyro_noise_3sigma_rad_s: gyro_noise(),
            gyro_bias_3sigma_rad_s: gyro_bias(),
            gyro_bias_tau_s: hour_s(),
            star_tracker_leader: star_leader(),
            star_tracker_follower: star_follower(),
            torque_noise_3sigma_n_m: torque_noise(),
            torque_bias_3sigma_n_m: torque_bias(),
        }
    }
}

impl MekfConfig {
    /// The 1σ model of agent `id` (1 leader, 2 follower).
    pub fn model(&self, id: u32, inertia_kg_m2: [f64; 3]) -> FilterModel {
        let st = if id == 1 { &self.star_tracker_leader } else { &self.star_tracker_follower };
        FilterModel {
            gyro_noise_sigma_rad_s: self.gyro_noise_3sigma_rad_s / 3.0,
            gyro_bias_sigma_rad_s: self.gyro_bias_3sigma_rad_s / 3.0,
            gyro_bias_tau_s: self.gyro_bias_tau_s,
            star_noise_sigma_rad: st.noise_3sigma_rad / 3.0,
            star_bias_sigma_rad: st.bias_3sigma_rad / 3.0,
            star_bias_tau_s: st.bias_tau_s,
            torque_noise_sigma_n_m: self.torque_noise_3sigma_n_m / 3.0,
            torque_bias_sigma_n_m: self.torque_bias_3sigma_n_m / 3.0,
            inertia_kg_m2,
        }
    }
}

/// `[algorithm.attitude]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttitudeControlConfig {
    /// q_f, scalar last, ECI → body.
    pub q_target_body_eci: [f64; 4],
    /// The science-phase law.
    pub science: ScienceAttitude,
    pub lyapunov: LyapunovGains,
    pub pd: PdGains,
    pub smc: SmcGains,
}

impl Default for AttitudeControlConfig {
    fn default() -> Self {
        Self {
            q_target_body_eci: [0.0, 0.0, 0.0, 1.0],
            science: ScienceAttitude::Smc,
            lyapunov: LyapunovGains::default(),
            pd: PdGains::default(),
            smc: SmcGains::default(),
        }
    }
}

/// (57): k₁ (N·m), k₂ (N·m·s); default the mode of Table 2.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LyapunovGains {
    pub k1: f64,
    pub k2: f64,
}
impl Default for LyapunovGains {
    fn default() -> Self {
        Self { k1: 0.085, k2: 0.25 }
    }
}

/// (54)–(55), Table 4's k̂_PD.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PdGains {
    pub k_p: f64,
    pub k_d: f64,
}
impl Default for PdGains {
    fn default() -> Self {
        Self { k_p: 0.1208, k_d: 0.3786 }
    }
}

/// (58)–(60), (63), Table 4's k̂_SMC = [z, k_SMC, ε].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SmcGains {
    pub z: f64,
    pub k: f64,
    pub epsilon: f64,
}
impl Default for SmcGains {
    fn default() -> Self {
        Self { z: 2.9947, k: 0.0193, epsilon: 0.2601 }
    }
}

/// `[algorithm.relative]`: the follower's relative-position controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RelativeControlConfig {
    pub controller: RelativeController,
    /// "sign" (Sec. 7) or "sat" (67).
    pub switching: Switching,
    /// r_rel^f (89), ECI, m.
    pub r_target_eci_m: [f64; 3],
    /// v_rel^f (88), ECI, m/s.
    pub v_target_eci_mps: [f64; 3],
    pub smc: RelativeSmcGains,
    pub pd: RelativePdGains,
    pub navigation: RelativeNavigation,
    /// What the filter assumes (`navigation = "filter"` only).
    pub filter: RelativeFilterConfig,
}

impl Default for RelativeControlConfig {
    fn default() -> Self {
        Self {
            controller: RelativeController::Smc,
            switching: Switching::Sign,
            r_target_eci_m: [0.0, 0.0, 1e3],
            v_target_eci_mps: [0.0; 3],
            smc: RelativeSmcGains::default(),
            pd: RelativePdGains::default(),
            navigation: RelativeNavigation::default(),
            filter: RelativeFilterConfig::default(),
        }
    }
}

/// (64)–(67): k (1/s), Z per axis (m/s²), ε per axis (m/s, used by "sat" only; the paper gives
/// none: 0.05 m/s, so that Z·dt/ε = 0.2 at dt = 10 ms, well inside the sampled law's stability
/// limit of 2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RelativeSmcGains {
    pub k: f64,
    pub z_mps2: [f64; 3],
    pub epsilon_mps: [f64; 3],
}
impl Default for RelativeSmcGains {
    fn default() -> Self {
        Self { k: 1.0, z_mps2: [1.0; 3], epsilon_mps: [0.05; 3] }
    }
}

/// (56): P (1/s²), D (1/s); Sec. 7: 1 and 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RelativePdGains {
    pub p: f64,
    pub d: f64,
}
impl Default for RelativePdGains {
    fn default() -> Self {
        Self { p: 1.0, d: 1.0 }
    }
}

/// How the follower estimates r_rel, v_rel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RelativeNavigation {
    /// Sec. 7: each sensor read for its own state, v̂_rel integrated from the accelerometers.
    #[default]
    DeadReckoning,
    /// Ours: the readings fused by [`crate::flight::relative_filter`].
    Filter,
}

/// `[algorithm.leader]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct LeaderConfig {
    pub control: LeaderControl,
}

impl VtxoAlgorithmConfig {
    /// The attitude law the phase selects.
    pub fn attitude_law(&self) -> AttitudeLaw {
        let a = &self.attitude;
        match (self.phase, a.science) {
            (Phase::Transient, _) => AttitudeLaw::Lyapunov { k1: a.lyapunov.k1, k2: a.lyapunov.k2 },
            (Phase::Science, ScienceAttitude::Pd) => AttitudeLaw::Pd { k_p: a.pd.k_p, k_d: a.pd.k_d },
            (Phase::Science, ScienceAttitude::Smc) => {
                AttitudeLaw::Smc { z: a.smc.z, k: a.smc.k, epsilon: a.smc.epsilon }
            }
        }
    }

    /// The follower's relative law.
    pub fn relative_law(&self) -> RelativeLaw {
        let r = &self.relative;
        match r.controller {
            RelativeController::Smc => RelativeLaw::Smc {
                k: r.smc.k,
                z_mps2: r.smc.z_mps2,
                epsilon_mps: r.smc.epsilon_mps,
                switching: r.switching,
            },
            RelativeController::Pd => RelativeLaw::Pd { p: r.pd.p, d: r.pd.d },
            RelativeController::Off => RelativeLaw::Off,
        }
    }

    /// The follower's navigation filter, when it flies one.
    pub fn relative_filter(&self) -> Option<RelativeFilterConfig> {
        match self.relative.navigation {
            RelativeNavigation::DeadReckoning => None,
            RelativeNavigation::Filter => Some(self.relative.filter.clone()),
        }
    }

    /// The SMC law (70) the leader flies when `leader.control = "smc"`.
    pub fn leader_law(&self) -> RelativeLaw {
        let r = &self.relative;
        match self.leader.control {
            LeaderControl::Drift => RelativeLaw::Off,
            LeaderControl::Smc => RelativeLaw::Smc {
                k: r.smc.k,
                z_mps2: r.smc.z_mps2,
                epsilon_mps: r.smc.epsilon_mps,
                switching: r.switching,
            },
        }
    }

    /// Every problem, with key paths under `prefix` (normally "algorithm").
    pub fn validate(&self, prefix: &str) -> Vec<Problem> {
        let mut c = Checker::new();
        c.positive(&format!("{prefix}.mass_kg"), self.mass_kg);
        c.positive_all(&format!("{prefix}.inertia_kg_m2"), &self.inertia_kg_m2);
        self.check_mekf(&mut c, &format!("{prefix}.mekf"));
        let a = &self.attitude;
        let p = format!("{prefix}.attitude");
        c.unit_quaternion(&format!("{p}.q_target_body_eci"), &a.q_target_body_eci);
        for (k, v) in [
            ("lyapunov.k1", a.lyapunov.k1),
            ("lyapunov.k2", a.lyapunov.k2),
            ("pd.k_p", a.pd.k_p),
            ("pd.k_d", a.pd.k_d),
            ("smc.z", a.smc.z),
            ("smc.k", a.smc.k),
            ("smc.epsilon", a.smc.epsilon),
        ] {
            c.positive(&format!("{p}.{k}"), v);
        }
        let r = &self.relative;
        let p = format!("{prefix}.relative");
        c.finite_all(&format!("{p}.r_target_eci_m"), &r.r_target_eci_m);
        c.finite_all(&format!("{p}.v_target_eci_mps"), &r.v_target_eci_mps);
        c.positive(&format!("{p}.smc.k"), r.smc.k);
        c.positive_all(&format!("{p}.smc.z_mps2"), &r.smc.z_mps2);
        c.positive_all(&format!("{p}.smc.epsilon_mps"), &r.smc.epsilon_mps);
        c.positive(&format!("{p}.pd.p"), r.pd.p);
        c.non_negative(&format!("{p}.pd.d"), r.pd.d);
        let f = &r.filter;
        // R and the prior of v must be positive definite; the rest may be zero.
        c.positive_all(&format!("{p}.filter.position_noise_3sigma_m"), &f.position_noise_3sigma_m);
        c.positive(&format!("{p}.filter.initial_velocity_3sigma_mps"), f.initial_velocity_3sigma_mps);
        c.positive(&format!("{p}.filter.accel_bias_tau_s"), f.accel_bias_tau_s);
        for (k, v) in [
            ("accel_noise_3sigma_mps2", f.accel_noise_3sigma_mps2),
            ("accel_bias_3sigma_mps2", f.accel_bias_3sigma_mps2),
            ("unmodelled_accel_3sigma_mps2", f.unmodelled_accel_3sigma_mps2),
        ] {
            c.non_negative(&format!("{p}.filter.{k}"), v);
        }
        c.problems
    }

    fn check_mekf(&self, c: &mut Checker, p: &str) {
        let m = &self.mekf;
        c.positive(&format!("{p}.gyro_noise_3sigma_rad_s"), m.gyro_noise_3sigma_rad_s);
        c.positive(&format!("{p}.gyro_bias_3sigma_rad_s"), m.gyro_bias_3sigma_rad_s);
        c.positive(&format!("{p}.gyro_bias_tau_s"), m.gyro_bias_tau_s);
        for (name, s) in
            [("star_tracker_leader", &m.star_tracker_leader), ("star_tracker_follower", &m.star_tracker_follower)]
        {
            // The filter's R and its prior must be positive definite.
            c.positive(&format!("{p}.{name}.noise_3sigma_rad"), s.noise_3sigma_rad);
            c.positive(&format!("{p}.{name}.bias_3sigma_rad"), s.bias_3sigma_rad);
            c.positive(&format!("{p}.{name}.bias_tau_s"), s.bias_tau_s);
        }
        c.non_negative(&format!("{p}.torque_noise_3sigma_n_m"), m.torque_noise_3sigma_n_m);
        c.non_negative(&format!("{p}.torque_bias_3sigma_n_m"), m.torque_bias_3sigma_n_m);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_are_the_sec7_case() {
        let c: VtxoAlgorithmConfig = toml::from_str("").unwrap();
        assert_eq!(c, VtxoAlgorithmConfig::default());
        assert!(c.validate("algorithm").is_empty());
        assert_eq!(
            c.relative_law(),
            RelativeLaw::Smc { k: 1.0, z_mps2: [1.0; 3], epsilon_mps: [0.05; 3], switching: Switching::Sign }
        );
        assert_eq!(c.leader_law(), RelativeLaw::Off);
        assert_eq!(c.attitude_law(), AttitudeLaw::Smc { z: 2.9947, k: 0.0193, epsilon: 0.2601 });
    }

    #[test]
    fn the_variants_are_expressible() {
        let text = r#"
            phase = "transient"
            [mekf]
            variant = "full"
            [attitude]
            science = "pd"
            [relative]
            controller = "pd"
            switching = "sat"
            [leader]
            control = "smc"
        "#;
        let c: VtxoAlgorithmConfig = toml::from_str(text).unwrap();
        assert!(c.validate("algorithm").is_empty());
        assert_eq!(c.mekf.variant, MekfVariant::Full);
        assert!(matches!(c.attitude_law(), AttitudeLaw::Lyapunov { .. }));
        assert_eq!(c.relative_law(), RelativeLaw::Pd { p: 1.0, d: 1.0 });
        assert!(matches!(c.leader_law(), RelativeLaw::Smc { switching: Switching::Sat, .. }));
        assert!(toml::from_str::<VtxoAlgorithmConfig>("[relative]\nswitching = \"tanh\"\n").is_err());
        assert!(toml::from_str::<VtxoAlgorithmConfig>("[relative.smc]\nzeta = 1.0\n").is_err());
    }

    #[test]
    fn every_bad_value_is_named_by_its_key_path() {
        let text = r#"
            mass_kg = -1.0
            inertia_kg_m2 = [0.1, 0.0, 0.1]
            [mekf]
            gyro_bias_tau_s = 0.0
            [mekf.star_tracker_follower]
            noise_3sigma_rad = 0.0
            bias_3sigma_rad = 1e-9
            [attitude]
            q_target_body_eci = [1.0, 1.0, 0.0, 0.0]
            [attitude.smc]
            epsilon = 0.0
            [attitude.lyapunov]
            k1 = -0.1
            [relative.smc]
            k = 0.0
            z_mps2 = [1.0, -1.0, 1.0]
            epsilon_mps = [0.05, 0.05, 0.0]
            [relative.pd]
            p = 0.0
        "#;
        let c: VtxoAlgorithmConfig = toml::from_str(text).unwrap();
        let paths: Vec<String> = c.validate("algorithm").into_iter().map(|p| p.path).collect();
        for want in [
            "algorithm.mass_kg",
            "algorithm.inertia_kg_m2[1]",
            "algorithm.mekf.gyro_bias_tau_s",
            "algorithm.mekf.star_tracker_follower.noise_3sigma_rad",
            "algorithm.attitude.q_target_body_eci",
            "algorithm.attitude.smc.epsilon",
            "algorithm.attitude.lyapunov.k1",
            "algorithm.relative.smc.k",
            "algorithm.relative.smc.z_mps2[1]",
            "algorithm.relative.smc.epsilon_mps[2]",
            "algorithm.relative.pd.p",
        ] {
            assert!(paths.iter().any(|p| p == want), "no problem at {want}: {paths:?}");
        }
    }
}
