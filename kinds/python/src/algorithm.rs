//! A Python class as an agent's [`Algorithm`]. Every call holds the GIL only for itself; a call
//! that raises or returns the wrong thing leaves zeros in its outputs and a failure the driver
//! collects at once ([`Algorithm::take_failure`]), so the run fails at that step naming the agent,
//! the method and the exception's last line, the full traceback in the agent's log.

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};

use crate::convert::{array, extend_floats, zeros_from};
use crate::failure::{Failure, columns, raised};
use crate::interp::last_line;

/// What the wrapper knows beside the object: sizes to check returns against, and names for errors.
pub struct Shape {
    /// `Class` as the errors name it (`consensus.py:ConsensusFormation`).
    pub name: String,
    pub command_len: usize,
    pub share_values: usize,
}

/// The instance's per-step methods, looked up once.
struct Methods {
    share: Py<PyAny>,
    step: Py<PyAny>,
    row: Py<PyAny>,
    /// `step(dt_s, neighbours, ages)`: the class asked for each share's age in steps too.
    step_takes_ages: bool,
}

/// Whether a bound method takes three positional arguments (after `self`).
fn takes_three(py: Python<'_>, method: &Bound<'_, PyAny>) -> bool {
    let params = py
        .import("inspect")
        .and_then(|i| i.call_method1("signature", (method,)))
        .and_then(|sig| sig.getattr("parameters"))
        .and_then(|p| p.len());
    params.is_ok_and(|n| n >= 3)
}

pub struct PyAlgorithm {
    shape: Shape,
    /// None when building it failed (the failure says why, at the first step).
    obj: Option<Py<PyAny>>,
    methods: Option<Methods>,
    /// The agent's `numpy.random.Generator`: its state is part of every checkpoint.
    rng: Option<Py<PyAny>>,
    columns: Vec<String>,
    has_roster: bool,
    failure: Failure,
}

impl PyAlgorithm {
    /// An algorithm whose construction failed: it commands zeros and fails the run at its first
    /// step with `why`.
    pub fn failed(shape: Shape, why: String) -> Self {
        Self {
            shape,
            obj: None,
            methods: None,
            rng: None,
            columns: Vec::new(),
            has_roster: false,
            failure: Failure::with(why),
        }
    }

    /// Wrap a constructed instance: read its columns and which optional methods it has.
    pub fn new(py: Python<'_>, shape: Shape, obj: Bound<'_, PyAny>, rng: Bound<'_, PyAny>) -> Self {
        let mut me = Self {
            has_roster: obj.hasattr("roster").unwrap_or(false),
            shape,
            obj: None,
            methods: None,
            rng: Some(rng.unbind()),
            columns: Vec::new(),
            failure: Failure::default(),
        };
        let method = |m: &str| obj.getattr(m).map(Bound::unbind);
        match (method("share"), method("step"), method("row")) {
            (Ok(share), Ok(step), Ok(row)) => {
                let step_takes_ages = takes_three(py, step.bind(py));
                me.methods = Some(Methods { share, step, row, step_takes_ages })
            }
            _ => me.failure.set(format!("{} lacks one of share, step, row", me.shape.name)),
        }
        me.columns = me.failure.keep(columns(py, &obj, (&me.shape.name, "agent's"))).unwrap_or_default();
        me.obj = Some(obj.unbind());
        me
    }

    fn raised(&self, py: Python<'_>, method: &str, e: &PyErr) -> String {
        raised(py, (&self.shape.name, "agent's"), method, e)
    }

    /// `share()`'s command and values, appended to `out`'s.
    fn call_share(
        &self,
        py: Python<'_>,
        m: &Methods,
        input: &AgentInput<'_>,
        out: &mut ShareOut,
    ) -> Result<(), String> {
        let y = array(py, input.readings);
        let ret = m.share.bind(py).call1((input.k, input.t_s, y)).map_err(|e| self.raised(py, "share", &e))?;
        let name = &self.shape.name;
        let pair = ret
            .cast::<PyTuple>()
            .ok()
            .filter(|t| t.len() == 2)
            .ok_or_else(|| format!("{name}.share(): expected a tuple (command, values)"))?;
        let get = |i: usize| pair.get_item(i).map_err(|e| self.raised(py, "share", &e));
        extend_floats(&get(0)?, self.shape.command_len, || format!("{name}.share() command"), &mut out.command)?;
        extend_floats(&get(1)?, self.shape.share_values, || format!("{name}.share() values"), &mut out.values)
    }

