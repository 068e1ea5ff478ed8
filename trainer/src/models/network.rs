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
use super::fused::{add_in_order, data, dims2, storage_data};

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

impl NetShape {
    /// Lengths of the concatenated matrices and biases: `(Σ in · out, Σ out)`.
    pub fn sizes(&self) -> (usize, usize) {
        (self.layers.iter().map(|&(i, o)| i * o).sum(), self.layers.iter().map(|&(_, o)| o).sum())
    }

    /// Output widths of the layers, in order.
    pub fn widths(&self) -> Vec<usize> {
        self.layers.iter().map(|&(_, m)| m).collect()
    }

    /// Output widths of the layers before the last: the activations a backward pass reads.
    pub fn inner_widths(&self) -> Vec<usize> {
        self.layers[..self.layers.len().saturating_sub(1)].iter().map(|&(_, m)| m).collect()
    }
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

/// Rows per task of the forward pass: each task runs every layer on its block, so that a layer reads
/// its input from L2, where the layer below has just written it (2 × 128 KiB at 128 columns).
pub(super) const FORWARD_ROWS: usize = 256;

/// Rows per task of the backward pass, each task's weight and bias gradients a partial sum of its own
/// rows, added in task order: fixed (not per thread count), so that a step rounds the same way on any
/// machine, and the blocks of the per-layer path ([`super::fused::K_BLOCK`]), so that both agree.
pub(super) const BACKWARD_ROWS: usize = super::fused::K_BLOCK;

/// Rows per sweep through the layers within a backward task: the gradient flows from layer to layer in
/// two buffers of this many rows that stay in L2.
pub(super) const SWEEP_ROWS: usize = 256;

/// Where a pass writes a block of rows: the address of the block's first row and the row stride.
#[derive(Clone, Copy)]
pub(super) struct Dst {
    pub at: Shared,
    pub ld: usize,
}

impl Dst {
    /// The same rows to read.
    #[inline]
    fn mat(self) -> Mat {
        Mat { ptr: self.at.0, ld: self.ld }
    }
}

/// Where a backward sweep puts an input's gradient: `C ← G` (`add: false`) or `C += G`.
#[derive(Clone, Copy)]
pub(super) struct Grad {
    pub to: Dst,
    pub add: bool,
}

/// One network of a pass, its weights checked against its shape and its input: `x [·, n_x]`, which
/// layer 0 and the skip layer read, behind which layer 0 alone may read a `lead [·, n_lead]` first
/// (`[lead, x]`): the Additive Shared specular head reads the trunk's features that way, in place, with
/// the sums of the joined matrix.
///
/// The passes are written for one block of rows ([`Net::forward_rows`], [`Net::backward_rows`]), so
/// that a caller can run several networks on a block while it is in L2 ([`super::additive_shared`]).
pub(super) struct Net<'a> {
    shape: &'a NetShape,
    w: &'a [f32],
    b: &'a [f32],
    off: Vec<(usize, usize)>,
    n_lead: usize,
    n_x: usize,
}

impl<'a> Net<'a> {
    /// `shape` with its concatenated matrices `w` and biases `b` (file order), read from an input of
    /// `n_lead + n_x` columns; an error names what does not fit.
    pub fn new(shape: &'a NetShape, w: &'a [f32], b: &'a [f32], n_lead: usize, n_x: usize, op: &str) -> Result<Self> {
        let (n_w, n_b) = shape.sizes();
        if w.len() != n_w || b.len() != n_b || shape.layers.first().is_none_or(|&(i, _)| i != n_lead + n_x) {
            candle_core::bail!("{op}: an input of {n_lead} + {n_x} columns, {} weights and {} biases do not fit {:?}", w.len(), b.len(), shape.layers)
        }
        let net = Net { shape, w, b, off: offsets(shape), n_lead, n_x };
        if let Some(l) = (1..shape.layers.len()).find(|&l| net.split(l).0 != shape.layers[l - 1].1) {
            candle_core::bail!("{op}: layer {l} does not read the {} outputs of the layer below: {:?}", shape.layers[l - 1].1, shape.layers)
        }
        Ok(net)
    }

