//! The objective of a training batch as one candle op: the output head of Sec. 4.1 (softplus, or the
//! additive `σ(d)/π + softplus(s)` and its Eq. 8 split), the rendering of Eq. 9, the tone-mapped MSE of
//! Eq. 10 and, for enhanced models, the L1 regularisers of Sec. 4.4, from the networks' raw outputs to
//! the scalar loss, with its own backward pass (issue 8).
//!
//! Why one op: composed from candle ops (`loss.rs`, `Model::forward`) the head and loss are ~20 nodes
//! over `[N, 3]` tensors (sigmoid, softplus, narrow, mul, clamp, maximum, powf, where, sub, sqr, mean,
//! and three γ chains for the enhanced split), each allocating and, in its backward, allocating again;
//! at N = 2^15 they cost 19 ms of an additive model's step and 33 ms of an enhanced one's, more than a
//! 128×128 layer. Fused, they are one pass over the batch that also writes the gradient.
//!
//! The composed functions stay the definition: `Model::forward` (used by evaluation and export) and
//! the functions of [`crate::loss`]; the test below checks that this op gives the same loss and the same
//! gradients for every head.

use std::borrow::Cow;
use std::sync::{Arc, Mutex};

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};
use nbrdf::math::{sigmoid_slice, softplus_slice};
use rayon::prelude::*;

use crate::models::fused::{data, storage_data, ROW_BLOCK};
use crate::models::{network, step, Kind, Model, Raw};
use crate::train::{Batch, TrainOptions};

/// How the packed raw outputs of a sample become its BRDF `f` (`[N, k]` rows, `k` columns).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Head {
    /// `f = u[0..3]`: a parametric model's op already evaluated the BRDF.
    Brdf,
    /// `f = softplus(u[0..3])`: the Single MLP.
    Softplus,
    /// `f = σ(u[0..3])/π + softplus(u[3..6])`: the additive models, `[d, s]` side by side.
    Additive,
    /// `f = (1 - σ(u[6..9])) σ(u[0..3])/π + softplus(u[3..6])` (Eq. 8), plus the Sec. 4.4 regularisers
    /// `λ_d mean|γ(f_d valid L) - γ(L_GT)| + λ_s mean|γ(f_s L)|`.
    Enhanced { lambda_diffuse: f32, lambda_specular: f32 },
}

impl Head {
    /// Columns of the packed input.
    pub fn width(self) -> usize {
        match self {
            Head::Brdf | Head::Softplus => 3,
            Head::Additive => 6,
            Head::Enhanced { .. } => 9,
        }
    }
}

/// Linear segment of the sRGB curve, as in [`crate::loss::gamma_t`].
const SRGB_KNEE: f32 = 0.003_130_8;

/// `γ(x)` of Eq. 10 (sRGB of `x` clamped to [0, 1]) and its derivative, as `loss::gamma_t` and candle's
/// backward define them: 0 outside [0, 1] (the clamp), `12.92` on the linear toe.
#[inline]
fn gamma_and_slope(x: f32) -> (f32, f32) {
    if x < 0.0 {
        (0.0, 0.0)
    } else if x > 1.0 {
        (1.0, 0.0)
    } else if x > SRGB_KNEE {
        let p = x.powf(1.0 / 2.4);
        (1.055 * p - 0.055, 1.055 / 2.4 * p / x)
    } else {
        (12.92 * x, 12.92)
    }
}

/// `d|e|/de` as candle's `abs` backward: +1 at 0.
#[inline]
fn sign(e: f32) -> f32 {
    if e >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// Eq. 10 and the regularisers are means over the `3N` colour values of a batch of `N` samples.
pub(crate) fn scale_of(n: usize) -> f32 {
    1.0 / (3 * n).max(1) as f32
}

/// A batch's constants: `L_i cos θ_l` and `γ(L_GT)` (`[N, 3]`) and the valid-pair mask (`[N]`).
#[derive(Clone, Copy)]
pub(crate) struct Constants<'a> {
    pub incident: &'a [f32],
    pub target: &'a [f32],
    pub valid: &'a [f32],
}

/// The batch's constants as an op holds them, contiguous tensors.
pub(crate) struct BatchConstants {
    incident: Tensor,
    target: Tensor,
    valid: Tensor,
}

