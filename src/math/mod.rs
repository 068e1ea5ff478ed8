//! Small numeric helpers shared by the models: safe square roots and inverse trigonometry, the output
//! nonlinearities of Sec. 4.1, and finite-value guards. All `#[inline]`, all `no_std` through `libm`.
//!
//! The output maps of the neural models on many values at once, vectorised where the CPU allows, live
//! beside the one-value activations (`output_map.rs`: [`map_outputs`], [`softplus_slice`],
//! [`sigmoid_slice`]).

mod output_map;

pub use output_map::{map_outputs, sigmoid_slice, softplus_slice};

use crate::Vec3;

/// π as `f32`.
pub const PI: f32 = core::f32::consts::PI;
/// 1/π as `f32`.
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;

/// `sqrt(max(x, 0))`: rounding can push a squared sine slightly below zero.
#[inline]
pub fn safe_sqrt(x: f32) -> f32 {
    libm::sqrtf(x.max(0.0))
}

/// `acos` of `x` clamped to [-1, 1].
#[inline]
pub fn safe_acos(x: f32) -> f32 {
    libm::acosf(x.clamp(-1.0, 1.0))
}

/// Logistic sigmoid `1 / (1 + e^-x)`, stable for large |x|.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + libm::expf(-x))
    } else {
        let e = libm::expf(x);
        e / (1.0 + e)
    }
}

/// [`sigmoid`] and its slope `σ'(x) = σ(x) σ(-x) = e^-|x| / (1 + e^-|x|)²`, from one exponential: the
/// activation's forward-mode derivative (the parametric models' dual numbers). The value is [`sigmoid`]'s bit for
/// bit (the same exponential `e^-|x|` and the same branch), and the slope is accurate at both tails,
/// unlike `σ (1 - σ)`, which is 0 once `σ` rounds to 1.
///
/// ```
/// use nbrdf::math::{sigmoid, sigmoid_and_slope};
/// let (s, ds) = sigmoid_and_slope(20.0);
/// assert_eq!(s, sigmoid(20.0));
/// assert!((ds - (-20.0f32).exp()).abs() < 1e-15 && s * (1.0 - s) == 0.0);
/// ```
#[inline]
pub fn sigmoid_and_slope(x: f32) -> (f32, f32) {
    let e = libm::expf(-x.abs());
    let one_e = 1.0 + e;
    let s = if x >= 0.0 { 1.0 / one_e } else { e / one_e };
    (s, e / (one_e * one_e))
}

/// Softplus `ln(1 + e^x)`, computed as `max(x, 0) + ln(1 + e^-|x|)` so it never overflows.
#[inline]
pub fn softplus(x: f32) -> f32 {
    x.max(0.0) + libm::log1pf(libm::expf(-x.abs()))
}

/// Inverse of [`softplus`] for `y > 0`: `ln(e^y - 1)`; used to initialise raw parameters.
#[inline]
pub fn softplus_inv(y: f32) -> f32 {
    if y > 20.0 {
        y
    } else {
        libm::logf(libm::expm1f(y.max(1e-30)))
    }
}

/// Inverse of [`sigmoid`] for `y` in (0, 1): `ln(y / (1 - y))`.
#[inline]
pub fn logit(y: f32) -> f32 {
    let y = y.clamp(1e-7, 1.0 - 1e-7);
    libm::logf(y / (1.0 - y))
}

/// `v` with every non-finite or negative component replaced by 0: the last guard of every `eval`.
#[inline]
pub fn sanitize(v: [f32; 3]) -> [f32; 3] {
    let f = |x: f32| if x.is_finite() && x > 0.0 { x } else { 0.0 };
    [f(v[0]), f(v[1]), f(v[2])]
}

/// `(*wi, *wo)` read one component at a time.
///
/// A caller that stored a direction as 8 + 4 bytes (how a 12-byte `Vec3` is usually copied) and a
/// callee that loads its `y, z` as one 8-byte pair (how the compiler likes to vectorise a length)
/// meet in a load that spans two stores: it cannot be forwarded from them and waits until they
/// retire, which serialises consecutive evaluations (seen here: a loop of independent queries ran
/// no faster than a dependent chain). A 4-byte load always lies inside one store.
#[inline(always)]
pub fn load_pair(wi: &Vec3, wo: &Vec3) -> (Vec3, Vec3) {
    use core::ptr::read_volatile as rd;
    // SAFETY: reads of the fields of two live references.
    unsafe { (Vec3::new(rd(&wi.x), rd(&wi.y), rd(&wi.z)), Vec3::new(rd(&wo.x), rd(&wo.y), rd(&wo.z))) }
}

/// Linear interpolation `a + t (b - a)`.
#[inline]
pub fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn softplus_matches_definition_and_never_overflows() {
        assert!((softplus(0.0) - core::f32::consts::LN_2).abs() < 1e-7);
        assert_eq!(softplus(1e4), 1e4);
        assert_eq!(softplus(-1e4), 0.0);
        assert!((softplus(softplus_inv(0.37)) - 0.37).abs() < 1e-6);
    }

    #[test]
    fn sigmoid_and_slope_has_sigmoids_bits_and_its_derivative() {
        // Every 997th f32 in [-120, 120] (both branches, the tails where e^-|x| underflows, ±0).
        let mut checked = 0;
        for bits in (0u32..=u32::MAX).step_by(997) {
            let x = f32::from_bits(bits);
            if x.is_nan() || x.abs() > 120.0 {
                continue;
            }
            let (s, ds) = sigmoid_and_slope(x);
            assert_eq!(s.to_bits(), sigmoid(x).to_bits(), "x = {x}");
            let (s64, x64) = (1.0 / (1.0 + (-(x as f64)).exp()), x as f64);
            let want = s64 * (1.0 / (1.0 + x64.exp()));
            assert!((ds as f64 - want).abs() <= 1e-6 * want + 3e-45, "x = {x}: {ds} vs {want}");
            checked += 1;
        }
        assert!(checked > 1_000_000);
        assert_eq!(sigmoid_and_slope(-0.0).0.to_bits(), sigmoid(-0.0).to_bits());
    }

    #[test]
    fn sigmoid_is_stable_and_inverts() {
        assert_eq!(sigmoid(-1e4), 0.0);
        assert_eq!(sigmoid(1e4), 1.0);
        assert!((sigmoid(logit(0.8)) - 0.8).abs() < 1e-6);
    }
}
