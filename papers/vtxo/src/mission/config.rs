//! The algorithm section of the discrete-event mission (`[algorithm] kind = "vtxo-mission"`,
//! [`crate::mission::kind`]): the supervisor's inputs of Sec. 8 of "Explainable AI-Enhanced
//! Supervisory Control for High-Precision Spacecraft Formation" and the abstracted durations of
//! what the dynamics would decide. Defaults: the paper's.
//!
//! ```toml
//! [algorithm.timers]
//! # orbit_period_s: absent = the plant's 2π√(a³/μ), 95 952.939 s = 26.65 h for Table D.9; a
//! # value given must agree with it to 1e-6 (crate::mission::period). Sec. 2.5 prints 32.5 h.
//! science_window_s = 36000.0     # 10 h of science per orbit
//! transient_max_s = 180.0        # 3 min: u1 = period − window − transient_max = 59 772.94 s
//! u3_h = [1440.0, 0.2, 1.5, 4.2, 4.9, 5.4, 19.0, 146.0, 452.0, 120.0]   # Table 6, Id 0..9
//! [algorithm.formation]
//! reach_s = 9001.0               # u4: time to the formation after an orbit switch
//! [algorithm.transient]
//! predictor = "fixed"            # the DNN plugs in here
//! t_s = 48.0                     # Table 2's mean T
//! k1 = 0.085                     # Table 2's modes
//! k2 = 0.25
//! w = 5.0                        # μ₃ of (83)
//! t_min_s = 7.2                  # the clamp of u2
//! t_max_s = 72.0
//! ```
//!
//! `reach_s` default: the Sec. 7 case's sliding-mode reaching time |s_z(0)|/Z = 9 001 s (measured
//! 9 001.05 s with the accelerometer bias off, README); the paper gives no value for u4.
//! Every timer must be a whole number of scenario steps (the mission's tick), except the orbit
//! period: it is the plant's, a physical quantity, so u1 = period − window − transient_max is
//! rounded to the nearest tick (at most half a tick, 0.05 s at 0.1 s: 5e-7 of the period).

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::config::Checker;

