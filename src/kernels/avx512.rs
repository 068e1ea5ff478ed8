//! The AVX-512 level (x86-64 AVX-512 F, BW and VL with FMA and F16C): 16-lane vectors for the kernels
//! of `x86.rs`, this level's entry points, and what only this level has: the chain kernel (a 128-wide
//! network's activations held in 8 of its 32 registers from one layer to the next) and the paired
//! sparse walk (each FMA masked to the query whose input is nonzero, which needs mask registers). The
//! lane masks and the 16 × 16 transpose are shared with the angle kernels (`angles::theta16`).

use core::arch::x86_64::*;

use nbrdf_lanes::{Avx512, Lanes};

use super::x86::{self, Compressed, Load, SparseBlock, X86, SPARSE_WIDTH};
use super::{Chain, Dense, Init, CHAIN_TAIL_MAX, CHAIN_WIDTH, PACKET};

// SAFETY: the dispatch hands out this level only where the CPU has AVX-512 F, BW and VL, FMA, F16C and
// POPCNT (`detect`); every entry point below enables them.
unsafe impl X86 for Avx512 {
    /// All 16 queries × 1 vector: 16 accumulators of the 32 registers, so one weight load (and, for
    /// f16, one `vcvtph2ps`) serves 16 FMAs.
    const QT: usize = 16;
    const K: usize = 1;
    type Mask = __mmask16;

    #[inline(always)]
    fn mask(m: usize) -> __mmask16 {
        mask16(m)
    }

    #[inline(always)]
    unsafe fn load_masked(p: *const f32, m: __mmask16) -> __m512 {
        // SAFETY: the caller's contract; lanes outside `m` are not read.
        unsafe { _mm512_maskz_loadu_ps(m, p) }
    }

    #[inline(always)]
    unsafe fn store_masked(p: *mut f32, m: __mmask16, v: __m512) {
        // SAFETY: the caller's contract; lanes outside `m` are not written.
        unsafe { _mm512_mask_storeu_ps(p, m, v) }
    }

    #[inline(always)]
    unsafe fn load_f16(p: *const half::f16) -> __m512 {
        // SAFETY: the caller's contract (16 halves, 32 bytes).
        unsafe { _mm512_cvtph_ps(_mm256_loadu_si256(p.cast())) }
    }

    #[inline(always)]
    unsafe fn load_f16_masked(p: *const half::f16, m: __mmask16) -> __m512 {
        // SAFETY: the caller's contract; lanes outside `m` are not read.
        unsafe { _mm512_cvtph_ps(_mm256_maskz_loadu_epi16(m, p.cast())) }
    }

    #[inline(always)]
    unsafe fn nonzero(x: *const f32, n: usize) -> u64 {
        // SAFETY: the caller's contract.
        unsafe { nonzero_mask(x, n) }
    }

    #[inline(always)]
    unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
        // SAFETY: the caller's contract.
        unsafe { compress(x, n, row_bytes, xs, offs) }
    }

    #[inline(never)]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
    unsafe fn packet_dense<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
        // SAFETY: the caller's contract.
        unsafe { x86::packet_dense::<Self, W, { Self::QT }, { Self::K }>(l, out, os) }
    }

    #[inline(always)]
    unsafe fn transpose(x: *const f32, stride: usize, n: usize, xt: *mut f32) {
        // SAFETY: the caller's contract.
        unsafe { transpose_inputs(x, stride, n, xt) }
    }

    #[inline(always)]
    unsafe fn sparse_pair(init: *const f32, b: &SparseBlock, oa: *mut f32, ob: *mut f32, q: usize) -> bool {
        // SAFETY: the level (POPCNT among its features) is present; the caller's contract.
        unsafe {
            if !pair_pays(b.nz[q], b.nz[q + 1]) {
                return false;
            }
            sparse_pair(init, b, oa, ob, q);
        }
        true
    }
}

/// One query through the layer ([`x86::one`]).
///
/// # Safety
/// The CPU has this level; `l` passed `check(1, ..)` for `out`.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn one<W: Load>(l: &Dense<'_, W>, out: *mut f32) {
    // SAFETY: the contract, passed on.
    unsafe { x86::one::<Avx512, W>(l, out) }
}

