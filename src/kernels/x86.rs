//! AVX2 and AVX-512 kernels (x86-64), instantiated for `f32` and `half::f16` weights by macros: the
//! weight type only changes how a vector of weights is loaded (`vcvtph2ps` widens half weights).
//!
//! Register tiles (acc = accumulators, lanes = outputs):
//! - one query: 8 vectors of outputs (128 with AVX-512, 64 with AVX2) per pass over the gathered
//!   nonzero inputs (layers of at most `DENSE_BELOW` inputs: every input);
//! - a packet: `QT` queries × `K` vectors of outputs; per input row, `K` weight loads are shared by
//!   `QT` broadcast inputs. AVX-512: all 16 queries × 1 vector = 16 accumulators of 32 registers, so
//!   one weight load (and, for f16, one `vcvtph2ps`) serves 16 FMAs, the inputs transposed first so
//!   that the 16 broadcasts of a row read one cache line at fixed offsets; AVX2: 4 queries × 2
//!   vectors = 8 of 16 registers, the packet run as four quarters;
//! - a chain (AVX-512 only): one query through every layer of a 128-wide network, its 128
//!   activations held in 8 registers from one layer to the next and compressed from there;
//! - a sparse packet (128-wide layers whose inputs are mostly zeros after a ReLU): each query alone,
//!   8 vectors of outputs (AVX2: twice), over its nonzero inputs only, in blocks of `SPARSE_BLOCK`
//!   weight rows that stay in L1 while the 16 queries use them; with AVX-512, two neighbouring
//!   queries that share most of their nonzero inputs together, 2 × 8 vectors, each weight vector
//!   loaded once for both and each FMA masked to the query whose input is nonzero.
//!
//! Partial vectors at the end of a row (odd widths, the 3 or 6 outputs of the last layer) use masked
//! loads and stores, which never touch memory outside the mask.
//!
//! Every function here is `unsafe` and `#[target_feature]`: callers guarantee that the CPU has the
//! features (the dispatch in `kernels` only calls levels ≤ `detected()`) and that the `Dense` passed
//! `Dense::check` for the extents used.

use core::arch::x86_64::*;

use super::{Chain, Dense, Init, CHAIN_TAIL_MAX, CHAIN_WIDTH, PACKET};

/// Loads 16 weights widened to f32, lanes outside `m` zero (AVX-512).
macro_rules! load16 {
    (f32, $p:expr, $m:expr, $masked:expr) => {
        if $masked {
            _mm512_maskz_loadu_ps($m, $p)
        } else {
            _mm512_loadu_ps($p)
        }
    };
    (f16, $p:expr, $m:expr, $masked:expr) => {
        if $masked {
            _mm512_cvtph_ps(_mm256_maskz_loadu_epi16($m, $p.cast::<i16>()))
        } else {
            _mm512_cvtph_ps(_mm256_loadu_si256($p.cast::<__m256i>()))
        }
    };
}

/// Loads 8 weights widened to f32, lanes at or after `m` zero (AVX2).
macro_rules! load8 {
    (f32, $p:expr, $m:expr, $masked:expr) => {
        if $masked {
            _mm256_maskload_ps($p, lane_mask($m))
        } else {
            _mm256_loadu_ps($p)
        }
    };
    (f16, $p:expr, $m:expr, $masked:expr) => {
        if $masked {
            // No masked 16-bit load before AVX-512: copy the `m` valid halves to a zeroed buffer.
            let mut t = [0u16; 8];
            core::ptr::copy_nonoverlapping($p.cast::<u16>(), t.as_mut_ptr(), $m.min(8));
            _mm256_cvtph_ps(_mm_loadu_si128(t.as_ptr().cast::<__m128i>()))
        } else {
            _mm256_cvtph_ps(_mm_loadu_si128($p.cast::<__m128i>()))
        }
    };
}

/// Layers with at most this many inputs skip the gathering of nonzero inputs in the one-query kernels
/// (the NBRDF-json networks, 6-21-21-3): there the gathering costs more than the FMAs it saves.
const DENSE_BELOW: usize = 32;

/// Inputs gathered per batch of the one-query kernels.
const GATHER: usize = 256;

/// The nonzero inputs of one query with pointers to their weight rows, in input order: the first
/// `len` entries of `x` and `rows` (the rest uninitialised).
struct Gathered<W> {
    x: *const f32,
    rows: *const *const W,
    len: usize,
}

/// Gathers the nonzero inputs of the layer's segments into `xs`/`rs` and hands each full batch of
/// [`GATHER`] (and the last one) to `flush(batch, first, last)`. Branch-free: every slot is written and
/// kept only for a nonzero input (NaN is kept, as the packet kernels propagate it). `len` stays in a
/// register (a struct field behind `&mut` made each step wait on a store-to-load round trip).
#[inline(always)]
fn gather<W>(l: &Dense<'_, W>, mut flush: impl FnMut(&Gathered<W>, bool, bool)) {
    let mut xs = [core::mem::MaybeUninit::<f32>::uninit(); GATHER];
    let mut rs = [core::mem::MaybeUninit::<*const W>::uninit(); GATHER];
    let (xp, rp) = (xs.as_mut_ptr().cast::<f32>(), rs.as_mut_ptr().cast::<*const W>());
    let mut len = 0usize;
    let mut first = true;
    for s in &l.segs[..l.n_segs] {
        let (x, rows) = (s.x.as_ptr(), s.rows.as_ptr());
        for i in 0..s.n {
            if len == GATHER {
                flush(&Gathered { x: xp, rows: rp, len }, first, false);
                first = false;
                len = 0;
            }
            // SAFETY: `len < GATHER` slots; `i < s.n` inputs and rows (`Dense::check`).
            unsafe {
                let v = *x.add(i);
                xp.add(len).write(v);
                rp.add(len).write(rows.add(i * l.n_out));
                len += (v != 0.0) as usize;
            }
        }
    }
    flush(&Gathered { x: xp, rows: rp, len }, first, true);
}

/// The AVX2 mask selecting lanes `0..m`.
#[inline]
#[target_feature(enable = "avx2")]
fn lane_mask(m: usize) -> __m256i {
    let idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    _mm256_cmpgt_epi32(_mm256_set1_epi32(m.min(8) as i32), idx)
}

/// The AVX-512 mask selecting lanes `0..m`.
#[inline(always)]
pub(crate) fn mask16(m: usize) -> __mmask16 {
    if m >= 16 {
        0xffff
    } else {
        ((1u32 << m) - 1) as __mmask16
    }
}

/// The nonzero inputs of one query in (a chunk of) one segment, as `compress` writes them: the
/// first `len` values of `x`, and the byte offsets `off` of their weight rows from `base`.
struct Compressed {
    x: *const f32,
    off: *const u32,
    base: *const u8,
    len: usize,
}

/// Writes the nonzero values of `x[..n]` to `xs` and the byte offsets `i * row_bytes` of their weight
/// rows to `offs`, in order, and returns their number: 16 inputs per step with `vcompressps` (the
/// scalar, branch-free gathering cost about a quarter of the one-query time). NaN counts as nonzero
/// (unordered not-equal), as in the other kernels.
///
/// # Safety
/// `x` holds `n` values; `xs` and `offs` have room for `n` rounded up to 16 entries (whole vectors are
/// stored); `n * row_bytes < 2^31`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
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
pub(super) unsafe fn compress8(h: &[__m512; 8], row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
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
    row_offsets_of(_mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15), row_bytes)
}

