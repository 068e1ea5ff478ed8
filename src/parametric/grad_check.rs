//! Tests of [`Parametric::eval_grad`] against an independent reference: central differences of the same
//! generic formulas instantiated in `f64` ([`F64`]), where the difference quotient carries about 1e-8
//! relative noise instead of the f32 function's rounding, which at grazing angles or saturated
//! activations swamps a difference quotient taken in `f32`.

use core::ops::{Add, Div, Mul, Neg, Sub};

use proptest::prelude::*;
use std::format;
use std::string::String;
use std::vec::Vec;

use crate::real::Real;
use super::{disney, fresnel_microfacet, lambert, phong, torrance_sparrow};
use super::{Parametric, ParametricKind, MAX_OBJECT, MAX_RAW};
use crate::Vec3;

/// An `f64` that is a [`Real`]: the reference scalar (a newtype, because the mixed `f64 ∘ f32` operators
/// cannot be implemented on the foreign `f64`).
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
struct F64(f64);

macro_rules! ops {
    ($($tr:ident $f:ident $op:tt),*) => {$(
        impl $tr for F64 {
            type Output = F64;
            fn $f(self, o: F64) -> F64 { F64(self.0 $op o.0) }
        }
        impl $tr<f32> for F64 {
            type Output = F64;
            fn $f(self, o: f32) -> F64 { F64(self.0 $op o as f64) }
        }
    )*};
}
ops!(Add add +, Sub sub -, Mul mul *, Div div /);

impl Neg for F64 {
    type Output = F64;
    fn neg(self) -> F64 {
        F64(-self.0)
    }
}

impl Real for F64 {
    fn from_f32(x: f32) -> Self {
        F64(x as f64)
    }
    fn value(self) -> f32 {
        self.0 as f32
    }
    fn exp(self) -> Self {
        F64(libm::exp(self.0))
    }
    fn ln(self) -> Self {
        F64(libm::log(self.0))
    }
    fn sqrt(self) -> Self {
        F64(libm::sqrt(self.0))
    }
    fn powf(self, e: Self) -> Self {
        F64(libm::pow(self.0, e.0))
    }
    fn powf_base(base: f32, e: Self) -> Self {
        F64(libm::pow(base as f64, e.0))
    }
    fn max(self, o: Self) -> Self {
        F64(self.0.max(o.0))
    }
    fn clamp(self, lo: f32, hi: f32) -> Self {
        F64(self.0.clamp(lo as f64, hi as f64))
    }
    fn sigmoid(self) -> Self {
        F64(1.0 / (1.0 + libm::exp(-self.0)))
    }
    fn softplus(self) -> Self {
        F64(self.0.max(0.0) + libm::log1p(libm::exp(-self.0.abs())))
    }
    fn sanitize(v: [Self; 3]) -> [Self; 3] {
        v.map(|x| if x.0.is_finite() && x.0 > 0.0 { x } else { F64(0.0) })
    }
}

/// The model of `kind` evaluated in `f64` at inputs `x` (raw outputs, then object parameters).
fn eval64(kind: ParametricKind, x: &[f64], wi: Vec3, wo: Vec3) -> [f64; 3] {
    fn arr<const N: usize>(x: &[f64]) -> [F64; N] {
        core::array::from_fn(|i| F64(x[i]))
    }
    let f = match kind {
        ParametricKind::Lambert => lambert::Params::from_raw(&arr(x)).eval(wi, wo),
        ParametricKind::Phong => phong::Params::from_raw(&arr(x)).eval(wi, wo),
        ParametricKind::TorranceSparrow => torrance_sparrow::Params::from_raw(&arr(x)).eval(wi, wo),
        ParametricKind::FresnelMicrofacet => {
            let n = kind.n_raw();
            fresnel_microfacet::Params::from_raw(&arr(x), &arr(&x[n..])).eval(wi, wo)
        }
        ParametricKind::Disney => disney::Params::from_raw(&arr(x)).eval(wi, wo),
    };
    f.map(|v| v.0)
}