/// `PACKET` queries through the layer ([`x86::packet`]).
///
/// # Safety
/// The CPU has this level; `l` passed `check(PACKET, ..)` for `out` with rows `os` apart.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn packet<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { x86::packet::<Avx512, W>(l, out, os, false) }
}

/// [`packet`] with the sparse kernel on every 128-wide ReLU layer whose masks fit, however dense: the
/// sparse kernel on its own, for the tests.
///
/// # Safety
/// As [`packet`].
#[cfg(test)]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn packet_sparse<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { x86::packet::<Avx512, W>(l, out, os, true) }
}

/// The dense packet kernel on its own ([`x86::packet_dense`]), for the tests.
///
/// # Safety
/// As [`packet`].
#[cfg(test)]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn packet_dense<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { Avx512::packet_dense(l, out, os) }
}

/// `dst[i] = src[i]` widened ([`x86::widen_f16`]): the f16 conversion behind `kernels::widen_f16`.
///
/// # Safety
/// The CPU has this level; `src` and `dst` have the same length.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn widen_f16(src: &[half::f16], dst: &mut [f32]) {
    // SAFETY: the contract, passed on.
    unsafe { x86::widen_f16::<Avx512>(src, dst) }
}

/// One query through a whole [`Chain`] (see there): its 128 activations stay in 8 registers from one
/// layer to the next, their nonzero entries compressed straight from there (`compress8`), and the
/// tail's nonzero entries are compressed once for layer 0 and the skip layer. Each layer is
/// [`x86::accumulate`] over the lists, as the one-query kernel runs it, so the same bits.
///
/// # Safety
/// The CPU has this level; the chain passed `Chain::check` for `out`.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
pub(super) unsafe fn chain<W: Load>(c: &Chain<'_, W>, out: *mut f32) {
    const { assert!(CHAIN_WIDTH == 128) };
    let row_bytes = (CHAIN_WIDTH * core::mem::size_of::<W>()) as u32;
    let mut txs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_TAIL_MAX + 16];
    let mut toffs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_TAIL_MAX + 16];
    let mut xs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_WIDTH];
    let mut offs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_WIDTH];
    let (tx, to) = (txs.as_mut_ptr().cast::<f32>(), toffs.as_mut_ptr().cast::<u32>());
    let (xp, op) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>());
    let all = [0xffff; 8];
    // SAFETY: `check` verified every extent: 128 starting values per layer, `tail.len()`
    // (≤ CHAIN_TAIL_MAX, the lists' room less the rounding) rows of 128 for layer 0 and the skip rows,
    // 128 rows of 128 per hidden layer, 128 rows of `n_out` for the output.
    unsafe {
        let tlen = compress(c.tail.as_ptr(), c.tail.len(), row_bytes, tx, to);
        let tail = |base: *const W| Compressed { x: tx, off: to, base: base.cast(), len: tlen };
        let mut h = init8(&Init::<W>::F32(c.first_init));
        x86::accumulate::<Avx512, W, 8, false>(&mut h, &tail(c.first_rows.as_ptr()), 0, all);
        relu8(&mut h);
        for l in c.hidden {
            let len = compress8(&h, row_bytes, xp, op);
            let mut acc = init8(&l.init);
            x86::accumulate::<Avx512, W, 8, false>(&mut acc, &Compressed { x: xp, off: op, base: l.rows.as_ptr().cast(), len }, 0, all);
            if let Some(t) = l.tail_rows {
                x86::accumulate::<Avx512, W, 8, false>(&mut acc, &tail(t.as_ptr()), 0, all);
            }
            relu8(&mut acc);
            h = acc;
        }
        match c.out {
            None => x86::relu_store::<Avx512, 8>(h, false, out),
            Some((bias, rows, n)) => {
                // The one-query kernel's output tile, on the bias widened to f32.
                let m = mask16(n);
                let mut init = [0.0f32; 16];
                _mm512_storeu_ps(init.as_mut_ptr(), W::load_masked::<Avx512>(bias.as_ptr(), m));
                let len = compress8(&h, (n * core::mem::size_of::<W>()) as u32, xp, op);
                let g = Compressed { x: xp, off: op, base: rows.as_ptr().cast(), len };
                x86::one_tile::<Avx512, W, 1, true>(init.as_ptr(), out, 0, [m], &g, false);
            }
        }
    }
}