/// [`row_offsets`] of the inputs `lanes` (their indices within each 16), for lists in another order.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) fn row_offsets_of(lanes: __m512i, row_bytes: u32) -> (__m512i, __m512i) {
    (_mm512_mullo_epi32(lanes, _mm512_set1_epi32(row_bytes as i32)), _mm512_set1_epi32((16 * row_bytes) as i32))
}

/// Appends the lanes of `v` in `valid` that are nonzero (NaN counts: unordered not-equal) to `xs` at
/// `len`, their row offsets `off` to `offs`, and returns the new length.
///
/// # Safety
/// `xs` and `offs` have room for 16 entries from `len` (whole vectors are stored).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
pub(super) unsafe fn append(v: __m512, valid: __mmask16, off: __m512i, xs: *mut f32, offs: *mut u32, len: usize) -> usize {
    let nz = _mm512_mask_cmp_ps_mask::<_CMP_NEQ_UQ>(valid, v, _mm512_setzero_ps());
    // SAFETY: 16 entries of room from `len` (contract).
    unsafe {
        _mm512_storeu_ps(xs.add(len), _mm512_maskz_compress_ps(nz, v));
        _mm512_storeu_si512(offs.add(len).cast(), _mm512_maskz_compress_epi32(nz, off));
    }
    len + nz.count_ones() as usize
}

