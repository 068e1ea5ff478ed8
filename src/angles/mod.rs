//! Direction parametrisations: Rusinkiewicz's half/difference angles (Rusinkiewicz 1998, "A New Change
//! of Variables for Efficient BRDF Representation") and the exact reciprocity map Θ of Sec. 4.3 (Eq. 6).
//!
//! Every function here is total: non-finite, zero-length or otherwise degenerate input gives `None`
//! instead of NaN, and unnormalised input is normalised first (each vector on its own, so the result does
//! not depend on which of the two is called `wi`).
//!
//! # Bitwise reciprocity
//! Θ(wi, wo) and Θ(wo, wi) are *bitwise* identical. Everything is computed from `s = wi + wo` (exactly
//! symmetric: IEEE addition commutes) and `u = wi - wo` (exactly antisymmetric: swapping negates every
//! component without rounding):
//! - the half vector `h = s / |s|` and `θh`,
//! - `θd = atan2(|u|, |s|)`, because `|wi - wo| = 2 sin θd` and `|wi + wo| = 2 cos θd` for unit vectors,
//! - `φd` from the tangential components `(a, b)` of `u` in the half-vector frame,
//!   `(a, b) = 2 sin θd (cos φd, sin φd)`. The swap maps `(a, b)` to exactly `(-a, -b)`, i.e. `φd` to
//!   `φd + π`. The pair is first brought to the canonical half plane `b > 0` (or `b = 0, a ≥ 0`), which
//!   both orders reach bit for bit, and only then passed to `atan2`; so `φd mod π` is identical too.
//!
//! # Hard cases (documented results)
//! - `θh = 0` (half vector along the normal): `φh` is undefined; the half frame uses `φh = 0`.
//! - `wi = wo`: `θd = 0` and `φd` is undefined; it is reported as 0.
//! - `wi = -wo`: the half vector is undefined; `None`.
//! - grazing or below-horizon directions are parametrised like any other (the angles are purely
//!   geometric); BRDFs reject them through [`upper_hemisphere_pair`].
//!
//! # 16 pairs at once
//! `theta16.rs` (x86-64) maps 16 direction pairs through Θ (or the plain Rusinkiewicz angles) and the
//! positional encoding at once for the batches (AVX-512): libm's `atanf`/`atan2f` and the rest of the
//! map with lanes for pairs, every lane the bits of the one-pair functions here, so `Model::eval_many`
//! keeps `Model::eval`'s bits.

#[cfg(target_arch = "x86_64")]
pub(crate) mod theta16;

use crate::math::{safe_sqrt, PI};
use crate::Vec3;

/// 2π as `f32`.
const TAU: f32 = core::f32::consts::TAU;

/// Rusinkiewicz coordinates of a direction pair.
///
/// `theta_h` is the polar angle of the half vector, `phi_h` its azimuth in [0, 2π); `theta_d` and `phi_d`
/// are the polar and azimuthal angles of `wi` in the frame of the half vector, with `phi_d` in [0, 2π).
/// For an isotropic BRDF only (`theta_h`, `theta_d`, `phi_d`) matter.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Rusinkiewicz {
    /// Polar angle of the half vector, in [0, π].
    pub theta_h: f32,
    /// Azimuth of the half vector, in [0, 2π).
    pub phi_h: f32,
    /// Polar angle of `wi` about the half vector, in [0, π/2].
    pub theta_d: f32,
    /// Azimuth of `wi` about the half vector, in [0, 2π).
    pub phi_d: f32,
}

/// The distance `| |v|² - 1 |` within which [`unit()`] takes `1 / |v|` as `1.5 - |v|²/2` (`2^-12`: the
/// neglected Taylor term is below `2.3e-8`).
pub const UNIT_TAYLOR: f32 = 1.0 / 4096.0;

/// The range of `|v|²` in which [`unit()`] normalises with one square root and one division.
pub const UNIT_FAST_MIN: f32 = 1e-30;
/// See [`UNIT_FAST_MIN`].
pub const UNIT_FAST_MAX: f32 = 1e30;

