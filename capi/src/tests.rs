//! The exported functions called as a careless C caller would, from Rust, so that Miri (`.ci/run`)
//! checks the boundary itself for undefined behaviour, not only the C program's view of it.

use std::ptr::{null, null_mut, without_provenance_mut};

use crate::*;

fn handle_of(make: impl FnOnce(*mut *mut NbrdfBrdf) -> NbrdfStatus) -> *mut NbrdfBrdf {
    let mut h = null_mut();
    assert_eq!(make(&mut h), NbrdfStatus::Ok);
    h
}

#[test]
fn an_undeclared_enum_value_is_an_error_and_out_stays_untouched() {
    let p = [0.5f32; 12];
    for kind in [-1, 5, 99, i32::MAX] {
        let mut out = null_mut();
        // SAFETY: valid pointers; the kind is what is under test.
        assert_eq!(unsafe { nbrdf_parametric(kind, p.as_ptr(), 3, &mut out) }, NbrdfStatus::InvalidValue);
        // SAFETY: as above.
        assert_eq!(unsafe { nbrdf_parametric_from_raw(kind, p.as_ptr(), 3, null(), 0, &mut out) }, NbrdfStatus::InvalidValue);
        assert!(out.is_null());
    }
    // SAFETY: valid arguments: the declared value works.
    let h = handle_of(|out| unsafe { nbrdf_parametric(0, p.as_ptr(), 3, out) });
    // SAFETY: a handle made above.
    unsafe { nbrdf_free(h) };
}

#[test]
fn impossible_lengths_are_refused_before_memory_is_read() {
    // SAFETY: valid arguments.
    let h = handle_of(|out| unsafe { nbrdf_builtin(c"velvet".as_ptr(), out) });
    let a = [[0.5f32; 4]; 6];
    let mut r = [[7.0f32; 4]; 3];
    let bytes = [0u32; 16];
    for n in [usize::MAX, usize::MAX / 4, 1 << 62, isize::MAX as usize / 4 + 1] {
        let wi = NbrdfDirections { x: a[0].as_ptr(), y: a[1].as_ptr(), z: a[2].as_ptr() };
        let wo = NbrdfDirections { x: a[3].as_ptr(), y: a[4].as_ptr(), z: a[5].as_ptr() };
        let out = NbrdfRgbArrays { r: r[0].as_mut_ptr(), g: r[1].as_mut_ptr(), b: r[2].as_mut_ptr() };
        // SAFETY: the length is what is under test; it must be refused unread.
        assert_eq!(unsafe { nbrdf_eval_many(h, null(), n, wi, wo, out) }, NbrdfStatus::BufferSize);
        let mut made = null_mut();
        let b = bytes.as_ptr().cast::<u8>();
        // SAFETY: as above.
        unsafe {
            assert_eq!(nbrdf_model_from_bytes(b, n, &mut made), NbrdfStatus::BufferSize);
            assert_eq!(nbrdf_model_borrow(b, n, &mut made), NbrdfStatus::BufferSize);
            assert_eq!(nbrdf_merl_from_bytes(b, n, &mut made), NbrdfStatus::BufferSize);
            assert_eq!(nbrdf_nbrdf_json_from_bytes(b, n, &mut made), NbrdfStatus::BufferSize);
        }
        assert!(made.is_null());
    }
    // An output array whose range wraps the address space.
    let wi = NbrdfDirections { x: a[0].as_ptr(), y: a[1].as_ptr(), z: a[2].as_ptr() };
    let top = without_provenance_mut::<f32>((usize::MAX & !3) - 4);
    let out = NbrdfRgbArrays { r: r[0].as_mut_ptr(), g: r[1].as_mut_ptr(), b: top };
    // SAFETY: the wrapping range is what is under test; it must be refused unread.
    assert_eq!(unsafe { nbrdf_eval_many(h, null(), 4, wi, wi, out) }, NbrdfStatus::BufferSize);
    assert_eq!(r, [[7.0; 4]; 3], "a refused call writes nothing");
    // The same call with a real output works (not under Miri: libm's square root is inline assembly).
    if !cfg!(miri) {
        let out = NbrdfRgbArrays { r: r[0].as_mut_ptr(), g: r[1].as_mut_ptr(), b: r[2].as_mut_ptr() };
        let wo = NbrdfDirections { x: a[3].as_ptr(), y: a[4].as_ptr(), z: a[5].as_ptr() };
        // SAFETY: valid arrays of 4.
        assert_eq!(unsafe { nbrdf_eval_many(h, null(), 4, wi, wo, out) }, NbrdfStatus::Ok);
        assert!(r.iter().flatten().all(|v| v.is_finite() && *v >= 0.0 && *v != 7.0));
    }
    // SAFETY: a handle made above.
    unsafe { nbrdf_free(h) };
}
