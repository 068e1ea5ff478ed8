//! Built-in procedural "measured-like" ground-truth materials: analytic BRDFs that behave like measured
//! ones (several lobes, coloured Fresnel, layering, back-scatter) and that none of the four parametric
//! models of Sec. 4.1.1 represents exactly, so fitting them shows the same model gap a MERL material does,
//! without needing any data file.
//!
//! All are reciprocal (every term is a symmetric function of the pair, built from
//! [`HalfGeometry`]), finite, non-negative and
//! energy conserving (directional albedo ≤ 1 for every incidence; the integration tests check it by Monte
//! Carlo).
//!
//! | id | what | why no parametric model fits it exactly |
//! |---|---|---|
//! | `two-lobe-metal` | gold-like metal: two GGX lobes (α 0.06 and 0.3) with different tints, conductor Fresnel | one Beckmann/GTR2 lobe each in TS and Disney; Schlick, not a complex-index Fresnel |
//! | `clear-coat` | red diffuse base under a glossy dielectric coat (η = 1.5) with coloured absorption | Disney's coat is GTR1 with fixed masking over an un-attenuated base; FMBRDF has no absorption tint |
//! | `velvet` | dark blue fabric: diffuse + Charlie sheen (grazing) + retro-reflective lobe | no model has a back-scatter lobe around `wi`, nor the sin^(1/α) sheen distribution |

use crate::brdf::{Brdf, BsdfSample};
use crate::math::{sanitize, INV_PI};
use crate::microfacet::{self, HalfGeometry};
use crate::sampling::{choose, finish, lum, normalise, valid_wo};
use crate::warp::{
    cosine_hemisphere_pdf, ggx_vndf_pdf, half_of, phong_lobe_pdf, reflect_about, sample_ggx_vndf, sample_phong_lobe,
    square_to_cosine_hemisphere,
};
use crate::{Rgb, Vec3, BLACK};

/// A built-in procedural material.
///
/// ```
/// use nbrdf::{builtin::Builtin, Vec3};
/// for m in Builtin::ALL {
///     assert_eq!(Builtin::from_id(m.id()), Some(m));
///     let (wi, wo) = (Vec3::new(0.2, 0.3, 0.9), Vec3::new(-0.4, 0.1, 0.7));
///     let (a, b) = (m.eval(wi, wo), m.eval(wo, wi));
///     assert!((0..3).all(|c| (a[c] - b[c]).abs() <= 1e-6 * a[c].max(1e-6)));
/// }
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Builtin {
    /// Gold-like metal with two GGX lobes of different roughness and tint and exact conductor Fresnel.
    TwoLobeMetal,
    /// Glossy clear coat over a red diffuse base; transmitted light is absorbed on its way through.
    ClearCoat,
    /// Velvet-like fabric with a grazing sheen and a retro-reflective lobe.
    Velvet,
}

/// Complex refractive index of gold at the R, G, B wavelengths (≈ 650, 550, 450 nm; Johnson & Christy
/// 1972, as tabulated in pbrt's `Au` spectrum).
pub(crate) const GOLD_ETA: Rgb = [0.143, 0.374, 1.442];
/// Extinction coefficient of gold at R, G, B (same source).
pub(crate) const GOLD_K: Rgb = [3.983, 2.385, 1.603];

/// `two-lobe-metal`: (weight · tint per channel, GGX α) of the sharp and the hazy lobe. The per-channel
/// sums of weight · tint are ≤ 1, so with Fresnel ≤ 1 and single-scattering masking each lobe's albedo,
/// and their sum, stays ≤ 1.
pub(crate) const METAL_LOBES: [(Rgb, f32); 2] = [([0.70, 0.70, 0.70], 0.06), ([0.28, 0.22, 0.14], 0.30)];

/// `clear-coat`: coat GGX α, coat index, base albedo, and optical depth of the coat per channel.
pub(crate) const COAT_ALPHA: f32 = 0.05;
pub(crate) const COAT_ETA: f32 = 1.5;
pub(crate) const COAT_BASE: Rgb = [0.75, 0.10, 0.06];
pub(crate) const COAT_DEPTH: Rgb = [0.02, 0.10, 0.15];

/// `velvet`: diffuse albedo, sheen colour and width, retro-reflection weight and exponent.
pub(crate) const VELVET_DIFFUSE: Rgb = [0.04, 0.05, 0.22];
pub(crate) const VELVET_SHEEN: Rgb = [0.35, 0.38, 0.60];
pub(crate) const VELVET_SHEEN_ALPHA: f32 = 0.35;
pub(crate) const VELVET_RETRO: Rgb = [0.10, 0.10, 0.16];
pub(crate) const VELVET_RETRO_N: f32 = 8.0;