/// 128 starting accumulators.
///
/// # Safety
/// `init` holds at least 128 values (`Chain::check`).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn init8<W: Load>(init: &Init<'_, W>) -> [__m512; 8] {
    // SAFETY: see the contract.
    unsafe {
        match init {
            Init::F32(s) => core::array::from_fn(|k| _mm512_loadu_ps(s.as_ptr().add(16 * k))),
            Init::Bias(s) => core::array::from_fn(|k| W::load::<Avx512>(s.as_ptr().add(16 * k))),
        }
    }
}

/// ReLU of 128 activations ([`Lanes::relu`]).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
fn relu8(acc: &mut [__m512; 8]) {
    for a in acc.iter_mut() {
        *a = Avx512::relu(*a);
    }
}

/// The mask selecting lanes `0..m`.
#[inline(always)]
pub(crate) fn mask16(m: usize) -> __mmask16 {
    if m >= 16 {
        0xffff
    } else {
        ((1u32 << m) - 1) as __mmask16
    }
}

/// [`X86::nonzero`]: 16 lanes per compare.
///
/// # Safety
/// `n ≤ 64` inputs are readable from `x` (the lanes past them are masked).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn nonzero_mask(x: *const f32, n: usize) -> u64 {
    let mut nz = 0u64;
    for v in 0..n.div_ceil(16) {
        let m = mask16(n - 16 * v);
        // SAFETY: see the contract.
        let xv = unsafe { _mm512_maskz_loadu_ps(m, x.add(16 * v)) };
        nz |= (_mm512_mask_cmp_ps_mask::<_CMP_NEQ_UQ>(m, xv, _mm512_setzero_ps()) as u64) << (16 * v);
    }
    nz
}

/// [`X86::compress`]: 16 inputs per step with `vcompressps`, where a scalar walk takes one step per
/// input.
///
/// # Safety
/// As [`X86::compress`].
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
    let mut len = 0;
    let (mut off, step) = row_offsets(row_bytes);
    let mut i = 0;
    while i < n {
        let valid = mask16(n - i);
        // SAFETY: lanes `i + j < n` only are read (mask); whole vectors are stored at `len <= i`, within
        // the rounded-up room.
        unsafe {
            let v = _mm512_maskz_loadu_ps(valid, x.add(i));
            len = append(v, valid, off, xs, offs, len);
        }
        off = _mm512_add_epi32(off, step);
        i += 16;
    }
    len
}

/// [`compress`] of 128 values held in registers (a 128-wide layer's activations), so that the next
/// layer does not wait for them to be stored and loaded again.
///
/// # Safety
/// `xs` and `offs` have room for 128 entries; `128 * row_bytes < 2^31`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn compress8(h: &[__m512; 8], row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
    let mut len = 0;
    let (mut off, step) = row_offsets(row_bytes);
    for v in h {
        // SAFETY: whole vectors are stored at `len ≤ 16 k`, within the 128 entries.
        len = unsafe { append(*v, 0xffff, off, xs, offs, len) };
        off = _mm512_add_epi32(off, step);
    }
    len
}

/// The byte offsets `i * row_bytes` of the rows of a first vector of inputs, and the step to the next.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
fn row_offsets(row_bytes: u32) -> (__m512i, __m512i) {
    let lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    (_mm512_mullo_epi32(lanes, _mm512_set1_epi32(row_bytes as i32)), _mm512_set1_epi32((16 * row_bytes) as i32))
}

