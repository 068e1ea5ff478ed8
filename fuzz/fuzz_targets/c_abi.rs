//! The C ABI (`capi/`, `libnbrdf`) driven as a careless C caller would: arbitrary integers for enums,
//! arbitrary lengths and counts, arbitrary bytes as model, MERL and NBRDF-json files, pointers whose
//! range wraps the address space. Whatever comes in, every call returns a status (never a panic
//! status, never a crash), a length no buffer can have is `BufferSize`, and a failed call leaves its
//! outputs untouched. Lengths within what the buffers really hold are the caller's promise the ABI
//! cannot check, so the target only passes those or ones no process can have.
#![no_main]

// The C ABI's crate builds only libnbrdf.a / .so (a library named like the core, which no Rust crate
// can depend on), so its modules are compiled into this target as they stand, under the crate paths
// they use (`crate::args`, ..., `nbrdf_core`).
extern crate nbrdf as nbrdf_core;
#[path = "../../capi/src/args.rs"]
mod args;
#[path = "../../capi/src/error.rs"]
mod error;
#[allow(dead_code)] // the enum is the header's documentation only
#[path = "../../capi/src/handle.rs"]
mod handle;
#[path = "../../capi/src/shade.rs"]
mod shade;
mod common;

use error::{nbrdf_last_error, NbrdfStatus};
use handle::*;
use shade::*;

use std::ffi::c_void;
use std::ptr::{null, null_mut};

use libfuzzer_sys::fuzz_target;

/// Reads the fuzzer's bytes as the call's arguments (zeros once they run out).
struct Input<'a>(&'a [u8]);

impl Input<'_> {
    fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(std::array::from_fn(|_| self.u8()))
    }
    fn i32(&mut self) -> i32 {
        self.u64() as i32
    }
    fn f32(&mut self) -> f32 {
        f32::from_bits(self.u64() as u32)
    }
    /// A length for a buffer of `real` values of `size` bytes: one it holds, or (when the fuzzer
    /// says so) one no buffer can have — past `isize::MAX` bytes, or past `cap` values.
    fn len(&mut self, real: usize, size: usize, cap: u64) -> (usize, bool) {
        if self.u8() & 1 == 0 {
            return ((self.u64() % (real as u64 + 1)) as usize, false);
        }
        let beyond_isize = isize::MAX as u64 / size as u64 + 1;
        let floor = beyond_isize.min(cap.saturating_add(1));
        let pick = [u64::MAX, u64::MAX / 4, 1 << 62, isize::MAX as u64 / 4 + 1, floor + self.u64() % (u64::MAX - floor)];
        let n = pick[self.u8() as usize % pick.len()].max(floor);
        (n as usize, true)
    }
}

/// The call's status is a real answer: no panic reached the boundary, and an impossible length was
/// refused as one.
fn check(status: NbrdfStatus, impossible: bool, what: &str) {
    assert_ne!(status, NbrdfStatus::Panic, "{what}: {}", last_error());
    if impossible {
        assert_ne!(status, NbrdfStatus::Ok, "{what}: an impossible length was accepted");
    }
}

fn last_error() -> String {
    // SAFETY: a NUL-terminated string owned by this thread's error slot.
    unsafe { std::ffi::CStr::from_ptr(nbrdf_last_error()) }.to_string_lossy().into_owned()
}

/// A handle made by `make`, checked: untouched `*out` on failure, freed on success.
fn made(what: &str, impossible: bool, make: impl FnOnce(*mut *mut NbrdfBrdf) -> NbrdfStatus) {
    let mut out: *mut NbrdfBrdf = null_mut();
    let status = make(&mut out);
    check(status, impossible, what);
    if status == NbrdfStatus::Ok {
        assert!(!out.is_null(), "{what}: OK without a handle");
        // SAFETY: a handle this library made.
        unsafe { nbrdf_free(out) };
    } else {
        assert!(out.is_null(), "{what}: failed ({status:?}) but wrote *out");
    }
}

/// A valid handle to shade with: a built-in, a parametric model or a small model file.
fn some_handle(input: &mut Input) -> *mut NbrdfBrdf {
    let mut out = null_mut();
    let choice = input.u8();
    // SAFETY: valid arguments throughout.
    let status = unsafe {
        match choice % 3 {
            0 => nbrdf_builtin(c"velvet".as_ptr(), &mut out),
            1 => nbrdf_parametric(2, [0.3f32, 0.2, 0.1, 0.5, 0.5, 0.5, 0.3].as_ptr(), 7, &mut out),
            _ => {
                let file = common::small_file(choice as usize / 3, input.u8());
                nbrdf_model_from_bytes(file.as_ptr(), file.len(), &mut out)
            }
        }
    };
    assert_eq!(status, NbrdfStatus::Ok, "{}", last_error());
    out
}

