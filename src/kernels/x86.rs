//! The x86-64 kernels (AVX2 and AVX-512), each operation written once over [`X86`]: the lanes of
//! `lanes.rs` plus what these kernels need beyond them (masked loads and stores, f16 loads through
//! `vcvtph2ps`, the nonzero inputs of a query as a mask or a compressed list, a packet's inputs
//! transposed). `avx2.rs` and `avx512.rs` hold each level's lanes, its entry points, and what only
//! that level has (AVX-512: the chain kernel and the paired sparse walk).
//!
//! Register tiles (`N` lanes a vector: 16 at AVX-512, 8 at AVX2; lanes are outputs unless said):
//! - one query: 8 vectors of outputs per pass over its nonzero inputs, compressed into a list first
//!   (layers of at most `DENSE_BELOW` inputs: every input);
//! - a packet: `QT` queries × `K` vectors of outputs ([`X86::QT`], [`X86::K`]); per input row, `K`
//!   weight loads (and f16 conversions) are shared by `QT` broadcast inputs, read from the packet's
//!   inputs transposed feature-major so that a row's broadcasts come from one cache line at fixed
//!   offsets. AVX-512: all 16 queries × 1 vector (16 of 32 registers); AVX2: 4 queries × 2 vectors
//!   (8 of 16), the packet in four quarters. An output head of at most 8 outputs has lanes for
//!   queries instead (`packet_narrow`);
//! - a sparse packet (128-wide layers whose inputs are mostly zeros after a ReLU): each query alone,
//!   8 vectors of outputs (AVX2: the walk twice, outputs 0–63 then 64–127), over its nonzero inputs
//!   only, in blocks of `SPARSE_BLOCK` weight rows that stay in L1 while the 16 queries use them; a
//!   level may walk two neighbouring queries together ([`X86::sparse_pair`], AVX-512).
//!
//! Partial vectors at the end of a row (odd widths, the 3 or 6 outputs of the last layer) use masked
//! loads and stores, which never touch memory outside the mask.
//!
//! How the levels are compiled: everything here is generic and `#[inline(always)]`, and the entry
//! points of `avx2.rs` and `avx512.rs` (with their [`X86::packet_dense`], kept out of line) are
//! `#[target_feature]` functions that instantiate it, so the intrinsics inline into code built for the
//! level. No closure here holds a kernel loop: a closure
//! is a function of its own, without the level's features wherever it is not inlined.
//!
//! Every function here is `unsafe`: callers guarantee that the CPU has the level (the dispatch in
//! `kernels` only calls levels ≤ `detected()`) and that the `Dense` passed `Dense::check` for the
//! extents used.

use core::mem::MaybeUninit;

use nbrdf_lanes::Lanes;
use super::{Dense, Weight, PACKET};

/// The lanes of an x86 level, with what the kernels here need beyond [`Lanes`].
///
/// # Safety
/// As [`Lanes`]: implementors may use their level's instructions, which callers guarantee.
pub(super) unsafe trait X86: Lanes {
    /// Queries per packet tile (a divisor of [`PACKET`]).
    const QT: usize;
    /// Vectors of outputs per packet tile.
    const K: usize;
    /// The valid lanes of a partial vector.
    type Mask: Copy;

    /// Lanes `0 .. min(m, N)`.
    fn mask(m: usize) -> Self::Mask;

    /// The lanes in `m` from `p`, the others zero (and not read).
    ///
    /// # Safety
    /// The lanes in `m` are readable.
    unsafe fn load_masked(p: *const f32, m: Self::Mask) -> Self::V;

    /// The lanes in `m` to `p` (the others not written).
    ///
    /// # Safety
    /// The lanes in `m` are writable.
    unsafe fn store_masked(p: *mut f32, m: Self::Mask, v: Self::V);

    /// `N` half values from `p`, widened (exactly).
    ///
    /// # Safety
    /// `p` addresses `N` readable values.
    unsafe fn load_f16(p: *const half::f16) -> Self::V;

    /// [`X86::load_f16`] of the lanes in `m`, the others zero (and not read).
    ///
    /// # Safety
    /// The lanes in `m` are readable.
    unsafe fn load_f16_masked(p: *const half::f16, m: Self::Mask) -> Self::V;

    /// The nonzero values among the `n ≤ 64` from `x`: bit `j` for value `j`; NaN counts (unordered
    /// not-equal), as the kernels propagate it.
    ///
    /// # Safety
    /// `n` values are readable from `x`.
    unsafe fn nonzero(x: *const f32, n: usize) -> u64;

    /// Writes the nonzero values of `x[..n]` (NaN counts) to `xs` and the byte offsets `i * row_bytes`
    /// of their weight rows to `offs`, in order, and returns their number.
    ///
    /// # Safety
    /// `x` holds `n` values; `xs` and `offs` have room for `n` rounded up to `N` entries (whole vectors
    /// are stored); `n * row_bytes < 2^31`.
    unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize;