/// Appends the lanes of `v` in `valid` that are nonzero (NaN counts: unordered not-equal) to `xs` at
/// `len`, their row offsets `off` to `offs`, and returns the new length.
///
/// # Safety
/// `xs` and `offs` have room for 16 entries from `len` (whole vectors are stored).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn append(v: __m512, valid: __mmask16, off: __m512i, xs: *mut f32, offs: *mut u32, len: usize) -> usize {
    let nz = _mm512_mask_cmp_ps_mask::<_CMP_NEQ_UQ>(valid, v, _mm512_setzero_ps());
    // SAFETY: 16 entries of room from `len` (contract).
    unsafe {
        _mm512_storeu_ps(xs.add(len), _mm512_maskz_compress_ps(nz, v));
        _mm512_storeu_si512(offs.add(len).cast(), _mm512_maskz_compress_epi32(nz, off));
    }
    len + nz.count_ones() as usize
}

/// The share (numerator over 16) of two queries' rows, summed, at or below which the rows either uses
/// are walked once for both (`pair_pays`). A query's walk alone is bound by its weight loads (8 a row,
/// one 512-bit load a cycle on Zen 4); a pair's walk loads each weight vector once for 16 FMAs (two
/// of them masked off where an input is zero), about twice the cycles a row, so it pays where the rows
/// either uses are at most 9/16 of their sum: where the two share at least 7/8 of their rows, as
/// neighbouring queries at one point usually do (docs/speed.md: the thresholds tried).
const SPARSE_PAIR_AT_MOST: u32 = 9;

/// Whether two queries of a sparse packet block walk together (`sparse_pair`) rather than one after
/// the other (`na`, `nb`: their masks of nonzero inputs).
#[inline]
#[target_feature(enable = "popcnt")]
fn pair_pays(na: u64, nb: u64) -> bool {
    16 * (na | nb).count_ones() <= SPARSE_PAIR_AT_MOST * (na.count_ones() + nb.count_ones())
}

/// Queries `q` and `q + 1` of a sparse block together: one walk over the rows either uses, each
/// weight vector loaded once for both, each query's FMA masked off (all lanes or none) where its input
/// is zero. Each query's sum sees `sparse_one`'s operations in its order (a masked-off FMA leaves it
/// as it was), so the same bits. Not built for AVX2: two queries' 16 accumulators would fill its 16
/// registers, and without mask registers a masked-off FMA is an FMA and a blend.
///
/// # Safety
/// As `x86::sparse_one`, for both queries (`oa`, `ob` their outputs).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn sparse_pair(init: *const f32, b: &SparseBlock, oa: *mut f32, ob: *mut f32, q: usize) {
    const { assert!(SPARSE_WIDTH == 128) };
    const C: usize = SPARSE_WIDTH;
    // SAFETY: see the contract; the rows either mask lists lie in the block.
    unsafe {
        let (fa, fb) = if b.first { (init, init) } else { (oa.cast_const(), ob.cast_const()) };
        let mut acc_a: [__m512; 8] = core::array::from_fn(|k| _mm512_loadu_ps(fa.add(16 * k)));
        let mut acc_b: [__m512; 8] = core::array::from_fn(|k| _mm512_loadu_ps(fb.add(16 * k)));
        let (xa, xb) = (b.x.add(q * b.stride), b.x.add((q + 1) * b.stride));
        let (na, nb) = (b.nz[q], b.nz[q + 1]);
        let mut both = na | nb;
        while both != 0 {
            let j = both.trailing_zeros() as usize;
            both &= both - 1;
            // All lanes where the query's input `j` is nonzero, none where it is zero.
            let (ka, kb) = ((((na >> j) & 1) as u16).wrapping_neg(), (((nb >> j) & 1) as u16).wrapping_neg());
            let (va, vb) = (_mm512_set1_ps(*xa.add(j)), _mm512_set1_ps(*xb.add(j)));
            let r = b.rows.add(j * C);
            for k in 0..8 {
                let w = _mm512_loadu_ps(r.add(16 * k));
                acc_a[k] = _mm512_mask3_fmadd_ps(va, w, acc_a[k], ka);
                acc_b[k] = _mm512_mask3_fmadd_ps(vb, w, acc_b[k], kb);
            }
        }
        x86::relu_store::<Avx512, 8>(acc_a, b.last, oa);
        x86::relu_store::<Avx512, 8>(acc_b, b.last, ob);
    }
}

