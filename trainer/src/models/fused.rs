//! A dense layer `y = act(x W + b)` (act = ReLU or identity) as one candle op with its own backward pass,
//! the training hot spot of every network (issue 8).
//!
//! Why hand-written: composed from candle ops the layer is a graph of five nodes (`x·W`, `ones·b`, `+`,
//! `relu`), and candle's backward of `relu` alone is `ge` + `to_dtype` + `mul` + accumulate — four
//! passes and three allocations over the `[N, out]` activations, about 4 ms per layer at N = 2^15 —
//! plus a GEMM for the useless gradient of `ones`. No crate fuses a bias and an activation into a CPU
//! GEMM with a matching backward, so this module does, with the GEMM itself left to the `gemm` crate
//! (the one candle uses):
//!
//! * forward: one GEMM `x W` into an uninitialised buffer, one pass adds the bias and clamps at 0;
//! * backward (PyTorch's `threshold_backward` convention, gradient 0 where `y = 0`):
//!   `dz = dy ⊙ [y > 0]` and the bias gradient `db = Σ_rows dz` in one pass, then `dW = xᵀ dz` and,
//!   only when `x` needs a gradient (not for a network's constant input), `dx = dz Wᵀ`.
//!
//! Determinism: the column sums are taken over fixed row blocks and added in block order, and the GEMM
//! splits only the output, so a step is bitwise reproducible for a thread count, as docs/training.md
//! promises.

use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::dense::{self, Epilogue, Mat, Shared};

/// Rows per block of the elementwise passes: large enough to amortise rayon's task cost, small enough
/// that 2 threads get many blocks; fixed (not per thread count) so that the column sums round the same
/// way on any machine.
pub(crate) const ROW_BLOCK: usize = 1024;

/// The contiguous f32 data of a candle CPU tensor.
pub(crate) fn data<'a>(s: &'a CpuStorage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let CpuStorage::F32(d) = s else { candle_core::bail!("{op}: f32 only") };
    let Some((a, b)) = l.contiguous_offsets() else { candle_core::bail!("{op}: contiguous tensors only") };
    Ok(&d[a..b])
}

/// The contiguous f32 data of a tensor's storage (from `storage_and_layout`), which must be on the CPU.
pub(crate) fn storage_data<'a>(s: &'a candle_core::Storage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let candle_core::Storage::Cpu(c) = s else { candle_core::bail!("{op}: CPU tensors only") };
    data(c, l, op)
}

/// `[rows, cols]` of a rank-2 layout.
pub(super) fn dims2(l: &Layout, op: &str) -> Result<(usize, usize)> {
    match l.shape().dims() {
        &[r, c] => Ok((r, c)),
        d => candle_core::bail!("{op}: rank-2 tensor expected, got {d:?}"),
    }
}

/// `lhs[m, k] · rhs[k, n]` (row-major, contiguous) as a new `m × n` row-major buffer: blocks of rows in
/// parallel, the products of [`super::dense`] (the same sums as the whole-network op's).
pub(super) fn gemm_new(m: usize, n: usize, k: usize, lhs: &[f32], rhs: &[f32]) -> Vec<f32> {
    assert!(lhs.len() == m * k && rhs.len() == k * n, "gemm_new: shapes");
    let mut dst: Vec<f32> = Vec::with_capacity(m * n);
    let out = Shared(dst.as_mut_ptr());
    (0..m.div_ceil(ROW_BLOCK)).into_par_iter().for_each(|t| {
        let (r0, rows) = (t * ROW_BLOCK, ROW_BLOCK.min(m - t * ROW_BLOCK));
        let a = Mat::new(lhs, k);
        // SAFETY: lhs and rhs hold exactly the m×k and k×n row-major matrices (checked above); this
        // task alone writes rows r0..r0 + rows of dst, which has room for m×n values. Skipping the
        // zero fill saves a pass over the largest buffer of the layer (`set_len` below exposes the
        // values once every task has written its rows).
        unsafe { dense::product(rows, n, a.at(r0, 0), k, a, 0, Mat::new(rhs, n), out.add(r0 * n), n, Epilogue::STORE) };
    });
    // SAFETY: every row was written above (a product over k = 0 terms writes zeros).
    unsafe { dst.set_len(m * n) };
    dst
}