    /// Output columns.
    pub fn m(&self) -> usize {
        self.shape.layers.last().map_or(0, |&(_, o)| o)
    }

    /// Columns of the largest matrix side, the width of a sweep's gradient buffers.
    pub fn width(&self) -> usize {
        self.shape.layers.iter().map(|&(k, m)| k.max(m)).max().unwrap_or(0)
    }

    /// Inputs of layer `l` split as (the part before `x`, the `x` part): the lead at layer 0, the
    /// previous activation at the skip layer (`[h, x]`), all of the previous activation elsewhere.
    fn split(&self, l: usize) -> (usize, usize) {
        let n_in = self.shape.layers[l].0;
        match (l, self.shape.skip) {
            (0, _) => (self.n_lead, self.n_x),
            (l, Some(s)) if l == s => (n_in.saturating_sub(self.n_x), self.n_x),
            _ => (n_in, 0),
        }
    }

    /// `Wᵀ` of every layer, which the backward pass multiplies the gradient by.
    pub fn transposed(&self) -> Vec<Vec<f32>> {
        self.shape.layers.iter().zip(&self.off).map(|(&(k, m), &(ow, _))| transpose(&self.w[ow..ow + k * m], k, m)).collect()
    }

    /// The layers on `rows` rows, `x` and `lead` from the block's first row, layer `l`'s output to
    /// `dst[l]`: each layer's GEMM applies its bias and ReLU before storing ([`dense::product`]) and
    /// reads the rows the layer below has just written, from L2; the skip layer reads `[h, x]` from the
    /// two matrices in place, its sums in the order of the joined input.
    ///
    /// # Safety
    /// `x` and `lead` must address `rows` rows of `n_x` and `n_lead` values, and `dst[l]` room for
    /// `rows` rows of layer `l`'s outputs that no one else writes meanwhile.
    pub unsafe fn forward_rows(&self, rows: usize, x: Mat, lead: Mat, dst: &[Dst]) {
        for (l, &(_, m)) in self.shape.layers.iter().enumerate() {
            let (n_h, n_xl) = self.split(l);
            let (ow, ob) = self.off[l];
            let hm = if l > 0 { dst[l - 1].mat() } else { lead };
            let (a1, p1, a2, p2) = match (n_h, n_xl) {
                (0, _) => (x, n_xl, x, 0),
                (_, 0) => (hm, n_h, hm, 0),
                _ => (hm, n_h, x, n_xl),
            };
            let epi = Epilogue { bias: Some(self.b[ob..].as_ptr()), relu: l < self.shape.hidden, ..Epilogue::STORE };
            // SAFETY: the caller's contract for x, lead and dst; the weights and biases are the layer's
            // (offsets of the checked shape).
            unsafe { dense::product(rows, m, a1, p1, a2, p2, Mat::new(&self.w[ow..], m), dst[l].at.0, dst[l].ld, epi) };
        }
    }

    /// The layers over `x [n, n_x]` (and `lead [n, n_lead]`): the output `[n, m]` and each hidden
    /// layer's activation, which the backward pass reads; blocks of [`FORWARD_ROWS`] rows in parallel.
    pub fn forward_pass(&self, x: &[f32], lead: &[f32], n: usize, op: &str) -> Result<(Vec<f32>, Vec<Vec<f32>>)> {
        if x.len() != n * self.n_x || lead.len() != n * self.n_lead {
            candle_core::bail!("{op}: {} and {} input values for {n} rows of {} and {} columns", x.len(), lead.len(), self.n_x, self.n_lead)
        }
        let mut outs: Vec<Vec<f32>> = self.shape.layers.iter().map(|&(_, m)| Vec::with_capacity(n * m)).collect();
        let m_of = self.shape.widths();
        let dst: Vec<Dst> = outs.iter_mut().zip(&m_of).map(|(o, &m)| Dst { at: Shared(o.as_mut_ptr()), ld: m }).collect();
        (0..n.div_ceil(FORWARD_ROWS)).into_par_iter().for_each(|t| {
            let (r0, rows) = (t * FORWARD_ROWS, FORWARD_ROWS.min(n - t * FORWARD_ROWS));
            // SAFETY: x and lead hold n rows (checked), read from row r0; each output has room for n
            // rows, of which this task alone writes rows r0..r0 + rows.
            unsafe {
                let at: Vec<Dst> = dst.iter().map(|d| Dst { at: Shared(d.at.add(r0 * d.ld)), ld: d.ld }).collect();
                let xm = Mat::new(x, self.n_x).at(r0, 0);
                let lead = if self.n_lead > 0 { Mat::new(lead, self.n_lead).at(r0, 0) } else { xm };
                self.forward_rows(rows, xm, lead, &at);
            }
        });
        for (o, m) in outs.iter_mut().zip(m_of) {
            // SAFETY: the tasks above wrote all n rows of every layer's output.
            unsafe { o.set_len(n * m) };
        }
        let y = outs.pop().unwrap_or_default();
        Ok((y, outs))
    }

