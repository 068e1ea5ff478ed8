//! The front door: any BRDF of the crate — a `.nbrdf` model, a MERL table, an NBRDF-json network, a
//! parametric model or a built-in material — made, checked and described by one type, [`AnyBrdf`].
//! The C ABI, the Python package, the path tracer and the examples are thin adapters over it, so a
//! file is read, a spec parsed and a parameter checked the same way everywhere.
//!
//! # Specs
//!
//! A spec names a BRDF in one string (the path tracer's `--brdf`, Python's `nbrdf.from_spec`):
//!
//! | spec | BRDF |
//! |---|---|
//! | `lambert:R,G,B` | Lambert, albedo in [0, 1] |
//! | `phong:KD×3,KS×3,N` (or `rp:`) | the energy-preserving Phong "RP", `kd + ks ≤ 1`, `n ≥ 0` |
//! | `torrance-sparrow:KD×3,KS×3,ALPHA` (or `ts:`) | Torrance-Sparrow, albedos in [0, 1], `alpha > 0` |
//! | `fmbrdf:RHO×3,KS,ALPHA,BETA,ETA,NORM` | the FMBRDF, `rho`, `ks` in [0, 1], the rest > 0 |
//! | `disney:BASE×3,SUBSURFACE,METALLIC,SPECULAR,SPECULAR_TINT,ROUGHNESS,SHEEN,SHEEN_TINT,CLEARCOAT,CLEARCOAT_GLOSS` | Disney, every value in [0, 1] |
//! | `raw:KIND:V,...` | a parametric model from raw network outputs, then its per-object values |
//! | `builtin:ID` | a built-in material (`two-lobe-metal`, `clear-coat`, `velvet`) |
//! | `model:FILE`, `merl:FILE`, `json:FILE` | a `.nbrdf` model, a MERL `.binary` table, an NBRDF-json network |
//! | `FILE.nbrdf`, `FILE.binary`, `FILE.json` | the file, by its extension |
//!
//! Numbers are comma-separated and must be finite. A one-letter kind is a Windows drive (`C:\m.nbrdf`).
//!
//! ```
//! use nbrdf::any::{AnyBrdf, Kind};
//! use nbrdf::{Brdf, Vec3};
//! let b = AnyBrdf::from_spec("lambert:0.5,0.5,0.5").unwrap();
//! assert_eq!(b.info().kind, Kind::Parametric);
//! let f = b.at(&[]).unwrap().eval(Vec3::Z, Vec3::Z);
//! assert!((f[0] - 0.5 / core::f32::consts::PI).abs() < 1e-7);
//! // Every problem is named.
//! let e = AnyBrdf::from_spec("lambert:0.5,2,0.5").unwrap_err().to_string();
//! assert!(e.contains("kd[1]") && e.contains("[0, 1]"), "{e}");
//! ```

use alloc::format;
use alloc::string::String;
#[cfg(feature = "std")]
use alloc::string::ToString;
use alloc::vec::Vec;

use crate::brdf::{Brdf, BsdfSample};
use crate::builtin::Builtin;
use crate::file::ModelKind;
use crate::measured::{MerlTable, NbrdfNetwork};
use crate::model::{Model, ModelAt, ModelBuf, Prepared};
use crate::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, ParametricKind, Phong, TorranceSparrow};
use crate::sampling::Proxy;
use crate::{Error, Rgb, Vec3};

/// Any BRDF of the crate, checked when made and immutable afterwards (share it between threads).
/// `'a` is the lifetime of borrowed model bytes ([`AnyBrdf::borrow_model`]); everything else owns its
/// data and is `AnyBrdf<'static>`.
pub struct AnyBrdf<'a> {
    source: Source<'a>,
    /// The prepared state of a model without point input, made once.
    uniform: Option<Prepared>,
}

// One per loaded BRDF: the sizes of the variants do not matter.
#[allow(clippy::large_enum_variant)]
enum Source<'a> {
    Model(ModelBuf),
    Borrowed(Model<'a>),
    Merl(MerlTable),
    NbrdfJson(NbrdfNetwork),
    Parametric(Parametric),
    Builtin(Builtin),
}

