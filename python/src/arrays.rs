//! numpy arrays in and out. Inputs are checked (dtype float32, the shape each argument needs) with a
//! message that names the argument and what it got, then copied, so that the work can run without the
//! GIL while Python threads are free to change the arrays.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use nbrdf::Vec3;

/// What `x` is, for messages: `float64 array of shape (4, 3)`, or its Python type.
fn describe(x: &Bound<'_, PyAny>) -> String {
    let attr = |name: &str| x.getattr(name).and_then(|v| v.str().map(|s| s.to_string())).ok();
    match (attr("dtype"), attr("shape")) {
        (Some(d), Some(s)) => format!("{d} array of shape {s}"),
        _ => x.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "an object".into()),
    }
}

/// A float32 array with two dimensions.
fn matrix<'py>(x: &Bound<'py, PyAny>, name: &str, want: &str) -> PyResult<Bound<'py, PyArray2<f32>>> {
    match x.cast::<PyArray2<f32>>() {
        Ok(a) => Ok(a.clone()),
        Err(_) => {
            let got = describe(x);
            let msg = format!("{name} must be a float32 array of shape {want}; got {got} (use np.asarray(x, dtype=np.float32))");
            // A numpy array of another dtype or rank is a value problem; anything else a type problem.
            if x.hasattr("dtype").unwrap_or(false) { Err(PyValueError::new_err(msg)) } else { Err(PyTypeError::new_err(msg)) }
        }
    }
}

/// Rows of a float32 `(N, cols)` array, flattened row by row (any strides).
pub(crate) fn rows(x: &Bound<'_, PyAny>, name: &str, cols: usize) -> PyResult<Vec<f32>> {
    let want = format!("(N, {cols})");
    let a = matrix(x, name, &want)?;
    if a.shape()[1] != cols {
        return Err(PyValueError::new_err(format!("{name} must be a float32 array of shape {want}; got {}", describe(x))));
    }
    let r = a.readonly();
    Ok(r.as_array().iter().copied().collect())
}

/// A float32 `(N, 3)` array as N vectors.
pub(crate) fn vec3s(x: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Vec3>> {
    Ok(rows(x, name, 3)?.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

/// A float32 `(N, 3)` array as N `[f32; 3]`.
pub(crate) fn rgbs(x: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[f32; 3]>> {
    Ok(rows(x, name, 3)?.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Point inputs: one point for every pair (a 1-D array of `k` values) or one per pair (`(N, k)`).
pub(crate) enum PointsIn {
    One(Vec<f32>),
    PerPair(Vec<f32>),
}

pub(crate) fn points(x: &Bound<'_, PyAny>, k: usize, n: usize) -> PyResult<PointsIn> {
    let want = || format!("({k},) for one point or ({n}, {k}) for one per direction pair");
    if let Ok(a) = x.cast::<PyArray1<f32>>() {
        if a.len() != k {
            return Err(PyValueError::new_err(format!("points must have shape {}; got {}", want(), describe(x))));
        }
        return Ok(PointsIn::One(a.readonly().as_array().iter().copied().collect()));
    }
    let a = matrix(x, "points", &want())?;
    if a.shape() != [n, k] {
        return Err(PyValueError::new_err(format!("points must have shape {}; got {}", want(), describe(x))));
    }
    Ok(PointsIn::PerPair(a.readonly().as_array().iter().copied().collect()))
}

/// Checks that every batch argument has the same number of rows.
pub(crate) fn same_len(lens: &[(&str, usize)]) -> PyResult<usize> {
    let n = lens[0].1;
    match lens.iter().find(|(_, l)| *l != n) {
        Some((name, l)) => Err(PyValueError::new_err(format!("{} has {n} rows but {name} has {l}", lens[0].0))),
        None => Ok(n),
    }
}

/// `(N, 3)` float32 out.
pub(crate) fn out3<'py>(py: Python<'py>, v: Vec<[f32; 3]>) -> Bound<'py, PyArray2<f32>> {
    let n = v.len();
    Array2::from_shape_vec((n, 3), v.into_flattened()).expect("n rows of 3").into_pyarray(py)
}

/// `(N,)` float32 out.
pub(crate) fn out1(py: Python<'_>, v: Vec<f32>) -> Bound<'_, PyArray1<f32>> {
    v.into_pyarray(py)
}
