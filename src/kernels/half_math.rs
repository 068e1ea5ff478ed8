//! Dense layers of half weights in half-precision arithmetic (x86-64 AVX512-FP16), every multiply-add
//! in f16: a packet kernel (`PACKET` queries through one hidden layer), a one-query kernel, and a
//! chain (one query through a 128-wide network's hidden layers).
//!
//! An f16 multiply-add covers 32 lanes where an f32 one covers 16, so a core does twice the work per
//! instruction: the way past the f32 FMA rate, which bounds the f32 packet kernels (`docs/speed.md`),
//! and half the bytes a single query streams from cache. The price is accuracy, and it is the
//! caller's choice ([`crate::model::Model::eval_many_half`], [`crate::model::Model::eval_half`]): every
//! product and partial sum is rounded to f16 (11 significant bits, largest finite value 65504; the
//! rounding of the MXCSR, to nearest unless the caller changed it). Inputs and starting accumulators
//! are rounded to f16 on the way in, results widened to f32 on the way out (ReLU after widening), so
//! layers still hand each other f32 values and the output layer (3 or 6 outputs, no ReLU) stays with
//! the f32 kernels.
//!
//! Packet tile: the 16 queries × 32 outputs (one vector of halves each) in 16 accumulators; per input
//! row one weight vector and 16 multiply-adds whose input is broadcast from a transposed copy of the
//! inputs (`vfmadd231ph m16{1to32}`, one fused micro-op on Intel cores), as the f32 tile. One query:
//! its nonzero inputs gathered with their row offsets (`x86::compress`), 4 vectors of 32 outputs per
//! row, the rows alternating between two sets of accumulators.

use core::arch::x86_64::*;

use super::x86::{compress, compress8, mask16, passes, transpose_columns, Piece, XT_CAP};
use super::{Chain, Dense, Init, CHAIN_TAIL_MAX, CHAIN_WIDTH, PACKET};

/// Outputs per register tile: one vector of halves.
const TILE: usize = 32;

/// f32 → f16 rounding: to nearest, ties to even, no exceptions.
const ROUND: i32 = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;

/// Whether the CPU has AVX512-FP16 (with the AVX-512 base the tile needs): detected once with
/// `std`, the compile-time target features without it.
pub(super) fn available() -> bool {
    #[cfg(feature = "std")]
    {
        use core::sync::atomic::{AtomicU8, Ordering};
        static HAS: AtomicU8 = AtomicU8::new(0);
        match HAS.load(Ordering::Relaxed) {
            0 => {
                let has = std::is_x86_feature_detected!("avx512fp16")
                    && std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512bw")
                    && std::is_x86_feature_detected!("avx512vl");
                HAS.store(if has { 2 } else { 1 }, Ordering::Relaxed);
                has
            }
            v => v == 2,
        }
    }
    #[cfg(not(feature = "std"))]
    {
        cfg!(all(
            target_feature = "avx512fp16",
            target_feature = "avx512f",
            target_feature = "avx512bw",
            target_feature = "avx512vl"
        ))
    }
}

/// Writes inputs `x[q * stride + i]`, `i < n`, of the `PACKET` queries feature-major to
/// `xt[i * PACKET + q]`, rounded to f16 (to nearest, ties to even): the f32 kernel's transpose, then
/// one conversion per column.
///
/// # Safety
/// Each query's `n` inputs are readable from `x + q * stride`; `xt` has room for `n * PACKET` values.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn transpose_inputs(x: *const f32, stride: usize, n: usize, xt: *mut u16) {
    // SAFETY: column `i < n` goes to `xt[i * PACKET..]`, within the room (contract).
    unsafe {
        transpose_columns(x, stride, n, |i, c| {
            let h = _mm512_cvtps_ph::<ROUND>(c);
            _mm256_storeu_si256(xt.add(i * PACKET).cast::<__m256i>(), h);
        })
    }
}

/// 32 f32 values from `p` (lanes outside `m` zero) rounded to one vector of halves.
///
/// # Safety
/// The lanes in `m` are readable from `p`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn load_rounded(p: *const f32, m: __mmask32) -> __m512i {
    // SAFETY: masked loads read only the lanes in `m` (contract).
    unsafe {
        let lo = _mm512_cvtps_ph::<ROUND>(_mm512_maskz_loadu_ps(m as __mmask16, p));
        let hi = _mm512_cvtps_ph::<ROUND>(_mm512_maskz_loadu_ps((m >> 16) as __mmask16, p.add(16)));
        _mm512_inserti64x4::<1>(_mm512_castsi256_si512(lo), hi)
    }
}

