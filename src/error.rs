//! The crate's error type: every failure on input data is a value that says what is wrong and where,
//! never a panic.

use core::fmt;

#[cfg(feature = "alloc")]
use alloc::string::String;

/// What went wrong while reading or validating input data.
///
/// `what` fields name the file section, table or field concerned so that a message alone locates the
/// problem.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// The input ended before `what` was complete.
    Truncated {
        /// The part being read.
        what: &'static str,
        /// Bytes (or elements) needed.
        needed: usize,
        /// Bytes (or elements) present.
        got: usize,
    },
    /// The file does not start with the expected magic bytes.
    BadMagic {
        /// The format expected.
        what: &'static str,
    },
    /// A format version this build cannot read.
    UnsupportedVersion {
        /// The format.
        what: &'static str,
        /// Version found in the file.
        found: u32,
        /// Newest version this build reads.
        supported: u32,
    },
    /// A size, count or dimension disagrees with what the rest of the input implies.
    SizeMismatch {
        /// The quantity.
        what: &'static str,
        /// Expected value.
        expected: usize,
        /// Value found.
        found: usize,
    },
    /// A size or count exceeds a fixed limit of the evaluator (stack array capacity, ...).
    TooLarge {
        /// The quantity.
        what: &'static str,
        /// Value found.
        found: usize,
        /// Largest accepted value.
        max: usize,
    },
    /// Stored and computed checksums differ: the file is corrupt.
    ChecksumMismatch {
        /// Checksum stored in the file.
        stored: u32,
        /// Checksum of the bytes read.
        computed: u32,
    },
    /// A NaN or infinite number where finite numbers are required.
    NonFinite {
        /// The array or field.
        what: &'static str,
        /// Index of the first offending element.
        index: usize,
    },
    /// A field holds a value outside its domain (unknown enum tag, inconsistent configuration, ...).
    InvalidValue {
        /// The field.
        what: &'static str,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// Zero-copy loading needs 4-byte aligned bytes; use the copying loader instead.
    Misaligned,
    /// A text format (JSON, OBJ, PLY, ...) could not be parsed.
    #[cfg(feature = "alloc")]
    Parse {
        /// The format or file.
        what: String,
        /// The parser's message.
        message: String,
    },
    /// A problem located in the user's terms: `what` is the file and field, the flag or the config
    /// key (and value), `message` what is wrong and what is allowed.
    #[cfg(feature = "alloc")]
    Context {
        /// Where: a file and its field, a flag, a config key.
        what: String,
        /// What is wrong there.
        message: String,
    },
    /// An I/O error, with the path it concerns.
    #[cfg(feature = "std")]
    Io {
        /// The path read or written.
        path: std::path::PathBuf,
        /// The kind of I/O failure.
        kind: std::io::ErrorKind,
        /// The operating system's message.
        message: String,
    },
}

impl Error {
    /// Wraps an I/O error with the path it concerns.
    #[cfg(feature = "std")]
    pub fn io(path: impl Into<std::path::PathBuf>, err: &std::io::Error) -> Self {
        use alloc::string::ToString;
        Error::Io { path: path.into(), kind: err.kind(), message: err.to_string() }
    }
}

impl Error {
    /// `self` located at `what` (a file, a view, a config key): I/O errors already name their path and
    /// are returned as they are, so that callers can still tell a missing file from a malformed one.
    #[cfg(feature = "alloc")]
    pub fn context(self, what: impl fmt::Display) -> Self {
        use alloc::string::ToString;
        match self {
            #[cfg(feature = "std")]
            e @ Error::Io { .. } => e,
            e => Error::Context { what: what.to_string(), message: e.to_string() },
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Truncated { what, needed, got } => {
                write!(f, "truncated {what}: needed {needed}, got {got}")
            }
            Error::BadMagic { what } => write!(f, "not a {what} file (bad magic bytes)"),
            Error::UnsupportedVersion { what, found, supported } => write!(
                f,
                "{what} version {found} is not supported (this build reads up to version {supported})"
            ),
            Error::SizeMismatch { what, expected, found } => {
                write!(f, "{what}: expected {expected}, found {found}")
            }
            Error::TooLarge { what, found, max } => {
                write!(f, "{what} is {found}, larger than the supported maximum {max}")
            }
            Error::ChecksumMismatch { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): the data is corrupt"
            ),
            Error::NonFinite { what, index } => {
                write!(f, "{what} holds a NaN or infinite value at index {index}")
            }
            Error::InvalidValue { what, reason } => write!(f, "invalid {what}: {reason}"),
            Error::Misaligned => {
                write!(f, "bytes are not 4-byte aligned for zero-copy loading; use the copying loader")
            }
            #[cfg(feature = "alloc")]
            Error::Parse { what, message } => write!(f, "cannot parse {what}: {message}"),
            #[cfg(feature = "alloc")]
            Error::Context { what, message } => write!(f, "{what}: {message}"),
            #[cfg(feature = "std")]
            Error::Io { path, message, .. } => write!(f, "{}: {message}", path.display()),
        }
    }
}

impl core::error::Error for Error {}
