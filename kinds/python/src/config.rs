//! The `[plant] kind = "python"` and `[algorithm] kind = "python"` sections, their checks (the
//! module imported in a child interpreter: `probe.rs`), and how each builds its model.
//!
//! ```toml
//! [algorithm]
//! kind = "python"
//! module = "consensus.py"      # relative to the scenario file
//! class = "ConsensusFormation"
//! share_values = 6             # floats in every share
//! [algorithm.params]           # ctx.params, a dict
//! kp_per_s2 = 0.5
//! [algorithm.per_agent.3]      # merged over params for agent 3
//! kp_per_s2 = 0.8
//!
//! [plant]
//! kind = "python"
//! module = "point_masses.py"
//! class = "PointMasses"
//! measurement = ["r_x_m", "r_y_m", "r_z_m"]        # names of every agent's readings, with units
//! command = ["u_x_mps2", "u_y_mps2", "u_z_mps2"]  # names of the command's components
//! [plant.params]
//! noise_std_m = 0.05
//! ```
//! A Python plant takes any per-agent keys (`[[agents]]` beyond `id`, `neighbours`, `host`): they
//! reach its constructor as `ctx.agents`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, deep_checks,
    section_as, table_of,
};
use cohort_scenario::{Checker, Scenario};
use serde::{Deserialize, Serialize};

use crate::probe::{Role, check};

/// `[algorithm] kind = "python"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PythonAlgorithm {
    /// The `.py` file, relative to the scenario file (absolute once resolved).
    pub module: String,
    /// The class in it.
    pub class: String,
    /// Floats in every share.
    pub share_values: usize,
    /// The constructor's `ctx.params`.
    #[serde(default)]
    pub params: toml::Table,
    /// Agent id → keys that replace `params`' for that agent.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub per_agent: BTreeMap<String, toml::Table>,
}

/// `[plant] kind = "python"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PythonPlant {
    pub module: String,
    pub class: String,
    /// Names of every agent's readings, in order, units last (`r_x_m`).
    pub measurement: Vec<String>,
    /// Names of the command's components, units last.
    pub command: Vec<String>,
    #[serde(default)]
    pub params: toml::Table,
}

/// The module file: it exists and is a `.py` file; resolved against the scenario's directory.
fn module_file(s: &Scenario, path: &str, key: &str, c: &mut Checker) -> Option<PathBuf> {
    let resolved = PathBuf::from(s.resolve_path(path));
    if resolved.extension().is_none_or(|e| e != "py") {
        c.fail(key, format!("{path:?}"), "expected a Python file (.py)");
        return None;
    }
    if !resolved.is_file() {
        c.fail(key, format!("{path:?}"), format!("no such file: {}", resolved.display()));
        return None;
    }
    Some(resolved)
}

/// The class name is an identifier, and (unless this process skips deep checks) the module
/// imports in a child interpreter and the class has every method `role` needs.
fn class_flies(file: &Path, class: &str, role: Role, section: &str, c: &mut Checker) {
    let ident = class.chars().next().is_some_and(|ch| ch.is_alphabetic() || ch == '_')
        && class.chars().all(|ch| ch.is_alphanumeric() || ch == '_');
    if !ident {
        c.fail(format!("{section}.class"), format!("{class:?}"), "not a Python class name");
        return;
    }
    if deep_checks()
        && let Some(why) = check(file, class, role)
    {
        let file = file.display().to_string();
        let why = if why.contains(&file) { why } else { format!("{why} ({file})") };
        c.fail(format!("{section}.class"), format!("{class:?}"), why);
    }
}

