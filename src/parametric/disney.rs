//! The isotropic Disney "principled" BRDF (Burley 2012, "Physically-Based Shading at Disney", Sec. 5 "The
//! Disney BRDF" and Appendix B), following the reference implementation `disney.brdf` of Disney's BRDF Explorer term by
//! term with `anisotropic = 0`:
//!
//! `f = (1 - metallic) (lerp(Fd, ss, subsurface) C / π + F_H sheen C_sheen)
//!    + Ds Fs Gs / (4 cos θl cos θv) + clearcoat / 4 · Dr Fr Gr / (4 cos θl cos θv)`
//!
//! - diffuse (Burley 2012, "Diffuse model details"): `Fd = (1 + (Fd90 - 1) F_L)(1 + (Fd90 - 1) F_V)`,
//!   `Fd90 = 0.5 + 2 roughness cos²θd`, `F_x = (1 - cos θx)^5` (Schlick weights);
//! - subsurface (Hanrahan-Krueger approximation, BRDF Explorer): `ss = 1.25 (Fss (1/(cos θl + cos θv) -
//!   0.5) + 0.5)`, `Fss = (1 + (Fss90 - 1) F_L)(1 + (Fss90 - 1) F_V)`, `Fss90 = roughness cos²θd`;
//! - sheen: `F_H sheen lerp(1, C_tint, sheenTint)`, `F_H = (1 - cos θd)^5`;
//! - specular: GTR2/GGX `Ds` with `α = max(0.001, roughness²)` (Burley's GTR with γ = 2), Schlick
//!   `Fs = lerp(C_spec0, 1, F_H)`, `C_spec0 = lerp(0.08 specular lerp(1, C_tint, specularTint), C,
//!   metallic)`, separable Smith GGX `Gs` (Walter et al. 2007);
//! - clearcoat: GTR1 `Dr` with `α = lerp(0.1, 0.001, clearcoatGloss)` (GTR with γ = 1), `Fr = lerp(0.04, 1,
//!   F_H)` (η = 1.5), Smith GGX `Gr` with fixed α = 0.25;
//! - `C_tint = C / lum(C)`, `lum(C) = 0.3 R + 0.6 G + 0.1 B` (1 where lum = 0).
//!
//! `cos θd = wi·h`. **`base_color` is linear RGB**: BRDF Explorer converts its slider value with
//! `mon2lin` (a 2.2 power) first; here the parameter is what the network predicts, so the model takes the
//! colour as already linear (as pbrt-v3's and Mitsuba's Disney materials do).
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `base_color` (R, G, B, linear) | [0, 1] | `sigmoid(raw)` |
//! | 3 | `subsurface` | [0, 1] | `sigmoid(raw)` |
//! | 4 | `metallic` | [0, 1] | `sigmoid(raw)` |
//! | 5 | `specular` | [0, 1] | `sigmoid(raw)` |
//! | 6 | `specular_tint` | [0, 1] | `sigmoid(raw)` |
//! | 7 | `roughness` | [0, 1] | `sigmoid(0.5 · raw[7])` |
//! | 8 | `sheen` | [0, 1] | `sigmoid(raw)` |
//! | 9 | `sheen_tint` | [0, 1] | `sigmoid(raw)` |
//! | 10 | `clearcoat` | [0, 1] | `sigmoid(raw)` |
//! | 11 | `clearcoat_gloss` | [0, 1] | `sigmoid(raw)` |
//!
//! Sampling (`sample` / `pdf` below): a mixture of the cosine lobe (diffuse, subsurface, sheen), GGX
//! visible normals (Heitz 2018) for the specular lobe and GTR1 half vectors for the clearcoat, chosen by
//! the lobes' weights in `eval` at `wo`.

use super::raw_at;
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{self, logit, INV_PI};
use crate::microfacet::{self, HalfGeometry, ALPHA_MIN};
use crate::real::{lerp, Real};
use crate::sampling::{choose, finish, lum, normalise, valid_wo};
use crate::warp::{
    cosine_hemisphere_pdf, ggx_vndf_pdf, half_of, half_vector_pdf, reflect_about, sample_ggx_vndf, sample_gtr1,
    square_to_cosine_hemisphere,
};
use crate::{Rgb, Vec3};

/// Isotropic Disney BRDF parameters (all in [0, 1]).
///
/// ```
/// use nbrdf::{parametric::Disney, Vec3};
/// let plastic = Disney { base_color: [0.8, 0.1, 0.1], roughness: 0.3, specular: 0.5, ..Disney::default() };
/// let f = plastic.eval(Vec3::new(0.5, 0.0, 0.8), Vec3::new(-0.5, 0.0, 0.8));
/// assert!(f[0] > f[1]); // red base
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Disney {
    /// Surface colour `C`, linear RGB: diffuse albedo, or the specular colour of a metal.
    pub base_color: Rgb,
    /// Blend from the Burley diffuse (0) to the Hanrahan-Krueger subsurface shape (1).
    pub subsurface: f32,
    /// Dielectric (0) to metal (1): a metal has no diffuse or sheen and a base-coloured specular.
    pub metallic: f32,
    /// Dielectric specular amount; 0.5 is F0 = 0.04 (η = 1.5).
    pub specular: f32,
    /// Tints the dielectric specular toward the base colour's hue.
    pub specular_tint: f32,
    /// Perceptual roughness; the GGX α is its square.
    pub roughness: f32,
    /// Grazing sheen for cloth.
    pub sheen: f32,
    /// Tints the sheen toward the base colour's hue.
    pub sheen_tint: f32,
    /// Strength of the second, GTR1 specular lobe (a clear coat).
    pub clearcoat: f32,
    /// Clear-coat glossiness: 0 is "satin" (α = 0.1), 1 is "gloss" (α = 0.001).
    pub clearcoat_gloss: f32,
}