    /// Writes inputs `x[q * stride + i]`, `i < n`, of the [`PACKET`] queries feature-major to
    /// `xt[i * PACKET + q]`.
    ///
    /// # Safety
    /// Each query's `n` inputs are readable from `x + q * stride`; `xt` has room for `n * PACKET`.
    unsafe fn transpose(x: *const f32, stride: usize, n: usize, xt: *mut f32);

    /// [`packet_dense`] at this level, with its tile (`QT`, `K`): a function of its own, out of line
    /// from [`packet`], whose sparse walks are the hot loops of a batch.
    ///
    /// # Safety
    /// As [`packet_dense`].
    unsafe fn packet_dense<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize);

    /// Queries `q` and `q + 1` of a sparse block walked together where the level can and it pays;
    /// `false` (nothing done) where they are to be walked one by one (`sparse_one`). Together, each
    /// query's sum must see `sparse_one`'s operations in its order.
    ///
    /// # Safety
    /// As `sparse_one`, for both queries (`oa`, `ob` their outputs).
    #[inline(always)]
    unsafe fn sparse_pair(_init: *const f32, _b: &SparseBlock, _oa: *mut f32, _ob: *mut f32, _q: usize) -> bool {
        false
    }
}

/// A weight type as the x86 kernels load it: f32 as it lies, f16 widened by `vcvtph2ps`.
pub(super) trait Load: Weight {
    /// `N` weights from `p` as f32.
    ///
    /// # Safety
    /// `p` addresses `N` readable weights; the CPU has `L`'s level.
    unsafe fn load<L: X86>(p: *const Self) -> L::V;

    /// The weights in `m` from `p` as f32, the others zero (and not read).
    ///
    /// # Safety
    /// The lanes in `m` are readable; the CPU has `L`'s level.
    unsafe fn load_masked<L: X86>(p: *const Self, m: L::Mask) -> L::V;
}

impl Load for f32 {
    #[inline(always)]
    unsafe fn load<L: X86>(p: *const f32) -> L::V {
        // SAFETY: the caller's contract.
        unsafe { L::load(p) }
    }

    #[inline(always)]
    unsafe fn load_masked<L: X86>(p: *const f32, m: L::Mask) -> L::V {
        // SAFETY: the caller's contract.
        unsafe { L::load_masked(p, m) }
    }
}

impl Load for half::f16 {
    #[inline(always)]
    unsafe fn load<L: X86>(p: *const half::f16) -> L::V {
        // SAFETY: the caller's contract.
        unsafe { L::load_f16(p) }
    }

    #[inline(always)]
    unsafe fn load_masked<L: X86>(p: *const half::f16, m: L::Mask) -> L::V {
        // SAFETY: the caller's contract.
        unsafe { L::load_f16_masked(p, m) }
    }
}

/// `N` weights from `p` as f32: the lanes in `m` only where `MASKED`.
///
/// # Safety
/// As [`Load::load`] or [`Load::load_masked`].
#[inline(always)]
unsafe fn load<L: X86, W: Load, const MASKED: bool>(p: *const W, m: L::Mask) -> L::V {
    // SAFETY: the caller's contract.
    unsafe {
        if MASKED {
            W::load_masked::<L>(p, m)
        } else {
            W::load::<L>(p)
        }
    }
}

/// `v` to `p`: the lanes in `m` only where `MASKED`.
///
/// # Safety
/// As [`Lanes::store`] or [`X86::store_masked`].
#[inline(always)]
unsafe fn store<L: X86, const MASKED: bool>(p: *mut f32, m: L::Mask, v: L::V) {
    // SAFETY: the caller's contract.
    unsafe {
        if MASKED {
            L::store_masked(p, m, v)
        } else {
            L::store(p, v)
        }
    }
}

/// `v`, or its ReLU where `relu`.
#[inline(always)]
fn relu_if<L: X86>(v: L::V, relu: bool) -> L::V {
    if relu {
        L::relu(v)
    } else {
        v
    }
}

/// Layers with at most this many inputs skip the compression of nonzero inputs in the one-query kernel
/// (the NBRDF-json networks, 6-21-21-3): there the compression costs more than the FMAs it saves.
const DENSE_BELOW: usize = 32;

/// Inputs compressed per list of the one-query kernel.
const GATHER: usize = 256;

/// The nonzero inputs of one query in (a chunk of) one segment, as [`X86::compress`] writes them: the
/// first `len` values of `x`, and the byte offsets `off` of their weight rows from `base`.
pub(super) struct Compressed {
    pub(super) x: *const f32,
    pub(super) off: *const u32,
    pub(super) base: *const u8,
    pub(super) len: usize,
}

