//! Shared microfacet pieces: the half-vector geometry of a direction pair, normal distributions (Beckmann,
//! GGX/GTR2, GTR1), shadowing terms (V-cavity, separable Smith GGX) and Fresnel factors (Schlick,
//! unpolarised dielectric, unpolarised conductor). Every parametric model and built-in material takes its
//! D, G and F from here, so a formula is written (and cited) once. The module sits below both
//! `parametric` and `sampling` (the warps' densities take their D and G from here too).
//!
//! # Reciprocity
//! [`HalfGeometry`] derives every cosine from quantities that are exactly symmetric under the swap of
//! `wi` and `wo`: `s = wi + wo` (IEEE addition commutes), `|s|` and the per-vector `z` components.
//! In particular `cos θd = (wi·h) = (wo·h)` is taken as `|wi + wo| / 2` instead of either dot product, so
//! the two orders see the same bits and a model built from these pieces is reciprocal to rounding of
//! products only (`a·b = b·a` exactly).
//!
//! # Extreme regimes
//! Roughness is clamped to [`ALPHA_MIN`], and the distributions are written with `sin²θh` taken from the
//! half vector's tangential components rather than `1 - cos²θh`, so a near-mirror lobe (α = 1e-3) does not
//! lose its peak to cancellation.
//!
//! # Differentiable parameters
//! The terms that take a material parameter (roughness, F0, η) are written once, generic over
//! `Real` (`real.rs`) in that parameter (`*_generic`), so the parametric models' gradients
//! ([`Parametric::eval_grad`](crate::parametric::Parametric::eval_grad)) differentiate the very
//! formula they evaluate; the `f32` functions are that formula at `f32`, the same bits.

use crate::real::{self, Real};
use crate::angles::upper_hemisphere_pair;
use crate::math::{safe_sqrt, INV_PI};
use crate::Vec3;

/// Smallest roughness α any model uses: `D(θh = 0) = 1/(π α²) ≈ 3.2e5` stays finite in `f32`.
/// Disney uses the same floor (`max(.001, roughness²)`, Burley 2012, BRDF Explorer `disney.brdf`).
pub const ALPHA_MIN: f32 = 1e-3;

/// The cosines of a valid direction pair that microfacet models need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfGeometry {
    /// Unit half vector `h = (wi + wo) / |wi + wo|`.
    pub h: Vec3,
    /// `cos θi = wi.z`, in (0, 1].
    pub cos_i: f32,
    /// `cos θo = wo.z`, in (0, 1].
    pub cos_o: f32,
    /// `cos θh = h.z`, in (0, 1].
    pub cos_h: f32,
    /// `sin² θh = h.x² + h.y²` (accurate near θh = 0, unlike `1 - cos²`).
    pub sin2_h: f32,
    /// `cos θd = wi·h = wo·h = |wi + wo| / 2`, in (0, 1].
    pub cos_d: f32,
}

impl HalfGeometry {
    /// The geometry of (`wi`, `wo`), or `None` unless both are finite and strictly above the horizon
    /// (the gate of [`upper_hemisphere_pair`]). Unnormalised input is normalised.
    ///
    /// ```
    /// use nbrdf::{microfacet::HalfGeometry, Vec3};
    /// let g = HalfGeometry::new(Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8)).unwrap();
    /// assert!((g.cos_h - 1.0).abs() < 1e-6 && (g.cos_d - 0.8).abs() < 1e-6);
    /// assert!(HalfGeometry::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z).is_none());
    /// ```
    #[inline]
    pub fn new(wi: Vec3, wo: Vec3) -> Option<Self> {
        let (wi, wo) = upper_hemisphere_pair(wi, wo)?;
        let s = wi + wo;
        let s_len = libm::sqrtf(s.length_squared());
        // Both z > 0, so s.z > 0 and |s| > 0; the check only guards denormal underflow.
        if s_len <= 0.0 {
            return None;
        }
        let h = s / s_len;
        Some(Self {
            h,
            cos_i: wi.z,
            cos_o: wo.z,
            cos_h: h.z,
            sin2_h: h.x * h.x + h.y * h.y,
            cos_d: (0.5 * s_len).min(1.0),
        })
    }
}

