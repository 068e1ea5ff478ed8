//! Importance sampling's shared machinery (core, no_std): the lobe-mixture helpers every BRDF's
//! `sample` / `pdf` uses, and the fitted [`Proxy`] that samples models without a closed form to invert.
//! The warps they draw from are in [`crate::warp`]; each parametric model's sampler is in its own file
//! under `parametric/`, beside its formula, and the built-in materials' in `builtin.rs`.
//!
//! Each model is a mixture of lobes (diffuse: cosine-weighted; specular: a microfacet or Phong lobe). A
//! sample picks one lobe with probability `p_k` (proportional to an estimate of that lobe's albedo at
//! `wo`), draws a direction from it, and reports the **mixture** pdf `Σ_k p_k pdf_k(wi)` (one-sample
//! MIS with the balance heuristic, Veach 1997, Sec. 9.2.4). So `sample` and `pdf` describe exactly the
//! same density, whatever lobe produced the direction, and `weight = f(wi, wo) cos θi / pdf` is an
//! unbiased estimator weight.
//!
//! Conventions: `wo` (toward the viewer) is given, `wi` (toward the light) is sampled; the density is per
//! unit solid angle of `wi`. A lobe may propose a direction below the horizon; that sample is dropped
//! (`None`), so `∫_H pdf = P(sample is Some) ≤ 1`, equal to 1 for the cosine lobe.
//!
//! | model | lobes |
//! |---|---|
//! | Lambert | cosine |
//! | RP (Phong) | cosine + Phong lobe `cos^n α` about the mirror of `wo` (Lafortune & Willems 1994) |
//! | Torrance-Sparrow | cosine + Beckmann `D cos θh` half vectors (Walter et al. 2007, Eq. 28) |
//! | FMBRDF | cosine + Beckmann half vectors of slope α as a proposal for its generalised Gaussian |
//! | Disney | cosine (diffuse, subsurface, sheen) + GGX visible normals (Heitz 2018) + GTR1 clearcoat |
//! | built-in `two-lobe-metal` | GGX visible normals of each lobe |
//! | built-in `clear-coat` | cosine (base) + GGX visible normals (coat) |
//! | built-in `velvet` | cosine (diffuse and sheen) + Phong lobe `cos^n` about `wo` (retro-reflection) |
//!
//! Models without a closed form to sample (neural models, MERL tables, NBRDF-json networks) sample an
//! analytic mixture fitted to them and evaluate the model itself for the weight: a [`ViewProxy`] (one
//! mixture per view angle, [`view`]) where they have one, else the single [`Proxy`] ([`proxy`],
//! [`fit_proxy`]) that model files written before the view table carry ([`Model::sample`](crate::Model::sample) for the neural models, [`measured`](crate::measured)
//! for the measured ones); the pdf is the proxy's, so the estimator stays unbiased.

pub mod fit;
pub mod proxy;
pub mod view;

pub use fit::fit_proxy;
pub use proxy::{GgxLobe, Proxy};
pub use view::{fit_view_proxy, fit_view_proxy_around, ViewProxy, VIEW_NODES};

pub use crate::brdf::BsdfSample;
use crate::{Rgb, Vec3};

/// `wo` normalised if it is finite and above the horizon, else `None`.
#[inline]
pub(crate) fn valid_wo(wo: Vec3) -> Option<Vec3> {
    let wo = crate::angles::unit(wo)?;
    (wo.z > 0.0).then_some(wo)
}

/// Rec. 709-like luminance used only to weigh lobes.
#[inline]
pub(crate) fn lum(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Normalised lobe-selection probabilities; all-zero weights select the first lobe.
#[inline]
pub(crate) fn normalise<const N: usize>(w: [f32; N]) -> [f32; N] {
    let w = w.map(|x| if x.is_finite() && x > 0.0 { x } else { 0.0 });
    let s: f32 = w.iter().sum();
    if s > 0.0 {
        w.map(|x| x / s)
    } else {
        let mut p = [0.0; N];
        p[0] = 1.0;
        p
    }
}

/// Index of the lobe chosen by `u` under probabilities `p`.
#[inline]
pub(crate) fn choose<const N: usize>(p: &[f32; N], u: f32) -> usize {
    let mut acc = 0.0;
    for (k, &pk) in p.iter().enumerate() {
        acc += pk;
        if u < acc {
            return k;
        }
    }
    // Rounding left u ≥ Σ p: take the last lobe with mass.
    p.iter().rposition(|&x| x > 0.0).unwrap_or(0)
}

/// A finished sample: `f cos θi / pdf`, or `None` where the direction is invalid or has no density.
#[inline]
pub(crate) fn finish(wi: Vec3, pdf: f32, f: Rgb) -> Option<BsdfSample> {
    if !(wi.z > 0.0 && wi.is_finite() && pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    let weight = crate::math::sanitize(f.map(|v| v * wi.z / pdf));
    Some(BsdfSample { wi, weight, pdf })
}
