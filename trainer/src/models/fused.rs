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

/// Rows per block of the elementwise passes: large enough to amortise rayon's task cost, small enough
/// that 2 threads get many blocks; fixed (not per thread count) so that the column sums round the same
/// way on any machine.
const ROW_BLOCK: usize = 1024;

/// The contiguous f32 data of a candle CPU tensor.
fn data<'a>(s: &'a CpuStorage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let CpuStorage::F32(d) = s else { candle_core::bail!("{op}: f32 only") };
    let Some((a, b)) = l.contiguous_offsets() else { candle_core::bail!("{op}: contiguous tensors only") };
    Ok(&d[a..b])
}

/// `[rows, cols]` of a rank-2 layout.
fn dims2(l: &Layout, op: &str) -> Result<(usize, usize)> {
    match l.shape().dims() {
        &[r, c] => Ok((r, c)),
        d => candle_core::bail!("{op}: rank-2 tensor expected, got {d:?}"),
    }
}

/// The threads gemm may use: candle's own count (RAYON_NUM_THREADS or the cores), so a fused layer
/// and a candle matmul run on the same threads.
fn parallelism() -> gemm::Parallelism {
    match candle_core::utils::get_num_threads() {
        0 | 1 => gemm::Parallelism::None,
        n => gemm::Parallelism::Rayon(n),
    }
}

/// `lhs[m, k] · rhs[k, n]` (row-major, contiguous) as a new `m × n` row-major buffer.
fn gemm_new(m: usize, n: usize, k: usize, lhs: &[f32], rhs: &[f32]) -> Vec<f32> {
    assert!(lhs.len() == m * k && rhs.len() == k * n, "gemm_new: shapes");
    if k == 0 {
        return vec![0.0; m * n];
    }
    let mut dst: Vec<f32> = Vec::with_capacity(m * n);
    // SAFETY: lhs and rhs hold exactly the m×k and k×n row-major matrices the strides describe (column
    // stride 1, row stride = columns), checked above; dst has room for m×n values, which gemm writes
    // without reading (`read_dst = false`) before `set_len` exposes them. Skipping the zero fill saves
    // a pass over the largest buffer of the layer; candle's own matmul allocates the same way.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            n as isize,
            false,
            lhs.as_ptr(),
            1,
            k as isize,
            rhs.as_ptr(),
            1,
            n as isize,
            0.0,
            1.0,
            false,
            false,
            false,
            parallelism(),
        );
        dst.set_len(m * n);
    }
    dst
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
        // Bias and activation in one parallel pass over the GEMM output.
        let relu = self.relu;
        y.par_chunks_mut(ROW_BLOCK * m.max(1)).for_each(|c| {
            for row in c.chunks_exact_mut(m) {
                for (v, &bj) in row.iter_mut().zip(b) {
                    let z = *v + bj;
                    *v = if relu { z.max(0.0) } else { z };
                }
            }
        });
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
/// (both outputs of one pass in one buffer, split by `narrow` without a copy).
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
        // Every value of dz is written below, so the buffer starts uninitialised (`MaybeUninit`)
        // instead of paying a zero fill over the layer's largest array.
        let mut out: Vec<f32> = Vec::with_capacity((n + 1) * m);
        let dz = &mut out.spare_capacity_mut()[..n * m];
        let block = ROW_BLOCK * m.max(1);
        let relu = self.relu;
        let partial: Vec<Vec<f32>> = dz
            .par_chunks_mut(block)
            .zip(dy.par_chunks(block).zip(y.par_chunks(block)))
            .map(|(dz, (dy, y))| {
                let mut sum = vec![0.0f32; m];
                // Iterators, not indices, and a select, not a branch: the loop vectorises.
                for ((dz, dy), y) in dz.chunks_exact_mut(m).zip(dy.chunks_exact(m)).zip(y.chunks_exact(m)) {
                    for (((d, &g), &yv), s) in dz.iter_mut().zip(dy).zip(y).zip(sum.iter_mut()) {
                        let g = if !relu || yv > 0.0 { g } else { 0.0 };
                        d.write(g);
                        *s += g;
                    }
                }
                sum
            })
            .collect();
        // SAFETY: the loop above wrote all n × m values of dz (the chunks cover it exactly).
        unsafe { out.set_len(n * m) };
        let mut db = vec![0.0f32; m];
        for p in &partial {
            for (d, s) in db.iter_mut().zip(p) {
                *d += s;
            }
        }
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
const K_BLOCK: usize = 4096;

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
        let partial: Vec<Vec<f32>> = (0..n.div_ceil(K_BLOCK))
            .into_par_iter()
            .map(|blk| {
                let (r0, r1) = (blk * K_BLOCK, ((blk + 1) * K_BLOCK).min(n));
                let (xb, db) = (&x[r0 * k..r1 * k], &dz[r0 * m..r1 * m]);
                let mut out: Vec<f32> = Vec::with_capacity(k * m);
                if k * m > 0 {
                    // SAFETY: xb is the (r1 - r0) × k row-major block of x, read as its transpose
                    // (row stride 1, column stride k); db the (r1 - r0) × m block of dz; out has room
                    // for k × m values, written without being read (`read_dst = false`).
                    unsafe {
                        gemm::gemm(
                            k,
                            m,
                            r1 - r0,
                            out.as_mut_ptr(),
                            1,
                            m as isize,
                            false,
                            xb.as_ptr(),
                            k as isize,
                            1,
                            db.as_ptr(),
                            1,
                            m as isize,
                            0.0,
                            1.0,
                            false,
                            false,
                            false,
                            gemm::Parallelism::None,
                        );
                        out.set_len(k * m);
                    }
                }
                out
            })
            .collect();
        let mut dw = vec![0.0f32; k * m];
        for p in &partial {
            for (d, v) in dw.iter_mut().zip(p) {
                *d += v;
            }
        }
        Ok((CpuStorage::F32(dw), Shape::from((k, m))))
    }
}