impl Disney {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 12;

    /// Parameters from raw network outputs (table at the top of the file); missing or non-finite raw
    /// values count as 0.
    #[inline]
    pub fn from_raw(raw: &[f32]) -> Self {
        Params::from_raw(&core::array::from_fn(|i| raw_at(raw, i))).into()
    }

    /// Raw outputs that [`Disney::from_raw`] maps back to these parameters (the inverse of the table;
    /// the roughness pre-activation is `2 logit(roughness)`).
    #[inline]
    pub fn to_raw(&self) -> [f32; Self::N_RAW] {
        let c = self.base_color.map(logit);
        [
            c[0],
            c[1],
            c[2],
            logit(self.subsurface),
            logit(self.metallic),
            logit(self.specular),
            logit(self.specular_tint),
            2.0 * logit(self.roughness),
            logit(self.sheen),
            logit(self.sheen_tint),
            logit(self.clearcoat),
            logit(self.clearcoat_gloss),
        ]
    }

    /// The formula at the top of the file (BRDF Explorer `disney.brdf`, `BRDF(L, V, N, X, Y)`).
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Params::from(*self).eval(wi, wo)
    }
}

/// [`Disney`]'s parameters in any [`Real`]: the one place its activations and formula are written.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    pub base_color: [T; 3],
    pub subsurface: T,
    pub metallic: T,
    pub specular: T,
    pub specular_tint: T,
    pub roughness: T,
    pub sheen: T,
    pub sheen_tint: T,
    pub clearcoat: T,
    pub clearcoat_gloss: T,
}

impl<T: Real> Params<T> {
    /// The table at the top of the file.
    #[inline]
    pub fn from_raw(raw: &[T; Disney::N_RAW]) -> Self {
        Self {
            base_color: [raw[0].sigmoid(), raw[1].sigmoid(), raw[2].sigmoid()],
            subsurface: raw[3].sigmoid(),
            metallic: raw[4].sigmoid(),
            specular: raw[5].sigmoid(),
            specular_tint: raw[6].sigmoid(),
            roughness: (raw[7] * 0.5).sigmoid(),
            sheen: raw[8].sigmoid(),
            sheen_tint: raw[9].sigmoid(),
            clearcoat: raw[10].sigmoid(),
            clearcoat_gloss: raw[11].sigmoid(),
        }
    }

    /// [`Disney::eval`]. Constants enter the generic [`lerp`] through `T::from_f32` (`k`), so each
    /// `lerp` below is BRDF Explorer's `mix` with its arguments in its order.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [T; 3] {
        let k = T::from_f32;
        let Some(g) = HalfGeometry::new(wi, wo) else {
            return [k(0.0); 3];
        };
        let c = self.base_color;
        let lum = c[0] * 0.3 + c[1] * 0.6 + c[2] * 0.1;
        let tint = if lum.value() > 0.0 { c.map(|x| x / lum) } else { [k(1.0); 3] };

        let fl = microfacet::schlick_weight(g.cos_i);
        let fv = microfacet::schlick_weight(g.cos_o);
        let fh = microfacet::schlick_weight(g.cos_d);
        let r = self.roughness;
        let cd2 = g.cos_d * g.cos_d;

        // Burley diffuse and the Hanrahan-Krueger-like subsurface shape.
        let fd90 = r * (2.0 * cd2) + 0.5;
        let fd = lerp(k(1.0), fd90, k(fl)) * lerp(k(1.0), fd90, k(fv));
        let fss90 = r * cd2;
        let fss = lerp(k(1.0), fss90, k(fl)) * lerp(k(1.0), fss90, k(fv));
        let ss = (fss * (1.0 / (g.cos_i + g.cos_o) - 0.5) + 0.5) * 1.25;
        let diffuse = lerp(fd, ss, self.subsurface) * INV_PI;

        // Primary specular: GTR2, separable Smith GGX (the product is G / (4 cos θl cos θv)).
        let alpha = (r * r).max(k(ALPHA_MIN));
        let ds = microfacet::ggx_d_generic(g.cos_h, g.sin2_h, alpha);
        let gs = microfacet::smith_ggx_g1_over_2cos_generic(g.cos_i, alpha)
            * microfacet::smith_ggx_g1_over_2cos_generic(g.cos_o, alpha);

