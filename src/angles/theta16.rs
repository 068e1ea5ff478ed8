//! The exact reciprocity map Θ (Sec. 4.3, [`super::theta_map`]), or the plain Rusinkiewicz angles,
//! and their positional encoding ([`crate::encoding::positional_encoding`]) for 16 direction pairs at
//! once (AVX-512), with the bits of the one-pair functions in every lane: the batch form of this
//! module's scalar functions, kept beside them (x86-64 only). It runs only where
//! [`crate::kernels::level`] is AVX-512; `Model::eval_many` checks that before calling [`encode16`].
//!
//! Why: a batch's per-pair work before the network is Θ's three `atan2f` (libm, scalar) and the
//! sines and cosines of its octaves, one vector of 16 per pair whose dependent chain the core cannot
//! overlap with the next pair's. Together ~110 ns a pair on Zen 4, a tenth of a batched Single MLP
//! query and a fifth of an Additive Shared one. Here the lanes are the pairs, so every step is one
//! vector for 16 of them.
//!
//! Why bit for bit: `Model::eval_many` promises the bits of `Model::eval`, exact reciprocity
//! included, and the trainer encodes through the scalar functions. So each lane runs the same IEEE
//! operations in the same order as the scalar code: [`super::unit`] (twice, as
//! `upper_hemisphere_pair` and then `half_frame` normalise), the half frame with glam's sums in
//! glam's order, libm's `atanf`/`atan2f` (FreeBSD `s_atanf.c`, `e_atan2f.c`; their branches as
//! masks, no fused multiply-adds), and the encoding's one sine-cosine body ([`crate::encoding`]'s
//! `sincos_vector`, `encoding/sincos.rs`; lanes it does not reduce go to `libm::sincosf` as there).
//! Pairs whose vectors need `unit`'s rescaled path (squared length outside `[1e-30, 1e30]`, zero, not
//! finite) are left to the caller's scalar code.

use core::arch::x86_64::*;

use super::{UNIT_FAST_MAX, UNIT_FAST_MIN, UNIT_TAYLOR};
use crate::kernels::{mask16, transpose16};
use crate::Vec3;

/// Three components of 16 vectors.
#[derive(Clone, Copy)]
struct V3 {
    x: __m512,
    y: __m512,
    z: __m512,
}

#[inline(always)]
fn splat(v: f32) -> __m512 {
    // SAFETY: only reached from functions compiled with AVX-512F (every caller below).
    unsafe { _mm512_set1_ps(v) }
}

/// `(x*x + y*y) + z*z` of each lane: glam's `length_squared` and `dot` order.
#[inline]
#[target_feature(enable = "avx512f")]
fn dot(a: V3, b: V3) -> __m512 {
    _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(a.x, b.x), _mm512_mul_ps(a.y, b.y)), _mm512_mul_ps(a.z, b.z))
}

/// [`super::unit`] of each lane, and the lanes its fast paths do not cover (the rescaled path:
/// left to the scalar code).
#[inline]
#[target_feature(enable = "avx512f")]
fn unit(v: V3) -> (V3, __mmask16) {
    let l2 = dot(v, v);
    let taylor = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(_mm512_sub_ps(l2, splat(1.0))), splat(UNIT_TAYLOR));
    let fast = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(l2, splat(UNIT_FAST_MIN)) & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(l2, splat(UNIT_FAST_MAX));
    let s = _mm512_mask_blend_ps(
        taylor,
        _mm512_div_ps(splat(1.0), _mm512_sqrt_ps(l2)),
        _mm512_sub_ps(splat(1.5), _mm512_mul_ps(splat(0.5), l2)),
    );
    (V3 { x: _mm512_mul_ps(v.x, s), y: _mm512_mul_ps(v.y, s), z: _mm512_mul_ps(v.z, s) }, !(taylor | fast))
}

#[inline]
#[target_feature(enable = "avx512f")]
fn neg(v: __m512) -> __m512 {
    _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(v), _mm512_set1_epi32(i32::MIN)))
}

#[inline]
#[target_feature(enable = "avx512f")]
fn bits(v: __m512) -> __m512i {
    _mm512_castps_si512(v)
}

