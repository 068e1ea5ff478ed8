//! A whole network `relu(... relu(x W_0 + b_0) ...) W_L + b_L` as one candle op with its own backward
//! pass through all layers (issue 8), built from the same pieces as the per-layer op of [`super::fused`].
//!
//! Why: candle's backward gives every node of a graph a gradient buffer (`zeros_like`, then `add`),
//! two passes over each `[2^15, 128]` activation per layer, plus a node per layer; one op per network
//! took a Single MLP training step from 236 to ~140 ms. The layer-by-layer path stays
//! ([`set_whole_network`]), and trainer/tests/fused.rs checks the two against each other.

use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::dense::{self, Epilogue, Mat, Shared};
use super::fused::{add_in_order, data, dims2, ROW_BLOCK};

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
    /// layer by layer ([`super::fused::linear`]). Per thread, so that a test comparing the two does not switch the
    /// path of another test running beside it.
    static WHOLE_NETWORK: std::cell::Cell<bool> = const { std::cell::Cell::new(true) };
}

/// Chooses, for networks run from this thread, between [`network`] (`true`, the default) and
/// per-layer [`super::fused::linear`] ops; tests compare the two and `bench-step --per-layer` times the latter.
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

impl NetShape {
    /// Inputs of layer `l` split as (activation part, network-input part): `(h, x)` widths.
    fn split(&self, l: usize, n_x: usize) -> (usize, usize) {
        let n_in = self.layers[l].0;
        match (l, self.skip) {
            (0, _) => (0, n_in),
            (l, Some(s)) if l == s => (n_in - n_x, n_x),
            _ => (n_in, 0),
        }
    }
}

/// `[h, x]` row by row: the input of a layer that reads an activation and a network input side by side.
///
/// Written into uninitialised memory: a zero fill first was a second pass over the ~20 MiB that the
/// Additive Shared specular head reads each step.
pub(super) fn join(h: &[f32], n_h: usize, x: &[f32], n_x: usize, n: usize) -> Vec<f32> {
    let k = n_h + n_x;
    assert!(h.len() == n * n_h && x.len() == n * n_x && n_h > 0 && n_x > 0, "join: shapes");
    let mut c: Vec<f32> = Vec::with_capacity(n * k);
    let rows = c.spare_capacity_mut()[..n * k].par_chunks_mut(ROW_BLOCK * k);
    rows.zip(h.par_chunks(ROW_BLOCK * n_h).zip(x.par_chunks(ROW_BLOCK * n_x))).for_each(|(c, (h, x))| {
        for (row, (hr, xr)) in c.chunks_exact_mut(k).zip(h.chunks_exact(n_h).zip(x.chunks_exact(n_x))) {
            let (ch, cx) = row.split_at_mut(n_h);
            ch.iter_mut().zip(hr).for_each(|(d, &v)| _ = d.write(v));
            cx.iter_mut().zip(xr).for_each(|(d, &v)| _ = d.write(v));
        }
    });
    // SAFETY: h and x hold n rows each (asserted), so the blocks above wrote all n rows of k values.
    unsafe { c.set_len(n * k) };
    c
}

/// Rows per task of the forward pass: each task runs every layer on its block, so that a layer reads
/// its input from L2, where the layer below has just written it (2 × 128 KiB at 128 columns).
const FORWARD_ROWS: usize = 256;

/// Rows per task of the backward pass, each task's weight and bias gradients a partial sum of its own
/// rows, added in task order: fixed (not per thread count), so that a step rounds the same way on any
/// machine, and the blocks of the per-layer path ([`super::fused::K_BLOCK`]), so that both agree.
const BACKWARD_ROWS: usize = super::fused::K_BLOCK;

/// Rows per sweep through the layers within a backward task: the gradient flows from layer to layer in
/// two buffers of this many rows that stay in L2.
const SWEEP_ROWS: usize = 256;

