//! Whole-network kernels for tiny dense networks: the NBRDF-json fits of measured BRDFs (6-21-21-3,
//! any widths up to [`TINY_MAX_WIDTH`]), input to `expm1`, in one call. They live with the format
//! they evaluate ([`super::NbrdfNetwork`]); the generic levels borrow the dense-layer kernels of
//! [`crate::kernels`].
//!
//! The generic layer kernels (`Kernels::one`) are built for 128-wide layers: per layer they pay an
//! indirect call, bounds checks and one FMA chain per input row, which for a 21-wide layer is a
//! latency-bound chain of 21 dependent FMAs. Here a whole network runs in one `#[target_feature]`
//! function; every output sums its inputs in **interleaved chains** (input `i` goes to chain
//! `i mod C`): `C = 4` in the hidden layers, whose 16 + 8 lanes of FMAs per input keep the FMA pipes
//! busy with four, and `C = 8` in the output layer, whose 3 outputs (one 8-lane vector) are bound by
//! the chain's latency alone.
//!
//! # Arithmetic of the AVX-512 kernels
//! The same at every lane width, so single queries and packets agree bit for bit. For output `o` of a
//! layer with inputs `x`: `p_c = Σ_{i ≡ c (mod C)} x_i W[i][o]` accumulated in ascending `i` (one FMA
//! each), `p_0` starting at the bias and the others at `+0`; then `y` is their sum as a balanced tree
//! of adjacent pairs (`(p_0 + p_1) + (p_2 + p_3)` for `C = 4`), then the ReLU `y > 0 ? y : +0` (0 for NaN, as
//! `vmaxps(y, 0)`). The output map is `expm1` as a vector polynomial (within 2.5e-7 relative of
//! `libm::expm1f`).
//!
//! - AVX-512, one query: lanes are outputs (a 21-wide layer is a 16-lane and an 8-lane vector, 8
//!   accumulators).
//! - AVX-512, a packet of [`TINY_PACKET`] queries: lanes are queries (activations stored
//!   neuron-major), the weights are broadcast from memory, 4 outputs × 4 chains = 16 accumulators per
//!   tile (the output layer: 3 × 8 = 24); no lane is wasted on padding (a 21-wide layer costs 21
//!   instead of 32 lanes per input).
//! - Other levels (AVX2, portable) run the layers through the generic kernels of their level
//!   (`Kernels::one` and `Kernels::packet`, one FMA chain per output; single queries and packets agree
//!   bit for bit there too) and `libm::expm1f`.

use crate::kernels::{detected, level, Dense, Level, Segment, Weight};

/// Widest layer the tiny kernels accept (a multiple of 8).
pub const TINY_MAX_WIDTH: usize = 64;

/// Queries per packet of [`TinyNet::packet`]: one AVX-512 vector of queries.
pub const TINY_PACKET: usize = 16;

/// Network inputs of a tiny network (the NBRDF-json input `[h, d]`).
pub const TINY_INPUTS: usize = 6;

/// The NBRDF-json network input `[ρ, 0, h_z, d_x, d_y, d_z]` of the pairs `(wi, wo)` in lanes `0..m`
/// (component-major: `wi[c][q]`), written to `x` (feature-major), with the same operations in the same
/// order as the scalar `nbrdf_json::input` (IEEE square root and division are exact-rounded in every
/// lane, so the bits agree). Returns `(valid, slow)` lane masks: `valid` pairs got their input;
/// `slow` pairs have a direction outside the one-division normalisation's range (or a non-AVX-512
/// level) and must be redone one by one with the scalar function; the rest are rejected (below
/// the horizon, degenerate, non-finite).
#[inline]
pub fn half_diff_packet(
    wi: &[[f32; TINY_PACKET]; 3],
    wo: &[[f32; TINY_PACKET]; 3],
    m: usize,
    x: &mut [[f32; TINY_PACKET]; TINY_INPUTS],
) -> (u16, u16) {
    let lanes = if m >= 16 { 0xffff } else { ((1u32 << m) - 1) as u16 };
    #[cfg(target_arch = "x86_64")]
    if level() == Level::Avx512 {
        // SAFETY: `level()` is at most the detected level, so the CPU has AVX-512.
        let (valid, slow) = unsafe { avx512::half_diff_packet(wi, wo, x) };
        return (valid & lanes, slow & lanes);
    }
    let _ = (wi, wo, x);
    (0, lanes)
}