impl core::fmt::Debug for AnyBrdf<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "AnyBrdf({})", self.describe())
    }
}

/// What an [`AnyBrdf`] holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A `.nbrdf` model file (neural or parametric network).
    Model,
    /// A MERL `.binary` table (nearest-bin lookup).
    Merl,
    /// An NBRDF-json network (Sztrajman et al. 2021).
    NbrdfJson,
    /// An analytic model with fixed parameters.
    Parametric,
    /// A built-in procedural material.
    Builtin,
}

impl Kind {
    /// Stable name: "model", "merl", "nbrdf-json", "parametric" or "builtin".
    pub const fn id(self) -> &'static str {
        match self {
            Kind::Model => "model",
            Kind::Merl => "merl",
            Kind::NbrdfJson => "nbrdf-json",
            Kind::Parametric => "parametric",
            Kind::Builtin => "builtin",
        }
    }
}

/// The file formats an [`AnyBrdf`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// A `.nbrdf` model file.
    Model,
    /// A MERL `.binary` table.
    Merl,
    /// An NBRDF-json network.
    NbrdfJson,
}

impl Format {
    /// The format of a file extension (`nbrdf`, `binary`, `json`; any case).
    pub fn from_extension(ext: &str) -> Option<Self> {
        match ext.to_ascii_lowercase().as_str() {
            "nbrdf" => Some(Format::Model),
            "binary" => Some(Format::Merl),
            "json" => Some(Format::NbrdfJson),
            _ => None,
        }
    }

    /// The largest input of the format: what a reader of untrusted lengths may accept.
    pub const fn max_bytes(self) -> u64 {
        match self {
            Format::Model => crate::file::MAX_FILE_BYTES,
            Format::Merl => crate::measured::merl::FILE_BYTES as u64,
            Format::NbrdfJson => crate::measured::nbrdf_json::MAX_JSON_BYTES as u64,
        }
    }
}

/// What an [`AnyBrdf`] is, in numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Info {
    /// What it holds.
    pub kind: Kind,
    /// The parametric model, for a parametric BRDF or a parametric `.nbrdf` network.
    pub parametric: Option<ParametricKind>,
    /// Whether `f(wi, wo) = f(wo, wi)` by construction (parametric models, models on the reciprocity
    /// map Θ, MERL tables).
    pub reciprocal: bool,
    /// Floats [`AnyBrdf::at`] takes per point: 0 for a BRDF that is the same everywhere, `k` for an
    /// intrinsic encoding, 3 (the point) for an extrinsic one.
    pub position_len: usize,
    /// Whether a model file carries the per-vertex table of [`AnyBrdf::position_features`].
    pub has_position_table: bool,
    /// Stored parameters: network weights (and per-object parameters), table entries, or the model's
    /// parameters.
    pub n_parameters: usize,
}

/// The BRDF of an [`AnyBrdf`] at one point: implements [`Brdf`].
// Lives on the stack for one shading call; boxing the prepared model would allocate per call.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
pub enum At<'a> {
    /// A BRDF that is the same everywhere.
    Fixed(&'a (dyn Brdf + Send + Sync)),
    /// A model at one point.
    Model(ModelAt<'a>),
}

impl Brdf for At<'_> {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        match self {
            At::Fixed(b) => b.eval(wi, wo),
            At::Model(m) => m.eval(wi, wo),
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        match self {
            At::Fixed(b) => b.sample(wo, u),
            At::Model(m) => m.sample(wo, u),
        }
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        match self {
            At::Fixed(b) => b.pdf(wi, wo),
            At::Model(m) => m.pdf(wi, wo),
        }
    }

    fn is_reciprocal(&self) -> bool {
        match self {
            At::Fixed(b) => b.is_reciprocal(),
            At::Model(m) => m.is_reciprocal(),
        }
    }
}

/// `Error::Context` for a spec or a parameter list.
fn bad(what: impl Into<String>, message: impl Into<String>) -> Error {
    Error::Context { what: what.into(), message: message.into() }
}

