//! The supervisor's orbit period comes from the plant's orbit (issue 36, item 9).
//!
//! Sec. 8 of "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft
//! Formation" (arXiv:2509.13331) times the stabilisation by u1 = orbit period − 10 h − 3 min,
//! and Sec. 2.5 prints the period as 32.5 h. The plant flies Table D.9 (a = 45 300 km), whose
//! period is 2π√(a³/μ) = 95 953 s = 26.65 h; 32.5 h would need a = 51 703 km. A supervisor on a
//! 32.5 h clock over a 26.65 h orbit would put its science windows and stabilisations where the
//! orbit no longer is, so the timers take the plant's period:
//! - `timers.orbit_period_s` absent: it is the plant's Keplerian period 2π√(a³/μ), with
//!   `plant.orbit.a_m` and the μ the plant integrates with ([`VtxoPlantConfig::orbit_period_s`]);
//!   configuring writes it into the resolved scenario, so a run's `scenario.toml` says which
//!   period its timers used.
//! - `timers.orbit_period_s` given: it must agree with the plant's period to
//!   [`PERIOD_REL_TOLERANCE`], or the scenario is refused naming both key paths and both values.
//!
//! Why 1e-6: it is 0.096 s of a 26.65 h orbit — loose enough for the period written to the
//! mission's 0.1 s tick or to three decimals, and ≈ 2e5 times tighter than the 22 % between the
//! paper's 32.5 h and Table D.9. J2 is not in the period (it shortens the perigee-to-perigee time
//! by 131 s, 1.37e-3; the print's period is Keplerian too).

use cohort_scenario::Problem;

use crate::mission::config::TimersConfig;
use crate::model::config::VtxoPlantConfig;

/// How far, relative, an explicit `timers.orbit_period_s` may lie from the plant's period.
pub const PERIOD_REL_TOLERANCE: f64 = 1e-6;

/// `x` seconds, and in hours: "95952.939 s (26.6536 h)".
fn s_and_h(x_s: f64) -> String {
    format!("{x_s:.3} s ({:.4} h)", x_s / 3600.0)
}

