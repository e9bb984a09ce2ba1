//! A run's verdict against its paper: one [`VerdictLine`] per published bound or value a paper
//! checks (the paper's number, ours, and whether ours meets it), from
//! [`crate::RunHooks::verdict`]. The orchestrator writes the lines into `summary.json`
//! (`verdict`, `verdict_overall`) and prints them at the end of `launch`.
//!
//! A line is `n/a` (with its reason) when the run cannot speak to the claim: shortened below the
//! time the claim is about, a fault run where the claim is about the fault-free formation, a run
//! that failed, or a quantity the paper does not define well enough to compare. A paper never
//! widens its bound to pass: the number is the paper's, and the criterion is written in the line.

use serde::{Deserialize, Serialize};

use crate::{Metrics, RunStatus, RunView};

/// Pass, fail, or not applicable to this run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Verdict {
    #[serde(rename = "pass")]
    Pass,
    #[serde(rename = "fail")]
    Fail,
    #[serde(rename = "n/a")]
    NotApplicable,
}

impl Verdict {
    /// How the terminal shows it.
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::NotApplicable => "n/a",
        }
    }
}

/// How our value is compared with the paper's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Ours ≤ the paper's bound.
    AtMost,
    /// Ours ≥ the paper's bound.
    AtLeast,
    /// |ours − paper| ≤ `rel` · |paper| (a published value, not a bound).
    WithinRelative { rel: f64 },
    /// |log₁₀ ours − log₁₀ paper| ≤ `decades` (a published order of magnitude).
    WithinDecades { decades: f64 },
}

impl Criterion {
    /// Whether `ours` meets `paper` (a non-finite value never does).
    pub fn holds(self, ours: f64, paper: f64) -> bool {
        if !ours.is_finite() {
            return false;
        }
        match self {
            Criterion::AtMost => ours <= paper,
            Criterion::AtLeast => ours >= paper,
            Criterion::WithinRelative { rel } => (ours - paper).abs() <= rel * paper.abs(),
            Criterion::WithinDecades { decades } => {
                ours > 0.0 && paper > 0.0 && (ours.log10() - paper.log10()).abs() <= decades
            }
        }
    }
    /// The comparison in words, e.g. "≤", "within 30 %", "within 1 decade".
    pub fn describe(self) -> String {
        match self {
            Criterion::AtMost => "≤".into(),
            Criterion::AtLeast => "≥".into(),
            Criterion::WithinRelative { rel } => format!("within {} %", rel * 100.0),
            Criterion::WithinDecades { decades } => {
                format!("within {decades} decade{}", if decades == 1.0 { "" } else { "s" })
            }
        }
    }
}

/// One claim of the paper against this run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerdictLine {
    /// Short name, e.g. "tracking error after 200 s (worst servicer)".
    pub name: String,
    /// Where the paper states it: section, figure, table or equation.
    pub source: String,
    /// The paper's bound or published value.
    pub paper: f64,
    /// Ours (None when the run did not produce it).
    pub ours: Option<f64>,
    /// Unit of both values ("" when dimensionless).
    pub unit: String,
    pub criterion: Criterion,
    pub verdict: Verdict,
    /// Why the line is n/a, or a remark on how ours was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl VerdictLine {
    /// Compare `ours` with the paper's number: pass or fail (n/a when `ours` is None, with the
    /// reason that the run did not produce it).
    pub fn compare(
        name: impl Into<String>,
        source: impl Into<String>,
        paper: f64,
        ours: Option<f64>,
        unit: impl Into<String>,
        criterion: Criterion,
    ) -> Self {
        let (verdict, note) = match ours {
            Some(x) if criterion.holds(x, paper) => (Verdict::Pass, None),
            Some(_) => (Verdict::Fail, None),
            None => (Verdict::NotApplicable, Some("the run did not produce this value".to_string())),
        };
        Self { name: name.into(), source: source.into(), paper, ours, unit: unit.into(), criterion, verdict, note }
    }
    /// The same line, not applicable to this run for `reason` (ours is kept for information).
    pub fn not_applicable(mut self, reason: impl Into<String>) -> Self {
        self.verdict = Verdict::NotApplicable;
        self.note = Some(reason.into());
        self
    }
    /// The same line with a remark on how ours was measured.
    pub fn with_note(mut self, note: impl Into<String>) -> Self {
        if self.note.is_none() {
            self.note = Some(note.into());
        }
        self
    }
}

