//! numpy arrays in and out, with numpy's conventions for what goes in: any array-like of real numbers
//! (an array of any real dtype, layout or byte order, a list, a tuple, a numpy scalar; integers for
//! vertex indices, booleans for masks), and the leading
//! dimensions of a call's arguments broadcast against each other by numpy's rules (a single `(3,)`
//! direction against `(N, 3)`, `(1, 3)` against `(N, 3)`, `(H, W, 3)` images of directions).
//!
//! The cost, the same for every argument: each input is read once into the call's own float32
//! buffer while the GIL is held, so that the work can run without it while Python threads change the
//! arrays. Aligned native float32 and float64 arrays (any strides) are read in place, float64 rounded
//! to nearest as `astype(np.float32)` rounds; anything else is made an array by `numpy.asarray` and,
//! where it is not one of those, converted to float32 once by `astype` (indices: uint32 read in
//! place, other integers as int64 or uint64). Strings, objects, complex numbers and datetimes are
//! refused naming the argument, never cast.

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use nbrdf::Vec3;

/// The values of an input, where they lie.
enum Data<'py> {
    F32(Bound<'py, PyArrayDyn<f32>>),
    F64(Bound<'py, PyArrayDyn<f64>>),
    I64(Bound<'py, PyArrayDyn<i64>>),
    U64(Bound<'py, PyArrayDyn<u64>>),
    U32(Bound<'py, PyArrayDyn<u32>>),
    Bool(Bound<'py, PyArrayDyn<bool>>),
}

/// What an argument holds.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    /// Real numbers, read as float32 (bool and integers accepted as numpy accepts them into a float
    /// array).
    Real,
    /// Integers (vertex indices), read as u32.
    Index,
    /// Booleans (masks).
    Bool,
}

/// One array argument of a call, converted (where it had to be) but not yet read.
pub(crate) struct Input<'py> {
    name: String,
    data: Data<'py>,
    shape: Vec<usize>,
    /// What the caller passed, for messages: `float64 array of shape (4, 3)` or `list of shape (4,)`.
    what: String,
}

/// `(4, 3)`, `(3,)`, `()`: a shape as numpy writes it.
pub(crate) fn shape_str(s: &[usize]) -> String {
    match s {
        [n] => format!("({n},)"),
        _ => format!("({})", s.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// `x` as an aligned native array of one of the types `kind` reads in place, if it is one (any
/// strides).
fn readable<'py>(x: &Bound<'py, PyAny>, kind: Kind) -> Option<Data<'py>> {
    fn aligned<'py, T: numpy::Element>(x: &Bound<'py, PyAny>) -> Option<Bound<'py, PyArrayDyn<T>>> {
        x.cast::<PyArrayDyn<T>>().ok().filter(|a| a.is_aligned()).cloned()
    }
    match kind {
        Kind::Real => aligned(x).map(Data::F32).or_else(|| aligned(x).map(Data::F64)),
        Kind::Index => aligned(x).map(Data::U32).or_else(|| aligned(x).map(Data::I64)).or_else(|| aligned(x).map(Data::U64)),
        Kind::Bool => aligned(x).map(Data::Bool),
    }
}

/// `numpy.asarray(x)`, a numpy error (a ragged list, say) re-raised as the same class with `name` in
/// front of its message.
fn asarray<'py>(x: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let py = x.py();
    py.import("numpy")?.getattr("asarray")?.call1((x,)).map_err(|e| {
        let msg = format!("{name}: {}", e.value(py));
        if e.is_instance_of::<PyTypeError>(py) {
            PyTypeError::new_err(msg)
        } else if e.is_instance_of::<PyValueError>(py) {
            PyValueError::new_err(msg)
        } else {
            e
        }
    })
}

/// `x` as an array of real numbers: read in place where it is an aligned native float32 or float64
/// array, else `numpy.asarray(x)` converted by `astype(np.float32)` once.
pub(crate) fn real<'py>(x: &Bound<'py, PyAny>, name: &str) -> PyResult<Input<'py>> {
    input(x, name, Kind::Real)
}

