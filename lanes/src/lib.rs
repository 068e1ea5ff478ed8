//! The SIMD lanes that the nbrdf workspace's kernels are written over: one small trait, [`Lanes`],
//! and one type per instruction-set level (`Avx512`, `Avx2`, `Neon`, and [`Scalar`] for every
//! target). The core's evaluation kernels (`nbrdf::kernels`) and the trainer's dense products each
//! write their algorithm once against this trait; a level adds only its entry points, which enable
//! the level's instructions and instantiate the algorithm with its lane type.
//!
//! Internal to the workspace: the functions of a level's lanes use that level's instructions, so
//! they may only be called from code compiled with the level enabled (an entry point with
//! `#[target_feature]`, reached after run-time detection); see [`Lanes`]'s safety contract.
//!
//! ```
//! use nbrdf_lanes::{Lanes, Scalar};
//!
//! // c + a · b on every lane, at the portable level (no CPU feature needed).
//! let (a, b, c) = (Scalar::<4>::splat(2.0), Scalar::<4>::splat(3.0), Scalar::<4>::splat(1.0));
//! assert_eq!(Scalar::<4>::mul_add(a, b, c), [7.0; 4]);
//! assert_eq!(Scalar::<4>::relu([-1.0, 0.0, f32::NAN, 2.0]), [0.0, 0.0, 0.0, 2.0]);
//! ```
#![no_std]

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "aarch64")]
mod neon;
mod portable;

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;
#[cfg(target_arch = "x86_64")]
pub use avx512::Avx512;
#[cfg(target_arch = "aarch64")]
pub use neon::Neon;
pub use portable::Scalar;

/// A vector of `N` f32 lanes of one instruction-set level: what the forward kernels need (load,
/// store, broadcast, multiply-add, ReLU) and what a backward pass adds (sum, ReLU mask).
///
/// Every lane function is `#[inline(always)]`, so that it compiles into its caller with the caller's
/// enabled features.
///
/// # Safety
/// Implementors' functions may use instructions of their level. Callers run them only on CPUs
/// that have the level, from code compiled with it enabled (an entry point with `#[target_feature]`
/// that dispatch reaches after detecting the level); the trait's functions are safe to call only there.
pub unsafe trait Lanes {
    /// Lanes per vector.
    const N: usize;
    /// The vector.
    type V: Copy;
    /// All lanes 0.
    #[inline(always)]
    fn zero() -> Self::V {
        Self::splat(0.0)
    }
    /// All lanes `x`.
    fn splat(x: f32) -> Self::V;
    /// `N` values from `p`, unaligned.
    ///
    /// # Safety
    /// `p` addresses `N` readable values.
    unsafe fn load(p: *const f32) -> Self::V;
    /// `N` values to `p`, unaligned.
    ///
    /// # Safety
    /// `p` addresses `N` writable values.
    unsafe fn store(p: *mut f32, v: Self::V);
    /// `c + a · b`, fused where the level has it (every lane alike; [`Scalar`] does not fuse).
    fn mul_add(a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `a + b`.
    fn add(a: Self::V, b: Self::V) -> Self::V;
    /// `max(v, 0)` as every level computes it: `+0` for either zero and for NaN.
    fn relu(v: Self::V) -> Self::V;
    /// `v` where `m > 0`, else `+0` (NaN in `m` is not `> 0`): the ReLU's derivative applied to `v`.
    fn keep_positive(m: Self::V, v: Self::V) -> Self::V;
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// The contract every level keeps, whatever its instructions: ReLU gives +0 (not -0, not NaN) for
    /// zeros and NaN, the mask keeps `v` only where `m > 0`, and multiply-add and sum are exact on
    /// small integers. Inlined into each level's `#[target_feature]` caller, as the kernels are.
    #[inline(always)]
    fn contract<L: Lanes>(level: &str) {
        let n = L::N;
        let x: std::vec::Vec<f32> = (0..n).map(|i| [f32::NAN, -0.0, 0.0, -2.0, 3.0, f32::INFINITY, -f32::INFINITY, 1.5][i % 8]).collect();
        let mut out = std::vec![7.0f32; n];
        // SAFETY: `x` and `out` hold N values; the caller runs this only where the level is present.
        let v = unsafe { L::load(x.as_ptr()) };
        unsafe { L::store(out.as_mut_ptr(), L::relu(v)) };
        for (i, (o, x)) in out.iter().zip(&x).enumerate() {
            let want = if *x > 0.0 { *x } else { 0.0 };
            assert_eq!(o.to_bits(), want.to_bits(), "{level} relu lane {i} of {x}");
        }
        unsafe { L::store(out.as_mut_ptr(), L::keep_positive(v, L::splat(5.0))) };
        for (o, x) in out.iter().zip(&x) {
            assert_eq!(o.to_bits(), if *x > 0.0 { 5.0f32 } else { 0.0 }.to_bits(), "{level} keep_positive of {x}");
        }
        unsafe { L::store(out.as_mut_ptr(), L::add(L::mul_add(L::splat(3.0), L::splat(4.0), L::splat(1.0)), L::zero())) };
        assert!(out.iter().all(|o| *o == 13.0), "{level} mul_add");
    }

    #[test]
    fn every_level_the_host_has_keeps_the_lane_contract() {
        contract::<Scalar<4>>("portable 4");
        contract::<Scalar<8>>("portable 8");
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2,fma")]
            fn avx2() {
                contract::<Avx2>("avx2");
            }
            #[target_feature(enable = "avx512f,fma")]
            fn avx512() {
                contract::<Avx512>("avx512");
            }
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                // SAFETY: the CPU has AVX2 and FMA.
                unsafe { avx2() };
            } else {
                std::println!("SKIPPED: the avx2 lane contract (this CPU has no AVX2 and FMA)");
            }
            if std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("fma") {
                // SAFETY: the CPU has AVX-512 F and FMA.
                unsafe { avx512() };
            } else {
                std::println!("SKIPPED: the avx512 lane contract (this CPU has no AVX-512 F)");
            }
        }
        #[cfg(target_arch = "aarch64")]
        contract::<Neon>("neon");
    }
}
