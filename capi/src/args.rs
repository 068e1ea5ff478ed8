//! What crosses the boundary, checked before Rust makes a value of it. C may put any integer in an
//! enum and any length beside a pointer, while a Rust enum with an undeclared value, or a slice of
//! more than `isize::MAX` bytes or one that wraps the address space, is undefined behaviour the
//! moment it exists. So enums arrive as their integer type and are matched here, and every length
//! is checked against `isize::MAX` bytes, the end of the address space and the largest input of its
//! kind before any slice is made.

use std::ffi::{c_char, CStr};
use std::mem::{align_of, size_of};
use std::path::PathBuf;

use nbrdf_core::parametric::ParametricKind;

use crate::error::{fail, NbrdfStatus, Result};

/// The parametric model a C `NbrdfParametricKind` names, or the failure naming the value.
pub(crate) fn parametric_kind(kind: i32) -> Result<ParametricKind> {
    // The header's order (`NbrdfParametricKind`); `ParametricKind::ALL` has the same.
    match usize::try_from(kind).ok().and_then(|k| ParametricKind::ALL.get(k)) {
        Some(&k) => Ok(k),
        None => fail(
            NbrdfStatus::InvalidValue,
            format!("kind {kind} is no NbrdfParametricKind (0 to {})", ParametricKind::ALL.len() - 1),
        ),
    }
}

/// Checks that `n` values of `T` from `ptr` are a range a slice can describe: at most `isize::MAX`
/// bytes, not wrapping past the end of the address space.
pub(crate) fn span<T>(ptr: *const T, n: usize, what: &str) -> Result<()> {
    let size = size_of::<T>().max(1);
    let max = isize::MAX as usize / size;
    if n > max {
        return fail(
            NbrdfStatus::BufferSize,
            format!("{what}: {n} values of {size} bytes are more than isize::MAX bytes (at most {max} values)"),
        );
    }
    // n * size <= isize::MAX here, so only the addition can overflow.
    if (ptr as usize).checked_add(n * size).is_none() {
        return fail(NbrdfStatus::BufferSize, format!("{what}: {n} values from {ptr:p} run past the end of the address space"));
    }
    Ok(())
}

/// Whether the ranges of `n` values of `T` from `a` and from `b` overlap; both passed [`span`], so
/// the ends do not wrap.
pub(crate) fn overlaps<T>(a: *const T, b: *const T, n: usize) -> bool {
    let len = n * size_of::<T>();
    let (a, b) = (a as usize, b as usize);
    a < b.saturating_add(len) && b < a.saturating_add(len)
}

/// A path from a C string: its bytes as they are on Unix, UTF-8 elsewhere.
pub(crate) fn path_of(path: *const c_char) -> Result<PathBuf> {
    if path.is_null() {
        return fail(NbrdfStatus::NullPointer, "path is null");
    }
    // SAFETY: non-null, and the caller passes a NUL-terminated string.
    let bytes = unsafe { CStr::from_ptr(path) }.to_bytes();
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Ok(PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
    }
    #[cfg(not(unix))]
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok(PathBuf::from(s)),
        Err(_) => fail(NbrdfStatus::InvalidValue, "path is not UTF-8"),
    }
}

/// `len` bytes at `bytes` (null allowed for 0), refused above `max`, the largest input of its kind.
///
/// # Safety
/// `bytes` addresses `len` readable bytes that outlive the returned slice.
pub(crate) unsafe fn bytes_of<'a>(bytes: *const u8, len: usize, max: u64, kind: &str) -> Result<&'a [u8]> {
    if len == 0 {
        return Ok(&[]);
    }
    if bytes.is_null() {
        return fail(NbrdfStatus::NullPointer, "bytes is null");
    }
    if len as u64 > max {
        return fail(NbrdfStatus::BufferSize, format!("len: {len} bytes are more than any {kind} has (at most {max})"));
    }
    span(bytes, len, "bytes")?;
    // SAFETY: the caller's contract; non-null, and a range a slice may describe (checked above).
    Ok(unsafe { std::slice::from_raw_parts(bytes, len) })
}

