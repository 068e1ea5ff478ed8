//! File-system helpers shared by every writer and reader (feature `std`): atomic writes and reads whose
//! errors name the path.

use std::path::Path;
use std::vec::Vec;

use crate::Error;

/// Reads a whole file; the error names the path.
pub fn read(path: &Path) -> Result<Vec<u8>, Error> {
    std::fs::read(path).map_err(|e| Error::io(path, &e))
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so that an
/// interrupted write never leaves a truncated file under the final name, and an existing file is only
/// replaced by a complete one.
///
/// ```
/// let dir = std::env::temp_dir().join("nbrdf-doc-write-atomic");
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("a.bin");
/// nbrdf::io::write_atomic(&path, b"abc").unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"abc");
/// ```
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    use std::io::Write;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path.file_name().ok_or_else(|| Error::Io {
        path: path.to_path_buf(),
        kind: std::io::ErrorKind::InvalidInput,
        message: "not a file path".into(),
    })?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(std::format!(".{}.tmp", std::process::id()));
    let tmp = dir.join(tmp_name);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, &e)
    })
}