impl BatchConstants {
    pub(crate) fn new(incident: &Tensor, target: &Tensor, valid: &Tensor) -> Result<Self> {
        Ok(BatchConstants { incident: incident.contiguous()?, target: target.contiguous()?, valid: valid.contiguous()? })
    }

    /// `f` of the constants' values (CPU tensors only; their lengths are the caller's to check).
    pub(crate) fn with<R>(&self, op: &str, f: impl FnOnce(Constants<'_>) -> Result<R>) -> Result<R> {
        let (si, li) = self.incident.storage_and_layout();
        let (st, lt) = self.target.storage_and_layout();
        let (sv, lv) = self.valid.storage_and_layout();
        f(Constants { incident: storage_data(&si, li, op)?, target: storage_data(&st, lt, op)?, valid: storage_data(&sv, lv, op)? })
    }
}

/// The objective on one block of rows, the batch's rows `r0..` (`u`, `g`: `[rows, k]`, `g` zeroed):
/// adds `d loss / d u` into `g` and returns the block's `(Σ e², Σ |e_d|, Σ |γ_s|)` in f64. Blocks of
/// [`ROW_BLOCK`] rows, their sums added in block order ([`loss_of`]), give the op's loss.
pub(crate) fn rows(head: Head, u: &[f32], g: &mut [f32], c: Constants<'_>, r0: usize, scale: f32) -> [f64; 3] {
    let k = head.width();
    let (inc, tgt, valid) = (c.incident, c.target, c.valid);
    let mut acc = [0.0f64; 3];
    // The block's softplus and sigmoid through the core's slice maps, as the exported model
    // maps its outputs: the loss is taken of what a renderer will evaluate, bit for bit (a
    // per-value `libm` map differs by a few ulp, and is slower). A parametric model's
    // outputs are its BRDF already and are not mapped (nor copied).
    let map = |f: fn(&mut [f32])| -> Cow<'_, [f32]> {
        if head == Head::Brdf {
            return Cow::Borrowed(u);
        }
        let mut v = u.to_vec();
        f(&mut v);
        Cow::Owned(v)
    };
    let (sp, sg) = (map(softplus_slice), map(sigmoid_slice));
    let rows = g.chunks_exact_mut(k).zip(u.chunks_exact(k)).zip(sp.chunks_exact(k).zip(sg.chunks_exact(k)));
    for (j, ((g, u), (softplus, sigmoid))) in rows.enumerate() {
        let r = r0 + j;
        let v = valid[r];
        for c in 0..3 {
            let (li, t) = (inc[3 * r + c], tgt[3 * r + c]);
            // f and its partial derivatives in the packed raw values of channel c.
            let (f, df) = match head {
                Head::Brdf => (u[c], [1.0, 0.0, 0.0]),
                Head::Softplus => (softplus[c], [sigmoid[c], 0.0, 0.0]),
                Head::Additive | Head::Enhanced { .. } => {
                    let sd = sigmoid[c];
                    let fd = sd * core::f32::consts::FRAC_1_PI;
                    let dfd = fd * (1.0 - sd);
                    let fs = softplus[3 + c];
                    let dfs = sigmoid[3 + c];
                    if let Head::Enhanced { lambda_diffuse, lambda_specular } = head {
                        let xi = sigmoid[6 + c];
                        // Sec. 4.4: the diffuse-only rendering against the target, the
                        // specular rendering against 0.
                        let (gd, sd_) = gamma_and_slope(fd * v * li);
                        let ed = gd - t;
                        acc[1] += ed.abs() as f64;
                        let (gs, ss) = gamma_and_slope(fs * li);
                        acc[2] += gs.abs() as f64;
                        g[c] += lambda_diffuse * scale * sign(ed) * sd_ * v * li * dfd;
                        g[3 + c] += lambda_specular * scale * sign(gs) * ss * li * dfs;
                        ((1.0 - xi) * fd + fs, [(1.0 - xi) * dfd, dfs, -fd * xi * (1.0 - xi)])
                    } else {
                        (fd + fs, [dfd, dfs, 0.0])
                    }
                }
            };
            // Eq. 9 (invalid pairs are black) and Eq. 10.
            let (gl, sl) = gamma_and_slope(f * v * li);
            let e = gl - t;
            acc[0] += (e * e) as f64;
            let de = 2.0 * scale * e * sl * v * li;
            for (m, d) in df.iter().enumerate().take(k / 3) {
                g[3 * m + c] += de * d;
            }
        }
    }
    acc
}