// -------------------------------------------------------------------------------------------------
// The whole network as one op

/// What [`network`] needs to know of a network: layer sizes, which layers end in a ReLU, and the skip.
#[derive(Clone, Debug)]
pub struct NetShape {
    /// `(inputs, outputs)` of each layer, as in the file; the skip layer's inputs are `[h, x]`.
    pub layers: Vec<(usize, usize)>,
    /// Layers `0..hidden` end in a ReLU, the rest (the output layer) are linear.
    pub hidden: usize,
    /// The layer that reads `[h, x]` (the previous activation and the network input), if any.
    pub skip: Option<usize>,
}

thread_local! {
    /// Whether [`super::mlp::Mlp::forward`] on this thread runs a network as one op ([`network`]) or
    /// layer by layer ([`linear`]). Per thread, so that a test comparing the two does not switch the
    /// path of another test running beside it.
    static WHOLE_NETWORK: std::cell::Cell<bool> = const { std::cell::Cell::new(true) };
}

/// Chooses, for networks run from this thread, between [`network`] (`true`, the default) and
/// per-layer [`linear`] ops; tests compare the two and `bench-step --per-layer` times the latter.
pub fn set_whole_network(on: bool) {
    WHOLE_NETWORK.with(|w| w.set(on));
}

/// Whether networks run from this thread run as one op (see [`set_whole_network`]).
pub fn whole_network() -> bool {
    WHOLE_NETWORK.with(|w| w.get())
}

/// The activations a forward pass keeps for its backward pass: each hidden layer's output.
type Saved = std::sync::Arc<std::sync::Mutex<Vec<Vec<f32>>>>;

/// `relu(... relu(x W_0 + b_0) ...) W_L + b_L` over `(x [N, n_in], w [Σ in·out], b [Σ out])`, the
/// layers' matrices and biases concatenated in file order.
///
/// Why one op for the network: candle's backward gives every node of the graph a gradient buffer
/// (`zeros_like`, then `add`), i.e. two passes over each `[N, 128]` activation per layer, ~10% of a
/// step; inside one op the gradient flows from layer to layer in place, and the backward of the skip
/// layer's `[h, x]` splits the matrix instead of the gradient.
struct Network {
    shape: NetShape,
    saved: Saved,
}

