//! The AVX2 level (x86-64 AVX2 with FMA): 8 lanes.

use core::arch::x86_64::*;

use crate::Lanes;

/// A vector of 8 f32 lanes.
pub struct Avx2;

// SAFETY: callers use these only where the CPU has AVX2 and FMA, inlined into code that enables them
// (the trait's contract).
unsafe impl Lanes for Avx2 {
    const N: usize = 8;
    type V = __m256;

    #[inline(always)]
    fn zero() -> __m256 {
        // SAFETY: the level is present (the trait's contract).
        unsafe { _mm256_setzero_ps() }
    }

    #[inline(always)]
    fn splat(x: f32) -> __m256 {
        // SAFETY: as `zero`.
        unsafe { _mm256_set1_ps(x) }
    }

    #[inline(always)]
    unsafe fn load(p: *const f32) -> __m256 {
        // SAFETY: the caller's contract (8 readable values), unaligned.
        unsafe { _mm256_loadu_ps(p) }
    }

    #[inline(always)]
    unsafe fn store(p: *mut f32, v: __m256) {
        // SAFETY: the caller's contract (8 writable values), unaligned.
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
        // `max(v, 0)` returns its second operand where `v` is NaN or either zero: +0.
        // SAFETY: as `zero`.
        unsafe { _mm256_max_ps(v, _mm256_setzero_ps()) }
    }

    #[inline(always)]
    fn keep_positive(m: __m256, v: __m256) -> __m256 {
        // Ordered compare: NaN is not > 0.
        // SAFETY: as `zero`.
        unsafe { _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(m, _mm256_setzero_ps()), v) }
    }
}