/// The loss from the blocks' sums of [`rows`], added in block order.
pub(crate) fn loss_of(head: Head, sums: &[[f64; 3]], scale: f32) -> f64 {
    let mut total = [0.0f64; 3];
    for s in sums {
        for (t, s) in total.iter_mut().zip(s) {
            *t += s;
        }
    }
    match head {
        Head::Enhanced { lambda_diffuse, lambda_specular } => {
            (total[0] + lambda_diffuse as f64 * total[1] + lambda_specular as f64 * total[2]) * scale as f64
        }
        _ => total[0] * scale as f64,
    }
}

/// The op over the packed raw outputs `u [N, k]`; the batch constants ride along.
struct Objective {
    head: Head,
    batch: BatchConstants,
    /// `d loss / d u`, written by the forward pass (the backward scales it by the incoming gradient).
    grad: Arc<Mutex<Vec<f32>>>,
}

impl CustomOp1 for Objective {
    fn name(&self) -> &'static str {
        "objective"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let u = data(s, l, self.name())?;
        let k = self.head.width();
        self.batch.with(self.name(), |c| self.run(u, k, c))
    }

    fn bwd(&self, u: &Tensor, _loss: &Tensor, grad_loss: &Tensor) -> Result<Option<Tensor>> {
        kept_gradient(&self.grad, u, grad_loss, self.name()).map(Some)
    }
}

/// The backward pass of an op whose forward pass computed a scalar loss and kept its gradient in the
/// input `x`: that gradient times the incoming `grad_loss`.
pub(crate) fn kept_gradient(grad: &Mutex<Vec<f32>>, x: &Tensor, grad_loss: &Tensor, op: &str) -> Result<Tensor> {
    let g = grad.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned gradient")))?.clone();
    if g.len() != x.elem_count() {
        candle_core::bail!("{op}: backward without its forward pass")
    }
    Tensor::from_vec(g, x.shape(), x.device())?.broadcast_mul(grad_loss)
}

impl Objective {
    /// The loss of the packed raw outputs `u` (`k` columns) and the batch's constants `c`; keeps the
    /// gradient for the backward pass.
    fn run(&self, u: &[f32], k: usize, c: Constants<'_>) -> Result<(CpuStorage, Shape)> {
        let (inc, tgt, valid) = (c.incident, c.target, c.valid);
        let n = valid.len();
        if u.len() != n * k || inc.len() != 3 * n || tgt.len() != 3 * n {
            candle_core::bail!("objective: {} raw outputs, {} incident, {} targets for {n} samples of {k}", u.len(), inc.len(), tgt.len())
        }
        let scale = scale_of(n);
        let head = self.head;
        let mut grad = vec![0.0f32; n * k];
        // Per block of rows: (Σ e², Σ |e_d|, Σ |γ_s|) in f64, added in block order (deterministic).
        let sums: Vec<[f64; 3]> = grad
            .par_chunks_mut(ROW_BLOCK * k)
            .zip(u.par_chunks(ROW_BLOCK * k))
            .enumerate()
            .map(|(b, (g, u))| rows(head, u, g, c, b * ROW_BLOCK, scale))
            .collect();
        let loss = loss_of(head, &sums, scale);
        *self.grad.lock().map_err(|_| candle_core::Error::Msg("objective: poisoned gradient".into()))? = grad;
        Ok((CpuStorage::F32(vec![loss as f32]), Shape::from(())))
    }
}

/// The loss of a batch from the packed raw outputs `u` (`[N, head.width()]`), the incident light
/// `L_i cos θ_l` and the target `γ(L_GT)` (`[N, 3]`) and the valid-pair mask (`[N, 1]`).
pub fn loss(u: &Tensor, head: Head, incident: &Tensor, target: &Tensor, valid: &Tensor) -> Result<Tensor> {
    let op = Objective { head, batch: BatchConstants::new(incident, target, valid)?, grad: Arc::default() };
    u.contiguous()?.apply_op1(op)
}

