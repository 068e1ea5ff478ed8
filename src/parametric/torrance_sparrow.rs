//! Torrance-Sparrow microfacet BRDF (Torrance & Sparrow 1967, "Theory for off-specular reflection from
//! roughened surfaces"; in the form of Cook & Torrance 1982 and Walter et al. 2007, Eq. 20) plus a Lambertian diffuse term:
//!
//! `f(wi, wo) = kd / π + D(h) G(wi, wo) F(cos θd) / (4 cos θi cos θo)`
//!
//! - `D`: Beckmann distribution with RMS slope `α` ([`microfacet::beckmann_d`]),
//! - `G`: the V-cavity shadowing-masking of Torrance & Sparrow ([`microfacet::v_cavity_g_over_4cos`]),
//! - `F`: **Schlick's approximation with an RGB `F0 = ks`** ([`microfacet::fresnel_schlick`], `cos θd =
//!   wi·h`). This variant is chosen over the dielectric Fresnel with a scalar η because a per-channel
//!   normal-incidence reflectance in [0, 1] also covers coloured metals (MERL's copper, gold, chrome), which
//!   a dielectric η ≤ 3 (F0 ≤ 0.25, colourless) cannot. The FMBRDF ([`super::FresnelMicrofacet`]) is the
//!   model with the physical dielectric Fresnel.
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `kd` (R, G, B diffuse albedo) | [0, 1] | `sigmoid(raw)` |
//! | 3, 4, 5 | `ks` (R, G, B Fresnel F0) | [0, 1] | `sigmoid(raw)` |
//! | 6 | `alpha` (Beckmann RMS slope) | [1e-3, 1] | `max(sigmoid(0.5 · raw[6]), 1e-3)` |
//!
//! The ×0.5 on the roughness pre-activation is Sec. 4.1.1's stabilisation of training.
//!
//! Sampling (`sample` / `pdf` below): a mixture of the cosine lobe and Beckmann `D cos θh` half vectors,
//! chosen by `lum(kd)` against the Schlick reflectance at `wo`; the FMBRDF reuses this proposal.

use super::raw_at;
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{logit, INV_PI};
use crate::microfacet::{self, clamp_alpha, clamp_alpha_generic, HalfGeometry};
use crate::real::Real;
use crate::sampling::{choose, finish, lum, normalise, valid_wo};
use crate::warp::{cosine_hemisphere_pdf, half_vector_pdf, reflect_about, sample_beckmann, square_to_cosine_hemisphere};
use crate::{Rgb, Vec3};

/// Torrance-Sparrow (Beckmann, V-cavity, Schlick) with a Lambertian base.
///
/// ```
/// use nbrdf::{parametric::TorranceSparrow, Vec3};
/// let ts = TorranceSparrow { kd: [0.5; 3], ks: [0.04; 3], alpha: 0.2 };
/// let f = ts.eval(Vec3::new(0.3, 0.1, 0.9), Vec3::new(-0.2, 0.0, 0.95));
/// assert!(f[0] > 0.5 / core::f32::consts::PI); // diffuse plus a highlight
/// assert_eq!(ts.eval(Vec3::new(0.3, 0.1, -0.9), Vec3::Z), [0.0; 3]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorranceSparrow {
    /// Lambertian diffuse albedo per channel.
    pub kd: Rgb,
    /// Specular reflectance at normal incidence (Schlick's F0) per channel.
    pub ks: Rgb,
    /// Beckmann RMS microfacet slope α, clamped to [1e-3, 1] when evaluated.
    pub alpha: f32,
}

impl TorranceSparrow {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 7;

    /// Parameters from raw network outputs (table at the top of the file); missing or non-finite raw
    /// values count as 0.
    #[inline]
    pub fn from_raw(raw: &[f32]) -> Self {
        Params::from_raw(&core::array::from_fn(|i| raw_at(raw, i))).into()
    }