impl Builtin {
    /// Every built-in material.
    pub const ALL: [Builtin; 3] = [Builtin::TwoLobeMetal, Builtin::ClearCoat, Builtin::Velvet];

    /// Stable identifier for files and command lines.
    pub const fn id(self) -> &'static str {
        match self {
            Builtin::TwoLobeMetal => "two-lobe-metal",
            Builtin::ClearCoat => "clear-coat",
            Builtin::Velvet => "velvet",
        }
    }

    /// The material whose [`id`](Self::id) is `id`.
    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.id() == id)
    }

    /// The BRDF value (1/sr, linear RGB); 0 below the horizon or for degenerate input.
    #[inline]
    pub fn eval(self, wi: Vec3, wo: Vec3) -> Rgb {
        let Some(g) = HalfGeometry::new(wi, wo) else {
            return BLACK;
        };
        sanitize(match self {
            Builtin::TwoLobeMetal => two_lobe_metal(&g),
            Builtin::ClearCoat => clear_coat(&g),
            Builtin::Velvet => velvet(&g),
        })
    }
}

/// `Σ_k w_k t_k D_GGX(h; α_k) F_conductor(cos θd; η, k) G_Smith(α_k) / (4 cos θi cos θo)` (Walter et al.
/// 2007, Eqs. 20, 33, 34; Fresnel of gold per channel).
#[inline]
fn two_lobe_metal(g: &HalfGeometry) -> Rgb {
    let f = [0, 1, 2].map(|c| microfacet::fresnel_conductor(g.cos_d, GOLD_ETA[c], GOLD_K[c]));
    let mut out = [0.0; 3];
    for (tint, alpha) in METAL_LOBES {
        let lobe = microfacet::ggx_d(g.cos_h, g.sin2_h, alpha)
            * (microfacet::smith_ggx_g1_over_2cos(g.cos_i, alpha)
                * microfacet::smith_ggx_g1_over_2cos(g.cos_o, alpha));
        for c in 0..3 {
            out[c] += tint[c] * lobe * f[c];
        }
    }
    out
}

/// `cos θt` of light refracted through the coat (Snell: `sin θt = sin θ / η`).
#[inline]
fn cos_refracted(cos: f32, eta: f32) -> f32 {
    libm::sqrtf((1.0 - (1.0 - cos * cos) / (eta * eta)).max(0.0))
}

/// Coat: `F(cos θd) D G / (4 cos θi cos θo)` (GGX, Smith, dielectric Fresnel). Base, single-bounce:
/// `(1 - F(cos θi)) (1 - F(cos θo)) · exp(-τ (1/cos θti + 1/cos θto)) · ρ / π`, the Fresnel transmissions
/// in and out of the coat, Beer-Lambert absorption along the refracted paths (θt by Snell) and a
/// Lambertian base (the two-layer model of Weidlich & Wilkie 2007, without internal re-reflection, which
/// only lowers the energy).
#[inline]
fn clear_coat(g: &HalfGeometry) -> Rgb {
    let coat = microfacet::fresnel_dielectric(g.cos_d, COAT_ETA)
        * microfacet::ggx_d(g.cos_h, g.sin2_h, COAT_ALPHA)
        * (microfacet::smith_ggx_g1_over_2cos(g.cos_i, COAT_ALPHA)
            * microfacet::smith_ggx_g1_over_2cos(g.cos_o, COAT_ALPHA));
    let t = (1.0 - microfacet::fresnel_dielectric(g.cos_i, COAT_ETA))
        * (1.0 - microfacet::fresnel_dielectric(g.cos_o, COAT_ETA));
    let path = 1.0 / cos_refracted(g.cos_i, COAT_ETA) + 1.0 / cos_refracted(g.cos_o, COAT_ETA);
    [0, 1, 2].map(|c| coat + t * libm::expf(-COAT_DEPTH[c] * path) * COAT_BASE[c] * INV_PI)
}

