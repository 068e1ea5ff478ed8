//! Lambertian reflection (Lambert 1760): `f = kd / π`, the diffuse reference of every other model.
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `kd` (R, G, B albedo) | [0, 1] | `sigmoid(raw)` |
//!
//! Sampling (`sample` / `pdf` below): the cosine lobe, so the estimator weight is `kd` exactly.

use super::raw_at;
use crate::angles::upper_hemisphere_pair;
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{logit, INV_PI};
use crate::real::Real;
use crate::sampling::{finish, valid_wo};
use crate::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use crate::{Rgb, Vec3};

/// A Lambertian BRDF with albedo `kd`: the albedo is exactly `kd` at every incidence.
///
/// ```
/// use nbrdf::{parametric::Lambert, Vec3};
/// let white = Lambert { kd: [1.0; 3] };
/// let f = white.eval(Vec3::new(0.3, 0.0, 0.9), Vec3::Z);
/// assert!((f[0] - core::f32::consts::FRAC_1_PI).abs() < 1e-7);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Diffuse albedo per channel, in [0, 1] for an energy-conserving surface.
    pub kd: Rgb,
}

impl Lambert {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 3;

    /// Parameters from raw network outputs (table at the top of the file); missing or non-finite raw
    /// values count as 0.
    #[inline]
    pub fn from_raw(raw: &[f32]) -> Self {
        Params::from_raw(&core::array::from_fn(|i| raw_at(raw, i))).into()
    }

    /// Raw outputs that [`Lambert::from_raw`] maps back to these parameters (values in the open range
    /// (0, 1) round-trip; the ends are clamped to 1e-7 from them).
    #[inline]
    pub fn to_raw(&self) -> [f32; Self::N_RAW] {
        self.kd.map(logit)
    }

    /// `kd / π` for a valid pair, 0 below the horizon or for degenerate input.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Params::from(*self).eval(wi, wo)
    }
}

/// [`Lambert`]'s parameters in any [`Real`]: the one place its activations and formula are written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    pub kd: [T; 3],
}

impl<T: Real> Params<T> {
    /// The table at the top of the file.
    #[inline]
    pub fn from_raw(raw: &[T; Lambert::N_RAW]) -> Self {
        Self { kd: [raw[0].sigmoid(), raw[1].sigmoid(), raw[2].sigmoid()] }
    }

    /// `kd / π` for a valid pair, 0 below the horizon or for degenerate input.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [T; 3] {
        if upper_hemisphere_pair(wi, wo).is_none() {
            return [T::from_f32(0.0); 3];
        }
        T::sanitize(self.kd.map(|k| k * INV_PI))
    }
}

impl From<Lambert> for Params<f32> {
    #[inline]
    fn from(m: Lambert) -> Self {
        Self { kd: m.kd }
    }
}

impl From<Params<f32>> for Lambert {
    #[inline]
    fn from(p: Params<f32>) -> Self {
        Self { kd: p.kd }
    }
}

// Importance sampling (see the module docs).

impl Brdf for Lambert {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Lambert::eval(self, wi, wo)
    }

    /// Cosine-weighted `wi`; the weight is `kd` exactly.
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let wi = square_to_cosine_hemisphere([u[0], u[1]]);
        finish(wi, cosine_hemisphere_pdf(wi), self.eval(wi, wo))
    }

    /// Density of `sample` at `wi`.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        match crate::angles::upper_hemisphere_pair(wi, wo) {
            Some((wi, _)) => cosine_hemisphere_pdf(wi),
            None => 0.0,
        }
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
    fn lambert_weight_is_the_albedo() {
        let m = Lambert { kd: [0.2, 0.5, 0.9] };
        let s = m.sample(Vec3::new(0.1, 0.2, 0.9), [0.3, 0.6, 0.1]).unwrap();
        for c in 0..3 {
            assert!((s.weight[c] - m.kd[c]).abs() < 1e-5);
        }
    }
}
