//! Scenario sections of seed 003 (Neural-Rendezvous): the `iso-encounter` plant and the
//! `neural-rendezvous` algorithm with its baselines, their validation with full key paths, and
//! the constructors the registry calls. Every default is a value the reference fixes where the
//! paper's is lost (see the crate README).

use std::path::PathBuf;

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::iso::dynamics::constants::{
    ISO_SET_SEED, ISO_SET_SIZE, ISP_S, M0_KG, RHO_F_RADIUS_M, T_F_S, TEST_ISOS, U_MAX_N,
};
use crate::iso::dynamics::navigation::{Decay, NavSigmas};
use crate::iso::dynamics::plant::{IsoEncounterPlant, PlantParams};
use crate::iso::guidance::scp::ScpSettings;

fn d_set_seed() -> u64 {
    ISO_SET_SEED
}
fn d_t_f() -> f64 {
    T_F_S
}
fn d_m0() -> f64 {
    M0_KG
}
fn d_u_max() -> f64 {
    U_MAX_N
}
fn d_isp() -> f64 {
    ISP_S
}
fn d_one() -> f64 {
    1.0
}
fn d_rho() -> f64 {
    RHO_F_RADIUS_M
}
fn d_substeps() -> u32 {
    1
}
fn d_hour_rate() -> f64 {
    1.0 / 3600.0
}
fn d_t_s_fraction() -> f64 {
    0.75
}
fn d_rebuild() -> f64 {
    3600.0
}
fn d_true() -> bool {
    true
}

/// `[plant]` of kind `iso-encounter`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IsoEncounterConfig {
    /// ISO index in the synthetic set (0–199 train, 200–299 test). Absent: 200 + (seed mod 100),
    /// a test ISO chosen by the run's seed.
    #[serde(default)]
    pub iso_index: Option<u32>,
    /// Seed of the synthetic ISO set (the trained weights assume the default).
    #[serde(default = "d_set_seed")]
    pub iso_set_seed: u64,
    /// Terminal time t_f, s (a multiple of the control interval).
    #[serde(default = "d_t_f")]
    pub t_f_s: f64,
    /// Wet mass at t = 0, kg.
    #[serde(default = "d_m0")]
    pub m0_kg: f64,
    /// Per-axis thrust limit, N.
    #[serde(default = "d_u_max")]
    pub u_max_n: f64,
    /// Specific impulse, s.
    #[serde(default = "d_isp")]
    pub isp_s: f64,
    /// Factor on every navigation σ (0: perfect navigation).
    #[serde(default = "d_one")]
    pub nav_scale: f64,
    /// Factor on the initial dispersion of the truth about the ideal trajectories (0: ideal).
    #[serde(default = "d_one")]
    pub initial_dispersion_scale: f64,
    /// Radius of the sphere ρ_f is drawn on, m.
    #[serde(default = "d_rho")]
    pub rho_f_radius_m: f64,
    /// Navigation standard deviations at t = 0 and t_f.
    #[serde(default)]
    pub nav: NavSigmas,
    /// RK4 sub-steps of the truth per control interval.
    #[serde(default = "d_substeps")]
    pub substeps: u32,
}

impl Default for IsoEncounterConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

/// Reports `v` at `path` unless it is a positive number.
pub(crate) fn positive(problems: &mut Vec<Problem>, path: &str, v: f64) {
    if !(v.is_finite() && v > 0.0) {
        problems.push(Problem::new(path, Some(v.to_string()), "must be a positive number"));
    }
}

/// Reports `v` at `path` unless it is a number ≥ 0.
pub(crate) fn non_negative(problems: &mut Vec<Problem>, path: &str, v: f64) {
    if !(v.is_finite() && v >= 0.0) {
        problems.push(Problem::new(path, Some(v.to_string()), "must be a number ≥ 0"));
    }
}

impl IsoEncounterConfig {
    /// The ISO a run with `seed` encounters.
    pub fn index(&self, seed: u64) -> u32 {
        self.iso_index.unwrap_or(TEST_ISOS.start + (seed % u64::from(TEST_ISOS.end - TEST_ISOS.start)) as u32)
    }