/// The lanes whose sign bit is set.
#[inline]
#[target_feature(enable = "avx512f")]
fn negative(v: __m512i) -> __mmask16 {
    _mm512_cmplt_epi32_mask(v, _mm512_setzero_si512())
}

#[inline]
#[target_feature(enable = "avx512f")]
fn from_bits(v: u32) -> __m512 {
    _mm512_castsi512_ps(_mm512_set1_epi32(v as i32))
}

/// libm's `atanf` (FreeBSD `s_atanf.c`) in each lane.
#[inline]
#[target_feature(enable = "avx512f")]
#[allow(clippy::excessive_precision)] // libm's constants, as written there.
fn atanf(x: __m512) -> __m512 {
    const A_T: [f32; 5] = [3.3333328366e-01, -1.9999158382e-01, 1.4253635705e-01, -1.0648017377e-01, 6.1687607318e-02];
    let ix = _mm512_and_si512(bits(x), _mm512_set1_epi32(0x7fff_ffff));
    let sign = negative(bits(x));
    let below = |c: u32| _mm512_cmplt_epu32_mask(ix, _mm512_set1_epi32(c as i32));
    let big = !below(0x4c80_0000); // |x| >= 2^26, infinity and NaN
    let small = below(0x3ee0_0000); // |x| < 7/16: id -1
    let tiny = below(0x3980_0000); // |x| < 2^-12: x itself
    let (lt_11_16, lt_19_16, lt_39_16) = (below(0x3f30_0000), below(0x3f98_0000), below(0x401c_0000));
    let ax = _mm512_abs_ps(x);
    let one = splat(1.0);
    // The four reductions of |x| (ids 0 to 3), each in libm's operations.
    let r0 = _mm512_div_ps(_mm512_sub_ps(_mm512_mul_ps(splat(2.0), ax), one), _mm512_add_ps(splat(2.0), ax));
    let r1 = _mm512_div_ps(_mm512_sub_ps(ax, one), _mm512_add_ps(ax, one));
    let r2 = _mm512_div_ps(_mm512_sub_ps(ax, splat(1.5)), _mm512_add_ps(one, _mm512_mul_ps(splat(1.5), ax)));
    let r3 = _mm512_div_ps(splat(-1.0), ax);
    let id0 = lt_11_16 & !small;
    let id1 = lt_19_16 & !lt_11_16;
    let id2 = lt_39_16 & !lt_19_16;
    let mut xr = r3;
    xr = _mm512_mask_mov_ps(xr, id2, r2);
    xr = _mm512_mask_mov_ps(xr, id1, r1);
    xr = _mm512_mask_mov_ps(xr, id0, r0);
    xr = _mm512_mask_mov_ps(xr, small, x);
    let pick = |t: [u32; 4]| {
        let mut v = from_bits(t[3]);
        v = _mm512_mask_mov_ps(v, id2, from_bits(t[2]));
        v = _mm512_mask_mov_ps(v, id1, from_bits(t[1]));
        _mm512_mask_mov_ps(v, id0, from_bits(t[0]))
    };
    let hi = pick([0x3eed_6338, 0x3f49_0fda, 0x3f7b_985e, 0x3fc9_0fda]);
    let lo = pick([0x31ac_3769, 0x3322_2168, 0x3314_0fb4, 0x33a2_2168]);
    let z = _mm512_mul_ps(xr, xr);
    let w = _mm512_mul_ps(z, z);
    let s1 = _mm512_mul_ps(z, _mm512_add_ps(splat(A_T[0]), _mm512_mul_ps(w, _mm512_add_ps(splat(A_T[2]), _mm512_mul_ps(w, splat(A_T[4]))))));
    let s2 = _mm512_mul_ps(w, _mm512_add_ps(splat(A_T[1]), _mm512_mul_ps(w, splat(A_T[3]))));
    let s12 = _mm512_add_ps(s1, s2);
    let near = _mm512_sub_ps(xr, _mm512_mul_ps(xr, s12));
    let far = _mm512_sub_ps(hi, _mm512_sub_ps(_mm512_sub_ps(_mm512_mul_ps(xr, s12), lo), xr));
    let far = _mm512_mask_mov_ps(far, sign, neg(far));
    let mut r = _mm512_mask_mov_ps(far, small, near);
    r = _mm512_mask_mov_ps(r, tiny, x);
    let huge = _mm512_add_ps(from_bits(0x3fc9_0fda), from_bits(0x0380_0000));
    let huge = _mm512_mask_mov_ps(huge, sign, neg(huge));
    let nan = _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(x, x);
    r = _mm512_mask_mov_ps(r, big, huge);
    _mm512_mask_mov_ps(r, nan, x)
}

