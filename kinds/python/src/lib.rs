//! `kind = "python"`: a user's own algorithm or plant, written as a Python class and flown without
//! rebuilding Cohort. Each agent process (and the plant process) embeds its own CPython through
//! pyo3, so N Python agents run on N interpreters with N GILs; `--reference` runs every one of
//! them in the orchestrator's one interpreter (each agent with its own copy of the module), through
//! the same drivers and in the same call order per agent, so the telemetry is the same bit for bit.
//!
//! The classes mirror the Rust traits one to one (docs/python-algorithms.md has the tutorial):
//!
//! | Rust [`Algorithm`](cohort_runtime::model::Algorithm) | Python algorithm class           |
//! |------------------------------------------------------|----------------------------------|
//! | built by the kind with the agent's settings          | `__init__(self, ctx)`            |
//! | `columns()`                                          | `columns()` → list of str        |
//! | `share(input, out)`                                  | `share(k, t_s, y)` → (command, values) |
//! | `step(dt_s, neighbours)`                             | `step(dt_s, neighbours)` (dict id → array), or `step(dt_s, neighbours, ages)` (dict id → steps since sent) |
//! | `row(out)`                                           | `row()` → sequence of float      |
//! | `roster(live)` (optional)                            | `roster(live)` (optional)        |
//! | `save_state()` / `restore_state(bytes)`              | the same, bytes                  |
//!
//! and the plant class mirrors [`PlantModel`](cohort_runtime::model::PlantModel): `__init__(ctx)`,
//! `columns()`, `readings(agent, rng)`, `apply_command(agent, u)`, `advance(dt_s)`, `row()`,
//! optional `metrics()` → dict. Where we depart from the sketch (`step(k, y, neighbours)`
//! returning the command): the class follows the trait's two phases instead, so that the share
//! of step k goes out before the neighbours' shares are waited for, as for a Rust agent.

// The kinds' names are the scenario's words.
mod algorithm;
pub mod config;
mod convert;
mod failure;
mod instance;
mod interp;
mod plant;
pub mod probe;
#[cfg(test)]
mod tests;

use cohort_runtime::paper::{AlgorithmKind, Paper, PlantKind};

/// The Python kinds (registered like a paper, though they belong to none).
pub struct Python;

impl Paper for Python {
    fn name(&self) -> &'static str {
        "python"
    }
    fn plants(&self) -> &'static [&'static dyn PlantKind] {
        &[&config::PythonPlantKind]
    }
    fn algorithms(&self) -> &'static [&'static dyn AlgorithmKind] {
        &[&config::PythonAlgorithmKind]
    }
}

/// No analysis, figures or commands of their own: a user's run is reported generically.
#[cfg(feature = "host")]
impl cohort_host::PaperHost for Python {}
