//! The portable level: plain Rust on `N` lanes held in an array, which the compiler vectorises for
//! the compile-time target. Multiply, then add: `f32::mul_add` is not in `core`, and its software
//! fallback on targets without FMA is slow.

use crate::Lanes;

/// A vector of `N` f32 lanes in plain Rust (the core evaluates on 8, the trainer's tiles use 4:
/// one SSE2 or NEON register).
pub struct Scalar<const N: usize>;

// SAFETY: plain Rust, no instruction beyond the compile-time target's.
unsafe impl<const N: usize> Lanes for Scalar<N> {
    const N: usize = N;
    type V = [f32; N];

    #[inline(always)]
    fn splat(x: f32) -> [f32; N] {
        [x; N]
    }

    #[inline(always)]
    unsafe fn load(p: *const f32) -> [f32; N] {
        // SAFETY: the caller's contract.
        unsafe { p.cast::<[f32; N]>().read_unaligned() }
    }

    #[inline(always)]
    unsafe fn store(p: *mut f32, v: [f32; N]) {
        // SAFETY: the caller's contract.
        unsafe { p.cast::<[f32; N]>().write_unaligned(v) }
    }

    #[inline(always)]
    fn mul_add(a: [f32; N], b: [f32; N], c: [f32; N]) -> [f32; N] {
        core::array::from_fn(|i| c[i] + a[i] * b[i])
    }

    #[inline(always)]
    fn add(a: [f32; N], b: [f32; N]) -> [f32; N] {
        core::array::from_fn(|i| a[i] + b[i])
    }

    #[inline(always)]
    fn relu(v: [f32; N]) -> [f32; N] {
        v.map(|x| if x > 0.0 { x } else { 0.0 })
    }

    #[inline(always)]
    fn keep_positive(m: [f32; N], v: [f32; N]) -> [f32; N] {
        core::array::from_fn(|i| if m[i] > 0.0 { v[i] } else { 0.0 })
    }
}