/// libm's `atan2f(y, x)` (FreeBSD `e_atan2f.c`) in each lane.
#[inline]
#[target_feature(enable = "avx512f")]
fn atan2f(y: __m512, x: __m512) -> __m512 {
    use core::f32::consts::PI;
    let pi_lo = from_bits(0xb3bb_bd2e);
    let (ix, iy) = (bits(x), bits(y));
    let abs_mask = _mm512_set1_epi32(0x7fff_ffff);
    let (ax, ay) = (_mm512_and_si512(ix, abs_mask), _mm512_and_si512(iy, abs_mask));
    let eq = |a: __m512i, c: u32| _mm512_cmpeq_epi32_mask(a, _mm512_set1_epi32(c as i32));
    let (y_neg, x_neg) = (negative(iy), negative(ix));
    // m = 2·sign(x) + sign(y): the quadrant picks among four values.
    let by_m = |m0: __m512, m1: __m512, m2: __m512, m3: __m512| {
        let pos_x = _mm512_mask_mov_ps(m0, y_neg, m1);
        let neg_x = _mm512_mask_mov_ps(m2, y_neg, m3);
        _mm512_mask_mov_ps(pos_x, x_neg, neg_x)
    };
    let half_pi = _mm512_mask_mov_ps(splat(PI / 2.), y_neg, splat(-PI / 2.));
    // The general case: z = atan(|y/x|), 0 where |y/x| < 2^-26 and x < 0.
    let shift = _mm512_set1_epi32(26 << 23);
    let tiny_ratio = x_neg & _mm512_cmplt_epu32_mask(_mm512_add_epi32(ay, shift), ax);
    let z = _mm512_maskz_mov_ps(!tiny_ratio, atanf(_mm512_abs_ps(_mm512_div_ps(y, x))));
    let z_lo = _mm512_sub_ps(z, pi_lo);
    let mut r = by_m(z, neg(z), _mm512_sub_ps(splat(PI), z_lo), _mm512_sub_ps(z_lo, splat(PI)));
    // |y/x| > 2^26, or y infinite: ±π/2.
    let steep = _mm512_cmplt_epu32_mask(_mm512_add_epi32(ax, shift), ay) | eq(ay, 0x7f80_0000);
    r = _mm512_mask_mov_ps(r, steep, half_pi);
    // x infinite.
    let x_inf = eq(ax, 0x7f80_0000);
    let inf_inf = by_m(splat(PI / 4.), splat(-PI / 4.), splat(3. * PI / 4.), splat(-3. * PI / 4.));
    let inf_fin = by_m(splat(0.), splat(-0.), splat(PI), splat(-PI));
    r = _mm512_mask_mov_ps(r, x_inf, _mm512_mask_mov_ps(inf_fin, eq(ay, 0x7f80_0000), inf_inf));
    // x = 0: ±π/2; y = 0: y itself, or ±π for x < 0 (checked after x = 0 in libm, so it wins).
    r = _mm512_mask_mov_ps(r, eq(ax, 0), half_pi);
    r = _mm512_mask_mov_ps(r, eq(ay, 0), by_m(y, y, splat(PI), splat(-PI)));
    // x = 1: atan(y).
    r = _mm512_mask_mov_ps(r, eq(ix, 0x3f80_0000), atanf(y));
    // NaN: x + y.
    _mm512_mask_mov_ps(r, _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(x, y), _mm512_add_ps(x, y))
}

