//! Numpy arrays in and out.

use crate::guard::value_error;
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// The values of the 1-D array `obj` (float64 or float32 numpy array of any strides, read in
/// place; anything else numpy converts with `numpy.asarray(obj, dtype=float64)`), as the
/// library's vector. Errors (`ValueError`, naming `name`): not 1-D, not convertible to float.
pub fn vec_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    if let Ok(a) = obj.downcast::<PyArrayDyn<f64>>() {
        check_1d(name, a.shape())?;
        let ro = a
            .try_readonly()
            .map_err(|e| value_error(format!("{name}: {e}")))?;
        return Ok(ro.as_array().iter().copied().collect());
    }
    if let Ok(a) = obj.downcast::<PyArrayDyn<f32>>() {
        check_1d(name, a.shape())?;
        let ro = a
            .try_readonly()
            .map_err(|e| value_error(format!("{name}: {e}")))?;
        return Ok(ro.as_array().iter().map(|&v| v as f64).collect());
    }
    let np = obj.py().import("numpy")?;
    let conv = np
        .call_method1("asarray", (obj, "float64"))
        .map_err(|e| value_error(format!("{name}: not an array of numbers ({e})")))?;
    let a = conv
        .downcast::<PyArrayDyn<f64>>()
        .map_err(|e| value_error(format!("{name}: {e}")))?;
    check_1d(name, a.shape())?;
    let ro = a
        .try_readonly()
        .map_err(|e| value_error(format!("{name}: {e}")))?;
    Ok(ro.as_array().iter().copied().collect())
}

fn check_1d(name: &str, shape: &[usize]) -> PyResult<()> {
    if shape.len() != 1 {
        return Err(value_error(format!(
            "{name}: want a 1-D array (one axis), got shape {shape:?}"
        )));
    }
    Ok(())
}

/// [`vec_of`] with every value finite and at least one value. Errors: as [`vec_of`], empty,
/// NaN or infinite (the first such index named).
pub fn finite_vec_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let v = vec_of(name, obj)?;
    if v.is_empty() {
        return Err(value_error(format!("{name} is empty")));
    }
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(value_error(format!(
            "{name} is not finite (NaN or inf) at index {k}"
        )));
    }
    Ok(v)
}

/// The vector as a numpy array that owns it (no copy).
pub fn to_numpy<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

/// A finite positive number, or a `ValueError` naming it.
pub fn positive(name: &str, v: f64) -> PyResult<f64> {
    if !(v.is_finite() && v > 0.0) {
        return Err(value_error(format!("{name} {v}: want a finite number > 0")));
    }
    Ok(v)
}

/// A JSON value as Python objects (`json.loads` of its text).
pub fn json_to_py<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| value_error(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}