impl AnyBrdf<'static> {
    /// A `.nbrdf` model that owns its bytes.
    pub fn model(buf: ModelBuf) -> Result<Self, Error> {
        Self::new(Source::Model(buf))
    }

    /// A MERL table.
    pub fn merl(table: MerlTable) -> Self {
        AnyBrdf { source: Source::Merl(table), uniform: None }
    }

    /// An NBRDF-json network.
    pub fn nbrdf_json(network: NbrdfNetwork) -> Self {
        AnyBrdf { source: Source::NbrdfJson(network), uniform: None }
    }

    /// A parametric model with fixed parameters (see [`AnyBrdf::from_params`] for checked natural
    /// parameters).
    pub fn parametric(p: Parametric) -> Self {
        AnyBrdf { source: Source::Parametric(p), uniform: None }
    }

    /// A built-in material.
    pub fn builtin(b: Builtin) -> Self {
        AnyBrdf { source: Source::Builtin(b), uniform: None }
    }

    /// A built-in material by id, or an error listing the known ones.
    pub fn builtin_id(id: &str) -> Result<Self, Error> {
        Builtin::from_id(id).map(Self::builtin).ok_or_else(|| {
            let known: Vec<&str> = Builtin::ALL.iter().map(|b| b.id()).collect();
            bad("built-in material", format!("unknown built-in material {id:?} (known: {})", known.join(", ")))
        })
    }

    /// A file's bytes in `format`, validated (sizes, checksum, finite values) and copied.
    pub fn from_bytes(bytes: &[u8], format: Format) -> Result<Self, Error> {
        match format {
            Format::Model => Self::model(ModelBuf::from_bytes(bytes)?),
            Format::Merl => Ok(Self::merl(MerlTable::from_bytes(bytes)?)),
            Format::NbrdfJson => Ok(Self::nbrdf_json(NbrdfNetwork::from_json_bytes(bytes)?)),
        }
    }

    /// A BRDF file, by extension: `.nbrdf` (a model), `.json` (an NBRDF-json network) or `.binary`
    /// (a MERL table). Validated and copied; the file may be deleted afterwards.
    #[cfg(feature = "std")]
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Self, Error> {
        let path = path.as_ref();
        let format = path.extension().and_then(|e| e.to_str()).and_then(Format::from_extension).ok_or_else(|| {
            bad(path.display().to_string(), "unknown BRDF file type (expected .nbrdf, .json or .binary)")
        })?;
        Self::load_as(path, format)
    }

    /// A BRDF file in `format`, whatever its extension.
    #[cfg(feature = "std")]
    pub fn load_as(path: impl AsRef<std::path::Path>, format: Format) -> Result<Self, Error> {
        let path = path.as_ref();
        match format {
            Format::Model => Self::model(ModelBuf::load(path)?),
            Format::Merl => Ok(Self::merl(MerlTable::read(path)?)),
            Format::NbrdfJson => Ok(Self::nbrdf_json(NbrdfNetwork::load(path)?)),
        }
    }

    /// A parametric model from its natural parameters, in the order of the [module docs](self)'s
    /// specs (Lambert `kd×3`; Phong `kd×3, ks×3, n`; Torrance-Sparrow `kd×3, ks×3, alpha`; FMBRDF
    /// `rho×3, ks, alpha, beta, eta, norm`; Disney its 12). Errors name the parameter: a wrong count,
    /// a non-finite value, an albedo outside [0, 1], Phong's `kd + ks > 1`, a roughness `≤ 0`.
    ///
    /// ```
    /// use nbrdf::any::AnyBrdf;
    /// use nbrdf::parametric::ParametricKind;
    /// assert!(AnyBrdf::from_params(ParametricKind::TorranceSparrow, &[0.5, 0.5, 0.5, 0.2, 0.2, 0.2, 0.3]).is_ok());
    /// let e = AnyBrdf::from_params(ParametricKind::TorranceSparrow, &[0.5; 6]).unwrap_err();
    /// assert!(e.to_string().contains("expected 7 parameters, got 6"), "{e}");
    /// ```
    pub fn from_params(kind: ParametricKind, v: &[f32]) -> Result<Self, Error> {
        let params = params_of(kind);
        let id = kind.id();
        if v.len() != params.len() {
            return Err(bad(format!("{id} parameters"), format!("expected {} parameters, got {}", params.len(), v.len())));
        }
        for (i, ((name, range), &x)) in params.iter().zip(v).enumerate() {
            let why = match range {
                _ if !x.is_finite() => "must be finite",
                Range::Unit if !(0.0..=1.0).contains(&x) => "must lie in [0, 1]",
                Range::Positive if x <= 0.0 => "must be > 0",
                _ => continue,
            };
            return Err(bad(format!("{id} {name} (parameter {i})"), format!("{why}, got {x}")));
        }
        let rgb = |i: usize| [v[i], v[i + 1], v[i + 2]];
        let p = match kind {
            ParametricKind::Lambert => Parametric::Lambert(Lambert { kd: rgb(0) }),
            ParametricKind::Phong => Parametric::Phong(Phong::new(rgb(0), rgb(3), v[6])?),
            ParametricKind::TorranceSparrow => Parametric::TorranceSparrow(TorranceSparrow { kd: rgb(0), ks: rgb(3), alpha: v[6] }),
            ParametricKind::FresnelMicrofacet => {
                Parametric::FresnelMicrofacet(FresnelMicrofacet { rho: rgb(0), ks: v[3], alpha: v[4], beta: v[5], eta: v[6], norm: v[7] })
            }
            ParametricKind::Disney => Parametric::Disney(Disney {
                    base_color: rgb(0),
                    subsurface: v[3],
                    metallic: v[4],
                    specular: v[5],
                    specular_tint: v[6],
                    roughness: v[7],
                    sheen: v[8],
                    sheen_tint: v[9],
                    clearcoat: v[10],
                clearcoat_gloss: v[11],
            }),
        };
        Ok(Self::parametric(p))
    }

    /// A parametric model from raw network outputs, as a parametric `.nbrdf` network predicts them
    /// (every raw value is mapped into its parameter's range, so any finite value is valid):
    /// `kind.n_raw()` raw values and `kind.n_object()` per-object parameters.
    pub fn from_raw(kind: ParametricKind, raw: &[f32], object: &[f32]) -> Result<Self, Error> {
        let id = kind.id();
        if (raw.len(), object.len()) != (kind.n_raw(), kind.n_object()) {
            return Err(bad(
                format!("{id} raw values"),
                format!(
                    "{id} takes {} raw values and {} object parameters, got {} and {}",
                    kind.n_raw(),
                    kind.n_object(),
                    raw.len(),
                    object.len()
                ),
            ));
        }
        if let Some(i) = raw.iter().chain(object).position(|x| !x.is_finite()) {
            return Err(bad(format!("{id} raw value {i}"), "raw values must be finite"));
        }
        Ok(Self::parametric(Parametric::from_raw(kind, raw, object)))
    }

    /// A BRDF from a spec (the grammar is in the [module docs](self)); files are loaded.
    #[cfg(feature = "std")]
    pub fn from_spec(spec: &str) -> Result<Self, Error> {
        let named = |e: Error| bad(format!("BRDF `{spec}`"), e.to_string());
        let (kind, rest) = match spec.split_once(':') {
            Some((k, r)) if k.len() > 1 => (k, r),
            _ => return Self::load(spec).map_err(named),
        };
        match kind {
            "builtin" => Self::builtin_id(rest).map_err(named),
            "merl" => Self::load_as(rest, Format::Merl).map_err(named),
            "json" => Self::load_as(rest, Format::NbrdfJson).map_err(named),
            "model" => Self::load_as(rest, Format::Model).map_err(named),
            "raw" => {
                let (k, values) =
                    rest.split_once(':').ok_or_else(|| bad(format!("BRDF `{spec}`"), "expected raw:KIND:V,..."))?;
                let pk = parametric_kind(k).map_err(named)?;
                let v = floats(values).map_err(named)?;
                let split = v.len().saturating_sub(pk.n_object());
                Self::from_raw(pk, &v[..split], &v[split..]).map_err(named)
            }
            k => {
                let pk = ParametricKind::from_name(k).ok_or_else(|| {
                    bad(
                        format!("BRDF `{spec}`"),
                        format!(
                            "unknown kind `{k}` (known: {}, raw, builtin, merl, json, model, or a .nbrdf/.binary/.json file)",
                            ParametricKind::ALL.map(|k| k.id()).join(", ")
                        ),
                    )
                })?;
                Self::from_params(pk, &floats(rest).map_err(named)?).map_err(named)
            }
        }
    }
}

