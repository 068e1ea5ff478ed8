//! The parametric BRDF models of Sec. 4.1.1 and the map from raw network outputs to their parameters.
//!
//! A neural BRDF "based on a parametric model" is an MLP that predicts, per surface point, the raw
//! (pre-activation) outputs of [`ParametricKind::n_raw`]; [`Parametric::from_raw`] applies the output
//! nonlinearities (sigmoid for bounded parameters, softplus for unbounded positive ones, the roughness
//! pre-activation scaled by 0.5 before its sigmoid) and [`Parametric::eval`] evaluates the model. Each
//! model's file documents at its top which raw index becomes which parameter through which function; the
//! trainer's candle twins mirror exactly those tables.
//!
//! | kind | file | raw outputs | object parameters |
//! |---|---|---|---|
//! | Lambert | [`lambert`] | 3 | 0 |
//! | RP (Phong) | [`phong`] | 7 | 0 |
//! | Torrance-Sparrow | [`torrance_sparrow`] | 7 | 0 |
//! | FMBRDF | [`fresnel_microfacet`] | 7 | 1 (NDF normalisation) |
//! | Disney | [`disney`] | 12 | 0 |
//!
//! Raw values that are missing (a slice shorter than `n_raw`) or not finite count as 0, so `from_raw`
//! never panics; every `eval` returns finite, non-negative values and 0 below the horizon.
//!
//! Each model's file also holds its importance sampling, `sample` and `pdf` in its `impl Brdf` (a lobe
//! mixture over [`crate::warp`]'s warps, as `crate::sampling` describes); [`Parametric`] dispatches to
//! them here.
//!
//! # Gradients
//! Each model's activations and formula are written once, generic over the scalar
//! `Real` (`real.rs`), and instantiated twice: at `f32` for [`Parametric::from_raw`] and
//! [`Parametric::eval`], and at the dual number (`dual.rs`) for [`Parametric::eval_grad`], which
//! returns the same value and its exact derivatives in the raw outputs and object parameters
//! (forward-mode automatic differentiation). A trainer's backward pass calls it; there is no second,
//! hand-differentiated copy of any formula.
//!
//! ```
//! use nbrdf::parametric::{Parametric, ParametricKind};
//! use nbrdf::Vec3;
//! let raw = [0.0; nbrdf::parametric::MAX_RAW];
//! for kind in ParametricKind::ALL {
//!     let m = Parametric::from_raw(kind, &raw[..kind.n_raw()], &[0.0; 1][..kind.n_object()]);
//!     let (wi, wo) = (Vec3::new(0.3, 0.2, 0.9), Vec3::new(-0.1, 0.4, 0.8));
//!     assert_eq!(m.eval(wi, wo), m.eval(wo, wi)); // reciprocal
//! }
//! ```

pub mod disney;
pub(crate) mod dual;
pub mod fresnel_microfacet;
pub mod lambert;
pub mod phong;
pub mod torrance_sparrow;

#[cfg(test)]
mod grad_check;

pub use disney::Disney;
pub use fresnel_microfacet::FresnelMicrofacet;
pub use lambert::Lambert;
pub use phong::Phong;
pub use torrance_sparrow::TorranceSparrow;

use crate::brdf::{Brdf, BsdfSample};
use crate::{Rgb, Vec3};
use dual::Dual;

/// `raw[i]` if present and finite, else 0 (the documented fallback of every `from_raw`).
#[inline]
pub(crate) fn raw_at(raw: &[f32], i: usize) -> f32 {
    match raw.get(i) {
        Some(&x) if x.is_finite() => x,
        _ => 0.0,
    }
}

/// Which parametric model a neural BRDF predicts the parameters of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum ParametricKind {
    /// [`Lambert`].
    Lambert,
    /// [`Phong`], the energy-preserving modified Phong "RP".
    Phong,
    /// [`TorranceSparrow`].
    TorranceSparrow,
    /// [`FresnelMicrofacet`], the FMBRDF.
    FresnelMicrofacet,
    /// [`Disney`].
    Disney,
}

impl ParametricKind {
    /// Every kind, in the order of the paper's tables.
    pub const ALL: [ParametricKind; 5] = [
        ParametricKind::Lambert,
        ParametricKind::Phong,
        ParametricKind::TorranceSparrow,
        ParametricKind::FresnelMicrofacet,
        ParametricKind::Disney,
    ];

    /// Raw network outputs this model needs per surface point.
    pub const fn n_raw(self) -> usize {
        match self {
            ParametricKind::Lambert => Lambert::N_RAW,
            ParametricKind::Phong => Phong::N_RAW,
            ParametricKind::TorranceSparrow => TorranceSparrow::N_RAW,
            ParametricKind::FresnelMicrofacet => FresnelMicrofacet::N_RAW,
            ParametricKind::Disney => Disney::N_RAW,
        }
    }

