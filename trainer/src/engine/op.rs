//! What the engine's candle ops share: reading a CPU tensor's data, and adding per-task partial sums
//! in a fixed order.

use candle_core::{CpuStorage, Layout, Result};

/// Rows per task of a step, and per block of the objective's sums: large enough to amortise rayon's
/// task cost, small enough that 2 threads get many tasks; fixed (not per thread count) so that the
/// sums round the same way on any machine.
pub(crate) const ROW_BLOCK: usize = 1024;

/// The contiguous f32 data of a candle CPU tensor.
pub(crate) fn data<'a>(s: &'a CpuStorage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let CpuStorage::F32(d) = s else { candle_core::bail!("{op}: f32 only") };
    let Some((a, b)) = l.contiguous_offsets() else { candle_core::bail!("{op}: contiguous tensors only") };
    Ok(&d[a..b])
}

/// `[rows, cols]` of a rank-2 layout.
pub(crate) fn dims2(l: &Layout, op: &str) -> Result<(usize, usize)> {
    match l.shape().dims() {
        &[r, c] => Ok((r, c)),
        d => candle_core::bail!("{op}: rank-2 tensor expected, got {d:?}"),
    }
}

/// `dst += Σ partial`, the partial results added in their order (the same rounding for any number of
/// threads).
pub(crate) fn add_in_order(dst: &mut [f32], partial: &[Vec<f32>]) {
    for p in partial {
        for (d, v) in dst.iter_mut().zip(p) {
            *d += v;
        }
    }
}

/// The contiguous f32 data of a tensor's storage (from `storage_and_layout`), which must be on the CPU.
pub(crate) fn storage_data<'a>(s: &'a candle_core::Storage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let candle_core::Storage::Cpu(c) = s else { candle_core::bail!("{op}: CPU tensors only") };
    data(c, l, op)
}
