//! Fresnel Microfacet BRDF, "FMBRDF" (Ichikawa, Fukao, Nobuhara & Nishino 2023, "Fresnel Microfacet BRDF:
//! Unification of Polarimetric Surface-Body Reflection"), in its unpolarised intensity form:
//!
//! `f(wi, wo) = ks D(h) G(wi, wo) F_R(cos θd; η) / (4 cos θi cos θo)
//!            + ρ / π · (1 - F_R(cos θi; η)) (1 - F_R(cos θo; η))`
//!
//! - surface (specular) term: microfacet mirror reflection with the exact unpolarised dielectric Fresnel
//!   reflectance `F_R` of index η ([`microfacet::fresnel_dielectric`]) at the microfacet, `cos θd = wi·h`;
//!   a **scalar** weight `ks` (the paper's Sec. 6.1 traces the FMBRDF's "glow" to this scalar term);
//! - body (diffuse) term: light refracted into the surface (Fresnel transmission `1 - F_R` in), scattered
//!   diffusely with albedo `ρ`, refracted out (transmission out);
//! - `D(h) = N · exp(-(θh / α)^β)`: a generalised Gaussian in the half-vector angle, `β = 2` the Gaussian
//!   of the original, `N` the normalisation `∫ D cos θh dω = 1` computed numerically
//!   ([`ndf_normalization`]); `G`: the V-cavity term ([`microfacet::v_cavity_g_over_4cos`]) since the
//!   generalised Gaussian has no closed-form Smith masking.
//!
//! **Dropped from the polarimetric original:** the Mueller-matrix (Stokes) formulation — separate s/p
//! Fresnel coefficients, the rotation into and out of each microfacet's plane of incidence and the
//! resulting degree and angle of polarisation — is averaged into the scalar unpolarised `F_R`; the body
//! term's transmission is taken through the macro surface (cos θi, cos θo) instead of being integrated over
//! the microfacets that the light enters and leaves by; and no inter-reflection between facets. What
//! remains is exactly what an intensity-only renderer (Eq. 9) can observe.
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `rho` (R, G, B body albedo) | [0, 1] | `sigmoid(raw)` |
//! | 3 | `ks` (scalar surface weight) | [0, 1] | `sigmoid(raw[3])` |
//! | 4 | `alpha` (NDF width, radians) | [1e-3, 1] | `max(sigmoid(0.5 · raw[4]), 1e-3)` |
//! | 5 | `beta` (NDF shape) | [0.5, 4] | `0.5 + 3.5 · sigmoid(raw[5])` |
//! | 6 | `eta` (refractive index) | [1, 3] | `1 + 2 · sigmoid(raw[6])` |
//! | object 0 | `norm` (NDF normalisation `N`) | (0, ∞) | `exp(clamp(object_raw[0], -80, 80))` |
//!
//! The normalisation is a per-object parameter (one per model, not per point: `n_object = 1`), learned
//! in log space because it spans 1/π (α = 1, β = 2) to ~3e5 (α = 1e-3). It is exact for a uniform material
//! when set from [`ndf_normalization`] ([`FresnelMicrofacet::new`], [`log_norm_raw`]).
//!
//! Sampling (`sample` / `pdf` below): a mixture of the cosine lobe and Beckmann half vectors of slope α,
//! Torrance-Sparrow's proposal. The generalised Gaussian has no closed-form inverse CDF; the Beckmann
//! proposal matches it exactly for β = 2 in the small-angle limit and stays a valid (unbiased,
//! higher-variance) proposal otherwise, because the pdf reported is always the proposal's own.

use super::raw_at;
use super::torrance_sparrow::{pdf_cosine_beckmann, sample_cosine_beckmann};
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{logit, INV_PI};
use crate::microfacet::{self, clamp_alpha, clamp_alpha_generic, HalfGeometry};
use crate::real::Real;
use crate::sampling::{finish, lum, normalise, valid_wo};
use crate::{Rgb, Vec3};