/// Offsets of each layer's matrix and bias in the concatenated `w` and `b`.
fn offsets(shape: &NetShape) -> Vec<(usize, usize)> {
    let (mut ow, mut ob) = (0, 0);
    shape
        .layers
        .iter()
        .map(|&(i, o)| {
            let at = (ow, ob);
            ow += i * o;
            ob += o;
            at
        })
        .collect()
}

/// `dst [m, n] (+)= lhs [m, k] · rhs`, with `rhs` read as `[k, n]` through strides `(rs, cs)`.
///
/// # Safety
/// `dst` must hold `m × n` values (initialised when `accumulate`), `lhs` `m × k` row-major values,
/// and `rhs` every element `r·rs + c·cs` for `r < k`, `c < n`.
#[allow(clippy::too_many_arguments)]
unsafe fn gemm_into(dst: *mut f32, accumulate: bool, m: usize, n: usize, k: usize, lhs: &[f32], rhs: *const f32, rs: isize, cs: isize, par: gemm::Parallelism) {
    // SAFETY: forwarded from the caller; dst row-major with row stride n, lhs row-major with row
    // stride k.
    unsafe {
        gemm::gemm(m, n, k, dst, 1, n as isize, accumulate, lhs.as_ptr(), 1, k as isize, rhs, cs, rs, 1.0, 1.0, false, false, false, par)
    }
}

impl Network {
    /// Inputs of layer `l` split as (activation part, network-input part): `(h, x)` widths.
    fn split(&self, l: usize, n_x: usize) -> (usize, usize) {
        let n_in = self.shape.layers[l].0;
        match (l, self.shape.skip) {
            (0, _) => (0, n_in),
            (l, Some(s)) if l == s => (n_in - n_x, n_x),
            _ => (n_in, 0),
        }
    }
}

impl CustomOp3 for Network {
    fn name(&self) -> &'static str {
        "mlp"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, w, b) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let (n, n_x) = dims2(l1, op)?;
        let off = offsets(&self.shape);
        let n_w: usize = self.shape.layers.iter().map(|&(i, o)| i * o).sum();
        let n_b: usize = self.shape.layers.iter().map(|&(_, o)| o).sum();
        if w.len() != n_w || b.len() != n_b || self.shape.layers.first().is_none_or(|&(i, _)| i != n_x) {
            candle_core::bail!("{op}: x [{n}, {n_x}], {} weights, {} biases do not fit {:?}", w.len(), b.len(), self.shape.layers)
        }
        let mut saved = Vec::with_capacity(self.shape.layers.len());
        let mut h: Vec<f32> = Vec::new();
        for (l, &(_, m)) in self.shape.layers.iter().enumerate() {
            let (n_h, n_xl) = self.split(l, n_x);
            let (ow, ob) = off[l];
            // The skip layer reads `[h, x]` copied side by side, not as two GEMMs into one output:
            // the same sums in the same order as the layer-by-layer path, so the two agree to the
            // last bit (a rounding difference flips ReLUs at the kink and shows in the gradients).
            let joined: Vec<f32>;
            let input: &[f32] = match (n_h, n_xl) {
                (0, _) => x,
                (_, 0) => &h,
                _ => {
                    let k = n_h + n_xl;
                    let mut c = vec![0.0f32; n * k];
                    c.par_chunks_mut(ROW_BLOCK * k).zip(h.par_chunks(ROW_BLOCK * n_h).zip(x.par_chunks(ROW_BLOCK * n_xl))).for_each(
                        |(c, (h, x))| {
                            for (row, (hr, xr)) in c.chunks_exact_mut(k).zip(h.chunks_exact(n_h).zip(x.chunks_exact(n_xl))) {
                                row[..n_h].copy_from_slice(hr);
                                row[n_h..].copy_from_slice(xr);
                            }
                        },
                    );
                    joined = c;
                    &joined
                }
            };
            let k = n_h + n_xl;
            let mut y: Vec<f32> = Vec::with_capacity(n * m);
            // SAFETY: y has room for n × m values, which the GEMM writes without reading; input is
            // n × k row-major (k ≥ 1: every layer has inputs) and the layer's matrix is the k × m
            // row-major block at w[ow..].
            unsafe {
                gemm_into(y.as_mut_ptr(), false, n, m, k, input, w[ow..].as_ptr(), m as isize, 1, parallelism());
                y.set_len(n * m);
            }
            let relu = l < self.shape.hidden;
            let bl = &b[ob..ob + m];
            y.par_chunks_mut(ROW_BLOCK * m.max(1)).for_each(|c| {
                for row in c.chunks_exact_mut(m) {
                    for (v, &bj) in row.iter_mut().zip(bl) {
                        let z = *v + bj;
                        *v = if relu { z.max(0.0) } else { z };
                    }
                }
            });
            if l > 0 {
                saved.push(std::mem::take(&mut h));
            }
            h = y;
        }
        let m = self.shape.layers.last().map_or(0, |&(_, o)| o);
        *self.saved.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned activations")))? = saved;
        Ok((CpuStorage::F32(h), Shape::from((n, m))))
    }

    fn bwd(&self, x: &Tensor, w: &Tensor, _b: &Tensor, y: &Tensor, dy: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let back = NetworkGrad { shape: self.shape.clone(), saved: self.saved.clone(), w: w.contiguous()?, want_dx: x.track_op() };
        let (n, n_x) = x.dims2()?;
        let packed = dy.contiguous()?.apply_op3_no_bwd(&y.contiguous()?, &x.contiguous()?, &back)?;
        let (n_w, n_b) = (w.elem_count(), _b.elem_count());
        let dw = packed.narrow(0, 0, n_w)?;
        let db = packed.narrow(0, n_w, n_b)?;
        let dx = if back.want_dx { Some(packed.narrow(0, n_w + n_b, n * n_x)?.reshape((n, n_x))?) } else { None };
        Ok((dx, Some(dw), Some(db)))
    }
}