/// One dense layer of a [`TinyNet`]: its matrix `[inputs][padded]` (outputs zero-padded to a multiple of
/// 8) starts at `offset` of the parameters, followed by the bias (`padded` values, zero-padded).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TinyLayer {
    /// Number of inputs.
    pub inputs: usize,
    /// Number of outputs.
    pub outputs: usize,
    /// `outputs` rounded up to a multiple of 8 (at most [`TINY_MAX_WIDTH`]).
    pub padded: usize,
    /// Offset of the matrix in the parameters.
    pub offset: usize,
    /// Apply ReLU.
    pub relu: bool,
}

/// A tiny network: layers over one parameter buffer, the first with [`TINY_INPUTS`] inputs, the last
/// with 3 outputs (RGB before `expm1`).
#[derive(Clone, Copy, Debug)]
pub struct TinyNet<'a> {
    /// The layers, input to output.
    pub layers: &'a [TinyLayer],
    /// The parameters of every layer (see [`TinyLayer`]).
    pub params: &'a [f32],
}

impl TinyNet<'_> {
    /// Checks every layer's extent and chaining once: the SIMD kernels read through raw pointers.
    fn check(&self) {
        let mut width = TINY_INPUTS;
        for l in self.layers {
            assert!(l.inputs == width, "layer inputs differ from the previous outputs");
            assert!(l.outputs <= l.padded && l.padded <= TINY_MAX_WIDTH && l.padded % 8 == 0, "bad padding");
            assert!(self.params.len() >= l.offset + (l.inputs + 1) * l.padded, "parameters out of bounds");
            width = l.outputs;
        }
        assert!(width == 3 && self.layers.last().is_some_and(|l| l.padded == 8), "the last layer has 3 outputs, padded to 8");
    }

    /// The NBRDF-json output of one input at the active kernel level: the network, then `expm1`,
    /// clamped by `max(·, 0)`, with non-finite values (an overflowing `expm1`) replaced by 0, as
    /// [`crate::math::sanitize`] does, without its branches on the AVX-512 level.
    #[inline]
    pub fn brdf(&self, x: &[f32; TINY_INPUTS]) -> [f32; 3] {
        self.single::<true>(level(), x)
    }

    /// One input at `level` (clamped to the detected level), then `expm1`, clamped if `CLAMP`.
    #[inline]
    fn single<const CLAMP: bool>(&self, level: Level, x: &[f32; TINY_INPUTS]) -> [f32; 3] {
        self.check();
        let level = level.min(detected());
        #[cfg(target_arch = "x86_64")]
        if level == Level::Avx512 {
            use core::arch::x86_64::*;
            // SAFETY: `level` is at most the detected level, so the CPU has AVX-512; `check` verified
            // every extent the kernel reads.
            let v = unsafe { avx512::one::<CLAMP>(self, x[0], x[1], x[2], x[3], x[4], x[5]) };
            // SAFETY: SSE, which these take, is part of x86_64.
            return unsafe {
                [_mm_cvtss_f32(v), _mm_cvtss_f32(_mm_shuffle_ps::<0x55>(v, v)), _mm_cvtss_f32(_mm_movehl_ps(v, v))]
            };
        }
        let y = generic_one(self, level, x);
        if CLAMP { crate::math::sanitize(y) } else { y }
    }

    /// The network, then `expm1` (not clamped), on [`TINY_PACKET`] inputs, each with the bits one input
    /// alone gets, feature-major: query `q`'s input is
    /// `x[..][q]`, its RGB goes to `out[..][q]`.
    #[inline]
    pub fn packet(&self, x: &[[f32; TINY_PACKET]; TINY_INPUTS], out: &mut [[f32; TINY_PACKET]; 3]) {
        self.packet_at(level(), x, out)
    }

    /// [`packet`](Self::packet) at `level` (clamped to the detected level).
    #[inline]
    fn packet_at(&self, level: Level, x: &[[f32; TINY_PACKET]; TINY_INPUTS], out: &mut [[f32; TINY_PACKET]; 3]) {
        self.check();
        let level = level.min(detected());
        #[cfg(target_arch = "x86_64")]
        if level == Level::Avx512 {
            // SAFETY: as in `one`.
            return unsafe { avx512::packet(self, x, out) };
        }
        let mut a = [0.0f32; TINY_PACKET * W];
        let mut b = [0.0f32; TINY_PACKET * W];
        for (f, x) in x.iter().enumerate() {
            for (q, v) in x.iter().enumerate() {
                a[q * W + f] = *v;
            }
        }
        generic::<TINY_PACKET>(self, level, &mut a, &mut b);
        for (c, o) in out.iter_mut().enumerate() {
            for (q, o) in o.iter_mut().enumerate() {
                *o = libm::expm1f(a[q * W + c]);
            }
        }
    }
}

