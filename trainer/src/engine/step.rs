//! The training step: the loss of a batch and its gradient in the weights as one candle op that runs
//! the forward pass, the objective and the backward pass on each block of rows in turn, for every
//! model. The only way the trainer computes a gradient; `Model::forward` and [`super::loss`] composed
//! from candle ops are its definition, which trainer/tests/engine.rs checks it against.
//!
//! Why one op: the objective of a batch is a sum over its samples, so a block's gradient in the
//! weights needs nothing of the other blocks. A task runs its 1024 rows forward, through the objective
//! and backward while its activations (3–4 MiB) stay in its core's caches, where separate ops sent
//! every hidden activation of the batch (six `[2^15, 128]` matrices for the Single MLP, 96 MiB) to
//! memory and back. The sums run over fixed row blocks ([`FORWARD_ROWS`], [`BACKWARD_ROWS`],
//! [`ROW_BLOCK`]) added in block order, so a step rounds the same way for any number of threads.

use std::sync::{Arc, Mutex};

use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::dense::{Mat, Shared};
use super::network::{shape_of, Dst, Net, NetShape, BACKWARD_ROWS, FORWARD_ROWS, SWEEP_ROWS};
use super::objective::{self, BatchConstants, Constants, Head};
use super::op::{add_in_order, data, dims2, ROW_BLOCK};
use super::trunked::Trunked;
use super::{Batch, Regularisers};
use crate::models::{parametric, Kind, Mlp, Model};
use nbrdf::parametric::{Parametric, ParametricKind};
use nbrdf::Vec3;

// A task's rows must be one block of the objective's sums, so that the loss does not depend on the
// number of threads.
const _: () = assert!(BACKWARD_ROWS == ROW_BLOCK && BACKWARD_ROWS.is_multiple_of(FORWARD_ROWS));

/// The networks of a fused step.
enum Nets {
    /// Networks side by side, each on `x` or (`true`) on `a`, their outputs side by side: the Single
    /// MLP (one network on the joint input), Additive Separate (the diffuse network on the position
    /// encoding, the specular one on the joint input).
    Parallel(Vec<(NetShape, bool)>),
    /// A trunk on the position `x` and its heads ([`Trunked`]): the Additive Shared model (diffuse
    /// head, specular head on `[t, a]`), a Single MLP whose directions enter late (one head on `[t, a]`).
    Trunked(Vec<NetShape>),
    /// A parametric model: the network on the position `x` predicts the raw parameters of `kind`
    /// at each sample's direction pair, `n_object` per-object parameters follow the weights in `p`.
    Parametric { shape: NetShape, kind: ParametricKind, pairs: Arc<Vec<[Vec3; 2]>> },
}

/// The op over `(x [N, n_x], a [N, n_a], p)`: the network input (a trunk's position encoding), the
/// angle encoding (read by a trunk's specular head only) and the networks' weights, each network's
/// matrices then its biases ([`flat`]). The batch's constants ride along.
/// Its value is the loss; its gradient in `p`, computed with it, waits for the backward pass.
struct Step {
    nets: Nets,
    head: Head,
    batch: BatchConstants,
    grad: Arc<Mutex<Vec<f32>>>,
}


/// A task's buffers: the networks' layer outputs on its rows (`acts`), the packed raw outputs `u`
/// and their gradient `du` (`[rows, k]`), a backward sweep's two gradient buffers, and the buffer that
/// carries the Additive Shared heads' `∂t` to the trunk.
#[derive(Default)]
struct Scratch {
    acts: Vec<Vec<f32>>,
    u: Vec<f32>,
    du: Vec<f32>,
    g: Vec<f32>,
    below: Vec<f32>,
    dt: Vec<f32>,
}

impl Scratch {
    /// Grows the buffers (never shrinks them) to a task of layers of `widths` outputs, `k` raw
    /// outputs, matrices of at most `width` columns and a trunk of `n_t` outputs.
    fn fit(&mut self, widths: &[usize], k: usize, width: usize, n_t: usize) {
        let grow = |v: &mut Vec<f32>, n: usize| {
            if v.len() < n {
                v.resize(n, 0.0);
            }
        };
        self.acts.resize_with(self.acts.len().max(widths.len()), Vec::new);
        for (a, &m) in self.acts.iter_mut().zip(widths) {
            grow(a, BACKWARD_ROWS * m);
        }
        grow(&mut self.u, BACKWARD_ROWS * k);
        grow(&mut self.du, BACKWARD_ROWS * k);
        grow(&mut self.g, SWEEP_ROWS * width);
        grow(&mut self.below, SWEEP_ROWS * width);
        grow(&mut self.dt, SWEEP_ROWS * n_t);
    }