    /// Per-object raw parameters (FMBRDF: 1, its NDF normalisation; the others 0).
    pub const fn n_object(self) -> usize {
        match self {
            ParametricKind::FresnelMicrofacet => FresnelMicrofacet::N_OBJECT,
            _ => 0,
        }
    }

    /// Display name as in the paper's tables.
    pub const fn name(self) -> &'static str {
        match self {
            ParametricKind::Lambert => "Lambert",
            ParametricKind::Phong => "RP (Phong)",
            ParametricKind::TorranceSparrow => "Torrance-Sparrow",
            ParametricKind::FresnelMicrofacet => "FMBRDF",
            ParametricKind::Disney => "Disney",
        }
    }

    /// Stable identifier for files and command lines.
    pub const fn id(self) -> &'static str {
        match self {
            ParametricKind::Lambert => "lambert",
            ParametricKind::Phong => "phong",
            ParametricKind::TorranceSparrow => "torrance-sparrow",
            ParametricKind::FresnelMicrofacet => "fmbrdf",
            ParametricKind::Disney => "disney",
        }
    }

    /// The kind whose [`id`](Self::id) is `id`.
    ///
    /// ```
    /// use nbrdf::parametric::ParametricKind;
    /// for k in ParametricKind::ALL {
    ///     assert_eq!(ParametricKind::from_id(k.id()), Some(k));
    /// }
    /// assert_eq!(ParametricKind::from_id("blinn"), None);
    /// ```
    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.id() == id)
    }

    /// Other names the command lines, configs and bindings accept: the paper's abbreviations.
    pub const fn aliases(self) -> &'static [&'static str] {
        match self {
            ParametricKind::Lambert => &[],
            ParametricKind::Phong => &["rp"],
            ParametricKind::TorranceSparrow => &["ts"],
            ParametricKind::FresnelMicrofacet => &["fresnel-microfacet"],
            ParametricKind::Disney => &[],
        }
    }

    /// The shortest of its names, as the study's tables and the trainer's logs print it: the paper's
    /// abbreviation where it has one.
    ///
    /// ```
    /// use nbrdf::parametric::ParametricKind;
    /// assert_eq!(ParametricKind::Phong.short_name(), "rp");
    /// assert_eq!(ParametricKind::FresnelMicrofacet.short_name(), "fmbrdf");
    /// ```
    pub fn short_name(self) -> &'static str {
        self.aliases().iter().copied().fold(self.id(), |best, a| if a.len() < best.len() { a } else { best })
    }

    /// The kind named `name`: its [`id`](Self::id) or one of its [`aliases`](Self::aliases). The one
    /// name table of the crate, the trainer and the bindings.
    ///
    /// ```
    /// use nbrdf::parametric::ParametricKind;
    /// assert_eq!(ParametricKind::from_name("rp"), Some(ParametricKind::Phong));
    /// assert_eq!(ParametricKind::from_name("torrance-sparrow"), Some(ParametricKind::TorranceSparrow));
    /// assert_eq!(ParametricKind::from_name("ts"), ParametricKind::from_id("torrance-sparrow"));
    /// ```
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.id() == name || k.aliases().contains(&name))
    }
}

/// The most raw outputs any parametric model needs (Disney's 12).
pub const MAX_RAW: usize = max_raw();

const fn max_raw() -> usize {
    let mut m = 0;
    let mut i = 0;
    while i < ParametricKind::ALL.len() {
        let n = ParametricKind::ALL[i].n_raw();
        if n > m {
            m = n;
        }
        i += 1;
    }
    m
}

/// The most per-object raw parameters any parametric model needs.
pub const MAX_OBJECT: usize = 1;

/// One parametric BRDF with its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Parametric {
    /// See [`Lambert`].
    Lambert(Lambert),
    /// See [`Phong`].
    Phong(Phong),
    /// See [`TorranceSparrow`].
    TorranceSparrow(TorranceSparrow),
    /// See [`FresnelMicrofacet`].
    FresnelMicrofacet(FresnelMicrofacet),
    /// See [`Disney`].
    Disney(Disney),
}