/// Names of readings or command components: some, each a plain identifier, none twice.
fn names(key: &str, v: &[String], c: &mut Checker) {
    if v.is_empty() {
        c.fail(key, "[]", "name at least one component (units last, e.g. \"r_x_m\")");
    }
    for (i, n) in v.iter().enumerate() {
        if n.is_empty() || !n.chars().all(|ch| ch.is_alphanumeric() || ch == '_') {
            c.fail(
                format!("{key}[{i}]"),
                format!("{n:?}"),
                "expected letters, digits and _ (units last, e.g. \"r_x_m\")",
            );
        } else if v[..i].contains(n) {
            c.fail(format!("{key}[{i}]"), format!("{n:?}"), "named twice");
        }
    }
}

pub struct PythonAlgorithmKind;

/// A configured Python algorithm.
pub struct PythonAlgorithmSetup {
    pub config: PythonAlgorithm,
    pub file: PathBuf,
    /// Components of the plant's command (the length `share()` must return).
    pub command_len: usize,
}

impl AlgorithmKind for PythonAlgorithmKind {
    fn kind(&self) -> &'static str {
        "python"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let s = ctx.scenario;
        let a = section_as::<PythonAlgorithm>(&s.algorithm.body, "algorithm", c)?;
        for id in a.per_agent.keys() {
            if !id.parse::<u32>().is_ok_and(|i| s.agents.iter().any(|x| x.id == i)) {
                c.fail(
                    format!("algorithm.per_agent.{id}"),
                    format!("{id:?}"),
                    "not the id of an agent of the scenario",
                );
            }
        }
        let file = module_file(s, &a.module, "algorithm.module", c)?;
        class_flies(&file, &a.class, Role::Algorithm, "algorithm", c);
        let mut config = a;
        config.module = file.display().to_string();
        Some(Arc::new(PythonAlgorithmSetup { config, file, command_len: plant?.command_len() }))
    }
}

impl PythonAlgorithmSetup {
    /// Agent `id`'s params: the common ones with its own over them.
    pub fn params_of(&self, id: u32) -> toml::Table {
        let mut p = self.config.params.clone();
        if let Some(own) = self.config.per_agent.get(&id.to_string()) {
            p.extend(own.clone());
        }
        p
    }
}

impl AlgorithmSetup for PythonAlgorithmSetup {
    fn kind(&self) -> &'static str {
        PythonAlgorithmKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        self.config.share_values
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        Box::new(crate::instance::algorithm(self, setup, id))
    }
    fn labels(&self) -> BTreeMap<String, String> {
        BTreeMap::from([("python_algorithm".into(), format!("{}:{}", self.file.display(), self.config.class))])
    }
}

pub struct PythonPlantKind;

/// A configured Python plant.
pub struct PythonPlantSetup {
    pub config: PythonPlant,
    pub file: PathBuf,
    /// Every agent's per-agent keys, in id order.
    pub agents: Vec<toml::Table>,
}

impl PlantKind for PythonPlantKind {
    fn kind(&self) -> &'static str {
        "python"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let s = ctx.scenario;
        let p = section_as::<PythonPlant>(&s.plant.body, "plant", c)?;
        names("plant.measurement", &p.measurement, c);
        names("plant.command", &p.command, c);
        let file = module_file(s, &p.module, "plant.module", c)?;
        class_flies(&file, &p.class, Role::Plant, "plant", c);
        if !ctx.ids_ok {
            return None;
        }
        // Any per-agent keys: the class reads them (ids are 1..=N here).
        let agents = (1..=s.n_agents()).map(|id| s.agent(id).extra.clone()).collect();
        let mut config = p;
        config.module = file.display().to_string();
        Some(Arc::new(PythonPlantSetup { config, file, agents }))
    }
}

impl PlantSetup for PythonPlantSetup {
    fn kind(&self) -> &'static str {
        PythonPlantKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        self.config.measurement.len()
    }
    fn reading_names(&self, _s: &Scenario, _id: u32) -> Vec<String> {
        self.config.measurement.clone()
    }
    fn command_len(&self) -> usize {
        self.config.command.len()
    }
    fn command_names(&self) -> Vec<String> {
        self.config.command.clone()
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        Box::new(crate::instance::plant(self, setup))
    }
}