/// The objective of one batch: Eq. 10, plus the Sec. 4.4 regularisers for enhanced models. The
/// networks, head and loss run as one fused step ([`step`]) where the networks read an input; else
/// the networks as their ops and everything after them as one [`loss`] op.
pub fn objective(model: &Model, batch: &Batch, opts: &TrainOptions) -> Result<Tensor> {
    // The networks, the head and the loss in one op where the networks feed the head directly (and
    // read an input; a uniform material's position-only trunk is a bias).
    let (nets, x) = (&model.nets[..], &batch.inputs);
    if network::whole_network() && step::fused_step() && nets.first().is_some_and(|n| n.desc.n_in > 0) {
        match (model.config.kind, nets) {
            (Kind::SingleMlp, [net]) => return step::single_mlp_loss(net, &x.joint, &batch.incident, &batch.target, &x.valid),
            (Kind::Parametric(kind), [net]) => {
                let object = model.object.as_ref().map(candle_core::Var::as_tensor);
                return step::parametric_loss(net, kind, object, &x.pairs, &x.position, &batch.incident, &batch.target, &x.valid);
            }
            (Kind::AdditiveSeparate, [d, s]) => {
                let head = additive_head(model, opts);
                return step::additive_separate_loss(d, s, head, &x.position, &x.joint, &batch.incident, &batch.target, &x.valid);
            }
            (Kind::AdditiveShared, [trunk, d, s]) => {
                let head = additive_head(model, opts);
                return step::additive_shared_loss(trunk, d, s, head, &x.position, &x.angles, &batch.incident, &batch.target, &x.valid);
            }
            _ => {}
        }
    }
    let (u, head) = match model.raw(&batch.inputs)? {
        Raw::Brdf(f) => (f, Head::Brdf),
        Raw::Softplus(out) => (out, Head::Softplus),
        Raw::Additive { d, s } => (Tensor::cat(&[&d, &s], 1)?, additive_head(model, opts)),
    };
    loss(&u, head, &batch.incident, &batch.target, &batch.inputs.valid)
}

