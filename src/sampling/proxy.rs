//! The sampling proxy of a BRDF that has no closed form to invert (a neural model, a MERL table, an
//! NBRDF-json network): a mixture of a cosine lobe and up to two GGX visible-normal lobes, each with a
//! selection probability. Sztrajman et al. 2021 ("Neural BRDF representation and importance sampling",
//! Sec. 5) sample neural BRDFs the same way, through an analytic model fitted to the network.
//!
//! A sample draws `wi` from the mixture and the caller's BRDF is evaluated there; the density reported is
//! always the whole mixture's (one-sample MIS with the balance heuristic, Veach 1997, Sec. 9.2.4), so
//! `weight = f cos θi / pdf` is unbiased whatever the proxy looks like. How good the proxy is only
//! changes the variance. The cosine lobe keeps a probability of at least [`DEFENSIVE`] in every fitted
//! proxy (defensive importance sampling, Hesterberg 1995), so the pdf is positive on the whole upper
//! hemisphere, wherever `f` can be.
//!
//! ```
//! use nbrdf::sampling::{GgxLobe, Proxy};
//! use nbrdf::Vec3;
//! let proxy = Proxy::new(0.2, [GgxLobe { weight: 0.8, alpha: 0.1 }, GgxLobe::NONE]).unwrap();
//! let wo = Vec3::new(0.3, 0.0, 0.9).normalize();
//! let brdf = |wi: Vec3, wo: Vec3| nbrdf::builtin::Builtin::TwoLobeMetal.eval(wi, wo);
//! let s = proxy.sample(wo, [0.4, 0.7, 0.5], brdf).unwrap();
//! assert_eq!(s.pdf, proxy.pdf(s.wi, wo));
//! let f = brdf(s.wi, wo);
//! assert!((s.weight[1] - f[1] * s.wi.z / s.pdf).abs() <= 1e-5 * s.weight[1]);
//! ```

use serde::{Deserialize, Serialize};

use super::{finish, valid_wo, BsdfSample};
use crate::microfacet::ALPHA_MIN;
use crate::warp::{
    cosine_hemisphere_pdf, ggx_vndf_pdf, half_of, reflect_about, sample_ggx_vndf, square_to_cosine_hemisphere,
};
use crate::{Error, Rgb, Vec3};

/// Number of GGX lobes a proxy holds.
pub const MAX_LOBES: usize = 2;

/// Smallest selection probability of the cosine lobe in a fitted proxy.
pub const DEFENSIVE: f32 = 0.1;

/// One GGX lobe of a proxy: its selection probability and its roughness.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct GgxLobe {
    /// Probability of choosing this lobe, in [0, 1]; 0 disables it.
    pub weight: f32,
    /// GGX roughness α in [[`ALPHA_MIN`], 1].
    pub alpha: f32,
}

impl GgxLobe {
    /// An unused lobe.
    pub const NONE: GgxLobe = GgxLobe { weight: 0.0, alpha: 1.0 };
}

/// A cosine lobe and up to [`MAX_LOBES`] GGX visible-normal lobes with selection probabilities that sum
/// to 1. Built by [`Proxy::new`] or fitted by [`fit_proxy`](super::fit_proxy); stored in the model file
/// header (`docs/models.md`).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct Proxy {
    /// Probability of the cosine lobe, > 0.
    pub diffuse: f32,
    /// The GGX lobes.
    pub lobes: [GgxLobe; MAX_LOBES],
}

// Bitwise equality and hashing, so the proxy can live in the `Eq + Hash` model header: every stored
// proxy is validated finite, where bitwise and numeric equality agree except for ±0 (never produced).
impl PartialEq for Proxy {
    fn eq(&self, other: &Self) -> bool {
        self.bits() == other.bits()
    }
}
impl Eq for Proxy {}
impl core::hash::Hash for Proxy {
    fn hash<H: core::hash::Hasher>(&self, state: &mut H) {
        self.bits().hash(state)
    }
}

impl Default for Proxy {
    fn default() -> Self {
        Proxy::COSINE
    }
}

impl Proxy {
    /// Pure cosine sampling: what a BRDF without a fitted proxy falls back to.
    pub const COSINE: Proxy = Proxy { diffuse: 1.0, lobes: [GgxLobe::NONE; MAX_LOBES] };

    fn bits(&self) -> [u32; 1 + 2 * MAX_LOBES] {
        let mut b = [self.diffuse.to_bits(); 1 + 2 * MAX_LOBES];
        for (k, l) in self.lobes.iter().enumerate() {
            b[1 + 2 * k] = l.weight.to_bits();
            b[2 + 2 * k] = l.alpha.to_bits();
        }
        b
    }

