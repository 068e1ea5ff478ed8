//! Forward-mode automatic differentiation: a value with its derivatives in `N` inputs, carried through
//! every operation by the chain rule (the dual numbers of Clifford 1873, as used for AD since Wengert
//! 1964; Griewank & Walther 2008, "Evaluating Derivatives", Ch. 3).
//!
//! [`Dual<N>`] implements [`Real`], so a parametric formula written once over `Real` yields both its value
//! (at `f32`) and, at `Dual<N>`, the same value bit for bit (every value is computed by the `f32`
//! operation the `f32` instantiation uses) plus its exact gradient. Fixed size, no allocation, `no_std`.

use core::ops::{Add, Div, Mul, Neg, Sub};

use crate::real::Real;
use crate::math;

/// A value `v` and its partial derivatives `d[i] = ∂v/∂x_i` in `N` inputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f32,
    /// The partial derivatives in the `N` inputs.
    pub d: [f32; N],
}

impl<const N: usize> Dual<N> {
    /// A constant (all derivatives 0).
    #[inline]
    pub const fn constant(v: f32) -> Self {
        Self { v, d: [0.0; N] }
    }

    /// Input number `i` with value `v` (derivative 1 in itself, 0 in the others).
    ///
    /// # Panics
    /// If `i >= N`.
    #[inline]
    pub fn variable(v: f32, i: usize) -> Self {
        let mut d = [0.0; N];
        d[i] = 1.0;
        Self { v, d }
    }

    /// The chain rule for a function of one argument: value `v`, local slope `slope`.
    #[inline]
    fn chain(self, v: f32, slope: f32) -> Self {
        Self { v, d: self.d.map(|x| x * slope) }
    }

    /// `self.d · a + other.d · b`, the chain rule for a function of two arguments.
    #[inline]
    fn combine(self, a: f32, other: Self, b: f32, v: f32) -> Self {
        Self { v, d: core::array::from_fn(|k| self.d[k] * a + other.d[k] * b) }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self { v: self.v + o.v, d: core::array::from_fn(|k| self.d[k] + o.d[k]) }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self { v: self.v - o.v, d: core::array::from_fn(|k| self.d[k] - o.d[k]) }
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        self.combine(o.v, o, self.v, self.v * o.v)
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    /// `(a/b)' = (a' - (a/b) b') / b`.
    #[inline]
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        let inv = 1.0 / o.v;
        self.combine(inv, o, -v * inv, v)
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self { v: -self.v, d: self.d.map(|x| -x) }
    }
}

impl<const N: usize> Add<f32> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, c: f32) -> Self {
        Self { v: self.v + c, d: self.d }
    }
}

impl<const N: usize> Sub<f32> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, c: f32) -> Self {
        Self { v: self.v - c, d: self.d }
    }
}

impl<const N: usize> Mul<f32> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, c: f32) -> Self {
        self.chain(self.v * c, c)
    }
}

impl<const N: usize> Div<f32> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, c: f32) -> Self {
        self.chain(self.v / c, 1.0 / c)
    }
}

impl<const N: usize> Real for Dual<N> {
    #[inline]
    fn from_f32(x: f32) -> Self {
        Self::constant(x)
    }

    #[inline]
    fn value(self) -> f32 {
        self.v
    }

    #[inline]
    fn exp(self) -> Self {
        let v = libm::expf(self.v);
        self.chain(v, v)
    }

    #[inline]
    fn ln(self) -> Self {
        self.chain(libm::logf(self.v), 1.0 / self.v)
    }

    /// The slope `1 / (2 √x)` is taken as 0 at `x = 0`, where it is infinite; the formulas only take
    /// roots of quantities bounded away from 0 where they depend on parameters.
    #[inline]
    fn sqrt(self) -> Self {
        let v = libm::sqrtf(self.v);
        self.chain(v, if v > 0.0 { 0.5 / v } else { 0.0 })
    }

    #[inline]
    fn powf(self, e: Self) -> Self {
        let v = libm::powf(self.v, e.v);
        if self.v > 0.0 {
            // ∂/∂x x^e = e x^(e-1) = e (x^e / x), ∂/∂e x^e = x^e ln x.
            self.combine(e.v * (v / self.v), e, v * libm::logf(self.v), v)
        } else {
            Self::constant(v)
        }
    }

    #[inline]
    fn powf_base(base: f32, e: Self) -> Self {
        let v = libm::powf(base, e.v);
        e.chain(v, if base > 0.0 { v * libm::logf(base) } else { 0.0 })
    }

    #[inline]
    fn max(self, o: Self) -> Self {
        let v = f32::max(self.v, o.v);
        if self.v >= o.v || o.v.is_nan() {
            Self { v, d: self.d }
        } else {
            Self { v, d: o.d }
        }
    }