/// Checks every derivative of `eval_grad` at one point against f64 central differences. A derivative
/// passes at the first of a few shrinking steps where the two agree to 2e-3 relative, widened by four
/// times the f32 value's own relative error at that point (its worst channel), plus an absolute floor of 1e-4 times the
/// channel's value per unit input (where the derivative is negligible next to the value); the smaller steps only matter next to a kink (a clamp of α, a `max`), which a wide step
/// straddles. Returns how many derivatives passed at the widest step, and how many were checked.
fn check_point(kind: ParametricKind, raw: &[f32], obj: &[f32], wi: Vec3, wo: Vec3) -> Result<(usize, usize), String> {
    let g = Parametric::eval_grad(kind, raw, obj, wi, wo);
    let x: Vec<f32> = raw[..kind.n_raw()].iter().chain(&obj[..kind.n_object()]).copied().collect();
    let value = eval64(kind, &x.iter().map(|&v| v as f64).collect::<Vec<_>>(), wi, wo);
    let mut widest = 0;
    for i in 0..x.len() {
        let ours = if i < kind.n_raw() { g.d_raw[i] } else { g.d_object[i - kind.n_raw()] };
        let mut seen = Vec::new();
        let mut passed = None;
        for (n, step) in [1e-4f64, 1e-5, 1e-6, 1e-7].into_iter().enumerate() {
            let h = step * (x[i].abs() as f64).max(1.0);
            let at = |s: f64| {
                let mut y: Vec<f64> = x.iter().map(|&v| v as f64).collect();
                y[i] += s;
                eval64(kind, &y, wi, wo)
            };
            let (fp, fm) = (at(h), at(-h));
            let fd = [0, 1, 2].map(|c| (fp[c] - fm[c]) / (2.0 * h));
            let ok = (0..3).all(|c| {
                let d = ours[c] as f64;
                // The f32 derivative can be no better conditioned than the f32 value it differentiates:
                // at grazing angles with η near 1 the value itself is off by ~0.2%.
                // The channels share the parameters, so the worst channel's error bounds them all.
                let value_error = (0..3)
                    .map(|c| (g.value[c] as f64 - value[c]).abs() / value[c].abs().max(1e-30))
                    .fold(0.0, f64::max);
                let tol = 2e-3 + 4.0 * value_error;
                (d - fd[c]).abs() <= tol * fd[c].abs().max(d.abs()) + 1e-4 * value[c].abs()
            });
            if ok {
                passed = Some(n);
                break;
            }
            seen.push(fd);
        }
        match passed {
            Some(0) => widest += 1,
            Some(_) => {}
            None => {
                return Err(format!(
                    "{kind:?} input {i} at raw {raw:?} obj {obj:?} wi {wi} wo {wo}: eval_grad {ours:?}, \
                     f64 central differences {seen:?}; value f32 {:?} f64 {value:?}", g.value
                ))
            }
        }
    }
    Ok((widest, x.len()))
}

fn kinds() -> impl Strategy<Value = ParametricKind> {
    prop::sample::select(ParametricKind::ALL.to_vec())
}

fn upper_direction() -> impl Strategy<Value = Vec3> {
    (0.0f32..1.0, 0.0f32..core::f32::consts::TAU).prop_map(|(u, phi)| {
        let z = 1e-3 + (1.0 - 1e-3) * u;
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    })
}

/// A direction pair above the horizon: independent, or `wo` near the mirror direction of `wi` (inside a
/// narrow specular peak, where the derivatives in the roughness are largest).
fn upper_pair() -> impl Strategy<Value = (Vec3, Vec3)> {
    prop_oneof![
        (upper_direction(), upper_direction()),
        (upper_direction(), -0.02f32..0.02, -0.02f32..0.02).prop_map(|(wi, dx, dy)| {
            (wi, Vec3::new(-wi.x + dx, -wi.y + dy, wi.z.max(1e-3)).normalize())
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Raw values within ±8: further out a sigmoid-ranged parameter sits within 3e-4 of its bound, where
    /// f32 keeps few digits of its distance to the bound (η - 1 enters the Fresnel factor squared), and
    /// the f32 formula itself, value and derivative alike, is that ill-conditioned. The saturated tails
    /// are checked at fixed points below.
    #[test]
    fn eval_grad_is_eval_with_its_derivatives(kind in kinds(),
                                              raw in prop::collection::vec(-8.0f32..8.0, MAX_RAW),
                                              obj in -2.0f32..14.0, (wi, wo) in upper_pair()) {
        let obj = [obj];
        let g = Parametric::eval_grad(kind, &raw, &obj, wi, wo);
        let f = Parametric::from_raw(kind, &raw, &obj).eval(wi, wo);
        prop_assert_eq!(g.value.map(f32::to_bits), f.map(f32::to_bits), "{:?}", kind);
        check_point(kind, &raw, &obj, wi, wo).map_err(TestCaseError::fail)?;
        // Inputs the model does not read have no derivative.
        prop_assert!(g.d_raw[kind.n_raw()..].iter().all(|d| *d == [0.0; 3]));
        prop_assert!(g.d_object[kind.n_object()..MAX_OBJECT].iter().all(|d| *d == [0.0; 3]));
    }
}

#[test]
fn eval_grad_matches_at_saturated_and_grazing_inputs() {
    // The activations' tails (raw ±10), the roughness floors (very negative roughness pre-activations),
    // and grazing pairs 0.06° above the horizon, for every input of every model.
    let z = 1e-3f32;
    let g = (1.0 - z * z).sqrt();
    let pairs = [
        (Vec3::new(g, 0.0, z), Vec3::new(-g, 0.0, z)),
        (Vec3::new(g, 0.0, z), Vec3::new(0.0, g, z)),
        (Vec3::new(0.3, 0.2, 0.93), Vec3::new(-0.31, -0.2, 0.93)),
        (Vec3::Z, Vec3::Z),
    ];
    let (mut widest, mut total) = (0, 0);
    for kind in ParametricKind::ALL {
        for r in [-10.0f32, -3.0, 0.0, 2.0, 10.0] {
            let raw: Vec<f32> = (0..MAX_RAW).map(|i| if i % 2 == 0 { r } else { -0.7 * r + 0.3 }).collect();
            for obj in [-1.0f32, 2.0, 12.0] {
                for (wi, wo) in pairs {
                    let (w, t) = check_point(kind, &raw, &[obj], wi.normalize(), wo.normalize()).unwrap();
                    widest += w;
                    total += t;
                }
            }
        }
    }
    // The smaller steps are the exception (kinks), not the rule.
    assert!(widest * 10 >= total * 9, "{widest} of {total} at the widest step");
}
