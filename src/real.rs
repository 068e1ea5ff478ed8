//! The scalar the parametric formulas are written in, so that each formula exists once and serves both
//! evaluation (`f32`) and exact differentiation ([`Dual`](crate::parametric::dual::Dual), forward-mode
//! automatic differentiation). It sits below `microfacet`, whose terms are generic over it.
//!
//! Only quantities that depend on a model's *parameters* are [`Real`]; the direction-only geometry
//! ([`HalfGeometry`](crate::microfacet::HalfGeometry), cosines, Schlick weights of the angles) stays plain
//! `f32` and enters through the mixed operators (`Real ∘ f32`). The `f32` implementation is the identity
//! on every operation (each method is the exact `f32`/`libm` call the models used before they were
//! generic), so the `f32` instantiation of a formula computes the same bits with the same instructions.
//!
//! Writing a formula generically: constants on the left of a non-commuting operator go through
//! [`Real::from_f32`] (`T::from_f32(1.0) - x`, not `1.0 - x`), and a commuting one is written with the
//! `Real` on the left (`x * 0.5`, the same bits as `0.5 * x` because IEEE addition and multiplication
//! commute exactly). The test `one_formula_gives_the_value_and_its_exact_derivative` shows a formula
//! at both.

use core::ops::{Add, Div, Mul, Neg, Sub};

/// A scalar the parametric formulas can be evaluated in: `f32`, or a number that also carries
/// derivatives ([`Dual`](crate::parametric::dual::Dual)).
///
/// Every method of the `f32` implementation is exactly the `f32` operation the name says (`libm` for the
/// transcendental ones, `core`'s `max`/`min`/`clamp`, [`crate::math`]'s activations), so generic code
/// instantiated at `f32` is bit for bit the plain `f32` code.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f32, Output = Self>
    + Sub<f32, Output = Self>
    + Mul<f32, Output = Self>
    + Div<f32, Output = Self>
{
    /// A constant: no derivative.
    fn from_f32(x: f32) -> Self;
    /// The `f32` value (for the formulas' branches: a branch is taken on the value alone).
    fn value(self) -> f32;
    /// `e^x` (`libm::expf`).
    fn exp(self) -> Self;
    /// `ln x` (`libm::logf`).
    fn ln(self) -> Self;
    /// `√x` (`libm::sqrtf`).
    fn sqrt(self) -> Self;
    /// `x^e` (`libm::powf`) with both base and exponent variable. At a base of 0 the derivatives are
    /// taken as 0: the limit of the exponent's term `x^e ln x`, and of the base's for `e > 1`.
    fn powf(self, e: Self) -> Self;
    /// `base^e` (`libm::powf`) for a constant `base > 0`: only the exponent varies, so no `0 · ∞` from the
    /// base's derivative `e · base^(e-1)` can arise when `base` underflows.
    fn powf_base(base: f32, e: Self) -> Self;
    /// The larger of two values (`f32::max`); the derivative is the chosen one's.
    fn max(self, other: Self) -> Self;
    /// `f32::clamp` to `[lo, hi]`; the derivative is 0 where the value is clamped.
    fn clamp(self, lo: f32, hi: f32) -> Self;
    /// The logistic sigmoid, [`crate::math::sigmoid`].
    fn sigmoid(self) -> Self;
    /// Softplus, [`crate::math::softplus`].
    fn softplus(self) -> Self;
    /// The last guard of every `eval`, [`crate::math::sanitize`]: a non-finite or non-positive channel
    /// becomes 0 (with derivative 0).
    fn sanitize(v: [Self; 3]) -> [Self; 3];
}

impl Real for f32 {
    #[inline]
    fn from_f32(x: f32) -> Self {
        x
    }
    #[inline]
    fn value(self) -> f32 {
        self
    }
    #[inline]
    fn exp(self) -> Self {
        libm::expf(self)
    }
    #[inline]
    fn ln(self) -> Self {
        libm::logf(self)
    }
    #[inline]
    fn sqrt(self) -> Self {
        libm::sqrtf(self)
    }
    #[inline]
    fn powf(self, e: Self) -> Self {
        libm::powf(self, e)
    }
    #[inline]
    fn powf_base(base: f32, e: Self) -> Self {
        libm::powf(base, e)
    }
    #[inline]
    fn max(self, other: Self) -> Self {
        f32::max(self, other)
    }
    #[inline]
    fn clamp(self, lo: f32, hi: f32) -> Self {
        f32::clamp(self, lo, hi)
    }
    #[inline]
    fn sigmoid(self) -> Self {
        crate::math::sigmoid(self)
    }
    #[inline]
    fn softplus(self) -> Self {
        crate::math::softplus(self)
    }
    #[inline]
    fn sanitize(v: [Self; 3]) -> [Self; 3] {
        crate::math::sanitize(v)
    }
}

/// [`crate::math::lerp`] in any [`Real`]: `a + t (b - a)`, the same operations in the same order.
#[inline]
pub fn lerp<T: Real>(a: T, b: T, t: T) -> T {
    a + t * (b - a)
}

/// [`crate::math::safe_sqrt`] in any [`Real`]: `sqrt(max(x, 0))`.
#[inline]
pub fn safe_sqrt<T: Real>(x: T) -> T {
    x.max(T::from_f32(0.0)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One formula, two instantiations: the value, and the value with its derivative.
    #[test]
    fn one_formula_gives_the_value_and_its_exact_derivative() {
        use crate::parametric::dual::Dual;
        fn lobe<T: Real>(n: T, cos: f32) -> T {
            (n + 2.0) * T::powf_base(cos, n)
        }
        let n = 10.0f32;
        let d = lobe(Dual::<1>::variable(n, 0), 0.9);
        assert_eq!(d.v, lobe(n, 0.9)); // the same bits
        let exact = libm::powf(0.9, n) * (1.0 + (n + 2.0) * libm::logf(0.9));
        assert!((d.d[0] - exact).abs() < 1e-5 * exact.abs());
    }
}
