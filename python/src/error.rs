//! Rust errors as Python exceptions: the message is the Rust error's, the class says what kind of
//! failure it was (a missing file is a `FileNotFoundError`, a bad value a `ValueError`), and a panic
//! is a `RuntimeError` rather than PyO3's `PanicException`, a `BaseException` that `except Exception`
//! lets through.

use std::io::ErrorKind;
use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyRuntimeError, PyValueError};
use pyo3::PyErr;
use pyo3::PyResult;

/// A core error: I/O failures as the matching `OSError` subclass, everything else (malformed files,
/// wrong sizes, values out of range) as `ValueError`.
pub(crate) fn core(e: nbrdf::Error) -> PyErr {
    match &e {
        nbrdf::Error::Io { kind, .. } => io(*kind, e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

fn io(kind: ErrorKind, message: String) -> PyErr {
    match kind {
        ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// A trainer error: bad options and data as `ValueError`, file failures as `OSError`, a loss that
/// stopped being finite or a failed tensor operation as `RuntimeError`.
pub(crate) fn trainer(e: trainer::Error) -> PyErr {
    match e {
        trainer::Error::Core(c) => core(c),
        trainer::Error::Io { .. } => {
            let missing = matches!(&e, trainer::Error::Io { path, .. } if !path.exists());
            io(if missing { ErrorKind::NotFound } else { ErrorKind::Other }, e.to_string())
        }
        trainer::Error::Invalid(m) => PyValueError::new_err(m),
        trainer::Error::Intrinsic(trainer::intrinsic::Error::Io { .. }) => io(ErrorKind::Other, e.to_string()),
        trainer::Error::Intrinsic(_) => PyValueError::new_err(e.to_string()),
        trainer::Error::Interrupted => pyo3::exceptions::PyKeyboardInterrupt::new_err(e.to_string()),
        trainer::Error::Candle(_) | trainer::Error::NonFinite { .. } => PyRuntimeError::new_err(e.to_string()),
    }
}

/// Runs `body`, turning a panic into a `RuntimeError` with the panic's message.
pub(crate) fn guard<T>(body: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(r) => r,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!("internal error in nbrdf (please report): {what}")))
        }
    }
}
