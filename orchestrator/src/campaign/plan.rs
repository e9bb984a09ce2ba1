//! A campaign's plan: the nominal scenario (its table without `[[dispersions]]`), the checked
//! dispersions, the seeds — and case `i`'s drawn values and scenario, a pure function of the plan
//! and `i`. Every case is drawn and validated before any runs (`check_cases`).

use std::path::{Path, PathBuf};

use cohort_runtime::paper::Setup;
use cohort_scenario::dispersion::{self, Dispersions};
use cohort_scenario::{Overrides, Problem, ScenarioError};

/// Why a campaign cannot start.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("{0}")]
    Invalid(String),
}

impl cohort_runtime::exit::ToExitCode for PlanError {
    fn exit_code(&self) -> u8 {
        cohort_runtime::exit::INVALID
    }
}

/// What the campaign draws and runs.
pub struct Plan {
    pub file: PathBuf,
    /// The scenario file's text (the manifest compares it on a resume).
    pub text: String,
    pub name: String,
    /// The scenario's table without its dispersions.
    base: toml::Table,
    pub dispersions: Dispersions,
    /// The dispersions as TOML (the manifest compares it on a resume).
    pub spec_text: String,
    /// The campaign seed: the draws' streams, and case `i`'s scenario seed `seed + i`
    /// (`seed` for every case with `fixed_seed`).
    pub seed: u64,
    pub fixed_seed: bool,
    pub overrides: Overrides,
}

/// How a plan is made (the command line's choices).
pub struct PlanArgs<'a> {
    pub file: &'a Path,
    pub dispersions_file: Option<&'a Path>,
    pub seed: Option<u64>,
    pub fixed_seed: bool,
    pub duration_s: Option<f64>,
}

impl Plan {
    /// Read the scenario (validated nominal) and the dispersions (the scenario's own, or those of
    /// `--dispersions FILE`, which replace them).
    pub fn new(a: &PlanArgs) -> Result<Self, PlanError> {
        let overrides = Overrides { duration_s: a.duration_s, ..Default::default() };
        let nominal = crate::load(a.file, &overrides)?;
        let read = |f: &Path| -> Result<(String, toml::Table), PlanError> {
            let text = cohort_scenario::parse::read_bounded(f).map_err(|r| ScenarioError {
                file: f.to_path_buf(),
                problems: vec![Problem::new("(file)", None, r)],
            })?;
            let table = text
                .parse::<toml::Table>()
                .map_err(|e| PlanError::Invalid(format!("{}: not valid TOML: {e}", f.display())))?;
            Ok((text, table))
        };
        let (text, mut base) = read(a.file)?;
        let own = dispersion::split(&mut base);
        let (spec_file, spec_source, raw) = match a.dispersions_file {
            Some(f) => {
                let (t, mut table) = read(f)?;
                if let Some(k) = table.keys().find(|k| *k != dispersion::SECTION) {
                    return Err(PlanError::Invalid(format!(
                        "{}: {k}: unknown key (a dispersions file holds [[{}]] only)",
                        f.display(),
                        dispersion::SECTION
                    )));
                }
                (f.to_path_buf(), t, dispersion::split(&mut table))
            }
            None => (a.file.to_path_buf(), text.clone(), own),
        };
        // Checked against the table the cases are drawn into (the command line's overrides in).
        let mut nominal_table = base.clone();
        if let (Some(d), Some(toml::Value::Table(meta))) = (a.duration_s, nominal_table.get_mut("scenario")) {
            meta.insert("duration_s".into(), toml::Value::Float(d));
        }
        let (dispersions, spec_text) = match raw {
            // No dispersions: the cases differ by their seeds only (a seed sweep with a table).
            None if a.fixed_seed => {
                return Err(PlanError::Invalid(format!(
                    "{}: no [[dispersions]] and --fixed-seed: every case would be the same run \
                     (docs/monte-carlo.md)",
                    spec_file.display()
                )));
            }
            None if a.dispersions_file.is_some() => {
                return Err(PlanError::Invalid(format!(
                    "{}: no [[dispersions]] in it (docs/monte-carlo.md)",
                    spec_file.display()
                )));
            }
            None => (Dispersions::default(), String::new()),
            Some(raw) => {
                let text = toml::to_string(&toml::Table::from_iter([(dispersion::SECTION.to_string(), raw.clone())]))
                    .map_err(|e| PlanError::Invalid(format!("{}: {e}", spec_file.display())))?;
                let d = Dispersions::parse(raw, &nominal_table)
                    .map_err(|problems| ScenarioError { file: spec_file.clone(), problems }.located(&spec_source))?;
                (d, text)
            }
        };
        // The command line's overrides are applied over every drawn case: a dispersion of one of
        // their keys would be drawn, tabled and never flown.
        for (path, flag) in overrides.flags() {
            if let Some(k) = dispersions.items.iter().position(|d| d.key.to_string() == path) {
                return Err(PlanError::Invalid(format!(
                    "{}: dispersions[{k}].key = {path:?}: {flag} sets it for every case; drop one of the two",
                    spec_file.display()
                )));
            }
        }
        let seed = a.seed.unwrap_or(nominal.scenario.seed);
        Ok(Self {
            file: a.file.to_path_buf(),
            text,
            name: nominal.scenario.name.clone(),
            base,
            dispersions,
            spec_text,
            seed,
            fixed_seed: a.fixed_seed,
            overrides,
        })
    }