/// [`X86::transpose`] by 16 × 16 blocks ([`transpose_columns`]).
///
/// # Safety
/// As [`X86::transpose`].
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn transpose_inputs(x: *const f32, stride: usize, n: usize, xt: *mut f32) {
    // SAFETY: column `i < n` goes to `xt[i * PACKET..]`, within the room (contract).
    unsafe { transpose_columns(x, stride, n, |i, c| _mm512_storeu_ps(xt.add(i * PACKET), c)) }
}

/// Hands input `i < n` of the `PACKET` queries (`x[q * stride + i]` in lane `q`) to `put(i, column)`, in
/// order: 16 × 16 blocks, each loaded as 16 rows (masked past `n`) and transposed in registers
/// ([`transpose16`]).
///
/// # Safety
/// Each query's `n` inputs are readable from `x + q * stride`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn transpose_columns(x: *const f32, stride: usize, n: usize, mut put: impl FnMut(usize, __m512)) {
    const { assert!(PACKET == 16) };
    let mut i = 0;
    while i < n {
        let m = mask16(n - i);
        // SAFETY: lanes `i + j < n` only are read (contract).
        let rows: [__m512; 16] = core::array::from_fn(|q| unsafe { _mm512_maskz_loadu_ps(m, x.add(q * stride + i)) });
        let cols = transpose16(rows);
        for (j, c) in cols.iter().enumerate().take(n - i) {
            put(i + j, *c);
        }
        i += 16;
    }
}

/// The transpose of a 16 × 16 block: lane `q` of result `j` is lane `j` of `r[q]`. Four rounds of
/// 16 shuffles: 32-bit and 64-bit interleaves within 128-bit lanes, then two rounds of 128-bit lane
/// shuffles.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(crate) fn transpose16(r: [__m512; 16]) -> [__m512; 16] {
    // t[2k] = a0 b0 a1 b1 | a4 b4 a5 b5 | ..., t[2k + 1] = a2 b2 a3 b3 | ... for rows a, b = 2k, 2k + 1.
    let t: [__m512; 16] = core::array::from_fn(|j| {
        let (a, b) = (r[j & !1], r[j | 1]);
        if j % 2 == 0 { _mm512_unpacklo_ps(a, b) } else { _mm512_unpackhi_ps(a, b) }
    });
    // u[4k + c] holds, in 128-bit lane L, column 4L + c of rows 4k .. 4k + 3.
    let u: [__m512; 16] = core::array::from_fn(|j| {
        let (k, c) = (j / 4, j % 4);
        let (a, b) = (_mm512_castps_pd(t[4 * k + c / 2]), _mm512_castps_pd(t[4 * k + 2 + c / 2]));
        _mm512_castpd_ps(if c % 2 == 0 { _mm512_unpacklo_pd(a, b) } else { _mm512_unpackhi_pd(a, b) })
    });
    // For each c: lanes 0, 1 and 2, 3 of the row groups 0, 1 (s01) and 2, 3 (s23), then the columns.
    let mut out = [_mm512_setzero_ps(); 16];
    for c in 0..4 {
        let (a, b, cc, d) = (u[c], u[4 + c], u[8 + c], u[12 + c]);
        let s0 = _mm512_shuffle_f32x4::<0b01_00_01_00>(a, b);
        let s1 = _mm512_shuffle_f32x4::<0b11_10_11_10>(a, b);
        let s2 = _mm512_shuffle_f32x4::<0b01_00_01_00>(cc, d);
        let s3 = _mm512_shuffle_f32x4::<0b11_10_11_10>(cc, d);
        out[c] = _mm512_shuffle_f32x4::<0b10_00_10_00>(s0, s2);
        out[4 + c] = _mm512_shuffle_f32x4::<0b11_01_11_01>(s0, s2);
        out[8 + c] = _mm512_shuffle_f32x4::<0b10_00_10_00>(s1, s3);
        out[12 + c] = _mm512_shuffle_f32x4::<0b11_01_11_01>(s1, s3);
    }
    out
}