/// `v / |v|`, or `None` when `v` is zero or not finite, by the cheapest rule that is exact enough:
/// - `| |v|² - 1 | ≤` [`UNIT_TAYLOR`] (every direction a renderer normalised itself): `1 / |v|` is
///   `1.5 - |v|²/2`, the first-order Taylor term of `(|v|²)^(-1/2)` about 1. The term left out is
///   `3/8 (|v|² - 1)² ≤ 2.3e-8`, a fifth of an f32 ulp at 1, and the value is one rounding (`|v|²/2`
///   is exact): four cycles instead of a square root and a division (about 25 on Zen 4), which every
///   BRDF query pays twice on its dependent chain;
/// - `|v|²` in `[`[`UNIT_FAST_MIN`]`, `[`UNIT_FAST_MAX`]`]`: one square root and one division;
/// - otherwise the vector is first scaled by its largest component, so that denormal and huge (finite)
///   inputs normalise without underflow or overflow.
///
/// The result is within 2e-7 (relative, per component) of the exact normalisation.
/// `measured::nbrdf_json::half_diff_packet` repeats the first two rules in the same order on 16 vectors.
///
/// ```
/// use nbrdf::{angles::unit, Vec3};
/// assert_eq!(unit(Vec3::new(0.0, 0.0, 1e-40)), Some(Vec3::Z));
/// assert_eq!(unit(Vec3::new(f32::NAN, 0.0, 1.0)), None);
/// assert_eq!(unit(Vec3::ZERO), None);
/// ```
#[inline(always)]
pub fn unit(v: Vec3) -> Option<Vec3> {
    let l2 = (v.x * v.x + v.y * v.y) + v.z * v.z;
    // Both comparisons are false for NaN and infinity.
    let s = if (l2 - 1.0).abs() <= UNIT_TAYLOR {
        1.5 - 0.5 * l2
    } else if (UNIT_FAST_MIN..=UNIT_FAST_MAX).contains(&l2) {
        1.0 / libm::sqrtf(l2)
    } else {
        return unit_rescaled(v);
    };
    Some(v * s)
}

/// [`unit`] for vectors whose squared length leaves the fast range: scaled by the largest component
/// first.
#[cold]
fn unit_rescaled(v: Vec3) -> Option<Vec3> {
    // `max_element` skips NaN, so finiteness is checked on the vector itself.
    let m = v.abs().max_element();
    if !(v.is_finite() && m > 0.0) {
        return None;
    }
    let v = v / m;
    let l = libm::sqrtf(v.length_squared());
    Some(v / l)
}

/// Both directions normalised, or `None` unless both are finite and strictly above the horizon
/// (`z > 0`). This is the gate every BRDF passes its input through: what it rejects evaluates to 0.
///
/// ```
/// use nbrdf::{angles::upper_hemisphere_pair, Vec3};
/// assert!(upper_hemisphere_pair(Vec3::new(1.0, 0.0, 1.0), Vec3::Z).is_some());
/// assert!(upper_hemisphere_pair(Vec3::new(1.0, 0.0, 0.0), Vec3::Z).is_none()); // grazing
/// assert!(upper_hemisphere_pair(Vec3::new(0.0, 0.0, -1.0), Vec3::Z).is_none());
/// ```
#[inline(always)]
pub fn upper_hemisphere_pair(wi: Vec3, wo: Vec3) -> Option<(Vec3, Vec3)> {
    let wi = unit(wi)?;
    let wo = unit(wo)?;
    if wi.z > 0.0 && wo.z > 0.0 {
        Some((wi, wo))
    } else {
        None
    }
}

/// The normalised half vector `(wi + wo) / |wi + wo|`; `None` for `wi = -wo` or degenerate input.
///
/// ```
/// use nbrdf::{angles::half_vector, Vec3};
/// let h = half_vector(Vec3::new(1.0, 0.0, 1.0), Vec3::new(-1.0, 0.0, 1.0)).unwrap();
/// assert!((h - Vec3::Z).length() < 1e-7);
/// ```
#[inline]
pub fn half_vector(wi: Vec3, wo: Vec3) -> Option<Vec3> {
    unit(unit(wi)? + unit(wo)?)
}

/// The quantities all angle functions derive from; see the module docs for why they are symmetric.
struct HalfFrame {
    /// Unit half vector.
    h: Vec3,
    /// `sin θh = sqrt(hx² + hy²)`.
    rho: f32,
    /// `θh`.
    theta_h: f32,
    /// `θd`.
    theta_d: f32,
    /// Canonical azimuth `φd mod π` in [0, π).
    phi_d_mod_pi: f32,
    /// Whether the canonical half plane was reached by negating `(a, b)`: then `φd = φd mod π + π`.
    flipped: bool,
}

