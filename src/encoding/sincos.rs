//! `sin` and `cos` of 16 arguments at once, for the positional encoding
//! ([`super::positional_encoding`], and the batch encoding of `angles/theta16.rs`, which shares the
//! vector body): a Single MLP query encodes 4 angles at 4 octaves, 16 `sincosf` calls that took ~5% of
//! a query one by one.
//!
//! AVX-512: the argument is reduced by `π/2` in three FMA steps (Cody & Waite 1980, with the split
//! constants of Cephes `sinf.c`), then `sin` and `cos` of the remainder `|r| ≤ π/4` are the Cephes
//! minimax polynomials (degree 7 and 8, within 1 ulp on that range), and the quadrant swaps and
//! negates them. Lanes with `|x| > REDUCE_MAX` (or not finite) are redone by `libm::sincosf`, which
//! reduces exactly. Other levels call `libm::sincosf` per lane. Both are within about one ulp of the
//! true values (`tests`), so levels differ by rounding only, as the dense kernels do; the trainer
//! encodes through the same function, so on one machine both sides feed the networks the same bits.
//!
//! [`sincos_octaves`] builds the encoding's arguments `2^k v` in the vector itself: written one by one
//! into an array and loaded as one vector, they cannot be forwarded from the store queue (a load that
//! spans several smaller stores waits until they retire), which cost about half of a 4 × 4 encoding.

#[cfg(target_arch = "x86_64")]
use crate::kernels::{level, Level};

/// Largest `|x|` reduced in the vector path: `j = round(2x/π)` stays below 2^13, where the three-part
/// constant keeps the remainder accurate to well under an ulp.
#[cfg(any(target_arch = "x86_64", test))]
const REDUCE_MAX: f32 = 8192.0;

/// `(sin x_i, cos x_i)` for the first `n ≤ 16` lanes of `x` (the rest are unspecified).
#[inline]
pub fn sincos16(x: &[f32; 16], n: usize) -> ([f32; 16], [f32; 16]) {
    #[cfg(target_arch = "x86_64")]
    if level() == Level::Avx512 {
        // SAFETY: `level()` is at most the detected level, so the CPU has AVX-512F.
        let (mut s, mut c, slow) = unsafe { avx512(x) };
        redo(x, slow as u32 & ((1u32 << n.min(16)) - 1), &mut s, &mut c);
        return (s, c);
    }
    let mut s = [0.0f32; 16];
    let mut c = [0.0f32; 16];
    for i in 0..n.min(16) {
        (s[i], c[i]) = libm::sincosf(x[i]);
    }
    (s, c)
}

/// `(sin, cos)` of the positional encoding's arguments `2^k v_j` (`docs/models.md`), in the order
/// `(j, k)` with `k < frequencies` fastest, from flat index `first` on: lane `i` holds argument
/// `first + i`; lanes past `values.len() × frequencies` are unspecified (all 0 when there are none).
/// The arguments are those of [`sincos16`] (`2^k` exact, one rounding of the product) and so are the
/// results, bit for bit.
///
/// ```
/// use nbrdf::encoding::{sincos16, sincos_octaves};
/// let v = [0.3f32, -1.2, 2.5];
/// let (s, c) = sincos_octaves(&v, 4, 4);
/// // Lane 0 is argument 4 = (j 1, k 0), lane 5 is (j 2, k 1).
/// let args: [f32; 16] = core::array::from_fn(|i| v[(4 + i) / 4 % 3] * (1 << ((4 + i) % 4)) as f32);
/// let (ws, wc) = sincos16(&args, 8);
/// assert_eq!((s[..8].to_vec(), c[..8].to_vec()), (ws[..8].to_vec(), wc[..8].to_vec()));
/// ```
#[inline]
pub fn sincos_octaves(values: &[f32], frequencies: usize, first: usize) -> ([f32; 16], [f32; 16]) {
    let total = values.len() * frequencies;
    let m = total.saturating_sub(first).min(16);
    // No argument at or after `first` (no values, no octaves): every lane is past the end.
    if m == 0 {
        return ([0.0; 16], [0.0; 16]);
    }
    #[cfg(target_arch = "x86_64")]
    // `2^k` is built from its exponent bits: below 2^127 only (the encodings use a handful of octaves).
    if level() == Level::Avx512 && frequencies <= 127 {
        // SAFETY: `level()` is at most the detected level, so the CPU has AVX-512F.
        let (args, (mut s, mut c, slow)) = unsafe {
            let args = octave_args(values, frequencies, first);
            (args, avx512_vector(args))
        };
        let slow = slow as u32 & ((1u32 << m) - 1);
        if slow != 0 {
            let mut x = [0.0f32; 16];
            // SAFETY: `x` holds 16 values (AVX-512F as above).
            unsafe { core::arch::x86_64::_mm512_storeu_ps(x.as_mut_ptr(), args) };
            redo(&x, slow, &mut s, &mut c);
        }
        return (s, c);
    }
    let mut x = [0.0f32; 16];
    for (i, x) in x.iter_mut().take(m).enumerate() {
        let (j, k) = ((first + i) / frequencies, (first + i) % frequencies);
        // 2^k by doubling, as the encoding always computed it (infinite from k = 128 on).
        *x = (0..k).fold(1.0f32, |p, _| p * 2.0) * values[j];
    }
    sincos16(&x, m)
}

