//! The aarch64 Advanced SIMD (NEON) level: 4 lanes with fused multiply-add, the algorithm of
//! `lanes.rs`. NEON is part of the aarch64 base architecture, so these need no run-time check.

use core::arch::aarch64::*;

use super::lanes::{self, Lanes};
use super::{Dense, Weight};

/// A vector of 4 f32 lanes.
pub(super) struct Neon;

// SAFETY: NEON is in every aarch64 CPU (and enabled on every Rust aarch64 target); the dispatch
// hands out this level only where `detect` found the `neon` target feature.
unsafe impl Lanes for Neon {
    const N: usize = 4;
    type V = float32x4_t;

    #[inline(always)]
    fn splat(x: f32) -> float32x4_t {
        // SAFETY: NEON is present (see the impl's SAFETY).
        unsafe { vdupq_n_f32(x) }
    }

    #[inline(always)]
    unsafe fn load(p: *const f32) -> float32x4_t {
        // SAFETY: the caller's contract (4 readable values).
        unsafe { vld1q_f32(p) }
    }

    #[inline(always)]
    unsafe fn store(p: *mut f32, v: float32x4_t) {
        // SAFETY: the caller's contract (4 writable values).
        unsafe { vst1q_f32(p, v) }
    }

    #[inline(always)]
    fn mul_add(a: float32x4_t, b: float32x4_t, c: float32x4_t) -> float32x4_t {
        // SAFETY: NEON is present. `vfmaq_f32(c, a, b)` = c + a·b, rounded once.
        unsafe { vfmaq_f32(c, a, b) }
    }

    #[inline(always)]
    fn relu(v: float32x4_t) -> float32x4_t {
        // A select on `v > 0`, not `vmaxq_f32` (which returns NaN for NaN): +0 for zeros and NaN.
        // SAFETY: NEON is present.
        unsafe {
            let zero = vdupq_n_f32(0.0);
            vbslq_f32(vcgtq_f32(v, zero), v, zero)
        }
    }
}

/// [`lanes::one`] over [`Neon`].
///
/// # Safety
/// As [`lanes::one`].
pub(super) unsafe fn one<W: Weight>(layer: &Dense<'_, W>, out: *mut f32) {
    // SAFETY: forwarded; NEON is present at this level.
    unsafe { lanes::one::<Neon, W>(layer, out) }
}

/// [`lanes::packet`] over [`Neon`].
///
/// # Safety
/// As [`lanes::packet`].
pub(super) unsafe fn packet<W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
    // SAFETY: forwarded; NEON is present at this level.
    unsafe { lanes::packet::<Neon, W>(layer, out, out_stride) }
}
