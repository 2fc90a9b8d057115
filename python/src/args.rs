//! The arguments of the Python entry points, each taken by name: a value of the wrong type
//! raises `TypeError`, one out of range `ValueError`, and either message names the function,
//! the argument, what it allows and what was given (`run: seed: a whole number from 0 to
//! 18446744073709551615 (an int), not 'abc' (str)`). pyo3's own conversion errors name
//! neither the argument nor what it takes, so the entry points take these values as Python
//! objects and convert them here.

use std::path::PathBuf;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt, PyString};

/// Argument `name` of entry point `f`, as given (`None` where left out or `None`).
pub(crate) struct Arg<'a, 'py> {
    f: &'static str,
    name: &'static str,
    v: Option<&'a Bound<'py, PyAny>>,
}

/// Argument `name` of `f` with value `v`.
pub(crate) fn arg<'a, 'py>(
    f: &'static str,
    name: &'static str,
    v: &'a Option<Bound<'py, PyAny>>,
) -> Arg<'a, 'py> {
    Arg {
        f,
        name,
        v: v.as_ref(),
    }
}

/// What was given: its repr and its type (`'abc' (str)`).
fn given(v: &Bound<'_, PyAny>) -> String {
    let ty = v
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default();
    let r = v.repr().map(|r| r.to_string()).unwrap_or_default();
    format!("{r} ({ty})")
}

fn is_number(v: &Bound<'_, PyAny>) -> bool {
    !v.is_instance_of::<PyBool>() && (v.is_instance_of::<PyInt>() || v.is_instance_of::<PyFloat>())
}

impl Arg<'_, '_> {
    fn message(&self, allowed: &str, v: &Bound<'_, PyAny>) -> String {
        format!("{}: {}: {allowed}, not {}", self.f, self.name, given(v))
    }

    fn type_error(&self, allowed: &str, v: &Bound<'_, PyAny>) -> PyErr {
        PyTypeError::new_err(self.message(allowed, v))
    }

    fn value_error(&self, allowed: &str, v: &Bound<'_, PyAny>) -> PyErr {
        PyValueError::new_err(self.message(allowed, v))
    }

    /// A whole number from `lo` to `hi`.
    pub(crate) fn whole(&self, lo: u64, hi: u64) -> PyResult<Option<u64>> {
        let Some(v) = self.v else { return Ok(None) };
        let allowed = format!("a whole number from {lo} to {hi} (an int)");
        if v.is_instance_of::<PyBool>() || !v.is_instance_of::<PyInt>() {
            return Err(self.type_error(&allowed, v));
        }
        match v.extract::<u64>() {
            Ok(x) if (lo..=hi).contains(&x) => Ok(Some(x)),
            _ => Err(self.value_error(&allowed, v)),
        }
    }

    /// A count from `lo` to `hi`.
    pub(crate) fn count(&self, lo: usize, hi: usize) -> PyResult<Option<usize>> {
        Ok(self.whole(lo as u64, hi as u64)?.map(|x| x as usize))
    }

    /// A finite number (an int or a float); `what` says what it is (`a duration in s`).
    pub(crate) fn number(&self, what: &str) -> PyResult<Option<f64>> {
        let Some(v) = self.v else { return Ok(None) };
        let allowed = format!("{what}, a finite number (an int or a float)");
        if !is_number(v) {
            return Err(self.type_error(&allowed, v));
        }
        match v.extract::<f64>() {
            Ok(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(self.value_error(&allowed, v)),
        }
    }

    /// A list of finite numbers; `what` says what each is.
    pub(crate) fn numbers(&self, what: &str) -> PyResult<Option<Vec<f64>>> {
        let Some(v) = self.v else { return Ok(None) };
        let allowed = format!("a list of {what}, finite numbers (ints or floats)");
        if v.is_instance_of::<PyString>() {
            return Err(self.type_error(&allowed, v));
        }
        let items = v.try_iter().map_err(|_| self.type_error(&allowed, v))?;
        let mut out = Vec::new();
        for item in items {
            let item = item?;
            if !is_number(&item) {
                return Err(self.type_error(&allowed, &item));
            }
            match item.extract::<f64>() {
                Ok(x) if x.is_finite() => out.push(x),
                _ => return Err(self.value_error(&allowed, &item)),
            }
        }
        Ok(Some(out))
    }

    /// A string; `allowed` says which (`"in-process" or "ipc"`).
    pub(crate) fn text(&self, allowed: &str) -> PyResult<Option<String>> {
        let Some(v) = self.v else { return Ok(None) };
        if !v.is_instance_of::<PyString>() {
            return Err(self.type_error(allowed, v));
        }
        Ok(Some(v.extract::<String>()?))
    }

    /// A string or a list of strings; `allowed` says which.
    pub(crate) fn texts(&self, allowed: &str) -> PyResult<Option<Vec<String>>> {
        let Some(v) = self.v else { return Ok(None) };
        if v.is_instance_of::<PyString>() {
            return Ok(Some(vec![v.extract::<String>()?]));
        }
        let items = v.try_iter().map_err(|_| self.type_error(allowed, v))?;
        let mut out = Vec::new();
        for item in items {
            let item = item?;
            if !item.is_instance_of::<PyString>() {
                return Err(self.type_error(allowed, &item));
            }
            out.push(item.extract::<String>()?);
        }
        Ok(Some(out))
    }

    /// True or False (left out: False).
    pub(crate) fn flag(&self) -> PyResult<bool> {
        let Some(v) = self.v else { return Ok(false) };
        if !v.is_instance_of::<PyBool>() {
            return Err(self.type_error("True or False", v));
        }
        v.extract::<bool>()
    }

    /// A path: a str or an `os.PathLike`.
    pub(crate) fn path(&self) -> PyResult<Option<PathBuf>> {
        let Some(v) = self.v else { return Ok(None) };
        let allowed = "a path (a str or an os.PathLike)";
        let text = v
            .py()
            .import("os")
            .and_then(|os| os.call_method1("fspath", (v,)))
            .and_then(|p| p.extract::<String>())
            .map_err(|_| self.type_error(allowed, v))?;
        Ok(Some(PathBuf::from(text)))
    }
}