/// Widest layer of the generic path: `TINY_MAX_WIDTH` floats per query.
const W: usize = TINY_MAX_WIDTH;

/// The network on `Q` queries (`x[q * W..][..6]`) through the generic layer kernels of `level`
/// (`Kernels::one` for `Q = 1`, `Kernels::packet` for `Q = TINY_PACKET`, which agree bit for bit),
/// leaving the last layer's outputs at `x[q * W..][..3]`.
#[inline(always)]
fn generic<const Q: usize>(net: &TinyNet<'_>, level: Level, x: &mut [f32], y: &mut [f32]) {
    let k = <f32 as Weight>::table(level);
    let (mut a, mut b) = (x, y);
    for l in net.layers {
        let (n_in, n_out) = (l.inputs, l.padded);
        let w = &net.params[l.offset..l.offset + (n_in + 1) * n_out];
        let seg = Segment { x: &a[..], stride: W, n: n_in, rows: &w[..n_in * n_out] };
        let dense = Dense {
            init: &w[n_in * n_out..],
            segs: [seg, Segment { x: &[], stride: 0, n: 0, rows: &[] }],
            n_segs: 1,
            n_out,
            relu: l.relu,
        };
        if Q == 1 {
            k.one(&dense, &mut b[..n_out]);
        } else {
            k.packet(&dense, b, W);
        }
        core::mem::swap(&mut a, &mut b);
    }
    // An even number of layers leaves the result in `x` itself; copy it there otherwise.
    if net.layers.len() % 2 == 1 {
        for q in 0..Q {
            b[q * W..q * W + 3].copy_from_slice(&a[q * W..q * W + 3]);
        }
    }
}

