//! The output maps of the neural models (Sec. 4.1.2), softplus `ln(1 + e^x)` and the sigmoid
//! `1 / (1 + e^-x)`, on many values at once, beside the one-value activations of [`crate::math`]: a
//! Single MLP query maps 3 raw outputs, a packet 48, and `libm`'s `expf` and `log1pf` one value at a
//! time took ~15 ns per value (4% of a batched Single MLP query).
//!
//! AVX-512: `e^x` as in Cephes `expf.c` (`x = k ln 2 + r` in two steps, a degree-7 polynomial for
//! `e^r`, `2^k` by `vscalefps`, which also underflows and overflows where `expf` does) and
//! `ln(1 + u)` for `u = e^-|x|` in `[0, 1]` as in Cephes `logf.c` (`1 + u = 2^e m` with
//! `m ∈ [√½, √2]`, the polynomial of `ln m`), plus the rounding error of `1 + u` divided by it, which
//! keeps `ln(1 + u) = u` exact for tiny `u`. Within 3 ulp of the true values (`tests`). Other levels
//! call [`super::softplus`] and [`super::sigmoid`] per value.
//!
//! Every value's result depends on that value alone, whatever its position in the slice, so a single
//! query and a packet agree bit for bit, and the trainer's output ops, which map their tensors through
//! [`softplus_slice`] and [`sigmoid_slice`], compute what an exported model computes.

use super::{sigmoid, softplus};
#[cfg(target_arch = "x86_64")]
use crate::kernels::{level, Level};

/// Maps `x` in place by each value's index modulo 8, the stride of the neural models' raw outputs:
/// bit `i` of `softplus` gives the values at `i mod 8` softplus, bit `i` of `sigmoid` the sigmoid
/// (softplus wins where both are set); the rest are left as they are.
///
/// ```
/// use nbrdf::math::map_outputs;
/// let mut s = [0.0f32, 1.0, -1.0, 0.0, 2.0, 9.0, 9.0, 9.0];
/// // An enhanced additive model: softplus of s[0..3], the sigmoid of s[3..6].
/// map_outputs(&mut s, 0b000_111, 0b111_000);
/// assert!((s[0] - 2f32.ln()).abs() < 1e-7 && (s[3] - 0.5).abs() < 1e-7);
/// assert_eq!(s[6], 9.0);
/// ```
#[inline]
pub fn map_outputs(x: &mut [f32], softplus_lanes: u8, sigmoid_lanes: u8) {
    let sigmoid_lanes = sigmoid_lanes & !softplus_lanes;
    #[cfg(target_arch = "x86_64")]
    if level() == Level::Avx512 {
        // The lane masks of 16 values starting at an index ≡ 0 (mod 8).
        let wide = |m: u8| m as u16 | (m as u16) << 8;
        for chunk in x.chunks_mut(16) {
            // SAFETY: `level()` is at most the detected level, so the CPU has AVX-512F; the chunk holds
            // `len ≤ 16` values.
            unsafe { avx512::map(chunk, wide(softplus_lanes), wide(sigmoid_lanes)) };
        }
        return;
    }
    for (i, v) in x.iter_mut().enumerate() {
        let bit = 1u8 << (i % 8);
        if softplus_lanes & bit != 0 {
            *v = softplus(*v);
        } else if sigmoid_lanes & bit != 0 {
            *v = sigmoid(*v);
        }
    }
}

/// Softplus of every value of `x`, in place (the same function as [`map_outputs`]).
#[inline]
pub fn softplus_slice(x: &mut [f32]) {
    map_outputs(x, 0xff, 0);
}