/// Clamps a roughness α into [[`ALPHA_MIN`], 1]; NaN becomes 1 (the most forgiving lobe).
#[inline]
pub fn clamp_alpha(alpha: f32) -> f32 {
    clamp_alpha_generic(alpha)
}

/// [`clamp_alpha`] in any [`Real`] (derivative 0 where clamped).
#[inline]
pub(crate) fn clamp_alpha_generic<T: Real>(alpha: T) -> T {
    if alpha.value().is_nan() {
        T::from_f32(1.0)
    } else {
        alpha.clamp(ALPHA_MIN, 1.0)
    }
}

/// Beckmann NDF (Beckmann & Spizzichino 1963; Cook & Torrance 1982; Walter et al. 2007, Eq. 25):
/// `D(h) = exp(-tan²θh / α²) / (π α² cos⁴θh)`, normalised so `∫ D cos θh dω = 1`.
/// `alpha` is the RMS slope `m`.
#[inline]
pub fn beckmann_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    beckmann_d_generic(cos_h, sin2_h, alpha)
}

/// [`beckmann_d`] in any [`Real`] roughness.
#[inline]
pub(crate) fn beckmann_d_generic<T: Real>(cos_h: f32, sin2_h: f32, alpha: T) -> T {
    let c2 = cos_h * cos_h;
    let a2 = alpha * alpha;
    let c4 = c2 * c2;
    if c4 <= 0.0 {
        return T::from_f32(0.0);
    }
    (T::from_f32(-sin2_h) / (a2 * c2)).exp() / (a2 * core::f32::consts::PI * c4)
}

/// GGX / Trowbridge-Reitz NDF, Disney's GTR2 (Walter et al. 2007, Eq. 33; Burley 2012's GTR with γ = 2):
/// `D(h) = α² / (π (α² cos²θh + sin²θh)²)`.
#[inline]
pub fn ggx_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    ggx_d_generic(cos_h, sin2_h, alpha)
}

/// [`ggx_d`] in any [`Real`] roughness.
#[inline]
pub(crate) fn ggx_d_generic<T: Real>(cos_h: f32, sin2_h: f32, alpha: T) -> T {
    let a2 = alpha * alpha;
    let t = a2 * cos_h * cos_h + sin2_h;
    a2 * INV_PI / (t * t)
}

/// Disney's GTR1 NDF for the clearcoat (Burley 2012's GTR with γ = 1, normalised as in BRDF Explorer's
/// `disney.brdf`): `D(h) = (α² - 1) / (π ln(α²) (α² cos²θh + sin²θh))`, and `1/π` for α ≥ 1.
#[inline]
pub fn gtr1_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    gtr1_d_generic(cos_h, sin2_h, alpha)
}

/// [`gtr1_d`] in any [`Real`] roughness.
#[inline]
pub(crate) fn gtr1_d_generic<T: Real>(cos_h: f32, sin2_h: f32, alpha: T) -> T {
    if alpha.value() >= 1.0 {
        return T::from_f32(INV_PI);
    }
    let a2 = alpha * alpha;
    let t = a2 * cos_h * cos_h + sin2_h;
    (a2 - 1.0) * INV_PI / (a2.ln() * t)
}

/// Separable Smith masking for GGX divided by `2 cos θ` (Walter et al. 2007, Eq. 34; BRDF Explorer's
/// `smithG_GGX`): `G1(v) / (2 cos θv) = 1 / (cos θv + sqrt(α² sin²θv + cos²θv))`. The product of two such
/// factors is `G / (4 cos θi cos θo)`, the whole microfacet denominator, finite at grazing angles.
#[inline]
pub fn smith_ggx_g1_over_2cos(cos_v: f32, alpha: f32) -> f32 {
    smith_ggx_g1_over_2cos_generic(cos_v, alpha)
}

/// [`smith_ggx_g1_over_2cos`] in any [`Real`] roughness.
#[inline]
pub(crate) fn smith_ggx_g1_over_2cos_generic<T: Real>(cos_v: f32, alpha: T) -> T {
    let c2 = cos_v * cos_v;
    T::from_f32(1.0) / (real::safe_sqrt(alpha * alpha * (1.0 - c2) + c2) + cos_v)
}

