//! The one-query and packet kernels written once over the workspace's lane trait
//! ([`nbrdf_lanes::Lanes`], shared with the trainer's dense products), for the levels without
//! hand-tiled x86 kernels: [`Scalar`] (portable, every target, 8 lanes) and `Neon` (aarch64,
//! `neon.rs`). The algorithm lives here only: outputs go in tiles of [`TILE`]; a packet reads each weight
//! row once (widened into a padded f32 buffer) and adds it to every query whose input is nonzero.
//! Each query's accumulator sees its `init`, then one multiply-add per nonzero input in row order, in
//! both kernels, so a packet gives every query the bits of [`one`] at the same level.

use nbrdf_lanes::{Lanes, Scalar};

use super::{Dense, Weight, PACKET};

/// The portable level's lanes: 8, as an array the compiler vectorises for the compile-time target.
type Portable = Scalar<8>;

/// Outputs per tile: a query's accumulators for a tile (64 values) and one widened row stay in L1
/// (a packet's 16 × 64 accumulators are 4 KB) while the weight rows stream past.
pub(super) const TILE: usize = 64;

/// `acc[..w] = mul_add(x, row[..w], acc[..w])` over whole vectors (the lanes past `w` are padding).
///
/// # Safety
/// `acc` and `row` hold `w` rounded up to `L::N` values; the level's features are present.
#[inline(always)]
unsafe fn axpy<L: Lanes>(x: f32, row: *const f32, acc: *mut f32, w: usize) {
    let xv = L::splat(x);
    let mut v = 0;
    while v < w {
        // SAFETY: `v < w`, and both buffers hold `w` rounded up to `N`.
        unsafe { L::store(acc.add(v), L::mul_add(xv, L::load(row.add(v)), L::load(acc.add(v)))) };
        v += L::N;
    }
}

/// [`axpy`] over a row of any weight type, each vector of weights widened as it is loaded (a
/// single query reads each row once, so widening a whole tile first would only add a round trip).
///
/// # Safety
/// As [`axpy`] for `acc`; `row` holds `w` weights.
#[inline(always)]
unsafe fn axpy_row<L: Lanes, W: Weight>(x: f32, row: &[W], acc: *mut f32, w: usize) {
    if let Some(f) = W::as_f32(row) {
        if w.is_multiple_of(L::N) {
            // SAFETY: `w` values, whole vectors.
            return unsafe { axpy::<L>(x, f.as_ptr(), acc, w) };
        }
    }
    let xv = L::splat(x);
    let mut v = 0;
    while v < w {
        let mut t = [0.0f32; 16];
        for (t, r) in t.iter_mut().zip(&row[v..w.min(v + L::N)]) {
            *t = r.to_f32();
        }
        // SAFETY: `t` holds 16 ≥ N values; `acc` as in the contract.
        unsafe { L::store(acc.add(v), L::mul_add(xv, L::load(t.as_ptr()), L::load(acc.add(v)))) };
        v += L::N;
    }
}

/// `out[..w] = relu?(acc[..w])`.
///
/// # Safety
/// As [`axpy`]; `out` holds `w` values.
#[inline(always)]
unsafe fn store_tile<L: Lanes>(acc: &[f32; TILE], out: *mut f32, w: usize, relu: bool) {
    let mut t = [0.0f32; TILE];
    let mut v = 0;
    while v < w {
        // SAFETY: within the tile.
        unsafe {
            let a = L::load(acc.as_ptr().add(v));
            L::store(t.as_mut_ptr().add(v), if relu { L::relu(a) } else { a });
        }
        v += L::N;
    }
    // SAFETY: the caller's contract.
    unsafe { core::ptr::copy_nonoverlapping(t.as_ptr(), out, w) };
}

