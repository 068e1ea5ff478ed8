//! File-system helpers shared by every writer and reader (feature `std`): atomic writes and reads whose
//! errors name the path, and the names of their temporary files (`.nbrdf-tmp-<pid>-…`) with the removal
//! of those a crashed process left behind. std only: `nbrdf-scene`'s image writers and the trainer's
//! staging build on these.

use std::path::Path;
use std::vec::Vec;

use crate::Error;

/// Most bytes [`read`] reads of one file, 2 GiB: twice the largest per-vertex table a model file
/// carries from the trainer (2^28 f32 values), so that a wrong path (`/dev/zero`, a disk image) is
/// refused instead of filling the memory.
pub const MAX_READ_BYTES: u64 = 2 << 30;

/// Reads a whole file of at most [`MAX_READ_BYTES`]; the error names the path.
pub fn read(path: &Path) -> Result<Vec<u8>, Error> {
    read_at_most(path, MAX_READ_BYTES)
}

/// Reads a whole file of at most `max` bytes; the error names the path. A longer regular file is
/// refused by its length before a byte is read; a device or pipe, whose length says nothing, is read
/// no further than `max + 1` bytes. Either is an [`Error::Io`] of kind `FileTooLarge`.
///
/// ```
/// let err = nbrdf::io::read_at_most(std::path::Path::new("/dev/zero"), 1024).unwrap_err();
/// assert!(err.to_string().contains("/dev/zero") && err.to_string().contains("1024 bytes"));
/// ```
pub fn read_at_most(path: &Path, max: u64) -> Result<Vec<u8>, Error> {
    use std::io::Read;
    let too_large = |found: &str| {
        let e = std::io::Error::new(std::io::ErrorKind::FileTooLarge, std::format!("{found}, more than the {max} bytes read of such a file"));
        Error::io(path, &e)
    };
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
    let len = file.metadata().map_err(|e| Error::io(path, &e))?.len();
    if len > max {
        return Err(too_large(&std::format!("{len} bytes")));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max.saturating_add(1)).read_to_end(&mut bytes).map_err(|e| Error::io(path, &e))?;
    if bytes.len() as u64 > max {
        return Err(too_large("it yields more bytes"));
    }
    Ok(bytes)
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
    write_atomic_with(path, |w| std::io::Write::write_all(w, bytes))
}

/// Streams `path` through `fill`, for encoders that write into a `Write + Seek` (EXR, PNG): into a
/// uniquely named temporary file in the same directory (so that the final rename stays on one file
/// system; unique, so that threads writing the same name cannot collide), flushed and synced, then
/// renamed over `path`. On any error the temporary file is removed and `path` is untouched.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("nbrdf-atomic-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let p = dir.join("hello.txt");
/// nbrdf::io::write_atomic_with(&p, |w| { use std::io::Write; w.write_all(b"hi") }).unwrap();
/// assert_eq!(std::fs::read(&p).unwrap(), b"hi");
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_atomic_with<F>(path: &Path, fill: F) -> Result<(), Error>
where
    F: FnOnce(&mut std::io::BufWriter<&mut std::fs::File>) -> std::io::Result<()>,
{
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let (tmp_path, mut file) = create_temp(dir)?;
    // Removes the temporary file on every early return below; disarmed once it has been renamed.
    let tmp = RemoveOnDrop(Some(tmp_path));
    {
        let mut w = std::io::BufWriter::new(&mut file);
        fill(&mut w).and_then(|_| std::io::Write::flush(&mut w)).map_err(|e| Error::io(path, &e))?;
    }
    file.sync_all().map_err(|e| Error::io(path, &e))?;
    // Closed before the rename, which some platforms refuse on an open file.
    drop(file);
    tmp.persist(path)
}

/// A new, empty file of a unique name `<temp_prefix()><16 hex digits>` in `dir`, created exclusively
/// (never an existing file or a link followed), mode 0666 minus the umask on Unix like any data file.
/// The digits come from std's randomly keyed hasher, fresh for every try; a name that is taken is
/// tried again with new digits.
fn create_temp(dir: &Path) -> Result<(std::path::PathBuf, std::fs::File), Error> {
    use std::hash::{BuildHasher, Hasher};
    // The pid in the name lets a later run tell a crashed writer's leftover from a live one's.
    let prefix = temp_prefix();
    let mut tries = 0;
    loop {
        let digits = std::hash::RandomState::new().build_hasher().finish();
        let p = dir.join(std::format!("{prefix}{digits:016x}"));
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o666);
        match options.open(&p) {
            Ok(file) => return Ok((p, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 64 => tries += 1,
            Err(e) => return Err(Error::io(dir, &e)),
        }
    }
}

/// A temporary file that is removed when dropped, unless [`persist`](Self::persist) renamed it.
struct RemoveOnDrop(Option<std::path::PathBuf>);

impl RemoveOnDrop {
    /// Renames the file over `path` (replacing a file there); on failure it is removed.
    fn persist(mut self, path: &Path) -> Result<(), Error> {
        if let Some(tmp) = &self.0 {
            std::fs::rename(tmp, path).map_err(|e| Error::io(path, &e))?;
        }
        self.0 = None;
        Ok(())
    }
}

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        if let Some(p) = self.0.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Prefix of every temporary file or folder this process creates beside an output:
/// `.nbrdf-tmp-<pid>-`. [`remove_stale_temps`] removes those of processes that are gone.
pub fn temp_prefix() -> std::string::String {
    std::format!("{TEMP_PREFIX}{}-", std::process::id())
}

const TEMP_PREFIX: &str = ".nbrdf-tmp-";

/// The pid a temporary name of [`temp_prefix`] carries, if `name` is one.
pub fn temp_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(TEMP_PREFIX)?;
    rest.split_once('-')?.0.parse().ok()
}

/// Whether process `pid` is still running. Where the platform cannot tell (no `/proc`), every
/// process counts as alive, so that nothing of a running writer is ever removed.
pub fn process_alive(pid: u32) -> bool {
    let proc_root = Path::new("/proc");
    if !proc_root.join("self").exists() {
        return true;
    }
    pid == std::process::id() || proc_root.join(std::format!("{pid}")).exists()
}

/// Removes the temporary files and folders in `dir` that writers which no longer run left behind
/// (a crash, SIGKILL or SIGINT between creating and renaming them); returns how many. A missing or
/// unreadable `dir` has none.
pub fn remove_stale_temps(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else { continue };
        if process_alive(pid) {
            continue;
        }
        let path = entry.path();
        let gone = match entry.file_type() {
            Ok(t) if t.is_dir() => std::fs::remove_dir_all(&path),
            _ => std::fs::remove_file(&path),
        };
        removed += usize::from(gone.is_ok());
    }
    removed
}
