//! The dense products written once over [`Tile`]: the workspace's lane trait ([`Lanes`], a vector
//! of `N` f32 lanes of one CPU level, shared with the core's kernels) with the level's register tile; `avx512.rs`, `avx2.rs`, `neon.rs` and `portable.rs` supply the lanes and the
//! entry points that instantiate this body with their level's instructions.
//!
//! Register tiles: `R` rows × `V` vectors of accumulators, `R ≤` [`Tile::MR`] and `V ≤` [`Tile::NV`]
//! (AVX-512: 6 × 4 of 32 registers; AVX2: 6 × 2 of 16; NEON: 6 × 4 of 32); per inner index `V` loads
//! of `B`, `R` broadcasts of `A` and `R·V` FMAs. Where the columns are one vector (a network's 3 or 6
//! outputs) a narrow tile of more rows (a const parameter of the entry points: stable Rust cannot size an
//! array by an associated const in a generic body) keeps enough independent FMA chains in flight. A panel
//! whose width is not a whole number of vectors runs on padded copies (its `B` columns zero-padded,
//! its `C` tile in a buffer on the stack), so no kernel needs a masked load.
//!
//! Order of sums: an output element is the multiply-add chain over the inner index in order,
//! `((0 + a_0 b_0) + a_1 b_1) + …`, whatever the block, panel and tile; a weight gradient's element
//! the chain over the rows in order. So at any one level a product computed whole and the same
//! product computed by row blocks agree to the last bit.
//!
//! Everything here is `#[inline(always)]` and generic; no closure holds a kernel loop (a closure is a
//! function of its own, compiled without the level's features wherever it is not inlined).

use nbrdf_lanes::Lanes;

use super::{Epilogue, Mat};

/// The register tile of a level's lanes ([`Lanes`], the workspace's lane trait shared with the core's
/// kernels).
///
/// # Safety
/// As [`Lanes`]: callers run the kernels only on CPUs that have the level.
pub(super) unsafe trait Tile: Lanes {
    /// Rows of a full tile (at most 6).
    const MR: usize;
    /// Vectors of a full tile (at most 4).
    const NV: usize;
}

/// The widest panel any level uses: 4 vectors of 16 lanes.
const PANEL_MAX: usize = 64;
/// Values of a padded `C` tile: the largest of `MR × panel` and `NARROW × N` over the levels.
const TILE_MAX: usize = 24 * 16;

/// One tile: `C[R × V·N] ← epi(C, A1 · B[0..p1] + A2 · B[p1..])`, `B` with row stride `ldb`.
///
/// # Safety
/// Every address within the tile must be valid (the callers' contract); the level's features present.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn tile<L: Tile, const R: usize, const V: usize>(a1: Mat, p1: usize, a2: Mat, p2: usize, b: *const f32, ldb: usize, c: *mut f32, ldc: usize, bias: Option<*const f32>, mask: Option<Mat>, accumulate: bool, relu: bool) {
    // SAFETY (whole body): the caller's tile contract.
    unsafe {
        let mut acc: [[L::V; V]; R] = core::array::from_fn(|r| core::array::from_fn(|j| if accumulate { L::load(c.add(r * ldc + j * L::N)) } else { L::zero() }));
        let brow = sweep::<L, R, V>(&mut acc, a1, p1, b, ldb);
        sweep::<L, R, V>(&mut acc, a2, p2, brow, ldb);
        let bias: [L::V; V] = core::array::from_fn(|j| bias.map_or(L::zero(), |p| L::load(p.add(j * L::N))));
        for (r, acc) in acc.iter().enumerate() {
            for (j, (&v, &bj)) in acc.iter().zip(&bias).enumerate() {
                let mut v = L::add(v, bj);
                if relu {
                    v = L::relu(v);
                }
                if let Some(m) = mask {
                    v = L::keep_positive(L::load(m.ptr.add(r * m.ld + j * L::N)), v);
                }
                L::store(c.add(r * ldc + j * L::N), v);
            }
        }
    }
}

