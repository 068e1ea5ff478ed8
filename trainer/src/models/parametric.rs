//! Candle twins of the parametric models of Sec. 4.1.1 (RP, Torrance-Sparrow, FMBRDF, Disney, and the
//! Lambertian reference).
//!
//! The forward pass *is* the core's code: a custom op evaluates `Parametric::from_raw(kind, raw,
//! object).eval(wi, wo)` per sample, so the activations table (sigmoid/softplus ranges, roughness
//! pre-activation ×0.5) and the formula agree with an exported model bit for bit by construction, not by
//! a second transcription of Disney & co. that could drift.
//!
//! The backward pass differentiates that same scalar function by central differences in each raw input
//! (step `4e-3 · max(1, |x|)`, the f32 optimum `∛ε` scale): about 1e-4 relative accuracy, ample for Adam,
//! at `2 (n_raw + n_object)` extra evaluations per sample (parallel over samples). The networks that
//! predict the raw values keep candle's exact gradients. An analytic backward is a speed, not an
//! accuracy, improvement (issue 8).

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

/// Central difference step for raw value `x`.
fn step(x: f32) -> f32 {
    4e-3 * x.abs().max(1.0)
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

    fn bwd(&self, raw: &Tensor, object: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let n_raw = self.kind.n_raw();
        let n_obj = self.kind.n_object();
        let raw_v = raw.flatten_all()?.to_vec1::<f32>()?;
        let obj_v = object.flatten_all()?.to_vec1::<f32>()?;
        let g = grad.flatten_all()?.to_vec1::<f32>()?;
        let dot = |s: usize, hi: [f32; 3], lo: [f32; 3], h: f32| -> f32 {
            (0..3).map(|c| g[3 * s + c] * (hi[c] - lo[c])).sum::<f32>() / h
        };
        let per_sample: Vec<(Vec<f32>, Vec<f32>)> = (0..self.pairs.len())
            .into_par_iter()
            .map(|s| {
                let mut r = raw_v[s * n_raw..(s + 1) * n_raw].to_vec();
                let mut o = obj_v.clone();
                let mut gr = vec![0.0f32; n_raw];
                for j in 0..n_raw {
                    let x = r[j];
                    let h = step(x);
                    r[j] = x + h;
                    let hi = self.f(s, &r, &o);
                    let xp = r[j];
                    r[j] = x - h;
                    let lo = self.f(s, &r, &o);
                    let xm = r[j];
                    r[j] = x;
                    gr[j] = dot(s, hi, lo, xp - xm);
                }
                let mut go = vec![0.0f32; n_obj];
                for k in 0..n_obj {
                    let x = o[k];
                    let h = step(x);
                    o[k] = x + h;
                    let hi = self.f(s, &r, &o);
                    let xp = o[k];
                    o[k] = x - h;
                    let lo = self.f(s, &r, &o);
                    let xm = o[k];
                    o[k] = x;
                    go[k] = dot(s, hi, lo, xp - xm);
                }
                (gr, go)
            })
            .collect();
        let mut g_raw = Vec::with_capacity(raw_v.len());
        let mut g_obj = vec![0.0f32; obj_v.len()];
        for (gr, go) in per_sample {
            g_raw.extend(gr);
            for (a, b) in g_obj.iter_mut().zip(go) {
                *a += b;
            }
        }
        let g_raw = Tensor::from_vec(g_raw, raw.shape(), raw.device())?;
        let g_obj = Tensor::from_vec(g_obj, object.shape(), object.device())?;
        Ok((Some(g_raw), Some(g_obj)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{PositionEncoding, RawBatch, Reciprocity};
    use candle_core::{Device, Var};

    /// The difference-quotient gradient of every model agrees with a loose f64 check of the loss.
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
        }
    }
}
