//! The dense products of a training step on a block of rows, with the layer's epilogue (bias, ReLU,
//! ReLU mask) applied before the block is stored (issue 8).
//!
//! Every product of a step is tall and skinny: a batch of 2^15 rows against a layer matrix of at most
//! ~200 × 128 values. Layer by layer, each product streams its `[2^15, 128]` operands (16 MiB, half the
//! L3) from memory, and then an elementwise pass streams them again for the bias and ReLU: the `gemm`
//! crate reached ~75% of the two cores' FMA peak on these shapes here, against ~94% on the same shapes
//! in cache. [`super::network`] therefore runs a network's layers on blocks of a few hundred rows that
//! stay in L2 from one layer to the next, and needs single-threaded products on such a block whose
//! epilogue does the elementwise work while the values are still in registers. No crate offers a GEMM
//! with a caller-defined epilogue or a two-part left-hand side (the skip layer's `[h, x]`), so this
//! module has its own AVX-512 kernels, chosen at run time; elsewhere the `gemm` crate computes the
//! product and a scalar pass the epilogue.
//!
//! Order of sums: an output element is the fused multiply-add chain over the inner index in order,
//! `((0 + a_0 b_0) + a_1 b_1) + …`, whatever the block and tile sizes; a weight gradient over a block of
//! rows is the chain over the rows in order. So a product computed per layer and the same product
//! computed per row block agree to the last bit, and a step is bitwise reproducible for any number of
//! threads.

/// The matrix side of a product: `rows × cols` f32 values at `ptr`, row-major with row stride `ld`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mat {
    pub ptr: *const f32,
    pub ld: usize,
}

// SAFETY: a `Mat` is an address and a stride, read only under the contract of the unsafe function it
// is passed to; sending it to the threads of a row-block loop is what it is for.
unsafe impl Send for Mat {}
unsafe impl Sync for Mat {}

impl Mat {
    /// The row-major matrix `data` with row stride `ld`.
    #[inline]
    pub fn new(data: &[f32], ld: usize) -> Mat {
        Mat { ptr: data.as_ptr(), ld }
    }

    /// The same matrix from row `r` and column `c` on.
    ///
    /// # Safety
    /// `r · ld + c` must be within the allocation.
    #[inline]
    pub unsafe fn at(self, r: usize, c: usize) -> Mat {
        // SAFETY: forwarded from the caller.
        Mat { ptr: unsafe { self.ptr.add(r * self.ld + c) }, ld: self.ld }
    }
}

/// An output buffer that the tasks of a row-block loop write in disjoint row ranges.
#[derive(Clone, Copy)]
pub(crate) struct Shared(pub *mut f32);
// SAFETY: the loops that share one write only their own rows (their callers' SAFETY comments).
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    /// The address `i` values in. A method, so that a closure captures the whole `Shared` (which is
    /// `Sync`), not its raw pointer field.
    ///
    /// # Safety
    /// `i` must be within the buffer.
    #[inline]
    pub unsafe fn add(self, i: usize) -> *mut f32 {
        // SAFETY: forwarded from the caller.
        unsafe { self.0.add(i) }
    }
}

/// What happens to a block's product `P` before it is stored in `C`:
/// `C ← mask(act(P [+ C] [+ bias]))`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Epilogue {
    /// Add the values already in `C` (`C += P`); otherwise `C` is written without being read.
    pub accumulate: bool,
    /// Add this row vector (`cols` values) to every row.
    pub bias: Option<*const f32>,
    /// `max(·, 0)`.
    pub relu: bool,
    /// A matrix the shape of `C`: zero `C` where it is not `> 0` (a ReLU layer's backward, PyTorch's
    /// `threshold_backward` convention: gradient 0 where the activation is 0).
    pub mask: Option<Mat>,
}

// SAFETY: as for `Mat`: addresses read only under the contract of the function they are passed to.
unsafe impl Send for Epilogue {}
unsafe impl Sync for Epilogue {}