/// The multiply-adds of a tile over the `p` columns of one part of its input, `B` from `brow` (row
/// stride `ldb`): returns the next row of `B`.
#[inline(always)]
unsafe fn sweep<L: Tile, const R: usize, const V: usize>(acc: &mut [[L::V; V]; R], a: Mat, p: usize, mut brow: *const f32, ldb: usize) -> *const f32 {
    // SAFETY (whole body): the caller's tile contract covers `p` rows of `a` and `B`.
    unsafe {
        for q in 0..p {
            let bv: [L::V; V] = core::array::from_fn(|j| L::load(brow.add(j * L::N)));
            for (r, acc) in acc.iter_mut().enumerate() {
                let av = L::splat(*a.ptr.add(r * a.ld + q));
                for (v, &bj) in acc.iter_mut().zip(&bv) {
                    *v = L::mul_add(av, bj, *v);
                }
            }
            brow = brow.add(ldb);
        }
        brow
    }
}

/// Calls `$f::<L, R, V>($args)` for the runtime `rows` (1..=6, or the narrow tile's `$narrow` with one vector) and
/// `vecs` (1..=4): the const parameters of a tile from its extent.
macro_rules! dispatch {
    ($f:ident, $L:ty, $narrow:expr, $rows:expr, $vecs:expr, ($($arg:expr),*)) => {
        match ($rows, $vecs) {
            (r, 1) if r == $narrow => $f::<$L, { $narrow }, 1>($($arg),*),
            (1, 1) => $f::<$L, 1, 1>($($arg),*), (1, 2) => $f::<$L, 1, 2>($($arg),*), (1, 3) => $f::<$L, 1, 3>($($arg),*), (1, _) => $f::<$L, 1, 4>($($arg),*),
            (2, 1) => $f::<$L, 2, 1>($($arg),*), (2, 2) => $f::<$L, 2, 2>($($arg),*), (2, 3) => $f::<$L, 2, 3>($($arg),*), (2, _) => $f::<$L, 2, 4>($($arg),*),
            (3, 1) => $f::<$L, 3, 1>($($arg),*), (3, 2) => $f::<$L, 3, 2>($($arg),*), (3, 3) => $f::<$L, 3, 3>($($arg),*), (3, _) => $f::<$L, 3, 4>($($arg),*),
            (4, 1) => $f::<$L, 4, 1>($($arg),*), (4, 2) => $f::<$L, 4, 2>($($arg),*), (4, 3) => $f::<$L, 4, 3>($($arg),*), (4, _) => $f::<$L, 4, 4>($($arg),*),
            (5, 1) => $f::<$L, 5, 1>($($arg),*), (5, 2) => $f::<$L, 5, 2>($($arg),*), (5, 3) => $f::<$L, 5, 3>($($arg),*), (5, _) => $f::<$L, 5, 4>($($arg),*),
            (_, 1) => $f::<$L, 6, 1>($($arg),*), (_, 2) => $f::<$L, 6, 2>($($arg),*), (_, 3) => $f::<$L, 6, 3>($($arg),*), (_, _) => $f::<$L, 6, 4>($($arg),*),
        }
    };
}

/// The rows of a tile that starts at row `r0` of a panel of `vecs` vectors: the narrow tile where the
/// panel is one vector and enough rows remain, else up to [`Tile::MR`].
#[inline(always)]
fn tile_rows<L: Tile, const NARROW: usize>(rows: usize, r0: usize, vecs: usize) -> usize {
    if vecs == 1 && rows - r0 >= NARROW {
        NARROW
    } else {
        (rows - r0).min(L::MR)
    }
}