macro_rules! avx512 {
    ($name:ident, $w:ty, $tag:tt) => {
        pub(super) mod $name {
            use super::*;

            /// Outputs `o .. o + 16 K` of one query: starting from `src`, one FMA per compressed input.
            ///
            /// # Safety
            /// See the module docs; `m[k]` masks the valid outputs of vector `k`; `src` and `out` hold
            /// `n_out` values, `g` lists rows of `n_out` weights.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn one_tile<const K: usize, const MASKED: bool>(
                src: *const f32,
                out: *mut f32,
                o: usize,
                m: [__mmask16; K],
                g: &Compressed,
            ) {
                // SAFETY (whole body): every access is at `o + 16 k + lane < n_out` (masked) of `src`,
                // `out` or a listed row (see the caller).
                unsafe {
                    let src = src.add(o);
                    let mut acc: [__m512; K] =
                        core::array::from_fn(|k| load16!(f32, src.add(16 * k), m[k], MASKED));
                    let base = g.base.cast::<$w>().add(o).cast::<u8>();
                    for j in 0..g.len {
                        let xb = _mm512_set1_ps(*g.x.add(j));
                        let r = base.add(*g.off.add(j) as usize).cast::<$w>();
                        for k in 0..K {
                            acc[k] = _mm512_fmadd_ps(xb, load16!($tag, r.add(16 * k), m[k], MASKED), acc[k]);
                        }
                    }
                    for k in 0..K {
                        _mm512_mask_storeu_ps(out.add(o + 16 * k), m[k], acc[k]);
                    }
                }
            }

            /// All output tiles of one query over one list of compressed inputs.
            ///
            /// # Safety
            /// As `one_tile`, for outputs `0..n`.
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn one_tiles(src: *const f32, out: *mut f32, n: usize, g: &Compressed) {
                let mut o = 0;
                // SAFETY: each tile stays below `n` (full tiles by the loop bounds, the rest masked).
                unsafe {
                    while o + 128 <= n {
                        one_tile::<8, false>(src, out, o, [0xffff; 8], g);
                        o += 128;
                    }
                    while o + 32 <= n {
                        one_tile::<2, false>(src, out, o, [0xffff; 2], g);
                        o += 32;
                    }
                    while o < n {
                        one_tile::<1, true>(src, out, o, [mask16(n - o)], g);
                        o += 16;
                    }
                }
            }

            /// Outputs `o .. o + 16 K` of one query, every input row (small layers: see `DENSE_BELOW`).
            ///
            /// # Safety
            /// As `one_tile`, over the checked segments.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn one_dense_tile<const K: usize, const MASKED: bool>(
                l: &Dense<'_, $w>,
                out: *mut f32,
                o: usize,
                m: [__mmask16; K],
            ) {
                let n = l.n_out;
                // SAFETY (whole body): as in `packet_tile`, for one query.
                unsafe {
                    let init = l.init.as_ptr().add(o);
                    let mut acc: [__m512; K] = core::array::from_fn(|k| load16!(f32, init.add(16 * k), m[k], MASKED));
                    for s in &l.segs[..l.n_segs] {
                        let (x, rows) = (s.x.as_ptr(), s.rows.as_ptr().add(o));
                        for i in 0..s.n {
                            let xb = _mm512_set1_ps(*x.add(i));
                            let r = rows.add(i * n);
                            for k in 0..K {
                                acc[k] = _mm512_fmadd_ps(xb, load16!($tag, r.add(16 * k), m[k], MASKED), acc[k]);
                            }
                        }
                    }
                    let zero = _mm512_setzero_ps();
                    for k in 0..K {
                        let v = if l.relu { _mm512_max_ps(acc[k], zero) } else { acc[k] };
                        _mm512_mask_storeu_ps(out.add(o + 16 * k), m[k], v);
                    }
                }
            }

            /// One query through a small layer, every input row.
            ///
            /// # Safety
            /// See the module docs (`check(1, ..)`).
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn one_dense(l: &Dense<'_, $w>, out: *mut f32) {
                let n = l.n_out;
                let mut o = 0;
                // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest masked).
                unsafe {
                    while o + 64 <= n {
                        one_dense_tile::<4, false>(l, out, o, [0xffff; 4]);
                        o += 64;
                    }
                    while o + 32 <= n {
                        one_dense_tile::<2, false>(l, out, o, [0xffff; 2]);
                        o += 32;
                    }
                    while o < n {
                        one_dense_tile::<1, true>(l, out, o, [mask16(n - o)]);
                        o += 16;
                    }
                }
            }

            /// One query through the layer: its nonzero inputs (about half after a ReLU, in no
            /// predictable pattern) are compressed into a list first, then each output tile runs one
            /// FMA per listed input; segments longer than `GATHER` go in chunks, the partial sums
            /// through `out` (exact), and the ReLU is a last pass.
            ///
            /// # Safety
            /// See the module docs (`check(1, ..)`).
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn one(l: &Dense<'_, $w>, out: *mut f32) {
                let n = l.n_out;
                if l.segs[..l.n_segs].iter().map(|s| s.n).sum::<usize>() <= DENSE_BELOW {
                    // SAFETY: same contract.
                    return unsafe { one_dense(l, out) };
                }
                let mut xs = [core::mem::MaybeUninit::<f32>::uninit(); GATHER + 16];
                let mut offs = [core::mem::MaybeUninit::<u32>::uninit(); GATHER + 16];
                let (xp, op) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>());
                let row_bytes = (n * core::mem::size_of::<$w>()) as u32;
                let mut src = l.init.as_ptr();
                for s in &l.segs[..l.n_segs] {
                    let mut i0 = 0;
                    while i0 < s.n {
                        let chunk = (s.n - i0).min(GATHER);
                        // SAFETY: `chunk` inputs and rows from `i0` lie in the checked segment; the
                        // lists have room for `GATHER` rounded up to 16; `src` and `out` hold `n`.
                        unsafe {
                            let len = compress(s.x.as_ptr().add(i0), chunk, row_bytes, xp, op);
                            let base = s.rows.as_ptr().add(i0 * n).cast::<u8>();
                            one_tiles(src, out, n, &Compressed { x: xp, off: op, base, len });
                        }
                        src = out;
                        i0 += chunk;
                    }
                }
                // SAFETY: `out` and `init` hold `n` values (`check`).
                unsafe {
                    let o = core::slice::from_raw_parts_mut(out, n);
                    if src != out.cast_const() {
                        o.copy_from_slice(&l.init[..n]);
                    }
                    if l.relu {
                        for v in o {
                            // As `_mm512_max_ps(v, 0)`: +0 for either zero, 0 for NaN.
                            *v = if *v > 0.0 { *v } else { 0.0 };
                        }
                    }
                }
            }

            /// `acc += Σ_j x_j row_j` over a compressed list of inputs, for all 128 outputs.
            ///
            /// # Safety
            /// Each listed offset from `base` starts a row of at least 128 weights; `g.len` entries.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn accumulate8(acc: &mut [__m512; 8], g: &Compressed) {
                // SAFETY: see the contract.
                unsafe {
                    for j in 0..g.len {
                        let xb = _mm512_set1_ps(*g.x.add(j));
                        let r = g.base.add(*g.off.add(j) as usize).cast::<$w>();
                        for k in 0..8 {
                            acc[k] = _mm512_fmadd_ps(xb, load16!($tag, r.add(16 * k), 0xffff, false), acc[k]);
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
            unsafe fn init8(init: &Init<'_, $w>) -> [__m512; 8] {
                // SAFETY: see the contract.
                unsafe {
                    match init {
                        Init::F32(s) => core::array::from_fn(|k| _mm512_loadu_ps(s.as_ptr().add(16 * k))),
                        Init::Bias(s) => core::array::from_fn(|k| load16!($tag, s.as_ptr().add(16 * k), 0xffff, false)),
                    }
                }
            }

            /// ReLU of 128 activations (as `max(v, 0)`: +0 for either zero and for NaN).
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            fn relu8(acc: &mut [__m512; 8]) {
                let zero = _mm512_setzero_ps();
                for a in acc.iter_mut() {
                    *a = _mm512_max_ps(*a, zero);
                }
            }

            /// One query through a whole [`Chain`] (see there).
            ///
            /// # Safety
            /// See the module docs; the chain passed `Chain::check` for `out`.
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn chain(c: &Chain<'_, $w>, out: *mut f32) {
                const { assert!(CHAIN_WIDTH == 128) };
                let row_bytes = (CHAIN_WIDTH * core::mem::size_of::<$w>()) as u32;
                let mut txs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_TAIL_MAX + 16];
                let mut toffs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_TAIL_MAX + 16];
                let mut xs = [core::mem::MaybeUninit::<f32>::uninit(); CHAIN_WIDTH];
                let mut offs = [core::mem::MaybeUninit::<u32>::uninit(); CHAIN_WIDTH];
                let (tx, to) = (txs.as_mut_ptr().cast::<f32>(), toffs.as_mut_ptr().cast::<u32>());
                let (xp, op) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>());
                // SAFETY: `check` verified every extent: 128 starting values per layer, `tail.len()`
                // (≤ CHAIN_TAIL_MAX, the lists' room less the rounding) rows of 128 for layer 0 and
                // the skip rows, 128 rows of 128 per hidden layer, 128 rows of `n_out` for the output.
                unsafe {
                    let tlen = compress(c.tail.as_ptr(), c.tail.len(), row_bytes, tx, to);
                    let tail = |base: *const $w| Compressed { x: tx, off: to, base: base.cast(), len: tlen };
                    let mut h = init8(&Init::F32(c.first_init));
                    accumulate8(&mut h, &tail(c.first_rows.as_ptr()));
                    relu8(&mut h);
                    for l in c.hidden {
                        let len = compress8(&h, row_bytes, xp, op);
                        let mut acc = init8(&l.init);
                        accumulate8(&mut acc, &Compressed { x: xp, off: op, base: l.rows.as_ptr().cast(), len });
                        if let Some(t) = l.tail_rows {
                            accumulate8(&mut acc, &tail(t.as_ptr()));
                        }
                        relu8(&mut acc);
                        h = acc;
                    }
                    match c.out {
                        None => {
                            for (k, v) in h.iter().enumerate() {
                                _mm512_storeu_ps(out.add(16 * k), *v);
                            }
                        }
                        Some((bias, rows, n)) => {
                            // The layer-by-layer path's output tile, on the bias widened to f32.
                            let m = mask16(n);
                            let mut init = [0.0f32; 16];
                            _mm512_storeu_ps(init.as_mut_ptr(), load16!($tag, bias.as_ptr(), m, true));
                            let len = compress8(&h, (n * core::mem::size_of::<$w>()) as u32, xp, op);
                            let g = Compressed { x: xp, off: op, base: rows.as_ptr().cast(), len };
                            one_tile::<1, true>(init.as_ptr(), out, 0, [m], &g);
                        }
                    }
                }
            }

            /// Outputs `o .. o + 16` of the `PACKET` queries over the inputs of one pass: `acc_q`
            /// starts at `init` (the first pass) or at the partial sums in `out`, then one FMA per
            /// listed input in order; ReLU where the pass says so.
            ///
            /// # Safety
            /// `p.xt` holds the inputs of every piece (`PACKET` values each, feature-major); each
            /// piece's rows hold `n_out` weights per input; `out` and `init` as in `Dense::check`;
            /// `m` masks the valid outputs from `o`.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn packet_tile<const MASKED: bool>(
                l: &Dense<'_, $w>,
                p: &Pass<'_, $w>,
                out: *mut f32,
                os: usize,
                o: usize,
                m: __mmask16,
            ) {
                let n = l.n_out;
                // SAFETY (whole body): as in `one_tile`, with query `q < PACKET` at `q * os` of the
                // outputs; every input read lies in `xt`'s listed pieces (contract).
                unsafe {
                    let mut acc: [__m512; PACKET] = if p.first {
                        [load16!(f32, l.init.as_ptr().add(o), m, MASKED); PACKET]
                    } else {
                        core::array::from_fn(|q| load16!(f32, out.add(q * os + o), m, MASKED))
                    };
                    for piece in p.pieces {
                        // Moving pointers, not `base + i * stride`: the broadcasts then address
                        // `x + 4q` (base and displacement), which Intel cores keep as one fused
                        // micro-op with the FMA, where an indexed address splits it in two.
                        let mut x = p.xt.add(piece.start * PACKET);
                        let mut r = piece.rows.add(o);
                        for _ in 0..piece.n {
                            let w = load16!($tag, r, m, MASKED);
                            for (q, a) in acc.iter_mut().enumerate() {
                                *a = _mm512_fmadd_ps(_mm512_set1_ps(*x.add(q)), w, *a);
                            }
                            x = x.add(PACKET);
                            r = r.add(n);
                        }
                    }
                    let zero = _mm512_setzero_ps();
                    for (q, a) in acc.iter().enumerate() {
                        let v = if p.relu { _mm512_max_ps(*a, zero) } else { *a };
                        _mm512_mask_storeu_ps(out.add(q * os + o), m, v);
                    }
                }
            }

            /// The whole layer for `N ≤ 8` outputs (an output head) over the inputs of one pass,
            /// with lanes for the `PACKET` queries: per input row one FMA per output, on the row's
            /// transposed inputs (one `xt` vector) and the broadcast weight, where a tile with lanes
            /// for outputs costs 16 (one per query) and leaves 13 of 16 lanes idle for 3 outputs.
            /// Each query's sum sees `packet_tile`'s operations in its order (the start, then one
            /// fused multiply-add per row), so the bits are the same.
            ///
            /// # Safety
            /// As `packet_tile`, with `l.n_out == N`.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn packet_narrow<const N: usize>(l: &Dense<'_, $w>, p: &Pass<'_, $w>, out: *mut f32, os: usize) {
                // SAFETY (whole body): as in `packet_tile`: `init` and each query's outputs hold `N`
                // values, every input read lies in `xt`'s listed pieces, each row holds `N` weights.
                unsafe {
                    let mut acc: [__m512; N] = core::array::from_fn(|o| {
                        if p.first {
                            _mm512_set1_ps(*l.init.as_ptr().add(o))
                        } else {
                            _mm512_setr_ps(
                                *out.add(o), *out.add(os + o), *out.add(2 * os + o), *out.add(3 * os + o),
                                *out.add(4 * os + o), *out.add(5 * os + o), *out.add(6 * os + o), *out.add(7 * os + o),
                                *out.add(8 * os + o), *out.add(9 * os + o), *out.add(10 * os + o), *out.add(11 * os + o),
                                *out.add(12 * os + o), *out.add(13 * os + o), *out.add(14 * os + o), *out.add(15 * os + o),
                            )
                        }
                    });
                    for piece in p.pieces {
                        let mut x = p.xt.add(piece.start * PACKET);
                        let mut r = piece.rows;
                        for _ in 0..piece.n {
                            let xv = _mm512_loadu_ps(x);
                            for (o, a) in acc.iter_mut().enumerate() {
                                *a = _mm512_fmadd_ps(xv, _mm512_set1_ps(crate::kernels::Weight::to_f32(*r.add(o))), *a);
                            }
                            x = x.add(PACKET);
                            r = r.add(N);
                        }
                    }
                    let mut lanes = [[0.0f32; PACKET]; N];
                    for (o, a) in acc.iter().enumerate() {
                        let v = if p.relu { _mm512_max_ps(*a, _mm512_setzero_ps()) } else { *a };
                        _mm512_storeu_ps(lanes[o].as_mut_ptr(), v);
                    }
                    for q in 0..PACKET {
                        for (o, l) in lanes.iter().enumerate() {
                            *out.add(q * os + o) = l[q];
                        }
                    }
                }
            }

            /// `PACKET` queries through the layer: 128-wide ReLU layers whose inputs are mostly zeros
            /// by `packet_sparse_with`, the rest by `packet_dense` (`sparse_or_dense`). Both give each
            /// query the operations of the one-query kernels, so the choice never changes a bit.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`).
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
            pub(in crate::kernels) unsafe fn packet(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                // SAFETY: the contract, passed on; the masks are the layer's.
                unsafe { sparse_or_dense(l, |x, n| nonzero_mask(x, n), false, |m| packet_sparse_with(l, out, os, m), || packet_dense(l, out, os)) }
            }

            /// `packet_sparse_with` on every 128-wide ReLU layer whose masks fit, however dense (the
            /// rest by `packet_dense`): the sparse kernel on its own, for the tests.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`), with `l.n_out == 128`.
            #[cfg(test)]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
            pub(in crate::kernels) unsafe fn packet_sparse(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                // SAFETY: the contract, passed on; the masks are the layer's.
                unsafe { sparse_or_dense(l, |x, n| nonzero_mask(x, n), true, |m| packet_sparse_with(l, out, os, m), || packet_dense(l, out, os)) }
            }

            /// `PACKET` queries through a 128-wide layer one query at a time, lanes for outputs (8
            /// accumulators), one FMA per nonzero input in row order: the operations of the one-query
            /// kernels, here with the inputs' zeros skipped for every query (about half of them after
            /// a ReLU), so half the FMAs of `packet_dense`. Two neighbouring queries that use nearly
            /// the same rows walk them together (`pair_pays`, `sparse_pair`). The weights go in blocks
            /// of `SPARSE_BLOCK` rows (of f16 ones, the rows some query uses widened into an f32 block
            /// first), each used by all the queries while it is in L1; a query's partial sums wait
            /// in its outputs between blocks.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`), with `l.n_out == 128`; `m` holds the
            /// masks of `l`'s inputs (`layer_masks`).
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,popcnt")]
            unsafe fn packet_sparse_with(l: &Dense<'_, $w>, out: *mut f32, os: usize, m: &LayerMasks) {
                const W: usize = 128;
                let widen = |row: *const $w, to: *mut f32| {
                    // SAFETY: a row of 128 from `row` to `to` (`sparse_blocks`).
                    unsafe {
                        for k in 0..W / 16 {
                            _mm512_storeu_ps(to.add(16 * k), load16!($tag, row.add(16 * k), 0xffff, false));
                        }
                    }
                };
                // SAFETY (whole body): `sparse_blocks`'s contract; each query's inputs are read at the
                // rows its mask lists, its outputs lie at `out + q os ..+ 128` (`check`).
                unsafe {
                    sparse_blocks(l, out, os, m, widen, |b| {
                        const { assert!(PACKET % 2 == 0) };
                        for q in (0..PACKET).step_by(2) {
                            if pair_pays(b.nz[q], b.nz[q + 1]) {
                                sparse_pair(l.init.as_ptr(), b, out.add(q * os), out.add((q + 1) * os), q);
                            } else {
                                sparse_one(l.init.as_ptr(), b, out.add(q * os), q);
                                sparse_one(l.init.as_ptr(), b, out.add((q + 1) * os), q + 1);
                            }
                        }
                    });
                }
            }

            /// Query `q` of a block of `packet_sparse_with`: one FMA per nonzero input and output
            /// vector, in row order, from `init` (the first block) or the partial sums at `o`, back to
            /// `o`.
            ///
            /// # Safety
            /// As `packet_sparse_with`: `b` is a block of `sparse_blocks`, `init` and `o` hold 128
            /// values.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn sparse_one(init: *const f32, b: &SparseBlock, o: *mut f32, q: usize) {
                const W: usize = 128;
                // SAFETY: see the contract; the rows `b.nz[q]` lists lie in the block.
                unsafe {
                    let from = if b.first { init } else { o.cast_const() };
                    let mut acc: [__m512; 8] = core::array::from_fn(|k| _mm512_loadu_ps(from.add(16 * k)));
                    let x = b.x.add(q * b.stride);
                    let mut nz = b.nz[q];
                    while nz != 0 {
                        let j = nz.trailing_zeros() as usize;
                        nz &= nz - 1;
                        let xb = _mm512_set1_ps(*x.add(j));
                        let r = b.rows.add(j * W);
                        for (k, a) in acc.iter_mut().enumerate() {
                            *a = _mm512_fmadd_ps(xb, _mm512_loadu_ps(r.add(16 * k)), *a);
                        }
                    }
                    relu_store8(acc, b.last, o);
                }
            }

            /// Queries `q` and `q + 1` of a block of `packet_sparse_with` together (`pair_pays`): one
            /// walk over the rows either uses, each weight vector loaded once for both, each query's
            /// FMA masked off (all lanes or none) where its input is zero. Each query's sum sees
            /// `sparse_one`'s operations in its order (a masked-off FMA leaves it as it was), so the
            /// same bits.
            ///
            /// # Safety
            /// As `sparse_one`, for both queries (`oa`, `ob` their outputs).
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn sparse_pair(init: *const f32, b: &SparseBlock, oa: *mut f32, ob: *mut f32, q: usize) {
                const W: usize = 128;
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
                        let r = b.rows.add(j * W);
                        for k in 0..8 {
                            let w = _mm512_loadu_ps(r.add(16 * k));
                            acc_a[k] = _mm512_mask3_fmadd_ps(va, w, acc_a[k], ka);
                            acc_b[k] = _mm512_mask3_fmadd_ps(vb, w, acc_b[k], kb);
                        }
                    }
                    relu_store8(acc_a, b.last, oa);
                    relu_store8(acc_b, b.last, ob);
                }
            }

            /// Stores 128 sums at `o`, after a ReLU (`relu8`) where `relu`.
            ///
            /// # Safety
            /// `o` has room for 128 values.
            #[inline]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            unsafe fn relu_store8(mut acc: [__m512; 8], relu: bool, o: *mut f32) {
                if relu {
                    relu8(&mut acc);
                }
                for (k, a) in acc.iter().enumerate() {
                    // SAFETY: see the contract.
                    unsafe { _mm512_storeu_ps(o.add(16 * k), *a) };
                }
            }

            /// `PACKET` queries through the layer, every input row: each query's inputs are first
            /// transposed to feature-major (`transpose_inputs`), so that a tile reads the 16 inputs
            /// of one row from one cache line at fixed offsets. Skipping each query's zero inputs
            /// with a tile of 32 outputs (one weight load, one broadcast and one offset load per FMA
            /// pair) was slower on Zen 4, whose single 512-bit load per cycle then limits the FMAs;
            /// `packet_sparse` amortises the broadcast over 128 outputs.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`).
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn packet_dense(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                let n = l.n_out;
                let mut xt = [core::mem::MaybeUninit::<__m512>::uninit(); XT_CAP];
                let xt = xt.as_mut_ptr().cast::<f32>();
                // Runs every output tile over the pieces transposed so far.
                let tiles = |pieces: &[Piece<$w>], first: bool, last: bool| {
                    let p = Pass { xt, pieces, first, relu: last && l.relu };
                    let mut o = 0;
                    // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest
                    // masked; a narrow layer is `n_out` wide); the pieces lie in `xt` and in their
                    // checked segments.
                    unsafe {
                        match n {
                            1 => return packet_narrow::<1>(l, &p, out, os),
                            2 => return packet_narrow::<2>(l, &p, out, os),
                            3 => return packet_narrow::<3>(l, &p, out, os),
                            4 => return packet_narrow::<4>(l, &p, out, os),
                            5 => return packet_narrow::<5>(l, &p, out, os),
                            6 => return packet_narrow::<6>(l, &p, out, os),
                            7 => return packet_narrow::<7>(l, &p, out, os),
                            8 => return packet_narrow::<8>(l, &p, out, os),
                            _ => {}
                        }
                        while o + 16 <= n {
                            packet_tile::<false>(l, &p, out, os, o, 0xffff);
                            o += 16;
                        }
                        if o < n {
                            packet_tile::<true>(l, &p, out, os, o, mask16(n - o));
                        }
                    }
                };
                // A longer layer passes its partial sums through `out` (exact), the ReLU on the last
                // pass only.
                // SAFETY: `passes` hands out inputs of checked segments, `xt` rows below `XT_CAP`.
                unsafe {
                    passes(l, |x, stride, c, used| transpose_inputs(x, stride, c, xt.add(used * PACKET)), tiles);
                }
            }
        }
    };
}

