//! Values across the boundary: readings and shares go to Python as read-only float64 arrays;
//! what Python returns may be an array or any sequence of numbers, checked for its length and
//! finiteness, every problem naming the method and what was expected.

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// `x` as a fresh float64 array the callee cannot write to (a write would not reach Cohort, so
/// it is refused rather than silently lost).
pub fn array<'py>(py: Python<'py>, x: &[f64]) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let a = PyArray1::from_slice(py, x);
    a.getattr("flags")?.setattr("writeable", false)?;
    Ok(a)
}

/// A returned vector of floats: `what` names the method and the value (`share() command`),
/// `expected` its length.
pub fn floats(obj: &Bound<'_, PyAny>, expected: usize, what: &str) -> Result<Vec<f64>, String> {
    let v = if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        a.as_slice().map(<[f64]>::to_vec).unwrap_or_else(|_| a.as_array().to_vec())
    } else {
        obj.extract::<Vec<f64>>().map_err(|_| {
            let ty = obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into());
            format!("{what}: expected a sequence of {expected} floats, got a {ty}")
        })?
    };
    if v.len() != expected {
        return Err(format!("{what}: expected {expected} values, got {}", v.len()));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(format!("{what}: value {i} is {} (not finite)", v[i]));
    }
    Ok(v)
}