/// `y ← act(y + b)` row by row (`y [N, m]`, `b [m]`), in parallel: the pass after a layer's GEMM.
pub(super) fn add_bias_act(y: &mut [f32], b: &[f32], relu: bool) {
    let m = b.len();
    y.par_chunks_mut(ROW_BLOCK * m.max(1)).for_each(|c| {
        for row in c.chunks_exact_mut(m) {
            for (v, &bj) in row.iter_mut().zip(b) {
                let z = *v + bj;
                *v = if relu { z.max(0.0) } else { z };
            }
        }
    });
}

/// `g ← g ⊙ act'(out)` in place (`g`, `out` `[N, m]`; PyTorch's convention: gradient 0 where
/// `out = 0`) and returns the column sums of the result, the bias gradient, taken over fixed row
/// blocks and added in block order.
pub(super) fn act_grad_colsum(g: &mut [f32], out: &[f32], m: usize, relu: bool) -> Vec<f32> {
    let block = ROW_BLOCK * m.max(1);
    let partial: Vec<Vec<f32>> = g
        .par_chunks_mut(block)
        .zip(out.par_chunks(block))
        .map(|(g, a)| {
            let mut sum = vec![0.0f32; m];
            // Iterators, not indices, and a select, not a branch: the loop vectorises.
            for (g, a) in g.chunks_exact_mut(m).zip(a.chunks_exact(m)) {
                for ((d, &av), s) in g.iter_mut().zip(a).zip(sum.iter_mut()) {
                    let v = if !relu || av > 0.0 { *d } else { 0.0 };
                    *d = v;
                    *s += v;
                }
            }
            sum
        })
        .collect();
    let mut db = vec![0.0f32; m];
    add_in_order(&mut db, &partial);
    db
}

/// `dst += Σ partial`, the partial results added in their order (the same rounding for any number of
/// threads).
pub(super) fn add_in_order(dst: &mut [f32], partial: &[Vec<f32>]) {
    for p in partial {
        for (d, v) in dst.iter_mut().zip(p) {
            *d += v;
        }
    }
}

/// The forward op over `(x [N, in], W [in, out], b [1, out])`.
struct Linear {
    relu: bool,
}

impl Linear {
    fn name_of(relu: bool) -> &'static str {
        if relu {
            "linear-relu"
        } else {
            "linear"
        }
    }
}

impl CustomOp3 for Linear {
    fn name(&self) -> &'static str {
        Self::name_of(self.relu)
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, w, b) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let ((n, k), (k2, m)) = (dims2(l1, op)?, dims2(l2, op)?);
        if k != k2 || b.len() != m {
            candle_core::bail!("{op}: x [{n}, {k}], W [{k2}, {m}], b [{}] do not fit", b.len())
        }
        let mut y = gemm_new(n, m, k, x, w);
        add_bias_act(&mut y, b, self.relu);
        Ok((CpuStorage::F32(y), Shape::from((n, m))))
    }

    fn bwd(&self, x: &Tensor, w: &Tensor, _b: &Tensor, y: &Tensor, dy: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let n = x.dim(0)?;
        let packed = dy.contiguous()?.apply_op2_no_bwd(&y.contiguous()?, &ActivationGrad { relu: self.relu })?;
        let dz = packed.narrow(0, 0, n)?;
        let db = packed.narrow(0, n, 1)?;
        let dw = x.contiguous()?.apply_op2_no_bwd(&dz, &WeightGrad)?;
        // A network's input (encoded positions and angles) is a constant: its gradient would be a
        // full-size GEMM and accumulation that nothing reads.
        let dx = if x.track_op() { Some(dz.matmul(&w.t()?)?) } else { None };
        Ok((dx, Some(dw), Some(db)))
    }
}