fuzz_target!(|data: &[u8]| {
    let mut input = Input(data);
    let floats: Vec<f32> = (0..16).map(|_| input.f32()).collect();
    match input.u8() % 8 {
        0 => {
            let kind = input.i32();
            let (n, impossible) = input.len(floats.len(), 4, u64::MAX);
            // SAFETY: n floats are readable unless n is impossible, which must be refused unread.
            made("nbrdf_parametric", impossible, |out| unsafe { nbrdf_parametric(kind, floats.as_ptr(), n, out) });
        }
        1 => {
            let kind = input.i32();
            let (n_raw, a) = input.len(12, 4, u64::MAX);
            let (n_object, b) = input.len(4, 4, u64::MAX);
            // SAFETY: as above, for both arrays.
            made("nbrdf_parametric_from_raw", a || b, |out| unsafe {
                nbrdf_parametric_from_raw(kind, floats.as_ptr(), n_raw, floats[12..].as_ptr(), n_object, out)
            });
        }
        2 | 3 | 4 => {
            let which = input.u8() % 4;
            let cap = [1 << 40, 34_992_012, 64 << 20, 1 << 40][which as usize];
            // The length's choices come first, the file's bytes are the rest.
            let mut choice = Input(input.0.get(..18).unwrap_or(input.0));
            let body = input.0.get(18..).unwrap_or(&[]);
            let (len, impossible) = choice.len(body.len(), 1, cap);
            // Borrowed bytes must be 4-byte aligned and outlive the handle.
            let words: Vec<u32> = body.chunks(4).map(|c| u32::from_le_bytes(std::array::from_fn(|i| *c.get(i).unwrap_or(&0)))).collect();
            let ptr = if body.is_empty() { null() } else { words.as_ptr().cast::<u8>() };
            // SAFETY: len bytes are readable unless len is impossible, which must be refused unread.
            match which {
                0 => made("nbrdf_model_from_bytes", impossible, |out| unsafe { nbrdf_model_from_bytes(ptr, len, out) }),
                1 => made("nbrdf_merl_from_bytes", impossible, |out| unsafe { nbrdf_merl_from_bytes(ptr, len, out) }),
                2 => made("nbrdf_nbrdf_json_from_bytes", impossible, |out| unsafe { nbrdf_nbrdf_json_from_bytes(ptr, len, out) }),
                _ => made("nbrdf_model_borrow", impossible, |out| unsafe { nbrdf_model_borrow(ptr, len, out) }),
            }
        }
        5 => {
            let h = some_handle(&mut input);
            let mut a = vec![0.5f32; 6 * 8];
            for (i, f) in floats.iter().enumerate() {
                a[i] = *f;
            }
            let mut r = [[7.0f32; 8]; 3];
            let (n, mut impossible) = input.len(8, 4, u64::MAX);
            let mut outs = [r[0].as_mut_ptr(), r[1].as_mut_ptr(), r[2].as_mut_ptr()];
            // A range that wraps the address space: a pointer near the top (never dereferenced).
            if input.u8() & 1 == 1 && n > 0 && n < 1 << 20 {
                outs[2] = ((usize::MAX & !3) - 4 * n + 4 + 4 * (input.u8() as usize % n.min(8))) as *mut f32;
                impossible = true;
            }
            let p = |k: usize| a[8 * k..].as_ptr();
            let wi = NbrdfDirections { x: p(0), y: p(1), z: p(2) };
            let wo = NbrdfDirections { x: p(3), y: p(4), z: p(5) };
            let out = NbrdfRgbArrays { r: outs[0], g: outs[1], b: outs[2] };
            // SAFETY: n floats at each array unless the length or a range is impossible.
            let status = unsafe { nbrdf_eval_many(h, null::<c_void>(), n, wi, wo, out) };
            check(status, impossible, "nbrdf_eval_many");
            if status != NbrdfStatus::Ok {
                assert!(r.iter().flatten().all(|v| *v == 7.0), "nbrdf_eval_many failed but wrote");
            } else {
                assert!(r.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
            }
            // SAFETY: a handle this library made.
            unsafe { nbrdf_free(h) };
        }
        _ => {
            let h = some_handle(&mut input);
            let (n, impossible) = input.len(floats.len(), 4, u64::MAX);
            let mut storage = vec![0u128; NBRDF_POINT_MAX_SIZE / 16];
            // SAFETY: n floats unless impossible; storage of the maximum size, 16-byte aligned.
            let status = unsafe { nbrdf_prepare(h, floats.as_ptr(), n, storage.as_mut_ptr().cast(), NBRDF_POINT_MAX_SIZE) };
            check(status, impossible, "nbrdf_prepare");
            let tri = [input.u64() as u32 % 4, input.u8() as u32 % 4, input.u8() as u32];
            let bary = [floats[0], floats[1], floats[2]];
            let mut features = [9.0f32; 16];
            let (m, impossible) = input.len(features.len(), 4, u64::MAX);
            // SAFETY: m writable floats unless impossible.
            let status = unsafe { nbrdf_position_features(h, tri.as_ptr(), bary.as_ptr(), features.as_mut_ptr(), m) };
            check(status, impossible, "nbrdf_position_features");
            if status != NbrdfStatus::Ok {
                assert!(features.iter().all(|v| *v == 9.0), "nbrdf_position_features failed but wrote");
            }
            // SAFETY: a handle this library made.
            unsafe { nbrdf_free(h) };
        }
    }
});