/// Smallest and largest shape exponent β.
pub const BETA_RANGE: (f32, f32) = (0.5, 4.0);
/// Smallest and largest refractive index η reachable from raw outputs.
pub const ETA_RANGE: (f32, f32) = (1.0, 3.0);

/// Unpolarised Fresnel Microfacet BRDF.
///
/// ```
/// use nbrdf::{parametric::FresnelMicrofacet, Vec3};
/// let m = FresnelMicrofacet::new([0.6, 0.3, 0.2], 0.8, 0.2, 2.0, 1.5);
/// let f = m.eval(Vec3::new(0.4, 0.0, 0.9), Vec3::new(-0.4, 0.0, 0.9));
/// assert!(f.iter().all(|v| v.is_finite() && *v > 0.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FresnelMicrofacet {
    /// Body (subsurface) albedo per channel.
    pub rho: Rgb,
    /// Scalar weight of the surface (specular) term.
    pub ks: f32,
    /// Width α of the generalised Gaussian NDF (radians of θh), clamped to [1e-3, 1] when evaluated.
    pub alpha: f32,
    /// Shape exponent β of the NDF (2: Gaussian; smaller: longer tails).
    pub beta: f32,
    /// Relative refractive index η of the surface.
    pub eta: f32,
    /// NDF normalisation `N` of `D = N exp(-(θh/α)^β)`.
    pub norm: f32,
}

/// `N(α, β) = 1 / ∫_H exp(-(θh/α)^β) cos θh dω_h`, so that `D = N exp(-(θh/α)^β)` projects to unit area
/// (the normalisation every microfacet NDF needs; Walter et al. 2007, Eq. 4).
///
/// Computed in `f64` by composite Simpson quadrature of `2π ∫ exp(-(θ/α)^β) cos θ sin θ dθ` over
/// `θ ∈ [0, θmax]`, `θmax = min(π/2, α · 60^(1/β))` (beyond it the integrand is below e^-60), with the
/// substitution `θ = θmax u²`, which keeps the integrand smooth at θ = 0 for every β ≥ 0.5. Relative error
/// below 1e-6 over α ∈ [1e-3, 1], β ∈ [0.5, 4].
///
/// ```
/// use nbrdf::parametric::fresnel_microfacet::ndf_normalization;
/// // Narrow Gaussian: ∫ ≈ π α² (small-angle limit), so N ≈ 1/(π α²).
/// let n = ndf_normalization(1e-3, 2.0);
/// assert!((n * core::f32::consts::PI * 1e-6 - 1.0).abs() < 1e-3);
/// ```
pub fn ndf_normalization(alpha: f32, beta: f32) -> f32 {
    let alpha = clamp_alpha(alpha) as f64;
    let beta = if beta.is_finite() { beta.clamp(BETA_RANGE.0, BETA_RANGE.1) as f64 } else { 2.0 };
    let theta_max = (alpha * libm::pow(60.0, 1.0 / beta)).min(core::f64::consts::FRAC_PI_2);
    // θ = θmax u², dθ = 2 θmax u du.
    let g = |u: f64| {
        let th = theta_max * u * u;
        libm::exp(-libm::pow(th / alpha, beta)) * libm::cos(th) * libm::sin(th) * 2.0 * theta_max * u
    };
    const N: usize = 2048; // even
    let h = 1.0 / N as f64;
    let mut sum = g(0.0) + g(1.0);
    for j in 1..N {
        sum += g(j as f64 * h) * if j % 2 == 1 { 4.0 } else { 2.0 };
    }
    let integral = 2.0 * core::f64::consts::PI * sum * h / 3.0;
    (1.0 / integral) as f32
}

/// The raw object parameter that makes [`FresnelMicrofacet::from_raw`] reproduce
/// `ndf_normalization(alpha, beta)`: `ln N` (the inverse of its activation).
pub fn log_norm_raw(alpha: f32, beta: f32) -> f32 {
    libm::logf(ndf_normalization(alpha, beta))
}