    /// Where the forward pass writes buffer `i` of `ld` columns, from row `r` on.
    fn dst(&mut self, i: usize, ld: usize, r: usize) -> Dst {
        // SAFETY: `fit` sized every buffer for BACKWARD_ROWS rows; callers stay within a task's rows.
        Dst { at: Shared(unsafe { self.acts[i].as_mut_ptr().add(r * ld) }), ld }
    }

    /// Buffer `i` of `ld` columns from row `r` on, to read.
    fn mat(&self, i: usize, ld: usize, r: usize) -> Mat {
        // SAFETY: as for `dst`.
        unsafe { Mat::new(&self.acts[i], ld).at(r, 0) }
    }
}

thread_local! {
    /// Each worker thread's [`Scratch`], kept from step to step: allocated per task, its ~3 MiB were
    /// zeroed 16–17 times a step (rayon's splits of 32 tasks).
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Runs the tasks of a step over `n` rows: per task, `forward(scratch, start, rows)` writes the raw
/// outputs to `scratch.u`, the objective turns them into `scratch.du`, and `backward(scratch, start,
/// rows, s0, first, dp)` runs sweep `s0` into the task's gradient `dp` (laid out as `p`, its bias
/// blocks zeroed by `zero`). Returns the loss and `d loss / d p`, both summed in task order.
#[allow(clippy::too_many_arguments)]
fn run_tasks(
    n: usize,
    p_len: usize,
    head: Head,
    c: Constants<'_>,
    fit: impl Fn(&mut Scratch) + Sync,
    forward: impl Fn(&mut Scratch, usize, usize) + Sync,
    zero: impl Fn(*mut f32) + Sync,
    backward: impl Fn(&mut Scratch, usize, usize, usize, bool, *mut f32) + Sync,
) -> (f64, Vec<f32>) {
    let (k, scale) = (head.width(), objective::scale_of(n));
    let parts: Vec<([f64; 3], Vec<f32>)> = (0..n.div_ceil(BACKWARD_ROWS))
        .into_par_iter()
        .map(|task| {
            SCRATCH.with_borrow_mut(|sc| {
                fit(sc);
                let (start, end) = (task * BACKWARD_ROWS, ((task + 1) * BACKWARD_ROWS).min(n));
                let rows = end - start;
                for f0 in (0..rows).step_by(FORWARD_ROWS) {
                    forward(sc, start + f0, FORWARD_ROWS.min(rows - f0));
                }
                let du = &mut sc.du[..rows * k];
                du.fill(0.0);
                let sums = objective::rows(head, &sc.u[..rows * k], du, c, start, scale);
                // The matrices' blocks are written by the first sweep, the biases' blocks are added
                // to from zero: no zero fill of a copy of every weight.
                let mut part: Vec<f32> = Vec::with_capacity(p_len);
                zero(part.as_mut_ptr());
                for s0 in (0..rows).step_by(SWEEP_ROWS) {
                    backward(sc, start, SWEEP_ROWS.min(rows - s0), s0, s0 == 0, part.as_mut_ptr());
                }
                // SAFETY: the first sweep wrote every matrix block and `zero` every bias block.
                unsafe { part.set_len(p_len) };
                (sums, part)
            })
        })
        .collect();
    let sums: Vec<[f64; 3]> = parts.iter().map(|(s, _)| *s).collect();
    let grads: Vec<Vec<f32>> = parts.into_iter().map(|(_, g)| g).collect();
    let mut dp = vec![0.0f32; p_len];
    add_in_order(&mut dp, &grads);
    (objective::loss_of(head, &sums, scale), dp)
}

impl CustomOp3 for Step {
    fn name(&self) -> &'static str {
        "fused-step"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, a, p) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let ((n, n_x), (n_a_rows, n_a)) = (dims2(l1, op)?, dims2(l2, op)?);
        self.batch.with(op, |c| self.run(x, (n, n_x), a, (n_a_rows, n_a), p, c))
    }

    fn bwd(&self, x: &Tensor, a: &Tensor, p: &Tensor, _loss: &Tensor, grad_loss: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let op = self.name();
        if x.track_op() || a.track_op() {
            candle_core::bail!("{op}: the network inputs are inputs of the batch; no gradient flows into them")
        }
        Ok((None, None, Some(objective::kept_gradient(&self.grad, p, grad_loss, op)?)))
    }
}

