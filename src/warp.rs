//! Warps from the unit square to directions and their densities (core, no_std): the cosine hemisphere,
//! GGX visible normals, Beckmann and GTR1 half vectors, the Phong lobe, and the reflection about a half
//! vector with its Jacobian. Every sampler builds on them: each parametric model's and built-in
//! material's `sample` / `pdf` beside its formula, and the proxy in `sampling`. The module sits below
//! both `parametric` and `sampling` and takes its distributions from `microfacet`.
//!
//! Each warp maps `u ∈ [0,1)²` to a direction (or a half vector) in the local frame, normal on +z; its
//! density is per unit solid angle. A warp about an axis other than the normal (the Phong lobe) may
//! propose a direction below the horizon; the caller drops it.

use crate::math::{safe_sqrt, PI};
use crate::microfacet;
use crate::Vec3;

/// 1/π as `f32`.
const INV_PI: f32 = crate::math::INV_PI;

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
/// use nbrdf::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
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
pub(crate) fn half_vector_pdf(wo: Vec3, wi: Vec3, d: impl Fn(f32, f32) -> f32) -> f32 {
    match half_of(wo, wi) {
        Some((h, oh)) => d(h.z, h.x * h.x + h.y * h.y) * h.z / (4.0 * oh),
        None => 0.0,
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
}
