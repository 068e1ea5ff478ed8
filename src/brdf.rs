//! The one interface a renderer shades with: [`Brdf`], the value of a BRDF, an importance sample of
//! it and that sample's density, for every BRDF of the crate (parametric models, built-ins, MERL
//! tables, NBRDF-json networks, and a `.nbrdf` model at a prepared point, [`crate::model::ModelAt`]).
//!
//! Conventions, the same for every method and every implementor:
//!
//! | | nbrdf | pbrt-v4 `BxDF` | Mitsuba 3 `BSDF` |
//! |---|---|---|---|
//! | frame | local shading frame, normal = +z | the same | the same |
//! | toward the viewer | `wo` | `wo` | `si.wi` |
//! | toward the light | `wi` | `wi` | `wo` |
//! | value | `f(wi, wo)` in 1/sr, cosine not included | `f(wo, wi)` | `eval` includes the cosine |
//!
//! Both directions are unit vectors pointing away from the surface. Below the horizon, degenerate or
//! non-finite input gives 0 (value and density) and no sample, never NaN.

use crate::{Rgb, Vec3};

/// A sampled incident direction with its estimator weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The sampled direction toward the light, unit, upper hemisphere.
    pub wi: Vec3,
    /// `f(wi, wo) cos θi / pdf`, finite and non-negative.
    pub weight: Rgb,
    /// Density of `wi` per unit solid angle (the whole mixture's), > 0.
    pub pdf: f32,
}

/// A BRDF a renderer can evaluate and importance-sample.
///
/// `sample` and `pdf` describe the same density: for every sample `s` of `sample(wo, u)`,
/// `pdf(s.wi, wo) == s.pdf` and `s.weight == eval(s.wi, wo) · s.wi.z / s.pdf` (to the rounding of
/// normalising a `wo` that is not exactly unit), so the weight is an unbiased estimator weight. The trait is object safe (`&dyn Brdf` works) and needs no allocation.
///
/// ```
/// use nbrdf::{parametric::Phong, Brdf, Vec3};
/// let rp = Phong::new([0.3; 3], [0.5; 3], 40.0).unwrap();
/// let wo = Vec3::new(0.3, 0.0, 0.9).normalize();
/// let s = rp.sample(wo, [0.2, 0.7, 0.9]).unwrap();
/// assert_eq!(s.pdf, rp.pdf(s.wi, wo));
/// let f = rp.eval(s.wi, wo);
/// assert!((s.weight[0] - f[0] * s.wi.z / s.pdf).abs() <= 1e-5 * s.weight[0]);
/// assert!(rp.is_reciprocal());
/// ```
pub trait Brdf {
    /// `f(wi, wo)` per channel, 1/sr; 0 below the horizon.
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb;

    /// Samples `wi` for the view `wo` from three uniform numbers in [0, 1); `None` where no direction
    /// was produced (`wo` below the horizon, or a lobe proposed one below it).
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample>;

    /// Density of [`Brdf::sample`] at `wi` per unit solid angle of `wi`.
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32;

    /// Whether `eval(wi, wo) == eval(wo, wi)` for every pair (Helmholtz reciprocity), by construction
    /// of the model rather than by measurement; equal up to float rounding (bitwise for the
    /// reciprocity map Θ).
    fn is_reciprocal(&self) -> bool;
}

impl<B: Brdf + ?Sized> Brdf for &B {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        (**self).eval(wi, wo)
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        (**self).sample(wo, u)
    }
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        (**self).pdf(wi, wo)
    }
    #[inline]
    fn is_reciprocal(&self) -> bool {
        (**self).is_reciprocal()
    }
}