/// The nonzero inputs among the `n ≤ 64` from `x` (bit `j` for input `j`; NaN counts, as in
/// `compress`).
///
/// # Safety
/// `n` inputs are readable from `x` (the lanes past them are masked).
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

/// [`nonzero_mask`] with 8-lane vectors (AVX2).
///
/// # Safety
/// `n ≤ 64` inputs are readable from `x` (read by `maskload` under `lane_mask`, which leaves the
/// lanes past them unread).
#[inline]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn nonzero_mask_avx2(x: *const f32, n: usize) -> u64 {
    let mut nz = 0u64;
    for v in 0..n.div_ceil(8) {
        // SAFETY: see the contract.
        let xv = unsafe { _mm256_maskload_ps(x.add(8 * v), lane_mask(n - 8 * v)) };
        let c = _mm256_cmp_ps::<_CMP_NEQ_UQ>(xv, _mm256_setzero_ps());
        nz |= (_mm256_movemask_ps(c) as u32 as u64) << (8 * v);
    }
    nz
}

/// Blocks of inputs a sparse packet layer may have: `SPARSE_MAX_BLOCKS × SPARSE_BLOCK` (512) inputs
/// over its segments, far more than the paper-size networks' 128 + 36; a layer with more runs dense.
const SPARSE_MAX_BLOCKS: usize = 8;