/// Encodes up to 16 pairs as `Model` does one (`upper_hemisphere_pair`, then
/// [`super::theta_map`] where `exact`, else [`super::rusinkiewicz_angles`], then
/// [`crate::encoding::positional_encoding`] with `frequencies` octaves): lane `q < n` to
/// `out[q * stride..][..len]` (`len` = 4 or 3 angles × `1 + 2 * frequencies`), the same bits. Returns `(valid, scalar)`: the
/// lanes whose row was written (the rest are off the upper hemisphere or degenerate: 0 for the
/// model, row untouched), and those left to the caller's scalar code (see the module docs), neither
/// written nor valid.
///
/// # Safety
/// [`crate::kernels::level`] is [`crate::kernels::Level::Avx512`] (the condition of the sine-cosine
/// body it shares with `sincos_octaves`); `n ≤ 16`; `frequencies ≤ 127`; `stride ≥ len` and `out` holds
/// `(n - 1) * stride + len` values.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn encode16(wi: &[Vec3; 16], wo: &[Vec3; 16], n: usize, exact: bool, frequencies: usize, out: &mut [f32], stride: usize) -> (u16, u16) {
    let lanes: __mmask16 = if n >= 16 { 0xffff } else { ((1u32 << n) - 1) as u16 };
    let load = |v: &[Vec3; 16]| V3 {
        x: _mm512_setr_ps(v[0].x, v[1].x, v[2].x, v[3].x, v[4].x, v[5].x, v[6].x, v[7].x, v[8].x, v[9].x, v[10].x, v[11].x, v[12].x, v[13].x, v[14].x, v[15].x),
        y: _mm512_setr_ps(v[0].y, v[1].y, v[2].y, v[3].y, v[4].y, v[5].y, v[6].y, v[7].y, v[8].y, v[9].y, v[10].y, v[11].y, v[12].y, v[13].y, v[14].y, v[15].y),
        z: _mm512_setr_ps(v[0].z, v[1].z, v[2].z, v[3].z, v[4].z, v[5].z, v[6].z, v[7].z, v[8].z, v[9].z, v[10].z, v[11].z, v[12].z, v[13].z, v[14].z, v[15].z),
    };
    let zero = _mm512_setzero_ps();
    // upper_hemisphere_pair: both normalised, both strictly above the horizon.
    let (wi, slow_i) = unit(load(wi));
    let (wo, slow_o) = unit(load(wo));
    let mut scalar = (slow_i | slow_o) & lanes;
    let above = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(wi.z, zero) & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(wo.z, zero);
    // half_frame normalises them again.
    let (wi, slow_i) = unit(wi);
    let (wo, slow_o) = unit(wo);
    scalar |= (slow_i | slow_o) & lanes & above;
    let s = V3 { x: _mm512_add_ps(wi.x, wo.x), y: _mm512_add_ps(wi.y, wo.y), z: _mm512_add_ps(wi.z, wo.z) };
    let u = V3 { x: _mm512_sub_ps(wi.x, wo.x), y: _mm512_sub_ps(wi.y, wo.y), z: _mm512_sub_ps(wi.z, wo.z) };
    let s_len = _mm512_sqrt_ps(dot(s, s));
    let valid = lanes & above & !scalar & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(s_len, zero);
    let h = V3 { x: _mm512_div_ps(s.x, s_len), y: _mm512_div_ps(s.y, s_len), z: _mm512_div_ps(s.z, s_len) };
    let rho = _mm512_sqrt_ps(_mm512_add_ps(_mm512_mul_ps(h.x, h.x), _mm512_mul_ps(h.y, h.y)));
    let theta_h = atan2f(rho, h.z);
    let theta_d = atan2f(_mm512_sqrt_ps(dot(u, u)), s_len);
    let tilted = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(rho, zero);
    let cos_phi_h = _mm512_mask_div_ps(splat(1.0), tilted, h.x, rho);
    let sin_phi_h = _mm512_maskz_div_ps(tilted, h.y, rho);
    let x_axis = V3 { x: _mm512_mul_ps(h.z, cos_phi_h), y: _mm512_mul_ps(h.z, sin_phi_h), z: neg(rho) };
    let y_axis = V3 { x: neg(sin_phi_h), y: cos_phi_h, z: zero };
    let (a, b) = (dot(u, x_axis), dot(u, y_axis));
    let flipped = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(b, zero)
        | (_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(b, zero) & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, zero));
    let (a, b) = (_mm512_mask_mov_ps(a, flipped, neg(a)), _mm512_mask_mov_ps(b, flipped, neg(b)));
    // Signed zeros dropped, so that atan2 sees the same bits for both orders.
    let a = _mm512_mask_mov_ps(a, _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a, zero), zero);
    let b = _mm512_mask_mov_ps(b, _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(b, zero), zero);
    let phi = atan2f(b, a);
    use core::f32::consts::{PI, TAU};
    // atan2 of (tiny b > 0, a < 0) can round up to π: 0 of the other half plane.
    let folded = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(phi, splat(PI));
    let phi = _mm512_mask_mov_ps(phi, folded, zero);
    let angles = if exact {
        // theta_map: [θh, θd, φd mod π, φd mod π + π].
        [theta_h, theta_d, phi, _mm512_add_ps(phi, splat(PI))]
    } else {
        // rusinkiewicz_angles: [θh, θd, φd] with φd in [0, 2π).
        let phi_d = _mm512_mask_add_ps(phi, flipped ^ folded, phi, splat(PI));
        let phi_d = _mm512_mask_mov_ps(phi_d, _mm512_cmp_ps_mask::<_CMP_GE_OQ>(phi_d, splat(TAU)), zero);
        [theta_h, theta_d, phi_d, zero]
    };
    let n_angles = if exact { 4 } else { 3 };

    // The encoding, feature-major: per angle its value, then sin and cos of 2^k times it.
    let block = 1 + 2 * frequencies;
    let len = n_angles * block;
    let mut cols = [zero; 16];
    let mut col = 0;
    let mut rows_done = 0;
    let mut put = |v: __m512, cols: &mut [__m512; 16], col: &mut usize, flush_all: bool| {
        cols[*col] = v;
        *col += 1;
        if *col == 16 || flush_all {
            let t = transpose16(*cols);
            // Only the row's own values: rows may lie `len` apart.
            let m = mask16(len - rows_done);
            for (q, row) in t.iter().enumerate().take(n) {
                if valid & (1 << q) != 0 {
                    // SAFETY: row `q < n` has room for `len` values (contract); the mask stores no more.
                    unsafe { _mm512_mask_storeu_ps(out.as_mut_ptr().add(q * stride + rows_done), m, *row) };
                }
            }
            rows_done += 16;
            *col = 0;
        }
    };
    for (j, &v) in angles.iter().enumerate().take(n_angles) {
        put(v, &mut cols, &mut col, j + 1 == n_angles && frequencies == 0);
        for k in 0..frequencies {
            // 2^k from its exponent bits, times the value: the product `octave_args` forms.
            let arg = _mm512_mul_ps(_mm512_castsi512_ps(_mm512_set1_epi32((k as i32 + 127) << 23)), v);
            // SAFETY: AVX-512F.
            let (mut sin, mut cos, done) = unsafe { crate::encoding::sincos_vector(arg) };
            let redo = !done & valid;
            if redo != 0 {
                let (mut xs, mut ss, mut cs) = ([0.0f32; 16], [0.0f32; 16], [0.0f32; 16]);
                // SAFETY: the arrays hold 16 values.
                unsafe {
                    _mm512_storeu_ps(xs.as_mut_ptr(), arg);
                    _mm512_storeu_ps(ss.as_mut_ptr(), sin);
                    _mm512_storeu_ps(cs.as_mut_ptr(), cos);
                }
                for q in (0..16).filter(|q| redo & (1 << q) != 0) {
                    (ss[q], cs[q]) = libm::sincosf(xs[q]);
                }
                // SAFETY: as above.
                unsafe {
                    sin = _mm512_loadu_ps(ss.as_ptr());
                    cos = _mm512_loadu_ps(cs.as_ptr());
                }
            }
            let last = j + 1 == n_angles && k + 1 == frequencies;
            put(sin, &mut cols, &mut col, false);
            put(cos, &mut cols, &mut col, last);
        }
    }
    debug_assert!(rows_done >= len);
    (valid, scalar)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angles::{rusinkiewicz_angles, theta_map, upper_hemisphere_pair};
    use crate::encoding::positional_encoding;

    fn avx512() -> bool {
        let here = crate::kernels::level() == crate::kernels::Level::Avx512;
        if !here {
            crate::kernels::skipped("Θ for 16 pairs", crate::kernels::Level::Avx512);
        }
        here
    }

    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// A 32-bit pattern generator (xorshift), for arguments of every exponent.
    fn xorshift(seed: &mut u32) -> u32 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 17;
        *seed ^= *seed << 5;
        *seed
    }

    /// `atan2f` and `atanf` in every lane against libm's, bit for bit: every special value libm
    /// branches on (zeros of both signs, ±1, infinities, NaN, the 2^±26 ratio limits, the reduction
    /// boundaries of `atanf`) against each other, and random bit patterns.
    #[test]
    fn atan2f_has_the_bits_of_libm_in_every_lane() {
        if !avx512() {
            return;
        }
        let mut special = std::vec![0.0f32, -0.0, 1.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 0.5, 2.0, 1e-30, -3e-39, 1e30, 7.0 / 16.0, 11.0 / 16.0, 19.0 / 16.0, 39.0 / 16.0, 6.7e7, 1.5e-8, f32::from_bits(0x3edf_ffff), f32::from_bits(0x401b_ffff), core::f32::consts::PI];
        for v in special.clone() {
            special.push(-v);
            special.push(f32::from_bits(v.to_bits().wrapping_add(1)));
        }
        let mut seed = 0x9e37_79b9u32;
        let mut ys = std::vec::Vec::new();
        let mut xs = std::vec::Vec::new();
        for &y in &special {
            for &x in &special {
                ys.push(y);
                xs.push(x);
            }
        }
        for _ in 0..20_000 {
            ys.push(f32::from_bits(xorshift(&mut seed)));
            xs.push(f32::from_bits(xorshift(&mut seed)));
            // Ratios near 1 and of moderate size, where the reductions run.
            let t = f32::from_bits(xorshift(&mut seed) >> 9 | 0x3f80_0000) - 1.0;
            ys.push(t * 3.0 - 1.0);
            xs.push(1.0 - t);
        }
        while ys.len() % 16 != 0 {
            ys.push(0.5);
            xs.push(0.25);
        }
        for (y, x) in ys.chunks(16).zip(xs.chunks(16)) {
            let (mut a2, mut a1) = ([0.0f32; 16], [0.0f32; 16]);
            // SAFETY: AVX-512 (checked); the arrays hold 16 values.
            unsafe {
                let (vy, vx) = (_mm512_loadu_ps(y.as_ptr()), _mm512_loadu_ps(x.as_ptr()));
                _mm512_storeu_ps(a2.as_mut_ptr(), atan2f(vy, vx));
                _mm512_storeu_ps(a1.as_mut_ptr(), atanf(vy));
            }
            for q in 0..16 {
                assert!(same(a2[q], libm::atan2f(y[q], x[q])), "atan2f({:e}, {:e}): {:e} vs {:e}", y[q], x[q], a2[q], libm::atan2f(y[q], x[q]));
                assert!(same(a1[q], libm::atanf(y[q])), "atanf({:e}): {:e} vs {:e}", y[q], a1[q], libm::atanf(y[q]));
            }
        }
    }

    /// `encode16` against `upper_hemisphere_pair`, `theta_map` (or `rusinkiewicz_angles`) and
    /// `positional_encoding`, one pair at a time: the same rows bit for bit, the same invalid pairs, and the pairs it leaves to the scalar
    /// code only where `unit` rescales. Directions on the sphere and near it, grazing, below the
    /// horizon, mirrored, equal and opposite, unnormalised by a little and by a lot, zero, huge, NaN;
    /// 0, 1, 4 and 16 octaves (16: the largest arguments, some redone by `libm::sincosf`); partial
    /// batches.
    #[test]
    fn encode16_has_the_bits_of_the_one_pair_functions() {
        if !avx512() {
            return;
        }
        let mut seed = 0x1234_5678u32;
        let mut uniform = || (xorshift(&mut seed) >> 8) as f32 / (1u32 << 24) as f32;
        let mut dirs = std::vec::Vec::new();
        for _ in 0..4000 {
            let (u, phi) = (uniform(), core::f32::consts::TAU * uniform());
            let z = 1.0 - 2.0 * u;
            let r = (1.0 - z * z).max(0.0).sqrt();
            dirs.push(Vec3::new(r * phi.cos(), r * phi.sin(), z) * if uniform() < 0.3 { 0.5 + 3.0 * uniform() } else { 1.0 });
        }
        let edges = [
            Vec3::Z, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8), Vec3::new(0.0, -0.6, 0.8), Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1e-7), Vec3::new(0.0, 0.0, -1.0), Vec3::ZERO, Vec3::new(1e20, 0.0, 1e20), Vec3::new(1e-20, 0.0, 1e-20),
            Vec3::new(f32::NAN, 0.0, 1.0), Vec3::new(0.0, f32::INFINITY, 1.0), Vec3::new(3e-39, 0.0, 1.0), Vec3::new(0.3, 0.4, 0.8660254),
        ];
        for a in edges {
            for b in edges {
                dirs.push(a);
                dirs.push(b);
                dirs.push(a);
                dirs.push(-b * Vec3::new(1.0, 1.0, -1.0));
            }
        }
        let (mut n_valid, mut n_scalar) = (0, 0);
        for (exact, frequencies) in [true, false].into_iter().flat_map(|e| [0usize, 1, 4, 16].map(|f| (e, f))) {
            let len = if exact { 4 } else { 3 } * (1 + 2 * frequencies);
            // Rows back to back: a row must not spill into the next.
            let stride = len;
            for (c, chunk) in dirs.chunks(32).enumerate() {
                let n = (chunk.len() / 2).min(16 - c % 3);
                let wi: [Vec3; 16] = core::array::from_fn(|q| chunk.get(2 * q).copied().unwrap_or(Vec3::Z));
                let wo: [Vec3; 16] = core::array::from_fn(|q| chunk.get(2 * q + 1).copied().unwrap_or(Vec3::Z));
                let mut out = std::vec![f32::NAN; 16 * stride.max(1)];
                // SAFETY: AVX-512 (checked); `out` holds 16 rows of `len`.
                let (valid, scalar) = unsafe { encode16(&wi, &wo, n, exact, frequencies, &mut out, stride) };
                assert_eq!(valid & scalar, 0);
                assert_eq!(u32::from(valid | scalar) >> n, 0, "lanes past n");
                for q in 0..n {
                    let want = upper_hemisphere_pair(wi[q], wo[q]).and_then(|(a, b)| {
                        if exact {
                            theta_map(a, b)
                        } else {
                            rusinkiewicz_angles(a, b).map(|r| [r[0], r[1], r[2], 0.0])
                        }
                    });
                    let rescaled = |v: Vec3| !(v.length_squared() - 1.0).abs().le(&UNIT_TAYLOR) && !(UNIT_FAST_MIN..=UNIT_FAST_MAX).contains(&v.length_squared());
                    if scalar & (1 << q) != 0 {
                        assert!(rescaled(wi[q]) || rescaled(wo[q]), "{:?} {:?} left to the scalar code", wi[q], wo[q]);
                        n_scalar += 1;
                        continue;
                    }
                    assert_eq!(valid & (1 << q) != 0, want.is_some(), "{:?} {:?}", wi[q], wo[q]);
                    let Some(t) = want else { continue };
                    n_valid += 1;
                    let mut row = [0.0f32; 132];
                    assert_eq!(positional_encoding(&t[..len / (1 + 2 * frequencies)], frequencies, &mut row), len);
                    for i in 0..len {
                        assert!(same(out[q * stride + i], row[i]), "F {frequencies} {:?} {:?} value {i}: {} vs {}", wi[q], wo[q], out[q * stride + i], row[i]);
                    }
                }
            }
        }
        assert!(n_valid > 2000 && n_scalar > 100, "{n_valid} valid, {n_scalar} scalar");
    }
}