    /// A proxy from unnormalised lobe weights: they are divided by their sum. Errors on non-finite or
    /// negative weights, a cosine weight of 0 (the pdf would vanish where no GGX lobe reaches) and α
    /// outside [[`ALPHA_MIN`], 1].
    pub fn new(diffuse: f32, lobes: [GgxLobe; MAX_LOBES]) -> Result<Self, Error> {
        let sum = diffuse + lobes.iter().map(|l| l.weight).sum::<f32>();
        if !(sum.is_finite() && sum > 0.0) {
            return Err(Error::InvalidValue { what: "proxy lobe weights", reason: "must be finite with a positive sum" });
        }
        let p = Proxy {
            diffuse: diffuse / sum,
            lobes: lobes.map(|l| GgxLobe { weight: l.weight / sum, alpha: l.alpha }),
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks what [`Proxy::sample`] relies on: finite probabilities in [0, 1] summing to 1 (to 1e-4), a
    /// positive cosine probability, every α in [[`ALPHA_MIN`], 1].
    pub fn validate(&self) -> Result<(), Error> {
        let ws = [self.diffuse, self.lobes[0].weight, self.lobes[1].weight];
        if ws.iter().any(|w| !(w.is_finite() && (0.0..=1.0).contains(w))) {
            return Err(Error::InvalidValue { what: "proxy lobe weights", reason: "must be finite and in [0, 1]" });
        }
        if (ws.iter().sum::<f32>() - 1.0).abs() > 1e-4 {
            return Err(Error::InvalidValue { what: "proxy lobe weights", reason: "must sum to 1" });
        }
        if self.diffuse <= 0.0 {
            return Err(Error::InvalidValue {
                what: "proxy cosine weight",
                reason: "must be positive so that the pdf covers the whole hemisphere",
            });
        }
        if self.lobes.iter().any(|l| !(l.alpha >= ALPHA_MIN && l.alpha <= 1.0)) {
            return Err(Error::InvalidValue { what: "proxy GGX alpha", reason: "must lie in [1e-3, 1]" });
        }
        Ok(())
    }

    /// Index of the lobe `u` selects: 0 is the cosine lobe, `1 + k` GGX lobe `k`.
    #[inline]
    fn choose(&self, u: f32) -> usize {
        let mut acc = self.diffuse;
        if u < acc {
            return 0;
        }
        for (k, l) in self.lobes.iter().enumerate() {
            acc += l.weight;
            if u < acc && l.weight > 0.0 {
                return 1 + k;
            }
        }
        // Rounding left u ≥ Σ p: the last lobe with mass.
        self.lobes.iter().rposition(|l| l.weight > 0.0).map_or(0, |k| 1 + k)
    }

    /// A direction `wi` drawn from the mixture for the view `wo`, or `None` when the chosen GGX lobe
    /// reflects below the horizon or `wo` is invalid. `u` is three uniform numbers in [0, 1): two for the
    /// direction, one for the lobe.
    #[inline]
    pub fn sample_wi(&self, wo: Vec3, u: [f32; 3]) -> Option<Vec3> {
        let wo = valid_wo(wo)?;
        let uv = [u[0], u[1]];
        let wi = match self.choose(u[2]) {
            0 => square_to_cosine_hemisphere(uv),
            k => reflect_about(wo, sample_ggx_vndf(wo, self.lobes[k - 1].alpha, uv)),
        };
        (wi.z > 0.0 && wi.is_finite()).then_some(wi)
    }

    /// Density of [`Proxy::sample_wi`] per unit solid angle of `wi`: `p_d cos θi / π + Σ_k p_k
    /// D_wo(h; α_k) / (4 wo·h)` (Heitz 2018, Sec. 2, with the reflection Jacobian of Walter et al. 2007,
    /// Eq. 14). 0 below the horizon or for invalid input.
    #[inline]
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((wi, wo)) = crate::angles::upper_hemisphere_pair(wi, wo) else {
            return 0.0;
        };
        let mut pdf = self.diffuse * cosine_hemisphere_pdf(wi);
        if let Some((h, oh)) = half_of(wo, wi) {
            for l in self.lobes.iter().filter(|l| l.weight > 0.0) {
                pdf += l.weight * ggx_vndf_pdf(wo, h, l.alpha) / (4.0 * oh);
            }
        }
        if pdf.is_finite() && pdf > 0.0 {
            pdf
        } else {
            0.0
        }
    }

    /// Samples the proxy and evaluates `brdf(wi, wo)` for the weight `f cos θi / pdf`, with the mixture
    /// pdf of [`Proxy::pdf`].
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f32; 3], brdf: impl FnOnce(Vec3, Vec3) -> Rgb) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let wi = self.sample_wi(wo, u)?;
        finish(wi, self.pdf(wi, wo), brdf(wi, wo))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_normalises_and_rejects_bad_weights() {
        let p = Proxy::new(1.0, [GgxLobe { weight: 3.0, alpha: 0.2 }, GgxLobe::NONE]).unwrap();
        assert_eq!((p.diffuse, p.lobes[0].weight), (0.25, 0.75));
        assert!(Proxy::new(0.0, [GgxLobe { weight: 1.0, alpha: 0.2 }, GgxLobe::NONE]).is_err());
        assert!(Proxy::new(1.0, [GgxLobe { weight: f32::NAN, alpha: 0.2 }, GgxLobe::NONE]).is_err());
        assert!(Proxy::new(1.0, [GgxLobe { weight: 1.0, alpha: 0.0 }, GgxLobe::NONE]).is_err());
    }

    #[test]
    fn cosine_proxy_is_the_cosine_density() {
        let wi = Vec3::new(0.3, -0.2, 0.9).normalize();
        // Within the rounding of normalising `wi` again.
        let want = wi.z * crate::math::INV_PI;
        assert!((Proxy::COSINE.pdf(wi, Vec3::Z) - want).abs() <= 2e-7 * want);
    }
}