impl Parametric {
    /// Sec. 4.1.1: raw (pre-activation) network outputs -> parameters, with sigmoid/softplus by range and
    /// the roughness pre-activation scaled by 0.5 before its sigmoid (Disney and the microfacet models).
    /// `object_raw` holds the per-object raw parameters ([`ParametricKind::n_object`]). Short slices and
    /// non-finite values read as 0; never panics.
    #[inline]
    pub fn from_raw(kind: ParametricKind, raw: &[f32], object_raw: &[f32]) -> Self {
        match kind {
            ParametricKind::Lambert => Parametric::Lambert(Lambert::from_raw(raw)),
            ParametricKind::Phong => Parametric::Phong(Phong::from_raw(raw)),
            ParametricKind::TorranceSparrow => Parametric::TorranceSparrow(TorranceSparrow::from_raw(raw)),
            ParametricKind::FresnelMicrofacet => {
                Parametric::FresnelMicrofacet(FresnelMicrofacet::from_raw(raw, object_raw))
            }
            ParametricKind::Disney => Parametric::Disney(Disney::from_raw(raw)),
        }
    }

    /// The kind of this model.
    #[inline]
    pub fn kind(&self) -> ParametricKind {
        match self {
            Parametric::Lambert(_) => ParametricKind::Lambert,
            Parametric::Phong(_) => ParametricKind::Phong,
            Parametric::TorranceSparrow(_) => ParametricKind::TorranceSparrow,
            Parametric::FresnelMicrofacet(_) => ParametricKind::FresnelMicrofacet,
            Parametric::Disney(_) => ParametricKind::Disney,
        }
    }

    /// Raw network outputs and per-object raw parameters that [`Parametric::from_raw`] maps back to this
    /// model (entries past `n_raw` / `n_object` are 0). For initialising a network's output bias at a
    /// known material, or exporting a uniform analytic material as a parametric model.
    ///
    /// ```
    /// use nbrdf::parametric::{Parametric, TorranceSparrow};
    /// let m = Parametric::TorranceSparrow(TorranceSparrow { kd: [0.3, 0.2, 0.1], ks: [0.9; 3], alpha: 0.25 });
    /// let (raw, object) = m.to_raw();
    /// let Parametric::TorranceSparrow(back) = Parametric::from_raw(m.kind(), &raw, &object) else { panic!() };
    /// assert!((back.alpha - 0.25).abs() < 1e-5 && (back.kd[2] - 0.1).abs() < 1e-6);
    /// ```
    pub fn to_raw(&self) -> ([f32; MAX_RAW], [f32; MAX_OBJECT]) {
        let mut raw = [0.0; MAX_RAW];
        let mut object = [0.0; MAX_OBJECT];
        match self {
            Parametric::Lambert(m) => raw[..Lambert::N_RAW].copy_from_slice(&m.to_raw()),
            Parametric::Phong(m) => raw[..Phong::N_RAW].copy_from_slice(&m.to_raw()),
            Parametric::TorranceSparrow(m) => raw[..TorranceSparrow::N_RAW].copy_from_slice(&m.to_raw()),
            Parametric::FresnelMicrofacet(m) => {
                let (r, o) = m.to_raw();
                raw[..FresnelMicrofacet::N_RAW].copy_from_slice(&r);
                object[..FresnelMicrofacet::N_OBJECT].copy_from_slice(&o);
            }
            Parametric::Disney(m) => raw[..Disney::N_RAW].copy_from_slice(&m.to_raw()),
        }
        (raw, object)
    }

