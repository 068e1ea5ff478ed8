//! Status codes, this thread's last error message, and the guard that turns every error and every
//! panic into a status before it reaches the caller.

use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, UnwindSafe};

use nbrdf_core::Error;

/// The result of every fallible function. `NBRDF_STATUS_OK` is 0; on any other value
/// [`nbrdf_last_error`] says what went wrong, and the function's outputs are left untouched.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NbrdfStatus {
    /// Success.
    Ok = 0,
    /// A required pointer was null.
    NullPointer = 1,
    /// A pointer lacks the alignment its type needs (4 bytes for borrowed model bytes, the point
    /// storage's [`nbrdf_point_align`](crate::nbrdf_point_align)).
    Misaligned = 2,
    /// A buffer is too small or a length is wrong (point input, point storage, output array).
    BufferSize = 3,
    /// A file could not be read (missing, permissions, ...).
    Io = 4,
    /// A file or byte buffer ends early.
    Truncated = 5,
    /// A model file written by a format version this library does not read.
    Version = 6,
    /// Malformed data: bad magic, checksum mismatch, unparsable JSON, inconsistent sizes.
    Corrupt = 7,
    /// A value outside its valid range (a parameter, a non-finite number, an unknown name).
    InvalidValue = 8,
    /// Point storage not written by `nbrdf_prepare` for this BRDF, or no point for a BRDF that varies
    /// over the surface.
    InvalidPoint = 9,
    /// A bug in nbrdf (a caught panic); the message says where.
    Panic = 10,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// The message of this thread's last failed call (UTF-8, no trailing newline), or `""` if none has
/// failed. The pointer stays valid until the next failing call on this thread; copy it to keep it.
/// Thread safe (each thread has its own message).
#[no_mangle]
pub extern "C" fn nbrdf_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// A failed call: the status and its message.
pub(crate) struct Failure(pub NbrdfStatus, pub String);

pub(crate) type Result<T> = std::result::Result<T, Failure>;

/// A failure with a message.
pub(crate) fn fail<T>(status: NbrdfStatus, message: impl Into<String>) -> Result<T> {
    Err(Failure(status, message.into()))
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        let status = match &e {
            Error::Io { .. } => NbrdfStatus::Io,
            Error::Truncated { .. } => NbrdfStatus::Truncated,
            Error::UnsupportedVersion { .. } => NbrdfStatus::Version,
            Error::Misaligned => NbrdfStatus::Misaligned,
            Error::InvalidValue { .. } | Error::NonFinite { .. } => NbrdfStatus::InvalidValue,
            Error::BadMagic { .. }
            | Error::SizeMismatch { .. }
            | Error::TooLarge { .. }
            | Error::ChecksumMismatch { .. }
            | Error::Parse { .. } => NbrdfStatus::Corrupt,
            // A kind of error added to the core later: its message still says what happened.
            _ => NbrdfStatus::InvalidValue,
        };
        Failure(status, e.to_string())
    }
}

/// Runs one exported function's body: its error, or a panic, becomes a status and this thread's
/// message.
pub(crate) fn guard(body: impl FnOnce() -> Result<()> + UnwindSafe) -> NbrdfStatus {
    let failure = match catch_unwind(body) {
        Ok(Ok(())) => return NbrdfStatus::Ok,
        Ok(Err(f)) => f,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Failure(NbrdfStatus::Panic, format!("internal error in nbrdf (please report): {what}"))
        }
    };
    // Interior NULs cannot end up in a C string: replace them.
    let message = CString::new(failure.1.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = message);
    failure.0
}