/// Each query's nonzero inputs of a packet layer, block by block in the order of `sparse_blocks`,
/// and their count: made once per layer, for the choice of kernel and for the sparse walk.
struct LayerMasks {
    nz: [[u64; PACKET]; SPARSE_MAX_BLOCKS],
    /// Nonzero inputs over all blocks and queries, and inputs.
    nonzero: usize,
    total: usize,
}

impl LayerMasks {
    #[inline(always)]
    fn new() -> LayerMasks {
        LayerMasks { nz: [[0; PACKET]; SPARSE_MAX_BLOCKS], nonzero: 0, total: 0 }
    }
}

/// Fills `m` with the masks of `l`'s inputs (`mask(x, n)` for the `n` inputs of a block from `x`);
/// `false` where the layer has more than `SPARSE_MAX_BLOCKS` blocks (`m` then partly filled).
///
/// Taking the masks once both chooses the kernel and feeds the walk: a second pass over the inputs
/// took 1.03–1.07× the time of an f32 batch (in one process, alternating). They are filled in place,
/// not returned: a returned kilobyte of masks was copied (`memmove`, ~0.7% of a batch).
///
/// # Safety
/// The layer passed `check(PACKET, ..)`; `mask` reads `n ≤ SPARSE_BLOCK` inputs from `x`.
#[inline(always)]
unsafe fn layer_masks<W>(l: &Dense<'_, W>, mask: impl Fn(*const f32, usize) -> u64, m: &mut LayerMasks) -> bool {
    const { assert!(SPARSE_BLOCK <= 64) };
    (m.nonzero, m.total) = (0, 0);
    let mut b = 0;
    for s in &l.segs[..l.n_segs] {
        let mut i0 = 0;
        while i0 < s.n {
            if b == SPARSE_MAX_BLOCKS {
                return false;
            }
            let n = (s.n - i0).min(SPARSE_BLOCK);
            for q in 0..PACKET {
                // SAFETY: inputs `i0 .. i0 + n` of query `q` lie in the checked segment.
                let v = mask(unsafe { s.x.as_ptr().add(q * s.stride + i0) }, n);
                m.nz[b][q] = v;
                m.nonzero += v.count_ones() as usize;
            }
            m.total += PACKET * n;
            b += 1;
            i0 += n;
        }
    }
    true
}

/// Whether two queries of a sparse packet block walk together (`sparse_pair`) rather than one after
/// the other: where the rows either uses number at most `SPARSE_PAIR_AT_MOST` sixteenths of the rows
/// each uses, summed (`na`, `nb`: their masks of nonzero inputs).
#[inline]
#[target_feature(enable = "popcnt")]
fn pair_pays(na: u64, nb: u64) -> bool {
    16 * (na | nb).count_ones() <= SPARSE_PAIR_AT_MOST * (na.count_ones() + nb.count_ones())
}

/// Whether a packet layer is sparse enough for the sparse kernel: at most `SPARSE_AT_MOST` sixteenths
/// of its `total` inputs (over all segments and queries) `nonzero` (NaN counts).
#[inline]
fn sparse_enough(nonzero: usize, total: usize) -> bool {
    16 * nonzero <= SPARSE_AT_MOST * total
}

/// The choice of the packet kernel (both levels): `sparse` on the masks of a 128-wide ReLU layer
/// (`layer_masks`, by `mask`) where they fit and its inputs are sparse enough (`sparse_enough`; every
/// such layer where `always`, for the tests), `dense` otherwise.
///
/// # Safety
/// As `layer_masks`.
#[inline(always)]
unsafe fn sparse_or_dense<W>(
    l: &Dense<'_, W>,
    mask: impl Fn(*const f32, usize) -> u64,
    always: bool,
    sparse: impl FnOnce(&LayerMasks),
    dense: impl FnOnce(),
) {
    if l.n_out == 128 && l.relu {
        let mut m = LayerMasks::new();
        // SAFETY: the contract, passed on.
        if unsafe { layer_masks(l, mask, &mut m) } && (always || sparse_enough(m.nonzero, m.total)) {
            return sparse(&m);
        }
    }
    dense()
}