    pub fn params(&self) -> PlantParams {
        PlantParams {
            t_f_s: self.t_f_s,
            m0_kg: self.m0_kg,
            u_max_n: self.u_max_n,
            isp_s: self.isp_s,
            nav_scale: self.nav_scale,
            nav: self.nav,
            substeps: self.substeps,
        }
    }

    /// Every problem, with key paths under `plant.`; `dt_s` is the scenario's control interval.
    pub fn validate(&self, dt_s: f64, n_agents: u32) -> Vec<Problem> {
        let mut p = Vec::new();
        if let Some(i) = self.iso_index.filter(|i| *i >= ISO_SET_SIZE) {
            p.push(Problem::new(
                "plant.iso_index",
                Some(i.to_string()),
                format!("the set holds ISOs 0–{}", ISO_SET_SIZE - 1),
            ));
        }
        for (path, v) in [
            ("plant.t_f_s", self.t_f_s),
            ("plant.m0_kg", self.m0_kg),
            ("plant.u_max_n", self.u_max_n),
            ("plant.isp_s", self.isp_s),
            ("plant.rho_f_radius_m", self.rho_f_radius_m),
        ] {
            positive(&mut p, path, v);
        }
        non_negative(&mut p, "plant.nav_scale", self.nav_scale);
        non_negative(&mut p, "plant.initial_dispersion_scale", self.initial_dispersion_scale);
        let n = self.nav;
        for (name, d) in [
            ("pos_along_m", n.pos_along_m),
            ("pos_cross_m", n.pos_cross_m),
            ("vel_along_mps", n.vel_along_mps),
            ("vel_cross_mps", n.vel_cross_mps),
        ] {
            let Decay { start, end } = d;
            positive(&mut p, &format!("plant.nav.{name}.start"), start);
            positive(&mut p, &format!("plant.nav.{name}.end"), end);
        }
        if !(1..=1000).contains(&self.substeps) {
            p.push(Problem::new("plant.substeps", Some(self.substeps.to_string()), "must be 1–1000"));
        }
        if dt_s.is_finite() && dt_s > 0.0 && self.t_f_s.is_finite() && self.t_f_s > 0.0 {
            let steps = self.t_f_s / dt_s;
            if (steps - steps.round()).abs() > 1e-9 * steps {
                p.push(Problem::new(
                    "plant.t_f_s",
                    Some(self.t_f_s.to_string()),
                    format!("must be a whole number of control intervals (dt_s = {dt_s})"),
                ));
            }
        }
        if !(1..=64).contains(&n_agents) {
            p.push(Problem::new("agents", Some(n_agents.to_string()), "the iso-encounter plant flies 1–64 spacecraft"));
        }
        p
    }
}

/// The plant for a validated section: `n_agents` spacecraft at the ISO the seed picks.
pub fn build_plant(
    cfg: &IsoEncounterConfig,
    n_agents: u32,
    dt_s: f64,
    seed: u64,
) -> Result<IsoEncounterPlant, Vec<Problem>> {
    let problems = cfg.validate(dt_s, n_agents);
    if !problems.is_empty() {
        return Err(problems);
    }
    Ok(IsoEncounterPlant::new(
        cfg.params(),
        cfg.iso_set_seed,
        cfg.index(seed),
        n_agents,
        cfg.rho_f_radius_m,
        cfg.initial_dispersion_scale,
    ))
}

/// Which guidance and control a spacecraft flies (`algorithm.method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Algorithm 1: SN-DNN guidance until t_s, then min-norm tracking of (21)–(23).
    NeuralRendezvous,
    /// The SN-DNN guidance policy alone (Lemma 1).
    SnDnn,
    /// The global solution: SCP every step.
    Nmpc,
    /// NMPC plus min-norm tracking of its own plan.
    RobustNmpc,
    /// One QP per step on the model linearised at p = 0, œ frozen.
    LinearMpc,
    /// PD on the plan solved at t = 0.
    Pd,
    /// u = ς − K s on the plan solved at t = 0.
    RobustTracking,
}