    /// Raw outputs that [`TorranceSparrow::from_raw`] maps back to these parameters (the inverse of the
    /// table; the roughness pre-activation is `2 logit(α)`).
    #[inline]
    pub fn to_raw(&self) -> [f32; Self::N_RAW] {
        let kd = self.kd.map(logit);
        let ks = self.ks.map(logit);
        [kd[0], kd[1], kd[2], ks[0], ks[1], ks[2], 2.0 * logit(self.alpha)]
    }

    /// Walter et al. 2007, Eq. 20 with the terms above, plus the Lambertian term.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Params::from(*self).eval(wi, wo)
    }
}

/// [`TorranceSparrow`]'s parameters in any [`Real`]: the one place its activations and formula are
/// written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    pub kd: [T; 3],
    pub ks: [T; 3],
    pub alpha: T,
}

impl<T: Real> Params<T> {
    /// The table at the top of the file.
    #[inline]
    pub fn from_raw(raw: &[T; TorranceSparrow::N_RAW]) -> Self {
        Self {
            kd: [raw[0].sigmoid(), raw[1].sigmoid(), raw[2].sigmoid()],
            ks: [raw[3].sigmoid(), raw[4].sigmoid(), raw[5].sigmoid()],
            alpha: clamp_alpha_generic((raw[6] * 0.5).sigmoid()),
        }
    }

    /// [`TorranceSparrow::eval`].
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [T; 3] {
        let Some(g) = HalfGeometry::new(wi, wo) else {
            return [T::from_f32(0.0); 3];
        };
        let alpha = clamp_alpha_generic(self.alpha);
        let dg = microfacet::beckmann_d_generic(g.cos_h, g.sin2_h, alpha) * microfacet::v_cavity_g_over_4cos(&g);
        T::sanitize(
            [0, 1, 2].map(|c| {
                self.kd[c] * INV_PI + dg * microfacet::fresnel_schlick_generic(self.ks[c], g.cos_d)
            }),
        )
    }
}

impl From<TorranceSparrow> for Params<f32> {
    #[inline]
    fn from(m: TorranceSparrow) -> Self {
        Self { kd: m.kd, ks: m.ks, alpha: m.alpha }
    }
}

impl From<Params<f32>> for TorranceSparrow {
    #[inline]
    fn from(p: Params<f32>) -> Self {
        Self { kd: p.kd, ks: p.ks, alpha: p.alpha }
    }
}

// Importance sampling (see the module docs).

impl TorranceSparrow {
    /// Lobe probabilities `[diffuse, specular]`: `lum(kd)` against the Schlick reflectance at `wo`.
    #[inline]
    fn lobe_probabilities(&self, wo: Vec3) -> [f32; 2] {
        let spec = self.ks.map(|f0| microfacet::fresnel_schlick(f0, wo.z));
        normalise([lum(self.kd), lum(spec)])
    }
}

impl Brdf for TorranceSparrow {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        TorranceSparrow::eval(self, wi, wo)
    }

    /// Mixture of the cosine lobe and Beckmann half vectors reflected about `wo`.
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

/// A direction from the mixture `p[0]` cosine lobe + `p[1]` Beckmann half vectors of slope `alpha`
/// reflected about `wo`: the proposal of Torrance-Sparrow and of the FMBRDF.
#[inline]
pub(super) fn sample_cosine_beckmann(p: [f32; 2], alpha: f32, u: [f32; 3], wo: Vec3) -> Vec3 {
    match choose(&p, u[2]) {
        0 => square_to_cosine_hemisphere([u[0], u[1]]),
        _ => reflect_about(wo, sample_beckmann(clamp_alpha(alpha), [u[0], u[1]])),
    }
}

/// Density of [`sample_cosine_beckmann`] at `wi` (both directions valid and unit).
#[inline]
pub(super) fn pdf_cosine_beckmann(p: [f32; 2], alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    let alpha = clamp_alpha(alpha);
    p[0] * cosine_hemisphere_pdf(wi) + p[1] * half_vector_pdf(wo, wi, |c, s2| microfacet::beckmann_d(c, s2, alpha))
}