/// Smith masking `G1(v)` for GGX (Walter et al. 2007, Eq. 34): `2 cos θv / (cos θv + sqrt(α² sin²θv +
/// cos²θv))`; the visible-normal sampler's weight uses it.
#[inline]
pub fn smith_ggx_g1(cos_v: f32, alpha: f32) -> f32 {
    2.0 * cos_v * smith_ggx_g1_over_2cos(cos_v, alpha)
}

/// V-cavity shadowing-masking of Torrance & Sparrow (1967) in the form of Cook & Torrance (1982),
/// divided by the microfacet denominator: `G / (4 cos θi cos θo)` with
/// `G = min(1, 2 cos θh cos θo / cos θd, 2 cos θh cos θi / cos θd)`.
///
/// Each branch is divided through separately (`min(1/(4 ci co), cos θh/(2 cos θd ci), cos θh/(2 cos θd
/// co))`), which is the same value but stays finite when `ci co` underflows at grazing angles.
#[inline]
pub fn v_cavity_g_over_4cos(g: &HalfGeometry) -> f32 {
    let a = 1.0 / (4.0 * g.cos_i * g.cos_o);
    let k = g.cos_h / (2.0 * g.cos_d);
    a.min(k / g.cos_i).min(k / g.cos_o)
}

/// Schlick's weight `(1 - cos θ)^5` (Schlick 1994, "An Inexpensive BRDF Model for Physically-based Rendering"), clamped to [0, 1].
#[inline]
pub fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Schlick's Fresnel approximation (Schlick 1994): `F = F0 + (1 - F0)(1 - cos θd)^5`.
#[inline]
pub fn fresnel_schlick(f0: f32, cos_d: f32) -> f32 {
    fresnel_schlick_generic(f0, cos_d)
}

/// [`fresnel_schlick`] in any [`Real`] `F0`.
#[inline]
pub(crate) fn fresnel_schlick_generic<T: Real>(f0: T, cos_d: f32) -> T {
    f0 + (T::from_f32(1.0) - f0) * schlick_weight(cos_d)
}

/// Unpolarised Fresnel reflectance of a dielectric interface seen from the outside (relative index
/// `eta = n_inside / n_outside ≥ 1`): the mean of the squared s- and p-amplitude coefficients (Born &
/// Wolf, Sec. 1.5.2; pbrt-v4 `FrDielectric`):
/// `r∥ = (η cos θ - cos θt)/(η cos θ + cos θt)`, `r⊥ = (cos θ - η cos θt)/(cos θ + η cos θt)`,
/// `sin θt = sin θ / η`, `F = (r∥² + r⊥²) / 2`.
///
/// ```
/// use nbrdf::microfacet::fresnel_dielectric;
/// // Normal incidence: ((η - 1)/(η + 1))², 0.04 for glass.
/// assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
/// assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
/// ```
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    fresnel_dielectric_generic(cos_i, eta)
}

/// [`fresnel_dielectric`] in any [`Real`] index of refraction.
#[inline]
pub(crate) fn fresnel_dielectric_generic<T: Real>(cos_i: f32, eta: T) -> T {
    let c = cos_i.clamp(0.0, 1.0);
    let one = T::from_f32(1.0);
    let sin2_t = T::from_f32(1.0 - c * c) / (eta * eta);
    if sin2_t.value() >= 1.0 {
        return one; // total internal reflection (only for η < 1)
    }
    let cos_t = real::safe_sqrt(one - sin2_t);
    let r_par = (eta * c - cos_t) / (eta * c + cos_t);
    let r_perp = (T::from_f32(c) - eta * cos_t) / (eta * cos_t + c);
    let f = (r_par * r_par + r_perp * r_perp) * 0.5;
    if f.value().is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        one
    }
}