    /// The BRDF value (1/sr, linear RGB) for light from `wi` seen from `wo`, both in the local frame.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        match self {
            Parametric::Lambert(m) => m.eval(wi, wo),
            Parametric::Phong(m) => m.eval(wi, wo),
            Parametric::TorranceSparrow(m) => m.eval(wi, wo),
            Parametric::FresnelMicrofacet(m) => m.eval(wi, wo),
            Parametric::Disney(m) => m.eval(wi, wo),
        }
    }

    /// The model of `kind` at raw outputs `raw` and object parameters `object_raw` (as
    /// [`Parametric::from_raw`]), evaluated at (`wi`, `wo`), with its exact derivatives in every raw
    /// output and object parameter: the backward pass of a network that predicts `raw`.
    ///
    /// [`EvalGrad::value`] is `Parametric::from_raw(kind, raw, object_raw).eval(wi, wo)` bit for bit (the
    /// same generic formula, see the module docs). The derivatives include the activations. A raw value
    /// that is missing or not finite counts as 0, as in `from_raw`, and has derivative 0; so does every
    /// channel below the horizon or clamped to 0 by `eval`'s final guard. Never allocates, never panics,
    /// never returns NaN.
    ///
    /// ```
    /// use nbrdf::parametric::{Parametric, ParametricKind};
    /// use nbrdf::Vec3;
    /// let kind = ParametricKind::TorranceSparrow;
    /// let raw = [0.3, -0.2, 0.1, -1.0, -1.5, -2.0, -1.0];
    /// let (wi, wo) = (Vec3::new(0.4, 0.1, 0.9).normalize(), Vec3::new(-0.3, 0.0, 0.95).normalize());
    /// let g = Parametric::eval_grad(kind, &raw, &[], wi, wo);
    /// assert_eq!(g.value, Parametric::from_raw(kind, &raw, &[]).eval(wi, wo));
    /// // ∂f_red/∂raw[0] through kd_red = σ(raw[0]) and f = kd/π + ...: σ'(raw[0]) / π.
    /// let s = 1.0 / (1.0 + (-0.3f32).exp());
    /// assert!((g.d_raw[0][0] - s * (1.0 - s) / core::f32::consts::PI).abs() < 1e-6);
    /// assert_eq!(g.d_raw[0][1], 0.0); // kd_red does not reach green
    /// ```
    #[inline]
    pub fn eval_grad(kind: ParametricKind, raw: &[f32], object_raw: &[f32], wi: Vec3, wo: Vec3) -> EvalGrad {
        const L: usize = Lambert::N_RAW;
        const P: usize = Phong::N_RAW;
        const T: usize = TorranceSparrow::N_RAW;
        const F: usize = FresnelMicrofacet::N_RAW;
        const FO: usize = FresnelMicrofacet::N_OBJECT;
        const D: usize = Disney::N_RAW;
        match kind {
            ParametricKind::Lambert => {
                let x = seeds::<L, 0, L>(raw, object_raw);
                EvalGrad::new::<L, 0, L>(lambert::Params::from_raw(&x.0).eval(wi, wo))
            }
            ParametricKind::Phong => {
                let x = seeds::<P, 0, P>(raw, object_raw);
                EvalGrad::new::<P, 0, P>(phong::Params::from_raw(&x.0).eval(wi, wo))
            }
            ParametricKind::TorranceSparrow => {
                let x = seeds::<T, 0, T>(raw, object_raw);
                EvalGrad::new::<T, 0, T>(torrance_sparrow::Params::from_raw(&x.0).eval(wi, wo))
            }
            ParametricKind::FresnelMicrofacet => {
                let x = seeds::<F, FO, { F + FO }>(raw, object_raw);
                EvalGrad::new::<F, FO, { F + FO }>(fresnel_microfacet::Params::from_raw(&x.0, &x.1).eval(wi, wo))
            }
            ParametricKind::Disney => {
                let x = seeds::<D, 0, D>(raw, object_raw);
                EvalGrad::new::<D, 0, D>(disney::Params::from_raw(&x.0).eval(wi, wo))
            }
        }
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

/// A parametric BRDF value and its derivatives in the model's inputs, from [`Parametric::eval_grad`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalGrad {
    /// The BRDF value, `Parametric::from_raw(..).eval(..)`.
    pub value: Rgb,
    /// `d_raw[j][c] = ∂value[c] / ∂raw[j]`, activations included; 0 for `j ≥ n_raw`.
    pub d_raw: [Rgb; MAX_RAW],
    /// `d_object[k][c] = ∂value[c] / ∂object_raw[k]`; 0 for `k ≥ n_object`.
    pub d_object: [Rgb; MAX_OBJECT],
}

impl EvalGrad {
    /// Unpacks a formula's three dual channels whose inputs are `R` raw outputs then `O` object
    /// parameters (`N = R + O`).
    #[inline]
    fn new<const R: usize, const O: usize, const N: usize>(f: [Dual<N>; 3]) -> Self {
        let d_raw = core::array::from_fn(|j| if j < R { f.map(|x| x.d[j]) } else { [0.0; 3] });
        let d_object = core::array::from_fn(|k| if k < O { f.map(|x| x.d[R + k]) } else { [0.0; 3] });
        Self { value: f.map(|x| x.v), d_raw, d_object }
    }
}

/// The `R` raw outputs and `O` object parameters as the `N = R + O` independent variables of a dual
/// evaluation, raw first; a missing or non-finite one is the constant 0 (as [`raw_at`] reads it).
#[inline]
fn seeds<const R: usize, const O: usize, const N: usize>(raw: &[f32], object_raw: &[f32]) -> ([Dual<N>; R], [Dual<N>; O]) {
    let seed = |x: &[f32], i: usize, var: usize| match x.get(i) {
        Some(&v) if v.is_finite() => Dual::variable(v, var),
        _ => Dual::constant(0.0),
    };
    (core::array::from_fn(|j| seed(raw, j, j)), core::array::from_fn(|k| seed(object_raw, k, R + k)))
}
