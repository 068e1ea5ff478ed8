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
pub mod fresnel_microfacet;
pub mod lambert;
pub mod microfacet;
pub mod phong;
pub mod torrance_sparrow;

pub use disney::Disney;
pub use fresnel_microfacet::FresnelMicrofacet;
pub use lambert::Lambert;
pub use phong::Phong;
pub use torrance_sparrow::TorranceSparrow;

use crate::{Rgb, Vec3};

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
}