impl Method {
    pub const ALL: [Method; 7] = [
        Method::NeuralRendezvous,
        Method::SnDnn,
        Method::Nmpc,
        Method::RobustNmpc,
        Method::LinearMpc,
        Method::Pd,
        Method::RobustTracking,
    ];
    /// Whether the method needs the SN-DNN weights.
    pub fn needs_weights(self) -> bool {
        matches!(self, Method::NeuralRendezvous | Method::SnDnn)
    }
    pub fn name(self) -> &'static str {
        match self {
            Method::NeuralRendezvous => "neural-rendezvous",
            Method::SnDnn => "sn-dnn",
            Method::Nmpc => "nmpc",
            Method::RobustNmpc => "robust-nmpc",
            Method::LinearMpc => "linear-mpc",
            Method::Pd => "pd",
            Method::RobustTracking => "robust-tracking",
        }
    }
}

/// `[algorithm]` of kind `neural-rendezvous`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NrAlgorithmConfig {
    pub method: Method,
    /// SN-DNN weights file (safetensors); required by `neural-rendezvous` and `sn-dnn`. A relative
    /// path is resolved by the scenario loader before the agent sees it.
    #[serde(default)]
    pub weights: Option<PathBuf>,
    /// Λ = λI of the composite variable, 1/s.
    #[serde(default = "d_hour_rate")]
    pub lambda_per_s: f64,
    /// α of the stability condition (35), 1/s.
    #[serde(default = "d_hour_rate")]
    pub alpha_per_s: f64,
    /// t_s / t_f: when the min-norm tracking starts.
    #[serde(default = "d_t_s_fraction")]
    pub t_s_fraction: f64,
    /// How often the desired trajectory is rebuilt from newer estimates, s.
    #[serde(default = "d_rebuild")]
    pub rebuild_every_s: f64,
    /// If given, must equal the weights file's C_sn (a guard against the wrong file).
    #[serde(default)]
    pub c_sn: Option<f64>,
    /// The SCP's stopping rule (NMPC, robust NMPC and the fixed plans).
    #[serde(default)]
    pub scp: ScpSettings,
    /// Rate λ of the PD baseline (critically damped), 1/s.
    #[serde(default = "d_hour_rate")]
    pub pd_lambda_per_s: f64,
    /// How the desired trajectory's backward pass picks its commands: `replay` (the forward
    /// roll-out's) or `policy` (the SN-DNN at each backward node); see `desired`.
    #[serde(default)]
    pub backward: crate::iso::guidance::desired::Backward,
    /// Clip each LVLH axis of the command to u_max (the min-norm solution can exceed it,
    /// Remark 8); clips are counted.
    #[serde(default = "d_true")]
    pub clip_to_u_max: bool,
    /// A Δv budget the agent keeps to, m/s (absent: none): each command is cut so that the Δv
    /// spent (rocket equation, as the plant counts it) never passes it; then the spacecraft
    /// coasts. For baselines that overspend (PD and robust tracking on the t = 0 plan).
    #[serde(default)]
    pub dv_budget_mps: Option<f64>,
    /// Linear MPC only: `receding` (one QP per step, the default) or `once` (one QP at the first
    /// step, its command sequence flown open-loop to t_f — the paper's reading of [12]).
    #[serde(default)]
    pub linear_mpc: LinearMpcMode,
}

/// How the linear MPC baseline is flown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinearMpcMode {
    #[default]
    Receding,
    Once,
}

impl NrAlgorithmConfig {
    pub fn new(method: Method) -> Self {
        let mut c: Self = toml::from_str("method = \"nmpc\"").expect("every other key has a default");
        c.method = method;
        c
    }

