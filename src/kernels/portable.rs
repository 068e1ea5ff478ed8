//! Plain-Rust kernels for every target: the sum of scaled weight rows, whose inner loop over outputs
//! the compiler vectorises for the compile-time target. Multiply, then add (no FMA: `mul_add` is not
//! in `core`, and its software fallback is slow).

use super::{Dense, PACKET};
use crate::mlp::Weight;

/// `max(v, 0)` as the SIMD kernels compute it: `+0` for either zero, and 0 for NaN.
#[inline(always)]
fn relu(v: f32) -> f32 {
    if v > 0.0 {
        v
    } else {
        0.0
    }
}

/// One query: `out = init + Σ x_i rows[i]`, skipping zero inputs (see the module docs of `kernels`).
///
/// # Safety
/// `layer` passed `Dense::check(1, ..)` for an output buffer at `out`.
pub(super) unsafe fn one<W: Weight>(layer: &Dense<'_, W>, out: *mut f32) {
    let n = layer.n_out;
    // SAFETY: `check` verified that `out` holds `n_out` values.
    let acc = unsafe { core::slice::from_raw_parts_mut(out, n) };
    acc.copy_from_slice(&layer.init[..n]);
    for s in &layer.segs[..layer.n_segs] {
        for (xi, row) in s.x[..s.n].iter().zip(s.rows.chunks_exact(n)) {
            if *xi == 0.0 {
                continue;
            }
            for (a, w) in acc.iter_mut().zip(row) {
                *a += *xi * w.to_f32();
            }
        }
    }
    if layer.relu {
        for a in acc.iter_mut() {
            *a = relu(*a);
        }
    }
}

/// Outputs per tile of [`packet`]: the packet's accumulators for a tile (16 × 64 values, 4 KB) and
/// one widened row stay in L1 while the weight rows stream past.
const TILE: usize = 64;

/// [`PACKET`] queries, a tile of outputs at a time: each weight row is read (and widened) once for
/// the packet, then added to every query whose input is nonzero. Each query's accumulator sees what
/// [`one`] gives it, in the same order (its `init`, then `x_i · row_i` for its nonzero inputs in row
/// order), so the bits are those of one query at a time. Against running [`one`] per query (each
/// row read, and its f16 weights converted, once per query): on this project's Zen 4 machine forced
/// to this level, f32 batches 0.90–0.99× the time in one process, and f16 calls of 48 pairs that
/// widen per packet 0.15–0.18× (`docs/speed.md`).
///
/// # Safety
/// `layer` passed `Dense::check(PACKET, ..)` for an output buffer at `out` with rows `out_stride` apart.
pub(super) unsafe fn packet<W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
    let n = layer.n_out;
    let mut acc = [[0.0f32; TILE]; PACKET];
    let mut row = [0.0f32; TILE];
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
                W::widen(&s.rows[i * n + t0..i * n + t0 + w], &mut row[..w]);
                for (q, a) in acc.iter_mut().enumerate() {
                    let xi = x(q);
                    if xi == 0.0 {
                        continue;
                    }
                    for (a, r) in a[..w].iter_mut().zip(&row[..w]) {
                        *a += xi * r;
                    }
                }
            }
        }
        for (q, a) in acc.iter().enumerate() {
            // SAFETY: `check` verified that query `q`'s `n_out` outputs lie at `out + q * out_stride`.
            let o = unsafe { core::slice::from_raw_parts_mut(out.add(q * out_stride + t0), w) };
            for (o, a) in o.iter_mut().zip(&a[..w]) {
                *o = if layer.relu { relu(*a) } else { *a };
            }
        }
    }
}