/// One block of a sparse packet kernel's walk: up to `SPARSE_BLOCK` consecutive inputs of a segment,
/// query `q`'s at `x + q * stride`, against their weight rows `rows` (128 f32 each; of f16 weights
/// only the rows some query's `nz` lists are widened).
struct SparseBlock {
    x: *const f32,
    stride: usize,
    rows: *const f32,
    /// The layer's first block: the queries start from `init`, later ones from their partial sums.
    first: bool,
    /// The layer's last block: the ReLU follows.
    last: bool,
    /// Each query's nonzero inputs of the block (bit `j` for input `j`; NaN counts, as in `compress`).
    nz: [u64; PACKET],
}

/// The walk of the sparse packet kernels (both levels): each segment's rows in blocks of
/// `SPARSE_BLOCK`, in order, with each query's nonzero inputs in the block (from `masks`, the
/// layer's, see `layer_masks`), then the block's rows as f32 (f32 weights where they lie; of f16
/// ones the rows some query uses, each widened by `widen(row, to)` into a copy), handed to `block`,
/// which runs the packet's queries over them. A layer without inputs gets the ReLU of `init` here (as
/// `max(v, 0)`: +0 for either zero and for NaN).
///
/// Widening only the rows some query uses saved 3–7% of an f16 batch (bench models and study fits:
/// the 16 queries of a packet share a point, and some units are off for all of them).
///
/// # Safety
/// The layer passed `check(PACKET, .., os)` for `out` with `l.n_out == 128`; `masks` are its inputs'
/// (`layer_masks`); `widen` converts 128 weights (exactly).
#[inline(always)]
unsafe fn sparse_blocks<W>(
    l: &Dense<'_, W>,
    out: *mut f32,
    os: usize,
    masks: &LayerMasks,
    widen: impl Fn(*const W, *mut f32),
    mut block: impl FnMut(&SparseBlock),
) {
    #[repr(align(64))]
    struct Wide([core::mem::MaybeUninit<f32>; SPARSE_BLOCK * 128]);
    let mut wide = Wide([core::mem::MaybeUninit::uninit(); SPARSE_BLOCK * 128]);
    let wide = wide.0.as_mut_ptr().cast::<f32>();
    let (mut first, mut b) = (true, 0);
    // The ReLU follows the last block of the last segment that has inputs (a skip layer's tail may be empty).
    let last_seg = l.segs[..l.n_segs].iter().rposition(|s| s.n > 0);
    for (si, s) in l.segs[..l.n_segs].iter().enumerate() {
        let mut i0 = 0;
        while i0 < s.n {
            let n = (s.n - i0).min(SPARSE_BLOCK);
            // SAFETY: inputs and rows `i0 .. i0 + n` lie in the checked segment.
            let (x, rows) = unsafe { (s.x.as_ptr().add(i0), s.rows.as_ptr().add(i0 * l.n_out)) };
            let last = Some(si) == last_seg && i0 + n == s.n;
            let nz = masks.nz[b];
            let rows = if core::mem::size_of::<W>() == 4 {
                rows.cast::<f32>()
            } else {
                let mut used = nz.iter().fold(0, |u, m| u | m);
                while used != 0 {
                    let j = used.trailing_zeros() as usize;
                    used &= used - 1;
                    // SAFETY: row `j < n` of the block, and of the copy (`SPARSE_BLOCK` rows).
                    unsafe { widen(rows.add(j * 128), wide.add(j * 128)) };
                }
                wide.cast_const()
            };
            block(&SparseBlock { x, stride: s.stride, rows, first, last, nz });
            first = false;
            b += 1;
            i0 += n;
        }
    }
    if first {
        for q in 0..PACKET {
            for (o, &v) in l.init[..l.n_out].iter().enumerate() {
                // SAFETY: query `q`'s outputs lie at `out + q os ..+ n_out` (`check`).
                unsafe { *out.add(q * os + o) = if v > 0.0 { v } else { 0.0 } };
            }
        }
    }
}

/// Inputs per pass of the AVX-512 packet kernel: `XT_CAP × PACKET` f32 (16 KB) on the stack, room
/// for every layer of the paper-size networks (at most 128 + 36 inputs) in one pass; a layer with
/// more inputs (a longer angle encoding) takes one pass per `XT_CAP`.
pub(super) const XT_CAP: usize = 256;

/// Weight rows per block of the sparse packet kernel: 64 rows of 128 f32 weights (32 KB, the L1 of
/// Zen 4 and of recent Intel cores) serve all 16 queries before the next block is read. In a C probe
/// of five 128-wide layers (Zen 4, 47% of the inputs nonzero) blocks of 16, 32 and 64 rows took 1.16,
/// 1.06 and 0.99 µs a query, no blocks (every query streaming the whole layer from L2) 1.24 µs, the
/// dense packet 1.62 µs; a batched Single MLP query took 0.81×, 0.82× and 0.77× its dense time with
/// blocks of 32, 48 and 64 rows (each in one process, alternating with the dense kernel).
const SPARSE_BLOCK: usize = 64;

/// The share of nonzero inputs (numerator over 16) at or below which a 128-wide packet layer runs
/// sparse. An FMA of the sparse kernel costs ~1.3× one of the dense kernel on Zen 4 (in the probe
/// above, 0.99 µs for 47% of the FMAs against 1.62 µs: each needs its own 64-byte weight load, and
/// the branch that ends each query's list mispredicts), so it pays below ~75% nonzero.
///
/// The same for f16 weights, whose used rows the sparse kernel widens block by block for the packet
/// (`vcvtph2ps`, two cycles a vector on Zen 4: ~12% of a batched query): with only the used rows
/// widened, 11 took 0.94–1.00× the time of 9 on the study's fits and bench models, 12 the same as 11.
///
/// With pairs of queries walking together (`SPARSE_PAIR_AT_MOST`) a sparse FMA costs about what a
/// dense one does where the pairs form, and 12 took 0.94–0.95× the time of 11 on the study's torus
/// Single MLP (a layer ~70% nonzero went sparse), the same on the other models and in f16; 13 and 14
/// the same as 12. At the AVX2 level (no pairs) 11 took 1.00–1.03× the time of 12.
const SPARSE_AT_MOST: usize = 12;

/// The share (numerator over 16) of two queries' rows, summed, at or below which the rows either uses
/// are walked once for both (`pair_pays`). A query's walk alone costs ~9 cycles a row on Zen 4 (8
/// weight loads and a broadcast: the one 512-bit load a cycle bounds it); a pair's walk loads each
/// weight vector once for 16 FMAs (two of them masked off where an input is zero), ~16 cycles a row
/// it walks, so it pays where the rows either uses are at most 9/16 of their sum: where the two share
/// at least 7/8 of their rows. Queries at one point often do: two neighbouring queries of the
/// study's fits share 88–93% of their nonzero inputs under random directions, 97–98% under
/// neighbouring ones (the bench's random-weight models 85% and 94%). In one process against
/// walking every query alone: batches 0.93–0.97× (fits, random directions) and 0.91–0.95×
/// (neighbouring), the bench's models 0.97–1.00× and 0.93–0.96×; thresholds of 8, 10 and 11
/// sixteenths: 8 gained less than half of that, 10 and 11 the same as 9.
const SPARSE_PAIR_AT_MOST: u32 = 9;