#[inline]
fn half_frame(wi: Vec3, wo: Vec3) -> Option<HalfFrame> {
    // One component at a time: a caller's fresh 8 + 4-byte copy would stall an 8-byte load of `x, y`
    // (`math::load_pair`); theta_map 0.74x the time in a loop of independent calls.
    let (wi, wo) = crate::math::load_pair(&wi, &wo);
    let wi = unit(wi)?;
    let wo = unit(wo)?;
    let s = wi + wo;
    let u = wi - wo;
    let s_len = libm::sqrtf(s.length_squared());
    // NaN must take this branch too, hence not `s_len <= 0.0`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(s_len > 0.0) {
        return None;
    }
    let h = s / s_len;
    let rho = libm::sqrtf(h.x * h.x + h.y * h.y);
    let theta_h = libm::atan2f(rho, h.z);
    let theta_d = libm::atan2f(libm::sqrtf(u.length_squared()), s_len);
    // Half frame: x' = Rz(φh) Ry(θh) x, y' = Rz(φh) y (Rusinkiewicz 1998). φh = 0 where it is undefined.
    let (cos_phi_h, sin_phi_h) = if rho > 0.0 { (h.x / rho, h.y / rho) } else { (1.0, 0.0) };
    let x_axis = Vec3::new(h.z * cos_phi_h, h.z * sin_phi_h, -rho);
    let y_axis = Vec3::new(-sin_phi_h, cos_phi_h, 0.0);
    let mut a = u.dot(x_axis);
    let mut b = u.dot(y_axis);
    let mut flipped = b < 0.0 || (b == 0.0 && a < 0.0);
    if flipped {
        a = -a;
        b = -b;
    }
    // Drop signed zeros so atan2 sees the same bits for both orders (atan2(+0, -0) = π).
    if a == 0.0 {
        a = 0.0;
    }
    if b == 0.0 {
        b = 0.0;
    }
    let mut phi = libm::atan2f(b, a);
    // atan2 of (tiny b > 0, a < 0) can round up to π; fold it to 0 of the other half plane.
    if phi >= PI {
        phi = 0.0;
        flipped = !flipped;
    }
    Some(HalfFrame { h, rho, theta_h, theta_d, phi_d_mod_pi: phi, flipped })
}

/// Rusinkiewicz coordinates of (`wi`, `wo`); `None` for degenerate input (see the module docs).
///
/// ```
/// use nbrdf::{angles::to_rusinkiewicz, Vec3};
/// // Mirror configuration: the half vector is the normal, θd is the angle of incidence.
/// let wi = Vec3::new(0.6, 0.0, 0.8);
/// let wo = Vec3::new(-0.6, 0.0, 0.8);
/// let r = to_rusinkiewicz(wi, wo).unwrap();
/// assert!(r.theta_h.abs() < 1e-6);
/// assert!((r.theta_d - 0.6f32.asin()).abs() < 1e-6);
/// assert!(r.phi_d.abs() < 1e-6);
/// ```
#[inline]
pub fn to_rusinkiewicz(wi: Vec3, wo: Vec3) -> Option<Rusinkiewicz> {
    let f = half_frame(wi, wo)?;
    let mut phi_h = if f.rho > 0.0 { libm::atan2f(f.h.y, f.h.x) } else { 0.0 };
    if phi_h < 0.0 {
        phi_h += TAU;
    }
    if phi_h >= TAU {
        phi_h = 0.0;
    }
    let mut phi_d = if f.flipped { f.phi_d_mod_pi + PI } else { f.phi_d_mod_pi };
    if phi_d >= TAU {
        phi_d = 0.0;
    }
    Some(Rusinkiewicz { theta_h: f.theta_h, phi_h, theta_d: f.theta_d, phi_d })
}

/// The direction pair (`wi`, `wo`) of Rusinkiewicz coordinates: the inverse of [`to_rusinkiewicz`].
///
/// Non-finite angles give non-finite vectors; callers that take angles from untrusted data check them.
///
/// ```
/// use nbrdf::angles::{from_rusinkiewicz, to_rusinkiewicz, Rusinkiewicz};
/// let r = Rusinkiewicz { theta_h: 0.3, phi_h: 1.0, theta_d: 0.7, phi_d: 2.0 };
/// let (wi, wo) = from_rusinkiewicz(&r);
/// let back = to_rusinkiewicz(wi, wo).unwrap();
/// assert!((back.theta_h - 0.3).abs() < 1e-5 && (back.theta_d - 0.7).abs() < 1e-5);
/// assert!((back.phi_h - 1.0).abs() < 1e-5 && (back.phi_d - 2.0).abs() < 1e-5);
/// ```
#[inline]
pub fn from_rusinkiewicz(r: &Rusinkiewicz) -> (Vec3, Vec3) {
    let (sth, cth) = libm::sincosf(r.theta_h);
    let (sph, cph) = libm::sincosf(r.phi_h);
    let (std_, ctd) = libm::sincosf(r.theta_d);
    let (spd, cpd) = libm::sincosf(r.phi_d);
    let h = Vec3::new(sth * cph, sth * sph, cth);
    let x_axis = Vec3::new(cth * cph, cth * sph, -sth);
    let y_axis = Vec3::new(-sph, cph, 0.0);
    let t = x_axis * (std_ * cpd) + y_axis * (std_ * spd);
    (t + h * ctd, h * ctd - t)
}