    /// The backward pass on one sweep of `rows` rows from the gradient `dy` of the network's output:
    /// `dW` and `db` of every layer into `dw` and `db` (the network's blocks, file order; `first`:
    /// `dw` is written, not added to), and the gradients of `x` and `lead` into `dx` and `dlead`.
    ///
    /// The gradient `g` of a layer's output is masked by its ReLU, summed into the bias gradient,
    /// multiplied into the weight gradient, and carried to the layer below as `(g Wᵀ) ⊙ [h > 0]` in
    /// one GEMM with a masking epilogue, in the two `scratch` buffers, without leaving L2.
    ///
    /// `acts[l]` are the hidden layers' outputs and `y` the network's output, read only through an
    /// output ReLU (a trunk); all, like `x`, `lead` and `dy`, from the sweep's first row.
    ///
    /// # Safety
    /// Every matrix must address `rows` rows of its layer's width; `dw` room for every layer's
    /// matrix (initialised unless `first`); `wt` must be [`Net::transposed`]; `scratch` buffers at
    /// least `rows × `[`Net::width`] values; `dx` and `dlead` room for `rows` rows of `n_x` and
    /// `n_lead` values (initialised when they add) that no one else writes meanwhile.
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn backward_rows(
        &self,
        wt: &[Vec<f32>],
        rows: usize,
        acts: &[Mat],
        y: Option<Mat>,
        x: Mat,
        lead: Mat,
        dy: Mat,
        dw: *mut f32,
        db: &mut [f32],
        first: bool,
        scratch: (&mut Vec<f32>, &mut Vec<f32>),
        dx: Option<Grad>,
        dlead: Option<Grad>,
    ) {
        let (mut g, mut below) = scratch;
        let layers = &self.shape.layers;
        let m_top = self.m();
        // The output's gradient goes through the output layer's ReLU where it has one (a trunk).
        let top = y.filter(|_| layers.len() <= self.shape.hidden);
        for (r, gr) in g.chunks_exact_mut(m_top).take(rows).enumerate() {
            // SAFETY: row r < rows of dy and y (the caller's contract).
            let (dr, yr) = unsafe { (std::slice::from_raw_parts(dy.at(r, 0).ptr, m_top), top.map(|y| std::slice::from_raw_parts(y.at(r, 0).ptr, m_top))) };
            match yr {
                Some(yr) => gr.iter_mut().zip(dr).zip(yr).for_each(|((gv, &dv), &yv)| *gv = if yv > 0.0 { dv } else { 0.0 }),
                None => gr.copy_from_slice(dr),
            }
        }
        let mut dx_written = false;
        for l in (0..layers.len()).rev() {
            let (k, m) = layers[l];
            let (n_h, n_xl) = self.split(l);
            let (ow, ob) = self.off[l];
            // db += Σ_rows g, row by row.
            for gr in g[..rows * m].chunks_exact(m) {
                for (d, v) in db[ob..ob + m].iter_mut().zip(gr) {
                    *d += v;
                }
            }
            let gm = Mat::new(g, m);
            let hm = if l > 0 { acts[l - 1] } else { lead };
            let wl = Mat::new(&wt[l], k);
            // SAFETY: the caller's contract; the blocks of dw and Wᵀ are the layer's (offsets of the
            // checked shape), `below` has room for rows × n_h values.
            unsafe {
                if n_h > 0 {
                    dense::weight_product(rows, n_h, m, hm, gm, dw.add(ow), !first);
                }
                dense::weight_product(rows, n_xl, m, x, gm, dw.add(ow + n_h * m), !first);
                if let (Some(d), true) = (dx, n_xl > 0) {
                    // x may be read twice (layer 0 and the skip layer): the second adds.
                    let epi = if d.add || dx_written { Epilogue::ADD } else { Epilogue::STORE };
                    dx_written = true;
                    dense::product(rows, n_xl, gm, m, gm, 0, wl.at(0, n_h), d.to.at.0, d.to.ld, epi);
                }
                if l > 0 {
                    let mask = (l - 1 < self.shape.hidden).then_some(hm);
                    dense::product(rows, n_h, gm, m, gm, 0, wl, below.as_mut_ptr(), n_h, Epilogue { mask, ..Epilogue::STORE });
                } else if let (Some(d), true) = (dlead, n_h > 0) {
                    let epi = if d.add { Epilogue::ADD } else { Epilogue::STORE };
                    dense::product(rows, n_h, gm, m, gm, 0, wl, d.to.at.0, d.to.ld, epi);
                }
            }
            if l > 0 {
                std::mem::swap(&mut g, &mut below);
            }
        }
    }