impl Step {
    /// The loss of the batch `(x, a)` (their `[rows, cols]`) for the weights `p` and the batch's
    /// constants `c`; keeps the gradient in `p` for the backward pass.
    fn run(&self, x: &[f32], (n, n_x): (usize, usize), a: &[f32], (n_a_rows, n_a): (usize, usize), p: &[f32], c: Constants<'_>) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        if n_a_rows != n || c.valid.len() != n || c.incident.len() != 3 * n || c.target.len() != 3 * n {
            candle_core::bail!("{op}: {n_a_rows} angle rows, {} incident, {} target and {} valid values for {n} samples", c.incident.len(), c.target.len(), c.valid.len())
        }
        let (head, k) = (self.head, self.head.width());
        // SAFETY (the closures below): x and a hold n rows (checked), read from a task's rows; the
        // scratch buffers are sized by `fit` for a task; `dp` has room for p.len() values.
        let (loss, dp) = match &self.nets {
            Nets::Parallel(nets) => {
                // Each network's blocks of p, its Net, and where its output starts in u.
                let mut built = Vec::with_capacity(nets.len());
                let (mut o, mut col) = (0, 0);
                for (shape, on_a) in nets {
                    let (n_w, n_b) = shape.sizes();
                    let Some(block) = p.get(o..o + n_w + n_b) else { candle_core::bail!("{op}: {} parameters for {:?}", p.len(), shape.layers) };
                    let net = Net::new(shape, &block[..n_w], &block[n_w..], 0, if *on_a { n_a } else { n_x }, op)?;
                    let (m, at) = (net.m(), (o, o + n_w, n_b));
                    built.push((net, *on_a, at, col, shape.inner_widths()));
                    (o, col) = (o + n_w + n_b, col + m);
                }
                if o != p.len() || col != k {
                    candle_core::bail!("{op}: {} parameters and {col} outputs for networks of {o} and a head of {k}", p.len())
                }
                let wt: Vec<Vec<Vec<f32>>> = built.iter().map(|b| b.0.transposed()).collect();
                let width = built.iter().map(|b| b.0.width()).max().unwrap_or(0);
                // The hidden layers' buffers of all networks in a row; network i's start at first[i].
                let widths: Vec<usize> = built.iter().flat_map(|b| b.4.iter().copied()).collect();
                let first: Vec<usize> = built.iter().scan(0, |at, b| Some(std::mem::replace(at, *at + b.4.len()))).collect();
                // SAFETY (the closure): callers pass a row of the batch (a task's), within x and a.
                let input = |on_a: bool, r: usize| unsafe { if on_a { Mat::new(a, n_a).at(r, 0) } else { Mat::new(x, n_x).at(r, 0) } };
                run_tasks(
                    n,
                    p.len(),
                    head,
                    c,
                    |sc| sc.fit(&widths, k, width, 0),
                    |sc, r, rows| unsafe {
                        let r_task = r % BACKWARD_ROWS;
                        for ((net, on_a, _, col, hid), &f) in built.iter().zip(&first) {
                            let mut dst: Vec<Dst> = (0..hid.len()).map(|i| sc.dst(f + i, hid[i], r_task)).collect();
                            dst.push(Dst { at: Shared(sc.u.as_mut_ptr().add(r_task * k + col)), ld: k });
                            let xm = input(*on_a, r);
                            net.forward_rows(rows, xm, xm, &dst);
                        }
                    },
                    |dp| unsafe {
                        for (_, _, (_, ob, nb), _, _) in &built {
                            std::ptr::write_bytes(dp.add(*ob), 0, *nb);
                        }
                    },
                    |sc, start, rows, s0, first_sweep, dp| unsafe {
                        for (((net, on_a, (ow, ob, nb), col, hid), &f), wt) in built.iter().zip(&first).zip(&wt) {
                            let acts: Vec<Mat> = (0..hid.len()).map(|i| sc.mat(f + i, hid[i], s0)).collect();
                            let (y, dy) = (Mat::new(&sc.u, k).at(s0, *col), Mat::new(&sc.du, k).at(s0, *col));
                            let xm = input(*on_a, start + s0);
                            let db = std::slice::from_raw_parts_mut(dp.add(*ob), *nb);
                            net.backward_rows(wt, rows, &acts, Some(y), xm, xm, dy, dp.add(*ow), db, first_sweep, (&mut sc.g, &mut sc.below), None, None);
                        }
                    },
                )
            }
            Nets::Parametric { shape, kind, pairs } => {
                let (kind, n_raw, n_obj) = (*kind, kind.n_raw(), kind.n_object());
                let (n_w, n_b) = shape.sizes();
                if p.len() != n_w + n_b + n_obj || pairs.len() != n || k != 3 {
                    candle_core::bail!("{op}: {} parameters, {} direction pairs for {:?} ({kind:?}) on {n} samples", p.len(), pairs.len(), shape.layers)
                }
                let net = Net::new(shape, &p[..n_w], &p[n_w..n_w + n_b], 0, n_x, op)?;
                if net.m() != n_raw {
                    candle_core::bail!("{op}: a network of {} outputs for {kind:?}'s {n_raw} parameters", net.m())
                }
                let object = &p[n_w + n_b..];
                let (wt, width) = (net.transposed(), net.width());
                // The hidden layers' buffers, then the raw parameters' (`[rows, n_raw]`).
                let mut widths = shape.inner_widths();
                let l = widths.len();
                widths.push(n_raw);
                run_tasks(
                    n,
                    p.len(),
                    head,
                    c,
                    |sc| sc.fit(&widths, k, width, n_raw),
                    |sc, r, rows| unsafe {
                        let r_task = r % BACKWARD_ROWS;
                        let dst: Vec<Dst> = (0..=l).map(|i| sc.dst(i, widths[i], r_task)).collect();
                        let xm = Mat::new(x, n_x).at(r, 0);
                        net.forward_rows(rows, xm, xm, &dst);
                        // The core's formula on each sample's raw parameters, as the parametric op.
                        let raw = &sc.acts[l][r_task * n_raw..(r_task + rows) * n_raw];
                        for ((f, raw), &[wi, wo]) in sc.u[r_task * 3..(r_task + rows) * 3].chunks_exact_mut(3).zip(raw.chunks_exact(n_raw)).zip(&pairs[r..r + rows]) {
                            f.copy_from_slice(&Parametric::from_raw(kind, raw, object).eval(wi, wo));
                        }
                    },
                    |dp| unsafe { std::ptr::write_bytes(dp.add(n_w), 0, n_b + n_obj) },
                    |sc, start, rows, s0, first_sweep, dp| unsafe {
                        // The gradient in the raw parameters and the object parameters from the core's
                        // dual-number evaluation, as the parametric op's backward pass; the object
                        // parameters' sums run over the rows in order.
                        let d_object = std::slice::from_raw_parts_mut(dp.add(n_w + n_b), n_obj);
                        for i in 0..rows {
                            let r = s0 + i;
                            let up = [sc.du[3 * r], sc.du[3 * r + 1], sc.du[3 * r + 2]];
                            let raw = &sc.acts[l][r * n_raw..(r + 1) * n_raw];
                            parametric::backward_sample(kind, raw, object, pairs[start + r], up, &mut sc.dt[i * n_raw..(i + 1) * n_raw], d_object);
                        }
                        let acts: Vec<Mat> = (0..l).map(|i| sc.mat(i, widths[i], s0)).collect();
                        let y = sc.mat(l, n_raw, s0);
                        let xm = Mat::new(x, n_x).at(start + s0, 0);
                        let db = std::slice::from_raw_parts_mut(dp.add(n_w), n_b);
                        net.backward_rows(&wt, rows, &acts, Some(y), xm, xm, Mat::new(&sc.dt, n_raw), dp, db, first_sweep, (&mut sc.g, &mut sc.below), None, None);
                    },
                )
            }
            Nets::Trunked(shapes) => {
                let tr = Trunked::new(&shapes.iter().collect::<Vec<_>>(), p, n_x, n_a, op)?;
                if tr.m() != k {
                    candle_core::bail!("{op}: heads of {} outputs for a head of {k}", tr.m())
                }
                let (wt, width, n_t) = (tr.transposed(), tr.width(), tr.trunk.m());
                // Every trunk layer's buffer (the last is `t`), then each head's hidden layers'.
                let no_d = Vec::new();
                let d_inner = if shapes.len() == 3 { shapes[1].inner_widths() } else { no_d };
                let parts = [shapes[0].widths(), d_inner, shapes[shapes.len() - 1].inner_widths()];
                let (lt, ld, widths) = (parts[0].len(), parts[1].len(), parts.concat());
                run_tasks(
                    n,
                    p.len(),
                    head,
                    c,
                    |sc| sc.fit(&widths, k, width, n_t),
                    |sc, r, rows| unsafe {
                        let r_task = r % BACKWARD_ROWS;
                        let dst: Vec<Dst> = (0..widths.len()).map(|i| sc.dst(i, widths[i], r_task)).collect();
                        let out = Dst { at: Shared(sc.u.as_mut_ptr().add(r_task * k)), ld: k };
                        let (xm, am) = (Mat::new(x, n_x).at(r, 0), Mat::new(a, n_a).at(r, 0));
                        tr.forward_rows(rows, xm, am, (&dst[..lt], &dst[lt..lt + ld], &dst[lt + ld..]), out);
                    },
                    |dp| unsafe { tr.zero_biases(dp) },
                    |sc, start, rows, s0, first, dp| unsafe {
                        let acts: Vec<Mat> = (0..widths.len()).map(|i| sc.mat(i, widths[i], s0)).collect();
                        let (acts_t, rest) = acts.split_at(lt);
                        let (acts_d, acts_s) = rest.split_at(ld);
                        let (xm, am) = (Mat::new(x, n_x).at(start + s0, 0), Mat::new(a, n_a).at(start + s0, 0));
                        let dy = Mat::new(&sc.du, k).at(s0, 0);
                        let dt = sc.dt.as_mut_ptr();
                        tr.backward_rows(&wt, rows, (acts_t, acts_d, acts_s), xm, am, dy, dp, first, (&mut sc.g, &mut sc.below), dt);
                    },
                )
            }
        };
        *self.grad.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned gradient")))? = dp;
        Ok((CpuStorage::F32(vec![loss as f32]), Shape::from(())))
    }
}