/// The tile of row `i` from output `t0` on, widened into `buf` (past `w` whatever an earlier tile
/// left: padding lanes, computed and never stored); for f32 rows whose tile is whole, the row itself.
#[inline(always)]
fn row_tile<W: Weight>(rows: &[W], i: usize, n: usize, t0: usize, w: usize, buf: &mut [f32; TILE]) -> *const f32 {
    let r = &rows[i * n + t0..i * n + t0 + w];
    if let Some(f) = W::as_f32(r) {
        if w == TILE {
            return f.as_ptr();
        }
    }
    W::widen(r, &mut buf[..w]);
    buf.as_ptr()
}

/// One query: `out = act(init + Σ x_i rows[i])`, skipping zero inputs (the module docs of `kernels`).
///
/// # Safety
/// `layer` passed `Dense::check(1, ..)` for an output buffer at `out`; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn one<L: Lanes, W: Weight>(layer: &Dense<'_, W>, out: *mut f32) {
    let n = layer.n_out;
    let mut acc = [0.0f32; TILE];
    for t0 in (0..n).step_by(TILE) {
        let w = (n - t0).min(TILE);
        acc[..w].copy_from_slice(&layer.init[t0..t0 + w]);
        for s in &layer.segs[..layer.n_segs] {
            for (i, xi) in s.x[..s.n].iter().enumerate() {
                if *xi == 0.0 {
                    continue;
                }
                // SAFETY: `acc` holds `TILE ≥ w` rounded up to `N` values.
                unsafe { axpy_row::<L, W>(*xi, &s.rows[i * n + t0..i * n + t0 + w], acc.as_mut_ptr(), w) };
            }
        }
        // SAFETY: `check` verified that `out` holds `n_out` values.
        unsafe { store_tile::<L>(&acc, out.add(t0), w, layer.relu) };
    }
}

/// [`PACKET`] queries, a tile of outputs at a time: each weight row is read (and widened) once for
/// the packet, then added to every query whose input is nonzero.
///
/// # Safety
/// `layer` passed `Dense::check(PACKET, ..)` for an output buffer at `out` with rows `out_stride`
/// apart; the CPU has `L`'s level.
#[inline(always)]
pub(super) unsafe fn packet<L: Lanes, W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
    let n = layer.n_out;
    let mut acc = [[0.0f32; TILE]; PACKET];
    let mut buf = [0.0f32; TILE];
    for t0 in (0..n).step_by(TILE) {
        let w = (n - t0).min(TILE);
        for a in acc.iter_mut() {
            a[..w].copy_from_slice(&layer.init[t0..t0 + w]);
        }
        for s in &layer.segs[..layer.n_segs] {
            for i in 0..s.n {
                let x = |q: usize| s.x[q * s.stride + i];
                if (0..PACKET).all(|q| x(q) == 0.0) {
                    continue;
                }
                let r = row_tile(s.rows, i, n, t0, w, &mut buf);
                for (q, a) in acc.iter_mut().enumerate() {
                    let xi = x(q);
                    if xi != 0.0 {
                        // SAFETY: as in `one`.
                        unsafe { axpy::<L>(xi, r, a.as_mut_ptr(), w) };
                    }
                }
            }
        }
        for (q, a) in acc.iter().enumerate() {
            // SAFETY: `check` verified that query `q`'s `n_out` outputs lie at `out + q * out_stride`.
            unsafe { store_tile::<L>(a, out.add(q * out_stride + t0), w, layer.relu) };
        }
    }
}

/// The portable level's kernels.
pub(super) mod portable {
    use super::*;

    /// [`super::one`] over 8 [`Scalar`] lanes.
    ///
    /// # Safety
    /// As [`super::one`].
    pub(in crate::kernels) unsafe fn one<W: Weight>(layer: &Dense<'_, W>, out: *mut f32) {
        // SAFETY: forwarded; `Scalar` needs no CPU feature.
        unsafe { super::one::<Portable, W>(layer, out) }
    }

    /// [`super::packet`] over 8 [`Scalar`] lanes.
    ///
    /// # Safety
    /// As [`super::packet`].
    pub(in crate::kernels) unsafe fn packet<W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
        // SAFETY: forwarded; `Scalar` needs no CPU feature.
        unsafe { super::packet::<Portable, W>(layer, out, out_stride) }
    }
}