    /// The backward pass of [`Net::forward_pass`] (without a lead) for the output gradient `dy`:
    /// writes `dW` and `db` (file order) into `dw_all` and `db_all` (which start at zero) and, when
    /// `dx` is given (`[n, n_x]`), adds the input's gradient into it.
    ///
    /// Tasks of [`BACKWARD_ROWS`] rows run in parallel, each sweeping [`SWEEP_ROWS`] rows at a time
    /// down through all layers ([`Net::backward_rows`]); their partial sums are added in task order.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_pass(&self, saved: &[Vec<f32>], x: &[f32], n: usize, y: &[f32], dy: &[f32], dw_all: &mut [f32], db_all: &mut [f32], dx: Option<&mut [f32]>) {
        let (n_x, m_top, n_layers) = (self.n_x, self.m(), self.shape.layers.len());
        assert!(
            self.n_lead == 0
                && saved.len() + 1 == n_layers
                && saved.iter().zip(&self.shape.layers).all(|(s, &(_, m))| s.len() == n * m)
                && x.len() == n * n_x
                && y.len() == n * m_top
                && dy.len() == n * m_top
                && dw_all.len() == self.w.len()
                && db_all.len() == self.b.len()
                && dx.as_ref().is_none_or(|d| d.len() == n * n_x),
            "backward_pass: shapes"
        );
        let wt = self.transposed();
        let dx = dx.map(|d| Dst { at: Shared(d.as_mut_ptr()), ld: n_x });
        let width = self.width();
        let (partial_w, partial_b): (Vec<Vec<f32>>, Vec<Vec<f32>>) = (0..n.div_ceil(BACKWARD_ROWS))
            .into_par_iter()
            .map(|t| {
                // Written by the first sweep's products (which start their sums from the product, as from
                // zero), accumulated by the later ones: no zero fill of a copy of every weight.
                let mut dw: Vec<f32> = Vec::with_capacity(dw_all.len());
                let mut db = vec![0.0f32; db_all.len()];
                let mut g = vec![0.0f32; SWEEP_ROWS * width];
                let mut below = vec![0.0f32; SWEEP_ROWS * width];
                let (start, end) = (t * BACKWARD_ROWS, ((t + 1) * BACKWARD_ROWS).min(n));
                for s0 in (start..end).step_by(SWEEP_ROWS) {
                    // SAFETY: every buffer holds n rows of its width (asserted), read or written from
                    // row s0 for `rows` rows; this task alone writes these rows of dx (which adds);
                    // dw has room for every layer's matrix, written by the first sweep.
                    unsafe {
                        let acts: Vec<Mat> = saved.iter().zip(&self.shape.layers).map(|(s, &(_, m))| Mat::new(s, m).at(s0, 0)).collect();
                        let dx = dx.map(|d| Grad { to: Dst { at: Shared(d.at.add(s0 * n_x)), ld: n_x }, add: true });
                        let rows = SWEEP_ROWS.min(end - s0);
                        let (ym, dym, xm) = (Mat::new(y, m_top).at(s0, 0), Mat::new(dy, m_top).at(s0, 0), Mat::new(x, n_x).at(s0, 0));
                        self.backward_rows(&wt, rows, &acts, Some(ym), xm, xm, dym, dw.as_mut_ptr(), &mut db, s0 == start, (&mut g, &mut below), dx, None);
                    }
                }
                // SAFETY: the first sweep wrote every layer's k × m block (its `split` covers all k
                // inputs), i.e. all of dw's capacity; a task has at least one row.
                unsafe { dw.set_len(dw_all.len()) };
                (dw, db)
            })
            .unzip();
        add_in_order(dw_all, &partial_w);
        add_in_order(db_all, &partial_b);
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
        let (y, saved) = Net::new(&self.shape, w, b, 0, n_x, op)?.forward_pass(x, &[], n, op)?;
        let m = self.shape.layers.last().map_or(0, |&(_, o)| o);
        *self.saved.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned activations")))? = saved;
        Ok((CpuStorage::F32(y), Shape::from((n, m))))
    }

    fn bwd(&self, x: &Tensor, w: &Tensor, b: &Tensor, y: &Tensor, dy: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let back = NetworkGrad { shape: self.shape.clone(), saved: self.saved.clone(), w: w.contiguous()?, b: b.contiguous()?, want_dx: x.track_op() };
        let (n, n_x) = x.dims2()?;
        let packed = dy.contiguous()?.apply_op3_no_bwd(&y.contiguous()?, &x.contiguous()?, &back)?;
        let (n_w, n_b) = (w.elem_count(), b.elem_count());
        let dw = packed.narrow(0, 0, n_w)?;
        let db = packed.narrow(0, n_w, n_b)?;
        let dx = if back.want_dx { Some(packed.narrow(0, n_w + n_b, n * n_x)?.reshape((n, n_x))?) } else { None };
        Ok((dx, Some(dw), Some(db)))
    }
}