impl Epilogue {
    /// `C ← P`.
    pub const STORE: Epilogue = Epilogue { accumulate: false, bias: None, relu: false, mask: None };
    /// `C ← C + P`.
    pub const ADD: Epilogue = Epilogue { accumulate: true, bias: None, relu: false, mask: None };
}

/// Whether the AVX-512 kernels run: the CPU has them and `NBRDF_KERNEL` does not ask for a lower
/// level (the core's [`nbrdf::kernels::detected`], so one host tests both paths).
pub(crate) fn avx512() -> bool {
    nbrdf::kernels::detected() >= nbrdf::kernels::Level::Avx512
}

/// `C [rows × cols] ← epilogue(A1 [rows × p1] · B[0..p1] + A2 [rows × p2] · B[p1..p1 + p2])`, with `B`
/// row-major `[(p1 + p2) × cols]`: one thread, one block of rows. `A2` (`p2 > 0`) is the second part of
/// a left-hand side stored as two matrices, the skip layer's `[h, x]`; its sums continue the chain of
/// `A1`'s, as if the two were one matrix.
///
/// # Safety
/// `a1`, `a2`, `b`, `c` and a mask must address the rows and columns named, `c` writable and, when the
/// epilogue accumulates, initialised; a bias must hold `cols` values. `c` must not overlap the inputs.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    if rows == 0 || cols == 0 {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if avx512() {
        // SAFETY: the CPU has AVX-512F (checked); the memory contract is the caller's.
        unsafe { x86::product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) };
        return;
    }
    // SAFETY: forwarded from the caller.
    unsafe { portable_product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// `W [k × m] += Aᵀ G` (`accumulate`) or `W = Aᵀ G` over one block of rows (`A [rows × k]`,
/// `G [rows × m]`), `W` row-major with row stride `m`: a layer's weight gradient, one thread. Without
/// `accumulate` the sums start from the first row's product, as they would from a zeroed `W`, and `W`
/// need not be initialised.
///
/// # Safety
/// `a` and `g` must address `rows` rows of `k` and `m` values, `w` `k × m` values (initialised when
/// `accumulate`) that overlap neither.
pub(crate) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    if k == 0 || m == 0 {
        return;
    }
    if rows == 0 {
        if !accumulate {
            // SAFETY: w holds k × m values (the caller's contract).
            unsafe { std::ptr::write_bytes(w, 0, k * m) };
        }
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if avx512() {
        // SAFETY: the CPU has AVX-512F (checked); the memory contract is the caller's.
        unsafe { x86::weight_product(rows, k, m, a, g, w, accumulate) };
        return;
    }
    // SAFETY: forwarded from the caller; gemm reads A transposed (row stride 1, column stride lda).
    unsafe {
        gemm::gemm(k, m, rows, w, 1, m as isize, accumulate, a.ptr, a.ld as isize, 1, g.ptr, 1, g.ld as isize, 1.0, 1.0, false, false, false, gemm::Parallelism::None)
    }
}

/// [`product`] through the `gemm` crate and a scalar epilogue, for CPUs without AVX-512.
#[allow(clippy::too_many_arguments)]
unsafe fn portable_product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded from the caller; C is written (or read and written) row-major with stride ldc.
    unsafe {
        let par = gemm::Parallelism::None;
        let mut read = epi.accumulate;
        for (a, p, b) in [(a1, p1, b), (a2, p2, b.at(p1, 0))] {
            if p > 0 {
                gemm::gemm(rows, cols, p, c, 1, ldc as isize, read, a.ptr, 1, a.ld as isize, b.ptr, 1, b.ld as isize, 1.0, 1.0, false, false, false, par);
                read = true;
            }
        }
        for r in 0..rows {
            let row = std::slice::from_raw_parts_mut(c.add(r * ldc), cols);
            if !read {
                row.fill(0.0);
            }
            for (j, v) in row.iter_mut().enumerate() {
                let mut z = *v + epi.bias.map_or(0.0, |bias| *bias.add(j));
                if epi.relu {
                    z = z.max(0.0);
                }
                if let Some(m) = epi.mask {
                    // Not `> 0`, NaN included, as the vector compare.
                    let mv = *m.ptr.add(r * m.ld + j);
                    if mv.is_nan() || mv <= 0.0 {
                        z = 0.0;
                    }
                }
                *v = z;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! The AVX-512 kernels: a tile of up to 6 rows × 4 vectors (64 columns) of accumulators, 24 of
    //! the 32 registers (24 rows × 1 vector where the columns are one vector, `NARROW_MR`); per inner
    //! index 4 loads of `B`, 6 broadcasts of `A` and 24 FMAs, which keeps Zen 4's one 512-bit FMA per
    //! cycle busy (~94% of peak in cache), and an Intel Xeon's two at 150-165 GFLOP/s per core in cache
    //! (256 rows by a 128 × 128 matrix; the same tile in C: 174). Edge tiles use masks; full ones do
    //! not (see `load!`).
    use super::{Epilogue, Mat};
    use std::arch::x86_64::*;

    /// Rows per tile.
    const MR: usize = 6;
    /// Rows per tile where the columns are one vector (a network's output layer, 3 or 6 wide): a
    /// 6 × 1 tile has only 6 independent FMA chains, too few for two FMA ports of 4-cycle latency
    /// (8 in flight), and pays a masked `B` load per 6 FMAs; 24 rows keep 24 chains in 24 of the 32
    /// registers. The same in a weight gradient whose layer has at most 16 outputs, along its inputs.
    const NARROW_MR: usize = 24;
    /// Columns per tile (four vectors).
    const NR: usize = 64;

    /// The lane masks of a tile's vectors when `left` columns remain.
    #[inline(always)]
    fn masks(left: usize) -> [u16; 4] {
        core::array::from_fn(|j| {
            let l = left.saturating_sub(16 * j).min(16);
            if l == 16 {
                u16::MAX
            } else {
                ((1u32 << l) - 1) as u16
            }
        })
    }

    /// Loads 16 values, or the lanes of `m` (the rest zero) unless the tile is `FULL`: on Intel cores
    /// a masked 512-bit load in the inner loop costs the product ~14% (150 against 174 GFLOP/s for a
    /// 6 × 4 tile in cache, measured in C on this project's Xeon), so full tiles load without one.
    macro_rules! load {
        ($full:expr, $m:expr, $p:expr) => {
            if $full {
                _mm512_loadu_ps($p)
            } else {
                _mm512_maskz_loadu_ps($m, $p)
            }
        };
    }

    /// One tile: `R` rows × `V` vectors; `FULL`: every lane of every vector (`m` all ones).
    #[target_feature(enable = "avx512f")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn tile<const R: usize, const V: usize, const FULL: bool>(a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, m: [u16; 4], epi: Epilogue) {
        // SAFETY (whole body): every address is within the tile the caller names (its contract);
        // masked lanes are neither read nor written.
        unsafe {
            // Built whole rather than zeroed and then overwritten in place, and the epilogue walks it
            // by iterators: the old form left the 6 × 3, 6 × 4 and 5 × 4 tiles a stack copy of the
            // accumulators (a 1.5 KiB memset per tile, stores and reloads around the sweeps). Without
            // it a 256 × 128 × 128 product runs 1.07× as fast, the masked backward one 1.13× (best of
            // six, alternating in one session).
            let mut acc: [[__m512; V]; R] = core::array::from_fn(|r| {
                core::array::from_fn(|j| if epi.accumulate { _mm512_maskz_loadu_ps(m[j], c.add(r * ldc + 16 * j)) } else { _mm512_setzero_ps() })
            });
            let brow = sweep::<R, V, FULL>(&mut acc, a1, p1, b.ptr, b.ld, m);
            sweep::<R, V, FULL>(&mut acc, a2, p2, brow, b.ld, m);
            let zero = _mm512_setzero_ps();
            let bias: [__m512; V] = core::array::from_fn(|j| match epi.bias {
                Some(bias) => _mm512_maskz_loadu_ps(m[j], bias.add(16 * j)),
                None => zero,
            });
            for (r, acc) in acc.iter().enumerate() {
                for (j, (&v, &bias)) in acc.iter().zip(&bias).enumerate() {
                    let mut v = v;
                    if epi.bias.is_some() {
                        v = _mm512_add_ps(v, bias);
                    }
                    if epi.relu {
                        v = _mm512_max_ps(v, zero);
                    }
                    if let Some(mask) = epi.mask {
                        let keep = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(_mm512_maskz_loadu_ps(m[j], mask.ptr.add(r * mask.ld + 16 * j)), zero);
                        v = _mm512_maskz_mov_ps(keep, v);
                    }
                    _mm512_mask_storeu_ps(c.add(r * ldc + 16 * j), m[j], v);
                }
            }
        }
    }

    /// The inner products of a tile over the `p` columns of one part of its input, `b` at `brow`
    /// (row stride `ldb`): returns the next row of `b`.
    #[inline(always)]
    unsafe fn sweep<const R: usize, const V: usize, const FULL: bool>(acc: &mut [[__m512; V]; R], a: Mat, p: usize, mut brow: *const f32, ldb: usize, m: [u16; 4]) -> *const f32 {
        // SAFETY (whole body): the caller's tile contract covers `p` rows of `a` and `b`.
        unsafe {
            for q in 0..p {
                let mut bv = [_mm512_setzero_ps(); V];
                for (j, v) in bv.iter_mut().enumerate() {
                    *v = load!(FULL, m[j], brow.add(16 * j));
                }
                for (r, acc) in acc.iter_mut().enumerate() {
                    let av = _mm512_set1_ps(*a.ptr.add(r * a.ld + q));
                    for (v, &bj) in acc.iter_mut().zip(&bv) {
                        *v = _mm512_fmadd_ps(av, bj, *v);
                    }
                }
                brow = brow.add(ldb);
            }
            brow
        }
    }

    /// Calls `$f::<R, V, FULL>` for the runtime `rows` (1..=6), `vecs` (1..=4) and lane masks `m`:
    /// the unmasked kernel for the tiles of all 6 rows whose vectors are all full (the bulk of every
    /// product), the masked one for the edges.
    macro_rules! dispatch {
        ($f:ident, $rows:expr, $vecs:expr, $m:expr, ($($arg:expr),*)) => {{
            let full = $m[..$vecs].iter().all(|&l| l == u16::MAX);
            match ($rows, $vecs) {
                (6.., 1) if full => $f::<6, 1, true>($($arg),*), (6.., 2) if full => $f::<6, 2, true>($($arg),*),
                (6.., 3) if full => $f::<6, 3, true>($($arg),*), (6.., _) if full => $f::<6, 4, true>($($arg),*),
                (1, 1) => $f::<1, 1, false>($($arg),*), (1, 2) => $f::<1, 2, false>($($arg),*), (1, 3) => $f::<1, 3, false>($($arg),*), (1, _) => $f::<1, 4, false>($($arg),*),
                (2, 1) => $f::<2, 1, false>($($arg),*), (2, 2) => $f::<2, 2, false>($($arg),*), (2, 3) => $f::<2, 3, false>($($arg),*), (2, _) => $f::<2, 4, false>($($arg),*),
                (3, 1) => $f::<3, 1, false>($($arg),*), (3, 2) => $f::<3, 2, false>($($arg),*), (3, 3) => $f::<3, 3, false>($($arg),*), (3, _) => $f::<3, 4, false>($($arg),*),
                (4, 1) => $f::<4, 1, false>($($arg),*), (4, 2) => $f::<4, 2, false>($($arg),*), (4, 3) => $f::<4, 3, false>($($arg),*), (4, _) => $f::<4, 4, false>($($arg),*),
                (5, 1) => $f::<5, 1, false>($($arg),*), (5, 2) => $f::<5, 2, false>($($arg),*), (5, 3) => $f::<5, 3, false>($($arg),*), (5, _) => $f::<5, 4, false>($($arg),*),
                (_, 1) => $f::<6, 1, false>($($arg),*), (_, 2) => $f::<6, 2, false>($($arg),*), (_, 3) => $f::<6, 3, false>($($arg),*), (_, _) => $f::<6, 4, false>($($arg),*),
            }
        }};
    }

    /// [`super::product`] on AVX-512: column panels of 64, each swept by tiles of 6 rows, so a panel of
    /// `B` (≤ 50 KiB) is reused from L1/L2 by every tile of the block.
    #[target_feature(enable = "avx512f")]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
        // SAFETY: every tile lies within the block the caller names.
        unsafe {
            for c0 in (0..cols).step_by(NR) {
                let m = masks(cols - c0);
                let vecs = (cols - c0).min(NR).div_ceil(16);
                let epi_c = Epilogue { bias: epi.bias.map(|p| p.add(c0)), mask: epi.mask.map(|k| k.at(0, c0)), ..epi };
                let mut start = 0;
                if vecs == 1 {
                    while rows - start >= NARROW_MR {
                        let epi_t = Epilogue { mask: epi_c.mask.map(|k| k.at(start, 0)), ..epi_c };
                        let args = (a1.at(start, 0), p1, a2.at(start, 0), p2, b.at(0, c0), c.add(start * ldc + c0), ldc, m, epi_t);
                        if m[0] == u16::MAX {
                            tile::<NARROW_MR, 1, true>(args.0, args.1, args.2, args.3, args.4, args.5, args.6, args.7, args.8);
                        } else {
                            tile::<NARROW_MR, 1, false>(args.0, args.1, args.2, args.3, args.4, args.5, args.6, args.7, args.8);
                        }
                        start += NARROW_MR;
                    }
                }
                for r0 in (start..rows).step_by(MR) {
                    let epi_t = Epilogue { mask: epi_c.mask.map(|k| k.at(r0, 0)), ..epi_c };
                    let args = (a1.at(r0, 0), p1, a2.at(r0, 0), p2, b.at(0, c0), c.add(r0 * ldc + c0), ldc, m, epi_t);
                    dispatch!(tile, rows - r0, vecs, m, (args.0, args.1, args.2, args.3, args.4, args.5, args.6, args.7, args.8));
                }
            }
        }
    }

    /// One tile of a weight gradient: `W[R × V·16] += Σ_rows a[row, 0..R]ᵀ g[row, ..]`.
    #[target_feature(enable = "avx512f")]
    unsafe fn weight_tile<const R: usize, const V: usize, const FULL: bool>(rows: usize, a: Mat, g: Mat, w: *mut f32, ldw: usize, m: [u16; 4], accumulate: bool) {
        // SAFETY (whole body): within the tile the caller names; masked lanes untouched.
        unsafe {
            let mut acc = [[_mm512_setzero_ps(); V]; R];
            for (r, acc) in acc.iter_mut().enumerate().filter(|_| accumulate) {
                for (j, v) in acc.iter_mut().enumerate() {
                    *v = _mm512_maskz_loadu_ps(m[j], w.add(r * ldw + 16 * j));
                }
            }
            for i in 0..rows {
                let gi = g.ptr.add(i * g.ld);
                let mut gv = [_mm512_setzero_ps(); V];
                for (j, v) in gv.iter_mut().enumerate() {
                    *v = load!(FULL, m[j], gi.add(16 * j));
                }
                let ai = a.ptr.add(i * a.ld);
                for (r, acc) in acc.iter_mut().enumerate() {
                    let av = _mm512_set1_ps(*ai.add(r));
                    for (v, &gj) in acc.iter_mut().zip(&gv) {
                        *v = _mm512_fmadd_ps(av, gj, *v);
                    }
                }
            }
            for (r, acc) in acc.iter().enumerate() {
                for (j, v) in acc.iter().enumerate() {
                    _mm512_mask_storeu_ps(w.add(r * ldw + 16 * j), m[j], *v);
                }
            }
        }
    }

    /// Rows of `A` and `G` per sweep of the weight tiles: 2 × 128 KiB at 128 columns, in L2.
    const W_ROWS: usize = 256;

    /// [`super::weight_product`] on AVX-512.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
        // SAFETY: every tile lies within the matrices the caller names.
        unsafe {
            for i0 in (0..rows).step_by(W_ROWS) {
                let n = W_ROWS.min(rows - i0);
                let mut start = 0;
                if m <= 16 {
                    let mask = masks(m);
                    while k - start >= NARROW_MR {
                        let args = (n, a.at(i0, start), g.at(i0, 0), w.add(start * m), m, mask, accumulate || i0 > 0);
                        if m == 16 {
                            weight_tile::<NARROW_MR, 1, true>(args.0, args.1, args.2, args.3, args.4, args.5, args.6);
                        } else {
                            weight_tile::<NARROW_MR, 1, false>(args.0, args.1, args.2, args.3, args.4, args.5, args.6);
                        }
                        start += NARROW_MR;
                    }
                }
                for k0 in (start..k).step_by(MR) {
                    for c0 in (0..m).step_by(NR) {
                        let mask = masks(m - c0);
                        let vecs = (m - c0).min(NR).div_ceil(16);
                        let args = (n, a.at(i0, k0), g.at(i0, c0), w.add(k0 * m + c0), m, mask, accumulate || i0 > 0);
                        dispatch!(weight_tile, k - k0, vecs, mask, (args.0, args.1, args.2, args.3, args.4, args.5, args.6));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible spread of values in [-1, 1), a quarter of them exactly 0 (ReLU kinks).
    fn values(n: usize, seed: u32) -> Vec<f32> {
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                if s.is_multiple_of(4) {
                    0.0
                } else {
                    (s >> 8) as f32 / (1u32 << 23) as f32 - 1.0
                }
            })
            .collect()
    }

    /// `epilogue([a1, a2] · b)` in f64, the definition the kernels must meet.
    #[allow(clippy::too_many_arguments)]
    fn reference(rows: usize, cols: usize, a1: &[f32], p1: usize, a2: &[f32], p2: usize, b: &[f32], c0: &[f32], bias: &[f32], mask: &[f32], epi: Epilogue) -> Vec<f64> {
        let mut out = vec![0.0f64; rows * cols];
        for r in 0..rows {
            for j in 0..cols {
                let mut v: f64 = (0..p1).map(|q| a1[r * p1 + q] as f64 * b[q * cols + j] as f64).sum();
                v += (0..p2).map(|q| a2[r * p2 + q] as f64 * b[(p1 + q) * cols + j] as f64).sum::<f64>();
                if epi.accumulate {
                    v += c0[r * cols + j] as f64;
                }
                if epi.bias.is_some() {
                    v += bias[j] as f64;
                }
                if epi.relu {
                    v = v.max(0.0);
                }
                if epi.mask.is_some() && mask[r * cols + j] <= 0.0 {
                    v = 0.0;
                }
                out[r * cols + j] = v;
            }
        }
        out
    }

    #[test]
    fn product_meets_its_definition_on_every_tile_shape() {
        // Rows and columns that leave partial tiles (1..5 rows, 1..3 vectors, masked lanes), a skip
        // layer's two-part input, and each epilogue.
        for &(rows, cols, p1, p2) in &[(1, 1, 1, 0), (7, 3, 5, 0), (13, 17, 9, 4), (6, 64, 128, 0), (25, 130, 40, 27), (12, 128, 128, 68), (53, 3, 128, 0), (50, 16, 20, 7)] {
            let (a1, a2, b) = (values(rows * p1, 1), values(rows * p2, 2), values((p1 + p2) * cols, 3));
            let (c0, bias, mask) = (values(rows * cols, 4), values(cols, 5), values(rows * cols, 6));
            let epilogues = [
                Epilogue::STORE,
                Epilogue::ADD,
                Epilogue { bias: Some(bias.as_ptr()), relu: true, ..Epilogue::STORE },
                Epilogue { mask: Some(Mat::new(&mask, cols)), ..Epilogue::STORE },
            ];
            for epi in epilogues {
                let want = reference(rows, cols, &a1, p1, &a2, p2, &b, &c0, &bias, &mask, epi);
                for portable in [false, true] {
                    let mut c = c0.clone();
                    let (m1, m2, mb) = (Mat::new(&a1, p1), Mat::new(&a2, p2), Mat::new(&b, cols));
                    // SAFETY: the matrices hold the rows and columns named; c is rows × cols.
                    unsafe {
                        if portable {
                            portable_product(rows, cols, m1, p1, m2, p2, mb, c.as_mut_ptr(), cols, epi)
                        } else {
                            product(rows, cols, m1, p1, m2, p2, mb, c.as_mut_ptr(), cols, epi)
                        }
                    }
                    let scale = (p1 + p2) as f64 * 1e-6 + 1e-6;
                    for (i, (&got, &w)) in c.iter().zip(&want).enumerate() {
                        assert!((got as f64 - w).abs() <= scale, "{rows}x{cols} p {p1}+{p2} {epi:?} portable {portable}: [{i}] {got} vs {w}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_product_by_row_blocks_is_the_whole_product_bit_for_bit() {
        // The whole-network op computes a layer block by block; the per-layer path all at once.
        let (rows, cols, p) = (50, 70, 33);
        let (a, b) = (values(rows * p, 7), values(p * cols, 8));
        let mut whole = vec![0.0f32; rows * cols];
        let mut blocks = vec![0.0f32; rows * cols];
        let (ma, mb) = (Mat::new(&a, p), Mat::new(&b, cols));
        // SAFETY: a is rows × p, b p × cols, the outputs rows × cols; each block's rows are in range.
        unsafe {
            product(rows, cols, ma, p, ma, 0, mb, whole.as_mut_ptr(), cols, Epilogue::STORE);
            for r0 in (0..rows).step_by(11) {
                product(11.min(rows - r0), cols, ma.at(r0, 0), p, ma, 0, mb, blocks.as_mut_ptr().add(r0 * cols), cols, Epilogue::STORE);
            }
        }
        assert!(whole.iter().zip(&blocks).all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    #[test]
    fn weight_product_adds_the_transposed_product() {
        // 300 rows: more than one sweep of the kernel's row blocks; 70 columns and 13 weight rows
        // leave partial tiles; an output layer's 3 and 16 columns take the narrow tiles, 53 and 48
        // weight rows with and without a remainder.
        for (rows, k, m) in [(300, 13, 70), (300, 53, 3), (290, 48, 16)] {
            let (a, g, w0) = (values(rows * k, 9), values(rows * m, 10), values(k * m, 11));
            for accumulate in [true, false] {
                // Without `accumulate` the old values must not matter: start from NaN.
                let mut w = if accumulate { w0.clone() } else { vec![f32::NAN; k * m] };
                // SAFETY: a is rows × k, g rows × m, w k × m.
                unsafe { weight_product(rows, k, m, Mat::new(&a, k), Mat::new(&g, m), w.as_mut_ptr(), accumulate) };
                for i in 0..k {
                    for j in 0..m {
                        let start = if accumulate { w0[i * m + j] as f64 } else { 0.0 };
                        let want = start + (0..rows).map(|r| a[r * k + i] as f64 * g[r * m + j] as f64).sum::<f64>();
                        assert!((w[i * m + j] as f64 - want).abs() < 1e-4, "{k}x{m} accumulate {accumulate} [{i}, {j}] {} vs {want}", w[i * m + j]);
                    }
                }
            }
        }
    }
}
