//! The on-disk cache of one mesh's encoding, so that the eigen solve runs once per mesh and k.
//!
//! Format (all little-endian), version 1:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `NBRDFLBE` |
//! | 8 | 4 | version `u32` |
//! | 12 | 4 | flags `u32`, 0 (reserved) |
//! | 16 | 8 | key `u64`: [`cache_key`] of the mesh and k |
//! | 24 | 4 | n_vertices `u32` |
//! | 28 | 4 | k `u32` |
//! | 32 | 8k | eigenvalues `f64`, ascending, the per-component constants (zeros) dropped |
//! | 32 + 8k | 4nk | per-vertex values `f32`, row-major `[n_vertices × k]` |
//! | end − 4 | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! The file is written to a temporary name in the same directory and renamed into place, so a reader
//! sees either no file or a complete one, even when several trainers start on the same mesh at once.

use std::hash::Hasher;
use std::path::Path;

use super::{Error, IntrinsicEncoding};

/// First bytes of a cache file.
pub const MAGIC: [u8; 8] = *b"NBRDFLBE";
/// Format version written and read.
pub const VERSION: u32 = 1;
/// Bumped whenever a change to assembly or solver changes the numbers, so old caches are not reused.
pub const SOLVER_VERSION: u32 = 2;
const HEADER_LEN: usize = 32;

/// Key of a mesh and k: 64-bit FNV-1a over the solver version, the exact bits of the positions, the
/// triangles and k. Any change of the mesh (even a last-bit change of one coordinate) gives a new key.
/// FNV is not cryptographic; it guards against mix-ups, not against an adversary.
pub fn cache_key(positions: &[[f32; 3]], triangles: &[[u32; 3]], k: usize) -> u64 {
    let mut h = fnv::FnvHasher::default();
    h.write(b"nbrdf-intrinsic");
    h.write(&SOLVER_VERSION.to_le_bytes());
    h.write(&(positions.len() as u64).to_le_bytes());
    for p in positions {
        for c in p {
            h.write(&c.to_bits().to_le_bytes());
        }
    }
    h.write(&(triangles.len() as u64).to_le_bytes());
    for t in triangles {
        for v in t {
            h.write(&v.to_le_bytes());
        }
    }
    h.write(&(k as u64).to_le_bytes());
    h.finish()
}

/// File name of the cache entry of `key` inside a cache directory.
pub fn cache_file_name(key: u64) -> String {
    format!("intrinsic-{key:016x}.lbe")
}

pub(crate) fn encode(enc: &IntrinsicEncoding) -> Vec<u8> {
    let (n, k) = (enc.n_vertices(), enc.k());
    let mut out = Vec::with_capacity(HEADER_LEN + 8 * k + 4 * n * k + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&enc.key().to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&(k as u32).to_le_bytes());
    for v in enc.eigenvalues() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in enc.values() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Parses a cache file; the `Err` is the reason it is unusable.
pub(crate) fn decode(bytes: &[u8]) -> Result<IntrinsicEncoding, String> {
    if bytes.len() < HEADER_LEN + 4 {
        return Err(format!(
            "{} bytes, shorter than the {}-byte header and checksum",
            bytes.len(),
            HEADER_LEN + 4
        ));
    }
    if bytes[..8] != MAGIC {
        return Err("bad magic: not an nbrdf eigenfunction cache".into());
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let version = u32_at(8);
    if version != VERSION {
        return Err(format!("format version {version}, this build reads {VERSION}"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    let computed = crc32fast::hash(body);
    if stored != computed {
        return Err(format!(
            "checksum mismatch: stored {stored:08x}, computed {computed:08x}"
        ));
    }
    let key = u64::from_le_bytes(bytes[16..24].try_into().expect("8 bytes"));
    let n = u32_at(24) as usize;
    let k = u32_at(28) as usize;
    let expected = n
        .checked_mul(k)
        .and_then(|nk| nk.checked_mul(4))
        .and_then(|v| v.checked_add(8 * k + HEADER_LEN + 4))
        .ok_or_else(|| format!("sizes n = {n}, k = {k} overflow"))?;
    if bytes.len() != expected {
        return Err(format!(
            "{} bytes, but n = {n} and k = {k} need {expected}",
            bytes.len()
        ));
    }
    let mut offset = HEADER_LEN;
    let eigenvalues: Vec<f64> = (0..k)
        .map(|i| f64::from_le_bytes(bytes[offset + 8 * i..offset + 8 * i + 8].try_into().expect("8 bytes")))
        .collect();
    offset += 8 * k;
    let values: Vec<f32> = bytes[offset..offset + 4 * n * k]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    if eigenvalues.iter().any(|v| !v.is_finite()) || values.iter().any(|v| !v.is_finite()) {
        return Err("non-finite eigenvalue or value".into());
    }
    Ok(IntrinsicEncoding::from_parts(key, n, k, eigenvalues, values))
}

/// Reads a cache file; any problem with its content is [`Error::CorruptCache`].
pub(crate) fn read(path: &Path) -> Result<IntrinsicEncoding, Error> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    decode(&bytes).map_err(|reason| Error::CorruptCache {
        path: path.to_owned(),
        reason,
    })
}

/// Writes `bytes` to `path` atomically (`nbrdf::io::write_atomic`), creating the cache directory first.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|source| Error::Io { path: dir.to_owned(), source })?;
    nbrdf::io::write_atomic(path, bytes).map_err(|e| match e {
        nbrdf::Error::Io { path, kind, message } => Error::Io { path, source: std::io::Error::new(kind, message) },
        other => Error::Io { path: path.to_owned(), source: std::io::Error::other(other.to_string()) },
    })
}