/// The parametric kind named `name` (its id or an alias), or an error listing them.
pub fn parametric_kind(name: &str) -> Result<ParametricKind, Error> {
    ParametricKind::from_name(name).ok_or_else(|| {
        bad("parametric kind", format!("unknown parametric kind `{name}` (known: {})", ParametricKind::ALL.map(|k| k.id()).join(", ")))
    })
}

/// Comma-separated numbers.
#[cfg(feature = "std")]
fn floats(s: &str) -> Result<Vec<f32>, Error> {
    s.split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| bad("number", format!("`{x}`: {e}"))))
        .collect()
}

/// What a natural parameter may be (besides finite).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// An albedo or a weight: [0, 1].
    Unit,
    /// A roughness, exponent or index: > 0.
    Positive,
    /// Checked by the model's own constructor (Phong's `kd + ks ≤ 1`, `n ≥ 0`).
    Model,
}

/// The natural parameters of a parametric model, in the order [`AnyBrdf::from_params`] takes them:
/// each name (as the bindings spell the argument) and its range. The one list of the crate.
pub const fn params_of(kind: ParametricKind) -> &'static [(&'static str, Range)] {
    use Range::{Model as M, Positive as P, Unit as U};
    match kind {
        ParametricKind::Lambert => &[("kd[0]", U), ("kd[1]", U), ("kd[2]", U)],
        ParametricKind::Phong => &[("kd[0]", M), ("kd[1]", M), ("kd[2]", M), ("ks[0]", M), ("ks[1]", M), ("ks[2]", M), ("n", M)],
        ParametricKind::TorranceSparrow => {
            &[("kd[0]", U), ("kd[1]", U), ("kd[2]", U), ("ks[0]", U), ("ks[1]", U), ("ks[2]", U), ("alpha", P)]
        }
        ParametricKind::FresnelMicrofacet => {
            &[("rho[0]", U), ("rho[1]", U), ("rho[2]", U), ("ks", U), ("alpha", P), ("beta", P), ("eta", P), ("norm", P)]
        }
        ParametricKind::Disney => &[
            ("base_color[0]", U),
            ("base_color[1]", U),
            ("base_color[2]", U),
            ("subsurface", U),
            ("metallic", U),
            ("specular", U),
            ("specular_tint", U),
            ("roughness", U),
            ("sheen", U),
            ("sheen_tint", U),
            ("clearcoat", U),
            ("clearcoat_gloss", U),
        ],
    }
}