impl TimersConfig {
    /// Take the orbit period from `plant` when absent, or check the one given against it: a
    /// problem at `{prefix}.timers.orbit_period_s` when it disagrees. A plant with no valid
    /// semi-major axis gives no period (its own problem names `plant.orbit.a_m`); a given value
    /// that is not finite and positive is left to [`crate::mission::config::VtxoMissionConfig::validate`].
    pub fn follow_plant(&mut self, prefix: &str, plant: &VtxoPlantConfig) -> Option<Problem> {
        let plant_s = plant.orbit_period_s()?;
        let Some(given_s) = self.orbit_period_s else {
            self.orbit_period_s = Some(plant_s);
            return None;
        };
        let rel = (given_s - plant_s).abs() / plant_s;
        if !given_s.is_finite() || given_s <= 0.0 || rel <= PERIOD_REL_TOLERANCE {
            return None;
        }
        Some(Problem::new(
            format!("{prefix}.timers.orbit_period_s"),
            Some(s_and_h(given_s)),
            format!(
                "disagrees with the plant's orbit period {} = 2π√(a³/μ) of plant.orbit.a_m = {:?} m and \
                 μ = {:e} m³/s² (relative difference {rel:.3e}, more than {PERIOD_REL_TOLERANCE:e}): the \
                 supervisor's timers must run on the orbit the plant flies; drop the key to take the plant's period",
                s_and_h(plant_s),
                plant.orbit.a_m,
                plant.gravity().mu_m3ps2,
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::config::VtxoMissionConfig;

    /// 2π√(a³/μ) for a = 45 300 km, μ = 3.986004418e14 m³/s², to 40 digits (mpmath):
    /// 95952.93943589334535578561337179203473916 s.
    const TABLE_D9_PERIOD_S: f64 = 95_952.939_435_893_35;

    fn follow(given: Option<f64>, plant: &VtxoPlantConfig) -> (TimersConfig, Option<Problem>) {
        let mut t = TimersConfig { orbit_period_s: given, ..TimersConfig::default() };
        let p = t.follow_plant("algorithm", plant);
        (t, p)
    }

    #[test]
    fn an_absent_period_is_the_plants_keplerian_period() {
        let (t, p) = follow(None, &VtxoPlantConfig::default());
        assert!(p.is_none(), "{p:?}");
        let got = t.orbit_period_s.unwrap();
        let rel = (got - TABLE_D9_PERIOD_S).abs() / TABLE_D9_PERIOD_S;
        assert!(rel < 1e-9, "{got} s against the hand value {TABLE_D9_PERIOD_S} s (rel {rel:e})");
        assert!((got / 3600.0 - 26.6536).abs() < 1e-4, "{} h", got / 3600.0);
        // u1 = period − 10 h − 3 min.
        assert!((t.u1_s() - (TABLE_D9_PERIOD_S - 36_180.0)).abs() < 1e-9);
        // Another plant orbit, another period: a³ ∝ P², so twice a is 2√2 times the period.
        let mut wide = VtxoPlantConfig::default();
        wide.orbit.a_m *= 2.0;
        let (t, _) = follow(None, &wide);
        let rel = (t.orbit_period_s.unwrap() - TABLE_D9_PERIOD_S * 8f64.sqrt()).abs() / TABLE_D9_PERIOD_S;
        assert!(rel < 1e-9, "rel {rel:e}");
    }

    #[test]
    fn a_disagreeing_period_is_refused_naming_both_key_paths_and_both_values() {
        let (t, p) = follow(Some(117_000.0), &VtxoPlantConfig::default());
        let p = p.expect("32.5 h over a 26.65 h orbit is refused");
        assert_eq!(p.path, "algorithm.timers.orbit_period_s");
        assert_eq!(p.value.as_deref(), Some("117000.000 s (32.5000 h)"));
        let msg = p.to_string();
        for want in ["algorithm.timers.orbit_period_s", "plant.orbit.a_m = 45300000.0 m", "95952.939 s (26.6536 h)"] {
            assert!(msg.contains(want), "{want:?} not in {msg}");
        }
        assert!(msg.contains("relative difference 2.193e-1"), "{msg}");
        assert_eq!(t.orbit_period_s, Some(117_000.0), "the given value is not replaced");
        // Just past the tolerance: 1.5e-6 relative.
        let (_, p) = follow(Some(TABLE_D9_PERIOD_S * (1.0 + 1.5e-6)), &VtxoPlantConfig::default());
        assert!(p.is_some());
        // Through a scenario section: the path carries the prefix (the hand-off's supervisor).
        let mut c = VtxoMissionConfig::default();
        c.timers.orbit_period_s = Some(117_000.0);
        let p = c.timers.follow_plant("algorithm.supervisor", &VtxoPlantConfig::default()).unwrap();
        assert_eq!(p.path, "algorithm.supervisor.timers.orbit_period_s");
    }

    #[test]
    fn an_agreeing_period_is_accepted_as_given() {
        let plant = VtxoPlantConfig::default();
        // To the 0.1 s tick, to the second, and the hand value itself.
        for given in [95_952.9, 95_953.0, TABLE_D9_PERIOD_S] {
            let (t, p) = follow(Some(given), &plant);
            assert!(p.is_none(), "{given}: {p:?}");
            assert_eq!(t.orbit_period_s, Some(given));
        }
        // The paper's 32.5 h agrees with a plant on a = 51 703 km.
        let mut paper = VtxoPlantConfig::default();
        paper.orbit.a_m = 51_703_100.514;
        assert!(follow(Some(117_000.0), &paper).1.is_none());
    }

    #[test]
    fn a_plant_without_an_orbit_gives_no_period_and_validation_says_so() {
        let mut bad = VtxoPlantConfig::default();
        bad.orbit.a_m = -1.0;
        let (t, p) = follow(None, &bad);
        assert!(p.is_none() && t.orbit_period_s.is_none());
        let c = VtxoMissionConfig { timers: t, ..VtxoMissionConfig::default() };
        let problems = c.validate("algorithm", 0.1);
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(problems[0].path, "algorithm.timers.orbit_period_s");
        // A given value that is not a period is validation's to refuse, once.
        let (_, p) = follow(Some(f64::NAN), &VtxoPlantConfig::default());
        assert!(p.is_none());
    }
}
