//! The AVX-512 level of the dense products: 16 lanes, tiles of 6 × 4 vectors (24 of the 32
//! registers) and a narrow tile of 24 rows.

use core::arch::x86_64::*;

use super::kernel::{self, Lanes};
use super::{Epilogue, Mat};

pub(super) struct Avx512;

// SAFETY: the entry points below enable AVX-512F and FMA, and are only called where the CPU has them.
unsafe impl Lanes for Avx512 {
    const N: usize = 16;
    const MR: usize = 6;
    const NV: usize = 4;
    type V = __m512;

    #[inline(always)]
    fn zero() -> __m512 {
        // SAFETY: inlined into the level's entry points (the trait's contract).
        unsafe { _mm512_setzero_ps() }
    }
    #[inline(always)]
    fn splat(x: f32) -> __m512 {
        // SAFETY: as `zero`.
        unsafe { _mm512_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> __m512 {
        // SAFETY: the caller's contract.
        unsafe { _mm512_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: __m512) {
        // SAFETY: the caller's contract.
        unsafe { _mm512_storeu_ps(p, v) }
    }
    #[inline(always)]
    fn mul_add(a: __m512, b: __m512, c: __m512) -> __m512 {
        // SAFETY: as `zero`.
        unsafe { _mm512_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    fn add(a: __m512, b: __m512) -> __m512 {
        // SAFETY: as `zero`.
        unsafe { _mm512_add_ps(a, b) }
    }
    #[inline(always)]
    fn relu(v: __m512) -> __m512 {
        // SAFETY: as `zero`. `max` returns its second operand, 0, for NaN.
        unsafe { _mm512_max_ps(v, _mm512_setzero_ps()) }
    }
    #[inline(always)]
    fn keep_positive(m: __m512, v: __m512) -> __m512 {
        // SAFETY: as `zero`. Ordered compare: NaN is not > 0.
        unsafe { _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(m, _mm512_setzero_ps()), v) }
    }
}

/// Rows of the narrow tile.
const NARROW: usize = 24;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`; the CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Avx512, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`; the CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Avx512, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
///
/// # Safety
/// The CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Avx512>(iters)
}
