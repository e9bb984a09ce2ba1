//! A Python class as the [`PlantModel`]: the truth side. Its readings draw from the plant's
//! `numpy.random.Generator` (seeded from the scenario seed as the plant process's own stream),
//! handed to `readings(agent, rng)` in agent order every step, so the draws are the same in every
//! run mode. Failures are collected as for an algorithm (see `algorithm.rs`).

use cohort_runtime::model::PlantModel;
use pyo3::prelude::*;
use rand_chacha::ChaCha8Rng;

use crate::convert::{array, extend_floats, zeros_from};
use crate::failure::{Failure, columns, raised};

pub struct PyPlant {
    name: String,
    obj: Option<Py<PyAny>>,
    rng: Option<Py<PyAny>>,
    columns: Vec<String>,
    n_readings: usize,
    command_len: usize,
    has_metrics: bool,
    failure: Failure,
}

impl PyPlant {
    pub fn failed(name: String, n_readings: usize, why: String) -> Self {
        Self {
            name,
            obj: None,
            rng: None,
            columns: Vec::new(),
            n_readings,
            command_len: 0,
            has_metrics: false,
            failure: Failure::with(why),
        }
    }

    pub fn new(
        py: Python<'_>,
        name: String,
        (n_readings, command_len): (usize, usize),
        obj: Bound<'_, PyAny>,
        rng: Bound<'_, PyAny>,
    ) -> Self {
        let mut me = Self {
            has_metrics: obj.hasattr("metrics").unwrap_or(false),
            name,
            obj: None,
            rng: Some(rng.unbind()),
            columns: Vec::new(),
            n_readings,
            command_len,
            failure: Failure::default(),
        };
        me.columns = me.failure.keep(columns(py, &obj, (&me.name, "plant's"))).unwrap_or_default();
        me.obj = Some(obj.unbind());
        me
    }

    fn raised(&self, py: Python<'_>, method: &str, e: &PyErr) -> String {
        raised(py, (&self.name, "plant's"), method, e)
    }

    /// Call `method` with `args` and make nothing of the result; a failure is kept.
    fn call(
        &self,
        method: &str,
        args: impl for<'py> FnOnce(Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyTuple>>,
    ) {
        let Some(obj) = &self.obj else { return };
        let r = Python::attach(|py| {
            let args = args(py).map_err(|e| self.raised(py, method, &e))?;
            obj.bind(py).call_method1(method, args).map(drop).map_err(|e| self.raised(py, method, &e))
        });
        self.failure.keep(r);
    }
}

impl PlantModel for PyPlant {
    fn columns(&self) -> Vec<String> {
        self.columns.clone()
    }

    fn readings(&mut self, agent: u32, _rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let start = out.len();
        // Not built (its failure is kept already), or the call failed: zeros.
        let (Some(obj), Some(rng)) = (&self.obj, &self.rng) else {
            return zeros_from(out, start, self.n_readings);
        };
        let r = Python::attach(|py| {
            let ret = obj
                .bind(py)
                .call_method1("readings", (agent, rng.bind(py)))
                .map_err(|e| self.raised(py, "readings", &e))?;
            extend_floats(&ret, self.n_readings, || format!("{}.readings({agent})", self.name), out)
        });
        if self.failure.keep(r).is_none() {
            zeros_from(out, start, self.n_readings);
        }
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        // An agent dead before it ever sent one holds an empty command: zeros, as the trait says.
        let u = if command.len() == self.command_len {
            std::borrow::Cow::Borrowed(command)
        } else {
            let mut u = command.to_vec();
            u.resize(self.command_len, 0.0);
            std::borrow::Cow::Owned(u)
        };
        self.call("apply_command", |py| {
            pyo3::types::PyTuple::new(py, [agent.into_pyobject(py)?.into_any(), array(py, &u).into_any()])
        });
    }

    fn advance(&mut self, dt_s: f64) {
        self.call("advance", |py| pyo3::types::PyTuple::new(py, [dt_s]));
    }

    fn row(&self, out: &mut Vec<f64>) {
        let Some(obj) = &self.obj else { return };
        let start = out.len();
        let r = Python::attach(|py| {
            let ret = obj.bind(py).call_method0("row").map_err(|e| self.raised(py, "row", &e))?;
            extend_floats(&ret, self.columns.len(), || format!("{}.row() (one per column)", self.name), out)
        });
        if self.failure.keep(r).is_none() {
            zeros_from(out, start, self.columns.len());
        }
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let (Some(obj), true) = (&self.obj, self.has_metrics) else { return Vec::new() };
        let r = Python::attach(|py| {
            let m = obj.bind(py).call_method0("metrics").map_err(|e| self.raised(py, "metrics", &e))?;
            m.extract::<std::collections::BTreeMap<String, f64>>()
                .map_err(|_| format!("{}.metrics(): expected a dict of str to float", self.name))
        });
        match r {
            Ok(m) => {
                let (finite, not): (Vec<_>, Vec<_>) = m.into_iter().partition(|(_, v)| v.is_finite());
                for (name, v) in not {
                    tracing::warn!("{}.metrics(): {name} = {v} is not finite; left out of the summary", self.name);
                }
                finite
            }
            Err(e) => {
                tracing::warn!("{e}");
                Vec::new()
            }
        }
    }

    fn take_failure(&mut self) -> Option<String> {
        self.failure.take()
    }
}
