//! The AVX-512 level (x86-64 AVX-512 F with FMA): 16 lanes.

use core::arch::x86_64::*;

use crate::Lanes;

/// A vector of 16 f32 lanes.
pub struct Avx512;

// SAFETY: callers use these only where the CPU has AVX-512 F and FMA, inlined into code that enables
// them (the trait's contract).
unsafe impl Lanes for Avx512 {
    const N: usize = 16;
    type V = __m512;

    #[inline(always)]
    fn zero() -> __m512 {
        // SAFETY: the level is present (the trait's contract).
        unsafe { _mm512_setzero_ps() }
    }

    #[inline(always)]
    fn splat(x: f32) -> __m512 {
        // SAFETY: as `zero`.
        unsafe { _mm512_set1_ps(x) }
    }

    #[inline(always)]
    unsafe fn load(p: *const f32) -> __m512 {
        // SAFETY: the caller's contract (16 readable values), unaligned.
        unsafe { _mm512_loadu_ps(p) }
    }

    #[inline(always)]
    unsafe fn store(p: *mut f32, v: __m512) {
        // SAFETY: the caller's contract (16 writable values), unaligned.
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
        // `max(v, 0)` returns its second operand where `v` is NaN or either zero: +0.
        // SAFETY: as `zero`.
        unsafe { _mm512_max_ps(v, _mm512_setzero_ps()) }
    }

    #[inline(always)]
    fn keep_positive(m: __m512, v: __m512) -> __m512 {
        // Ordered compare: NaN is not > 0.
        // SAFETY: as `zero`.
        unsafe { _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(m, _mm512_setzero_ps()), v) }
    }
}