/// Redoes the lanes of `slow` with `libm::sincosf`, which reduces any argument exactly.
#[cfg(target_arch = "x86_64")]
#[inline]
fn redo(x: &[f32; 16], mut slow: u32, s: &mut [f32; 16], c: &mut [f32; 16]) {
    while slow != 0 {
        let i = slow.trailing_zeros() as usize;
        (s[i], c[i]) = libm::sincosf(x[i]);
        slow &= slow - 1;
    }
}

/// The arguments of [`sincos_octaves`] in one vector: each value `v_j` is broadcast (from a 4-byte
/// load, which is always forwarded) into the lanes of its block, where the exponent `k = lane - start`
/// of `2^k` is built alike; lanes past the last block are `+0`.
///
/// # Safety
/// The CPU has AVX-512F; `1 ≤ frequencies ≤ 127`.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn octave_args(values: &[f32], frequencies: usize, first: usize) -> core::arch::x86_64::__m512 {
    use core::arch::x86_64::*;
    let f = frequencies;
    let lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let (mut v, mut k) = (_mm512_setzero_ps(), _mm512_setzero_si512());
    // A range, not `iter().enumerate().skip().take()`: that form ran the whole encoding 1.3x slower.
    #[allow(clippy::needless_range_loop)]
    for j in first / f..values.len().min((first + 16).div_ceil(f)) {
        let value = values[j];
        // Block j covers lanes [j f - first, j f + f - first) ∩ [0, 16).
        let start = (j * f) as isize - first as isize;
        let (a, b) = (start.max(0) as u32, (start + f as isize).min(16) as u32);
        let mask = (((1u32 << b) - 1) & !((1u32 << a) - 1)) as __mmask16;
        v = _mm512_mask_mov_ps(v, mask, _mm512_set1_ps(value));
        k = _mm512_mask_sub_epi32(k, mask, lane, _mm512_set1_epi32(start as i32));
    }
    let two_k = _mm512_castsi512_ps(_mm512_slli_epi32::<23>(_mm512_add_epi32(k, _mm512_set1_epi32(127))));
    _mm512_mul_ps(two_k, v)
}

/// The vector path: `(sin, cos, lanes to redo)`.
///
/// # Safety
/// The CPU has AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn avx512(x: &[f32; 16]) -> ([f32; 16], [f32; 16], u16) {
    // SAFETY: the array holds 16 values; AVX-512F (contract).
    unsafe { avx512_vector(core::arch::x86_64::_mm512_loadu_ps(x.as_ptr())) }
}

/// [`avx512`] of a vector.
///
/// # Safety
/// The CPU has AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn avx512_vector(v: core::arch::x86_64::__m512) -> ([f32; 16], [f32; 16], u16) {
    use core::arch::x86_64::*;
    // SAFETY: AVX-512F (contract).
    let (s, co, ok) = unsafe { sincos_vector(v) };
    let mut so = [0.0f32; 16];
    let mut cout = [0.0f32; 16];
    // SAFETY: the arrays hold 16 values.
    unsafe {
        _mm512_storeu_ps(so.as_mut_ptr(), s);
        _mm512_storeu_ps(cout.as_mut_ptr(), co);
    }
    (so, cout, !ok)
}

