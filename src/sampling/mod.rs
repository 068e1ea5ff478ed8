//! Importance sampling of the parametric models (core, no_std): warps from the unit
//! square to directions, the pdfs of those warps, and per model a `sample`/`pdf` pair that renderers use
//! for path tracing.
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
//! The built-ins' `sample` and `pdf` live beside their formulas in `builtin.rs`; the parametric models'
//! are here until `parametric::microfacet` moves below both modules (docs/architecture.md).
//!
//! The FMBRDF's generalised Gaussian has no closed-form inverse CDF; the Beckmann proposal matches it
//! exactly for β = 2 in the small-angle limit and stays a valid (unbiased, higher-variance) proposal
//! otherwise, because the pdf reported is always the proposal's own.
//!
//! Models without a closed form to sample (neural models, MERL tables, NBRDF-json networks) sample an
//! analytic [`Proxy`] fitted to them ([`proxy`], [`fit_proxy`]) and evaluate the model itself for the
//! weight ([`Model::sample`](crate::Model::sample) for the neural models, [`measured`] for the
//! measured ones); the pdf is the proxy's, so the estimator stays unbiased.

pub mod fit;
pub mod proxy;

pub use fit::fit_proxy;
pub use proxy::{GgxLobe, Proxy};

use crate::math::{safe_sqrt, PI};
use crate::parametric::microfacet::{self, clamp_alpha, ALPHA_MIN};
use crate::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, Phong, TorranceSparrow};
pub use crate::brdf::BsdfSample;
use crate::brdf::Brdf;
use crate::{Rgb, Vec3};

/// 1/π as `f32`.
const INV_PI: f32 = crate::math::INV_PI;

// -------------------------------------------------------------------------------------------------
// Warps

/// A point of the unit disk from `u ∈ [0,1)²` by Shirley & Chiu's concentric map (1997), which keeps
/// strata compact.
#[inline]
pub fn square_to_disk_concentric(u: [f32; 2]) -> (f32, f32) {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) =
        if a.abs() > b.abs() { (a, 0.25 * PI * (b / a)) } else { (b, 0.5 * PI - 0.25 * PI * (a / b)) };
    let (s, c) = libm::sincosf(phi);
    (r * c, r * s)
}

/// Cosine-weighted direction on the upper hemisphere (Malley's method: lift a uniform disk point).
///
/// ```
/// use nbrdf::sampling::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
/// let w = square_to_cosine_hemisphere([0.3, 0.8]);
/// assert!((w.length() - 1.0).abs() < 1e-6 && w.z > 0.0);
/// assert!((cosine_hemisphere_pdf(w) - w.z / core::f32::consts::PI).abs() < 1e-7);
/// ```
#[inline]
pub fn square_to_cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let (x, y) = square_to_disk_concentric(u);
    // Keep z strictly positive so the direction passes the upper-hemisphere gate.
    let z = safe_sqrt(1.0 - x * x - y * y).max(1e-7);
    Vec3::new(x, y, z)
}

/// Density of [`square_to_cosine_hemisphere`]: `cos θ / π` above the horizon, else 0.
#[inline]
pub fn cosine_hemisphere_pdf(w: Vec3) -> f32 {
    if w.z > 0.0 {
        w.z * INV_PI
    } else {
        0.0
    }
}

/// An orthonormal basis `(t, b)` completing the unit vector `n` (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited", Listing 3).
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Direction at polar angle `acos(cos_t)` and azimuth `phi` about the unit axis `n`.
#[inline]
fn around(n: Vec3, cos_t: f32, phi: f32) -> Vec3 {
    let (t, b) = orthonormal_basis(n);
    let sin_t = safe_sqrt(1.0 - cos_t * cos_t);
    let (s, c) = libm::sincosf(phi);
    t * (sin_t * c) + b * (sin_t * s) + n * cos_t
}