/// `acc[k] += x_j row_j[o + N k ..]` for each listed input `j`, in order: one FMA per input and vector.
///
/// # Safety
/// Each listed offset from `g.base` starts a row of weights that holds the lanes in `m` from `o`;
/// `g.len` entries; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn accumulate<L: X86, W: Load, const K: usize, const MASKED: bool>(
    acc: &mut [L::V; K],
    g: &Compressed,
    o: usize,
    m: [L::Mask; K],
) {
    // SAFETY: see the contract.
    unsafe {
        let base = g.base.cast::<W>().add(o).cast::<u8>();
        for j in 0..g.len {
            let xb = L::splat(*g.x.add(j));
            let r = base.add(*g.off.add(j) as usize).cast::<W>();
            for k in 0..K {
                acc[k] = L::mul_add(xb, load::<L, W, MASKED>(r.add(L::N * k), m[k]), acc[k]);
            }
        }
    }
}

/// Outputs `o .. o + N K` of one query: starting from `src`, one FMA per listed input, then the ReLU
/// where `relu`, to `out`.
///
/// # Safety
/// `m[k]` masks the valid outputs of vector `k` (all lanes unless `MASKED`); `src` and `out` hold
/// those outputs; `g` lists rows that hold them too; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn one_tile<L: X86, W: Load, const K: usize, const MASKED: bool>(
    src: *const f32,
    out: *mut f32,
    o: usize,
    m: [L::Mask; K],
    g: &Compressed,
    relu: bool,
) {
    // SAFETY (whole body): every access is at `o + N k + lane` in the lanes of `m[k]` (contract).
    unsafe {
        let src = src.add(o);
        let mut acc = [L::splat(0.0); K];
        for k in 0..K {
            acc[k] = load::<L, f32, MASKED>(src.add(L::N * k), m[k]);
        }
        accumulate::<L, W, K, MASKED>(&mut acc, g, o, m);
        for k in 0..K {
            store::<L, MASKED>(out.add(o + L::N * k), m[k], relu_if::<L>(acc[k], relu));
        }
    }
}

/// All output tiles of one query over one list of compressed inputs: 8 vectors at a time, then 2,
/// then one masked.
///
/// # Safety
/// As [`one_tile`], for outputs `0..n`.
#[inline(always)]
unsafe fn one_tiles<L: X86, W: Load>(src: *const f32, out: *mut f32, n: usize, g: &Compressed, relu: bool) {
    let all = L::mask(L::N);
    let mut o = 0;
    // SAFETY: each tile stays below `n` (full tiles by the loop bounds, the rest masked).
    unsafe {
        while o + 8 * L::N <= n {
            one_tile::<L, W, 8, false>(src, out, o, [all; 8], g, relu);
            o += 8 * L::N;
        }
        while o + 2 * L::N <= n {
            one_tile::<L, W, 2, false>(src, out, o, [all; 2], g, relu);
            o += 2 * L::N;
        }
        while o < n {
            one_tile::<L, W, 1, true>(src, out, o, [L::mask(n - o)], g, relu);
            o += L::N;
        }
    }
}

/// Outputs `o .. o + N K` of one query, every input row (small layers: see `DENSE_BELOW`).
///
/// # Safety
/// As [`one_tile`], over the checked segments.
#[inline(always)]
unsafe fn one_dense_tile<L: X86, W: Load, const K: usize, const MASKED: bool>(
    l: &Dense<'_, W>,
    out: *mut f32,
    o: usize,
    m: [L::Mask; K],
) {
    let n = l.n_out;
    // SAFETY (whole body): as in `one_tile`, over the rows of the checked segments.
    unsafe {
        let init = l.init.as_ptr().add(o);
        let mut acc = [L::splat(0.0); K];
        for k in 0..K {
            acc[k] = load::<L, f32, MASKED>(init.add(L::N * k), m[k]);
        }
        for s in &l.segs[..l.n_segs] {
            let (x, rows) = (s.x.as_ptr(), s.rows.as_ptr().add(o));
            for i in 0..s.n {
                let xb = L::splat(*x.add(i));
                let r = rows.add(i * n);
                for k in 0..K {
                    acc[k] = L::mul_add(xb, load::<L, W, MASKED>(r.add(L::N * k), m[k]), acc[k]);
                }
            }
        }
        for k in 0..K {
            store::<L, MASKED>(out.add(o + L::N * k), m[k], relu_if::<L>(acc[k], l.relu));
        }
    }
}