/// A vector of halves widened to f32, lanes 0..16 and 16..32, after ReLU where `relu`.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
fn widen(a: __m512h, relu: bool) -> [__m512; 2] {
    let a = _mm512_castph_si512(a);
    let v = [_mm512_cvtph_ps(_mm512_castsi512_si256(a)), _mm512_cvtph_ps(_mm512_extracti64x4_epi64::<1>(a))];
    if relu { v.map(|v| _mm512_max_ps(v, _mm512_setzero_ps())) } else { v }
}

/// Stores the lanes of `m` of a vector of halves, widened to f32 (after ReLU where `relu`), at `p`.
///
/// # Safety
/// The lanes in `m` are writable at `p`.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn store_widened(p: *mut f32, m: __mmask32, a: __m512h, relu: bool) {
    let [lo, hi] = widen(a, relu);
    // SAFETY: masked stores write only the lanes in `m` (contract).
    unsafe {
        _mm512_mask_storeu_ps(p, m as __mmask16, lo);
        _mm512_mask_storeu_ps(p.add(16), (m >> 16) as __mmask16, hi);
    }
}

/// Outputs `o .. o + 32` (the lanes of `m`) of the packet over the pieces in `xt`, starting from
/// `init` (the first pass) or from the partial sums in `out`; ReLU where `relu`.
///
/// # Safety
/// `xt` holds the inputs of every piece (`PACKET` halves each, feature-major); each piece's rows hold
/// `n_out` halves per input; `out` and `init` as in `Dense::check`; `m` masks the valid outputs from `o`.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
#[allow(clippy::too_many_arguments)]
unsafe fn tile<const MASKED: bool>(
    l: &Dense<'_, half::f16>,
    xt: *const u16,
    pieces: &[Piece<half::f16>],
    first: bool,
    relu: bool,
    out: *mut f32,
    os: usize,
    o: usize,
    m: __mmask32,
) {
    let n = l.n_out;
    // SAFETY (whole body): query `q < PACKET` at `q * os` of the outputs, lanes in `m` only; every
    // input read lies in `xt`'s listed pieces, every row in its checked segment (contract).
    unsafe {
        let mut acc: [__m512h; PACKET] = if first {
            [_mm512_castsi512_ph(load_rounded(l.init.as_ptr().add(o), m)); PACKET]
        } else {
            core::array::from_fn(|q| _mm512_castsi512_ph(load_rounded(out.add(q * os + o), m)))
        };
        for piece in pieces {
            // Moving pointers, as in the f32 tile: the broadcasts address `x + 2q`.
            let mut x = xt.add(piece.start * PACKET);
            let mut r = piece.rows.cast::<u16>().add(o);
            for _ in 0..piece.n {
                let w = _mm512_castsi512_ph(if MASKED {
                    _mm512_maskz_loadu_epi16(m, r.cast::<i16>())
                } else {
                    _mm512_loadu_si512(r.cast::<__m512i>())
                });
                for (q, a) in acc.iter_mut().enumerate() {
                    let xb = _mm512_castsi512_ph(_mm512_set1_epi16(*x.add(q) as i16));
                    *a = _mm512_fmadd_ph(xb, w, *a);
                }
                x = x.add(PACKET);
                r = r.add(n);
            }
        }
        for (q, a) in acc.iter().enumerate() {
            store_widened(out.add(q * os + o), m, *a, relu);
        }
    }
}

/// `PACKET` queries through the layer in f16 arithmetic, every input row.
///
/// # Safety
/// The CPU has AVX512-FP16, F, BW and VL ([`available`]); the layer passed `check(PACKET, ..)`.
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) unsafe fn packet(l: &Dense<'_, half::f16>, out: *mut f32, os: usize) {
    let n = l.n_out;
    let mut xt = [core::mem::MaybeUninit::<__m256i>::uninit(); XT_CAP];
    let xt = xt.as_mut_ptr().cast::<u16>();
    let tiles = |pieces: &[Piece<half::f16>], first: bool, last: bool| {
        let relu = last && l.relu;
        let mut o = 0;
        // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest masked);
        // the pieces lie in `xt` and in their checked segments.
        unsafe {
            while o + TILE <= n {
                tile::<false>(l, xt, pieces, first, relu, out, os, o, u32::MAX);
                o += TILE;
            }
            if o < n {
                tile::<true>(l, xt, pieces, first, relu, out, os, o, (1u32 << (n - o)) - 1);
            }
        }
    };
    // A longer layer passes its partial sums through `out` (rounded to f16 again when they are read
    // back: exact, they are halves already).
    // SAFETY: `passes` hands out inputs of checked segments, `xt` rows below `XT_CAP`.
    unsafe {
        passes(l, |x, stride, c, used| transpose_inputs(x, stride, c, xt.add(used * PACKET)), tiles);
    }
}