/// `C [rows × cols] ← epi(A1 · B[0..p1] + A2 · B[p1..p1 + p2])` (see `super::product`) at level `L`:
/// column panels of [`Tile::NV`] vectors, each swept by tiles of rows, so that a panel of `B`
/// (≤ 50 KiB) is reused from L1/L2 by every tile of the block.
///
/// # Safety
/// As `super::product`; the CPU has `L`'s level.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product<L: Tile, const NARROW: usize>(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    let panel = L::NV * L::N;
    let p = p1 + p2;
    // SAFETY (whole body): every tile lies within the block the caller names; the padded copies hold
    // a whole number of vectors per row.
    unsafe {
        for c0 in (0..cols).step_by(panel) {
            let w = (cols - c0).min(panel);
            let vecs = w.div_ceil(L::N);
            let bias = epi.bias.map(|q| q.add(c0));
            if w % L::N == 0 {
                let mut r0 = 0;
                while r0 < rows {
                    let rt = tile_rows::<L, NARROW>(rows, r0, vecs);
                    let mask = epi.mask.map(|m| m.at(r0, c0));
                    let args = (a1.at(r0, 0), p1, a2.at(r0, 0), p2, b.ptr.add(c0), b.ld, c.add(r0 * ldc + c0), ldc, bias, mask, epi.accumulate, epi.relu);
                    dispatch!(tile, L, NARROW, rt, vecs, (args.0, args.1, args.2, args.3, args.4, args.5, args.6, args.7, args.8, args.9, args.10, args.11));
                    r0 += rt;
                }
                continue;
            }
            // A partial vector: B's columns, the bias, C and the mask through zero-padded copies.
            let ld = vecs * L::N;
            let mut bp = vec![0.0f32; p * ld];
            for (q, row) in bp.chunks_exact_mut(ld).enumerate() {
                core::ptr::copy_nonoverlapping(b.ptr.add(q * b.ld + c0), row.as_mut_ptr(), w);
            }
            let mut bias_p = [0.0f32; PANEL_MAX];
            if let Some(q) = bias {
                core::ptr::copy_nonoverlapping(q, bias_p.as_mut_ptr(), w);
            }
            let bias_p = bias.map(|_| bias_p.as_ptr());
            let (mut ct, mut mt) = ([0.0f32; TILE_MAX], [0.0f32; TILE_MAX]);
            let mut r0 = 0;
            while r0 < rows {
                let rt = tile_rows::<L, NARROW>(rows, r0, vecs);
                for r in 0..rt {
                    if epi.accumulate {
                        core::ptr::copy_nonoverlapping(c.add((r0 + r) * ldc + c0), ct.as_mut_ptr().add(r * ld), w);
                    }
                    if let Some(m) = epi.mask {
                        core::ptr::copy_nonoverlapping(m.ptr.add((r0 + r) * m.ld + c0), mt.as_mut_ptr().add(r * ld), w);
                    }
                }
                let mask = epi.mask.map(|_| Mat { ptr: mt.as_ptr(), ld });
                let args = (a1.at(r0, 0), p1, a2.at(r0, 0), p2, bp.as_ptr(), ld, ct.as_mut_ptr(), ld, bias_p, mask, epi.accumulate, epi.relu);
                dispatch!(tile, L, NARROW, rt, vecs, (args.0, args.1, args.2, args.3, args.4, args.5, args.6, args.7, args.8, args.9, args.10, args.11));
                for r in 0..rt {
                    core::ptr::copy_nonoverlapping(ct.as_ptr().add(r * ld), c.add((r0 + r) * ldc + c0), w);
                }
                r0 += rt;
            }
        }
    }
}

/// One tile of a weight gradient: `W[R × V·N] (+)= Σ_i a[i, 0..R]ᵀ g[i, ..]` over `rows` rows.
///
/// # Safety
/// Within the tile the caller names; the level's features present.
#[inline(always)]
unsafe fn weight_tile<L: Tile, const R: usize, const V: usize>(rows: usize, a: Mat, g: Mat, w: *mut f32, ldw: usize, accumulate: bool) {
    // SAFETY (whole body): the caller's tile contract.
    unsafe {
        let mut acc: [[L::V; V]; R] = core::array::from_fn(|r| core::array::from_fn(|j| if accumulate { L::load(w.add(r * ldw + j * L::N)) } else { L::zero() }));
        for i in 0..rows {
            let gi = g.ptr.add(i * g.ld);
            let gv: [L::V; V] = core::array::from_fn(|j| L::load(gi.add(j * L::N)));
            let ai = a.ptr.add(i * a.ld);
            for (r, acc) in acc.iter_mut().enumerate() {
                let av = L::splat(*ai.add(r));
                for (v, &gj) in acc.iter_mut().zip(&gv) {
                    *v = L::mul_add(av, gj, *v);
                }
            }
        }
        for (r, acc) in acc.iter().enumerate() {
            for (j, &v) in acc.iter().enumerate() {
                L::store(w.add(r * ldw + j * L::N), v);
            }
        }
    }
}