/// Table 6 in hours: commissioning 60 d, the eight objects, de-commissioning 5 d.
pub const TABLE6_U3_H: [f64; 10] = [1440.0, 0.2, 1.5, 4.2, 4.9, 5.4, 19.0, 146.0, 452.0, 120.0];

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct VtxoMissionConfig {
    pub timers: TimersConfig,
    pub formation: FormationConfig,
    pub transient: TransientConfig,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimersConfig {
    /// The orbit period, s: None in a scenario that leaves it to the plant, until configuring
    /// takes it from the plant's orbit ([`TimersConfig::follow_plant`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orbit_period_s: Option<f64>,
    pub science_window_s: f64,
    pub transient_max_s: f64,
    pub u3_h: Vec<f64>,
}

impl Default for TimersConfig {
    fn default() -> Self {
        Self { orbit_period_s: None, science_window_s: 36_000.0, transient_max_s: 180.0, u3_h: TABLE6_U3_H.to_vec() }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FormationConfig {
    pub reach_s: f64,
}

impl Default for FormationConfig {
    fn default() -> Self {
        Self { reach_s: 9001.0 }
    }
}

/// Where (k1, k2, T) come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum PredictorKind {
    /// The values below, whatever the state.
    #[default]
    Fixed,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TransientConfig {
    pub predictor: PredictorKind,
    pub t_s: f64,
    pub k1: f64,
    pub k2: f64,
    pub w: f64,
    pub t_min_s: f64,
    pub t_max_s: f64,
}

impl Default for TransientConfig {
    fn default() -> Self {
        Self { predictor: PredictorKind::Fixed, t_s: 48.0, k1: 0.085, k2: 0.25, w: 5.0, t_min_s: 7.2, t_max_s: 72.0 }
    }
}

/// `x` seconds in ticks of `tick_s`, when it is a whole number of them.
pub fn whole_ticks(x_s: f64, tick_s: f64) -> Option<u64> {
    let n = x_s / tick_s;
    let r = n.round();
    (n.is_finite() && r >= 1.0 && (n - r).abs() <= 1e-9 * r).then_some(r as u64)
}

impl TimersConfig {
    /// u1 = orbit period − science window − transient maximum (Sec. 8), s; NaN while the period
    /// is unknown (validation refuses that).
    pub fn u1_s(&self) -> f64 {
        self.orbit_period_s.unwrap_or(f64::NAN) - self.science_window_s - self.transient_max_s
    }

    /// The Id of the last science object (Table 6: 8).
    pub fn last_object(&self) -> u32 {
        self.u3_h.len().saturating_sub(2) as u32
    }
}

impl VtxoMissionConfig {
    /// Every problem with its key path under `prefix` (`algorithm`); `tick_s` = scenario.dt_s.
    pub fn validate(&self, prefix: &str, tick_s: f64) -> Vec<Problem> {
        let mut c = Checker::new();
        let p = |k: &str| format!("{prefix}.{k}");
        let ticks = |c: &mut Checker, path: &str, x: f64| {
            if c.finite(path, x) && x > 0.0 && whole_ticks(x, tick_s).is_none() {
                c.fail(
                    path,
                    Some(format!("{x:?}")),
                    &format!("must be a whole number of scenario.dt_s = {tick_s} s (the mission's tick)"),
                );
            }
        };
        let t = &self.timers;
        match t.orbit_period_s {
            Some(period_s) => c.positive(&p("timers.orbit_period_s"), period_s),
            None => c.fail(
                &p("timers.orbit_period_s"),
                None,
                "is absent and the plant gives no orbit to take it from (plant.kind = \"vtxo\" with a valid plant.orbit.a_m)",
            ),
        }
        for (k, v) in [("science_window_s", t.science_window_s), ("transient_max_s", t.transient_max_s)] {
            c.positive(&p(&format!("timers.{k}")), v);
            ticks(&mut c, &p(&format!("timers.{k}")), v);
        }
        let period_s = t.orbit_period_s.unwrap_or(f64::NAN);
        // A period that is no period is refused above; u1 is checked with a valid one.
        if period_s > 0.0 && t.u1_s().is_finite() && t.u1_s() < tick_s {
            c.fail(
                &p("timers.science_window_s"),
                Some(format!("{:?}", t.science_window_s)),
                &format!(
                    "must leave u1 = orbit period − science_window_s − transient_max_s ≥ one tick ({tick_s} s): \
                     the orbit period is {period_s:.3} s = {:.4} h, transient_max_s {} s",
                    period_s / 3600.0,
                    t.transient_max_s
                ),
            );
        }
        if t.u3_h.len() < 3 {
            c.fail(
                &p("timers.u3_h"),
                Some(format!("{:?}", t.u3_h)),
                "needs commissioning, at least one object and de-commissioning (Table 6)",
            );
        }
        for (i, h) in t.u3_h.iter().enumerate() {
            let path = p(&format!("timers.u3_h[{i}]"));
            c.positive(&path, *h);
            ticks(&mut c, &path, h * 3600.0);
        }
        c.positive(&p("formation.reach_s"), self.formation.reach_s);
        ticks(&mut c, &p("formation.reach_s"), self.formation.reach_s);
        let x = &self.transient;
        c.range(&p("transient.k1"), x.k1, 0.01, 0.5, "the Lyapunov gains' range (79), as the data has it");
        c.range(&p("transient.k2"), x.k2, 0.01, 0.5, "the Lyapunov gains' range (79), as the data has it");
        c.non_negative(&p("transient.w"), x.w);
        c.positive(&p("transient.t_min_s"), x.t_min_s);
        c.positive(&p("transient.t_max_s"), x.t_max_s);
        if x.t_min_s.is_finite() && x.t_max_s.is_finite() && x.t_min_s > x.t_max_s {
            c.fail(
                &p("transient.t_min_s"),
                Some(format!("{:?}", x.t_min_s)),
                &format!("must be ≤ transient.t_max_s = {}", x.t_max_s),
            );
        }
        if x.t_max_s.is_finite() && t.transient_max_s.is_finite() && x.t_max_s > t.transient_max_s {
            c.fail(
                &p("transient.t_max_s"),
                Some(format!("{:?}", x.t_max_s)),
                &format!(
                    "must be ≤ timers.transient_max_s = {} (u1 leaves that much for the transient)",
                    t.transient_max_s
                ),
            );
        }
        if c.finite(&p("transient.t_s"), x.t_s) && !(x.t_min_s..=x.t_max_s).contains(&x.t_s) {
            c.fail(
                &p("transient.t_s"),
                Some(format!("{:?}", x.t_s)),
                &format!("must be in [t_min_s, t_max_s] = [{}, {}]", x.t_min_s, x.t_max_s),
            );
        }
        c.problems
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::config::VtxoPlantConfig;

    /// The defaults on the default plant (Table D.9): the period taken from the orbit.
    fn on_table_d9() -> VtxoMissionConfig {
        let mut c = VtxoMissionConfig::default();
        assert!(c.timers.follow_plant("algorithm", &VtxoPlantConfig::default()).is_none());
        c
    }

    fn paths(c: &VtxoMissionConfig) -> Vec<String> {
        c.validate("algorithm", 0.01).into_iter().map(|p| p.path).collect()
    }

    #[test]
    fn defaults_on_the_plants_orbit_are_valid_and_give_u1_from_its_period() {
        let c = on_table_d9();
        assert!(paths(&c).is_empty(), "{:?}", c.validate("algorithm", 0.01));
        // u1 = 26.65 h − 10 h − 3 min (95 952.939 s by hand, mission_period's tests).
        assert!((c.timers.u1_s() - 59_772.939).abs() < 1e-3, "{}", c.timers.u1_s());
        assert_eq!(c.timers.last_object(), 8);
        let parsed: VtxoMissionConfig = toml::from_str("").unwrap();
        assert_eq!(parsed, VtxoMissionConfig::default());
        assert_eq!(parsed.timers.orbit_period_s, None, "absent: the plant's");
        // Without a period (no plant to take it from) the section is refused there, once.
        assert_eq!(paths(&VtxoMissionConfig::default()), ["algorithm.timers.orbit_period_s"]);
        // The period is not held to whole ticks (the plant's is not one): u1 is rounded.
        assert!(c.validate("algorithm", 0.1).is_empty());
    }

    #[test]
    fn every_bad_value_is_reported_at_its_key_path() {
        let mut c = on_table_d9();
        c.timers.u3_h[3] = -1.0;
        c.timers.science_window_s = 200_000.0;
        c.formation.reach_s = 0.005;
        c.transient.k2 = 0.7;
        c.transient.t_s = 100.0;
        assert_eq!(
            paths(&c),
            vec![
                "algorithm.timers.science_window_s",
                "algorithm.timers.u3_h[3]",
                "algorithm.formation.reach_s",
                "algorithm.transient.k2",
                "algorithm.transient.t_s",
            ]
        );
        let msg = c.validate("algorithm", 0.01)[0].to_string();
        assert!(msg.contains("the orbit period is 95952.939") && msg.contains("26.6536 h"), "{msg}");
        let mut c = on_table_d9();
        c.timers.u3_h = vec![1.0, 2.0];
        c.transient.t_max_s = 200.0;
        c.timers.orbit_period_s = Some(-1.0);
        assert_eq!(
            paths(&c),
            vec!["algorithm.timers.orbit_period_s", "algorithm.timers.u3_h", "algorithm.transient.t_max_s"]
        );
        assert!(toml::from_str::<VtxoMissionConfig>("[timers]\nu3 = [1.0]").is_err());
    }

    #[test]
    fn whole_ticks_accepts_table_values_and_refuses_fractions() {
        assert_eq!(whole_ticks(0.2 * 3600.0, 0.01), Some(72_000));
        assert_eq!(whole_ticks(4.9 * 3600.0, 0.01), Some(1_764_000));
        assert_eq!(whole_ticks(48.005, 0.01), None);
        assert_eq!(whole_ticks(0.0, 0.01), None);
    }
}