        // Clearcoat: GTR1, fixed-roughness masking, F0 = 0.04.
        let dr = microfacet::gtr1_d_generic(g.cos_h, g.sin2_h, lerp(k(0.1), k(0.001), self.clearcoat_gloss));
        let fr = math::lerp(0.04, 1.0, fh);
        let gr = microfacet::smith_ggx_g1_over_2cos(g.cos_i, 0.25)
            * microfacet::smith_ggx_g1_over_2cos(g.cos_o, 0.25);
        let coat = self.clearcoat * 0.25 * gr * fr * dr;

        let m = self.metallic;
        T::sanitize([0, 1, 2].map(|i| {
            let spec0 = lerp(self.specular * 0.08 * lerp(k(1.0), tint[i], self.specular_tint), c[i], m);
            let fs = lerp(spec0, k(1.0), k(fh));
            let sheen = self.sheen * fh * lerp(k(1.0), tint[i], self.sheen_tint);
            (diffuse * c[i] + sheen) * (k(1.0) - m) + gs * fs * ds + coat
        }))
    }
}

impl From<Disney> for Params<f32> {
    #[inline]
    fn from(m: Disney) -> Self {
        Self {
            base_color: m.base_color,
            subsurface: m.subsurface,
            metallic: m.metallic,
            specular: m.specular,
            specular_tint: m.specular_tint,
            roughness: m.roughness,
            sheen: m.sheen,
            sheen_tint: m.sheen_tint,
            clearcoat: m.clearcoat,
            clearcoat_gloss: m.clearcoat_gloss,
        }
    }
}

impl From<Params<f32>> for Disney {
    #[inline]
    fn from(p: Params<f32>) -> Self {
        Self {
            base_color: p.base_color,
            subsurface: p.subsurface,
            metallic: p.metallic,
            specular: p.specular,
            specular_tint: p.specular_tint,
            roughness: p.roughness,
            sheen: p.sheen,
            sheen_tint: p.sheen_tint,
            clearcoat: p.clearcoat,
            clearcoat_gloss: p.clearcoat_gloss,
        }
    }
}

// Importance sampling (see the module docs).

impl Disney {
    /// GGX α of the primary specular lobe (as in [`Disney::eval`]).
    #[inline]
    fn alpha(&self) -> f32 {
        (self.roughness * self.roughness).max(ALPHA_MIN)
    }

    /// GTR1 α of the clearcoat lobe (as in [`Disney::eval`]).
    #[inline]
    fn coat_alpha(&self) -> f32 {
        crate::math::lerp(0.1, 0.001, self.clearcoat_gloss)
    }

    /// Lobe probabilities `[diffuse, specular, clearcoat]` from the lobes' weights in [`Disney::eval`]:
    /// `(1 - metallic) (lum(C) + sheen)`, `lum(lerp(Cspec0, 1, F(θo)))`, `clearcoat / 4 · lerp(0.04, 1,
    /// F(θo))`.
    #[inline]
    fn lobe_probabilities(&self, wo: Vec3) -> [f32; 3] {
        let c = self.base_color;
        let l = 0.3 * c[0] + 0.6 * c[1] + 0.1 * c[2];
        let tint = if l > 0.0 { c.map(|x| x / l) } else { [1.0; 3] };
        let fw = microfacet::schlick_weight(wo.z);
        let spec = [0, 1, 2].map(|k| {
            let s0 = crate::math::lerp(
                self.specular * 0.08 * crate::math::lerp(1.0, tint[k], self.specular_tint),
                c[k],
                self.metallic,
            );
            crate::math::lerp(s0, 1.0, fw)
        });
        normalise([
            (1.0 - self.metallic) * (lum(c) + self.sheen),
            lum(spec),
            0.25 * self.clearcoat * crate::math::lerp(0.04, 1.0, fw),
        ])
    }
}

impl Brdf for Disney {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Disney::eval(self, wi, wo)
    }

    /// Mixture of the cosine lobe, GGX visible normals and GTR1 half vectors, chosen by their weights.
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let p = self.lobe_probabilities(wo);
        let wi = match choose(&p, u[2]) {
            0 => square_to_cosine_hemisphere([u[0], u[1]]),
            1 => reflect_about(wo, sample_ggx_vndf(wo, self.alpha(), [u[0], u[1]])),
            _ => reflect_about(wo, sample_gtr1(self.coat_alpha(), [u[0], u[1]])),
        };
        finish(wi, self.pdf(wi, wo), self.eval(wi, wo))
    }

    /// Density of `sample` at `wi`.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((wi, wo)) = crate::angles::upper_hemisphere_pair(wi, wo) else {
            return 0.0;
        };
        let p = self.lobe_probabilities(wo);
        let Some((h, oh)) = half_of(wo, wi) else {
            return p[0] * cosine_hemisphere_pdf(wi);
        };
        let alpha = self.alpha();
        let coat_alpha = self.coat_alpha();
        let spec = ggx_vndf_pdf(wo, h, alpha) / (4.0 * oh);
        let coat = half_vector_pdf(wo, wi, |c, s2| microfacet::gtr1_d(c, s2, coat_alpha));
        p[0] * cosine_hemisphere_pdf(wi) + p[1] * spec + p[2] * coat
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        true
    }
}