/// The head of an additive model: Eq. 8 with the Sec. 4.4 regularisers where it is enhanced.
fn additive_head(model: &Model, opts: &TrainOptions) -> Head {
    if model.config.has_xi() {
        Head::Enhanced { lambda_diffuse: opts.lambda_diffuse, lambda_specular: opts.lambda_specular }
    } else {
        Head::Additive
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adam::Adam;
    use crate::models::{arch, Config, Inputs, Kind, ParametricKind, PositionEncoding, RawBatch, Reciprocity};
    use candle_core::Device;

    /// The objective as candle ops, the definition this op must reproduce: `Model::forward`, Eq. 9/10
    /// and the Sec. 4.4 regularisers of `crate::loss`.
    fn composed(model: &Model, batch: &Batch, opts: &TrainOptions) -> Tensor {
        use crate::loss;
        let out = model.forward(&batch.inputs).unwrap();
        let mut total = loss::tone_mapped_mse(&loss::render(&out.f, &batch.incident).unwrap(), &batch.target).unwrap();
        if let (true, Some(d), Some(s)) = (model.config.has_xi(), &out.diffuse, &out.specular) {
            let rd = loss::diffuse_l1(&d.broadcast_mul(&batch.inputs.valid).unwrap(), &batch.incident, &batch.target).unwrap();
            let rs = loss::specular_l1(s, &batch.incident).unwrap();
            total = ((total + (rd * opts.lambda_diffuse as f64).unwrap()).unwrap() + (rs * opts.lambda_specular as f64).unwrap()).unwrap();
        }
        total
    }

    /// For every head, the fused op gives the composed objective's loss and the same gradient in every
    /// weight, on a batch whose rendered values cover the clamp at 0 and 1, the sRGB toe and curve, and
    /// invalid pairs.
    #[test]
    fn fused_objective_matches_the_composed_one() {
        let device = Device::Cpu;
        let position = PositionEncoding::Intrinsic { k: 4 };
        let n = 700;
        let obs = crate::toy::observations(n, position, 11);
        let opts = TrainOptions { lambda_diffuse: 0.3, lambda_specular: 0.2, ..Default::default() };
        // Incident light from 0 to ~40: pixels below the knee, on the curve and clamped at 1.
        let incident: Vec<f32> = (0..n).flat_map(|i| [(i % 13) as f32 * 3.0 * obs.wi[i].z.max(0.0); 3]).collect();
        let target: Vec<f32> = obs.radiance.iter().flatten().map(|&v| crate::loss::gamma(v)).collect();
        let mut configs = arch::study_variants(position, Reciprocity::Exact);
        configs.push(Config::paper(Kind::Parametric(ParametricKind::Lambert), false, Reciprocity::None, position));
        for config in configs {
            let model = Model::init(config, 2, &device).unwrap();
            let inputs = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &device).unwrap();
            let batch = Batch {
                inputs,
                incident: Tensor::from_vec(incident.clone(), (n, 3), &device).unwrap(),
                target: Tensor::from_vec(target.clone(), (n, 3), &device).unwrap(),
            };
            let want = composed(&model, &batch, &opts);
            let got = objective(&model, &batch, &opts).unwrap();
            let (w, g) = (want.to_scalar::<f32>().unwrap(), got.to_scalar::<f32>().unwrap());
            assert!((w - g).abs() <= 1e-5 * w.abs(), "{}: loss {g} vs {w}", config.name());
            let vars = model.vars();
            let gw = Adam::gradients(&vars, &want.backward().unwrap()).unwrap();
            let gg = Adam::gradients(&vars, &got.backward().unwrap()).unwrap();
            for (v, (a, b)) in gw.iter().zip(&gg).enumerate() {
                let scale = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
                for (x, y) in a.iter().zip(b) {
                    assert!((x - y).abs() <= 1e-4 * scale + 1e-9, "{} var {v}: {y} vs {x}", config.name());
                }
            }
        }
    }

    /// The softplus head fits exactly what an exported model evaluates: the raw outputs mapped by the
    /// core's `softplus_slice` and rendered as a BRDF give the same loss, and the gradient in the raw
    /// outputs is the BRDF head's gradient times `sigmoid_slice`, bit for bit. Raw values from -8 to
    /// -5.8 under unit light render in the linear toe of the sRGB curve, where an ulp of `f` reaches
    /// the gradient; the scalar `libm` softplus differs from the slice map in about a third of them.
    #[test]
    fn softplus_head_is_the_exported_output_map() {
        let device = Device::Cpu;
        let n = 1000;
        let raw: Vec<f32> = (0..3 * n).map(|i| ((i * 7919) % 2001) as f32 * 0.0011 - 8.0).collect();
        let (mut f, mut slope) = (raw.clone(), raw.clone());
        softplus_slice(&mut f);
        sigmoid_slice(&mut slope);
        let t = |v: Vec<f32>, k: usize| Tensor::from_vec(v, (n, k), &device).unwrap();
        let target: Vec<f32> = (0..3 * n).map(|i| (i % 11) as f32 * 0.004).collect();
        let (inc, tgt) = (t(vec![1.0; 3 * n], 3), t(target, 3));
        let valid = t((0..n).map(|i| (i % 5 != 0) as u8 as f32).collect(), 1);
        // The loss and its gradient in the head's input.
        let run = |head: Head, values: Vec<f32>| {
            let u = candle_core::Var::from_tensor(&t(values, 3)).unwrap();
            let l = loss(&u, head, &inc, &tgt, &valid).unwrap();
            let g = l.backward().unwrap().get(&u).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
            (l.to_scalar::<f32>().unwrap(), g)
        };
        let (mapped, g_raw) = run(Head::Softplus, raw);
        let (exported, g_f) = run(Head::Brdf, f);
        assert!(mapped > 0.0);
        assert_eq!(mapped.to_bits(), exported.to_bits(), "{mapped} vs {exported}");
        let moved = g_raw.iter().filter(|g| **g != 0.0).count();
        assert!(moved > n, "{moved} non-zero gradients");
        for (i, ((gr, gf), s)) in g_raw.iter().zip(&g_f).zip(&slope).enumerate() {
            assert_eq!(gr.to_bits(), (gf * s).to_bits(), "value {i}: {gr} vs {gf} × {s}");
        }
    }

    /// The loss reads the batch sizes it is given and names a mismatch.
    #[test]
    fn mismatched_batches_are_an_error() {
        let device = Device::Cpu;
        let u = Tensor::zeros((4, 6), candle_core::DType::F32, &device).unwrap();
        let three = Tensor::zeros((4, 3), candle_core::DType::F32, &device).unwrap();
        let valid = Tensor::ones((5, 1), candle_core::DType::F32, &device).unwrap();
        let e = loss(&u, Head::Additive, &three, &three, &valid).unwrap_err().to_string();
        assert!(e.contains("for 5 samples of 6"), "{e}");
    }
}