    #[inline]
    fn clamp(self, lo: f32, hi: f32) -> Self {
        let v = f32::clamp(self.v, lo, hi);
        if self.v < lo || self.v > hi {
            Self::constant(v)
        } else {
            Self { v, d: self.d }
        }
    }

    #[inline]
    fn sigmoid(self) -> Self {
        let (s, slope) = math::sigmoid_and_slope(self.v);
        self.chain(s, slope)
    }

    /// `softplus' = sigmoid`.
    #[inline]
    fn softplus(self) -> Self {
        self.chain(math::softplus(self.v), math::sigmoid(self.v))
    }

    /// [`math::sanitize`]'s rule on the value (kept iff finite and positive, else 0 with derivative 0),
    /// and a derivative that overflowed to a non-finite number is 0 too: it carries no usable direction,
    /// and one NaN would poison a whole training step.
    #[inline]
    fn sanitize(v: [Self; 3]) -> [Self; 3] {
        v.map(|x| {
            if x.v.is_finite() && x.v > 0.0 {
                Self { v: x.v, d: x.d.map(|g| if g.is_finite() { g } else { 0.0 }) }
            } else {
                Self::constant(0.0)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f(x, y) = x y + e^x at (2, 3): ∂f/∂x = y + e^x, ∂f/∂y = x.
    #[test]
    fn the_chain_rule_through_a_product_and_an_exponential() {
        let (x, y) = (Dual::<2>::variable(2.0, 0), Dual::<2>::variable(3.0, 1));
        let f = x * y + x.exp();
        assert_eq!(f.v, 2.0 * 3.0 + libm::expf(2.0));
        assert_eq!(f.d, [3.0 + libm::expf(2.0), 2.0]);
    }

    /// Central difference of `f` at `x` in f64 of an f32 function.
    fn fd(f: impl Fn(f32) -> f32, x: f32, h: f32) -> f64 {
        let (a, b) = (x + h, x - h);
        (f(a) as f64 - f(b) as f64) / (a as f64 - b as f64)
    }

    fn check(what: &str, f: impl Fn(f32) -> f32, g: impl Fn(Dual<1>) -> Dual<1>, xs: &[f32]) {
        for &x in xs {
            let d = g(Dual::variable(x, 0));
            assert_eq!(d.v.to_bits(), f(x).to_bits(), "{what}({x}): value");
            let want = fd(&f, x, 1e-3 * x.abs().max(1.0));
            assert!((d.d[0] as f64 - want).abs() <= 1e-3 * want.abs() + 1e-6, "{what}'({x}): {} vs {want}", d.d[0]);
        }
    }

    #[test]
    fn every_operation_has_the_f32_value_and_the_derivative() {
        let xs = [0.3f32, 1.7, 2.5, 0.05];
        check("exp", libm::expf, |x| x.exp(), &xs);
        check("ln", libm::logf, |x| x.ln(), &xs);
        check("sqrt", libm::sqrtf, |x| x.sqrt(), &xs);
        check("recip", |x| 1.0 / x, |x| Dual::constant(1.0) / x, &xs);
        check("square", |x| x * x, |x| x * x, &xs);
        check("x/(1+x)", |x| x / (x + 1.0), |x| x / (x + 1.0), &xs);
        check("x^x", |x| libm::powf(x, x), |x| x.powf(x), &xs);
        check("0.7^x", |x| libm::powf(0.7, x), |x| Dual::powf_base(0.7, x), &xs);
        let raw = [-30.0f32, -4.0, -0.5, 0.0, 0.5, 4.0, 30.0];
        check("sigmoid", math::sigmoid, |x| x.sigmoid(), &raw);
        check("softplus", math::softplus, |x| x.softplus(), &raw);
        check("clamp", |x| x.clamp(-1.0, 1.0), |x| x.clamp(-1.0, 1.0), &[-0.5, 0.25, 3.0, -3.0]);
        check("max", |x| x.max(0.5), |x| x.max(Dual::constant(0.5)), &[0.25, 3.0]);
    }

    #[test]
    fn degenerate_points_give_zero_not_nan() {
        let zero = Dual::<1>::variable(0.0, 0);
        assert_eq!(zero.sqrt().d, [0.0]);
        assert_eq!(zero.powf(Dual::constant(0.5)), Dual::constant(0.0));
        // A constant base that underflows: only the exponent's term, which stays finite.
        let e = Dual::<1>::variable(0.0, 0);
        assert!(Dual::powf_base(1e-45, e).d[0].is_finite());
        let bad = [Dual::<1> { v: 1.0, d: [f32::INFINITY] }, Dual { v: f32::NAN, d: [1.0] }, Dual { v: -1.0, d: [1.0] }];
        assert_eq!(Dual::sanitize(bad), [Dual { v: 1.0, d: [0.0] }, Dual::constant(0.0), Dual::constant(0.0)]);
    }
}
