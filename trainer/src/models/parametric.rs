//! Candle twins of the parametric models of Sec. 4.1.1 (RP, Torrance-Sparrow, FMBRDF, Disney, and the
//! Lambertian reference).
//!
//! The forward pass *is* the core's code: a custom op evaluates `Parametric::from_raw(kind, raw,
//! object).eval(wi, wo)` per sample, so the activations table (sigmoid/softplus ranges, roughness
//! pre-activation ×0.5) and the formula agree with an exported model bit for bit by construction, not by
//! a second transcription of Disney & co. that could drift.
//!
//! The backward pass is exact too, and again the core's code: [`Parametric::eval_grad`] evaluates that
//! same generic formula at dual numbers (forward-mode automatic differentiation), one evaluation per
//! sample for all `n_raw + n_object` derivatives, in parallel over blocks of samples. (It replaced central
//! differences, which cost `2 (n_raw + n_object)` evaluations per sample and 1e-4 relative accuracy.)

use std::sync::Arc;

use candle_core::{CpuStorage, CustomOp2, Layout, Result, Shape, Tensor};
use nbrdf::parametric::{Parametric, ParametricKind};
use nbrdf::Vec3;
use rayon::prelude::*;

use super::arch::{Config, Kind};
use super::features::Inputs;

/// Initial per-object parameters: FMBRDF's log NDF normalisation exact for the parameters the network
/// predicts at raw 0 (α = σ(0) = 0.5, β = 0.5 + 3.5 σ(0) = 2.25).
pub fn initial_object(config: &Config) -> Vec<f32> {
    match config.kind {
        Kind::Parametric(ParametricKind::FresnelMicrofacet) => {
            vec![nbrdf::parametric::fresnel_microfacet::log_norm_raw(0.5, 2.25)]
        }
        _ => vec![0.0; config.n_object()],
    }
}

/// The BRDF `[N, 3]` of the raw network outputs `raw` `[N, n_raw]` and the object parameters.
pub fn eval(kind: ParametricKind, raw: &Tensor, object: Option<&Tensor>, x: &Inputs) -> Result<Tensor> {
    let n_obj = kind.n_object();
    // Models without object parameters get a 1-element placeholder the op ignores.
    let object = match object {
        Some(o) => o.reshape((1, n_obj))?,
        None => Tensor::zeros((1, 1), candle_core::DType::F32, raw.device())?,
    };
    raw.contiguous()?.apply_op2(&object.contiguous()?, ParametricOp { kind, pairs: x.pairs.clone() })
}

struct ParametricOp {
    kind: ParametricKind,
    pairs: Arc<Vec<[Vec3; 2]>>,
}

impl ParametricOp {
    fn f(&self, s: usize, raw: &[f32], object: &[f32]) -> [f32; 3] {
        let [wi, wo] = self.pairs[s];
        Parametric::from_raw(self.kind, raw, &object[..self.kind.n_object()]).eval(wi, wo)
    }
}

fn contiguous<'a>(s: &'a CpuStorage, l: &Layout, what: &str) -> Result<&'a [f32]> {
    let CpuStorage::F32(d) = s else { candle_core::bail!("parametric BRDF: {what} must be f32") };
    let Some((a, b)) = l.contiguous_offsets() else { candle_core::bail!("parametric BRDF: {what} must be contiguous") };
    Ok(&d[a..b])
}

impl CustomOp2 for ParametricOp {
    fn name(&self) -> &'static str {
        "parametric-brdf"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let raw = contiguous(s1, l1, "raw outputs")?;
        let object = contiguous(s2, l2, "object parameters")?;
        let n_raw = self.kind.n_raw();
        let n = self.pairs.len();
        if raw.len() != n * n_raw {
            candle_core::bail!("parametric BRDF: {} raw values for {n} samples of {n_raw}", raw.len());
        }
        let out: Vec<f32> =
            raw.par_chunks(n_raw).enumerate().flat_map_iter(|(s, r)| self.f(s, r, object)).collect();
        Ok((CpuStorage::F32(out), Shape::from((n, 3))))
    }

    /// The exact gradient from the core's [`Parametric::eval_grad`]: the same generic formula as the
    /// forward pass, instantiated at dual numbers (forward-mode AD, one evaluation per sample).
    fn bwd(&self, raw: &Tensor, object: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let (kind, n_raw, n_obj) = (self.kind, self.kind.n_raw(), self.kind.n_object());
        let raw_v = raw.flatten_all()?.to_vec1::<f32>()?;
        let obj_v = object.flatten_all()?.to_vec1::<f32>()?;
        let g = grad.flatten_all()?.to_vec1::<f32>()?;
        let n = self.pairs.len();
        if raw_v.len() != n * n_raw || g.len() != 3 * n {
            candle_core::bail!("parametric BRDF backward: {} raw values and {} gradients for {n} samples", raw_v.len(), g.len());
        }
        let obj = &obj_v[..n_obj];
        let mut g_raw = vec![0.0f32; raw_v.len()];
        // Blocks of samples, each returning its share of the object parameters' gradient.
        const BLOCK: usize = 256;
        let g_obj = g_raw
            .par_chunks_mut(BLOCK * n_raw)
            .enumerate()
            .map(|(b, out)| {
                let mut go = [0.0f32; nbrdf::parametric::MAX_OBJECT];
                for (i, out) in out.chunks_mut(n_raw).enumerate() {
                    let s = b * BLOCK + i;
                    let up = [g[3 * s], g[3 * s + 1], g[3 * s + 2]];
                    backward_sample(kind, &raw_v[s * n_raw..(s + 1) * n_raw], obj, self.pairs[s], up, out, &mut go[..n_obj]);
                }
                go
            })
            .reduce(|| [0.0; nbrdf::parametric::MAX_OBJECT], |a, b| core::array::from_fn(|k| a[k] + b[k]));
        let mut g_obj_v = vec![0.0f32; obj_v.len()];
        g_obj_v[..n_obj].copy_from_slice(&g_obj[..n_obj]);
        let g_raw = Tensor::from_vec(g_raw, raw.shape(), raw.device())?;
        let g_obj = Tensor::from_vec(g_obj_v, object.shape(), object.device())?;
        Ok((Some(g_raw), Some(g_obj)))
    }
}