/// `x` as an array argument holding `kind`: `numpy.asarray(x)` (nothing for an array), its dtype
/// checked, then read in place or converted once by `astype`.
pub(crate) fn input<'py>(x: &Bound<'py, PyAny>, name: &str, kind: Kind) -> PyResult<Input<'py>> {
    let py = x.py();
    let is_array = x.cast::<PyUntypedArray>().is_ok();
    let a = if is_array { x.clone() } else { asarray(x, name)? };
    let u = a.cast::<PyUntypedArray>()?;
    let shape = u.shape().to_vec();
    let dtype = u.dtype();
    let what = if is_array {
        format!("{} array of shape {}", dtype.str()?, shape_str(&shape))
    } else {
        let ty = x.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "object".into());
        format!("{ty} of shape {} (as {} values)", shape_str(&shape), dtype.str()?)
    };
    let (want, accepted, to) = match kind {
        Kind::Real => ("real numbers", &b"biuf"[..], "float32"),
        // Indices as numpy takes them: integers only, not bool or float.
        Kind::Index => ("integers", &b"iu"[..], if dtype.kind() == b'u' { "uint64" } else { "int64" }),
        Kind::Bool => ("booleans", &b"b"[..], "bool"),
    };
    if !accepted.contains(&dtype.kind()) {
        let msg = format!("{name} must hold {want}; got {what}");
        // numpy's own classes where it refuses a value: ValueError for strings, TypeError otherwise
        // (complex numbers, which numpy would cast to float with a warning, are refused too).
        return Err(if matches!(dtype.kind(), b'U' | b'S') { PyValueError::new_err(msg) } else { PyTypeError::new_err(msg) });
    }
    let data = match readable(&a, kind) {
        Some(d) => d,
        None => {
            let c = a.call_method1("astype", (py.import("numpy")?.getattr(to)?,))?;
            readable(&c, kind).expect("astype makes an aligned native array")
        }
    };
    Ok(Input { name: name.to_string(), data, shape, what })
}

/// The values of `a` broadcast to `dim`, in logical order (a copy the call owns).
fn gather<T: numpy::Element + Copy, U>(a: &Bound<'_, PyArrayDyn<T>>, dim: &[usize], f: impl Fn(T) -> U) -> Vec<U> {
    let r = a.readonly();
    r.as_array().broadcast(IxDyn(dim)).expect("a checked broadcast").iter().map(|&v| f(v)).collect()
}

impl Input<'_> {
    pub(crate) fn shape(&self) -> &[usize] {
        &self.shape
    }

    /// Checks that the last dimension has `cols` values (`want` names the accepted shapes for the
    /// message) and returns the leading shape.
    pub(crate) fn rows_of(&self, cols: usize, want: &str) -> PyResult<&[usize]> {
        match self.shape.split_last() {
            Some((&c, lead)) if c == cols => Ok(lead),
            _ => Err(self.shape_error(want)),
        }
    }

    /// "`name` must have shape `want`; got `what it is`".
    pub(crate) fn shape_error(&self, want: &str) -> PyErr {
        PyValueError::new_err(format!("{} must have shape {want}; got {}", self.name, self.what))
    }

    /// The leading shape (all but the last dimension).
    pub(crate) fn lead(&self) -> &[usize] {
        &self.shape[..self.shape.len().saturating_sub(1)]
    }

    /// `lead` followed by this argument's last dimension (`keep_last`), or `lead` alone.
    fn dim(&self, lead: &[usize], keep_last: bool) -> Vec<usize> {
        let mut dim = lead.to_vec();
        if keep_last {
            dim.extend(self.shape.last());
        }
        dim
    }

    /// Real values broadcast to `lead` followed by this argument's last dimension, row by row.
    /// `lead` must be a broadcast of `self.lead()`.
    pub(crate) fn floats(&self, lead: &[usize]) -> Vec<f32> {
        let dim = self.dim(lead, true);
        match &self.data {
            Data::F32(a) => gather(a, &dim, |v| v),
            // Round to nearest, ties to even: numpy's astype(np.float32), bit for bit.
            Data::F64(a) => gather(a, &dim, |v| v as f32),
            _ => unreachable!("a real input is float32 or float64"),
        }
    }

    /// Indices broadcast to `lead` followed by the last dimension, each checked to fit u32.
    pub(crate) fn indices(&self, lead: &[usize]) -> PyResult<Vec<u32>> {
        let dim = self.dim(lead, true);
        let wide: Vec<i128> = match &self.data {
            Data::U32(a) => return Ok(gather(a, &dim, |v| v)),
            Data::I64(a) => gather(a, &dim, i128::from),
            Data::U64(a) => gather(a, &dim, i128::from),
            _ => unreachable!("an index input is an integer array"),
        };
        wide.iter()
            .map(|&v| u32::try_from(v).map_err(|_| PyValueError::new_err(format!("{}: index {v} is negative or too large", self.name))))
            .collect()
    }

    /// Booleans broadcast to `lead` (the whole shape is leading: no last dimension is kept).
    pub(crate) fn bools(&self, lead: &[usize]) -> Vec<bool> {
        match &self.data {
            Data::Bool(a) => gather(a, lead, |v| v),
            _ => unreachable!("a bool input is a bool array"),
        }
    }

    /// The values as `Vec3`s broadcast to `lead` (the last dimension must be 3).
    pub(crate) fn vec3s(&self, lead: &[usize]) -> Vec<Vec3> {
        self.floats(lead).chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
    }

    /// The values as `[f32; 3]`s broadcast to `lead` (the last dimension must be 3).
    pub(crate) fn rgbs(&self, lead: &[usize]) -> Vec<[f32; 3]> {
        self.floats(lead).chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }
}