/// The layers of `shape` over `x [n, n_x]` with the concatenated weights `w` and biases `b`: the output
/// `[n, m]` and each hidden layer's activation, which the backward pass reads.
///
/// Blocks of [`FORWARD_ROWS`] rows run through all layers in parallel; each layer's GEMM applies its
/// bias and ReLU before storing ([`dense::product`]), and the skip layer reads `[h, x]` from the two
/// matrices in place, its sums in the order of the joined input.
pub(super) fn forward_pass(shape: &NetShape, x: &[f32], n: usize, n_x: usize, w: &[f32], b: &[f32], op: &str) -> Result<(Vec<f32>, Vec<Vec<f32>>)> {
    let off = offsets(shape);
    let n_w: usize = shape.layers.iter().map(|&(i, o)| i * o).sum();
    let n_b: usize = shape.layers.iter().map(|&(_, o)| o).sum();
    if w.len() != n_w || b.len() != n_b || x.len() != n * n_x || shape.layers.first().is_none_or(|&(i, _)| i != n_x) {
        candle_core::bail!("{op}: x [{n}, {n_x}], {} weights, {} biases do not fit {:?}", w.len(), b.len(), shape.layers)
    }
    if let Some(l) = (1..shape.layers.len()).find(|&l| shape.split(l, n_x).0 != shape.layers[l - 1].1) {
        candle_core::bail!("{op}: layer {l} does not read the {} outputs of the layer below: {:?}", shape.layers[l - 1].1, shape.layers)
    }
    let mut outs: Vec<Vec<f32>> = shape.layers.iter().map(|&(_, m)| Vec::with_capacity(n * m)).collect();
    let dst: Vec<Shared> = outs.iter_mut().map(|o| Shared(o.as_mut_ptr())).collect();
    (0..n.div_ceil(FORWARD_ROWS)).into_par_iter().for_each(|t| {
        let (r0, rows) = (t * FORWARD_ROWS, FORWARD_ROWS.min(n - t * FORWARD_ROWS));
        for (l, &(_, m)) in shape.layers.iter().enumerate() {
            let (n_h, n_xl) = shape.split(l, n_x);
            let (ow, ob) = off[l];
            // SAFETY: x holds n × n_x values (checked); layer l - 1's output holds n × n_h values
            // (checked: it is what layer l reads), of which this task wrote rows r0..r0 + rows above;
            // this task alone writes the same rows of layer l's output, which has room for n × m
            // values; the weights and biases are the layer's (offsets from the checked shape).
            unsafe {
                let xm = Mat::new(x, n_x).at(r0, 0);
                let hm = if l > 0 { Mat { ptr: dst[l - 1].add(r0 * n_h), ld: n_h } } else { xm };
                let (a1, p1, a2, p2) = match (n_h, n_xl) {
                    (0, _) => (xm, n_xl, xm, 0),
                    (_, 0) => (hm, n_h, hm, 0),
                    _ => (hm, n_h, xm, n_xl),
                };
                let epi = Epilogue { bias: Some(b[ob..].as_ptr()), relu: l < shape.hidden, ..Epilogue::STORE };
                dense::product(rows, m, a1, p1, a2, p2, Mat::new(&w[ow..], m), dst[l].add(r0 * m), m, epi);
            }
        }
    });
    for (o, &(_, m)) in outs.iter_mut().zip(&shape.layers) {
        // SAFETY: the tasks above wrote all n rows of every layer's output.
        unsafe { o.set_len(n * m) };
    }
    let y = outs.pop().unwrap_or_default();
    Ok((y, outs))
}

/// `W [k, m]` as `Wᵀ [m, k]`, row-major.
fn transpose(w: &[f32], k: usize, m: usize) -> Vec<f32> {
    let mut t = vec![0.0f32; k * m];
    for (i, row) in w.chunks_exact(m).enumerate() {
        for (j, &v) in row.iter().enumerate() {
            t[j * k + i] = v;
        }
    }
    t
}

