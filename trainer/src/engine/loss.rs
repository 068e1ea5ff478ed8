//! The rendering of a training pixel (Eq. 9) and the tone-mapped MSE (Eq. 10), with the L1 regularisers
//! of the enhanced additive split (Sec. 4.4).

use candle_core::{Result, Tensor};

/// Linear segment of the sRGB curve: below it `γ(x) = 12.92 x`.
const SRGB_KNEE: f64 = 0.003_130_8;

/// The gamma curve `γ: [0, 1] → [0, 1]` of Eq. 10: the sRGB transfer function (IEC 61966-2-1) of the
/// input clamped to [0, 1], `12.92 x` below 0.0031308 and `1.055 x^(1/2.4) - 0.055` above.
///
/// sRGB rather than a pure power `x^(1/2.2)`: both compress HDR highlights the way Mildenhall et al.
/// (2022) motivate, but the power's slope is infinite at 0, so a dark pixel would give an unbounded
/// gradient; sRGB's linear toe keeps the slope at most 12.92. Evaluation converts to sRGB the
/// same way.
pub fn gamma(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0) as f64;
    (if x <= SRGB_KNEE { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }) as f32
}

/// [`gamma`] on a tensor, differentiable (the power's base is kept above the knee so that its
/// gradient stays finite on the branch that `where_cond` discards).
pub fn gamma_t(x: &Tensor) -> Result<Tensor> {
    let c = x.clamp(0.0f32, 1.0f32)?;
    let linear = (&c * 12.92)?;
    let curve = c.maximum(SRGB_KNEE as f32)?.powf(1.0 / 2.4)?.affine(1.055, -0.055)?;
    c.gt(SRGB_KNEE as f32)?.where_cond(&curve, &linear)
}

/// Rendered radiance of Eq. 9, `L_o = f · L_i · cos θ_l` per channel, with `incident = L_i cos θ_l`
/// (`[N, 3]`). The shadow indicator is 1: shadowed pixels are not training samples.
pub fn render(f: &Tensor, incident: &Tensor) -> Result<Tensor> {
    f.mul(incident)
}

/// Tone-mapped MSE of Eq. 10, `1/N Σ (γ(L_o) - γ(L_GT))²` over the `3N` colour values, with
/// `target = γ(L_GT)` precomputed.
pub fn tone_mapped_mse(radiance: &Tensor, target: &Tensor) -> Result<Tensor> {
    (gamma_t(radiance)? - target)?.sqr()?.mean_all()
}

/// Sec. 4.4, first regulariser: L1 between the diffuse-only rendering and the reference image in the
/// tone-mapped domain of Eq. 10, `mean |γ(f_d L_i cos θ_l) - γ(L_GT)|`; it pulls as much as possible into
/// the view-independent diffuse part. (The weighting domain is our choice; the appendix is not in the
/// text we have.)
pub fn diffuse_l1(diffuse: &Tensor, incident: &Tensor, target: &Tensor) -> Result<Tensor> {
    (gamma_t(&render(diffuse, incident)?)? - target)?.abs()?.mean_all()
}

/// Sec. 4.4, second regulariser: sparsity of the specular part, `mean |γ(f_s L_i cos θ_l)|`.
pub fn specular_l1(specular: &Tensor, incident: &Tensor) -> Result<Tensor> {
    gamma_t(&render(specular, incident)?)?.abs()?.mean_all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    /// γ maps [0, 1] onto [0, 1], is continuous at the knee and clamps HDR values.
    #[test]
    fn gamma_is_srgb() {
        assert_eq!(gamma(0.0), 0.0);
        assert!((gamma(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(gamma(50.0), gamma(1.0));
        let k = SRGB_KNEE as f32;
        assert!((gamma(k * 0.999_99) - gamma(k * 1.000_01)).abs() < 1e-5);
        assert!((gamma(0.18) - 0.461).abs() < 1e-3, "middle grey");
    }

    /// The tensor version agrees with the scalar one and has finite gradients at 0 and beyond 1.
    #[test]
    fn gamma_tensor_matches_and_has_finite_gradient() {
        let xs = [0.0f32, 1e-6, 0.002, 0.01, 0.5, 1.0, 3.0, -1.0];
        let x = Var::from_slice(&xs, xs.len(), &Device::Cpu).unwrap();
        let y = gamma_t(x.as_tensor()).unwrap();
        for (a, b) in y.to_vec1::<f32>().unwrap().iter().zip(xs) {
            assert!((a - gamma(b)).abs() < 1e-6);
        }
        let g = y.sum_all().unwrap().backward().unwrap();
        let g = g.get(x.as_tensor()).unwrap().to_vec1::<f32>().unwrap();
        assert!(g.iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!((g[1] - 12.92).abs() < 1e-3, "linear toe");
        assert_eq!(g[6], 0.0, "clamped highlight");
    }
}
