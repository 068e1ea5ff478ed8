//! The energy-preserving modified Phong BRDF "RP" (Lafortune & Willems 1994, "Using the modified Phong
//! reflectance model for physically based rendering"; the paper's "Realistic Phong", Sec. 4.1.1):
//!
//! `f(wi, wo) = kd / π + ks (n + 2) / (2π) · cos^n α`, with `cos α = max(0, wo · reflect(wi, n))`,
//!
//! `α` the angle between `wo` and the mirror direction of `wi`. The `(n + 2)/(2π)` factor makes the
//! specular lobe's albedo exactly `ks` at normal incidence and less elsewhere, so `kd + ks ≤ 1` per
//! channel makes the whole BRDF energy preserving (Lafortune & Willems 1994, their energy-conservation condition).
//!
//! The raw parametrisation enforces that constraint instead of hoping the network learns it: `kd` takes a
//! sigmoid, and `ks` is a sigmoid *fraction of what is left*, `ks = (1 - kd) σ(raw)`.
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `kd` (R, G, B) | [0, 1] | `kd_c = sigmoid(raw[c])` |
//! | 3, 4, 5 | `ks` (R, G, B) | [0, 1 - kd_c] | `ks_c = (1 - kd_c) · sigmoid(raw[3 + c])` |
//! | 6 | `n` (exponent) | [0, ∞) | `softplus(raw[6])` |
//!
//! Sampling (`sample` / `pdf` below): a mixture of the cosine lobe and the lobe `cos^n α` about the
//! mirror of `wo`, chosen by `lum(kd)` against `lum(ks)`.

use super::raw_at;
use crate::angles::upper_hemisphere_pair;
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{logit, softplus_inv, INV_PI};
use crate::real::Real;
use crate::sampling::{choose, finish, lum, normalise, valid_wo};
use crate::warp::{cosine_hemisphere_pdf, phong_lobe_pdf, sample_phong_lobe, square_to_cosine_hemisphere};
use crate::{Error, Rgb, Vec3};

/// Energy-preserving modified Phong ("RP").
///
/// ```
/// use nbrdf::{parametric::Phong, Vec3};
/// let rp = Phong::new([0.0; 3], [1.0; 3], 10.0).unwrap();
/// // In the mirror direction cos α = 1: f = ks (n + 2) / 2π.
/// let (wi, wo) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8));
/// assert!((rp.eval(wi, wo)[0] - 12.0 / (2.0 * core::f32::consts::PI)).abs() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    /// Diffuse albedo per channel.
    pub kd: Rgb,
    /// Specular albedo (at normal incidence) per channel; `kd + ks ≤ 1` preserves energy
    /// ([`Phong::new`] checks it; a struct literal does not).
    pub ks: Rgb,
    /// Phong exponent `n ≥ 0`; larger is shinier.
    pub n: f32,
}

impl Phong {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 7;

    /// The model with albedos `kd`, `ks` and exponent `n`, checked: albedos in [0, 1] with
    /// `kd + ks ≤ 1` per channel (else the BRDF reflects more than it receives), `n` finite and ≥ 0.
    ///
    /// ```
    /// use nbrdf::parametric::Phong;
    /// assert!(Phong::new([0.4; 3], [0.5; 3], 20.0).is_ok());
    /// let err = Phong::new([0.6; 3], [0.5; 3], 20.0).unwrap_err();
    /// assert!(err.to_string().contains("kd + ks"));
    /// ```
    pub fn new(kd: Rgb, ks: Rgb, n: f32) -> Result<Self, Error> {
        let albedo = |x: f32| x.is_finite() && (0.0..=1.0).contains(&x);
        if !kd.iter().chain(&ks).all(|&x| albedo(x)) {
            return Err(Error::InvalidValue { what: "Phong kd and ks", reason: "must be finite and in [0, 1]" });
        }
        // One ulp of slack: `from_raw`'s `ks = (1 - kd) σ` may round a hair above.
        if (0..3).any(|c| kd[c] + ks[c] > 1.0 + f32::EPSILON) {
            return Err(Error::InvalidValue {
                what: "Phong kd + ks",
                reason: "must be at most 1 per channel, or the BRDF creates energy (Lafortune & Willems 1994)",
            });
        }
        if !(n.is_finite() && n >= 0.0) {
            return Err(Error::InvalidValue { what: "Phong exponent n", reason: "must be finite and >= 0" });
        }
        Ok(Phong { kd, ks, n })
    }

