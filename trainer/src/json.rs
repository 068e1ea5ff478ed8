//! The trainer's JSON files (checkpoints, study configs and results) read whole, with errors that
//! name the file, and the line and column or the byte that is wrong.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::{Error, Result};

/// Reads `path` as JSON of type `T`; `what` says what the file should be ("study config").
///
/// The whole file must be UTF-8: serde_json does not check the bytes of values it skips, so an
/// invalid byte in an unknown field would otherwise pass.
pub fn read<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(path, what, &bytes)
}

/// [`read`] on bytes already read from `path`.
pub fn parse<T: DeserializeOwned>(path: &Path, what: &str, bytes: &[u8]) -> Result<T> {
    if let Err(e) = std::str::from_utf8(bytes) {
        return Err(Error::Invalid(format!("{}: not a {what}: not UTF-8 (invalid byte at offset {})", path.display(), e.valid_up_to())));
    }
    serde_json::from_slice(bytes).map_err(|e| Error::Invalid(format!("{}: not a {what}: {e}", path.display())))
}