/// `len` floats at `values` (null allowed for 0).
///
/// # Safety
/// `values` addresses `len` readable floats that outlive the returned slice.
pub(crate) unsafe fn floats_of<'a>(values: *const f32, len: usize, what: &str) -> Result<&'a [f32]> {
    if len == 0 {
        return Ok(&[]);
    }
    if values.is_null() {
        return fail(NbrdfStatus::NullPointer, format!("{what} is null"));
    }
    if !(values as usize).is_multiple_of(align_of::<f32>()) {
        return fail(NbrdfStatus::Misaligned, format!("{what} is not 4-byte aligned"));
    }
    span(values, len, what)?;
    // SAFETY: the caller's contract; non-null, aligned and a range a slice may describe.
    Ok(unsafe { std::slice::from_raw_parts(values, len) })
}

/// Checks an output pointer of `n` floats: non-null, aligned, a range a slice may describe.
pub(crate) fn out_floats(out: *mut f32, n: usize, what: &str) -> Result<()> {
    if out.is_null() {
        return fail(NbrdfStatus::NullPointer, format!("{what} is null"));
    }
    if !(out as usize).is_multiple_of(align_of::<f32>()) {
        return fail(NbrdfStatus::Misaligned, format!("{what} is not 4-byte aligned"));
    }
    span(out.cast_const(), n, what)
}

/// `n` writable floats at `out`, checked as [`out_floats`] does.
///
/// # Safety
/// `out` addresses `n` writable floats that no other live slice covers and that outlive the slice.
pub(crate) unsafe fn floats_mut<'a>(out: *mut f32, n: usize, what: &str) -> Result<&'a mut [f32]> {
    out_floats(out, n, what)?;
    // SAFETY: the caller's contract; non-null, aligned and a range a slice may describe.
    Ok(unsafe { std::slice::from_raw_parts_mut(out, n) })
}

/// A count the caller passed that must equal `want` (checked before any slice of it is made).
pub(crate) fn exactly(n: usize, want: usize, what: impl FnOnce() -> String) -> Result<()> {
    if n == want {
        Ok(())
    } else {
        fail(NbrdfStatus::BufferSize, what())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status<T>(r: Result<T>) -> NbrdfStatus {
        match r {
            Ok(_) => NbrdfStatus::Ok,
            Err(f) => f.0,
        }
    }

    #[test]
    fn enum_values_c_can_pass_are_matched_not_assumed() {
        assert_eq!(status(parametric_kind(2)), NbrdfStatus::Ok);
        for k in [-1, 5, 99, i32::MAX, i32::MIN] {
            let Err(f) = parametric_kind(k) else { panic!("{k} is no kind") };
            assert_eq!(f.0, NbrdfStatus::InvalidValue);
            assert!(f.1.contains(&format!("kind {k}")), "{}", f.1);
        }
    }

    #[test]
    fn lengths_beyond_isize_or_the_address_space_are_refused_before_a_slice() {
        let x = [1.0f32; 4];
        let p = x.as_ptr();
        for n in [usize::MAX, usize::MAX / 4, 1 << 62, isize::MAX as usize / 4 + 1] {
            assert_eq!(status(span(p, n, "wi.x")), NbrdfStatus::BufferSize, "n = {n}");
            // SAFETY: refused before the slice is made.
            assert_eq!(status(unsafe { floats_of(p, n, "wi.x") }), NbrdfStatus::BufferSize, "n = {n}");
        }
        assert_eq!(status(span(p, 4, "wi.x")), NbrdfStatus::Ok);
        // A range that would wrap: a pointer near the top of the address space.
        let top = std::ptr::without_provenance::<f32>(usize::MAX - 7);
        let Err(f) = span(top, 4, "out.r") else { panic!("wraps") };
        assert!(f.1.contains("end of the address space"), "{}", f.1);
        let bytes = [0u8; 8];
        for len in [usize::MAX, usize::MAX / 4, 1 << 62, isize::MAX as usize / 4 + 1] {
            // SAFETY: refused before the slice is made.
            let r = unsafe { bytes_of(bytes.as_ptr(), len, 1 << 36, "model file") };
            assert_eq!(status(r), NbrdfStatus::BufferSize, "len = {len}");
        }
    }

    #[test]
    fn overlap_is_decided_without_wrapping() {
        let top = std::ptr::without_provenance::<f32>(usize::MAX - 15);
        assert!(overlaps(top, top, 4));
        assert!(!overlaps(top, std::ptr::without_provenance(16), 4));
        let x = [0.0f32; 8];
        assert!(overlaps(x.as_ptr(), x[3..].as_ptr(), 4));
        assert!(!overlaps(x.as_ptr(), x[4..].as_ptr(), 4));
    }
}