/// The backward pass of [`forward_pass`] for the output gradient `dy`: writes `dW` and `db` (file
/// order) into `dw_all` and `db_all` (which start at zero) and, when `dx = Some((buffer, cols))`, adds
/// the gradient of the input's first `cols` columns into `buffer` (`[n, cols]`): the columns of the
/// Additive Shared specular head's input that come from the trunk, which two heads add into one buffer.
///
/// Tasks of [`BACKWARD_ROWS`] rows run in parallel, each sweeping [`SWEEP_ROWS`] rows at a time down
/// through all layers: the gradient `g` of a layer's output is masked by its ReLU, summed into the
/// bias gradient, multiplied into the weight gradient, and carried to the layer below as
/// `(g Wᵀ) ⊙ [h > 0]` in one GEMM with a masking epilogue, without leaving L2.
#[allow(clippy::too_many_arguments)]
pub(super) fn backward_pass(
    shape: &NetShape,
    saved: &[Vec<f32>],
    x: &[f32],
    n: usize,
    n_x: usize,
    w: &[f32],
    y: &[f32],
    dy: &[f32],
    dw_all: &mut [f32],
    db_all: &mut [f32],
    dx: Option<(&mut [f32], usize)>,
) {
    let layers = &shape.layers;
    let n_layers = layers.len();
    let off = offsets(shape);
    let m_top = layers.last().map_or(0, |&(_, o)| o);
    assert!(saved.len() + 1 == n_layers && x.len() == n * n_x && y.len() == n * m_top && dy.len() == n * m_top, "backward_pass: shapes");
    let wt: Vec<Vec<f32>> = layers.iter().zip(&off).map(|(&(k, m), &(ow, _))| transpose(&w[ow..ow + k * m], k, m)).collect();
    let (dx, dx_cols) = match dx {
        Some((buf, cols)) => {
            assert!(buf.len() >= n * cols, "input gradient buffer too small");
            (Some(Shared(buf.as_mut_ptr())), cols)
        }
        None => (None, 0),
    };
    let width = layers.iter().map(|&(k, m)| k.max(m)).max().unwrap_or(0);
    // The output's gradient goes through the output layer's ReLU where it has one (a trunk).
    let top_relu = n_layers <= shape.hidden;
    let (partial_w, partial_b): (Vec<Vec<f32>>, Vec<Vec<f32>>) = (0..n.div_ceil(BACKWARD_ROWS))
        .into_par_iter()
        .map(|t| {
            // Written by the first sweep's products (which start their sums from the product, as from
            // zero), accumulated by the later ones: no zero fill of a copy of every weight.
            let mut dw: Vec<f32> = Vec::with_capacity(dw_all.len());
            let mut db = vec![0.0f32; db_all.len()];
            let mut g = vec![0.0f32; SWEEP_ROWS * width];
            let mut below = vec![0.0f32; SWEEP_ROWS * width];
            let end = ((t + 1) * BACKWARD_ROWS).min(n);
            let start = t * BACKWARD_ROWS;
            for s0 in (start..end).step_by(SWEEP_ROWS) {
                let rows = SWEEP_ROWS.min(end - s0);
                let first = s0 == start;
                for ((gr, dr), yr) in g.chunks_exact_mut(m_top).zip(dy[s0 * m_top..].chunks_exact(m_top)).zip(y[s0 * m_top..].chunks_exact(m_top)).take(rows) {
                    for ((gv, &dv), &yv) in gr.iter_mut().zip(dr).zip(yr) {
                        *gv = if !top_relu || yv > 0.0 { dv } else { 0.0 };
                    }
                }
                for l in (0..n_layers).rev() {
                    let (k, m) = layers[l];
                    let (n_h, n_xl) = shape.split(l, n_x);
                    let (ow, ob) = off[l];
                    // db += Σ_rows g, row by row.
                    for gr in g[..rows * m].chunks_exact(m) {
                        for (d, v) in db[ob..ob + m].iter_mut().zip(gr) {
                            *d += v;
                        }
                    }
                    // SAFETY: g holds rows × m values of this sweep; saved[l - 1] and x hold n rows of
                    // n_h and n_x values, read from row s0; dw has room for every layer's k × m block; Wᵀ is m × k;
                    // this task alone writes rows s0..s0 + rows of dx, which holds n × dx_cols values
                    // (checked); `below` has room for rows × n_h values.
                    unsafe {
                        let gm = Mat::new(&g, m);
                        let xm = Mat::new(x, n_x).at(s0, 0);
                        if n_h > 0 {
                            dense::weight_product(rows, n_h, m, Mat::new(&saved[l - 1], n_h).at(s0, 0), gm, dw.as_mut_ptr().add(ow), !first);
                        }
                        dense::weight_product(rows, n_xl, m, xm, gm, dw.as_mut_ptr().add(ow + n_h * m), !first);
                        let wl = Mat::new(&wt[l], k);
                        if let (Some(dx), true) = (dx, n_xl > 0) {
                            let cols = dx_cols.min(n_xl);
                            dense::product(rows, cols, gm, m, gm, 0, wl.at(0, n_h), dx.add(s0 * dx_cols), dx_cols, Epilogue::ADD);
                        }
                        if l > 0 {
                            let mask = (l - 1 < shape.hidden).then(|| Mat::new(&saved[l - 1], n_h).at(s0, 0));
                            dense::product(rows, n_h, gm, m, gm, 0, wl, below.as_mut_ptr(), n_h, Epilogue { mask, ..Epilogue::STORE });
                        }
                    }
                    if l > 0 {
                        std::mem::swap(&mut g, &mut below);
                    }
                }
            }
            // SAFETY: the first sweep wrote every layer's k × m block (its `split` covers all k inputs),
            // i.e. all of dw's capacity; a task has at least one row.
            unsafe { dw.set_len(dw_all.len()) };
            (dw, db)
        })
        .unzip();
    add_in_order(dw_all, &partial_w);
    add_in_order(db_all, &partial_b);
}

impl CustomOp3 for Network {
    fn name(&self) -> &'static str {
        "mlp"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, w, b) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let (n, n_x) = dims2(l1, op)?;
        let (y, saved) = forward_pass(&self.shape, x, n, n_x, w, b, op)?;
        let m = self.shape.layers.last().map_or(0, |&(_, o)| o);
        *self.saved.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned activations")))? = saved;
        Ok((CpuStorage::F32(y), Shape::from((n, m))))
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
        let n_w: usize = layers.iter().map(|&(i, o)| i * o).sum();
        let n_b: usize = layers.iter().map(|&(_, o)| o).sum();
        let mut out = vec![0.0f32; n_w + n_b + if self.want_dx { n * n_x } else { 0 }];
        let (dw_all, rest) = out.split_at_mut(n_w);
        let (db_all, dx) = rest.split_at_mut(n_b);
        let dx = self.want_dx.then_some((dx, n_x));
        backward_pass(&self.shape, &saved, x, n, n_x, w, y, dy, dw_all, db_all, dx);
        let len = out.len();
        Ok((CpuStorage::F32(out), Shape::from(len)))
    }
}

/// The whole network `x → y` as one op (the `Network` op above); `w` and `b` are the layers' matrices and
/// biases flattened and concatenated in file order.
pub fn network(x: &Tensor, w: &Tensor, b: &Tensor, shape: NetShape) -> Result<Tensor> {
    x.contiguous()?.apply_op3(&w.contiguous()?, &b.contiguous()?, Network { shape, saved: Saved::default() })
}