/// `(sin, cos, lanes done)` of a vector: the lanes not done (`|x| > REDUCE_MAX` or not finite) hold
/// nothing of use and are for `libm::sincosf`. The one body of every vector sine and cosine of the
/// encodings, so that they give the same bits wherever they run.
///
/// # Safety
/// The CPU has AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(clippy::excessive_precision)] // The constants as Cephes prints them, so they can be checked there.
pub(crate) unsafe fn sincos_vector(v: core::arch::x86_64::__m512) -> (core::arch::x86_64::__m512, core::arch::x86_64::__m512, u16) {
    use core::arch::x86_64::*;
    let c = |f: f32| _mm512_set1_ps(f);
    // Ordered comparison: false for NaN, so NaN lanes go to libm as well.
    let ok = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(v), c(REDUCE_MAX));
    let v = _mm512_maskz_mov_ps(ok, v);
    let j = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(_mm512_mul_ps(v, c(core::f32::consts::FRAC_2_PI)));
    // π/2 = DP1 + DP2 + DP3 (Cephes sinf.c's split of π/4, doubled).
    let r = _mm512_fnmadd_ps(j, c(1.570_312_5), v);
    let r = _mm512_fnmadd_ps(j, c(4.837_512_969_970_703e-4), r);
    let r = _mm512_fnmadd_ps(j, c(7.549_789_948_768_648e-8), r);
    let z = _mm512_mul_ps(r, r);
    // Cephes sinf/cosf polynomials on |r| ≤ π/4.
    let sp = _mm512_fmadd_ps(_mm512_fmadd_ps(c(-1.951_529_589_1e-4), z, c(8.332_160_873_6e-3)), z, c(-1.666_665_461_1e-1));
    let sin_r = _mm512_fmadd_ps(_mm512_mul_ps(sp, z), r, r);
    let cp = _mm512_fmadd_ps(_mm512_fmadd_ps(c(2.443_315_711_809_948e-5), z, c(-1.388_731_625_493_765e-3)), z, c(4.166_664_568_298_827e-2));
    let cos_r = _mm512_fmadd_ps(cp, _mm512_mul_ps(z, z), _mm512_fnmadd_ps(c(0.5), z, c(1.0)));
    // Quadrant q = j mod 4: sin x = (s, c, -s, -c)[q], cos x = (c, -s, -c, s)[q].
    let q = _mm512_cvtps_epi32(j);
    let swap = _mm512_test_epi32_mask(q, _mm512_set1_epi32(1));
    let (s, co) = (_mm512_mask_blend_ps(swap, sin_r, cos_r), _mm512_mask_blend_ps(swap, cos_r, sin_r));
    let sign_bit = |m: __mmask16| _mm512_maskz_mov_epi32(m, _mm512_set1_epi32(i32::MIN));
    let neg_s = _mm512_test_epi32_mask(q, _mm512_set1_epi32(2));
    let neg_c = _mm512_test_epi32_mask(_mm512_add_epi32(q, _mm512_set1_epi32(1)), _mm512_set1_epi32(2));
    let s = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(s), sign_bit(neg_s)));
    let co = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(co), sign_bit(neg_c)));
    (s, co, ok)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against f64 `sin`/`cos` of the same f32 arguments, over the range the encodings use and beyond
    /// the vector path's: within 1.5e-7 absolute (about one ulp near 1).
    #[test]
    fn sincos16_is_within_an_ulp_or_so_of_the_true_values() {
        let mut x = -9000.0f32;
        let mut worst = 0.0f64;
        while x < 9000.0 {
            let xs: [f32; 16] = core::array::from_fn(|i| x + i as f32 * 0.37);
            let (s, c) = sincos16(&xs, 16);
            for i in 0..16 {
                let (ws, wc) = (libm::sin(xs[i] as f64), libm::cos(xs[i] as f64));
                for (got, want) in [(s[i], ws), (c[i], wc)] {
                    let err = (got as f64 - want).abs();
                    assert!(err <= 1.5e-7, "x = {}: {got} vs {want}", xs[i]);
                    worst = worst.max(err);
                }
            }
            x += if x.abs() < 70.0 { 0.9 } else { 97.3 };
        }
    }

    #[test]
    fn octaves_built_in_the_vector_equal_the_arguments_written_out() {
        let values = [0.3f32, -1.7, 2.9, 6.1, 1e-3, 4000.0, -0.0, 1.1];
        for n in [1, 3, 4, 8] {
            for frequencies in [1, 3, 4, 5, 16, 17, 130] {
                let total = n * frequencies;
                for first in (0..total).step_by(16).chain([1, 7].into_iter().filter(|f| *f < total)) {
                    let (s, c) = sincos_octaves(&values[..n], frequencies, first);
                    let m = (total - first).min(16);
                    // The arguments as the encoding defines them: 2^k by doubling, times v_j.
                    let args: [f32; 16] = core::array::from_fn(|i| {
                        let t = (first + i).min(total - 1);
                        (0..t % frequencies).fold(1.0f32, |p, _| p * 2.0) * values[t / frequencies]
                    });
                    let (ws, wc) = sincos16(&args, m);
                    for i in 0..m {
                        let ok = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
                        assert!(ok(s[i], ws[i]) && ok(c[i], wc[i]), "n {n} F {frequencies} first {first} lane {i}");
                    }
                }
            }
        }
    }

    #[test]
    fn octaves_past_the_end_or_of_nothing_are_empty_not_a_panic() {
        let v = [0.3f32, 1.2];
        for (values, frequencies, first) in [(&v[..], 0, 0), (&v[..0], 4, 0), (&v[..], 4, 8), (&v[..], 4, 100)] {
            assert_eq!(sincos_octaves(values, frequencies, first), ([0.0; 16], [0.0; 16]), "{values:?} F {frequencies} first {first}");
        }
    }

    #[test]
    fn special_and_partial_lanes_follow_libm() {
        let xs = [0.0, -0.0, f32::NAN, f32::INFINITY, 1e6, -3e4, 1e-30, core::f32::consts::PI, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0];
        let (s, c) = sincos16(&xs, 16);
        for i in 0..16 {
            let (ws, wc) = libm::sincosf(xs[i]);
            if ws.is_nan() {
                assert!(s[i].is_nan() && c[i].is_nan(), "lane {i}");
            } else if xs[i].abs() > REDUCE_MAX {
                assert_eq!((s[i], c[i]), (ws, wc), "lane {i}: redone by libm");
            } else {
                assert!((s[i] - ws).abs() <= 1.2e-7 && (c[i] - wc).abs() <= 1.2e-7, "lane {i}");
            }
        }
        assert_eq!(s[0].to_bits(), 0.0f32.to_bits());
        assert_eq!(s[6], 1e-30, "sin x = x for tiny x");
    }
}
