//! A whole network `relu(... relu(x W_0 + b_0) ...) W_L + b_L` as one candle op with its own backward
//! pass through all layers (issue 8), built from the same pieces as the per-layer op of [`super::fused`].
//!
//! Why: candle's backward gives every node of a graph a gradient buffer (`zeros_like`, then `add`),
//! two passes over each `[2^15, 128]` activation per layer, plus a node per layer; one op per network
//! took a Single MLP training step from 236 to ~140 ms. The layer-by-layer path stays
//! ([`set_whole_network`]), and trainer/tests/fused.rs checks the two against each other.

use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::fused::{act_grad_colsum, add_bias_act, data, dims2, gemm_into, gemm_new, parallelism, weight_grad_into, ROW_BLOCK};

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
pub(super) fn join(h: &[f32], n_h: usize, x: &[f32], n_x: usize, n: usize) -> Vec<f32> {
    let k = n_h + n_x;
    let mut c = vec![0.0f32; n * k];
    c.par_chunks_mut(ROW_BLOCK * k).zip(h.par_chunks(ROW_BLOCK * n_h).zip(x.par_chunks(ROW_BLOCK * n_x))).for_each(|(c, (h, x))| {
        for (row, (hr, xr)) in c.chunks_exact_mut(k).zip(h.chunks_exact(n_h).zip(x.chunks_exact(n_x))) {
            row[..n_h].copy_from_slice(hr);
            row[n_h..].copy_from_slice(xr);
        }
    });
    c
}

/// The layers of `shape` over `x [n, n_x]` with the concatenated weights `w` and biases `b`: the output
/// `[n, m]` and each hidden layer's activation, which the backward pass reads.
pub(super) fn forward_pass(shape: &NetShape, x: &[f32], n: usize, n_x: usize, w: &[f32], b: &[f32], op: &str) -> Result<(Vec<f32>, Vec<Vec<f32>>)> {
    let off = offsets(shape);
    let n_w: usize = shape.layers.iter().map(|&(i, o)| i * o).sum();
    let n_b: usize = shape.layers.iter().map(|&(_, o)| o).sum();
    if w.len() != n_w || b.len() != n_b || x.len() != n * n_x || shape.layers.first().is_none_or(|&(i, _)| i != n_x) {
        candle_core::bail!("{op}: x [{n}, {n_x}], {} weights, {} biases do not fit {:?}", w.len(), b.len(), shape.layers)
    }
    let mut saved = Vec::with_capacity(shape.layers.len());
    let mut h: Vec<f32> = Vec::new();
    for (l, &(_, m)) in shape.layers.iter().enumerate() {
        let (n_h, n_xl) = shape.split(l, n_x);
        let (ow, ob) = off[l];
        // The skip layer reads `[h, x]` copied side by side, not as two GEMMs into one output: the same
        // sums in the same order as the layer-by-layer path, so the two agree to the last bit (a
        // rounding difference flips ReLUs at the kink and shows in the gradients).
        let joined: Vec<f32>;
        let input: &[f32] = match (n_h, n_xl) {
            (0, _) => x,
            (_, 0) => &h,
            _ => {
                joined = join(&h, n_h, x, n_xl, n);
                &joined
            }
        };
        let k = n_h + n_xl;
        let mut y = gemm_new(n, m, k, input, &w[ow..ow + k * m]);
        add_bias_act(&mut y, &b[ob..ob + m], l < shape.hidden);
        if l > 0 {
            saved.push(std::mem::take(&mut h));
        }
        h = y;
    }
    Ok((h, saved))
}

/// The backward pass of [`forward_pass`] for the output gradient `dy`: writes `dW` and `db` (file
/// order) into `dw_all` and `db_all` and, when `dx = Some((buffer, cols))`, adds the gradient of the
/// input's first `cols` columns into `buffer` (`[n, cols]`): the columns of the Additive Shared
/// specular head's input that come from the trunk, which two heads add into one buffer.
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
    mut dx: Option<(&mut [f32], usize)>,
) {
    let layers = &shape.layers;
    let off = offsets(shape);
    let mut g: Vec<f32> = dy.to_vec();
    for l in (0..layers.len()).rev() {
        let (_, m) = layers[l];
        let (n_h, n_xl) = shape.split(l, n_x);
        let (ow, ob) = off[l];
        // dz = g ⊙ [out > 0] in place, and db = Σ_rows dz.
        let act: &[f32] = if l + 1 == layers.len() { y } else { &saved[l] };
        let db = act_grad_colsum(&mut g, act, m, l < shape.hidden);
        db_all[ob..ob + m].copy_from_slice(&db);
        // dW = [h, x]ᵀ dz, each part split over the batch (see WeightGrad).
        let h: &[f32] = if l == 0 { &[] } else { &saved[l - 1] };
        weight_grad_into(&mut dw_all[ow..ow + n_h * m], h, n_h, &g, m, n);
        weight_grad_into(&mut dw_all[ow + n_h * m..ow + (n_h + n_xl) * m], x, n_xl, &g, m, n);
        // dx += dz W_xᵀ where the layer reads x and x needs a gradient.
        if let (Some((dx, cols)), true) = (dx.as_mut(), n_xl > 0) {
            let cols = (*cols).min(n_xl);
            assert!(dx.len() >= n * cols, "input gradient buffer too small");
            // SAFETY: dx holds n × cols initialised values (checked); g is n × m; the first `cols`
            // rows of W_x, the n_x × m block at ow + n_h m, are read transposed (row stride 1,
            // column stride m).
            unsafe { gemm_into(dx.as_mut_ptr(), true, n, cols, m, &g, w[ow + n_h * m..].as_ptr(), 1, m as isize, parallelism()) };
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