/// One query through a small layer, every input row: 4 vectors at a time, then 2, then one masked.
///
/// # Safety
/// As [`one`].
#[inline(always)]
unsafe fn one_dense<L: X86, W: Load>(l: &Dense<'_, W>, out: *mut f32) {
    let (n, all) = (l.n_out, L::mask(L::N));
    let mut o = 0;
    // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest masked).
    unsafe {
        while o + 4 * L::N <= n {
            one_dense_tile::<L, W, 4, false>(l, out, o, [all; 4]);
            o += 4 * L::N;
        }
        while o + 2 * L::N <= n {
            one_dense_tile::<L, W, 2, false>(l, out, o, [all; 2]);
            o += 2 * L::N;
        }
        while o < n {
            one_dense_tile::<L, W, 1, true>(l, out, o, [L::mask(n - o)]);
            o += L::N;
        }
    }
}

/// One query through the layer: its nonzero inputs (about half after a ReLU, in no predictable
/// pattern) are compressed into a list first ([`X86::compress`]), then each output tile runs one FMA
/// per listed input; segments longer than `GATHER` go in chunks, the partial sums through `out`
/// (exact), and the ReLU follows the last list.
///
/// # Safety
/// `l` passed `check(1, ..)` for `out`; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn one<L: X86, W: Load>(l: &Dense<'_, W>, out: *mut f32) {
    let n = l.n_out;
    if l.segs[..l.n_segs].iter().map(|s| s.n).sum::<usize>() <= DENSE_BELOW {
        // SAFETY: same contract.
        return unsafe { one_dense::<L, W>(l, out) };
    }
    let mut xs = [MaybeUninit::<f32>::uninit(); GATHER + 16];
    let mut offs = [MaybeUninit::<u32>::uninit(); GATHER + 16];
    let (xp, op) = (xs.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>());
    let row_bytes = (n * core::mem::size_of::<W>()) as u32;
    // The ReLU follows the last chunk of the last segment that has inputs.
    let last_seg = l.segs[..l.n_segs].iter().rposition(|s| s.n > 0);
    let mut src = l.init.as_ptr();
    for (si, s) in l.segs[..l.n_segs].iter().enumerate() {
        let mut i0 = 0;
        while i0 < s.n {
            let chunk = (s.n - i0).min(GATHER);
            let relu = l.relu && Some(si) == last_seg && i0 + chunk == s.n;
            // SAFETY: `chunk` inputs and rows from `i0` lie in the checked segment; the lists have room
            // for `GATHER` rounded up to a vector; `src` and `out` hold `n`.
            unsafe {
                let len = L::compress(s.x.as_ptr().add(i0), chunk, row_bytes, xp, op);
                let base = s.rows.as_ptr().add(i0 * n).cast::<u8>();
                one_tiles::<L, W>(src, out, n, &Compressed { x: xp, off: op, base, len }, relu);
            }
            src = out;
            i0 += chunk;
        }
    }
    if last_seg.is_none() {
        // SAFETY: `out` holds `n` values (`check`).
        let o = unsafe { core::slice::from_raw_parts_mut(out, n) };
        for (o, &v) in o.iter_mut().zip(&l.init[..n]) {
            // As `Lanes::relu`: +0 for either zero and for NaN.
            *o = if !l.relu || v > 0.0 { v } else { 0.0 };
        }
    }
}

/// Inputs per pass of the dense packet kernel: `XT_CAP × PACKET` f32 (16 KB) on the stack, room for
/// every layer of the paper-size networks (at most 128 + 36 inputs) in one pass; a layer with more
/// inputs (a longer angle encoding) takes one pass per `XT_CAP`.
const XT_CAP: usize = 256;

/// Consecutive inputs of one segment, transposed: rows `rows[i * n_out..]` for the inputs at
/// `xt[(start + i) * PACKET..][..PACKET]`, `i < n`.
#[derive(Clone, Copy)]
struct Piece<W> {
    rows: *const W,
    start: usize,
    n: usize,
}

/// One pass of the dense packet kernel over transposed inputs: the pieces in `xt`, whether it is the
/// first pass (starting from `init`) and whether the ReLU follows (the last pass of a hidden layer).
struct Pass<'a, W> {
    xt: *const f32,
    pieces: &'a [Piece<W>],
    first: bool,
    relu: bool,
}