/// The weights of `nets` as the op takes them: each network's matrices, then its biases, in turn
/// (their `cat` hands each layer's gradient back to its own variables).
fn flat(nets: &[Mlp]) -> Result<Tensor> {
    let mut parts = Vec::with_capacity(4 * nets.len());
    for net in nets {
        let flat = |v: &candle_core::Var| v.as_tensor().flatten_all();
        parts.extend(net.layers.iter().map(|l| flat(&l.weight)).collect::<Result<Vec<_>>>()?);
        parts.extend(net.layers.iter().map(|l| flat(&l.bias)).collect::<Result<Vec<_>>>()?);
    }
    Tensor::cat(&parts, 0)
}

/// The loss of `batch` (Eq. 10, plus the Sec. 4.4 regularisers `reg` for an enhanced model) as one op
/// whose backward pass hands every weight of `model` its gradient.
pub fn batch_loss(model: &Model, batch: &Batch, reg: Regularisers) -> Result<Tensor> {
    let (nets, i) = (&model.nets[..], &batch.inputs);
    let shapes: Vec<NetShape> = nets.iter().map(shape_of).collect();
    let additive = if model.config.has_xi() { Head::Enhanced { lambda_diffuse: reg.lambda_diffuse, lambda_specular: reg.lambda_specular } } else { Head::Additive };
    let mut p = flat(nets)?;
    let (ops, head, x, a) = match (model.config.kind, nets.len()) {
        (Kind::SingleMlp, 1) => (Nets::Parallel(vec![(shapes[0].clone(), false)]), Head::Softplus, &i.joint, &i.joint),
        (Kind::SingleMlp, 2) => (Nets::Trunked(shapes), Head::Softplus, &i.position, &i.angles),
        (Kind::Parametric(kind), 1) => {
            if let Some(o) = &model.object {
                p = Tensor::cat(&[&p, &o.as_tensor().flatten_all()?], 0)?;
            }
            (Nets::Parametric { shape: shapes[0].clone(), kind, pairs: i.pairs.clone() }, Head::Brdf, &i.position, &i.position)
        }
        (Kind::AdditiveSeparate, 2) => (Nets::Parallel(vec![(shapes[0].clone(), false), (shapes[1].clone(), true)]), additive, &i.position, &i.joint),
        (Kind::AdditiveShared, 3) => (Nets::Trunked(shapes), additive, &i.position, &i.angles),
        (kind, n) => candle_core::bail!("fused-step: {n} networks for a {kind:?} model"),
    };
    let op = Step { nets: ops, head, batch: BatchConstants::new(&batch.incident, &batch.target, &i.valid)?, grad: Arc::default() };
    x.contiguous()?.apply_op3(&a.contiguous()?, &p, op)
}