/// Unpolarised Fresnel reflectance of a conductor with complex index `eta + i k` (relative to air), exact
/// (pbrt-v3 `FrConductor`, after Born & Wolf): with `a² + b² = sqrt((η² - k² - sin²θ)² + 4η²k²)` and
/// `a = sqrt((a² + b² + η² - k² - sin²θ)/2)`,
/// `Rs = (a²+b² + cos²θ - 2a cos θ)/(a²+b² + cos²θ + 2a cos θ)`,
/// `Rp = Rs (cos²θ (a²+b²) + sin⁴θ - 2a cos θ sin²θ)/(cos²θ (a²+b²) + sin⁴θ + 2a cos θ sin²θ)`,
/// `F = (Rs + Rp) / 2`.
///
/// ```
/// use nbrdf::microfacet::fresnel_conductor;
/// // Normal incidence: ((η - 1)² + k²)/((η + 1)² + k²).
/// let (eta, k) = (0.2, 3.0);
/// let f0 = ((eta - 1.0f32).powi(2) + k * k) / ((eta + 1.0f32).powi(2) + k * k);
/// assert!((fresnel_conductor(1.0, eta, k) - f0).abs() < 1e-5);
/// ```
#[inline]
pub fn fresnel_conductor(cos_i: f32, eta: f32, k: f32) -> f32 {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let eta2 = eta * eta;
    let k2 = k * k;
    let t0 = eta2 - k2 - s2;
    let a2b2 = safe_sqrt(t0 * t0 + 4.0 * eta2 * k2);
    let t1 = a2b2 + c2;
    let a = safe_sqrt(0.5 * (a2b2 + t0));
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + s2 * s2;
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    let f = 0.5 * (rp + rs);
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::PI;

    /// ∫ D(h) cos θh dω_h over the hemisphere by the midpoint rule in θh (isotropic D).
    fn projected_area(d: impl Fn(f32, f32) -> f32) -> f64 {
        let n = 200_000;
        let mut sum = 0.0f64;
        for j in 0..n {
            let th = (j as f64 + 0.5) / n as f64 * core::f64::consts::FRAC_PI_2;
            let (s, c) = (th.sin(), th.cos());
            sum += d(c as f32, (s * s) as f32) as f64 * c * s;
        }
        sum * 2.0 * core::f64::consts::PI * core::f64::consts::FRAC_PI_2 / n as f64
    }

    #[test]
    fn distributions_are_normalised() {
        for alpha in [0.02f32, 0.1, 0.5, 1.0] {
            let b = projected_area(|c, s2| beckmann_d(c, s2, alpha));
            let g = projected_area(|c, s2| ggx_d(c, s2, alpha));
            assert!((b - 1.0).abs() < 2e-3, "Beckmann α={alpha}: {b}");
            assert!((g - 1.0).abs() < 2e-3, "GGX α={alpha}: {g}");
        }
        for alpha in [0.01f32, 0.1, 0.5] {
            let g1 = projected_area(|c, s2| gtr1_d(c, s2, alpha));
            assert!((g1 - 1.0).abs() < 2e-3, "GTR1 α={alpha}: {g1}");
        }
    }

    #[test]
    fn peaks_stay_finite_at_the_roughness_floor() {
        let d = ggx_d(1.0, 0.0, ALPHA_MIN);
        assert!((d - 1.0 / (PI * 1e-6)).abs() / d < 1e-5);
        let b = beckmann_d(1.0, 0.0, ALPHA_MIN);
        assert!((b - 1.0 / (PI * 1e-6)).abs() / b < 1e-5);
        assert!(gtr1_d(1.0, 0.0, ALPHA_MIN).is_finite());
    }

    #[test]
    fn v_cavity_is_one_over_4cos_away_from_grazing() {
        // Mirror configuration at 30°: no shadowing, G = 1.
        let wi = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let wo = Vec3::new(-0.5, 0.0, 0.75f32.sqrt());
        let g = HalfGeometry::new(wi, wo).unwrap();
        assert!((v_cavity_g_over_4cos(&g) - 1.0 / (4.0 * 0.75)).abs() < 1e-6);
    }

    #[test]
    fn conductor_with_zero_k_is_the_dielectric() {
        for c in [0.05f32, 0.3, 0.7, 1.0] {
            assert!((fresnel_conductor(c, 1.5, 0.0) - fresnel_dielectric(c, 1.5)).abs() < 1e-5);
        }
    }
}