impl FresnelMicrofacet {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 7;
    /// Per-object raw parameters: the NDF normalisation.
    pub const N_OBJECT: usize = 1;

    /// A uniform material, its NDF normalised exactly by [`ndf_normalization`].
    pub fn new(rho: Rgb, ks: f32, alpha: f32, beta: f32, eta: f32) -> Self {
        Self { rho, ks, alpha, beta, eta, norm: ndf_normalization(alpha, beta) }
    }

    /// Parameters from raw network outputs and the per-object raw normalisation (table at the top of the
    /// file); missing or non-finite raw values count as 0.
    #[inline]
    pub fn from_raw(raw: &[f32], object_raw: &[f32]) -> Self {
        Params::from_raw(&core::array::from_fn(|i| raw_at(raw, i)), &[raw_at(object_raw, 0)]).into()
    }

    /// Raw outputs and the raw object parameter that [`FresnelMicrofacet::from_raw`] maps back to these
    /// parameters (the inverse of the table).
    #[inline]
    pub fn to_raw(&self) -> ([f32; Self::N_RAW], [f32; Self::N_OBJECT]) {
        let (b0, b1) = BETA_RANGE;
        let (e0, e1) = ETA_RANGE;
        let rho = self.rho.map(logit);
        let raw = [
            rho[0],
            rho[1],
            rho[2],
            logit(self.ks),
            2.0 * logit(self.alpha),
            logit((self.beta - b0) / (b1 - b0)),
            logit((self.eta - e0) / (e1 - e0)),
        ];
        (raw, [libm::logf(self.norm)])
    }

    /// The generalised Gaussian NDF `N exp(-(θh/α)^β)` at a half-vector angle.
    #[inline]
    pub fn ndf(&self, theta_h: f32) -> f32 {
        Params::from(*self).ndf(theta_h)
    }

    /// The formula at the top of the file.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Params::from(*self).eval(wi, wo)
    }
}

/// [`FresnelMicrofacet`]'s parameters in any [`Real`]: the one place its activations and formula are
/// written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    pub rho: [T; 3],
    pub ks: T,
    pub alpha: T,
    pub beta: T,
    pub eta: T,
    pub norm: T,
}

impl<T: Real> Params<T> {
    /// The table at the top of the file.
    #[inline]
    pub fn from_raw(raw: &[T; FresnelMicrofacet::N_RAW], object_raw: &[T; FresnelMicrofacet::N_OBJECT]) -> Self {
        let (b0, b1) = BETA_RANGE;
        let (e0, e1) = ETA_RANGE;
        Self {
            rho: [raw[0].sigmoid(), raw[1].sigmoid(), raw[2].sigmoid()],
            ks: raw[3].sigmoid(),
            alpha: clamp_alpha_generic((raw[4] * 0.5).sigmoid()),
            beta: raw[5].sigmoid() * (b1 - b0) + b0,
            eta: raw[6].sigmoid() * (e1 - e0) + e0,
            norm: object_raw[0].clamp(-80.0, 80.0).exp(),
        }
    }

    /// [`FresnelMicrofacet::ndf`].
    #[inline]
    pub fn ndf(&self, theta_h: f32) -> T {
        let alpha = clamp_alpha_generic(self.alpha);
        self.norm * (-(T::from_f32(theta_h) / alpha).powf(self.beta)).exp()
    }

    /// [`FresnelMicrofacet::eval`].
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [T; 3] {
        let Some(g) = HalfGeometry::new(wi, wo) else {
            return [T::from_f32(0.0); 3];
        };
        let theta_h = libm::atan2f(libm::sqrtf(g.sin2_h), g.cos_h);
        let surface = self.ks
            * self.ndf(theta_h)
            * microfacet::v_cavity_g_over_4cos(&g)
            * microfacet::fresnel_dielectric_generic(g.cos_d, self.eta);
        let one = T::from_f32(1.0);
        let t_i = one - microfacet::fresnel_dielectric_generic(g.cos_i, self.eta);
        let t_o = one - microfacet::fresnel_dielectric_generic(g.cos_o, self.eta);
        let body = (t_i * t_o) * INV_PI;
        T::sanitize(self.rho.map(|r| surface + r * body))
    }
}