    /// Parameters from raw network outputs (table at the top of the file); missing or non-finite raw
    /// values count as 0. The result always satisfies `kd + ks ≤ 1` per channel.
    #[inline]
    pub fn from_raw(raw: &[f32]) -> Self {
        Params::from_raw(&core::array::from_fn(|i| raw_at(raw, i))).into()
    }

    /// Raw outputs that [`Phong::from_raw`] maps back to these parameters (the inverse of the table).
    #[inline]
    pub fn to_raw(&self) -> [f32; Self::N_RAW] {
        let mut r = [0.0; Self::N_RAW];
        for c in 0..3 {
            r[c] = logit(self.kd[c]);
            let rest = 1.0 - self.kd[c];
            r[3 + c] = logit(if rest > 0.0 { self.ks[c] / rest } else { 0.0 });
        }
        r[6] = softplus_inv(self.n);
        r
    }

    /// `cos α = wo · reflect(wi, z) = wi.z wo.z - (wi.x wo.x + wi.y wo.y)`, written so that swapping `wi`
    /// and `wo` gives the same bits (every product commutes, the sum order is fixed).
    #[inline]
    pub fn cos_alpha(wi: Vec3, wo: Vec3) -> f32 {
        wi.z * wo.z - (wi.x * wo.x + wi.y * wo.y)
    }

    /// Lafortune & Willems 1994, the modified Phong BRDF: `kd/π + ks (n+2)/(2π) max(0, cos α)^n`.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Params::from(*self).eval(wi, wo)
    }
}

/// [`Phong`]'s parameters in any [`Real`]: the one place its activations and formula are written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    pub kd: [T; 3],
    pub ks: [T; 3],
    pub n: T,
}

impl<T: Real> Params<T> {
    /// The table at the top of the file.
    #[inline]
    pub fn from_raw(raw: &[T; Phong::N_RAW]) -> Self {
        let kd = [raw[0].sigmoid(), raw[1].sigmoid(), raw[2].sigmoid()];
        let ks = [0, 1, 2].map(|c| (T::from_f32(1.0) - kd[c]) * raw[3 + c].sigmoid());
        Self { kd, ks, n: raw[6].softplus() }
    }

    /// [`Phong::eval`].
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [T; 3] {
        let Some((wi, wo)) = upper_hemisphere_pair(wi, wo) else {
            return [T::from_f32(0.0); 3];
        };
        let cos_a = Phong::cos_alpha(wi, wo).min(1.0);
        // The lobe lives where cos α > 0 only (also for n = 0, where powf(0, 0) would give 1).
        let lobe = if cos_a > 0.0 {
            (self.n + 2.0) * (0.5 * INV_PI) * T::powf_base(cos_a, self.n)
        } else {
            T::from_f32(0.0)
        };
        T::sanitize([0, 1, 2].map(|c| self.kd[c] * INV_PI + self.ks[c] * lobe))
    }
}

impl From<Phong> for Params<f32> {
    #[inline]
    fn from(m: Phong) -> Self {
        Self { kd: m.kd, ks: m.ks, n: m.n }
    }
}

impl From<Params<f32>> for Phong {
    #[inline]
    fn from(p: Params<f32>) -> Self {
        Self { kd: p.kd, ks: p.ks, n: p.n }
    }
}

// Importance sampling (see the module docs).

impl Phong {
    /// Lobe probabilities `[diffuse, specular]`, proportional to `lum(kd)` and `lum(ks)`.
    #[inline]
    fn lobe_probabilities(&self) -> [f32; 2] {
        normalise([lum(self.kd), lum(self.ks)])
    }
}

impl Brdf for Phong {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Phong::eval(self, wi, wo)
    }

    /// Mixture of the cosine lobe and the Phong lobe about the mirror direction of `wo`.
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let p = self.lobe_probabilities();
        let wi = match choose(&p, u[2]) {
            0 => square_to_cosine_hemisphere([u[0], u[1]]),
            _ => sample_phong_lobe(crate::angles::reflect(wo, Vec3::Z), self.n, [u[0], u[1]]),
        };
        finish(wi, self.pdf(wi, wo), self.eval(wi, wo))
    }

    /// Density of `sample` at `wi`.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((wi, wo)) = crate::angles::upper_hemisphere_pair(wi, wo) else {
            return 0.0;
        };
        let p = self.lobe_probabilities();
        p[0] * cosine_hemisphere_pdf(wi) + p[1] * phong_lobe_pdf(Phong::cos_alpha(wi, wo), self.n)
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        true
    }
}
