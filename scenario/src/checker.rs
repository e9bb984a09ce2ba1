//! The problem collector every check uses — the generic ones here and each paper's for its own
//! sections: every check records (key path, value, reason) and returns whether it passed.

use crate::error::Problem;

/// Collects problems; every check records its own (path, value, reason) and returns whether it
/// passed, so callers can skip checks that depend on it. Papers validate their sections with it.
pub struct Checker {
    pub problems: Vec<Problem>,
    /// What the configuration changed or ignored without it being an error (`path = value:
    /// reason`); `launch` prints each as a `note:` line.
    pub notes: Vec<String>,
}

impl Default for Checker {
    fn default() -> Self {
        Self::new()
    }
}

impl Checker {
    pub fn new() -> Self {
        Self { problems: Vec::new(), notes: Vec::new() }
    }
    /// Record a note: something taken differently from the file, on purpose.
    pub fn note(&mut self, path: &str, value: impl std::fmt::Display, reason: &str) {
        self.notes.push(format!("{path} = {value}: {reason}"));
    }
    pub fn fail(&mut self, path: impl Into<String>, value: impl ToString, reason: impl Into<String>) {
        self.problems.push(Problem::new(path, Some(value.to_string()), reason));
    }
    pub fn finite(&mut self, path: &str, x: f64) -> bool {
        if x.is_finite() {
            true
        } else {
            self.fail(path, fmt_f64(x), "must be a finite number");
            false
        }
    }
    pub fn positive(&mut self, path: &str, x: f64) -> bool {
        if !self.finite(path, x) {
            return false;
        }
        if x <= 0.0 {
            self.fail(path, fmt_f64(x), "must be > 0");
            return false;
        }
        true
    }
    pub fn non_negative(&mut self, path: &str, x: f64) {
        if self.finite(path, x) && x < 0.0 {
            self.fail(path, fmt_f64(x), "must be ≥ 0");
        }
    }
    pub fn all_finite(&mut self, path: &str, v: &[f64]) -> bool {
        let mut ok = true;
        for (k, x) in v.iter().enumerate() {
            ok &= self.finite(&format!("{path}[{k}]"), *x);
        }
        ok
    }
    pub fn vec3(&mut self, path: &str, v: &[f64; 3]) {
        self.all_finite(path, v);
    }
    /// A key the configuration needs that is missing (`path: reason`, no value).
    pub fn missing(&mut self, path: impl Into<String>, reason: impl Into<String>) {
        self.problems.push(Problem::new(path, None, reason));
    }
}

pub fn fmt_f64(x: f64) -> String {
    if x.is_nan() { "nan".into() } else { format!("{x:?}") }
}