/// The backward pass of [`Network`] over `(dy [N, m], y [N, m], x [N, n_in])`, `y` the network's
/// output: `dw ++ db ++ dx` (dx only when the input needs it), 1-D. The weights `w` and biases `b`
/// ride along in the op (an op takes at most three tensors).
struct NetworkGrad {
    shape: NetShape,
    saved: Saved,
    w: Tensor,
    b: Tensor,
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
        let ((w_storage, w_layout), (b_storage, b_layout)) = (self.w.storage_and_layout(), self.b.storage_and_layout());
        let (w, b) = (storage_data(&w_storage, w_layout, op)?, storage_data(&b_storage, b_layout, op)?);
        let saved = self.saved.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned activations")))?;
        if saved.len() + 1 != layers.len() {
            candle_core::bail!("{op}: backward without its forward pass")
        }
        let (n_w, n_b) = self.shape.sizes();
        let mut out = vec![0.0f32; n_w + n_b + if self.want_dx { n * n_x } else { 0 }];
        let (dw_all, rest) = out.split_at_mut(n_w);
        let (db_all, dx) = rest.split_at_mut(n_b);
        let net = Net::new(&self.shape, w, b, 0, n_x, op);
        net?.backward_pass(&saved, x, n, y, dy, dw_all, db_all, self.want_dx.then_some(dx));
        let len = out.len();
        Ok((CpuStorage::F32(out), Shape::from(len)))
    }
}

/// The whole network `x → y` as one op (the `Network` op above); `w` and `b` are the layers' matrices and
/// biases flattened and concatenated in file order.
pub fn network(x: &Tensor, w: &Tensor, b: &Tensor, shape: NetShape) -> Result<Tensor> {
    x.contiguous()?.apply_op3(&w.contiguous()?, &b.contiguous()?, Network { shape, saved: Saved::default() })
}