/// Outputs `o .. o + N K` of queries `q0 .. q0 + QT` over the inputs of one pass: `acc` starts at
/// `init` (the first pass) or at the partial sums in `out`, then one FMA per input row in order; the
/// ReLU where the pass says so.
///
/// # Safety
/// `p.xt` holds the inputs of every piece (`PACKET` values each, feature-major); each piece's rows
/// hold `n_out` weights per input; `out` and `init` as in `Dense::check`; `m` masks the valid outputs
/// from `o`; `q0 + QT ≤ PACKET`; the CPU has `L`'s level.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn packet_tile<L: X86, W: Load, const QT: usize, const K: usize, const MASKED: bool>(
    l: &Dense<'_, W>,
    p: &Pass<'_, W>,
    out: *mut f32,
    os: usize,
    q0: usize,
    o: usize,
    m: [L::Mask; K],
) {
    let n = l.n_out;
    // SAFETY (whole body): as in `one_tile`, with query `q0 + q` at `(q0 + q) os` of the outputs;
    // every input read lies in `xt`'s listed pieces (contract).
    unsafe {
        let mut acc = [[L::splat(0.0); K]; QT];
        for (q, a) in acc.iter_mut().enumerate() {
            let from = if p.first { l.init.as_ptr() } else { out.add((q0 + q) * os) }.add(o);
            for k in 0..K {
                a[k] = load::<L, f32, MASKED>(from.add(L::N * k), m[k]);
            }
        }
        for piece in p.pieces {
            // Moving pointers, not `base + i * stride`: the broadcasts then address `x + 4q` (base and
            // displacement), which Intel cores keep as one fused micro-op with the FMA, where an
            // indexed address splits it in two.
            let mut x = p.xt.add(piece.start * PACKET + q0);
            let mut r = piece.rows.add(o);
            for _ in 0..piece.n {
                let mut w = [L::splat(0.0); K];
                for k in 0..K {
                    w[k] = load::<L, W, MASKED>(r.add(L::N * k), m[k]);
                }
                for (q, a) in acc.iter_mut().enumerate() {
                    let xb = L::splat(*x.add(q));
                    for k in 0..K {
                        a[k] = L::mul_add(xb, w[k], a[k]);
                    }
                }
                x = x.add(PACKET);
                r = r.add(n);
            }
        }
        for (q, a) in acc.iter().enumerate() {
            for k in 0..K {
                store::<L, MASKED>(out.add((q0 + q) * os + o + L::N * k), m[k], relu_if::<L>(a[k], p.relu));
            }
        }
    }
}

/// The whole layer for `NO ≤ 8` outputs (an output head) over the inputs of one pass, with lanes for
/// `N` queries at a time: per input row one FMA per output, on the row's transposed inputs (one
/// vector) and the broadcast weight, where a tile with lanes for outputs costs one per query and
/// leaves most lanes idle. Each query's sum sees `packet_tile`'s operations in its order (the start,
/// then one fused multiply-add per row), so the bits are the same.
///
/// # Safety
/// As [`packet_tile`], with `l.n_out == NO`.
#[inline(always)]
unsafe fn packet_narrow<L: X86, W: Load, const NO: usize>(l: &Dense<'_, W>, p: &Pass<'_, W>, out: *mut f32, os: usize) {
    const { assert!(L::N <= 16 && PACKET.is_multiple_of(L::N)) };
    // SAFETY (whole body): as in `packet_tile`: `init` and each query's outputs hold `NO` values,
    // every input read lies in `xt`'s listed pieces, each row holds `NO` weights.
    unsafe {
        for q0 in (0..PACKET).step_by(L::N) {
            let mut acc = [L::splat(0.0); NO];
            for (o, a) in acc.iter_mut().enumerate() {
                *a = if p.first {
                    L::splat(*l.init.as_ptr().add(o))
                } else {
                    let mut t = [0.0f32; 16];
                    for (q, t) in t.iter_mut().enumerate().take(L::N) {
                        *t = *out.add((q0 + q) * os + o);
                    }
                    L::load(t.as_ptr())
                };
            }
            for piece in p.pieces {
                let mut x = p.xt.add(piece.start * PACKET + q0);
                let mut r = piece.rows;
                for _ in 0..piece.n {
                    let xv = L::load(x);
                    for (o, a) in acc.iter_mut().enumerate() {
                        *a = L::mul_add(xv, L::splat((*r.add(o)).to_f32()), *a);
                    }
                    x = x.add(PACKET);
                    r = r.add(NO);
                }
            }
            let mut lanes = [[0.0f32; 16]; NO];
            for (o, a) in acc.iter().enumerate() {
                L::store(lanes[o].as_mut_ptr(), relu_if::<L>(*a, p.relu));
            }
            for q in 0..L::N {
                for (o, v) in lanes.iter().enumerate() {
                    *out.add((q0 + q) * os + o) = v[q];
                }
            }
        }
    }
}