impl From<FresnelMicrofacet> for Params<f32> {
    #[inline]
    fn from(m: FresnelMicrofacet) -> Self {
        Self { rho: m.rho, ks: m.ks, alpha: m.alpha, beta: m.beta, eta: m.eta, norm: m.norm }
    }
}

impl From<Params<f32>> for FresnelMicrofacet {
    #[inline]
    fn from(p: Params<f32>) -> Self {
        Self { rho: p.rho, ks: p.ks, alpha: p.alpha, beta: p.beta, eta: p.eta, norm: p.norm }
    }
}

// Importance sampling (see the module docs).

impl FresnelMicrofacet {
    /// Lobe probabilities `[body, surface]`: body albedo times the transmission at `wo` against `ks`
    /// times the Fresnel reflectance at `wo`.
    #[inline]
    fn lobe_probabilities(&self, wo: Vec3) -> [f32; 2] {
        let f = microfacet::fresnel_dielectric(wo.z, self.eta);
        normalise([lum(self.rho) * (1.0 - f), self.ks * f])
    }
}

impl Brdf for FresnelMicrofacet {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        FresnelMicrofacet::eval(self, wi, wo)
    }

    /// Mixture of the cosine lobe and Beckmann half vectors of slope α (a proposal for the generalised
    /// Gaussian; see the module docs).
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let wi = sample_cosine_beckmann(self.lobe_probabilities(wo), self.alpha, u, wo);
        finish(wi, self.pdf(wi, wo), self.eval(wi, wo))
    }

    /// Density of `sample` at `wi`.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((wi, wo)) = crate::angles::upper_hemisphere_pair(wi, wo) else {
            return 0.0;
        };
        pdf_cosine_beckmann(self.lobe_probabilities(wo), self.alpha, wo, wi)
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalisation_matches_closed_forms() {
        // In the narrow limit (cos θ sin θ ≈ θ) 2π ∫ exp(-(θ/α)^β) θ dθ = 2π α² Γ(2/β)/β. β = 0.5 has
        // too long a tail for that limit at α = 1e-3; the direct sums below cover it.
        let narrow = |a: f64, b: f64| 2.0 * core::f64::consts::PI * a * a * libm::tgamma(2.0 / b) / b;
        for beta in [1.0f32, 2.0, 4.0] {
            let a = 1e-3;
            let n = ndf_normalization(a, beta) as f64;
            assert!((n * narrow(a as f64, beta as f64) - 1.0).abs() < 1e-4, "β={beta}");
        }
        for (a, b) in [(1.0f32, 2.0f32), (0.3, 0.5), (0.7, 4.0)] {
            let m = 400_000;
            let mut s = 0.0f64;
            for j in 0..m {
                let th = (j as f64 + 0.5) / m as f64 * core::f64::consts::FRAC_PI_2;
                s += (-(th / a as f64).powf(b as f64)).exp() * th.cos() * th.sin();
            }
            let direct = 1.0 / (s * core::f64::consts::FRAC_PI_2 / m as f64 * 2.0 * core::f64::consts::PI);
            let n = ndf_normalization(a, b) as f64;
            assert!((n / direct - 1.0).abs() < 1e-5, "α={a} β={b}: {n} vs {direct}");
        }
    }

    #[test]
    fn raw_object_parameter_round_trips() {
        let m = FresnelMicrofacet::from_raw(&[0.0, 0.0, 0.0, 0.0, -1.0, 0.3, 0.0], &[log_norm_raw(0.3, 2.0)]);
        let exact = ndf_normalization(0.3, 2.0);
        assert!((m.norm / exact - 1.0).abs() < 1e-5);
    }
}
