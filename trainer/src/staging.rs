//! Outputs that appear whole or not at all: a folder is built beside its destination and swapped in
//! when complete ([`StagedDir`]), files are written under temporary names and renamed together at the
//! end ([`StagedFile`]). An interrupted or failed run leaves the previous output as it was; what a
//! crashed run left behind (named `.nbrdf-tmp-<pid>-…`, the pid no longer running) is removed by the
//! next run that writes there; what an interrupted one (SIGINT, SIGTERM) staged is removed as it exits
//! ([`remove_staging_on_interrupt`]).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use nbrdf::io::{remove_stale_temps, temp_owner, temp_prefix};
use nbrdf::Error;

/// The folder a path lies in (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

fn name_of(path: &Path) -> Result<String, Error> {
    path.file_name().and_then(|n| n.to_str()).map(str::to_owned).ok_or_else(|| Error::Context {
        what: path.display().to_string(),
        message: "an output folder needs a plain UTF-8 name".into(),
    })
}

/// A folder being written beside `target` under a temporary name; [`commit`](Self::commit) puts it in
/// place of `target` (whose previous content goes only then), dropping it uncommitted removes it.
#[derive(Debug)]
pub struct StagedDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Prepares to replace `target`, which must be absent, an empty folder, or a folder that `owns`
    /// says holds only this kind of output (so that nothing else the user keeps there is replaced).
    /// Restores a previous output a crash left under its temporary name mid-swap, then removes the
    /// leftovers of crashed runs in the parent folder, and creates the staging folder.
    pub fn new(target: &Path, what: &str, owns: impl Fn(&Path) -> bool) -> Result<Self, Error> {
        let parent = parent_of(target);
        let name = name_of(target)?;
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, &e))?;
        if !target.exists() {
            restore_swapped_out(parent, &name);
        }
        remove_stale_temps(parent);
        if target.exists() {
            if !target.is_dir() {
                return Err(Error::Context {
                    what: target.display().to_string(),
                    message: format!("is a file, not a folder; {what} writes a folder"),
                });
            }
            let empty = std::fs::read_dir(target).map_err(|e| Error::io(target, &e))?.next().is_none();
            if !empty && !owns(target) {
                return Err(Error::Context {
                    what: target.display().to_string(),
                    message: format!(
                        "holds files that are not a {what}; it would be replaced whole, so give a new or empty folder"
                    ),
                });
            }
        }
        let staging = parent.join(format!("{}{name}", temp_prefix()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, &e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| Error::io(&staging, &e))?;
        pending().push(staging.clone());
        Ok(StagedDir { staging, target: target.to_path_buf(), committed: false })
    }

    /// Where to write.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Puts the staged folder in place of the target: one atomic exchange where the platform has it
    /// (Linux `renameat2`), else two renames whose gap a crash can only leave recoverable (the previous
    /// output under a temporary name, restored by the next [`StagedDir::new`]).
    pub fn commit(mut self) -> Result<(), Error> {
        // Held until the swap is done, so that an interrupt removes the staging folder before the swap
        // or not at all.
        let mut pending = pending();
        let target = self.target.clone();
        let io = |e: std::io::Error| Error::io(&target, &e);
        sync_dir(&self.staging);
        if !target.exists() {
            std::fs::rename(&self.staging, &target).map_err(io)?;
        } else if std::fs::read_dir(&target).map_err(io)?.next().is_none() {
            std::fs::remove_dir(&target).map_err(io)?;
            std::fs::rename(&self.staging, &target).map_err(io)?;
        } else if exchange(&self.staging, &target).is_ok() {
            // The staging name now holds the previous output.
            std::fs::remove_dir_all(&self.staging).map_err(|e| Error::io(&self.staging, &e))?;
        } else {
            let old = swapped_out_name(parent_of(&target), &name_of(&target)?);
            std::fs::rename(&target, &old).map_err(io)?;
            std::fs::rename(&self.staging, &target).map_err(io)?;
            std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, &e))?;
        }
        sync_dir(parent_of(&target));
        self.committed = true;
        pending.retain(|p| *p != self.staging);
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let mut pending = pending();
            std::fs::remove_dir_all(&self.staging).ok();
            pending.retain(|p| *p != self.staging);
        }
    }
}

/// The staging folders and files of this process not committed yet: what an interrupt removes.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding the list leaves it as it was; it stays usable.
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every staged folder and file not committed yet: each is first renamed aside (so that a
/// writer still running fails to create anything more in it), then removed.
fn remove_pending() {
    let mut pending = pending();
    for p in pending.drain(..) {
        let aside = p.with_file_name(format!("{}-interrupted", p.file_name().unwrap_or_default().to_string_lossy()));
        let target = if std::fs::rename(&p, &aside).is_ok() { aside } else { p };
        match std::fs::symlink_metadata(&target) {
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(&target).ok(),
            _ => std::fs::remove_file(&target).ok(),
        };
    }
}

/// On SIGINT or SIGTERM, removes what this process staged and not yet committed ([`StagedDir`],
/// [`StagedFile`]), then ends the process by the same signal, as it would have ended without this.
/// Without it an interrupted `synth` left its staging folder (as large as the data set) until the
/// next run in that folder. A signal the process started with ignored stays ignored.
///
/// Call it first in `main`, before any thread starts: the signals are blocked in every thread and
/// taken by one thread of their own (`sigwait`), so no handler runs amid other work. Child
/// processes start with the signals unblocked (std's `Command` resets the mask).
#[cfg(unix)]
pub fn remove_staging_on_interrupt() {
    // SAFETY: plain libc calls on a zeroed, then initialised signal set owned here.
    let set = unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for sig in [libc::SIGINT, libc::SIGTERM] {
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN {
                continue;
            }
            libc::sigaddset(&mut set, sig);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        set
    };
    let spawned = std::thread::Builder::new().name("interrupt".into()).spawn(move || {
        let mut sig = 0;
        // SAFETY: `set` is an initialised signal set, `sig` a valid out-parameter.
        if unsafe { libc::sigwait(&set, &mut sig) } != 0 {
            return;
        }
        INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
        remove_pending();
        // SAFETY: restores the default action and delivers the signal again, now unblocked here.
        unsafe {
            libc::signal(sig, libc::SIG_DFL);
            let mut one: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut one);
            libc::sigaddset(&mut one, sig);
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &one, std::ptr::null_mut());
            libc::raise(sig);
        }
        std::process::exit(128 + sig);
    });
    if spawned.is_err() {
        // No thread to take them: the signals act as before.
        // SAFETY: unblocks the set blocked above in this thread.
        unsafe { libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut()) };
    }
}

