//! Bad input for the trainer's files (the table is `docs/bad-input.md`): the intrinsic-encoding
//! cache's malformed variants that `tests/intrinsic.rs` does not already assert (it covers a flipped
//! bit, a cut file and a 5-byte file), each with the reason it gets, and a failed save that leaves the
//! existing cache file intact.

use std::path::Path;

use trainer::intrinsic::{Error, IntrinsicEncoding};

/// A tetrahedron: the smallest closed mesh (4 vertices, so k ≤ 3).
fn tetrahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let p = vec![[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];
    (p, vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
}

fn crc_fix(b: &mut [u8]) {
    let n = b.len() - 4;
    let crc = crc32fast::hash(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
}

/// Loads `bytes` as a cache file and returns the reason it is corrupt.
fn reason(dir: &Path, bytes: &[u8]) -> String {
    let path = dir.join("case.bin");
    std::fs::write(&path, bytes).unwrap();
    match IntrinsicEncoding::load(&path) {
        Err(Error::CorruptCache { path: p, reason }) => {
            assert_eq!(p, path, "the error names the file");
            reason
        }
        other => panic!("expected CorruptCache, got {other:?}"),
    }
}

#[test]
fn cache_files_malformed_in_every_field() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, triangles) = tetrahedron();
    let enc = IntrinsicEncoding::compute(&positions, &triangles, 2).unwrap();
    let path = dir.path().join("good.bin");
    enc.save(&path).unwrap();
    let good = std::fs::read(&path).unwrap();
    assert_eq!(IntrinsicEncoding::load(&path).unwrap(), enc);

    let edit = |at: usize, bytes: &[u8], fix: bool| {
        let mut b = good.clone();
        b[at..at + bytes.len()].copy_from_slice(bytes);
        if fix {
            crc_fix(&mut b);
        }
        b
    };
    assert!(reason(dir.path(), &edit(0, b"NBRDFMDL", true)).contains("bad magic"));
    assert!(reason(dir.path(), &edit(8, &2u32.to_le_bytes(), true)).contains("format version 2"));
    assert!(reason(dir.path(), &edit(8, &0u32.to_le_bytes(), true)).contains("format version 0"));
    assert!(reason(dir.path(), &edit(40, &[0xff], false)).contains("checksum mismatch"));
    // Sizes that disagree with the length (checksum correct), and sizes whose product overflows.
    assert!(reason(dir.path(), &edit(24, &5u32.to_le_bytes(), true)).contains("need"));
    assert!(reason(dir.path(), &edit(28, &3u32.to_le_bytes(), true)).contains("need"));
    let huge = edit(24, &[0xff; 8], true);
    let r = reason(dir.path(), &huge);
    assert!(r.contains("need") || r.contains("overflow"), "{r}");
    // NaN eigenvalue and inf value with a correct checksum.
    assert!(reason(dir.path(), &edit(32, &f64::NAN.to_le_bytes(), true)).contains("non-finite"));
    let values_at = 32 + 8 * 2;
    assert!(reason(dir.path(), &edit(values_at + 4, &f32::INFINITY.to_le_bytes(), true)).contains("non-finite"));
    // Every prefix is corrupt, never a panic.
    for cut in 0..good.len() {
        reason(dir.path(), &good[..cut]);
    }
    // Trailing bytes.
    let mut long = good.clone();
    long.extend_from_slice(&[0; 8]);
    crc_fix(&mut long);
    assert!(reason(dir.path(), &long).contains("need"));

    // Missing file: an I/O error naming it.
    let missing = dir.path().join("missing.bin");
    assert!(matches!(IntrinsicEncoding::load(&missing), Err(Error::Io { path, .. }) if path == missing));
}

#[test]
fn a_cache_of_another_mesh_is_refused_not_reused() {
    // A file under the right name that holds another mesh's encoding (a copied cache directory, a hash
    // collision): the key check refuses it.
    let dir = tempfile::tempdir().unwrap();
    let (positions, triangles) = tetrahedron();
    let first = IntrinsicEncoding::load_or_compute(dir.path(), &positions, &triangles, 2).unwrap();
    let file = std::fs::read_dir(dir.path()).unwrap().next().unwrap().unwrap().path();
    let mut moved = positions.clone();
    moved[0][0] = 1.5;
    let other = IntrinsicEncoding::compute(&moved, &triangles, 2).unwrap();
    other.save(&file).unwrap();
    assert!(matches!(
        IntrinsicEncoding::load_or_compute(dir.path(), &positions, &triangles, 2),
        Err(Error::CorruptCache { reason, .. }) if reason.contains("expected")
    ));
    first.save(&file).unwrap();
    assert_eq!(IntrinsicEncoding::load_or_compute(dir.path(), &positions, &triangles, 2).unwrap(), first);
}

#[test]
fn a_failed_save_leaves_the_existing_cache_intact() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, triangles) = tetrahedron();
    let enc = IntrinsicEncoding::compute(&positions, &triangles, 3).unwrap();
    // The destination is a non-empty directory: the final rename fails, the temporary file goes.
    let taken = dir.path().join("taken");
    std::fs::create_dir(&taken).unwrap();
    std::fs::write(taken.join("x"), b"x").unwrap();
    assert!(matches!(enc.save(&taken), Err(Error::Io { .. })));
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, vec![std::ffi::OsString::from("taken")], "a temporary file was left behind");

    // A read-only directory (mode 0555; root ignores it, then the immutable attribute): the old file
    // stays byte for byte.
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    let file = ro.join("cache.bin");
    std::fs::write(&file, b"old").unwrap();
    {
        let guard = ReadOnly::new(&ro);
        if guard.effective {
            assert!(matches!(enc.save(&file), Err(Error::Io { .. })));
            assert_eq!(std::fs::read(&file).unwrap(), b"old");
        } else {
            eprintln!("skipping the read-only case: cannot make a directory unwritable here");
        }
    }
    assert_eq!(std::fs::read_dir(&ro).unwrap().count(), 1, "a temporary file was left behind");
}

/// Makes a directory unwritable until dropped (also when a test fails, so the temporary directory can
/// still be removed): mode 0555, or for root the immutable attribute.
struct ReadOnly {
    dir: std::path::PathBuf,
    immutable: bool,
    effective: bool,
}

impl ReadOnly {
    fn new(dir: &Path) -> Self {
        use std::os::unix::fs::PermissionsExt;
        let writable = || std::fs::File::create(dir.join(".probe")).map(|_| std::fs::remove_file(dir.join(".probe"))).is_ok();
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o555)).unwrap();
        let mut guard = ReadOnly { dir: dir.to_path_buf(), immutable: false, effective: !writable() };
        if !guard.effective {
            guard.immutable =
                std::process::Command::new("chattr").arg("+i").arg(dir).output().is_ok_and(|o| o.status.success());
            guard.effective = !writable();
        }
        guard
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
