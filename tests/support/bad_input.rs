//! What the bad-input tests of the core and of nbrdf-scene share (included by both with `#[path]`):
//! an error matcher, a scratch folder, a folder made unwritable, a folder's listing and the check that
//! failed writes leave a folder as it was.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// Asserts that `$result` is an `Err` matching `$pat`, naming the case and what came instead.
#[macro_export]
macro_rules! assert_err {
    ($case:expr, $result:expr, $pat:pat $(if $guard:expr)?) => {
        match $result {
            Err($pat) $(if $guard)? => {}
            Err(other) => panic!("{}: expected {}, got the error {other:?}", $case, stringify!($pat)),
            Ok(_) => panic!("{}: expected {}, got Ok", $case, stringify!($pat)),
        }
    };
}

/// A scratch directory removed at the end of the test.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("nbrdf-bad-input-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Makes `dir` unwritable for the duration of the guard: mode 0555, or for root (whom permissions do not
/// stop) the immutable attribute. `None` where neither works here.
pub struct ReadOnly {
    dir: PathBuf,
    immutable: bool,
}

impl ReadOnly {
    pub fn new(dir: &Path) -> Option<Self> {
        use std::os::unix::fs::PermissionsExt;
        let writable = || {
            let probe = dir.join(".probe");
            let ok = std::fs::File::create(&probe).is_ok();
            let _ = std::fs::remove_file(&probe);
            ok
        };
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o555)).unwrap();
        if !writable() {
            return Some(ReadOnly { dir: dir.to_path_buf(), immutable: false });
        }
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755)).unwrap();
        let chattr = std::process::Command::new("chattr").arg("+i").arg(dir).output();
        let guard = ReadOnly { dir: dir.to_path_buf(), immutable: true };
        if chattr.is_ok_and(|o| o.status.success()) && !writable() {
            Some(guard)
        } else {
            None
        }
    }
}

impl Drop for ReadOnly {
    fn drop(&mut self) {
        use std::os::unix::fs::PermissionsExt;
        if self.immutable {
            let _ = std::process::Command::new("chattr").arg("-i").arg(&self.dir).output();
        }
        let _ = std::fs::set_permissions(&self.dir, std::fs::Permissions::from_mode(0o755));
    }
}

/// The entries of `dir`, sorted.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}


/// A write to try, for [`failed_writes_keep_the_old_files`].
pub type WriteCase<'a> = Box<dyn Fn() -> Result<(), nbrdf::Error> + 'a>;

/// With `dir` made unwritable, each of `writes` fails with `Error::Io`, and afterwards every file of
/// `names` still holds `old` and no file was added. Says so and checks nothing where no folder can be
/// made unwritable here.
pub fn failed_writes_keep_the_old_files(dir: &Path, names: &[&str], old: &[u8], writes: &[(&str, WriteCase)]) {
    let before = listing(dir);
    let Some(guard) = ReadOnly::new(dir) else {
        eprintln!("skipping the read-only directory case: cannot make a directory unwritable here");
        return;
    };
    for (case, write) in writes {
        assert_err!(case, write(), nbrdf::Error::Io { .. });
    }
    drop(guard);
    for n in names {
        assert_eq!(std::fs::read(dir.join(n)).unwrap(), old, "{n} changed by a failed write");
    }
    assert_eq!(listing(dir), before, "a failed write left a file behind");
}
