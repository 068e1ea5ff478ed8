//! The weights' gradient for a caller's `∂L/∂f`: a renderer that differentiates its loss through the
//! BRDF's values (Mitsuba's path replay, any autodiff framework) hands over `∂L/∂f` at each evaluated
//! `(x, wi, wo)` and gets `∂L/∂w = Σ_n ∂L/∂f_n · ∂f_n/∂w` back — a vector-Jacobian product by the
//! trainer's own backward pass (candle's autograd through [`Model::forward`], the definition the fused
//! step is checked against), so no framework re-implements a model.
//!
//! The values it differentiates are the core's: [`Model::forward`] is the core's `eval` of the same
//! weights without an energy bound (see the tests).

use candle_core::{Device, Tensor};
use nbrdf::Vec3;

use super::adam::Adam;
use crate::models::{Inputs, Model, RawBatch};
use crate::{Error, Result};

/// Rows per forward and backward pass: bounds the activations held for the backward pass (about
/// 8 MB per 128-wide layer) whatever the caller's batch.
const ROWS: usize = 8192;

/// One batch of queries and the caller's `∂L/∂f` at each.
pub struct Cotangents<'a> {
    /// Row-major `[N, model.config.position.input_len()]`: what the core's `prepare` takes per point.
    pub position: &'a [f32],
    pub wi: &'a [Vec3],
    pub wo: &'a [Vec3],
    /// `∂L/∂f` per query and channel.
    pub grad_f: &'a [[f32; 3]],
}

