//! A network's passes on one block of rows: the layers of docs/models.md ("Mlp") forward, each
//! layer's product applying its bias and ReLU before it stores the block, and backward, the gradient
//! flowing from layer to layer in two buffers that stay in L2. The fused step ([`super::step`]) runs
//! them, and several networks on one block ([`super::trunked`]).

use candle_core::Result;

use super::dense::{self, Epilogue, Mat, Shared};
use crate::models::Mlp;

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
pub(crate) const FORWARD_ROWS: usize = 256;

/// Rows per task of the backward pass, each task's weight and bias gradients a partial sum of its own
/// rows, added in task order: fixed (not per thread count), so that a step rounds the same way on any
/// machine, and the blocks of the objective's sums ([`super::op::ROW_BLOCK`]).
pub(crate) const BACKWARD_ROWS: usize = super::op::ROW_BLOCK;

/// Rows per sweep through the layers within a backward task: the gradient flows from layer to layer in
/// two buffers of this many rows that stay in L2.
pub(crate) const SWEEP_ROWS: usize = 256;

/// Where a pass writes a block of rows: the address of the block's first row and the row stride.
#[derive(Clone, Copy)]
pub(crate) struct Dst {
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
pub(crate) struct Grad {
    pub to: Dst,
    pub add: bool,
}

/// One network of a pass, its weights checked against its shape and its input: `x [·, n_x]`, which
/// layer 0 and the skip layer read, behind which layer 0 alone may read a `lead [·, n_lead]` first
/// (`[lead, x]`): the Additive Shared specular head reads the trunk's features that way, in place, with
/// the sums of the joined matrix.
///
/// The passes are written for one block of rows ([`Net::forward_rows`], [`Net::backward_rows`]), so
/// that a caller can run several networks on a block while it is in L2 ([`super::trunked`]).
pub(crate) struct Net<'a> {
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
}

/// What the passes need to know of `net`: its layers, which end in a ReLU, and the skip layer.
pub(crate) fn shape_of(net: &Mlp) -> NetShape {
    NetShape { layers: crate::models::arch::layers(&net.desc), hidden: net.desc.hidden as usize, skip: net.skip() }
}