/// `(dy [N, m], y [N, m]) → [N + 1, m]`: rows `0..N` are `dz = dy ⊙ act'(y)`, row `N` is `Σ_rows dz`
/// (one buffer, split by `narrow` without a copy): `dy` is copied in, then [`act_grad_colsum`], the
/// pass the whole-network op runs in place, masks it and sums its columns.
struct ActivationGrad {
    relu: bool,
}

impl CustomOp2 for ActivationGrad {
    fn name(&self) -> &'static str {
        "linear-activation-grad"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (dy, y) = (data(s1, l1, op)?, data(s2, l2, op)?);
        let (n, m) = dims2(l1, op)?;
        if dims2(l2, op)? != (n, m) {
            candle_core::bail!("{op}: dy {:?} and y {:?} differ", l1.shape(), l2.shape())
        }
        let mut out: Vec<f32> = Vec::with_capacity((n + 1) * m);
        out.extend_from_slice(dy);
        let db = act_grad_colsum(&mut out, y, m, self.relu);
        out.extend_from_slice(&db);
        Ok((CpuStorage::F32(out), Shape::from((n + 1, m))))
    }
}

/// `relu(x W + b)` (`relu = true`) or `x W + b`, with `x [N, in]`, `W [in, out]`, `b [1, out]`.
pub fn linear(x: &Tensor, w: &Tensor, b: &Tensor, relu: bool) -> Result<Tensor> {
    x.contiguous()?.apply_op3(&w.contiguous()?, &b.contiguous()?, Linear { relu })
}

/// Rows per partial product of the weight gradient: fixed, so that the partial sums round the same way
/// for any thread count.
pub(super) const K_BLOCK: usize = 1024;

/// `(x [N, in], dz [N, out]) → xᵀ dz [in, out]`, split over the batch.
///
/// Why not candle's `x.t().matmul(dz)`: gemm parallelises over the output, and a `128 × 128` output
/// with a reduction over 2^15 rows gives it too few blocks to keep the threads busy. Here each block
/// of `K_BLOCK` rows is its own single-threaded GEMM, run in parallel, and the partial products are
/// added in block order.
struct WeightGrad;

impl CustomOp2 for WeightGrad {
    fn name(&self) -> &'static str {
        "linear-weight-grad"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, dz) = (data(s1, l1, op)?, data(s2, l2, op)?);
        let ((n, k), (n2, m)) = (dims2(l1, op)?, dims2(l2, op)?);
        if n != n2 {
            candle_core::bail!("{op}: x has {n} rows, dz {n2}")
        }
        let mut dw = vec![0.0f32; k * m];
        weight_grad_into(&mut dw, x, k, dz, m, n);
        Ok((CpuStorage::F32(dw), Shape::from((k, m))))
    }
}

/// `dw [k, m] = aᵀ dz` for `a [n, k]`, `dz [n, m]`: the products of `K_BLOCK`-row blocks in parallel,
/// added in block order (deterministic for any thread count, and the sums of the whole-network op).
pub(super) fn weight_grad_into(dw: &mut [f32], a: &[f32], k: usize, dz: &[f32], m: usize, n: usize) {
    if k == 0 || m == 0 {
        return;
    }
    let partial: Vec<Vec<f32>> = (0..n.div_ceil(K_BLOCK))
        .into_par_iter()
        .map(|blk| {
            let (r0, r1) = (blk * K_BLOCK, ((blk + 1) * K_BLOCK).min(n));
            let mut out: Vec<f32> = Vec::with_capacity(k * m);
            // SAFETY: rows r0..r1 of a [n, k] and dz [n, m]; out has room for k × m values, which the
            // product writes without reading (`accumulate = false`) before `set_len` exposes them.
            unsafe {
                dense::weight_product(r1 - r0, k, m, Mat::new(a, k).at(r0, 0), Mat::new(dz, m).at(r0, 0), out.as_mut_ptr(), false);
                out.set_len(k * m);
            }
            out
        })
        .collect();
    add_in_order(dw, &partial);
}
