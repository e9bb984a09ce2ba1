//! The embedded interpreter: loading a user's class from its file (a module object of its own per
//! agent, so that agents sharing one interpreter in `--reference` share no module state, as they
//! share none as processes), checking numpy is there, and turning exceptions into words.

use std::path::Path;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// What to install when numpy is missing, naming the interpreter Cohort embeds.
fn numpy_missing(py: Python<'_>, e: &PyErr) -> String {
    let prefix = py
        .import("sys")
        .and_then(|s| s.getattr("prefix"))
        .and_then(|p| p.extract::<String>())
        .unwrap_or_else(|_| "?".into());
    format!(
        "cannot import numpy ({}) into the Python Cohort embeds (prefix {prefix}): install it for that \
         interpreter, e.g. `python3 -m pip install numpy`",
        last_line(py, e)
    )
}

/// Import numpy (the arrays every call hands over), or say what to install.
pub fn numpy(py: Python<'_>) -> Result<Bound<'_, PyModule>, String> {
    py.import("numpy").map_err(|e| numpy_missing(py, &e))
}

/// The exception's last line, as Python prints it (`ValueError: bad gain`).
pub fn last_line(py: Python<'_>, e: &PyErr) -> String {
    let kind = e.get_type(py).name().map(|n| n.to_string()).unwrap_or_else(|_| "Exception".into());
    let value = e.value(py).str().map(|s| s.to_string()).unwrap_or_default();
    if value.is_empty() { kind } else { format!("{kind}: {value}") }
}

/// The full traceback, as Python prints it.
pub fn traceback(py: Python<'_>, e: &PyErr) -> String {
    // The three-argument form: pyo3 keeps the traceback beside the value, not in it.
    let formatted = py
        .import("traceback")
        .and_then(|tb| tb.call_method1("format_exception", (e.get_type(py), e.value(py), e.traceback(py))));
    match formatted.and_then(|lines| lines.extract::<Vec<String>>()) {
        Ok(lines) => lines.concat(),
        Err(_) => last_line(py, e),
    }
}

/// Load `class` from the file `path` as a fresh module registered as `unique` (a name no other
/// agent uses), with the file's directory on `sys.path` so it may import its siblings.
pub fn load_class<'py>(py: Python<'py>, path: &Path, class: &str, unique: &str) -> Result<Bound<'py, PyAny>, String> {
    let file = path.display().to_string();
    let fail = |what: &str, e: PyErr| {
        tracing::error!("{what} {file}:\n{}", traceback(py, &e));
        format!("{what} {file}: {}", last_line(py, &e))
    };
    let sys = py.import("sys").map_err(|e| fail("cannot import sys for", e))?;
    if let Some(dir) = path.parent() {
        let sys_path = sys.getattr("path").and_then(|p| p.cast_into::<PyList>().map_err(PyErr::from));
        let sys_path = sys_path.map_err(|e| fail("no sys.path for", e))?;
        let dir = dir.display().to_string();
        if !sys_path.contains(&dir).unwrap_or(false) {
            sys_path.insert(0, dir).map_err(|e| fail("cannot extend sys.path for", e))?;
        }
    }
    let util = py.import("importlib.util").map_err(|e| fail("cannot import importlib.util for", e))?;
    let spec = util.call_method1("spec_from_file_location", (unique, &file)).map_err(|e| fail("cannot read", e))?;
    if spec.is_none() {
        return Err(format!("{file}: not a Python module Python can load"));
    }
    let module = util.call_method1("module_from_spec", (&spec,)).map_err(|e| fail("cannot load", e))?;
    let modules = sys.getattr("modules").and_then(|m| m.cast_into::<PyDict>().map_err(PyErr::from));
    modules.and_then(|m| m.set_item(unique, &module)).map_err(|e| fail("cannot register", e))?;
    spec.getattr("loader")
        .and_then(|l| l.call_method1("exec_module", (&module,)))
        .map_err(|e| fail("importing raised in", e))?;
    module.getattr(class).map_err(|_| format!("{file} defines no class \"{class}\""))
}

/// A scenario value as the Python object it reads as (tables are dicts, arrays lists; dates, which
/// Python's tomllib would make datetimes, are strings here).
pub fn to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(x) => x.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            PyList::new(py, a.iter().map(|x| to_py(py, x)).collect::<PyResult<Vec<_>>>()?)?.into_any()
        }
        toml::Value::Table(t) => table_to_py(py, t)?.into_any(),
    })
}

/// A TOML table as a dict.
pub fn table_to_py<'py>(py: Python<'py>, t: &toml::Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in t {
        d.set_item(k, to_py(py, v)?)?;
    }
    Ok(d)
}

/// A seeded `numpy.random.Generator` (PCG64).
pub fn generator<'py>(py: Python<'py>, seed: u64) -> Result<Bound<'py, PyAny>, String> {
    let np = numpy(py)?;
    np.getattr("random")
        .and_then(|r| r.call_method1("Generator", (r.call_method1("PCG64", (seed,))?,)))
        .map_err(|e| format!("cannot make numpy.random.Generator: {}", last_line(py, &e)))
}
