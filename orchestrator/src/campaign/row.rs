//! One finished case: its index, seed, drawn values, status, summary metrics and verdict lines —
//! kept as `cases/case-NNNNNN/row.json` the moment the case ends, so an interrupted campaign
//! resumes from the rows on disk. Floats are stored as their bits: a resumed campaign's table is
//! the uninterrupted one's, bit for bit.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// A drawn value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Cell {
    /// `f64::to_bits`.
    Float(u64),
    Int(i64),
    Text(String),
    Bool(bool),
}

impl Cell {
    pub fn of(v: &toml::Value) -> Self {
        match v {
            toml::Value::Float(x) => Cell::Float(x.to_bits()),
            toml::Value::Integer(i) => Cell::Int(*i),
            toml::Value::Boolean(b) => Cell::Bool(*b),
            toml::Value::String(s) => Cell::Text(s.clone()),
            other => Cell::Text(other.to_string()),
        }
    }

    /// The value as a number, when it is one (plots, statistics).
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Cell::Float(b) => Some(f64::from_bits(*b)),
            Cell::Int(i) => Some(*i as f64),
            _ => None,
        }
    }
}

impl std::fmt::Display for Cell {
    /// As TOML writes the value (`"dmpc"`, `3`, `true`, `0.25`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cell::Float(b) => write!(f, "{:?}", f64::from_bits(*b)),
            Cell::Int(i) => write!(f, "{i}"),
            Cell::Text(s) => write!(f, "{s:?}"),
            Cell::Bool(b) => write!(f, "{b}"),
        }
    }
}

/// One verdict line of a case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerdictCell {
    pub name: String,
    /// "pass", "fail" or "n/a".
    pub verdict: String,
    /// Ours, `f64::to_bits`.
    pub ours: Option<u64>,
    pub unit: String,
}

/// What running a case gave: everything of its row but the campaign's own columns (index, seed,
/// drawn values). A host daemon sends it back as JSON (`campaign --hosts`), floats as bits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The run's status ("ok", "degraded", "diverged", "failed").
    pub status: String,
    pub error: Option<String>,
    /// Summary metrics, `f64::to_bits`.
    pub metrics: BTreeMap<String, u64>,
    pub verdict: Vec<VerdictCell>,
    pub verdict_overall: String,
    /// Wall time of the case's run, s (progress only; not in the table).
    pub wall_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseRow {
    pub case: u64,
    pub seed: u64,
    pub values: Vec<Cell>,
    /// Its fields sit beside the three above in `row.json`.
    #[serde(flatten)]
    pub outcome: Outcome,
    /// The host daemon that ran it (`campaign --hosts`; not in the table, which does not depend
    /// on where a case ran).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
}

impl CaseRow {
    pub fn new(case: u64, seed: u64, values: &[toml::Value], outcome: Outcome, host: Option<String>) -> Self {
        Self { case, seed, values: values.iter().map(Cell::of).collect(), outcome, host }
    }

    pub fn metric(&self, name: &str) -> Option<f64> {
        self.outcome.metrics.get(name).map(|b| f64::from_bits(*b))
    }

    /// A summary metric, or `ours: <verdict line>`: what `--metric` and `--until` may name.
    pub fn value(&self, name: &str) -> Option<f64> {
        self.metric(name).or_else(|| {
            let line = name.strip_prefix("ours: ")?;
            self.outcome.verdict.iter().find(|v| v.name == line)?.ours.map(f64::from_bits)
        })
    }
}

/// Case `i`'s directory under the campaign's root.
pub fn case_dir(root: &Path, i: u64) -> PathBuf {
    root.join("cases").join(format!("case-{i:06}"))
}

const ROW: &str = "row.json";

/// Keep a finished case's row (written whole, then renamed into place).
pub fn save(root: &Path, row: &CaseRow) -> std::io::Result<()> {
    let text = serde_json::to_vec_pretty(row).map_err(std::io::Error::other)?;
    // A case run on a host has no directory here until its row comes.
    std::fs::create_dir_all(case_dir(root, row.case))?;
    cohort_runtime::record::write_atomic(&case_dir(root, row.case).join(ROW), &text)
}

/// Case `i`'s row if it finished in an earlier invocation; an unreadable row is an error naming
/// the file (it is never silently run again nor skipped).
pub fn load(root: &Path, i: u64, columns: usize) -> Result<Option<CaseRow>, String> {
    let path = case_dir(root, i).join(ROW);
    match std::fs::read(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("{}: {e}", path.display())),
        Ok(bytes) => match serde_json::from_slice::<CaseRow>(&bytes) {
            Ok(r) if r.case == i && r.values.len() == columns => Ok(Some(r)),
            Ok(r) if r.case == i => Err(format!(
                "{}: {} drawn values where the campaign draws {columns}; remove the case's directory to run it again",
                path.display(),
                r.values.len()
            )),
            Ok(r) => Err(format!("{}: holds case {}, not {i}", path.display(), r.case)),
            Err(e) => {
                Err(format!("{}: not a case row ({e}); remove the case's directory to run it again", path.display()))
            }
        },
    }
}
