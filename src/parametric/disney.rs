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

use super::microfacet::{self, HalfGeometry, ALPHA_MIN};
use super::raw_at;
use crate::math::{lerp, logit, sanitize, sigmoid, INV_PI};
use crate::{Rgb, Vec3, BLACK};

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
        let s = |i: usize| sigmoid(raw_at(raw, i));
        Self {
            base_color: [s(0), s(1), s(2)],
            subsurface: s(3),
            metallic: s(4),
            specular: s(5),
            specular_tint: s(6),
            roughness: sigmoid(0.5 * raw_at(raw, 7)),
            sheen: s(8),
            sheen_tint: s(9),
            clearcoat: s(10),
            clearcoat_gloss: s(11),
        }
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
        let Some(g) = HalfGeometry::new(wi, wo) else {
            return BLACK;
        };
        let c = self.base_color;
        let lum = 0.3 * c[0] + 0.6 * c[1] + 0.1 * c[2];
        let tint = if lum > 0.0 { c.map(|x| x / lum) } else { [1.0; 3] };

        let fl = microfacet::schlick_weight(g.cos_i);
        let fv = microfacet::schlick_weight(g.cos_o);
        let fh = microfacet::schlick_weight(g.cos_d);
        let r = self.roughness;
        let cd2 = g.cos_d * g.cos_d;

        // Burley diffuse and the Hanrahan-Krueger-like subsurface shape.
        let fd90 = 0.5 + 2.0 * cd2 * r;
        let fd = lerp(1.0, fd90, fl) * lerp(1.0, fd90, fv);
        let fss90 = cd2 * r;
        let fss = lerp(1.0, fss90, fl) * lerp(1.0, fss90, fv);
        let ss = 1.25 * (fss * (1.0 / (g.cos_i + g.cos_o) - 0.5) + 0.5);
        let diffuse = lerp(fd, ss, self.subsurface) * INV_PI;

        // Primary specular: GTR2, separable Smith GGX (the product is G / (4 cos θl cos θv)).
        let alpha = (r * r).max(ALPHA_MIN);
        let ds = microfacet::ggx_d(g.cos_h, g.sin2_h, alpha);
        let gs = microfacet::smith_ggx_g1_over_2cos(g.cos_i, alpha)
            * microfacet::smith_ggx_g1_over_2cos(g.cos_o, alpha);

        // Clearcoat: GTR1, fixed-roughness masking, F0 = 0.04.
        let dr = microfacet::gtr1_d(g.cos_h, g.sin2_h, lerp(0.1, 0.001, self.clearcoat_gloss));
        let fr = lerp(0.04, 1.0, fh);
        let gr = microfacet::smith_ggx_g1_over_2cos(g.cos_i, 0.25)
            * microfacet::smith_ggx_g1_over_2cos(g.cos_o, 0.25);
        let coat = 0.25 * self.clearcoat * gr * fr * dr;

        let m = self.metallic;
        sanitize([0, 1, 2].map(|k| {
            let spec0 = lerp(self.specular * 0.08 * lerp(1.0, tint[k], self.specular_tint), c[k], m);
            let fs = lerp(spec0, 1.0, fh);
            let sheen = fh * self.sheen * lerp(1.0, tint[k], self.sheen_tint);
            (diffuse * c[k] + sheen) * (1.0 - m) + gs * fs * ds + coat
        }))
    }
}