/// The sigmoid of every value of `x`, in place (the same function as [`map_outputs`]).
#[inline]
pub fn sigmoid_slice(x: &mut [f32]) {
    map_outputs(x, 0, 0xff);
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use core::arch::x86_64::*;

    /// `e^x` per lane (Cephes `expf`); NaN stays NaN, `-∞` gives 0 and `+∞` gives `+∞`.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    #[allow(clippy::excessive_precision)] // The constants as Cephes prints them.
    fn exp(x: __m512) -> __m512 {
        let c = |v: f32| _mm512_set1_ps(v);
        // `vminps`/`vmaxps` return their second operand where either is NaN: `x` goes second. Above 89
        // the result is infinite already.
        // Below -103.972, `e^x < 2^-150` rounds to 0 (unordered: NaN is kept).
        let nonzero = _mm512_cmp_ps_mask::<_CMP_NLT_UQ>(x, c(-103.972));
        let x = _mm512_max_ps(c(-104.0), _mm512_min_ps(c(89.0), x));
        let k = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(_mm512_mul_ps(x, c(core::f32::consts::LOG2_E)));
        let r = _mm512_fnmadd_ps(k, c(0.693_359_375), x);
        let r = _mm512_fnmadd_ps(k, c(-2.121_944_4e-4), r);
        let mut p = c(1.987_569_150_0e-4);
        for a in [1.398_199_950_7e-3, 8.333_451_907_3e-3, 4.166_579_589_4e-2, 1.666_666_545_9e-1, 5.000_000_120_1e-1] {
            p = _mm512_fmadd_ps(p, r, c(a));
        }
        let p = _mm512_add_ps(_mm512_fmadd_ps(p, _mm512_mul_ps(r, r), r), c(1.0));
        _mm512_maskz_mov_ps(nonzero, _mm512_scalef_ps(p, k))
    }

    /// `ln(1 + u)` per lane for `u ∈ [0, 1]` (Cephes `logf` on `1 + u`, plus its rounding error).
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    #[allow(clippy::excessive_precision)] // The constants as Cephes prints them.
    fn log1p_unit(u: __m512) -> __m512 {
        let c = |v: f32| _mm512_set1_ps(v);
        let one = c(1.0);
        let w = _mm512_add_ps(one, u);
        // `1 + u` rounded and its exact error (Fast2Sum: 1 ≥ u).
        let err = _mm512_sub_ps(u, _mm512_sub_ps(w, one));
        // `w = 2^e m` with `m ∈ [√½, √2]`, `e ∈ {0, 1}`: `f = m - 1` is exact (Sterbenz).
        let big = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(w, c(core::f32::consts::SQRT_2));
        let m = _mm512_mask_mul_ps(w, big, w, c(0.5));
        let e = _mm512_maskz_mov_ps(big, one);
        let f = _mm512_sub_ps(m, one);
        let z = _mm512_mul_ps(f, f);
        let mut p = c(7.037_683_629_2e-2);
        for a in [-1.151_461_031_0e-1, 1.167_699_874_0e-1, -1.242_014_084_6e-1, 1.424_932_278_7e-1, -1.666_805_766_5e-1, 2.000_071_476_5e-1, -2.499_999_399_3e-1, 3.333_333_117_4e-1] {
            p = _mm512_fmadd_ps(p, f, c(a));
        }
        let y = _mm512_mul_ps(_mm512_mul_ps(p, f), z);
        let y = _mm512_fmadd_ps(e, c(-2.121_944_40e-4), y);
        let y = _mm512_fnmadd_ps(c(0.5), z, y);
        let l = _mm512_add_ps(f, y);
        let l = _mm512_fmadd_ps(e, c(0.693_359_375), l);
        _mm512_add_ps(l, _mm512_div_ps(err, w))
    }

    /// `max(x, 0) + ln(1 + e^-|x|)`, the overflow-free softplus, per lane; NaN stays NaN.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn softplus(x: __m512) -> __m512 {
        let e = exp(_mm512_sub_ps(_mm512_setzero_ps(), _mm512_abs_ps(x)));
        // `x` second: NaN propagates.
        _mm512_add_ps(_mm512_max_ps(_mm512_setzero_ps(), x), log1p_unit(e))
    }

    /// `1 / (1 + e^-x)` for `x ≥ 0`, `e^x / (1 + e^x)` below (no overflow either way), per lane.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn sigmoid(x: __m512) -> __m512 {
        let one = _mm512_set1_ps(1.0);
        let e = exp(_mm512_sub_ps(_mm512_setzero_ps(), _mm512_abs_ps(x)));
        let pos = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(x, _mm512_setzero_ps());
        _mm512_div_ps(_mm512_mask_mov_ps(e, pos, one), _mm512_add_ps(one, e))
    }

    /// Maps the `x.len() ≤ 16` values of `x` in place: softplus on the lanes of `sp`, the sigmoid on
    /// those of `sg` (disjoint).
    ///
    /// # Safety
    /// The CPU has AVX-512F; `x.len() ≤ 16`.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe fn map(x: &mut [f32], sp: u16, sg: u16) {
        let valid = ((1u32 << x.len()) - 1) as u16;
        let (sp, sg) = (sp & valid, sg & valid);
        // SAFETY: the masked load and store touch the `len` values of `x` only.
        unsafe {
            let v = _mm512_maskz_loadu_ps(valid, x.as_ptr());
            let mut y = v;
            if sp != 0 {
                y = _mm512_mask_mov_ps(y, sp, softplus(v));
            }
            if sg != 0 {
                y = _mm512_mask_mov_ps(y, sg, sigmoid(v));
            }
            _mm512_mask_storeu_ps(x.as_mut_ptr(), sp | sg, y);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn softplus64(x: f64) -> f64 {
        x.max(0.0) + libm::log1p(libm::exp(-x.abs()))
    }

    fn sigmoid64(x: f64) -> f64 {
        1.0 / (1.0 + libm::exp(-x))
    }

    /// Against f64 over the range of raw outputs and beyond: within 3 ulp (relative 3.6e-7, or a
    /// denormal's absolute spacing).
    #[test]
    fn maps_are_within_three_ulp_of_the_true_values() {
        let mut xs = alloc::vec::Vec::new();
        let mut x = -110.0f32;
        while x < 110.0 {
            xs.push(x);
            x += if x.abs() < 2.0 { 0.000_731 } else { 0.0173 };
        }
        xs.extend([0.0, -0.0, 1e-30, -1e-30, 1e-8, -1e-8, 88.0, -88.0, 103.0, -103.0, 1e30, -1e30]);
        for (f, f64_of, slice) in [
            (softplus as fn(f32) -> f32, softplus64 as fn(f64) -> f64, softplus_slice as fn(&mut [f32])),
            (sigmoid, sigmoid64, sigmoid_slice),
        ] {
            let mut got = xs.clone();
            slice(&mut got);
            for (&x, &g) in xs.iter().zip(&got) {
                let want = f64_of(x as f64);
                let err = (g as f64 - want).abs();
                assert!(err <= 3.6e-7 * want.abs() || err < 1e-44, "x = {x}: {g} vs {want}");
                // The scalar function (other levels, and the parametric models) is as close.
                assert!((f(x) as f64 - want).abs() <= 3.6e-7 * want.abs() || want.abs() < 1e-37, "scalar at {x}");
            }
        }
    }

    #[test]
    fn non_finite_values_map_as_the_scalar_functions_do() {
        let xs = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        let mut s = xs;
        softplus_slice(&mut s);
        assert!(s[0].is_nan() && s[1] == f32::INFINITY && s[2] == 0.0, "{s:?}");
        let mut g = xs;
        sigmoid_slice(&mut g);
        assert!(g[0].is_nan() && g[1] == 1.0 && g[2] == 0.0, "{g:?}");
    }

    #[test]
    fn a_value_maps_alike_wherever_it_sits() {
        let raw: alloc::vec::Vec<f32> = (0..40).map(|i| (i as f32 * 0.77).sin() * 12.0).collect();
        let mut all = raw.clone();
        map_outputs(&mut all, 0b0000_0111, 0b0011_1000);
        for (i, &v) in raw.iter().enumerate() {
            let mut one = [v];
            match i % 8 {
                0..=2 => softplus_slice(&mut one),
                3..=5 => sigmoid_slice(&mut one),
                _ => {}
            }
            assert_eq!(all[i].to_bits(), one[0].to_bits(), "value {i}");
        }
    }
}
