//! Scenario configuration of seed 002: the plant section ([`crate::model::config`]) and the
//! algorithm section ([`crate::flight::config`]), validation helpers that report every problem
//! with its full key path, and the check that the two sections agree where both name a target.

use cohort_scenario::Problem;

use crate::flight::config::VtxoAlgorithmConfig;
use crate::model::config::VtxoPlantConfig;

/// Collects problems under a key-path prefix (`plant`, `algorithm`).
pub struct Checker {
    pub problems: Vec<Problem>,
}

fn show(v: f64) -> Option<String> {
    Some(format!("{v:?}"))
}

impl Checker {
    pub fn new() -> Self {
        Self { problems: Vec::new() }
    }

    pub fn fail(&mut self, path: &str, value: Option<String>, reason: &str) {
        self.problems.push(Problem::new(path, value, reason));
    }

    pub fn finite(&mut self, path: &str, v: f64) -> bool {
        if !v.is_finite() {
            self.fail(path, show(v), "must be a finite number");
            return false;
        }
        true
    }

    pub fn positive(&mut self, path: &str, v: f64) {
        if self.finite(path, v) && v <= 0.0 {
            self.fail(path, show(v), "must be > 0");
        }
    }

    pub fn non_negative(&mut self, path: &str, v: f64) {
        if self.finite(path, v) && v < 0.0 {
            self.fail(path, show(v), "must be ≥ 0 (a 3σ value)");
        }
    }

    pub fn range(&mut self, path: &str, v: f64, lo: f64, hi: f64, why: &str) {
        if self.finite(path, v) && !(lo..=hi).contains(&v) {
            self.fail(path, show(v), &format!("must be in [{lo}, {hi}]: {why}"));
        }
    }

    pub fn finite_all(&mut self, path: &str, v: &[f64]) {
        for (i, x) in v.iter().enumerate() {
            self.finite(&format!("{path}[{i}]"), *x);
        }
    }

    pub fn positive_all(&mut self, path: &str, v: &[f64]) {
        for (i, x) in v.iter().enumerate() {
            self.positive(&format!("{path}[{i}]"), *x);
        }
    }

    pub fn non_negative_all(&mut self, path: &str, v: &[f64]) {
        for (i, x) in v.iter().enumerate() {
            self.non_negative(&format!("{path}[{i}]"), *x);
        }
    }

    /// A unit quaternion, scalar last (norm within 1e-9 of 1).
    pub fn unit_quaternion(&mut self, path: &str, q: &[f64; 4]) {
        self.finite_all(path, q);
        let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n.is_finite() && (n - 1.0).abs() > 1e-9 {
            self.fail(path, Some(format!("{q:?}")), &format!("must be a unit quaternion (norm {n})"));
        }
    }
}

impl Default for Checker {
    fn default() -> Self {
        Self::new()
    }
}

/// Where both sections name the same target, they must agree: the plant's metrics measure the
/// errors from the targets the agents fly to.
pub fn check_pair(plant: &VtxoPlantConfig, algorithm: &VtxoAlgorithmConfig) -> Vec<Problem> {
    let mut c = Checker::new();
    if plant.attitude.q_target_body_eci != algorithm.attitude.q_target_body_eci {
        c.fail(
            "algorithm.attitude.q_target_body_eci",
            Some(format!("{:?}", algorithm.attitude.q_target_body_eci)),
            &format!(
                "differs from plant.attitude.q_target_body_eci = {:?} (the attitude error is measured from it)",
                plant.attitude.q_target_body_eci
            ),
        );
    }
    if plant.metrics.r_target_eci_m != algorithm.relative.r_target_eci_m {
        c.fail(
            "algorithm.relative.r_target_eci_m",
            Some(format!("{:?}", algorithm.relative.r_target_eci_m)),
            &format!(
                "differs from plant.metrics.r_target_eci_m = {:?} (the formation error is measured from it)",
                plant.metrics.r_target_eci_m
            ),
        );
    }
    c.problems
}