/// Every output tile of the layer over the inputs of one pass: `packet_narrow` for at most 8
/// outputs, else tiles of `QT` queries × `K` vectors, the rest of a row one masked vector at a time.
///
/// # Safety
/// As [`packet_tile`], for the whole layer.
#[inline(always)]
unsafe fn packet_pass<L: X86, W: Load, const QT: usize, const K: usize>(l: &Dense<'_, W>, p: &Pass<'_, W>, out: *mut f32, os: usize) {
    let (n, all) = (l.n_out, L::mask(L::N));
    // SAFETY: each tile stays below `n_out` (full tiles by the loop bounds, the rest masked; a narrow
    // layer is `n_out` wide) and below `PACKET` queries.
    unsafe {
        match n {
            1 => return packet_narrow::<L, W, 1>(l, p, out, os),
            2 => return packet_narrow::<L, W, 2>(l, p, out, os),
            3 => return packet_narrow::<L, W, 3>(l, p, out, os),
            4 => return packet_narrow::<L, W, 4>(l, p, out, os),
            5 => return packet_narrow::<L, W, 5>(l, p, out, os),
            6 => return packet_narrow::<L, W, 6>(l, p, out, os),
            7 => return packet_narrow::<L, W, 7>(l, p, out, os),
            8 => return packet_narrow::<L, W, 8>(l, p, out, os),
            _ => {}
        }
        for q0 in (0..PACKET).step_by(QT) {
            let mut o = 0;
            while o + K * L::N <= n {
                packet_tile::<L, W, QT, K, false>(l, p, out, os, q0, o, [all; K]);
                o += K * L::N;
            }
            while o < n {
                packet_tile::<L, W, QT, 1, true>(l, p, out, os, q0, o, [L::mask(n - o)]);
                o += L::N;
            }
        }
    }
}

/// `PACKET` queries through the layer, every input row: the inputs are transposed feature-major
/// ([`X86::transpose`]) up to `XT_CAP` at a time, in segment order, and each full buffer (and the
/// last) runs every output tile (`packet_pass`). A longer layer passes its partial sums through `out`
/// (exact), the ReLU on the last pass only. `QT` and `K` are the level's tile ([`X86::QT`], [`X86::K`]).
///
/// # Safety
/// `l` passed `check(PACKET, ..)` for `out` with rows `os` apart; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn packet_dense<L: X86, W: Load, const QT: usize, const K: usize>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    const { assert!(QT == L::QT && K == L::K && PACKET.is_multiple_of(QT)) };
    #[repr(align(64))]
    struct Xt([MaybeUninit<f32>; XT_CAP * PACKET]);
    let mut xt = Xt([MaybeUninit::uninit(); XT_CAP * PACKET]);
    let xt = xt.0.as_mut_ptr().cast::<f32>();
    let mut pieces = [Piece { rows: core::ptr::null(), start: 0, n: 0 }; 2];
    let (mut np, mut used, mut first) = (0, 0, true);
    // SAFETY: the inputs transposed lie in the checked segments, within `xt`'s `XT_CAP` rows; the
    // passes' tiles as in `packet_pass`.
    unsafe {
        for s in &l.segs[..l.n_segs] {
            let mut i0 = 0;
            while i0 < s.n {
                if used == XT_CAP {
                    packet_pass::<L, W, QT, K>(l, &Pass { xt, pieces: &pieces[..np], first, relu: false }, out, os);
                    (np, used, first) = (0, 0, false);
                }
                let c = (s.n - i0).min(XT_CAP - used);
                L::transpose(s.x.as_ptr().add(i0), s.stride, c, xt.add(used * PACKET));
                pieces[np] = Piece { rows: s.rows.as_ptr().add(i0 * l.n_out), start: used, n: c };
                (np, used, i0) = (np + 1, used + c, i0 + c);
            }
        }
        packet_pass::<L, W, QT, K>(l, &Pass { xt, pieces: &pieces[..np], first, relu: l.relu }, out, os);
    }
}

/// Weight rows per block of the sparse packet kernel: 64 rows of 128 f32 weights (32 KB, the L1 of
/// Zen 4 and of recent Intel cores) serve all 16 queries before the next block is read
/// (docs/speed.md has the block sizes tried).
const SPARSE_BLOCK: usize = 64;

/// Outputs of the layers the sparse packet kernel runs (the paper's hidden width).
pub(super) const SPARSE_WIDTH: usize = 128;

/// Blocks of inputs a sparse packet layer may have: `SPARSE_MAX_BLOCKS × SPARSE_BLOCK` (512) inputs
/// over its segments, far more than the paper-size networks' 128 + 36; a layer with more runs dense.
const SPARSE_MAX_BLOCKS: usize = 8;

/// The share of nonzero inputs (numerator over 16) at or below which a 128-wide packet layer runs
/// sparse: an FMA of the sparse kernel costs more than one of the dense kernel (each needs its own
/// weight load, and the branch that ends each query's list mispredicts), so it pays below ~3/4 nonzero
/// (docs/speed.md: the thresholds tried).
const SPARSE_AT_MOST: usize = 12;

/// Each query's nonzero inputs of a packet layer, block by block in the order of the sparse walk, and
/// their count: made once per layer, for the choice of kernel and for the walk.
struct LayerMasks {
    nz: [[u64; PACKET]; SPARSE_MAX_BLOCKS],
    /// Nonzero inputs over all blocks and queries, and inputs.
    nonzero: usize,
    total: usize,
}

