//! A Single MLP's loss and its gradient in the weights as one candle op that runs the forward pass,
//! the objective and the backward pass on each block of rows in turn (issue 8).
//!
//! Why: the objective of a batch is a sum over its samples, so a block's gradient in the weights needs
//! nothing of the other blocks. As a network op followed by the objective op, every hidden
//! activation of the batch (six `[2^15, 128]` matrices, 96 MiB) went to memory in the forward pass and
//! came back in the backward one, as did the network output and its gradient; here a task runs its
//! 1024 rows forward, through the objective and backward while its activations (3 MiB) stay in its
//! core's caches. The sums are the unfused path's, bit for bit: the same row blocks
//! ([`super::network::FORWARD_ROWS`], [`BACKWARD_ROWS`], [`super::fused::ROW_BLOCK`]) in the same
//! order; trainer/tests/fused.rs compares the two.

use std::sync::{Arc, Mutex};

use candle_core::{CpuStorage, CustomOp2, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::dense::{Mat, Shared};
use super::fused::{add_in_order, data, dims2, ROW_BLOCK};
use super::mlp::Mlp;
use super::network::{Dst, Net, NetShape, BACKWARD_ROWS, FORWARD_ROWS, SWEEP_ROWS};
use crate::objective::{self, Constants, Head};

// A task's rows must be one block of the objective's sums, so that the loss is the unfused op's.
const _: () = assert!(BACKWARD_ROWS == ROW_BLOCK && BACKWARD_ROWS.is_multiple_of(FORWARD_ROWS));

thread_local! {
    /// Whether [`crate::objective::objective`] on this thread runs a Single MLP's step as this op.
    static FUSED_STEP: std::cell::Cell<bool> = const { std::cell::Cell::new(true) };
}

/// Chooses, for objectives built on this thread, between this op (`true`, the default) and the
/// network op followed by the objective op; tests compare the two.
pub fn set_fused_step(on: bool) {
    FUSED_STEP.with(|f| f.set(on));
}

/// Whether objectives built on this thread use this op (see [`set_fused_step`]).
pub fn fused_step() -> bool {
    FUSED_STEP.with(|f| f.get())
}

/// The op over `(x [N, n_x], p)`, `p` the network's matrices then its biases (file order); the
/// batch's constants ride along. Its value is the loss; its gradient in `p`, computed with it, waits
/// for the backward pass.
struct Step {
    shape: NetShape,
    head: Head,
    incident: Tensor,
    target: Tensor,
    valid: Tensor,
    grad: Arc<Mutex<Vec<f32>>>,
}

/// The contiguous f32 data of a CPU tensor.
fn cpu<'a>(s: &'a candle_core::Storage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let candle_core::Storage::Cpu(c) = s else { candle_core::bail!("{op}: CPU tensors only") };
    data(c, l, op)
}

/// A task's buffers: every layer's output on its rows, the output's gradient, and the backward
/// sweep's two gradient buffers.
#[derive(Default)]
struct Scratch {
    acts: Vec<Vec<f32>>,
    du: Vec<f32>,
    g: Vec<f32>,
    below: Vec<f32>,
}

impl Scratch {
    /// Grows the buffers (never shrinks them) to a task of `layers` with `k` outputs and matrices of
    /// at most `width` columns.
    fn fit(&mut self, layers: &[(usize, usize)], k: usize, width: usize) {
        let grow = |v: &mut Vec<f32>, n: usize| {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        };
        self.acts.resize_with(self.acts.len().max(layers.len()), Vec::new);
        for (a, &(_, m)) in self.acts.iter_mut().zip(layers) {
            grow(a, BACKWARD_ROWS * m);
        }
        grow(&mut self.du, BACKWARD_ROWS * k);
        grow(&mut self.g, SWEEP_ROWS * width);
        grow(&mut self.below, SWEEP_ROWS * width);
    }
}