/// Rows of `A` and `G` per sweep of the weight tiles: 2 × 128 KiB at 128 columns, in L2.
const W_ROWS: usize = 256;

/// `W [k × m] (+)= Aᵀ G` over `rows` rows (see `super::weight_product`) at level `L`.
///
/// # Safety
/// As `super::weight_product`; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn weight_product<L: Tile, const NARROW: usize>(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    let panel = L::NV * L::N;
    // SAFETY (whole body): every tile lies within the matrices the caller names; the padded copies
    // hold a whole number of vectors per row.
    unsafe {
        for i0 in (0..rows).step_by(W_ROWS) {
            let n = W_ROWS.min(rows - i0);
            let acc = accumulate || i0 > 0;
            for c0 in (0..m).step_by(panel) {
                let wd = (m - c0).min(panel);
                let vecs = wd.div_ceil(L::N);
                let full = wd % L::N == 0;
                // A partial vector: G's columns zero-padded, W's tile through a buffer.
                let ld = vecs * L::N;
                let gp: Vec<f32> = if full {
                    Vec::new()
                } else {
                    let mut gp = vec![0.0f32; n * ld];
                    for (i, row) in gp.chunks_exact_mut(ld).enumerate() {
                        core::ptr::copy_nonoverlapping(g.ptr.add((i0 + i) * g.ld + c0), row.as_mut_ptr(), wd);
                    }
                    gp
                };
                let gm = if full { g.at(i0, c0) } else { Mat { ptr: gp.as_ptr(), ld } };
                let mut wt = [0.0f32; TILE_MAX];
                let mut k0 = 0;
                while k0 < k {
                    let rt = tile_rows::<L, NARROW>(k, k0, vecs);
                    let am = a.at(i0, k0);
                    if full {
                        dispatch!(weight_tile, L, NARROW, rt, vecs, (n, am, gm, w.add(k0 * m + c0), m, acc));
                    } else {
                        for r in (0..rt).filter(|_| acc) {
                            core::ptr::copy_nonoverlapping(w.add((k0 + r) * m + c0), wt.as_mut_ptr().add(r * ld), wd);
                        }
                        dispatch!(weight_tile, L, NARROW, rt, vecs, (n, am, gm, wt.as_mut_ptr(), ld, acc));
                        for r in 0..rt {
                            core::ptr::copy_nonoverlapping(wt.as_ptr().add(r * ld), w.add((k0 + r) * m + c0), wd);
                        }
                    }
                    k0 += rt;
                }
            }
        }
    }
}

/// The FMA throughput this level reaches with no memory traffic: 12 independent chains of `N`-lane
/// multiply-adds on registers, `iters` rounds; returns the flops done (2 per lane and FMA) and a
/// value that depends on every chain, so that none is optimised away.
#[inline(always)]
pub(super) fn fma_peak<L: Tile>(iters: usize) -> (f64, f32) {
    let (a, b) = (L::splat(0.999_999), L::splat(1e-7));
    let mut acc = [L::zero(); 12];
    for _ in 0..iters {
        for v in acc.iter_mut() {
            *v = L::mul_add(*v, a, b);
        }
    }
    let mut out = [0.0f32; 64];
    let mut s = 0.0;
    for v in acc {
        // SAFETY: `out` holds 64 ≥ N values.
        unsafe { L::store(out.as_mut_ptr(), v) };
        s += out[0];
    }
    ((iters * 12 * L::N * 2) as f64, s)
}
