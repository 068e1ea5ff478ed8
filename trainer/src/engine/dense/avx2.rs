//! The AVX2 level of the dense products: 8 lanes, tiles of 6 × 2 vectors (12 of the 16
//! registers) and a narrow tile of 12 rows.

use core::arch::x86_64::*;

use super::kernel::{self, Lanes};
use super::{Epilogue, Mat};

pub(super) struct Avx2;

// SAFETY: the entry points below enable AVX2 and FMA, and are only called where the CPU has them.
unsafe impl Lanes for Avx2 {
    const N: usize = 8;
    const MR: usize = 6;
    const NV: usize = 2;
    type V = __m256;

    #[inline(always)]
    fn zero() -> __m256 {
        // SAFETY: inlined into the level's entry points (the trait's contract).
        unsafe { _mm256_setzero_ps() }
    }
    #[inline(always)]
    fn splat(x: f32) -> __m256 {
        // SAFETY: as `zero`.
        unsafe { _mm256_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> __m256 {
        // SAFETY: the caller's contract.
        unsafe { _mm256_loadu_ps(p) }
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: __m256) {
        // SAFETY: the caller's contract.
        unsafe { _mm256_storeu_ps(p, v) }
    }
    #[inline(always)]
    fn mul_add(a: __m256, b: __m256, c: __m256) -> __m256 {
        // SAFETY: as `zero`.
        unsafe { _mm256_fmadd_ps(a, b, c) }
    }
    #[inline(always)]
    fn add(a: __m256, b: __m256) -> __m256 {
        // SAFETY: as `zero`.
        unsafe { _mm256_add_ps(a, b) }
    }
    #[inline(always)]
    fn relu(v: __m256) -> __m256 {
        // SAFETY: as `zero`. `max` returns its second operand, 0, for NaN.
        unsafe { _mm256_max_ps(v, _mm256_setzero_ps()) }
    }
    #[inline(always)]
    fn keep_positive(m: __m256, v: __m256) -> __m256 {
        // SAFETY: as `zero`. Ordered compare: NaN is not > 0.
        unsafe { _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(m, _mm256_setzero_ps()), v) }
    }
}

/// Rows of the narrow tile.
const NARROW: usize = 12;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`; the CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Avx2, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`; the CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Avx2, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
///
/// # Safety
/// The CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Avx2>(iters)
}