/// One sample's backward pass through the formula: `d_raw ← upᵀ ∂f/∂raw` and `d_object += upᵀ ∂f/∂object`
/// for the gradient `up` of its BRDF value, from the core's dual-number evaluation at (`wi`, `wo`).
pub(crate) fn backward_sample(kind: ParametricKind, raw: &[f32], object: &[f32], [wi, wo]: [Vec3; 2], up: [f32; 3], d_raw: &mut [f32], d_object: &mut [f32]) {
    let d = Parametric::eval_grad(kind, raw, object, wi, wo);
    let dot = |v: [f32; 3]| up[0] * v[0] + up[1] * v[1] + up[2] * v[2];
    for (o, dj) in d_raw.iter_mut().zip(&d.d_raw) {
        *o = dot(*dj);
    }
    for (o, dk) in d_object.iter_mut().zip(&d.d_object) {
        *o += dot(*dk);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{PositionEncoding, RawBatch, Reciprocity};
    use candle_core::{Device, Var};

    /// The backward pass of every model agrees with a central difference of the summed core function.
    #[test]
    fn gradients_match_the_core_function() {
        let device = Device::Cpu;
        for kind in ParametricKind::ALL {
            let config = Config::paper(Kind::Parametric(kind), false, Reciprocity::None, PositionEncoding::Uniform);
            let (wi, wo) = crate::toy::direction_pairs(8, 3);
            let x = Inputs::build(&config, &RawBatch { position: &[], wi: &wi, wo: &wo, swap: None }, &device).unwrap();
            let vals: Vec<f32> = (0..8 * kind.n_raw()).map(|i| ((i * 37 % 11) as f32 - 5.0) * 0.3).collect();
            let raw = Var::from_vec(vals.clone(), (8, kind.n_raw()), &device).unwrap();
            let obj = Var::from_vec(initial_object(&config).into_iter().chain([0.0]).take(kind.n_object().max(1)).collect::<Vec<_>>(), kind.n_object().max(1), &device).unwrap();
            let object = (kind.n_object() > 0).then(|| obj.as_tensor().clone());
            let f = eval(kind, raw.as_tensor(), object.as_ref(), &x).unwrap();
            let grads = f.sum_all().unwrap().backward().unwrap();
            let g = grads.get(raw.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
            // Check one raw input per sample against a wider central difference of the sum.
            for s in 0..8 {
                let j = s % kind.n_raw();
                let total = |d: f32| -> f64 {
                    let mut v = vals.clone();
                    v[s * kind.n_raw() + j] += d;
                    let o: Vec<f32> = initial_object(&config);
                    let [a, b] = x.pairs[s];
                    Parametric::from_raw(kind, &v[s * kind.n_raw()..(s + 1) * kind.n_raw()], &o)
                        .eval(a, b)
                        .iter()
                        .map(|&c| c as f64)
                        .sum()
                };
                let fd = (total(2e-2) - total(-2e-2)) / 4e-2;
                let ours = g[s * kind.n_raw() + j] as f64;
                assert!((ours - fd).abs() <= 2e-2 * fd.abs().max(1e-2), "{kind:?} s{s} raw{j}: {ours} vs {fd}");
            }
            // The object parameter (FMBRDF's log normalisation) collects its gradient over all samples.
            if kind.n_object() > 0 {
                let g_obj = grads.get(obj.as_tensor()).unwrap().to_vec1::<f32>().unwrap()[0] as f64;
                let total = |d: f32| -> f64 {
                    let o: Vec<f32> = initial_object(&config).iter().map(|v| v + d).collect();
                    (0..8)
                        .map(|s| {
                            let [a, b] = x.pairs[s];
                            let r = &vals[s * kind.n_raw()..(s + 1) * kind.n_raw()];
                            Parametric::from_raw(kind, r, &o).eval(a, b).iter().map(|&c| c as f64).sum::<f64>()
                        })
                        .sum()
                };
                let fd = (total(2e-2) - total(-2e-2)) / 4e-2;
                assert!((g_obj - fd).abs() <= 2e-2 * fd.abs().max(1e-2), "{kind:?} object: {g_obj} vs {fd}");
            }
        }
    }
}