impl<'a> AnyBrdf<'a> {
    fn new(source: Source<'a>) -> Result<Self, Error> {
        let mut b = AnyBrdf { source, uniform: None };
        if let Some(m) = b.as_model() {
            if m.position_len() == 0 {
                b.uniform = Some(m.prepare(&[])?);
            }
        }
        Ok(b)
    }

    /// A `.nbrdf` model over borrowed bytes, without a copy (embedded models, memory-mapped files):
    /// 4-byte aligned ([`Error::Misaligned`] otherwise); f16 files are widened row by row as read.
    pub fn borrow_model(bytes: &'a [u8]) -> Result<Self, Error> {
        Self::new(Source::Borrowed(Model::from_bytes(bytes)?))
    }

    /// The model of a `.nbrdf` BRDF.
    pub fn as_model(&self) -> Option<Model<'_>> {
        match &self.source {
            Source::Model(buf) => Some(buf.model()),
            Source::Borrowed(m) => Some(*m),
            _ => None,
        }
    }

    /// The BRDF, for everything but `.nbrdf` models (which vary with the point).
    pub fn fixed(&self) -> Option<&(dyn Brdf + Send + Sync)> {
        Some(match &self.source {
            Source::Parametric(p) => p,
            Source::Builtin(b) => b,
            Source::Merl(t) => t,
            Source::NbrdfJson(n) => n,
            Source::Model(_) | Source::Borrowed(_) => return None,
        })
    }

    /// The parametric model of a parametric BRDF.
    pub fn as_parametric(&self) -> Option<&Parametric> {
        match &self.source {
            Source::Parametric(p) => Some(p),
            _ => None,
        }
    }

    /// The built-in material of a built-in BRDF.
    pub fn as_builtin(&self) -> Option<Builtin> {
        match &self.source {
            Source::Builtin(b) => Some(*b),
            _ => None,
        }
    }

    /// What it is, in numbers.
    pub fn info(&self) -> Info {
        let base = |kind, parametric, reciprocal, n_parameters| Info {
            kind,
            parametric,
            reciprocal,
            position_len: 0,
            has_position_table: false,
            n_parameters,
        };
        match &self.source {
            Source::Model(_) | Source::Borrowed(_) => {
                let m = self.as_model().expect("a model");
                let h = m.header();
                let parametric = match h.kind {
                    ModelKind::Parametric(k) => Some(k),
                    _ => None,
                };
                Info {
                    kind: Kind::Model,
                    parametric,
                    reciprocal: m.is_reciprocal(),
                    position_len: m.position_len(),
                    has_position_table: h.n_vertices > 0,
                    // The networks' weights and the per-object parameters, once.
                    n_parameters: h.n_weights(),
                }
            }
            Source::Merl(t) => base(Kind::Merl, None, true, t.raw().len()),
            Source::NbrdfJson(n) => {
                base(Kind::NbrdfJson, None, n.is_reciprocal(), n.widths().windows(2).map(|p| (p[0] + 1) * p[1]).sum())
            }
            Source::Parametric(p) => base(Kind::Parametric, Some(p.kind()), p.is_reciprocal(), p.kind().n_raw() + p.kind().n_object()),
            Source::Builtin(b) => base(Kind::Builtin, None, b.is_reciprocal(), 0),
        }
    }

    /// The importance-sampling proxy a neural model, MERL table or NBRDF-json network samples through
    /// (None for the analytic ones, which sample their own lobes, and for a model file without one).
    pub fn proxy(&self) -> Option<Proxy> {
        match &self.source {
            Source::Merl(t) => Some(*t.proxy()),
            Source::NbrdfJson(n) => Some(*n.proxy()),
            Source::Model(_) | Source::Borrowed(_) => {
                let m = self.as_model()?;
                (m.header().proxy.is_some() && !matches!(m.header().kind, ModelKind::Parametric(_))).then(|| m.proxy())
            }
            Source::Parametric(_) | Source::Builtin(_) => None,
        }
    }

    /// A one-line description: what it is and how it samples.
    pub fn describe(&self) -> String {
        let proxy = |p: &Proxy| {
            format!(
                "proxy: cosine {:.2}, GGX {:.2} (α {:.3}), GGX {:.2} (α {:.3})",
                p.diffuse, p.lobes[0].weight, p.lobes[0].alpha, p.lobes[1].weight, p.lobes[1].alpha
            )
        };
        match &self.source {
            Source::Parametric(p) => format!("parametric {}, sampled by own lobes", p.kind().name()),
            Source::Builtin(b) => format!("built-in {}, sampled by own lobes", b.id()),
            Source::Merl(t) => format!("MERL table, sampled per view around {}", proxy(t.proxy())),
            Source::NbrdfJson(n) => format!("NBRDF-json {}, sampled per view around {}", n.name(), proxy(n.proxy())),
            Source::Model(_) | Source::Borrowed(_) => {
                let m = self.as_model().expect("a model");
                match m.header().kind {
                    ModelKind::Parametric(k) => format!(".nbrdf {} network, sampled by own lobes at each point", k.name()),
                    k => match self.proxy() {
                        Some(p) if m.header().view_proxy.is_some() => format!(".nbrdf {k:?}, sampled per view around {}", proxy(&p)),
                        Some(p) => format!(".nbrdf {k:?}, sampled by {}", proxy(&p)),
                        None => format!(".nbrdf {k:?}, sampled by cosine (no proxy in the file)"),
                    },
                }
            }
        }
    }

    /// The BRDF at a point: `position` holds [`Info::position_len`] floats (none for a BRDF that is the
    /// same everywhere; the point for an extrinsic encoding; [`position_features`](Self::position_features)
    /// for an intrinsic one).
    pub fn at(&self, position: &[f32]) -> Result<At<'_>, Error> {
        let prepared = if position.is_empty() { None } else { Some(self.prepare(position)?) };
        self.at_prepared(prepared.as_ref()).ok_or(Error::SizeMismatch {
            what: "position input (this model varies over the surface)",
            expected: self.position_len(),
            found: 0,
        })
    }

    /// Floats [`at`](Self::at) and [`prepare`](Self::prepare) take per point ([`Info::position_len`]).
    pub fn position_len(&self) -> usize {
        self.as_model().map_or(0, |m| m.position_len())
    }

    /// The state at a point, to keep and pass to [`at_prepared`](Self::at_prepared) (a renderer
    /// prepares a hit point once and evaluates it many times): `position` as in [`at`](Self::at); the
    /// default state for a BRDF that is the same everywhere.
    pub fn prepare(&self, position: &[f32]) -> Result<Prepared, Error> {
        let want = self.position_len();
        if position.len() != want {
            return Err(Error::SizeMismatch { what: "position input", expected: want, found: position.len() });
        }
        match self.as_model() {
            Some(m) => m.prepare(position),
            None => Ok(Prepared::default()),
        }
    }

    /// The BRDF at a point [`prepare`](Self::prepare)d before (`None`: no point, for a BRDF that is
    /// the same everywhere); `None` for a model that varies over the surface and no point.
    pub fn at_prepared(&self, prepared: Option<&Prepared>) -> Option<At<'_>> {
        if let Some(b) = self.fixed() {
            return Some(At::Fixed(b));
        }
        let model = self.as_model()?;
        prepared.or(self.uniform.as_ref()).map(|&prepared| At::Model(ModelAt { model, prepared }))
    }

    /// The per-point input of an intrinsically encoded model at triangle `tri` (vertex indices) with
    /// barycentric weights `bary`, interpolated from the file's per-vertex table into `out`
    /// ([`Info::position_len`] floats).
    pub fn position_features(&self, tri: [u32; 3], bary: [f32; 3], out: &mut [f32]) -> Result<(), Error> {
        let m = self.as_model().ok_or(Error::InvalidValue {
            what: "BRDF",
            reason: "not a model: only intrinsically encoded models have position features",
        })?;
        if let Some(i) = bary.iter().position(|b| !b.is_finite()) {
            return Err(bad(format!("bary[{i}]"), format!("is {}: barycentric weights must be finite", bary[i])));
        }
        m.position_features(tri, bary, out)
    }

    /// `f(wi[i], wo[i])` into `out[i]` for every pair at one point (`position` as in [`at`](Self::at));
    /// a model evaluates the batch in SIMD packets, with the bits of one `eval` per pair.
    pub fn eval_many(&self, position: &[f32], wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) -> Result<(), Error> {
        eval_batch(self.at(position)?, wi, wo, out)
    }

    /// [`eval_many`](Self::eval_many) at a point [`prepare`](Self::prepare)d before (`None`: a BRDF
    /// that is the same everywhere).
    pub fn eval_many_prepared(&self, prepared: Option<&Prepared>, wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) -> Result<(), Error> {
        let at = self.at_prepared(prepared).ok_or(Error::InvalidValue {
            what: "position",
            reason: "this model varies over the surface: pass a point",
        })?;
        eval_batch(at, wi, wo, out)
    }
}

