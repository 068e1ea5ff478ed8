//! The trainer's error type: what failed and where, as a value.

use std::fmt;
use std::path::PathBuf;

/// A failure of fitting, exporting or reading training data.
#[derive(Debug)]
pub enum Error {
    /// A tensor operation failed (shapes, dtypes): a bug or inconsistent input sizes.
    Candle(candle_core::Error),
    /// Reading or writing a file.
    Io { path: PathBuf, message: String },
    /// The core rejected a model, file or value (data sets report their files' problems this way).
    Core(nbrdf::Error),
    /// The intrinsic encoding of a mesh could not be computed, cached or read.
    Intrinsic(crate::intrinsic::Error),
    /// The loss or a gradient stopped being finite; the weights were not updated with it.
    NonFinite {
        /// Training step (0-based) whose loss or gradient was NaN or infinite.
        step: usize,
        /// What was not finite.
        what: &'static str,
        /// The last checkpoint written from finite weights, if any.
        last_good: Option<PathBuf>,
    },
    /// Training data or options that cannot be used.
    Invalid(String),
    /// The embedding process asked the work to stop ([`crate::cancel`]); nothing was written.
    Interrupted,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Candle(e) => write!(f, "tensor operation failed: {e}"),
            Error::Io { path, message } => write!(f, "{}: {message}", path.display()),
            Error::Core(e) => write!(f, "{e}"),
            Error::Intrinsic(e) => write!(f, "intrinsic encoding of the mesh: {e}"),
            Error::NonFinite { step, what, last_good } => {
                write!(f, "the {what} became NaN or infinite at step {step}; training stopped")?;
                match last_good {
                    Some(p) => write!(f, "; the last good checkpoint is {}", p.display()),
                    None => write!(f, " before any checkpoint was written"),
                }
            }
            Error::Invalid(m) => f.write_str(m),
            Error::Interrupted => f.write_str("interrupted; the output folder is left as it was"),
        }
    }
}

impl std::error::Error for Error {}

impl From<candle_core::Error> for Error {
    fn from(e: candle_core::Error) -> Self {
        Error::Candle(e)
    }
}

impl From<crate::intrinsic::Error> for Error {
    fn from(e: crate::intrinsic::Error) -> Self {
        Error::Intrinsic(e)
    }
}

impl From<nbrdf::Error> for Error {
    fn from(e: nbrdf::Error) -> Self {
        Error::Core(e)
    }
}

impl Error {
    /// The same error with `what` (a file and field, a flag) in front, as [`nbrdf::Error::context`]
    /// does for the core's errors.
    pub fn context(self, what: impl fmt::Display) -> Self {
        match self {
            Error::Core(e) => Error::Core(e.context(what)),
            Error::Invalid(m) => Error::Invalid(format!("{what}: {m}")),
            other => other,
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, e: impl fmt::Display) -> Self {
        Error::Io { path: path.into(), message: e.to_string() }
    }
}

/// The trainer's result type.
pub type Result<T> = std::result::Result<T, Error>;