/// The broadcast of the arguments' leading shapes by numpy's rules (aligned at the right; a 1 or a
/// missing dimension stretches), or a ValueError naming every argument and its shape.
pub(crate) fn broadcast(shapes: &[(&str, &[usize])]) -> PyResult<Vec<usize>> {
    let ndim = shapes.iter().map(|(_, s)| s.len()).max().unwrap_or(0);
    let mut out = vec![1usize; ndim];
    for (_, s) in shapes {
        for (o, &d) in out[ndim - s.len()..].iter_mut().zip(s.iter()) {
            if *o == 1 {
                *o = d;
            } else if d != 1 && d != *o {
                let all: Vec<String> = shapes.iter().map(|(n, s)| format!("{n} {}", shape_str(s))).collect();
                return Err(PyValueError::new_err(format!(
                    "the leading dimensions of {} do not broadcast together (numpy's rules)",
                    all.join(", ")
                )));
            }
        }
    }
    Ok(out)
}

/// One 3-vector (a point, a direction, an RGB value) of any real dtype or array-like, shape (3,).
pub(crate) fn vec3(x: &Bound<'_, PyAny>, name: &str) -> PyResult<[f32; 3]> {
    let a = real(x, name)?;
    if a.shape() != [3] {
        return Err(a.shape_error("(3,)"));
    }
    let v = a.floats(&[]);
    Ok([v[0], v[1], v[2]])
}

/// The shapes a direction argument takes, for messages.
pub(crate) const WANT3: &str = "(3,) or (N, 3) (any leading shape: (..., 3))";

/// Float32 out with shape `lead` followed by `tail` (`v` holds that many values, row by row).
pub(crate) fn out<'py>(py: Python<'py>, lead: &[usize], tail: &[usize], v: Vec<f32>) -> Bound<'py, PyArrayDyn<f32>> {
    let shape: Vec<usize> = lead.iter().chain(tail).copied().collect();
    ArrayD::from_shape_vec(IxDyn(&shape), v).expect("the values of the shape").into_pyarray(py)
}

/// `(..., 3)` float32 out.
pub(crate) fn out3<'py>(py: Python<'py>, lead: &[usize], v: Vec<[f32; 3]>) -> Bound<'py, PyArrayDyn<f32>> {
    out(py, lead, &[3], v.into_flattened())
}

/// Float32 out with shape `lead`: a numpy float32 scalar where `lead` is `()`, as numpy's own functions
/// return a single value.
pub(crate) fn out1<'py>(py: Python<'py>, lead: &[usize], v: Vec<f32>) -> PyResult<Bound<'py, PyAny>> {
    let a = out(py, lead, &[], v);
    if lead.is_empty() {
        a.get_item(PyTuple::empty(py))
    } else {
        Ok(a.into_any())
    }
}
