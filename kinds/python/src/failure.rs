//! What the algorithm and plant wrappers share: the failure kept until the driver asks for it,
//! and the words for an exception (its last line; the traceback to the process's log).

use std::cell::RefCell;

use pyo3::prelude::*;

use crate::interp::{last_line, traceback};

/// The first failure since the driver last asked, kept across the trait's `&self` calls.
#[derive(Default)]
pub struct Failure(RefCell<Option<String>>);

impl Failure {
    /// Already failed with `why` (a model whose construction failed).
    pub fn with(why: String) -> Self {
        Self(RefCell::new(Some(why)))
    }
    /// Keep `why` unless a failure is already kept (the first one is the cause).
    pub fn set(&self, why: String) {
        let mut f = self.0.borrow_mut();
        if f.is_none() {
            *f = Some(why);
        }
    }
    /// The kept failure, if any, without taking it.
    pub fn peek(&self) -> Option<String> {
        self.0.borrow().clone()
    }
    /// `r`'s value, or None with its error kept.
    pub fn keep<T>(&self, r: Result<T, String>) -> Option<T> {
        r.map_err(|e| self.set(e)).ok()
    }
    pub fn take(&mut self) -> Option<String> {
        self.0.get_mut().take()
    }
}

/// Words for an exception `class.method()` raised; the traceback goes to the log of `whose`
/// process ("agent's", "plant's").
pub fn raised(py: Python<'_>, (class, whose): (&str, &str), method: &str, e: &PyErr) -> String {
    tracing::error!("{class}.{method}() raised:\n{}", traceback(py, e));
    format!("Python {class}.{method}() raised {} (traceback in the {whose} log)", last_line(py, e))
}

/// The instance's `columns()`: a list of str.
pub fn columns(py: Python<'_>, obj: &Bound<'_, PyAny>, who: (&str, &str)) -> Result<Vec<String>, String> {
    let c = obj.call_method0("columns").map_err(|e| raised(py, who, "columns", &e))?;
    c.extract::<Vec<String>>().map_err(|_| format!("{}.columns(): expected a list of str", who.0))
}