/// `f(wi[i], wo[i])` into `out[i]` at one point: a model in SIMD packets (the bits of one `eval` per
/// pair), anything else pair by pair.
fn eval_batch(at: At<'_>, wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) -> Result<(), Error> {
    if wo.len() != wi.len() || out.len() != wi.len() {
        return Err(Error::SizeMismatch { what: "wi, wo and out lengths", expected: wi.len(), found: wo.len().max(out.len()) });
    }
    match at {
        At::Fixed(b) => {
            for ((o, &i), &v) in out.iter_mut().zip(wi).zip(wo) {
                *o = b.eval(i, v);
            }
        }
        At::Model(m) => m.model.eval_many(&m.prepared, wi, wo, out),
    }
    Ok(())
}

#[cfg(all(test, feature = "std"))]
mod tests {
    use super::*;

    #[test]
    fn specs_make_the_model_they_name_and_refuse_what_they_cannot() {
        let rp = AnyBrdf::from_spec("rp:0.3,0.3,0.3,0.2,0.2,0.2,20").unwrap();
        assert_eq!(rp.info().parametric, Some(ParametricKind::Phong));
        let ts = AnyBrdf::from_spec("ts:0.3,0.3,0.3,0.2,0.2,0.2,0.2").unwrap();
        assert_eq!(ts.info().parametric, Some(ParametricKind::TorranceSparrow));
        let raw = AnyBrdf::from_spec("raw:fmbrdf:0,0,0,0,0,0,0,1").unwrap();
        assert_eq!(raw.info().parametric, Some(ParametricKind::FresnelMicrofacet));
        assert_eq!(AnyBrdf::from_spec("builtin:velvet").unwrap().as_builtin(), Some(Builtin::Velvet));
        for (spec, says) in [
            ("lambert:0.5,0.5", "expected 3 parameters, got 2"),
            ("lambert:0.5,x,0.5", "`x`"),
            ("phong:0.6,0.6,0.6,0.6,0.6,0.6,10", "kd + ks"),
            ("torrance-sparrow:0.5,0.5,0.5,0.5,0.5,0.5,0", "alpha (parameter 6): must be > 0, got 0"),
            ("disney:0.5,0.5,0.5,0,0,0.5,0,1.5,0,0,0,1", "roughness (parameter 7): must lie in [0, 1], got 1.5"),
            ("fmbrdf:0.5,0.5,0.5,0.5,0.1,0.1,1.5,inf", "must be finite"),
            ("blinn:1,2", "unknown kind `blinn`"),
            ("raw:blinn:1", "unknown parametric kind `blinn`"),
            ("builtin:felt", "unknown built-in material \"felt\""),
            ("material.obj", "unknown BRDF file type"),
            ("model:/no/such/file.nbrdf", "/no/such/file.nbrdf"),
        ] {
            let e = AnyBrdf::from_spec(spec).err().unwrap_or_else(|| panic!("{spec} was accepted")).to_string();
            assert!(e.contains(says) && e.contains(spec), "{spec}: {e}");
        }
    }

    #[test]
    fn one_point_evaluation_and_the_batch_agree_bit_for_bit() {
        let b = AnyBrdf::from_spec("builtin:two-lobe-metal").unwrap();
        let wi = [Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(0.0, 0.0, -1.0)];
        let wo = [Vec3::new(-0.2, 0.4, 0.8).normalize(), Vec3::Z];
        let mut out = [[1.0; 3]; 2];
        b.eval_many(&[], &wi, &wo, &mut out).unwrap();
        let at = b.at(&[]).unwrap();
        assert_eq!(out, [at.eval(wi[0], wo[0]), at.eval(wi[1], wo[1])]);
        assert_eq!(out[1], [0.0; 3]);
        assert!(b.at(&[0.0, 0.0, 0.0]).is_err());
        assert!(b.eval_many(&[], &wi, &wo[..1], &mut out).is_err());
    }
}