    fn call_step(&self, py: Python<'_>, m: &Methods, dt_s: f64, nb: &[Neighbour<'_>]) -> Result<(), String> {
        let (d, ages) = (PyDict::new(py), PyDict::new(py));
        for n in nb {
            d.set_item(n.id, array(py, n.values)).map_err(|e| self.raised(py, "step", &e))?;
            ages.set_item(n.id, n.age_steps).map_err(|e| self.raised(py, "step", &e))?;
        }
        let called =
            if m.step_takes_ages { m.step.bind(py).call1((dt_s, d, ages)) } else { m.step.bind(py).call1((dt_s, d)) };
        called.map_err(|e| self.raised(py, "step", &e))?;
        Ok(())
    }

    fn call_row(&self, py: Python<'_>, m: &Methods, out: &mut Vec<f64>) -> Result<(), String> {
        let ret = m.row.bind(py).call0().map_err(|e| self.raised(py, "row", &e))?;
        extend_floats(&ret, self.columns.len(), || format!("{}.row() (one per column)", self.shape.name), out)
    }

    /// The user's state, then the generator's, as one checkpoint: [u64 LE length][user][rng].
    fn call_save(&self, py: Python<'_>, obj: &Bound<'_, PyAny>) -> Result<Vec<u8>, String> {
        let name = &self.shape.name;
        let user = obj.call_method0("save_state").map_err(|e| self.raised(py, "save_state", &e))?;
        let user = user.extract::<Vec<u8>>().map_err(|_| format!("{name}.save_state(): expected bytes"))?;
        let rng = self.rng.as_ref().expect("built with its generator").bind(py);
        let state = py
            .import("pickle")
            .and_then(|p| p.call_method1("dumps", (rng.getattr("bit_generator")?.getattr("state")?,)))
            .and_then(|b| b.extract::<Vec<u8>>())
            .map_err(|e| format!("saving the agent's numpy generator: {}", last_line(py, &e)))?;
        let mut out = (user.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(&user);
        out.extend_from_slice(&state);
        Ok(out)
    }

    fn call_restore(&self, py: Python<'_>, obj: &Bound<'_, PyAny>, bytes: &[u8]) -> Result<(), String> {
        let name = &self.shape.name;
        let (len, rest) = bytes.split_at_checked(8).ok_or("a Python checkpoint shorter than its header")?;
        let len = u64::from_le_bytes(len.try_into().expect("8 bytes")) as usize;
        let (user, state) = rest.split_at_checked(len).ok_or("a Python checkpoint shorter than it says")?;
        let rng = self.rng.as_ref().expect("built with its generator").bind(py);
        let state = py
            .import("pickle")
            .and_then(|p| p.call_method1("loads", (PyBytes::new(py, state),)))
            .map_err(|e| format!("the checkpoint's numpy generator state: {}", last_line(py, &e)))?;
        obj.call_method1("restore_state", (PyBytes::new(py, user),))
            .map_err(|e| format!("{name}.restore_state() raised {}", last_line(py, &e)))?;
        rng.getattr("bit_generator")
            .and_then(|g| g.setattr("state", state))
            .map_err(|e| format!("restoring the agent's numpy generator: {}", last_line(py, &e)))
    }
}

impl Algorithm for PyAlgorithm {
    fn columns(&self) -> Vec<String> {
        self.columns.clone()
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        // Not built (its failure is kept already), or the call failed: zeros.
        let done = self
            .methods
            .as_ref()
            .and_then(|m| self.failure.keep(Python::attach(|py| self.call_share(py, m, input, out))));
        if done.is_none() {
            zeros_from(&mut out.command, 0, self.shape.command_len);
            zeros_from(&mut out.values, 0, self.shape.share_values);
        }
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        if let Some(m) = &self.methods {
            self.failure.keep(Python::attach(|py| self.call_step(py, m, dt_s, neighbours)));
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        let start = out.len();
        if let Some(m) = &self.methods
            && self.failure.keep(Python::attach(|py| self.call_row(py, m, out))).is_none()
        {
            zeros_from(out, start, self.columns.len());
        }
    }

    fn roster(&mut self, live: &[bool]) {
        if let (Some(obj), true) = (&self.obj, self.has_roster) {
            self.failure.keep(Python::attach(|py| {
                obj.bind(py)
                    .call_method1("roster", (live.to_vec(),))
                    .map(drop)
                    .map_err(|e| self.raised(py, "roster", &e))
            }));
        }
    }

    fn save_state(&self) -> Vec<u8> {
        let Some(obj) = &self.obj else { return Vec::new() };
        self.failure.keep(Python::attach(|py| self.call_save(py, obj.bind(py)))).unwrap_or_default()
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        let Some(obj) = &self.obj else {
            return Err(RestoreStateError::Refused(self.failure.peek().unwrap_or_else(|| "not built".into())));
        };
        Python::attach(|py| self.call_restore(py, obj.bind(py), bytes)).map_err(RestoreStateError::Refused)
    }

    fn take_failure(&mut self) -> Option<String> {
        self.failure.take()
    }
}
