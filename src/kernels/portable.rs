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

/// [`PACKET`] queries, one after the other (the portable path does not block over queries).
///
/// # Safety
/// `layer` passed `Dense::check(PACKET, ..)` for an output buffer at `out` with rows `out_stride` apart.
pub(super) unsafe fn packet<W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
    for q in 0..PACKET {
        let mut l = *layer;
        for s in &mut l.segs[..l.n_segs] {
            s.x = if s.n == 0 { &s.x[..0] } else { &s.x[q * s.stride..] };
        }
        // SAFETY: query `q`'s outputs lie inside the checked extent; its inputs were re-sliced above.
        unsafe { one(&l, out.add(q * out_stride)) };
    }
}