/// One input through the generic kernels (below AVX-512), then `expm1`.
fn generic_one(net: &TinyNet<'_>, level: Level, input: &[f32; TINY_INPUTS]) -> [f32; 3] {
    let mut x = [0.0f32; W];
    let mut y = [0.0f32; W];
    x[..TINY_INPUTS].copy_from_slice(input);
    generic::<1>(net, level, &mut x, &mut y);
    [libm::expm1f(x[0]), libm::expm1f(x[1]), libm::expm1f(x[2])]
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use core::arch::x86_64::*;
    use core::mem::MaybeUninit;

    use super::{TinyNet, TINY_INPUTS, TINY_MAX_WIDTH, TINY_PACKET};

    /// `expm1` of every lane: `x = k ln 2 + r` with `|r| ≤ ln 2 / 2` (`k ≤ 127`, so up to the f32
    /// overflow at 88.72 `r` stays below 0.7), `expm1(r)` by its Taylor series to degree 9 (relative
    /// error below 1e-7 on that range), then `expm1(x) = 2^k expm1(r) + (2^k - 1)`, which does not
    /// cancel: for `k ≠ 0`, `|expm1(x)| > 0.29`. `vscalefps` multiplies by `2^k` exactly and overflows
    /// to infinity where `expm1f` does; `k = 0` returns `expm1(r)` itself, accurate near 0.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn expm1(x: __m512) -> __m512 {
        let k = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(_mm512_mul_ps(
            x,
            _mm512_set1_ps(core::f32::consts::LOG2_E),
        ));
        let k = _mm512_min_ps(k, _mm512_set1_ps(127.0));
        // ln 2 split in a part with trailing zero bits (k ln2_hi is exact for |k| < 2^8) and the rest.
        let r = _mm512_fnmadd_ps(k, _mm512_set1_ps(0.693_145_75), x);
        let r = _mm512_fnmadd_ps(k, _mm512_set1_ps(1.428_606_8e-6), r);
        // expm1(r) = r + r² q(r), q(r) = Σ_j r^j / (j + 2)!, j ≤ 7, by Estrin's scheme (three FMA levels
        // instead of a chain of seven: the single-query path waits on this latency).
        let c = |v: f32| _mm512_set1_ps(v);
        let r2 = _mm512_mul_ps(r, r);
        let r4 = _mm512_mul_ps(r2, r2);
        let a0 = _mm512_fmadd_ps(c(1.0 / 6.0), r, c(1.0 / 2.0));
        let a1 = _mm512_fmadd_ps(c(1.0 / 120.0), r, c(1.0 / 24.0));
        let a2 = _mm512_fmadd_ps(c(1.0 / 5040.0), r, c(1.0 / 720.0));
        let a3 = _mm512_fmadd_ps(c(1.0 / 362_880.0), r, c(1.0 / 40320.0));
        let b0 = _mm512_fmadd_ps(a1, r2, a0);
        let b1 = _mm512_fmadd_ps(a3, r2, a2);
        let q = _mm512_fmadd_ps(b1, r4, b0);
        let p = _mm512_fmadd_ps(r2, q, r);
        let one = _mm512_set1_ps(1.0);
        _mm512_add_ps(_mm512_scalef_ps(p, k), _mm512_sub_ps(_mm512_scalef_ps(one, k), one))
    }

    /// [`expm1`] for the tests.
    #[cfg(test)]
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) fn expm1_for_test(x: __m512) -> __m512 {
        expm1(x)
    }

    /// `v / |v|` for the lanes with `|v|²` near 1 or in the fast range (the first two rules of `angles::unit`),
    /// and the mask of those lanes.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn unit_fast(v: [__m512; 3]) -> ([__m512; 3], __mmask16) {
        let [x, y, z] = v;
        let l2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(x, x), _mm512_mul_ps(y, y)), _mm512_mul_ps(z, z));
        let one = _mm512_set1_ps(1.0);
        // Ordered comparisons: false for NaN.
        let near = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(_mm512_sub_ps(l2, one)), _mm512_set1_ps(crate::angles::UNIT_TAYLOR));
        let ok = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(l2, _mm512_set1_ps(crate::angles::UNIT_FAST_MIN))
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(l2, _mm512_set1_ps(crate::angles::UNIT_FAST_MAX));
        let taylor = _mm512_sub_ps(_mm512_set1_ps(1.5), _mm512_mul_ps(_mm512_set1_ps(0.5), l2));
        // The square root and division only where some lane needs them (never, for a renderer's unit
        // directions).
        let s = if near == 0xffff {
            taylor
        } else {
            _mm512_mask_mov_ps(_mm512_div_ps(one, _mm512_sqrt_ps(l2)), near, taylor)
        };
        ([_mm512_mul_ps(x, s), _mm512_mul_ps(y, s), _mm512_mul_ps(z, s)], near | ok)
    }

    /// See `super::half_diff_packet`: returns `(valid, slow)` for all 16 lanes.
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe fn half_diff_packet(
        wi: &[[f32; TINY_PACKET]; 3],
        wo: &[[f32; TINY_PACKET]; 3],
        out: &mut [[f32; TINY_PACKET]; TINY_INPUTS],
    ) -> (u16, u16) {
        // SAFETY: every array holds 16 values per row.
        let ld = |v: &[f32; TINY_PACKET]| unsafe { _mm512_loadu_ps(v.as_ptr()) };
        let (i, i_ok) = unit_fast([ld(&wi[0]), ld(&wi[1]), ld(&wi[2])]);
        let (o, o_ok) = unit_fast([ld(&wo[0]), ld(&wo[1]), ld(&wo[2])]);
        let fast = i_ok & o_ok;
        let zero = _mm512_setzero_ps();
        let above = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(i[2], zero) & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(o[2], zero);
        let (hx, hy, hz) = (_mm512_add_ps(i[0], o[0]), _mm512_add_ps(i[1], o[1]), _mm512_add_ps(i[2], o[2]));
        let q = _mm512_add_ps(_mm512_mul_ps(hx, hx), _mm512_mul_ps(hy, hy));
        let one = _mm512_set1_ps(1.0);
        let inv_len = _mm512_div_ps(one, _mm512_sqrt_ps(_mm512_add_ps(q, _mm512_mul_ps(hz, hz))));
        let cos_h = _mm512_mul_ps(hz, inv_len);
        let pos = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(q, zero);
        let r = _mm512_sqrt_ps(q);
        let inv_r = _mm512_div_ps(one, r);
        let a = _mm512_add_ps(_mm512_mul_ps(hx, i[0]), _mm512_mul_ps(hy, i[1]));
        let b = _mm512_sub_ps(_mm512_mul_ps(hx, i[1]), _mm512_mul_ps(hy, i[0]));
        let dx = _mm512_mul_ps(
            _mm512_mul_ps(inv_len, inv_r),
            _mm512_sub_ps(_mm512_mul_ps(hz, a), _mm512_mul_ps(q, i[2])),
        );
        let dz = _mm512_mul_ps(inv_len, _mm512_add_ps(a, _mm512_mul_ps(hz, i[2])));
        // `h_xy = 0`: `d` is `wi` rotated by `-θh` alone (see `nbrdf_json::input`).
        let v = [
            _mm512_maskz_mov_ps(pos, _mm512_mul_ps(r, inv_len)),
            zero,
            cos_h,
            _mm512_mask_mov_ps(_mm512_mul_ps(cos_h, i[0]), pos, dx),
            _mm512_mask_mov_ps(i[1], pos, _mm512_mul_ps(b, inv_r)),
            _mm512_mask_mov_ps(_mm512_mul_ps(cos_h, i[2]), pos, dz),
        ];
        // Finite: |v| ≤ MAX (false for NaN and infinity).
        let max = _mm512_set1_ps(f32::MAX);
        let mut finite = 0xffff;
        for (o, v) in out.iter_mut().zip(v) {
            finite &= _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(v), max);
            // SAFETY: `o` holds 16 values.
            unsafe { _mm512_storeu_ps(o.as_mut_ptr(), v) };
        }
        (fast & above & finite, !fast)
    }

    /// `Σ p_c` of `C` (a power of two) chains as a balanced tree of adjacent pairs, `(p_0 + p_1) +
    /// (p_2 + p_3)` for 4: the order the single and the packet kernels share.
    #[inline(always)]
    fn tree<T: Copy, const C: usize>(mut p: [T; C], add: impl Fn(T, T) -> T) -> T {
        let mut n = C;
        while n > 1 {
            for j in 0..n / 2 {
                p[j] = add(p[2 * j], p[2 * j + 1]);
            }
            n /= 2;
        }
        p[0]
    }

    /// One layer for one query, lanes = outputs: `K` 16-lane vectors of outputs and, with `H`, one
    /// 8-lane vector more (a 21-wide layer is 16 + 8 lanes: on Zen 4 a 256-bit FMA costs half a
    /// 512-bit one, so padding to 8 instead of 16 saves a quarter of the FMA work), `C` chains each;
    /// writes `16 K + 8 H` values (the padding lanes: `0`, or ReLU of `0`) to `y`.
    ///
    /// # Safety
    /// `x` holds `n` inputs, `w` a matrix `[n][16 K + 8 H]` followed by as many biases, `y` room for
    /// `16 K + 8 H` values.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn layer_one<const K: usize, const H: bool, const C: usize>(
        x: impl Fn(usize) -> f32,
        n: usize,
        w: *const f32,
        y: *mut f32,
        relu: bool,
    ) -> __m512 {
        let stride = 16 * K + if H { 8 } else { 0 };
        // SAFETY (whole body): reads `x[..n]`, `w[..(n + 1) stride]`, writes `y[..stride]` (contract).
        unsafe {
            let zero = _mm512_setzero_ps();
            let zero8 = _mm256_setzero_ps();
            let bias = w.add(n * stride);
            let mut acc: [[__m512; K]; C] = [[zero; K]; C];
            let mut acc8: [__m256; C] = [zero8; C];
            for (k, a) in acc[0].iter_mut().enumerate() {
                *a = _mm512_loadu_ps(bias.add(16 * k));
            }
            if H {
                acc8[0] = _mm256_loadu_ps(bias.add(16 * K));
            }
            macro_rules! step {
                ($c:expr, $i:expr) => {{
                    let (c, i) = ($c, $i);
                    let xi = x(i);
                    let xb = _mm512_set1_ps(xi);
                    let r = w.add(i * stride);
                    for (k, a) in acc[c].iter_mut().enumerate() {
                        *a = _mm512_fmadd_ps(xb, _mm512_loadu_ps(r.add(16 * k)), *a);
                    }
                    if H {
                        acc8[c] = _mm256_fmadd_ps(_mm256_set1_ps(xi), _mm256_loadu_ps(r.add(16 * K)), acc8[c]);
                    }
                }};
            }
            let mut i = 0;
            while i + C <= n {
                for c in 0..C {
                    step!(c, i + c);
                }
                i += C;
            }
            for c in 0..n - i {
                step!(c, i + c);
            }
            let mut first = zero;
            #[allow(clippy::needless_range_loop)] // `k` picks the same vector from every chain.
            for k in 0..K {
                let v = tree(core::array::from_fn::<_, C, _>(|c| acc[c][k]), |a, b| _mm512_add_ps(a, b));
                let v = if relu { _mm512_max_ps(v, zero) } else { v };
                _mm512_storeu_ps(y.add(16 * k), v);
                if k == 0 {
                    first = v;
                }
            }
            if H {
                let v = tree(acc8, |a, b| _mm256_add_ps(a, b));
                let v = if relu { _mm256_max_ps(v, zero8) } else { v };
                _mm256_storeu_ps(y.add(16 * K), v);
                if K == 0 {
                    first = _mm512_zextps256_ps512(v);
                }
            }
            first
        }
    }

    /// The network and `expm1` for one query, clamped as `TinyNet::brdf` where `CLAMP`, in the low
    /// three lanes of the result.
    ///
    /// The inputs arrive in registers and the result leaves in one (the C ABI; the Rust ABI would
    /// pass the array through memory and return it there). What goes through memory is written
    /// no narrower than it is read: a load that spans several smaller stores cannot be forwarded
    /// from them and waits until they retire, which serialises consecutive queries (with
    /// `math::load_pair` in the caller, 0.89x the time of `nbrdf-json/eval` in `benches/eval.rs`).
    ///
    /// # Safety
    /// The CPU has AVX-512F; `net` passed `TinyNet::check`.
    #[allow(improper_ctypes_definitions, clippy::too_many_arguments)] // Only called from Rust.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe extern "C" fn one<const CLAMP: bool>(
        net: &TinyNet<'_>,
        x0: f32,
        x1: f32,
        x2: f32,
        x3: f32,
        x4: f32,
        x5: f32,
    ) -> __m128 {
        // Activations ping-pong between two buffers, not zeroed (a layer reads only the `inputs` values
        // the previous one wrote).
        let mut a = [MaybeUninit::<f32>::uninit(); TINY_MAX_WIDTH];
        let mut b = [MaybeUninit::<f32>::uninit(); TINY_MAX_WIDTH];
        let (mut x, mut y) = (a.as_mut_ptr().cast::<f32>(), b.as_mut_ptr().cast::<f32>());
        let input = [x0, x1, x2, x3, x4, x5];
        // SAFETY: the buffers hold 64 values; `check` verified `(inputs + 1) padded` parameters from each
        // `offset`, `padded ≤ 64`, and each layer's inputs are the previous layer's outputs.
        unsafe {
            // A layer with `K` 16-lane and `H` 8-lane vectors of outputs in `C` chains; the first
            // broadcasts the network inputs from their registers (`check`: it has `TINY_INPUTS` inputs;
            // a constant count unrolls the loop), the others read the previous layer's buffer.
            macro_rules! run {
                ($first:expr, $l:expr, $k:literal, $h:literal, $c:literal) => {{
                    let l = $l;
                    let w = net.params.as_ptr().add(l.offset);
                    if $first {
                        layer_one::<$k, $h, $c>(|i| input[i], TINY_INPUTS, w, y, l.relu)
                    } else {
                        let x = x as *const f32;
                        layer_one::<$k, $h, $c>(|i| *x.add(i), l.inputs, w, y, l.relu)
                    }
                }};
            }
            // `check`: at least one layer, the last with 3 outputs padded to 8.
            let (hidden, output) = net.layers.split_at(net.layers.len() - 1);
            for (j, l) in hidden.iter().enumerate() {
                match l.padded {
                    8 => run!(j == 0, l, 0, true, 4),
                    16 => run!(j == 0, l, 1, false, 4),
                    24 => run!(j == 0, l, 1, true, 4),
                    32 => run!(j == 0, l, 2, false, 4),
                    40 => run!(j == 0, l, 2, true, 4),
                    48 => run!(j == 0, l, 3, false, 4),
                    56 => run!(j == 0, l, 3, true, 4),
                    64 => run!(j == 0, l, 4, false, 4),
                    // A layer without outputs (the next one has no inputs).
                    _ => _mm512_setzero_ps(),
                };
                core::mem::swap(&mut x, &mut y);
            }
            let last = run!(hidden.is_empty(), &output[0], 0, true, 8);
            let v = expm1(last);
            _mm512_castps512_ps128(if CLAMP { clamp(v) } else { v })
        }
    }

    /// `v` where `0 < v < ∞`, else 0 (NaN included), per lane: `math::sanitize` without branches.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn clamp(v: __m512) -> __m512 {
        let keep = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(v, _mm512_setzero_ps())
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v, _mm512_set1_ps(f32::INFINITY));
        _mm512_maskz_mov_ps(keep, v)
    }

    /// Outputs `o0 .. o0 + J` of one layer for a packet, lanes = queries, in `C` chains each: `x` and
    /// `y` are neuron-major (`x[i]` holds input `i` of the 16 queries).
    ///
    /// # Safety
    /// `x` holds `n` vectors, `w` a matrix `[n][stride]` followed by the bias, `o0 + J ≤ stride`,
    /// `y` room for `o0 + J` vectors.
    #[inline]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn packet_tile<const J: usize, const C: usize>(
        x: *const __m512,
        n: usize,
        w: *const f32,
        stride: usize,
        o0: usize,
        y: *mut __m512,
        relu: bool,
    ) {
        // SAFETY (whole body): within the extents of the contract.
        unsafe {
            let zero = _mm512_setzero_ps();
            let w = w.add(o0);
            let mut acc: [[__m512; C]; J] = [[zero; C]; J];
            for (j, a) in acc.iter_mut().enumerate() {
                a[0] = _mm512_set1_ps(*w.add(n * stride + j));
            }
            let mut i = 0;
            while i + C <= n {
                for c in 0..C {
                    let xv = *x.add(i + c);
                    let r = w.add((i + c) * stride);
                    for (j, a) in acc.iter_mut().enumerate() {
                        a[c] = _mm512_fmadd_ps(xv, _mm512_set1_ps(*r.add(j)), a[c]);
                    }
                }
                i += C;
            }
            for c in 0..n - i {
                let xv = *x.add(i + c);
                let r = w.add((i + c) * stride);
                for (j, a) in acc.iter_mut().enumerate() {
                    a[c] = _mm512_fmadd_ps(xv, _mm512_set1_ps(*r.add(j)), a[c]);
                }
            }
            for (j, a) in acc.iter().enumerate() {
                let v = tree(*a, |a, b| _mm512_add_ps(a, b));
                *y.add(o0 + j) = if relu { _mm512_max_ps(v, zero) } else { v };
            }
        }
    }

    /// The network and `expm1` for a packet of 16 queries.
    ///
    /// # Safety
    /// As `one`.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe fn packet(
        net: &TinyNet<'_>,
        input: &[[f32; TINY_PACKET]; TINY_INPUTS],
        out: &mut [[f32; TINY_PACKET]; 3],
    ) {
        // Neuron-major activations, not zeroed (as in `one`).
        let mut a = [MaybeUninit::<__m512>::uninit(); TINY_MAX_WIDTH];
        let mut b = [MaybeUninit::<__m512>::uninit(); TINY_MAX_WIDTH];
        let (mut x, mut y) = (a.as_mut_ptr().cast::<__m512>(), b.as_mut_ptr().cast::<__m512>());
        // SAFETY: as in `one`; tiles stay below `outputs ≤ 64` vectors, each layer reads the `inputs`
        // vectors the previous one wrote.
        unsafe {
            for (f, v) in input.iter().enumerate() {
                x.add(f).write(_mm512_loadu_ps(v.as_ptr()));
            }
            // `check`: at least one layer, the last with 3 outputs.
            let (hidden, output) = net.layers.split_at(net.layers.len() - 1);
            for l in hidden {
                let w = net.params.as_ptr().add(l.offset);
                let mut o = 0;
                while o + 4 <= l.outputs {
                    packet_tile::<4, 4>(x, l.inputs, w, l.padded, o, y, l.relu);
                    o += 4;
                }
                match l.outputs - o {
                    1 => packet_tile::<1, 4>(x, l.inputs, w, l.padded, o, y, l.relu),
                    2 => packet_tile::<2, 4>(x, l.inputs, w, l.padded, o, y, l.relu),
                    3 => packet_tile::<3, 4>(x, l.inputs, w, l.padded, o, y, l.relu),
                    _ => {}
                }
                core::mem::swap(&mut x, &mut y);
            }
            let l = &output[0];
            packet_tile::<3, 8>(x, l.inputs, net.params.as_ptr().add(l.offset), l.padded, 0, y, l.relu);
            core::mem::swap(&mut x, &mut y);
            for (c, o) in out.iter_mut().enumerate() {
                _mm512_storeu_ps(o.as_mut_ptr(), expm1(*x.add(c)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;
    use alloc::vec::Vec;

    /// xorshift, values in [-0.5, 0.5).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        }
        /// A multiple of `1 / scale` in `[-0.5, 0.5) · range`.
        fn dyadic(&mut self, range: f32, scale: f32) -> f32 {
            libm::roundf(self.next() * range) / scale
        }
    }

    /// A network of the given widths: weights dyadic (multiples of 1/64) and inputs dyadic, so that
    /// the first layer's pre-activations are exact; the bias of every third output of the first layer
    /// is chosen to make its pre-activation at `zero_at` exactly 0.
    fn network(widths: &[usize], rng: &mut Rng, zero_at: &[f32; TINY_INPUTS]) -> (Vec<TinyLayer>, Vec<f32>) {
        let mut layers = Vec::new();
        let mut params = Vec::new();
        let mut x: Vec<f64> = zero_at.iter().map(|v| *v as f64).collect();
        for (l, w) in widths.windows(2).enumerate() {
            let (n_in, n_out) = (w[0], w[1]);
            let padded = n_out.div_ceil(8) * 8;
            let offset = params.len();
            params.resize(offset + (n_in + 1) * padded, 0.0);
            let relu = l + 2 < widths.len();
            let mut y = vec![0.0f64; n_out];
            for (o, y) in y.iter_mut().enumerate() {
                let mut s = 0.0f64;
                for (i, xi) in x.iter().enumerate() {
                    let v = rng.dyadic(64.0, 64.0);
                    params[offset + i * padded + o] = v;
                    s += v as f64 * xi;
                }
                let b = if l == 0 && o % 3 == 1 { -s as f32 } else { rng.dyadic(16.0, 64.0) };
                assert!(b as f64 == -s || !(l == 0 && o % 3 == 1), "the zero bias is exact");
                params[offset + n_in * padded + o] = b;
                *y = if relu { (s + b as f64).max(0.0) } else { s + b as f64 };
            }
            layers.push(TinyLayer { inputs: n_in, outputs: n_out, padded, offset, relu });
            x = y;
        }
        (layers, params)
    }

    /// The network in f64, then `expm1`.
    fn reference(layers: &[TinyLayer], params: &[f32], input: &[f32; TINY_INPUTS]) -> [f64; 3] {
        let mut x: Vec<f64> = input.iter().map(|v| *v as f64).collect();
        for l in layers {
            x = (0..l.outputs)
                .map(|o| {
                    let mut s = params[l.offset + l.inputs * l.padded + o] as f64;
                    for (i, xi) in x.iter().enumerate() {
                        s += xi * params[l.offset + i * l.padded + o] as f64;
                    }
                    if l.relu { s.max(0.0) } else { s }
                })
                .collect();
        }
        [libm::expm1(x[0]), libm::expm1(x[1]), libm::expm1(x[2])]
    }

    /// At every level the host runs: one query matches an f64 reference, the clamped output is
    /// `sanitize` of it bit for bit, and a packet gives each query the bits of one query.
    #[test]
    fn tiny_networks_match_a_scalar_reference_and_packets_match_single_queries() {
        let mut rng = Rng(0x2545f4914f6cdd1d);
        for widths in [&[6, 21, 21, 3][..], &[6, 3], &[6, 8, 3], &[6, 64, 17, 40, 3], &[6, 2, 3], &[6, 33, 3]] {
            // Dyadic inputs: the first one makes some pre-activations exactly zero.
            let inputs: Vec<[f32; TINY_INPUTS]> =
                (0..TINY_PACKET * 3).map(|_| core::array::from_fn(|_| rng.dyadic(64.0, 32.0))).collect();
            let (layers, params) = network(widths, &mut rng, &inputs[0]);
            let net = TinyNet { layers: &layers, params: &params };
            for level in Level::usable() {
                for chunk in inputs.chunks(TINY_PACKET) {
                    let x: [[f32; TINY_PACKET]; TINY_INPUTS] = core::array::from_fn(|f| core::array::from_fn(|q| chunk[q][f]));
                    let mut packet = [[f32::NAN; TINY_PACKET]; 3];
                    net.packet_at(level, &x, &mut packet);
                    for (q, input) in chunk.iter().enumerate() {
                        let got = net.single::<false>(level, input);
                        let clamped = net.single::<true>(level, input);
                        assert_eq!(clamped.map(f32::to_bits), crate::math::sanitize(got).map(f32::to_bits));
                        let want = reference(&layers, &params, input);
                        for c in 0..3 {
                            assert_eq!(got[c].to_bits(), packet[c][q].to_bits(), "{level:?} {widths:?}: single vs packet");
                            let tol = 1e-5 * want[c].abs().max(0.05);
                            assert!((got[c] as f64 - want[c]).abs() <= tol, "{level:?} {widths:?} q {q} c {c}: {} vs {}", got[c], want[c]);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn vector_expm1_is_within_two_ulp_of_libm() {
        #[cfg(target_arch = "x86_64")]
        if crate::kernels::detected() != Level::Avx512 {
            crate::kernels::skipped("the vector expm1", Level::Avx512);
        }
        #[cfg(target_arch = "x86_64")]
        if crate::kernels::detected() == Level::Avx512 {
            use core::arch::x86_64::*;
            let mut x = -30.0f32;
            while x < 89.0 {
                let xs: [f32; 16] = core::array::from_fn(|i| x + i as f32 * 1.3e-3);
                let mut got = [0.0f32; 16];
                // SAFETY: AVX-512F was detected; both arrays hold 16 values.
                unsafe { _mm512_storeu_ps(got.as_mut_ptr(), avx512::expm1_for_test(_mm512_loadu_ps(xs.as_ptr()))) };
                for (x, g) in xs.iter().zip(got) {
                    let want = libm::expm1(*x as f64);
                    if want > f32::MAX as f64 {
                        continue;
                    }
                    assert!(((g as f64 - want) / want).abs() < 2.5e-7 || (g as f64 - want).abs() < 1e-44, "expm1({x}) = {g}, want {want}");
                }
                x += 0.0517;
            }
        }
    }
}