/// Consecutive inputs of one segment, transposed: rows `rows[i * n_out..]` for the inputs at
/// `xt[(start + i) * PACKET..][..PACKET]`, `i < n`.
#[derive(Clone, Copy)]
pub(super) struct Piece<W> {
    pub(super) rows: *const W,
    pub(super) start: usize,
    pub(super) n: usize,
}

/// The passes of a packet kernel over a layer's inputs: up to `XT_CAP` inputs at a time, in segment
/// order, each run of consecutive inputs handed to `transpose(x, stride, count, slot)` (the first
/// transposed slot `slot`), then every full buffer and the last to `tiles(pieces, first, last)`.
///
/// # Safety
/// The layer passed `check(PACKET, ..)` (what `transpose` is handed lies in its segments).
#[inline(always)]
pub(super) unsafe fn passes<W: Copy>(
    l: &Dense<'_, W>,
    mut transpose: impl FnMut(*const f32, usize, usize, usize),
    mut tiles: impl FnMut(&[Piece<W>], bool, bool),
) {
    let mut pieces = [Piece { rows: core::ptr::null(), start: 0, n: 0 }; 2];
    let (mut np, mut used, mut first) = (0, 0, true);
    for s in &l.segs[..l.n_segs] {
        let mut i0 = 0;
        while i0 < s.n {
            if used == XT_CAP {
                tiles(&pieces[..np], first, false);
                (np, used, first) = (0, 0, false);
            }
            let c = (s.n - i0).min(XT_CAP - used);
            // SAFETY: inputs `i0 .. i0 + c` of every query lie in the checked segment (contract).
            unsafe {
                transpose(s.x.as_ptr().add(i0), s.stride, c, used);
                pieces[np] = Piece { rows: s.rows.as_ptr().add(i0 * l.n_out), start: used, n: c };
            }
            (np, used, i0) = (np + 1, used + c, i0 + c);
        }
    }
    tiles(&pieces[..np], first, true);
}

/// One pass of the AVX-512 packet kernel over transposed inputs: the pieces in `xt`, whether it is
/// the first pass (starting from `init`) and whether the ReLU follows (the last pass of a hidden layer).
struct Pass<'a, W> {
    xt: *const f32,
    pieces: &'a [Piece<W>],
    first: bool,
    relu: bool,
}

