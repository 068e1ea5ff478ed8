//! The trainer's JSON files (checkpoints, study configs and results) read whole, with errors that
//! name the file, and the line and column or the byte that is wrong.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::{Error, Result};

/// Most bytes of a JSON file read, 256 MiB: a checkpoint of the largest variant is a few MB and a
/// paper-scale study's results some tens, so a longer file or a device (`/dev/zero`) is a wrong
/// path, refused without filling the memory.
pub const MAX_JSON_BYTES: u64 = 256 << 20;

/// Reads `path` as JSON of type `T`; `what` says what the file should be ("study config").
///
/// The whole file must be UTF-8: serde_json does not check the bytes of values it skips, so an
/// invalid byte in an unknown field would otherwise pass. At most [`MAX_JSON_BYTES`] are read.
pub fn read<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    parse(path, what, &read_bytes(path)?)
}

/// The bytes of a JSON file, at most [`MAX_JSON_BYTES`]; the error names the file.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    nbrdf::io::read_at_most(path, MAX_JSON_BYTES).map_err(Error::Core)
}

/// [`read`] on bytes already read from `path`.
pub fn parse<T: DeserializeOwned>(path: &Path, what: &str, bytes: &[u8]) -> Result<T> {
    if let Err(e) = std::str::from_utf8(bytes) {
        return Err(Error::Invalid(format!("{}: not a {what}: not UTF-8 (invalid byte at offset {})", path.display(), e.valid_up_to())));
    }
    // The path of the value that is wrong (`models[3].reciprocity`) goes before serde's message.
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let at = e.path().to_string();
        let inner = e.into_inner();
        let key = if at == "." { String::new() } else { format!("\"{at}\": ") };
        Error::Invalid(format!("{}: not a {what}: {key}{inner}", path.display()))
    })?;
    de.end().map_err(|e| Error::Invalid(format!("{}: not a {what}: {e}", path.display())))?;
    Ok(value)
}