/// Inputs gathered per step of [`one`]: the nonzero values of up to this many inputs of a segment
/// (and their row offsets) on the stack.
const GATHER: usize = 256;

/// Outputs per pass of [`one`]: 4 vectors of halves.
const ONE_TILE: usize = 128;

/// One query through the layer in f16 arithmetic: its nonzero inputs (half of the activations after
/// a ReLU, and every nonzero encoded angle) gathered with their row offsets, then per gathered input
/// one multiply-add per vector of 32 outputs. A single query streams its weight rows from L2 (see
/// `docs/speed.md`); half weights and no widening halve the bytes and the instructions per row.
///
/// # Safety
/// The CPU has AVX512-FP16, F, BW and VL ([`available`]); the layer passed `check(1, ..)`.
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) unsafe fn one(l: &Dense<'_, half::f16>, out: *mut f32) {
    let n = l.n_out;
    let mut o = 0;
    // SAFETY: each tile stays below `n_out` (full tiles by the loop bound, the rest masked).
    unsafe {
        while o + ONE_TILE <= n {
            one_tile::<false>(l, out, o, [u32::MAX; 4]);
            o += ONE_TILE;
        }
        if o < n {
            let rem = n - o;
            let m = core::array::from_fn(|k| match rem.saturating_sub(32 * k) {
                0 => 0,
                r if r >= 32 => u32::MAX,
                r => (1u32 << r) - 1,
            });
            one_tile::<true>(l, out, o, m);
        }
    }
}

/// Outputs `o .. o + 128` (the lanes of `m`, vector by vector) of [`one`], gathered input by
/// gathered input through [`accumulate4`].
///
/// # Safety
/// As [`one`]; the lanes in `m` lie below `n_out`.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn one_tile<const MASKED: bool>(l: &Dense<'_, half::f16>, out: *mut f32, o: usize, m: [__mmask32; 4]) {
    let n = l.n_out;
    let mut xs = [core::mem::MaybeUninit::<__m512>::uninit(); GATHER / 16];
    let mut offs = [core::mem::MaybeUninit::<__m512i>::uninit(); GATHER / 16];
    let mut hx = [core::mem::MaybeUninit::<__m256i>::uninit(); GATHER / 16];
    let (xs, offs, hx) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>(), hx.as_mut_ptr().cast::<u16>());
    // SAFETY (whole body): `init` and `out` hold `n_out` values and the masks stay below it; every
    // gathered input lies in its checked segment, every row offset within its rows; the gather
    // buffers have room for `GATHER` entries (`compress` stores whole vectors) and only entries
    // below `len` are read.
    unsafe {
        let zero = _mm512_castsi512_ph(_mm512_setzero_si512());
        let first = core::array::from_fn(|k| _mm512_castsi512_ph(load_rounded(l.init.as_ptr().add(o + 32 * k), m[k])));
        let mut acc = [first, [zero; 4]];
        for s in &l.segs[..l.n_segs] {
            let mut i0 = 0;
            while i0 < s.n {
                let c = (s.n - i0).min(GATHER);
                let len = compress(s.x.as_ptr().add(i0), c, (2 * n) as u32, xs, offs);
                round_list(xs, len, hx);
                accumulate4::<MASKED>(&mut acc, m, hx, offs, s.rows.as_ptr().add(i0 * n + o).cast(), len);
                i0 += c;
            }
        }
        for k in 0..4 {
            store_widened(out.add(o + 32 * k), m[k], _mm512_add_ph(acc[0][k], acc[1][k]), l.relu);
        }
    }
}

/// The f16 copies of a compressed list of inputs: `xs[..len]` rounded into `hx` (whole vectors of
/// 16; lanes past `len` are not read).
///
/// # Safety
/// `xs` holds `len` values; `hx` has room for `len` rounded up to 16.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn round_list(xs: *const f32, len: usize, hx: *mut u16) {
    let mut j = 0;
    while j < len {
        // SAFETY: lanes below `len` only are read; whole vectors stored within the room (contract).
        unsafe {
            let h = _mm512_cvtps_ph::<ROUND>(_mm512_maskz_loadu_ps(mask16(len - j), xs.add(j)));
            _mm256_storeu_si256(hx.add(j).cast::<__m256i>(), h);
        }
        j += 16;
    }
}