/// Writes inputs `x[q * stride + i]`, `i < n`, of the `PACKET` queries feature-major to
/// `xt[i * PACKET + q]` ([`transpose_columns`]).
///
/// # Safety
/// Each query's `n` inputs are readable from `x + q * stride`; `xt` has room for `n * PACKET` values.
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
pub(super) unsafe fn transpose_columns(x: *const f32, stride: usize, n: usize, mut put: impl FnMut(usize, __m512)) {
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

avx512!(avx512_f32, f32, f32);
avx512!(avx512_f16, half::f16, f16);

/// Queries per AVX2 packet tile: 4 queries × 2 vectors = 8 of the 16 registers hold accumulators.
const QT2: usize = 4;

macro_rules! avx2 {
    ($name:ident, $w:ty, $tag:tt) => {
        pub(super) mod $name {
            use super::*;

            /// Outputs `o .. o + 8 K` of one query: starting from `src`, one FMA per gathered input;
            /// `m[k]` valid lanes in vector `k`.
            ///
            /// # Safety
            /// As the AVX-512 `one_tile`.
            #[inline]
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn one_tile<const K: usize, const MASKED: bool>(
                src: *const f32,
                out: *mut f32,
                o: usize,
                m: [usize; K],
                g: &Gathered<$w>,
                relu: bool,
            ) {
                // SAFETY (whole body): as in the AVX-512 `one_tile`; masked lanes are never read or
                // written (maskload/maskstore, or the bounded copy of `load8!`).
                unsafe {
                    let src = src.add(o);
                    let mut acc: [__m256; K] =
                        core::array::from_fn(|k| load8!(f32, src.add(8 * k), m[k], MASKED));
                    for j in 0..g.len {
                        let xb = _mm256_set1_ps(*g.x.add(j));
                        let r = (*g.rows.add(j)).add(o);
                        for k in 0..K {
                            acc[k] = _mm256_fmadd_ps(xb, load8!($tag, r.add(8 * k), m[k], MASKED), acc[k]);
                        }
                    }
                    let zero = _mm256_setzero_ps();
                    for k in 0..K {
                        let v = if relu { _mm256_max_ps(acc[k], zero) } else { acc[k] };
                        if MASKED {
                            _mm256_maskstore_ps(out.add(o + 8 * k), lane_mask(m[k]), v);
                        } else {
                            _mm256_storeu_ps(out.add(o + 8 * k), v);
                        }
                    }
                }
            }

            /// All output tiles of one query over one batch of gathered inputs.
            ///
            /// # Safety
            /// As `one_tile`, for outputs `0..n`.
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn one_tiles(src: *const f32, out: *mut f32, n: usize, g: &Gathered<$w>, relu: bool) {
                let mut o = 0;
                // SAFETY: each tile stays below `n` (full tiles by the loop bounds, the rest masked).
                unsafe {
                    while o + 64 <= n {
                        one_tile::<8, false>(src, out, o, [8; 8], g, relu);
                        o += 64;
                    }
                    while o + 16 <= n {
                        one_tile::<2, false>(src, out, o, [8; 2], g, relu);
                        o += 16;
                    }
                    while o < n {
                        one_tile::<1, true>(src, out, o, [n - o], g, relu);
                        o += 8;
                    }
                }
            }

            /// Outputs `o .. o + 8 K` of one query, every input row (small layers: see `DENSE_BELOW`).
            ///
            /// # Safety
            /// As `one_tile`, over the checked segments.
            #[inline]
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn one_dense_tile<const K: usize, const MASKED: bool>(
                l: &Dense<'_, $w>,
                out: *mut f32,
                o: usize,
                m: [usize; K],
            ) {
                let n = l.n_out;
                // SAFETY (whole body): as in `packet_tile`, for one query.
                unsafe {
                    let init = l.init.as_ptr().add(o);
                    let mut acc: [__m256; K] = core::array::from_fn(|k| load8!(f32, init.add(8 * k), m[k], MASKED));
                    for s in &l.segs[..l.n_segs] {
                        let (x, rows) = (s.x.as_ptr(), s.rows.as_ptr().add(o));
                        for i in 0..s.n {
                            let xb = _mm256_set1_ps(*x.add(i));
                            let r = rows.add(i * n);
                            for k in 0..K {
                                acc[k] = _mm256_fmadd_ps(xb, load8!($tag, r.add(8 * k), m[k], MASKED), acc[k]);
                            }
                        }
                    }
                    let zero = _mm256_setzero_ps();
                    for k in 0..K {
                        let v = if l.relu { _mm256_max_ps(acc[k], zero) } else { acc[k] };
                        if MASKED {
                            _mm256_maskstore_ps(out.add(o + 8 * k), lane_mask(m[k]), v);
                        } else {
                            _mm256_storeu_ps(out.add(o + 8 * k), v);
                        }
                    }
                }
            }

            /// One query through a small layer, every input row.
            ///
            /// # Safety
            /// See the module docs (`check(1, ..)`).
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn one_dense(l: &Dense<'_, $w>, out: *mut f32) {
                let n = l.n_out;
                let mut o = 0;
                // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest masked).
                unsafe {
                    while o + 32 <= n {
                        one_dense_tile::<4, false>(l, out, o, [8; 4]);
                        o += 32;
                    }
                    while o + 8 <= n {
                        one_dense_tile::<1, false>(l, out, o, [8]);
                        o += 8;
                    }
                    if o < n {
                        one_dense_tile::<1, true>(l, out, o, [n - o]);
                    }
                }
            }

            /// One query through the layer (nonzero inputs gathered first, as with AVX-512).
            ///
            /// # Safety
            /// See the module docs (`check(1, ..)`).
            #[target_feature(enable = "avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn one(l: &Dense<'_, $w>, out: *mut f32) {
                if l.segs[..l.n_segs].iter().map(|s| s.n).sum::<usize>() <= DENSE_BELOW {
                    // SAFETY: same contract.
                    return unsafe { one_dense(l, out) };
                }
                let init = l.init.as_ptr();
                gather(l, |g, first, last| {
                    // SAFETY: `init` and `out` hold `n_out` values (`check`), the gathered rows come from
                    // checked segments; partial sums of a long input go through `out` unrounded.
                    unsafe { one_tiles(if first { init } else { out }, out, l.n_out, g, last && l.relu) }
                });
            }

            /// Outputs `o .. o + 8 K` of queries `q0 .. q0 + QT2`.
            ///
            /// # Safety
            /// See the module docs.
            #[inline]
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn packet_tile<const K: usize, const MASKED: bool>(
                l: &Dense<'_, $w>,
                out: *mut f32,
                os: usize,
                q0: usize,
                o: usize,
                m: [usize; K],
            ) {
                let n = l.n_out;
                // SAFETY (whole body): as in the AVX-512 `packet_tile`, for queries `q0 + q < PACKET`.
                unsafe {
                    let init = l.init.as_ptr().add(o);
                    let init: [__m256; K] = core::array::from_fn(|k| load8!(f32, init.add(8 * k), m[k], MASKED));
                    let mut acc: [[__m256; K]; QT2] = [init; QT2];
                    for s in &l.segs[..l.n_segs] {
                        let (x, rows) = (s.x.as_ptr().add(q0 * s.stride), s.rows.as_ptr().add(o));
                        for i in 0..s.n {
                            let r = rows.add(i * n);
                            let w: [__m256; K] = core::array::from_fn(|k| load8!($tag, r.add(8 * k), m[k], MASKED));
                            for q in 0..QT2 {
                                let xb = _mm256_set1_ps(*x.add(q * s.stride + i));
                                for k in 0..K {
                                    acc[q][k] = _mm256_fmadd_ps(xb, w[k], acc[q][k]);
                                }
                            }
                        }
                    }
                    let zero = _mm256_setzero_ps();
                    for q in 0..QT2 {
                        for k in 0..K {
                            let v = if l.relu { _mm256_max_ps(acc[q][k], zero) } else { acc[q][k] };
                            let p = out.add((q0 + q) * os + o + 8 * k);
                            if MASKED {
                                _mm256_maskstore_ps(p, lane_mask(m[k]), v);
                            } else {
                                _mm256_storeu_ps(p, v);
                            }
                        }
                    }
                }
            }

            /// `PACKET` queries through the layer: 128-wide ReLU layers whose inputs are mostly zeros
            /// by `packet_sparse_with`, the rest by `packet_dense` (`sparse_or_dense`), each query's
            /// bits the same either way.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`).
            #[target_feature(enable = "avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn packet(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                // SAFETY: the contract, passed on; the masks are the layer's.
                unsafe { sparse_or_dense(l, |x, n| nonzero_mask_avx2(x, n), false, |m| packet_sparse_with(l, out, os, m), || packet_dense(l, out, os)) }
            }

            /// `packet_sparse_with` on every 128-wide ReLU layer whose masks fit, however dense (the
            /// rest by `packet_dense`): the sparse kernel on its own, for the tests.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`), with `l.n_out == 128`.
            #[cfg(test)]
            #[target_feature(enable = "avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn packet_sparse(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                // SAFETY: the contract, passed on; the masks are the layer's.
                unsafe { sparse_or_dense(l, |x, n| nonzero_mask_avx2(x, n), true, |m| packet_sparse_with(l, out, os, m), || packet_dense(l, out, os)) }
            }

            /// The AVX-512 `packet_sparse_with` with 8-lane vectors: one query at a time over its
            /// nonzero inputs, in blocks of `SPARSE_BLOCK` weight rows shared by the packet, each
            /// query's walk run twice, for outputs 0–63 and 64–127 (8 accumulators, a broadcast and
            /// a weight vector fill the 16 registers). The operations of `one` per query. No pairs
            /// (`sparse_pair`, not built): two queries' 16 accumulators would fill the 16 registers,
            /// and without mask registers a masked-off FMA is an FMA and a blend.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`), with `l.n_out == 128`; `m` holds the
            /// masks of `l`'s inputs (`layer_masks`).
            #[inline]
            #[target_feature(enable = "avx2,fma,f16c")]
            unsafe fn packet_sparse_with(l: &Dense<'_, $w>, out: *mut f32, os: usize, m: &LayerMasks) {
                const W: usize = 128;
                let zero = _mm256_setzero_ps();
                let widen = |row: *const $w, to: *mut f32| {
                    // SAFETY: a row of 128 from `row` to `to` (`sparse_blocks`).
                    unsafe {
                        for k in 0..W / 8 {
                            _mm256_storeu_ps(to.add(8 * k), load8!($tag, row.add(8 * k), 8, false));
                        }
                    }
                };
                // SAFETY (whole body): as in the AVX-512 `packet_sparse_with`: each query's inputs are
                // read at the rows its mask lists, its outputs lie at `out + q os ..+ 128` (`check`).
                unsafe {
                    sparse_blocks(l, out, os, m, widen, |b| {
                        for q in 0..PACKET {
                            let o = out.add(q * os);
                            let x = b.x.add(q * b.stride);
                            let nz = b.nz[q];
                            for h in [0, 64] {
                                let from = if b.first { l.init.as_ptr() } else { o.cast_const() }.add(h);
                                let mut acc: [__m256; 8] = core::array::from_fn(|k| _mm256_loadu_ps(from.add(8 * k)));
                                let mut m = nz;
                                while m != 0 {
                                    let j = m.trailing_zeros() as usize;
                                    m &= m - 1;
                                    let xb = _mm256_set1_ps(*x.add(j));
                                    let r = b.rows.add(j * W + h);
                                    for (k, a) in acc.iter_mut().enumerate() {
                                        *a = _mm256_fmadd_ps(xb, _mm256_loadu_ps(r.add(8 * k)), *a);
                                    }
                                }
                                for (k, a) in acc.iter().enumerate() {
                                    let v = if b.last { _mm256_max_ps(*a, zero) } else { *a };
                                    _mm256_storeu_ps(o.add(h + 8 * k), v);
                                }
                            }
                        }
                    });
                }
            }

            /// `PACKET` queries through the layer, every input row.
            ///
            /// # Safety
            /// See the module docs (`check(PACKET, ..)`).
            #[target_feature(enable = "avx2,fma,f16c")]
            pub(in crate::kernels) unsafe fn packet_dense(l: &Dense<'_, $w>, out: *mut f32, os: usize) {
                let n = l.n_out;
                // SAFETY: each tile stays below `n_out` and `PACKET` queries.
                unsafe {
                    for q0 in (0..PACKET).step_by(QT2) {
                        let mut o = 0;
                        while o + 16 <= n {
                            packet_tile::<2, false>(l, out, os, q0, o, [8; 2]);
                            o += 16;
                        }
                        while o < n {
                            packet_tile::<1, true>(l, out, os, q0, o, [n - o]);
                            o += 8;
                        }
                    }
                }
            }
        }
    };
}

avx2!(avx2_f32, f32, f32);
avx2!(avx2_f16, half::f16, f16);