/// Set once an interrupt is being handled: the process is about to end by its signal.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Ends the process with `code` — unless an interrupt is being handled, whose removal of the staged
/// outputs may be what made the work fail: then it waits for the interrupt to end the process by its
/// signal, so an interrupted run never exits with an error (or success) of its own.
pub fn exit(code: i32) -> ! {
    if INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst) {
        loop {
            std::thread::park();
        }
    }
    std::process::exit(code)
}

/// Whether an interrupt is being handled (see [`exit`]).
pub fn interrupted() -> bool {
    INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst)
}

/// Elsewhere interrupts end the process as before; the next run removes what it staged.
#[cfg(not(unix))]
pub fn remove_staging_on_interrupt() {}

/// The temporary name of a previous output between the two renames of a non-atomic swap.
fn swapped_out_name(parent: &Path, name: &str) -> PathBuf {
    parent.join(format!("{}previous-{name}", temp_prefix()))
}

/// A previous output that a crash left under its swapped-out name (target gone, the writer dead) goes
/// back to its name.
fn restore_swapped_out(parent: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else { return };
    let suffix = format!("-previous-{name}");
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(f) = file.to_str() else { continue };
        if f.ends_with(&suffix)
            && temp_owner(f).is_some_and(|pid| !nbrdf::io::process_alive(pid))
            && std::fs::rename(e.path(), parent.join(name)).is_ok()
        {
            return;
        }
    }
}

#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (ca, cb) = (c(a)?, c(b)?);
    // SAFETY: two valid NUL-terminated paths, relative to the working directory.
    let r = unsafe { libc::renameat2(libc::AT_FDCWD, ca.as_ptr(), libc::AT_FDCWD, cb.as_ptr(), libc::RENAME_EXCHANGE) };
    if r == 0 { Ok(()) } else { Err(std::io::Error::last_os_error()) }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// Flushes a folder's entries (the renames) to disk where the platform allows; best effort.
fn sync_dir(dir: &Path) {
    if let Ok(f) = std::fs::File::open(dir) {
        f.sync_all().ok();
    }
}

/// A file written completely under a temporary name beside `dest`, renamed over it by
/// [`commit_all`]; dropped uncommitted, it is removed.
#[derive(Debug)]
pub struct StagedFile {
    tmp: PathBuf,
    dest: PathBuf,
    /// Whether dropping it uncommitted removes `tmp` (not for a file the run keeps for a resume).
    owned: bool,
}

impl StagedFile {
    /// Writes and syncs `bytes` beside `dest`.
    pub fn new(dest: &Path, bytes: &[u8]) -> Result<Self, Error> {
        let name = name_of(dest)?;
        let tmp = parent_of(dest).join(format!("{}{name}", temp_prefix()));
        let staged = StagedFile { tmp, dest: dest.to_path_buf(), owned: true };
        pending().push(staged.tmp.clone());
        let mut f = std::fs::File::create(&staged.tmp).map_err(|e| Error::io(&staged.tmp, &e))?;
        f.write_all(bytes).and_then(|_| f.sync_all()).map_err(|e| Error::io(dest, &e))?;
        Ok(staged)
    }

    /// A file already written under a name of its own (the checkpoint a run kept updating, which a
    /// resume needs if the commit fails), to be renamed over `dest` with the others.
    pub fn existing(tmp: PathBuf, dest: &Path) -> Self {
        StagedFile { tmp, dest: dest.to_path_buf(), owned: false }
    }
}

impl Drop for StagedFile {
    fn drop(&mut self) {
        if self.owned {
            let mut pending = pending();
            std::fs::remove_file(&self.tmp).ok();
            pending.retain(|p| *p != self.tmp);
        }
    }
}

/// Checks, before any work, that files can be created in `dir` (created if missing): a run that
/// would fail only at its end is refused at its start.
pub fn check_writable(dir: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, &e))?;
    StagedFile::new(&dir.join("write-probe"), b"").map(drop)
}

/// Renames every staged file over its destination, back to back, once all of them are complete.
pub fn commit_all(files: Vec<StagedFile>) -> Result<(), Error> {
    let mut pending = pending();
    for f in &files {
        std::fs::rename(&f.tmp, &f.dest).map_err(|e| Error::io(&f.dest, &e))?;
        pending.retain(|p| *p != f.tmp);
    }
    drop(pending);
    if let Some(f) = files.first() {
        sync_dir(parent_of(&f.dest));
    }
    Ok(())
}