/// GGX visible-normal sampling (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", Listing
/// 1) for an isotropic `alpha`: a microfacet normal `h` with density [`ggx_vndf_pdf`]. `wo.z > 0`.
#[inline]
pub fn sample_ggx_vndf(wo: Vec3, alpha: f32, u: [f32; 2]) -> Vec3 {
    // Stretch the view vector to the hemisphere configuration (α = 1).
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / libm::sqrtf(lensq) } else { Vec3::X };
    let t2 = vh.cross(t1);
    // A uniform disk point, squashed onto the visible half of the projected hemisphere.
    let r = libm::sqrtf(u[0]);
    let (s, c) = libm::sincosf(2.0 * PI * u[1]);
    let p1 = r * c;
    let sh = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - sh) * safe_sqrt(1.0 - p1 * p1) + sh * (r * s);
    let nh = t1 * p1 + t2 * p2 + vh * safe_sqrt(1.0 - p1 * p1 - p2 * p2);
    // Unstretch.
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-7)).normalize()
}

/// Density of [`sample_ggx_vndf`] over half vectors: `D_wo(h) = G1(wo) max(0, wo·h) D(h) / cos θo`
/// (Heitz 2018, Sec. 2).
#[inline]
pub fn ggx_vndf_pdf(wo: Vec3, h: Vec3, alpha: f32) -> f32 {
    let oh = wo.dot(h);
    if !(oh > 0.0 && wo.z > 0.0 && h.z > 0.0) {
        return 0.0;
    }
    let sin2_h = h.x * h.x + h.y * h.y;
    microfacet::smith_ggx_g1(wo.z, alpha) * oh * microfacet::ggx_d(h.z, sin2_h, alpha) / wo.z
}

/// A Beckmann half vector with density `D(h) cos θh` (Walter et al. 2007, Eq. 28:
/// `tan²θh = -α² ln(1 - u)`).
#[inline]
pub fn sample_beckmann(alpha: f32, u: [f32; 2]) -> Vec3 {
    let tan2 = -alpha * alpha * libm::logf(1.0 - u[0]);
    let cos_t = 1.0 / libm::sqrtf(1.0 + tan2);
    around(Vec3::Z, cos_t.max(1e-7), 2.0 * PI * u[1])
}

/// A GTR1 half vector with density `D(h) cos θh` (Burley 2012, Appendix B:
/// `cos²θh = (1 - α^(2(1-u))) / (1 - α²)`).
#[inline]
pub fn sample_gtr1(alpha: f32, u: [f32; 2]) -> Vec3 {
    let a2 = alpha * alpha;
    let cos2 = if alpha >= 1.0 { 1.0 - u[0] } else { (1.0 - libm::powf(a2, 1.0 - u[0])) / (1.0 - a2) };
    around(Vec3::Z, safe_sqrt(cos2).max(1e-7), 2.0 * PI * u[1])
}

/// A direction with density `(n + 1)/(2π) cos^n α` about the unit `axis` (Lafortune & Willems 1994,
/// sampling of the modified Phong lobe: `cos α = u^(1/(n+1))`); may fall below the horizon.
#[inline]
pub fn sample_phong_lobe(axis: Vec3, n: f32, u: [f32; 2]) -> Vec3 {
    let cos_a = libm::powf(u[0], 1.0 / (n + 1.0));
    around(axis, cos_a, 2.0 * PI * u[1])
}

/// Density of [`sample_phong_lobe`].
#[inline]
pub fn phong_lobe_pdf(cos_a: f32, n: f32) -> f32 {
    if cos_a > 0.0 {
        (n + 1.0) * (0.5 * INV_PI) * libm::powf(cos_a.min(1.0), n)
    } else {
        0.0
    }
}

/// Reflects `wo` about the half vector into `wi` (`2 (wo·h) h - wo`).
#[inline]
pub(crate) fn reflect_about(wo: Vec3, h: Vec3) -> Vec3 {
    h * (2.0 * wo.dot(h)) - wo
}

/// `wo` normalised if it is finite and above the horizon, else `None`.
#[inline]
pub(crate) fn valid_wo(wo: Vec3) -> Option<Vec3> {
    let wo = crate::angles::unit(wo)?;
    (wo.z > 0.0).then_some(wo)
}

