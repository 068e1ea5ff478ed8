//! The portable level of the dense products: plain Rust on 4 lanes as an array (one SSE2 or NEON register), which the compiler
//! vectorises for the compile-time target; multiply, then add (`mul_add` is not in `core`, and its
//! software fallback is slow). Tiles of 4 × 2 vectors (8 of the 16 SSE2 registers) and a narrow tile of 8 rows.

use super::kernel::{self, Lanes};
use super::{Epilogue, Mat};

pub(super) struct Portable;

// SAFETY: plain Rust, no instruction beyond the compile-time target's.
unsafe impl Lanes for Portable {
    const N: usize = 4;
    const MR: usize = 4;
    const NV: usize = 2;
    type V = [f32; 4];

    #[inline(always)]
    fn zero() -> [f32; 4] {
        [0.0; 4]
    }
    #[inline(always)]
    fn splat(x: f32) -> [f32; 4] {
        [x; 4]
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> [f32; 4] {
        // SAFETY: the caller's contract.
        unsafe { p.cast::<[f32; 4]>().read_unaligned() }
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: [f32; 4]) {
        // SAFETY: the caller's contract.
        unsafe { p.cast::<[f32; 4]>().write_unaligned(v) }
    }
    #[inline(always)]
    fn mul_add(a: [f32; 4], b: [f32; 4], c: [f32; 4]) -> [f32; 4] {
        core::array::from_fn(|i| c[i] + a[i] * b[i])
    }
    #[inline(always)]
    fn add(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
        core::array::from_fn(|i| a[i] + b[i])
    }
    #[inline(always)]
    fn relu(v: [f32; 4]) -> [f32; 4] {
        v.map(|x| if x > 0.0 { x } else { 0.0 })
    }
    #[inline(always)]
    fn keep_positive(m: [f32; 4], v: [f32; 4]) -> [f32; 4] {
        core::array::from_fn(|i| if m[i] > 0.0 { v[i] } else { 0.0 })
    }
}

/// Rows of the narrow tile.
const NARROW: usize = 8;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`.
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Portable, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`.
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Portable, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
pub(super) fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Portable>(iters)
}
