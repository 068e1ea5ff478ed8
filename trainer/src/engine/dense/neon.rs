//! The NEON level of the dense products (aarch64, where NEON is part of every CPU): 4 lanes, tiles
//! of 6 × 4 vectors (24 of the 32 registers) and a narrow tile of 24 rows.

use core::arch::aarch64::*;

use super::kernel::{self, Lanes};
use super::{Epilogue, Mat};

pub(super) struct Neon;

// SAFETY: NEON is a baseline feature of every aarch64 target.
unsafe impl Lanes for Neon {
    const N: usize = 4;
    const MR: usize = 6;
    const NV: usize = 4;
    type V = float32x4_t;

    #[inline(always)]
    fn zero() -> float32x4_t {
        // SAFETY: NEON is present (the trait's contract).
        unsafe { vdupq_n_f32(0.0) }
    }
    #[inline(always)]
    fn splat(x: f32) -> float32x4_t {
        // SAFETY: as `zero`.
        unsafe { vdupq_n_f32(x) }
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> float32x4_t {
        // SAFETY: the caller's contract.
        unsafe { vld1q_f32(p) }
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: float32x4_t) {
        // SAFETY: the caller's contract.
        unsafe { vst1q_f32(p, v) }
    }
    #[inline(always)]
    fn mul_add(a: float32x4_t, b: float32x4_t, c: float32x4_t) -> float32x4_t {
        // SAFETY: as `zero`.
        unsafe { vfmaq_f32(c, a, b) }
    }
    #[inline(always)]
    fn add(a: float32x4_t, b: float32x4_t) -> float32x4_t {
        // SAFETY: as `zero`.
        unsafe { vaddq_f32(a, b) }
    }
    #[inline(always)]
    fn relu(v: float32x4_t) -> float32x4_t {
        // SAFETY: as `zero`. `maxnm` returns the number, 0, for NaN (`max` would return the NaN).
        unsafe { vmaxnmq_f32(v, vdupq_n_f32(0.0)) }
    }
    #[inline(always)]
    fn keep_positive(m: float32x4_t, v: float32x4_t) -> float32x4_t {
        // SAFETY: as `zero`. The compare is false for NaN.
        unsafe { vreinterpretq_f32_u32(vandq_u32(vcgtq_f32(m, vdupq_n_f32(0.0)), vreinterpretq_u32_f32(v))) }
    }
}

/// Rows of the narrow tile.
const NARROW: usize = 24;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`.
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Neon, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`.
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Neon, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
pub(super) fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Neon>(iters)
}
