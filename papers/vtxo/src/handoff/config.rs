//! The algorithm section of the hand-off scenario (`[algorithm] kind = "vtxo-handoff"`,
//! [`crate::handoff::kind`]): one visit of the Sec. 8 supervisor of "Explainable AI-Enhanced
//! Supervisory Control for High-Precision Spacecraft Formation" (arXiv:2509.13331) through
//! s1 stabilisation → s2 transient → s3 science with the full dynamics, the controllers switching
//! with the supervisor's location ([`crate::handoff::agent`]).
//!
//! ```toml
//! [algorithm.flight]            # the two agents' flight layer: VtxoAlgorithmConfig
//! [algorithm.flight.attitude]   # (MEKF, science law and gains, relative law, …); `phase` is
//! science = "smc"               # not read: the supervisor decides the law
//! [algorithm.supervisor]        # the supervisor's inputs: VtxoMissionConfig (science window,
//! [algorithm.supervisor.transient]  # u3, the u2 clamp [t_min_s, t_max_s], w of χ = E + w·e,
//! w = 5.0                       # and the fixed (k1, k2, T) used without a weights file)
//! [algorithm.handoff]
//! stabilisation_s = 30.0        # u1: s1's duration (the print's 22.45 h, scaled to a short run)
//! object_id = 1                 # the Id of Table 6 being observed (1..=last object)
//! transient_weights = "../papers/vtxo/weights/transient.safetensors"  # the transient DNN
//! science_gains = "dnn"         # the science law's gains at the entry to s3: "dnn" (the science
//! science_weights = "../papers/vtxo/weights/science.safetensors"  # DNN of these weights, at w =
//! science_w_deg_per_j = 100.0   # science_w_deg_per_j) or "configured" (flight.attitude's gains)
//! ```
//!
//! Departures, and why: u1 is `handoff.stabilisation_s` instead of orbit period − 10 h − 3 min
//! (80 820 s in the print, 59 773 s on the plant's 26.65 h orbit; a short run is the point of this
//! scenario), so the supervisor's `timers.orbit_period_s` is not read (it is still the plant's
//! period, or refused when it disagrees, as in the mission: [`crate::mission::period`]); the run starts in s1 (the mission's s0 → s4 → s2 prefix is
//! the discrete-event scenario's business). `transient_weights` is relative to the scenario file;
//! without it the supervisor's fixed (k1, k2, T) answer. `science_weights`, also relative to the
//! scenario file, is required by `science_gains = "dnn"`; when named it is loaded and checked
//! whatever `science_gains` says (so switching the source with `--set` never skips the check).
//! The science DNN's w is a scenario constant (the print's w of Table 4 is outside our data's
//! range; see [`crate::handoff::science`]): 100 deg/J by default, about the SMC data's median (96);
//! the PD data's median is 457.

use std::path::PathBuf;

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::config::Checker;
use crate::flight::config::VtxoAlgorithmConfig;
use crate::mission::config::{VtxoMissionConfig, whole_ticks};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct VtxoHandoffConfig {
    pub flight: VtxoAlgorithmConfig,
    pub supervisor: VtxoMissionConfig,
    pub handoff: HandoffConfig,
}

/// Where the science law's gains come from at the entry to s3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ScienceGainsSource {
    /// `flight.attitude.science` with its configured gains (Table 4 by default).
    #[default]
    Configured,
    /// `flight.attitude.science` with the gains the science DNN (`science_weights`) answers at
    /// the agent's own estimate.
    Dnn,
}