/// Fills `m` with the masks of `l`'s inputs ([`X86::nonzero`] per block of each query); `false` where
/// the layer has more than `SPARSE_MAX_BLOCKS` blocks (`m` then partly filled). Taking them once both
/// chooses the kernel and feeds the walk; they are filled in place, as a returned kilobyte of masks
/// was copied.
///
/// # Safety
/// The layer passed `check(PACKET, ..)`; the CPU has `L`'s level.
#[inline(always)]
unsafe fn layer_masks<L: X86, W>(l: &Dense<'_, W>, m: &mut LayerMasks) -> bool {
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
                let v = unsafe { L::nonzero(s.x.as_ptr().add(q * s.stride + i0), n) };
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

/// One block of the sparse packet kernel's walk: up to `SPARSE_BLOCK` consecutive inputs of a segment,
/// query `q`'s at `x + q * stride`, against their weight rows `rows` (128 f32 each; of f16 weights
/// only the rows some query's `nz` lists are widened).
pub(super) struct SparseBlock {
    pub(super) x: *const f32,
    pub(super) stride: usize,
    pub(super) rows: *const f32,
    /// The layer's first block: the queries start from `init`, later ones from their partial sums.
    pub(super) first: bool,
    /// The layer's last block: the ReLU follows.
    pub(super) last: bool,
    /// Each query's nonzero inputs of the block (bit `j` for input `j`; NaN counts).
    pub(super) nz: [u64; PACKET],
}

/// `PACKET` queries through the layer: 128-wide ReLU layers whose inputs are mostly zeros by
/// `packet_sparse` (every such layer whose masks fit where `always`, for the tests), the rest by
/// [`packet_dense`] ([`X86::packet_dense`]). Both give each query the operations of the one-query
/// kernel, so the choice never changes a bit.
///
/// # Safety
/// As [`packet_dense`].
#[inline(always)]
pub(super) unsafe fn packet<L: X86, W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize, always: bool) {
    if l.n_out == SPARSE_WIDTH && l.relu {
        let mut m = LayerMasks { nz: [[0; PACKET]; SPARSE_MAX_BLOCKS], nonzero: 0, total: 0 };
        // SAFETY: the contract, passed on; the masks are the layer's.
        unsafe {
            if layer_masks::<L, W>(l, &mut m) && (always || 16 * m.nonzero <= SPARSE_AT_MOST * m.total) {
                return packet_sparse::<L, W>(l, out, os, &m);
            }
        }
    }
    // SAFETY: the contract, passed on.
    unsafe { L::packet_dense(l, out, os) }
}

/// `PACKET` queries through a 128-wide layer one query at a time, lanes for outputs (8 accumulators),
/// one FMA per nonzero input in row order: the operations of the one-query kernel, here with the
/// inputs' zeros skipped for every query (about half of them after a ReLU), so half the FMAs of
/// `packet_dense`. The weights go in blocks of `SPARSE_BLOCK` rows, each segment's in order (of f16
/// ones, the rows some query uses widened into an f32 block first: the 16 queries of a packet share a
/// point, and some units are off for all of them), each block used by all the queries while it is in
/// L1 (`sparse_block`); a query's partial sums wait in its outputs between blocks. A layer without
/// inputs gets the ReLU of `init`.
///
/// # Safety
/// As [`packet_dense`], with `l.n_out == 128`; `masks` are the layer's (`layer_masks`).
#[inline(always)]
unsafe fn packet_sparse<L: X86, W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize, masks: &LayerMasks) {
    const C: usize = SPARSE_WIDTH;
    #[repr(align(64))]
    struct Wide([MaybeUninit<f32>; SPARSE_BLOCK * C]);
    let mut wide = Wide([MaybeUninit::uninit(); SPARSE_BLOCK * C]);
    let wide = wide.0.as_mut_ptr().cast::<f32>();
    let (mut first, mut b) = (true, 0);
    // The ReLU follows the last block of the last segment that has inputs (a skip layer's tail may be
    // empty).
    let last_seg = l.segs[..l.n_segs].iter().rposition(|s| s.n > 0);
    for (si, s) in l.segs[..l.n_segs].iter().enumerate() {
        let mut i0 = 0;
        while i0 < s.n {
            let n = (s.n - i0).min(SPARSE_BLOCK);
            // SAFETY: inputs and rows `i0 .. i0 + n` lie in the checked segment.
            let (x, rows) = unsafe { (s.x.as_ptr().add(i0), s.rows.as_ptr().add(i0 * C)) };
            let nz = masks.nz[b];
            let rows = match W::as_f32(&[]) {
                Some(_) => rows.cast::<f32>(),
                None => {
                    let mut used = nz.iter().fold(0, |u, m| u | m);
                    while used != 0 {
                        let j = used.trailing_zeros() as usize;
                        used &= used - 1;
                        for k in 0..C / L::N {
                            // SAFETY: row `j < n` of the block, and of the copy (`SPARSE_BLOCK` rows).
                            unsafe { L::store(wide.add(j * C + L::N * k), W::load::<L>(rows.add(j * C + L::N * k))) };
                        }
                    }
                    wide.cast_const()
                }
            };
            let last = Some(si) == last_seg && i0 + n == s.n;
            // SAFETY: a block of the checked layer; query `q`'s outputs lie at `out + q os ..+ 128`.
            unsafe { sparse_block::<L>(l.init.as_ptr(), &SparseBlock { x, stride: s.stride, rows, first, last, nz }, out, os) };
            first = false;
            b += 1;
            i0 += n;
        }
    }
    if first {
        for q in 0..PACKET {
            for (o, &v) in l.init[..C].iter().enumerate() {
                // SAFETY: query `q`'s outputs lie at `out + q os ..+ 128` (`check`).
                unsafe { *out.add(q * os + o) = if v > 0.0 { v } else { 0.0 } };
            }
        }
    }
}