/// `ρ/π + c_s D_charlie(h) V(wi, wo) + k_r (n + 2)/(2π) max(0, wi·wo)^n`:
/// - Charlie sheen distribution (Estevez & Kulla 2017, "Production Friendly Microfacet Sheen BRDF"):
///   `D = (2 + 1/α) sin^(1/α) θh / (2π)`, with the cloth visibility of Neubelt & Pettineo 2013 ("Crafting
///   a Next-Gen Material Pipeline for The Order: 1886"), `V = 1 / (4 (cos θi + cos θo - cos θi cos θo))`;
/// - a Phong-normalised lobe around the incident direction (retro-reflection of fabric fibres).
#[inline]
fn velvet(g: &HalfGeometry) -> Rgb {
    let inv_a = 1.0 / VELVET_SHEEN_ALPHA;
    let d = (2.0 + inv_a) * libm::powf(g.sin2_h, 0.5 * inv_a) * (0.5 * INV_PI);
    let v = 1.0 / (4.0 * (g.cos_i + g.cos_o - g.cos_i * g.cos_o));
    let sheen = d * v;
    // wi·wo = 2 cos²θd - 1 (|wi + wo| = 2 cos θd), exactly symmetric under the swap.
    let cos_r = 2.0 * g.cos_d * g.cos_d - 1.0;
    let retro = if cos_r > 0.0 {
        (VELVET_RETRO_N + 2.0) * (0.5 * INV_PI) * libm::powf(cos_r.min(1.0), VELVET_RETRO_N)
    } else {
        0.0
    };
    [0, 1, 2].map(|c| VELVET_DIFFUSE[c] * INV_PI + VELVET_SHEEN[c] * sheen + VELVET_RETRO[c] * retro)
}

// Sampling: a mixture of the lobes in `crate::sampling`'s table, each drawn by its `crate::warp`.
impl Builtin {
    /// Lobe probabilities of the built-in material at `wo` (up to two lobes; see the module table).
    #[inline]
    fn lobe_probabilities(self, wo: Vec3) -> [f32; 2] {
        match self {
            Builtin::TwoLobeMetal => normalise(METAL_LOBES.map(|(tint, _)| lum(tint))),
            Builtin::ClearCoat => {
                let f = microfacet::fresnel_dielectric(wo.z, COAT_ETA);
                normalise([lum(COAT_BASE) * (1.0 - f), f])
            }
            // The sheen is broad and grazing: the cosine lobe carries it along with the diffuse part.
            Builtin::Velvet => normalise([
                lum(VELVET_DIFFUSE) + 0.5 * lum(VELVET_SHEEN),
                lum(VELVET_RETRO),
            ]),
        }
    }
}

impl Brdf for Builtin {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Builtin::eval(*self, wi, wo)
    }

    /// Samples `wi` for the given `wo` (lobes in the module table); `u` is three uniform numbers in
    /// [0, 1).
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wo = valid_wo(wo)?;
        let p = self.lobe_probabilities(wo);
        let k = choose(&p, u[2]);
        let uv = [u[0], u[1]];
        let wi = match self {
            Builtin::TwoLobeMetal => reflect_about(wo, sample_ggx_vndf(wo, METAL_LOBES[k].1, uv)),
            Builtin::ClearCoat if k == 0 => square_to_cosine_hemisphere(uv),
            Builtin::ClearCoat => reflect_about(wo, sample_ggx_vndf(wo, COAT_ALPHA, uv)),
            Builtin::Velvet if k == 0 => square_to_cosine_hemisphere(uv),
            Builtin::Velvet => sample_phong_lobe(wo, VELVET_RETRO_N, uv),
        };
        finish(wi, self.pdf(wi, wo), self.eval(wi, wo))
    }

    /// Density of `sample` at `wi` per unit solid angle.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some((wi, wo)) = crate::angles::upper_hemisphere_pair(wi, wo) else {
            return 0.0;
        };
        let Some((h, oh)) = half_of(wo, wi) else {
            return 0.0;
        };
        let p = self.lobe_probabilities(wo);
        let vndf = |alpha: f32| ggx_vndf_pdf(wo, h, alpha) / (4.0 * oh);
        let pdf = match self {
            Builtin::TwoLobeMetal => {
                p[0] * vndf(METAL_LOBES[0].1) + p[1] * vndf(METAL_LOBES[1].1)
            }
            Builtin::ClearCoat => p[0] * cosine_hemisphere_pdf(wi) + p[1] * vndf(COAT_ALPHA),
            Builtin::Velvet => {
                p[0] * cosine_hemisphere_pdf(wi) + p[1] * phong_lobe_pdf(wi.dot(wo), VELVET_RETRO_N)
            }
        };
        if pdf.is_finite() && pdf > 0.0 {
            pdf
        } else {
            0.0
        }
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        true
    }
}