/// Everything a paper's verdict reads: the run (setup, directory), its final metrics (the
/// plant's and the analyses'), how it ended and whether faults were carried out.
pub struct VerdictInput<'a> {
    pub run: &'a RunView<'a>,
    pub metrics: &'a Metrics,
    /// How the run ended.
    pub status: RunStatus,
    /// The scenario had a fault plan or the timeline has events (a kill, a death, a freeze …).
    pub faulted: bool,
}

impl VerdictInput<'_> {
    /// A metric, if the run produced a finite value of it.
    pub fn metric(&self, key: &str) -> Option<f64> {
        self.metrics.get(key).copied().filter(|x| x.is_finite())
    }
    /// Why the run as a whole cannot be judged against the paper, if it cannot: it did not end
    /// normally, or it carried out faults (every claim of the papers is about the fault-free
    /// run).
    pub fn not_judgeable(&self) -> Option<String> {
        match self.status {
            RunStatus::Ok if !self.faulted => None,
            RunStatus::Ok | RunStatus::Degraded => {
                Some("fault run: the paper's figure is for the fault-free run".into())
            }
            other => Some(format!("the run ended {other}")),
        }
    }
    /// Scenario duration, s (after any `--duration`).
    pub fn duration_s(&self) -> f64 {
        self.run.setup.scenario.duration_s
    }
}

/// The run's overall verdict: "fail" if any line fails, else "pass" if any passes, else "n/a";
/// None without lines.
pub fn overall(lines: &[VerdictLine]) -> Option<&'static str> {
    if lines.is_empty() {
        None
    } else if lines.iter().any(|l| l.verdict == Verdict::Fail) {
        Some("fail")
    } else if lines.iter().any(|l| l.verdict == Verdict::Pass) {
        Some("pass")
    } else {
        Some("n/a")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn criteria_compare_as_written() {
        assert!(Criterion::AtMost.holds(5.0, 5.0) && !Criterion::AtMost.holds(5.01, 5.0));
        assert!(Criterion::AtLeast.holds(1.0, 0.5) && !Criterion::AtLeast.holds(0.4, 0.5));
        let r = Criterion::WithinRelative { rel: 0.3 };
        assert!(r.holds(1.29, 1.0) && !r.holds(1.31, 1.0) && r.holds(0.71, 1.0) && !r.holds(0.69, 1.0));
        let d = Criterion::WithinDecades { decades: 1.0 };
        assert!(d.holds(9e-8, 1e-8) && !d.holds(2e-7, 1e-8) && !d.holds(0.0, 1e-8));
        assert!(!Criterion::AtMost.holds(f64::NAN, 5.0));
    }

    #[test]
    fn overall_is_fail_over_pass_over_na() {
        let pass = VerdictLine::compare("a", "s", 1.0, Some(0.5), "m", Criterion::AtMost);
        let fail = VerdictLine::compare("b", "s", 1.0, Some(2.0), "m", Criterion::AtMost);
        let na = VerdictLine::compare("c", "s", 1.0, None, "m", Criterion::AtMost);
        assert_eq!((pass.verdict, fail.verdict, na.verdict), (Verdict::Pass, Verdict::Fail, Verdict::NotApplicable));
        assert_eq!(overall(&[]), None);
        assert_eq!(overall(std::slice::from_ref(&na)), Some("n/a"));
        assert_eq!(overall(&[na.clone(), pass.clone()]), Some("pass"));
        assert_eq!(overall(&[pass, fail, na]), Some("fail"));
        let json = serde_json::to_value(VerdictLine::compare("c", "s", 1.0, None, "m", Criterion::AtMost)).unwrap();
        assert_eq!(json["verdict"], "n/a");
    }
}