/// Half vector with `φh = 0` and difference vector of isotropic Rusinkiewicz angles:
/// `h = (sin θh, 0, cos θh)`, `d = (sin θd cos φd, sin θd sin φd, cos θd)`. This is the input layout of
/// the NBRDF networks (Sztrajman et al. 2021).
///
/// ```
/// use nbrdf::angles::half_diff_vectors;
/// let (h, d) = half_diff_vectors(0.0, 0.0, 0.0);
/// assert_eq!((h.z, d.z), (1.0, 1.0));
/// ```
#[inline]
pub fn half_diff_vectors(theta_h: f32, theta_d: f32, phi_d: f32) -> (Vec3, Vec3) {
    let (sth, cth) = libm::sincosf(theta_h);
    let (std_, ctd) = libm::sincosf(theta_d);
    let (spd, cpd) = libm::sincosf(phi_d);
    (Vec3::new(sth, 0.0, cth), Vec3::new(std_ * cpd, std_ * spd, ctd))
}

/// The half vector `h` and the difference vector `d` (`wi` in the half-vector frame) of a direction
/// pair, in the local frame.
///
/// ```
/// use nbrdf::{angles::half_diff, Vec3};
/// let (h, d) = half_diff(Vec3::Z, Vec3::Z).unwrap();
/// assert_eq!(h, Vec3::Z);
/// assert!((d - Vec3::Z).length() < 1e-7);
/// ```
#[inline]
pub fn half_diff(wi: Vec3, wo: Vec3) -> Option<(Vec3, Vec3)> {
    let f = half_frame(wi, wo)?;
    let (spd, cpd) = libm::sincosf(if f.flipped { f.phi_d_mod_pi + PI } else { f.phi_d_mod_pi });
    let (std_, ctd) = libm::sincosf(f.theta_d);
    Some((f.h, Vec3::new(std_ * cpd, std_ * spd, ctd)))
}

/// The reciprocity map Θ of Sec. 4.3, Eq. 6: `[θh, θd, φd mod π, φd mod π + π]`.
///
/// Range `[0, π] x [0, π/2] x [0, π) x [π, 2π)` (θh ≤ π/2 in the upper hemisphere). Θ(wi, wo) and
/// Θ(wo, wi) are bitwise identical (module docs), so any function of Θ is exactly reciprocal.
///
/// ```
/// use nbrdf::{angles::theta_map, Vec3};
/// let (wi, wo) = (Vec3::new(0.5, -0.2, 0.7), Vec3::new(-0.1, 0.6, 0.3));
/// let t = theta_map(wi, wo).unwrap();
/// assert_eq!(t, theta_map(wo, wi).unwrap());
/// assert_eq!(t[3], t[2] + core::f32::consts::PI);
/// ```
#[inline]
pub fn theta_map(wi: Vec3, wo: Vec3) -> Option<[f32; 4]> {
    let f = half_frame(wi, wo)?;
    Some([f.theta_h, f.theta_d, f.phi_d_mod_pi, f.phi_d_mod_pi + PI])
}

/// Isotropic Rusinkiewicz angles `[θh, θd, φd]` (φd in [0, 2π)), the non-reciprocal network input.
///
/// ```
/// use nbrdf::{angles::rusinkiewicz_angles, Vec3};
/// let a = rusinkiewicz_angles(Vec3::new(0.3, 0.2, 0.9), Vec3::new(-0.4, 0.1, 0.8)).unwrap();
/// let b = rusinkiewicz_angles(Vec3::new(-0.4, 0.1, 0.8), Vec3::new(0.3, 0.2, 0.9)).unwrap();
/// assert_eq!((a[0], a[1]), (b[0], b[1]));
/// assert!(((a[2] - b[2]).abs() - core::f32::consts::PI).abs() < 1e-5);
/// ```
#[inline]
pub fn rusinkiewicz_angles(wi: Vec3, wo: Vec3) -> Option<[f32; 3]> {
    let r = to_rusinkiewicz(wi, wo)?;
    Some([r.theta_h, r.theta_d, r.phi_d])
}