/// The packet's queries over one block of `packet_sparse`, in neighbouring pairs: together where the
/// level walks them so ([`X86::sparse_pair`]), else one after the other.
///
/// # Safety
/// As `sparse_one`, for every query (query `q`'s outputs at `out + q os`).
#[inline(always)]
unsafe fn sparse_block<L: X86>(init: *const f32, b: &SparseBlock, out: *mut f32, os: usize) {
    const { assert!(PACKET.is_multiple_of(2)) };
    for q in (0..PACKET).step_by(2) {
        // SAFETY: the contract, for queries `q` and `q + 1`.
        unsafe {
            let (oa, ob) = (out.add(q * os), out.add((q + 1) * os));
            if !L::sparse_pair(init, b, oa, ob, q) {
                sparse_one::<L>(init, b, oa, q);
                sparse_one::<L>(init, b, ob, q + 1);
            }
        }
    }
}

/// Query `q` of a block of `packet_sparse`: one FMA per nonzero input and output vector, in row order,
/// from `init` (the first block) or the partial sums at `o`, back to `o`; 8 vectors of outputs at a
/// time (AVX2: twice).
///
/// # Safety
/// `b` is a block of `packet_sparse`, `init` and `o` hold 128 values; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn sparse_one<L: X86>(init: *const f32, b: &SparseBlock, o: *mut f32, q: usize) {
    const C: usize = SPARSE_WIDTH;
    // SAFETY: see the contract; the rows `b.nz[q]` lists lie in the block.
    unsafe {
        let x = b.x.add(q * b.stride);
        for h in (0..C).step_by(8 * L::N) {
            let from = if b.first { init } else { o.cast_const() }.add(h);
            let mut acc = [L::splat(0.0); 8];
            for (k, a) in acc.iter_mut().enumerate() {
                *a = L::load(from.add(L::N * k));
            }
            let mut nz = b.nz[q];
            while nz != 0 {
                let j = nz.trailing_zeros() as usize;
                nz &= nz - 1;
                let xb = L::splat(*x.add(j));
                let r = b.rows.add(j * C + h);
                for (k, a) in acc.iter_mut().enumerate() {
                    *a = L::mul_add(xb, L::load(r.add(L::N * k)), *a);
                }
            }
            relu_store::<L, 8>(acc, b.last, o.add(h));
        }
    }
}

/// Stores `K` vectors of sums at `o`, after a ReLU where `relu`.
///
/// # Safety
/// `o` has room for `K N` values; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn relu_store<L: X86, const K: usize>(acc: [L::V; K], relu: bool, o: *mut f32) {
    for (k, a) in acc.iter().enumerate() {
        // SAFETY: see the contract.
        unsafe { L::store(o.add(L::N * k), relu_if::<L>(*a, relu)) };
    }
}

/// `dst[i] = src[i]` widened, `N` values per `vcvtph2ps` ([`X86::load_f16`]), the tail as scalars.
///
/// # Safety
/// `src` and `dst` have the same length; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn widen_f16<L: X86>(src: &[half::f16], dst: &mut [f32]) {
    let body = src.len() / L::N * L::N;
    for i in (0..body).step_by(L::N) {
        // SAFETY: `i + N ≤ body ≤` both lengths; unaligned loads and stores.
        unsafe { L::store(dst.as_mut_ptr().add(i), L::load_f16(src.as_ptr().add(i))) };
    }
    for i in body..src.len() {
        dst[i] = src[i].to_f32();
    }
}