/// The backward pass of [`Network`] over `(dy [N, m], y [N, m], x [N, n_in])`, `y` the network's
/// output: `dw ++ db ++ dx` (dx only when the input needs it), 1-D. The weights `w` ride along in the
/// op (an op takes at most three tensors).
struct NetworkGrad {
    shape: NetShape,
    saved: Saved,
    w: Tensor,
    want_dx: bool,
}

impl CustomOp3 for NetworkGrad {
    fn name(&self) -> &'static str {
        "mlp-grad"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (dy, y, x) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let (n, n_x) = dims2(l3, op)?;
        let layers = &self.shape.layers;
        let m_out = layers.last().map_or(0, |&(_, o)| o);
        if dy.len() != n * m_out || y.len() != n * m_out {
            candle_core::bail!("{op}: output gradient of {} values for [{n}, {m_out}]", dy.len())
        }
        let (w_storage, w_layout) = self.w.storage_and_layout();
        let candle_core::Storage::Cpu(w_cpu) = &*w_storage else { candle_core::bail!("{op}: CPU tensors only") };
        let w = data(w_cpu, w_layout, op)?;
        let saved = self.saved.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned activations")))?;
        if saved.len() + 1 != layers.len() {
            candle_core::bail!("{op}: backward without its forward pass")
        }
        let net = Network { shape: self.shape.clone(), saved: self.saved.clone() };
        let off = offsets(&self.shape);
        let n_w: usize = layers.iter().map(|&(i, o)| i * o).sum();
        let n_b: usize = layers.iter().map(|&(_, o)| o).sum();
        let mut out = vec![0.0f32; n_w + n_b + if self.want_dx { n * n_x } else { 0 }];
        let (dw_all, rest) = out.split_at_mut(n_w);
        let (db_all, dx) = rest.split_at_mut(n_b);
        let mut g: Vec<f32> = dy.to_vec();
        for l in (0..layers.len()).rev() {
            let (_, m) = layers[l];
            let (n_h, n_xl) = net.split(l, n_x);
            let (ow, ob) = off[l];
            // dz = g ⊙ [out > 0] in place, and db = Σ_rows dz over fixed blocks in order.
            let act: &[f32] = if l + 1 == layers.len() { y } else { &saved[l] };
            let relu = l < self.shape.hidden;
            let block = ROW_BLOCK * m.max(1);
            let partial: Vec<Vec<f32>> = g
                .par_chunks_mut(block)
                .zip(act.par_chunks(block))
                .map(|(g, a)| {
                    let mut sum = vec![0.0f32; m];
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
            for p in &partial {
                for (d, s) in db_all[ob..ob + m].iter_mut().zip(p) {
                    *d += s;
                }
            }
            // dW = [h, x]ᵀ dz, each part split over the batch (see WeightGrad).
            let h: &[f32] = if l == 0 { &[] } else { &saved[l - 1] };
            weight_grad_into(&mut dw_all[ow..ow + n_h * m], h, n_h, &g, m, n);
            weight_grad_into(&mut dw_all[ow + n_h * m..ow + (n_h + n_xl) * m], x, n_xl, &g, m, n);
            // dx += dz W_xᵀ where the layer reads x and x needs a gradient.
            if self.want_dx && n_xl > 0 {
                // SAFETY: dx holds n × n_x initialised values; g is n × m; W_x is the n_x × m block
                // at ow + n_h m, read transposed (row stride 1, column stride m).
                unsafe { gemm_into(dx.as_mut_ptr(), true, n, n_x, m, &g, w[ow + n_h * m..].as_ptr(), 1, m as isize, parallelism()) };
            }
            // g ← dz W_hᵀ for the layer below.
            if l > 0 {
                let mut below: Vec<f32> = Vec::with_capacity(n * n_h);
                // SAFETY: below has room for n × n_h values, written without being read; W_h is the
                // n_h × m block at ow, read transposed.
                unsafe {
                    gemm_into(below.as_mut_ptr(), false, n, n_h, m, &g, w[ow..].as_ptr(), 1, m as isize, parallelism());
                    below.set_len(n * n_h);
                }
                g = below;
            }
        }
        let len = out.len();
        Ok((CpuStorage::F32(out), Shape::from(len)))
    }
}

/// `dw [k, m] = aᵀ dz` for `a [n, k]`, `dz [n, m]`: single-threaded GEMMs over `K_BLOCK`-row blocks in
/// parallel, added in block order (deterministic for any thread count).
fn weight_grad_into(dw: &mut [f32], a: &[f32], k: usize, dz: &[f32], m: usize, n: usize) {
    if k == 0 || m == 0 {
        return;
    }
    let partial: Vec<Vec<f32>> = (0..n.div_ceil(K_BLOCK))
        .into_par_iter()
        .map(|blk| {
            let (r0, r1) = (blk * K_BLOCK, ((blk + 1) * K_BLOCK).min(n));
            let mut out: Vec<f32> = Vec::with_capacity(k * m);
            // SAFETY: a[r0 k..r1 k] is the block of a, read as its transpose (row stride 1, column
            // stride k); dz[r0 m..] the block of dz; out has room for k × m values, written unread.
            unsafe {
                gemm::gemm(
                    k, m, r1 - r0, out.as_mut_ptr(), 1, m as isize, false,
                    a[r0 * k..r1 * k].as_ptr(), k as isize, 1,
                    dz[r0 * m..r1 * m].as_ptr(), 1, m as isize,
                    0.0, 1.0, false, false, false, gemm::Parallelism::None,
                );
                out.set_len(k * m);
            }
            out
        })
        .collect();
    for p in &partial {
        for (d, v) in dw.iter_mut().zip(p) {
            *d += v;
        }
    }
}

/// The whole network `x → y` as one op (see [`Network`]); `w` and `b` are the layers' matrices and
/// biases flattened and concatenated in file order.
pub fn network(x: &Tensor, w: &Tensor, b: &Tensor, shape: NetShape) -> Result<Tensor> {
    x.contiguous()?.apply_op3(&w.contiguous()?, &b.contiguous()?, Network { shape, saved: Saved::default() })
}