/// `∂L/∂w` in file order (`Model::weights`'s order, `n_weights` values) for `L` whose derivative with
/// respect to `f(x_n, wi_n, wo_n)` is `grad_f[n]`.
pub fn weight_gradient(model: &Model, q: &Cotangents<'_>) -> Result<Vec<f32>> {
    let n = q.wi.len();
    let k = model.config.position.input_len();
    if q.wo.len() != n || q.grad_f.len() != n || q.position.len() != n * k {
        return Err(Error::Invalid(format!(
            "weight_gradient: {n} wi, {} wo, {} ∂L/∂f rows and {} position values ({k} per query expected)",
            q.wo.len(),
            q.grad_f.len(),
            q.position.len()
        )));
    }
    let vars = model.vars();
    let mut total = vec![0.0f32; model.config.n_weights()];
    for start in (0..n).step_by(ROWS) {
        let end = (start + ROWS).min(n);
        let raw = RawBatch { position: &q.position[start * k..end * k], wi: &q.wi[start..end], wo: &q.wo[start..end], swap: None };
        let inputs = Inputs::build(&model.config, &raw, &Device::Cpu)?;
        let g: Vec<f32> = q.grad_f[start..end].iter().flatten().copied().collect();
        let g = Tensor::from_vec(g, (end - start, 3), &Device::Cpu)?;
        // L = Σ g ∘ f: its gradient is the product of the Jacobian's transpose with g.
        let l = (model.forward(&inputs)?.f * g)?.sum_all()?;
        let grads = Adam::gradients(&vars, &l.backward()?)?;
        for (t, v) in total.iter_mut().zip(grads.iter().flatten()) {
            *t += v;
        }
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{Config, Kind, ParametricKind, PositionEncoding, Reciprocity};
    use nbrdf::ModelBuf;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `Σ g ∘ f` by the core's `eval` (the Rust forward pass every renderer uses), in f64.
    fn core_loss(config: &Config, weights: &[f32], position: &[f32], wi: &[Vec3], wo: &[Vec3], g: &[[f32; 3]]) -> f64 {
        let bytes = nbrdf::file::encode(&config.header(), weights, None).unwrap();
        let buf = ModelBuf::from_bytes(&bytes).unwrap();
        let model = buf.model();
        let k = config.position.input_len();
        (0..wi.len())
            .map(|i| {
                let p = model.prepare(&position[i * k..(i + 1) * k]).unwrap();
                let f = model.eval(&p, wi[i], wo[i]);
                (0..3).map(|c| f64::from(f[c]) * f64::from(g[i][c])).sum::<f64>()
            })
            .sum()
    }

    fn direction(rng: &mut ChaCha8Rng) -> Vec3 {
        let z: f32 = rng.random_range(0.05..1.0);
        let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// The gradient agrees with central differences of the core's values, weight by weight, for a
    /// Single MLP, an enhanced Additive Separate and two parametric-by-MLP models (one with a
    /// per-object parameter), at the kernel level this process runs.
    #[test]
    fn weight_gradient_matches_central_differences_of_the_core() {
        let position = PositionEncoding::Extrinsic { frequencies: 2 };
        let configs = [
            Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, position),
            Config::paper(Kind::AdditiveSeparate, true, Reciprocity::None, position),
            Config::paper(Kind::Parametric(ParametricKind::TorranceSparrow), false, Reciprocity::Exact, position),
            Config::paper(Kind::Parametric(ParametricKind::FresnelMicrofacet), false, Reciprocity::Exact, position),
        ];
        for (c, config) in configs.into_iter().enumerate() {
            // Outputs around a mid-grey image rather than the dark start, so every head's derivative counts.
            let start = crate::models::OutputStart::for_median(Some(0.5));
            let model = Model::init_at(config, 7 + c as u64, &Device::Cpu, start).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(c as u64);
            let mut w = model.weights().unwrap();
            let n_weights = w.len();
            let n = 48;
            let pos: Vec<f32> = (0..n * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
            let wi: Vec<Vec3> = (0..n).map(|_| direction(&mut rng)).collect();
            let wo: Vec<Vec3> = (0..n).map(|_| direction(&mut rng)).collect();
            let g: Vec<[f32; 3]> = (0..n).map(|_| [0; 3].map(|_| rng.random_range(-1.0..1.0))).collect();
            let q = Cotangents { position: &pos, wi: &wi, wo: &wo, grad_f: &g };
            let grad = weight_gradient(&model, &q).unwrap();
            assert_eq!(grad.len(), n_weights);
            let largest = grad.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            assert!(largest > 0.0, "{}: an all-zero gradient", config.name());
            // Per network layer and the object parameters: the weight with the largest gradient and a
            // random one, so first, skip and last layers and both heads are all checked.
            let mut picks = Vec::new();
            let mut at = 0;
            let mut spans: Vec<usize> = config.nets().iter().flat_map(crate::models::arch::layers).map(|(i, o)| (i + 1) * o).collect();
            spans.push(config.n_object());
            for len in spans.into_iter().filter(|&l| l > 0) {
                let span = at..at + len;
                let top = span.clone().max_by(|&a, &b| grad[a].abs().total_cmp(&grad[b].abs())).unwrap();
                picks.extend([top, rng.random_range(span)]);
                at += len;
            }
            assert_eq!(at, n_weights);
            for i in picks {
                let h = 2e-3f32;
                let w0 = w[i];
                w[i] = w0 + h;
                let up = core_loss(&config, &w, &pos, &wi, &wo, &g);
                w[i] = w0 - h;
                let down = core_loss(&config, &w, &pos, &wi, &wo, &g);
                w[i] = w0;
                let fd = (up - down) / (2.0 * f64::from(h));
                let an = f64::from(grad[i]);
                assert!(
                    (fd - an).abs() <= 0.03 * an.abs() + 2e-3 * f64::from(largest),
                    "{} weight {i}: backward {an:.6e}, central difference {fd:.6e} (largest {largest:.3e})",
                    config.name()
                );
            }
        }
    }

    #[test]
    fn weight_gradient_names_mismatched_lengths() {
        let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform);
        let model = Model::init(config, 1, &Device::Cpu).unwrap();
        let q = Cotangents { position: &[], wi: &[Vec3::Z; 2], wo: &[Vec3::Z; 2], grad_f: &[[1.0; 3]] };
        let e = weight_gradient(&model, &q).unwrap_err().to_string();
        assert!(e.contains("2 wi") && e.contains("1 ∂L/∂f rows"), "{e}");
    }

    #[test]
    fn of_header_gives_back_every_variant_the_trainer_writes() {
        let position = PositionEncoding::Intrinsic { k: 5 };
        let mut variants = crate::models::arch::study_variants(position, Reciprocity::Exact);
        let first = variants[0];
        variants.extend((1..=5).map(|d| Config { direction_layers: Some(d), ..first }));
        for config in variants {
            let back = Config::of_header(&config.header()).unwrap();
            assert_eq!(back.header(), config.header(), "{}", config.name());
        }
        let narrow = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, position).header().with_width(32);
        assert!(Config::of_header(&narrow).is_none(), "a width the trainer does not build");
    }
}
