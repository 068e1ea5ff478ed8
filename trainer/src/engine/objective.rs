//! The objective of a training batch on one block of rows: the output head of Sec. 4.1 (softplus, or
//! the additive `σ(d)/π + softplus(s)` and its Eq. 8 split), the rendering of Eq. 9, the tone-mapped
//! MSE of Eq. 10 and, for enhanced models, the L1 regularisers of Sec. 4.4, from the networks' raw
//! outputs to the block's sums and their gradient in the raw outputs, in one pass ([`rows`]).
//!
//! Why by hand: composed from candle ops (`super::loss`, `Model::forward`) the head and loss are ~20
//! nodes over `[N, 3]` tensors, each allocating and, in its backward, allocating again; here they are
//! one pass over a block that the fused step ([`super::step`]) runs while the block is in cache. The
//! composed functions stay the definition, and trainer/tests/engine.rs checks the step against them.

use std::borrow::Cow;
use std::sync::Mutex;

use candle_core::{Result, Tensor};
use nbrdf::math::{sigmoid_slice, softplus_slice};

use super::op::storage_data;

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

/// Linear segment of the sRGB curve, as in [`super::loss::gamma_t`].
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
/// [`super::op::ROW_BLOCK`] rows, their sums added in block order ([`loss_of`]), give the batch's loss.
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

/// The backward pass of an op whose forward pass computed a scalar loss and kept its gradient in the
/// input `x`: that gradient times the incoming `grad_loss`.
pub(crate) fn kept_gradient(grad: &Mutex<Vec<f32>>, x: &Tensor, grad_loss: &Tensor, op: &str) -> Result<Tensor> {
    let g = grad.lock().map_err(|_| candle_core::Error::Msg(format!("{op}: poisoned gradient")))?.clone();
    if g.len() != x.elem_count() {
        candle_core::bail!("{op}: backward without its forward pass")
    }
    Tensor::from_vec(g, x.shape(), x.device())?.broadcast_mul(grad_loss)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The softplus head fits exactly what an exported model evaluates: the raw outputs mapped by the
    /// core's `softplus_slice` and rendered as a BRDF give the same loss, and the gradient in the raw
    /// outputs is the BRDF head's gradient times `sigmoid_slice`, bit for bit. Raw values from -8 to
    /// -5.8 under unit light render in the linear toe of the sRGB curve, where an ulp of `f` reaches
    /// the gradient; the scalar `libm` softplus differs from the slice map in about a third of them.
    #[test]
    fn softplus_head_is_the_exported_output_map() {
        let n = 1000;
        let raw: Vec<f32> = (0..3 * n).map(|i| ((i * 7919) % 2001) as f32 * 0.0011 - 8.0).collect();
        let (mut f, mut slope) = (raw.clone(), raw.clone());
        softplus_slice(&mut f);
        sigmoid_slice(&mut slope);
        let target: Vec<f32> = (0..3 * n).map(|i| (i % 11) as f32 * 0.004).collect();
        let incident = vec![1.0; 3 * n];
        let valid: Vec<f32> = (0..n).map(|i| (i % 5 != 0) as u8 as f32).collect();
        let c = Constants { incident: &incident, target: &target, valid: &valid };
        // The loss and its gradient in the head's input.
        let run = |head: Head, u: &[f32]| {
            let mut g = vec![0.0f32; u.len()];
            let sums = rows(head, u, &mut g, c, 0, scale_of(n));
            (loss_of(head, &[sums], scale_of(n)) as f32, g)
        };
        let (mapped, g_raw) = run(Head::Softplus, &raw);
        let (exported, g_f) = run(Head::Brdf, &f);
        assert!(mapped > 0.0);
        assert_eq!(mapped.to_bits(), exported.to_bits(), "{mapped} vs {exported}");
        let moved = g_raw.iter().filter(|g| **g != 0.0).count();
        assert!(moved > n, "{moved} non-zero gradients");
        for (i, ((gr, gf), s)) in g_raw.iter().zip(&g_f).zip(&slope).enumerate() {
            assert_eq!(gr.to_bits(), (gf * s).to_bits(), "value {i}: {gr} vs {gf} × {s}");
        }
    }
}