    /// Every problem, with key paths under `algorithm.`.
    pub fn validate(&self) -> Vec<Problem> {
        let mut p = Vec::new();
        for (path, v) in [
            ("algorithm.lambda_per_s", self.lambda_per_s),
            ("algorithm.alpha_per_s", self.alpha_per_s),
            ("algorithm.rebuild_every_s", self.rebuild_every_s),
            ("algorithm.pd_lambda_per_s", self.pd_lambda_per_s),
            ("algorithm.scp.tol_m", self.scp.tol_m),
        ] {
            positive(&mut p, path, v);
        }
        if !(self.t_s_fraction.is_finite() && (0.0..=1.0).contains(&self.t_s_fraction)) {
            p.push(Problem::new("algorithm.t_s_fraction", Some(self.t_s_fraction.to_string()), "must be in [0, 1]"));
        }
        if !(1..=100).contains(&self.scp.max_iter) {
            p.push(Problem::new("algorithm.scp.max_iter", Some(self.scp.max_iter.to_string()), "must be 1–100"));
        }
        if let Some(c) = self.c_sn {
            positive(&mut p, "algorithm.c_sn", c);
        }
        if let Some(b) = self.dv_budget_mps {
            positive(&mut p, "algorithm.dv_budget_mps", b);
        }
        if self.method.needs_weights() && self.weights.is_none() {
            p.push(Problem::new(
                "algorithm.weights",
                None,
                format!("method {} needs an SN-DNN weights file", self.method.name()),
            ));
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_reference_values_and_a_full_section_parses() {
        let p = IsoEncounterConfig::default();
        assert_eq!((p.t_f_s, p.m0_kg, p.u_max_n, p.isp_s, p.iso_set_seed), (86_400.0, 500.0, 1.0, 220.0, 3));
        assert_eq!(p.nav.pos_along_m, Decay { start: 100e3, end: 10.0 });
        assert_eq!(p.index(7), 207);
        assert!(p.validate(600.0, 1).is_empty());
        let a: NrAlgorithmConfig = toml::from_str(
            "method = \"neural-rendezvous\"\nweights = \"w.safetensors\"\n[scp]\ntol_m = 0.5\nmax_iter = 8",
        )
        .unwrap();
        assert_eq!((a.method, a.t_s_fraction, a.scp.tol_m), (Method::NeuralRendezvous, 0.75, 0.5));
        assert!(a.validate().is_empty());
        let p: IsoEncounterConfig =
            toml::from_str("iso_index = 12\nnav_scale = 0.0\n[nav.pos_along_m]\nstart = 5e4\nend = 5.0").unwrap();
        assert_eq!((p.iso_index, p.nav.pos_along_m.end, p.nav.vel_cross_mps.end), (Some(12), 5.0, 1e-4));
    }

    #[test]
    fn unknown_keys_are_refused_and_every_bad_value_is_reported_with_its_path() {
        assert!(toml::from_str::<IsoEncounterConfig>("t_f = 3").is_err());
        assert!(toml::from_str::<NrAlgorithmConfig>("method = \"nmpc\"\nlambda = 3").is_err());
        assert!(toml::from_str::<NrAlgorithmConfig>("method = \"magic\"").is_err());
        let p: IsoEncounterConfig = toml::from_str("iso_index = 300\nt_f_s = 1000.0\nu_max_n = -1.0\nsubsteps = 0\n[nav.vel_cross_mps]\nstart = 0.1\nend = 0.0").unwrap();
        let paths: Vec<String> = p.validate(600.0, 0).into_iter().map(|x| x.path).collect();
        for want in [
            "plant.iso_index",
            "plant.t_f_s",
            "plant.u_max_n",
            "plant.substeps",
            "plant.nav.vel_cross_mps.end",
            "agents",
        ] {
            assert!(paths.iter().any(|x| x == want), "{want} missing from {paths:?}");
        }
        let a: NrAlgorithmConfig = toml::from_str(
            "method = \"sn-dnn\"\nt_s_fraction = 1.5\nalpha_per_s = 0.0\n[scp]\ntol_m = 1.0\nmax_iter = 0",
        )
        .unwrap();
        let paths: Vec<String> = a.validate().into_iter().map(|x| x.path).collect();
        for want in ["algorithm.t_s_fraction", "algorithm.alpha_per_s", "algorithm.scp.max_iter", "algorithm.weights"] {
            assert!(paths.iter().any(|x| x == want), "{want} missing from {paths:?}");
        }
    }
}