thread_local! {
    /// Each worker thread's [`Scratch`], kept from step to step: allocated per task, its ~3 MiB were
    /// zeroed 16–17 times a step (rayon's splits of 32 tasks).
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

impl CustomOp2 for Step {
    fn name(&self) -> &'static str {
        "single-mlp-step"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, p) = (data(s1, l1, op)?, data(s2, l2, op)?);
        let (n, n_x) = dims2(l1, op)?;
        let n_w: usize = self.shape.layers.iter().map(|&(i, o)| i * o).sum();
        if p.len() < n_w {
            candle_core::bail!("{op}: {} parameters for {:?}", p.len(), self.shape.layers)
        }
        let (w, b) = p.split_at(n_w);
        let net = Net::new(&self.shape, w, b, 0, n_x, op)?;
        let k = self.head.width();
        if net.m() != k {
            candle_core::bail!("{op}: a network of {} outputs for a head of {k}", net.m())
        }
        let (si, li) = self.incident.storage_and_layout();
        let (st, lt) = self.target.storage_and_layout();
        let (sv, lv) = self.valid.storage_and_layout();
        let c = Constants { incident: cpu(&si, li, op)?, target: cpu(&st, lt, op)?, valid: cpu(&sv, lv, op)? };
        if c.valid.len() != n || c.incident.len() != 3 * n || c.target.len() != 3 * n {
            candle_core::bail!("{op}: {} incident, {} target and {} valid values for {n} samples", c.incident.len(), c.target.len(), c.valid.len())
        }
        let (scale, head, layers) = (objective::scale_of(n), self.head, &self.shape.layers);
        let wt = net.transposed();
        let width = net.width();
        let parts: Vec<([f64; 3], Vec<f32>)> = (0..n.div_ceil(BACKWARD_ROWS))
            .into_par_iter()
            .map(|task| SCRATCH.with_borrow_mut(|sc| {
                sc.fit(layers, k, width);
                let (start, end) = (task * BACKWARD_ROWS, ((task + 1) * BACKWARD_ROWS).min(n));
                let rows = end - start;
                // SAFETY: x holds n rows of n_x values (checked by `dims2` and the layout), read from
                // row `start`; every scratch buffer holds BACKWARD_ROWS ≥ rows rows of its width,
                // written by the forward sub-blocks in turn and then read; `part` has room for p.len()
                // values: the biases are zeroed here, the matrices written by the first sweep.
                unsafe {
                    let xm = Mat::new(x, n_x).at(start, 0);
                    for f0 in (0..rows).step_by(FORWARD_ROWS) {
                        let dst: Vec<Dst> = sc.acts.iter_mut().zip(layers).map(|(a, &(_, m))| Dst { at: Shared(a.as_mut_ptr().add(f0 * m)), ld: m }).collect();
                        net.forward_rows(FORWARD_ROWS.min(rows - f0), xm.at(f0, 0), xm, &dst);
                    }
                    let du = &mut sc.du[..rows * k];
                    du.fill(0.0);
                    let sums = objective::rows(head, &sc.acts[layers.len() - 1][..rows * k], du, c, start, scale);
                    let mut part: Vec<f32> = Vec::with_capacity(p.len());
                    let base = part.as_mut_ptr();
                    std::ptr::write_bytes(base.add(n_w), 0, p.len() - n_w);
                    let db = std::slice::from_raw_parts_mut(base.add(n_w), p.len() - n_w);
                    for s0 in (0..rows).step_by(SWEEP_ROWS) {
                        let acts: Vec<Mat> = sc.acts.iter().zip(layers).map(|(a, &(_, m))| Mat::new(a, m).at(s0, 0)).collect();
                        let (hidden, y) = acts.split_at(acts.len() - 1);
                        let dy = Mat::new(&sc.du, k).at(s0, 0);
                        let sweep = SWEEP_ROWS.min(rows - s0);
                        let scratch = (&mut sc.g, &mut sc.below);
                        net.backward_rows(&wt, sweep, hidden, Some(y[0]), xm.at(s0, 0), xm, dy, base, db, s0 == 0, scratch, None, None);
                    }
                    part.set_len(p.len());
                    (sums, part)
                }
            }))
            .collect();
        let sums: Vec<[f64; 3]> = parts.iter().map(|(s, _)| *s).collect();
        let grads: Vec<Vec<f32>> = parts.into_iter().map(|(_, g)| g).collect();
        let mut dp = vec![0.0f32; p.len()];
        add_in_order(&mut dp, &grads);
        *self.grad.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned gradient")))? = dp;
        Ok((CpuStorage::F32(vec![objective::loss_of(head, &sums, scale) as f32]), Shape::from(())))
    }

    fn bwd(&self, x: &Tensor, p: &Tensor, _loss: &Tensor, grad_loss: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let op = self.name();
        if x.track_op() {
            candle_core::bail!("{op}: the network input is an input of the batch; no gradient flows into it")
        }
        let dp = self.grad.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned gradient")))?.clone();
        if dp.len() != p.elem_count() {
            candle_core::bail!("{op}: backward without its forward pass")
        }
        Ok((None, Some(Tensor::from_vec(dp, p.shape(), p.device())?.broadcast_mul(grad_loss)?)))
    }
}

/// The loss of a batch for a Single MLP `net` on its input `x` with the softplus head, and its
/// gradient in the network's weights, as one op (the module docs).
pub fn single_mlp_loss(net: &Mlp, x: &Tensor, incident: &Tensor, target: &Tensor, valid: &Tensor) -> Result<Tensor> {
    let (w, b) = net.flat()?;
    let p = Tensor::cat(&[&w, &b], 0)?;
    let op = Step {
        shape: net.net_shape(),
        head: Head::Softplus,
        incident: incident.contiguous()?,
        target: target.contiguous()?,
        valid: valid.contiguous()?,
        grad: Arc::default(),
    };
    x.contiguous()?.apply_op2(&p, op)
}