    /// Case `i`'s scenario seed.
    pub fn case_seed(&self, i: u64) -> u64 {
        if self.fixed_seed { self.seed } else { self.seed + i }
    }

    /// Case `i`'s drawn values and its scenario text.
    fn case_text(&self, i: u64) -> (Vec<toml::Value>, String) {
        let values = self.dispersions.draw(self.seed, i);
        let mut t = self.base.clone();
        self.dispersions.apply(&mut t, &values);
        if let Some(toml::Value::Table(meta)) = t.get_mut("scenario") {
            meta.insert("seed".into(), toml::Value::Integer(self.case_seed(i) as i64));
        }
        let text = toml::to_string(&t).expect("a TOML table read from a file serialises");
        (values, text)
    }

    /// Case `i`, validated and configured; the reason, naming the dispersion, when it is not valid.
    pub fn case(&self, i: u64) -> Result<(Vec<toml::Value>, Setup), String> {
        self.case_and_text(i).map(|(values, _, s)| (values, s))
    }

    /// [`Plan::case`] with the scenario text it was loaded from (what a host daemon is sent).
    pub fn case_and_text(&self, i: u64) -> Result<(Vec<toml::Value>, String, Setup), String> {
        let (values, text) = self.case_text(i);
        match cohort_registry::load_text(&text, &self.file, &self.overrides) {
            Ok(s) => Ok((values, text, s)),
            Err(e) => Err(self.blame(i, &values, &e)),
        }
    }

    /// A drawn case's problems, each tied to the dispersion that drew its key when one did.
    fn blame(&self, i: u64, values: &[toml::Value], e: &ScenarioError) -> String {
        let columns = self.dispersions.columns();
        let mut out =
            format!("{}: case {i} (seed {}) is not a valid scenario:", self.file.display(), self.case_seed(i));
        for p in &e.problems {
            match self.dispersions.blame(&p.path) {
                Some(k) => {
                    let key = self.dispersions.items[k].key.to_string();
                    let drawn: Vec<String> = columns
                        .iter()
                        .zip(values)
                        .filter(|(c, _)| *c == &key || c.strip_prefix(&key).is_some_and(|r| r.starts_with('[')))
                        .map(|(c, v)| format!("{c} = {v}"))
                        .collect();
                    // The problem is the drawn key's own: its value is in `drawn` already.
                    let own = columns.iter().zip(values).any(|(c, _)| *c == p.path);
                    let what = if own { p.reason.clone() } else { p.to_string() };
                    out.push_str(&format!("\n  dispersions[{k}] drew {}: {what}", drawn.join(", ")));
                }
                None => out.push_str(&format!("\n  {p}")),
            }
        }
        out
    }
}