/// Reflects `w` about the unit normal `n`: `2 (w·n) n - w`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    n * (2.0 * w.dot(n)) - w
}

/// `sin θ` of a unit direction in the local frame, `sqrt(1 - z²)` clamped.
#[inline]
pub fn sin_theta(w: Vec3) -> f32 {
    safe_sqrt(1.0 - w.z * w.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_unit_directions_normalise_within_2e_7_relative() {
        // |v|² - 1 from -6e-4 to 6e-4: inside and outside the Taylor range (2^-12 = 2.4e-4).
        // Unit vectors, and one of |v|² = 0.54 (the square-root path).
        let base = [Vec3::new(0.36, -0.48, 0.8), Vec3::new(-0.6, 0.0, 0.8), Vec3::new(0.1, 0.7, 0.2)];
        for v in base {
            for k in -40..=40 {
                let scale = libm::sqrt(1.0 + k as f64 * 1.5e-5);
                let v = Vec3::new((v.x as f64 * scale) as f32, (v.y as f64 * scale) as f32, (v.z as f64 * scale) as f32);
                let u = unit(v).unwrap();
                let len = libm::sqrt((v.x as f64).powi(2) + (v.y as f64).powi(2) + (v.z as f64).powi(2));
                for (got, c) in [(u.x, v.x), (u.y, v.y), (u.z, v.z)] {
                    let want = c as f64 / len;
                    assert!((got as f64 - want).abs() <= 2e-7 * want.abs(), "{v:?}: {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn huge_and_denormal_vectors_normalise_through_the_rescaled_path() {
        for v in [Vec3::new(3e20, -4e20, 0.0), Vec3::new(3e-25, 4e-25, 0.0), Vec3::new(0.0, 3e-42, 4e-42)] {
            let u = unit(v).unwrap();
            let len = libm::sqrt((v.x as f64).powi(2) + (v.y as f64).powi(2) + (v.z as f64).powi(2));
            for (got, c) in [(u.x, v.x), (u.y, v.y), (u.z, v.z)] {
                assert!((got as f64 - c as f64 / len).abs() <= 2e-7, "{v:?} -> {u:?}");
            }
        }
        assert_eq!(unit(Vec3::new(f32::MAX, f32::MAX, 0.0)), Some(Vec3::new(core::f32::consts::FRAC_1_SQRT_2, core::f32::consts::FRAC_1_SQRT_2, 0.0)));
        assert_eq!(unit(Vec3::new(f32::INFINITY, 0.0, 1.0)), None);
    }

    #[test]
    fn half_frame_axes_are_orthonormal_and_give_back_wi() {
        let wi = unit(Vec3::new(0.3, -0.4, 0.6)).unwrap();
        let wo = unit(Vec3::new(-0.5, 0.1, 0.4)).unwrap();
        let r = to_rusinkiewicz(wi, wo).unwrap();
        let (wi2, wo2) = from_rusinkiewicz(&r);
        assert!((wi - wi2).length() < 1e-6, "{wi} vs {wi2}");
        assert!((wo - wo2).length() < 1e-6, "{wo} vs {wo2}");
    }

    #[test]
    fn degenerate_pairs_give_none_not_nan() {
        assert!(theta_map(Vec3::Z, -Vec3::Z).is_none());
        assert!(theta_map(Vec3::new(f32::INFINITY, 0.0, 1.0), Vec3::Z).is_none());
        assert!(theta_map(Vec3::ZERO, Vec3::Z).is_none());
        let t = theta_map(Vec3::Z, Vec3::Z).unwrap();
        assert_eq!(t, [0.0, 0.0, 0.0, PI]);
    }

    #[test]
    fn phi_d_canonicalisation_handles_signed_zeros() {
        // In the plane of incidence: b is ±0 for both orders.
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let wo = Vec3::new(0.0, 0.0, 1.0);
        let a = theta_map(wi, wo).unwrap();
        let b = theta_map(wo, wi).unwrap();
        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
        assert!(a[2] >= 0.0 && a[2] < PI);
    }
}
