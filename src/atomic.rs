//! Atomic file writes: a reader sees either the old file or the complete new one, never a torn write.

use std::io::{BufWriter, Write};
use std::path::Path;

use crate::Error;

/// Writes `path` through `fill`: into a temporary file in the same directory (so that the final rename
/// stays on one file system), flushed and synced, then renamed over `path`. On any error the temporary
/// file is removed and `path` is untouched.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("nbrdf-atomic-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let p = dir.join("hello.txt");
/// nbrdf::atomic::write_atomic(&p, |w| { use std::io::Write; w.write_all(b"hi") }).unwrap();
/// assert_eq!(std::fs::read(&p).unwrap(), b"hi");
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<(), Error>
where
    F: FnOnce(&mut BufWriter<&mut std::fs::File>) -> std::io::Result<()>,
{
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".nbrdf-tmp-")
        .tempfile_in(dir)
        .map_err(|e| Error::io(dir, &e))?;
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        fill(&mut w).and_then(|_| w.flush()).map_err(|e| Error::io(path, &e))?;
    }
    tmp.as_file().sync_all().map_err(|e| Error::io(path, &e))?;
    tmp.persist(path).map_err(|e| Error::io(path, &e.error))?;
    Ok(())
}