/// `Σ_j x_j row_j` in f16 over a compressed list (f16 inputs `hx`, row byte offsets `offs` from
/// `base`), 128 outputs (the lanes of `m` where `MASKED`), the rows alternating between `acc[0]` and
/// `acc[1]` (added when the layer is done). The one-query kernel and the chain both sum through
/// here, so a chain gives the bits of its layers run one by one.
///
/// # Safety
/// Each listed offset from `base` starts a row of at least 128 halves (the lanes of `m`); `len`
/// entries.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn accumulate4<const MASKED: bool>(
    acc: &mut [[__m512h; 4]; 2],
    m: [__mmask32; 4],
    hx: *const u16,
    offs: *const u32,
    base: *const u8,
    len: usize,
) {
    // SAFETY: see the contract.
    unsafe {
        let row = |j: usize, a: &mut [__m512h; 4]| {
            let r = base.add(*offs.add(j) as usize).cast::<__m512i>();
            let xb = _mm512_castsi512_ph(_mm512_set1_epi16(*hx.add(j) as i16));
            for (k, a) in a.iter_mut().enumerate() {
                let w = if MASKED { _mm512_maskz_loadu_epi16(m[k], r.add(k).cast::<i16>()) } else { _mm512_loadu_si512(r.add(k)) };
                *a = _mm512_fmadd_ph(xb, _mm512_castsi512_ph(w), *a);
            }
        };
        let [a0, a1] = acc;
        let mut j = 0;
        while j + 2 <= len {
            row(j, a0);
            row(j + 1, a1);
            j += 2;
        }
        if j < len {
            row(j, a0);
        }
    }
}

/// The sums of the two sets of [`accumulate4`] widened to f32, after ReLU where `relu`.
#[inline]
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
fn widen8(h: &[[__m512h; 4]; 2], relu: bool) -> [__m512; 8] {
    let w: [[__m512; 2]; 4] = core::array::from_fn(|k| widen(_mm512_add_ph(h[0][k], h[1][k]), relu));
    core::array::from_fn(|k| w[k / 2][k % 2])
}

/// One query through the hidden layers of a [`Chain`] of half weights in f16 arithmetic, the
/// activations in registers from one layer to the next (as the f32 chain kernel); writes the last
/// hidden layer's 128 activations (f32, after ReLU) to `out`. The output layer is the caller's.
///
/// # Safety
/// As [`one`]; the chain passed `Chain::check` and has no output layer.
#[target_feature(enable = "avx512fp16,avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) unsafe fn chain(c: &Chain<'_, half::f16>, out: *mut f32) {
    const { assert!(CHAIN_WIDTH == 128) };
    let row_bytes = (CHAIN_WIDTH * 2) as u32;
    let mut txs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_TAIL_MAX + 16];
    let mut toffs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_TAIL_MAX + 16];
    let mut thx = [core::mem::MaybeUninit::<u16>::uninit(); CHAIN_TAIL_MAX + 16];
    let mut xs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_WIDTH];
    let mut offs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_WIDTH];
    let mut hx = [core::mem::MaybeUninit::<u16>::uninit(); CHAIN_WIDTH];
    let (tx, to, th) = (txs.as_mut_ptr().cast::<f32>(), toffs.as_mut_ptr().cast::<u32>(), thx.as_mut_ptr().cast::<u16>());
    let (xp, op, hp) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>(), hx.as_mut_ptr().cast::<u16>());
    // SAFETY: `check` verified every extent: 128 starting values per layer, `tail.len()` (≤
    // CHAIN_TAIL_MAX, the lists' room less the rounding) rows of 128 for layer 0 and the skip rows,
    // 128 rows of 128 per hidden layer, 128 outputs.
    unsafe {
        let tlen = compress(c.tail.as_ptr(), c.tail.len(), row_bytes, tx, to);
        round_list(tx, tlen, th);
        let zero = _mm512_castsi512_ph(_mm512_setzero_si512());
        let init = |i: &Init<'_, half::f16>| -> [[__m512h; 4]; 2] {
            let a = core::array::from_fn(|k| {
                _mm512_castsi512_ph(match i {
                    Init::F32(s) => load_rounded(s.as_ptr().add(32 * k), u32::MAX),
                    Init::Bias(s) => _mm512_loadu_si512(s.as_ptr().add(32 * k).cast::<__m512i>()),
                })
            });
            [a, [zero; 4]]
        };
        let mut h = init(&Init::F32(c.first_init));
        accumulate4::<false>(&mut h, [u32::MAX; 4], th, to, c.first_rows.as_ptr().cast(), tlen);
        for l in c.hidden {
            let len = compress8(&widen8(&h, true), row_bytes, xp, op);
            round_list(xp, len, hp);
            let mut acc = init(&l.init);
            accumulate4::<false>(&mut acc, [u32::MAX; 4], hp, op, l.rows.as_ptr().cast(), len);
            if let Some(t) = l.tail_rows {
                accumulate4::<false>(&mut acc, [u32::MAX; 4], th, to, t.as_ptr().cast(), tlen);
            }
            h = acc;
        }
        for (k, v) in widen8(&h, true).iter().enumerate() {
            _mm512_storeu_ps(out.add(16 * k), *v);
        }
    }
}
