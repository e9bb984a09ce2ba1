//! Values across the boundary: readings and shares go to Python as read-only float64 arrays;
//! what Python returns may be an array or any sequence of numbers, checked for its length and
//! finiteness, every problem naming the method and what was expected.

use numpy::npyffi::NPY_ARRAY_WRITEABLE;
use numpy::{PyArray1, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

/// `x` as a fresh float64 array the callee cannot write to (a write would not reach Cohort, so
/// it is refused rather than silently lost).
pub fn array<'py>(py: Python<'py>, x: &[f64]) -> Bound<'py, PyArray1<f64>> {
    let a = PyArray1::from_slice(py, x);
    // SAFETY: the array was just created and is owned by us alone; clearing the flag is what
    // `a.flags.writeable = False` does, without two attribute look-ups per call.
    unsafe { (*a.as_array_ptr()).fields.flags &= !NPY_ARRAY_WRITEABLE };
    a
}

/// A list's or tuple's items as floats appended to `out` (None if one is not a number).
fn items<'py>(mut it: impl Iterator<Item = Bound<'py, PyAny>>, out: &mut Vec<f64>) -> Option<()> {
    it.try_for_each(|x| x.extract::<f64>().ok().map(|v| out.push(v)))
}

/// Append a returned vector of floats to `out`: `what` names the method and the value
/// (`share() command`; made only for an error), `expected` its length. On an error `out` is as
/// it was.
pub fn extend_floats(
    obj: &Bound<'_, PyAny>,
    expected: usize,
    what: impl Fn() -> String,
    out: &mut Vec<f64>,
) -> Result<(), String> {
    let start = out.len();
    let r = read_floats(obj, expected, &what, out);
    if r.is_err() {
        out.truncate(start);
    }
    r
}

fn read_floats(
    obj: &Bound<'_, PyAny>,
    expected: usize,
    what: &dyn Fn() -> String,
    out: &mut Vec<f64>,
) -> Result<(), String> {
    let start = out.len();
    // Lists and tuples first: the common returns, read without a failed conversion's cost.
    let ok = if let Ok(l) = obj.cast::<PyList>() {
        items(l.iter(), out)
    } else if let Ok(t) = obj.cast::<PyTuple>() {
        items(t.iter(), out)
    } else if let Ok(a) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        out.extend(a.as_array().iter());
        Some(())
    } else {
        obj.extract::<Vec<f64>>().ok().map(|x| out.extend(x))
    };
    if ok.is_none() {
        let ty = obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into());
        return Err(format!("{}: expected a sequence of {expected} floats, got a {ty}", what()));
    }
    let v = &out[start..];
    if v.len() != expected {
        return Err(format!("{}: expected {expected} values, got {}", what(), v.len()));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(format!("{}: value {i} is {} (not finite)", what(), v[i]));
    }
    Ok(())
}

/// `out` from `start` on replaced by `n` zeros: what a failed call leaves.
pub fn zeros_from(out: &mut Vec<f64>, start: usize, n: usize) {
    out.truncate(start);
    out.resize(start + n, 0.0);
}