impl ScienceGainsSource {
    pub fn name(self) -> &'static str {
        match self {
            ScienceGainsSource::Configured => "configured",
            ScienceGainsSource::Dnn => "dnn",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandoffConfig {
    /// u1, s: how long s1 lasts before the transient.
    pub stabilisation_s: f64,
    /// The Id (Table 6) of the object observed in this visit.
    pub object_id: u32,
    /// The transient DNN's weights (resolved against the scenario file while configuring).
    pub transient_weights: Option<PathBuf>,
    pub science_gains: ScienceGainsSource,
    /// The science DNN's weights (resolved against the scenario file while configuring).
    pub science_weights: Option<PathBuf>,
    /// w of the science DNN's input, deg/J (e/E of the Pareto data).
    pub science_w_deg_per_j: f64,
}

/// The default w of the science DNN, deg/J (about the median e/E of the SMC Pareto data).
pub const SCIENCE_W_DEG_PER_J: f64 = 100.0;

impl Default for HandoffConfig {
    fn default() -> Self {
        Self {
            stabilisation_s: 30.0,
            object_id: 1,
            transient_weights: None,
            science_gains: ScienceGainsSource::Configured,
            science_weights: None,
            science_w_deg_per_j: SCIENCE_W_DEG_PER_J,
        }
    }
}

impl VtxoHandoffConfig {
    /// u1 in ticks of `tick_s` (validated: a whole number of them).
    pub fn u1_ticks(&self, tick_s: f64) -> u64 {
        whole_ticks(self.handoff.stabilisation_s, tick_s)
            .unwrap_or_else(|| (self.handoff.stabilisation_s / tick_s).round().max(1.0) as u64)
    }

    /// Every problem of the section with its key path under `prefix` (`algorithm`); the weights
    /// file is checked by the kind, which knows the scenario's directory.
    pub fn validate(&self, prefix: &str, tick_s: f64) -> Vec<Problem> {
        let p = |k: &str| format!("{prefix}.{k}");
        let mut out = self.flight.validate(&p("flight"));
        out.extend(self.supervisor.validate(&p("supervisor"), tick_s));
        let mut c = Checker::new();
        let h = &self.handoff;
        let path = p("handoff.stabilisation_s");
        if c.finite(&path, h.stabilisation_s) && whole_ticks(h.stabilisation_s, tick_s).is_none() {
            c.fail(
                &path,
                Some(format!("{:?}", h.stabilisation_s)),
                &format!("must be a positive whole number of scenario.dt_s = {tick_s} s (u1, the supervisor's tick)"),
            );
        }
        let last = self.supervisor.timers.last_object();
        if !(1..=last).contains(&h.object_id) {
            c.fail(
                &p("handoff.object_id"),
                Some(h.object_id.to_string()),
                &format!("must be a science object of supervisor.timers.u3_h: 1..={last}"),
            );
        }
        c.positive(&p("handoff.science_w_deg_per_j"), h.science_w_deg_per_j);
        if h.science_gains == ScienceGainsSource::Dnn && h.science_weights.is_none() {
            c.fail(
                &p("handoff.science_weights"),
                None,
                "is required by handoff.science_gains = \"dnn\" (the science DNN's weights file)",
            );
        }
        out.extend(c.problems);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::config::VtxoPlantConfig;

    /// The defaults with the supervisor's period taken from the default plant (as configuring does).
    fn on_table_d9() -> VtxoHandoffConfig {
        let mut c = VtxoHandoffConfig::default();
        assert!(c.supervisor.timers.follow_plant("algorithm.supervisor", &VtxoPlantConfig::default()).is_none());
        c
    }

    #[test]
    fn defaults_are_valid_and_bad_values_are_reported_at_their_key_paths() {
        let c = on_table_d9();
        assert!(c.validate("algorithm", 0.01).is_empty(), "{:?}", c.validate("algorithm", 0.01));
        assert_eq!(c.u1_ticks(0.01), 3000);
        let parsed: VtxoHandoffConfig = toml::from_str("").unwrap();
        assert_eq!(parsed, VtxoHandoffConfig::default());
        let mut c = on_table_d9();
        c.handoff.stabilisation_s = 30.005;
        c.handoff.object_id = 9;
        c.flight.mass_kg = -1.0;
        c.supervisor.transient.k1 = 2.0;
        c.handoff.science_w_deg_per_j = 0.0;
        c.handoff.science_gains = ScienceGainsSource::Dnn;
        let paths: Vec<String> = c.validate("algorithm", 0.01).into_iter().map(|p| p.path).collect();
        assert_eq!(
            paths,
            vec![
                "algorithm.flight.mass_kg",
                "algorithm.supervisor.transient.k1",
                "algorithm.handoff.stabilisation_s",
                "algorithm.handoff.object_id",
                "algorithm.handoff.science_w_deg_per_j",
                "algorithm.handoff.science_weights",
            ]
        );
        assert!(toml::from_str::<VtxoHandoffConfig>("[handoff]\nstabilisation = 1.0").is_err());
        assert!(toml::from_str::<VtxoHandoffConfig>("[handoff]\nscience_gains = \"neural\"").is_err());
        let mut dnn: VtxoHandoffConfig =
            toml::from_str("[handoff]\nscience_gains = \"dnn\"\nscience_weights = \"s.safetensors\"").unwrap();
        dnn.supervisor = on_table_d9().supervisor;
        assert!(dnn.validate("algorithm", 0.01).is_empty());
        let mut nan = dnn.clone();
        nan.handoff.science_w_deg_per_j = f64::NAN;
        let paths: Vec<String> = nan.validate("algorithm", 0.01).into_iter().map(|p| p.path).collect();
        assert_eq!(paths, ["algorithm.handoff.science_w_deg_per_j"]);
    }
}