/// The half vector of a valid pair and `wo·h`, or `None`.
#[inline]
pub(crate) fn half_of(wo: Vec3, wi: Vec3) -> Option<(Vec3, f32)> {
    let (wi, wo) = crate::angles::upper_hemisphere_pair(wi, wo)?;
    let h = crate::angles::unit(wi + wo)?;
    let oh = wo.dot(h);
    (oh > 0.0).then_some((h, oh))
}

/// Density over `wi` of half vectors drawn with density `D(h) cos θh`, reflected about `h`:
/// `D(h) cos θh / (4 wo·h)` (the reflection Jacobian, Walter et al. 2007, Eq. 14).
#[inline]
fn half_vector_pdf(wo: Vec3, wi: Vec3, d: impl Fn(f32, f32) -> f32) -> f32 {
    match half_of(wo, wi) {
        Some((h, oh)) => d(h.z, h.x * h.x + h.y * h.y) * h.z / (4.0 * oh),
        None => 0.0,
    }
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

// -------------------------------------------------------------------------------------------------
// Per model

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
fn sample_cosine_beckmann(p: [f32; 2], alpha: f32, u: [f32; 3], wo: Vec3) -> Vec3 {
    match choose(&p, u[2]) {
        0 => square_to_cosine_hemisphere([u[0], u[1]]),
        _ => reflect_about(wo, sample_beckmann(clamp_alpha(alpha), [u[0], u[1]])),
    }
}

/// Density of [`sample_cosine_beckmann`] at `wi` (both directions valid and unit).
#[inline]
fn pdf_cosine_beckmann(p: [f32; 2], alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    let alpha = clamp_alpha(alpha);
    p[0] * cosine_hemisphere_pdf(wi) + p[1] * half_vector_pdf(wo, wi, |c, s2| microfacet::beckmann_d(c, s2, alpha))
}

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

impl Brdf for Parametric {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        Parametric::eval(self, wi, wo)
    }

    /// Samples `wi` for the given `wo` (see the model's `sample`); `u` is three uniform numbers in [0, 1).
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        match self {
            Parametric::Lambert(m) => m.sample(wo, u),
            Parametric::Phong(m) => m.sample(wo, u),
            Parametric::TorranceSparrow(m) => m.sample(wo, u),
            Parametric::FresnelMicrofacet(m) => m.sample(wo, u),
            Parametric::Disney(m) => m.sample(wo, u),
        }
    }

    /// Density of `sample` at `wi` per unit solid angle.
    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let p = match self {
            Parametric::Lambert(m) => m.pdf(wi, wo),
            Parametric::Phong(m) => m.pdf(wi, wo),
            Parametric::TorranceSparrow(m) => m.pdf(wi, wo),
            Parametric::FresnelMicrofacet(m) => m.pdf(wi, wo),
            Parametric::Disney(m) => m.pdf(wi, wo),
        };
        if p.is_finite() && p > 0.0 {
            p
        } else {
            0.0
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
    fn orthonormal_basis_is_orthonormal() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.8, 0.1).normalize(), Vec3::X] {
            let (t, b) = orthonormal_basis(n);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn vndf_at_normal_view_is_the_ndf_cosine() {
        // wo = n: every facet is visible with weight cos θh, so D_wo(h) = D(h) cos θh (G1(n) = 1).
        let h = Vec3::new(0.2, 0.1, 0.9).normalize();
        let a = 0.4;
        let want = microfacet::ggx_d(h.z, h.x * h.x + h.y * h.y, a) * h.z;
        assert!((ggx_vndf_pdf(Vec3::Z, h, a) - want).abs() < 1e-5 * want);
    }

    #[test]
    fn lambert_weight_is_the_albedo() {
        let m = Lambert { kd: [0.2, 0.5, 0.9] };
        let s = m.sample(Vec3::new(0.1, 0.2, 0.9), [0.3, 0.6, 0.1]).unwrap();
        for c in 0..3 {
            assert!((s.weight[c] - m.kd[c]).abs() < 1e-5);
        }
    }
}
