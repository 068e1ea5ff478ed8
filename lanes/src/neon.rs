//! The aarch64 Advanced SIMD (NEON) level: 4 lanes with fused multiply-add. NEON is part of the
//! aarch64 base architecture (and enabled on every Rust aarch64 target).

use core::arch::aarch64::*;

use crate::Lanes;

/// A vector of 4 f32 lanes.
pub struct Neon;

// SAFETY: NEON is in every aarch64 CPU and enabled on every Rust aarch64 target.
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
        // `vfmaq_f32(c, a, b)` = c + a·b, rounded once.
        // SAFETY: NEON is present.
        unsafe { vfmaq_f32(c, a, b) }
    }

    #[inline(always)]
    fn add(a: float32x4_t, b: float32x4_t) -> float32x4_t {
        // SAFETY: NEON is present.
        unsafe { vaddq_f32(a, b) }
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

    #[inline(always)]
    fn keep_positive(m: float32x4_t, v: float32x4_t) -> float32x4_t {
        // The compare is false for NaN.
        // SAFETY: NEON is present.
        unsafe { vreinterpretq_f32_u32(vandq_u32(vcgtq_f32(m, vdupq_n_f32(0.0)), vreinterpretq_u32_f32(v))) }
    }
}
