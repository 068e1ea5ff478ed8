//! `nbrdf.Model`: one class for every BRDF of the core (a `.nbrdf` model, a MERL table, an NBRDF-json
//! network, a parametric model, a built-in material), like the C ABI's handle, with `eval`, `sample`
//! and `pdf` over arrays of directions (`(3,)`, `(N, 3)` or any `(..., 3)`, broadcast by numpy's rules;
//! see `arrays`), and the functions that make one.
//!
//! Values are the Rust API's bit for bit: a batch at one point goes through `Model::eval_many` (the
//! bits of `eval`), per-pair points through `Model::prepare_many` (the bits of `prepare`), and every
//! other call through the `Brdf` trait one pair at a time. Batches above [`CHUNK`] pairs are split
//! across rayon's threads; the split changes no value.

use std::ops::Range;
use std::path::PathBuf;

use numpy::PyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;

use nbrdf::builtin::Builtin;
use nbrdf::file::ModelKind;
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::model::ModelAt;
use nbrdf::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, ParametricKind, Phong, TorranceSparrow};
use nbrdf::{Brdf, BsdfSample, ModelBuf, Prepared, Vec3};

use crate::arrays::{self, Input, Kind};
use crate::error::{self, guard};

/// Pairs per task of a parallel batch: large enough that a task's work (~0.1-3 ms) dwarfs rayon's
/// scheduling, small enough that two cores share a batch of a few thousand.
const CHUNK: usize = 1024;

pub(crate) enum Source {
    Model(ModelBuf),
    Parametric(Parametric),
    Builtin(Builtin),
    Merl(MerlTable),
    NbrdfJson(NbrdfNetwork),
}

/// A BRDF: a fitted `.nbrdf` model, a MERL table, an NBRDF-json network, a parametric model or a
/// built-in material. Directions are arrays of shape (3,) or (N, 3) (any real dtype, any array-like) in
/// the local shading frame (normal +z), `wi` toward the light, `wo` toward the viewer; values are in 1/sr without the cosine,
/// 0 below the horizon or for non-finite directions. Immutable; safe to share between threads.
#[pyclass(frozen, module = "nbrdf")]
pub struct Model {
    pub(crate) source: Source,
    /// The state of a model without point input, prepared once.
    uniform: Option<Prepared>,
    /// What it was made from, for `repr`.
    what: String,
}

/// How the BRDF varies over one call's pairs.
// One per call, borrowed by every chunk: boxing the prepared state would buy nothing.
#[allow(clippy::large_enum_variant)]
enum At {
    /// The same BRDF for every pair (a fixed BRDF, or a model at one point).
    Same(Option<Prepared>),
    /// A model with one point input per pair, `position_len` values each.
    PerPair(Vec<f32>),
}

/// The inputs of one call: two direction arguments (or a direction and `u`) as one `Vec3` per pair,
/// the BRDF at each pair, and the leading shape of the outputs.
struct Pairs {
    a: Vec<Vec3>,
    b: Vec<Vec3>,
    at: At,
    lead: Vec<usize>,
}

/// One sampled direction, or zeros where none was produced.
#[derive(Clone, Copy, Default)]
struct Sampled {
    wi: [f32; 3],
    weight: [f32; 3],
    pdf: f32,
}

impl From<Option<BsdfSample>> for Sampled {
    fn from(s: Option<BsdfSample>) -> Self {
        match s {
            Some(s) => Sampled { wi: s.wi.to_array(), weight: s.weight, pdf: s.pdf },
            None => Sampled::default(),
        }
    }
}

/// `out[i] = f(i)` over `0..n`, in parallel chunks of [`CHUNK`] where `n` is larger; `chunk` fills
/// one chunk `range` of the output.
fn par_fill<T: Clone + Default + Send>(
    n: usize,
    chunk: impl Fn(Range<usize>, &mut [T]) -> Result<(), nbrdf::Error> + Sync,
) -> Result<Vec<T>, nbrdf::Error> {
    let mut out = vec![T::default(); n];
    if n <= CHUNK {
        chunk(0..n, &mut out)?;
    } else {
        out.par_chunks_mut(CHUNK).enumerate().try_for_each(|(c, o)| chunk(c * CHUNK..c * CHUNK + o.len(), o))?;
    }
    Ok(out)
}

impl Model {
    pub(crate) fn new(source: Source, what: String) -> Result<Self, nbrdf::Error> {
        let uniform = match &source {
            Source::Model(buf) if buf.model().position_len() == 0 => Some(buf.model().prepare(&[])?),
            _ => None,
        };
        Ok(Model { source, uniform, what })
    }

    /// The BRDF that is the same at every point, for everything but `.nbrdf` models.
    pub(crate) fn fixed(&self) -> Option<&(dyn Brdf + Sync)> {
        Some(match &self.source {
            Source::Parametric(p) => p,
            Source::Builtin(b) => b,
            Source::Merl(t) => t,
            Source::NbrdfJson(n) => n,
            Source::Model(_) => return None,
        })
    }

    fn position_len_(&self) -> usize {
        match &self.source {
            Source::Model(buf) => buf.model().position_len(),
            _ => 0,
        }
    }

    /// The `points` argument checked against the BRDF: None where it takes none, else the input.
    fn points_arg<'py>(&self, points: Option<&Bound<'py, PyAny>>) -> PyResult<Option<Input<'py>>> {
        let k = self.position_len_();
        let Source::Model(buf) = &self.source else {
            return match points {
                None => Ok(None),
                Some(_) => Err(PyValueError::new_err(format!("points given, but this {} is the same at every point", self.kind()))),
            };
        };
        match points {
            None if k == 0 => Ok(None),
            None => Err(PyValueError::new_err(format!(
                "this model varies over the surface: pass points ({k} values per point: {})",
                if buf.header().n_vertices > 0 { "the intrinsic features, see position_features" } else { "the point x, y, z" }
            ))),
            Some(_) if k == 0 => Err(PyValueError::new_err("points given, but this model is the same at every point (position_len 0)")),
            Some(p) => Ok(Some(arrays::real(p, "points")?)),
        }
    }

    /// The BRDF at each pair of a call with the leading shape `lead`: one point (a `points` with a
    /// single row) is prepared once, more are read per pair.
    fn at(&self, points: Option<&Input<'_>>, lead: &[usize]) -> PyResult<At> {
        let Source::Model(buf) = &self.source else { return Ok(At::Same(None)) };
        Ok(match points {
            None => At::Same(self.uniform),
            Some(p) if p.lead().iter().product::<usize>() == 1 => {
                At::Same(Some(buf.model().prepare(&p.floats(p.lead())).map_err(error::core)?))
            }
            Some(p) => At::PerPair(p.floats(lead)),
        })
    }

    /// Runs `each(brdf, i)` for every pair `i` of `range`, with the BRDF at that pair's point.
    fn for_each(&self, at: &At, range: Range<usize>, mut each: impl FnMut(&dyn Brdf, usize)) -> Result<(), nbrdf::Error> {
        if let Some(b) = self.fixed() {
            range.for_each(|i| each(b, i));
            return Ok(());
        }
        let Source::Model(buf) = &self.source else { unreachable!("fixed() covers the rest") };
        let model = buf.model();
        match at {
            At::Same(p) => {
                let brdf = ModelAt { model, prepared: p.expect("a model's uniform or given point") };
                range.for_each(|i| each(&brdf, i));
            }
            At::PerPair(points) => {
                let k = model.position_len();
                let mut prepared = vec![Prepared::default(); range.len()];
                model.prepare_many(&points[range.start * k..range.end * k], &mut prepared)?;
                for (i, p) in range.zip(prepared) {
                    each(&ModelAt { model, prepared: p }, i);
                }
            }
        }
        Ok(())
    }

    fn eval_pairs(&self, at: &At, wi: &[Vec3], wo: &[Vec3]) -> Result<Vec<[f32; 3]>, nbrdf::Error> {
        par_fill(wi.len(), |r, out| match (&self.source, at) {
            // Many pairs at one point: the packet kernels, with the bits of `eval`.
            (Source::Model(buf), At::Same(Some(p))) => {
                buf.model().eval_many(p, &wi[r.clone()], &wo[r], out);
                Ok(())
            }
            _ => {
                let start = r.start;
                self.for_each(at, r, |b, i| out[i - start] = b.eval(wi[i], wo[i]))
            }
        })
    }

    /// Two direction arguments (or a direction and `u`) and the points of a call, their leading
    /// shapes broadcast by numpy's rules.
    fn inputs(
        &self,
        (a, a_name): (&Bound<'_, PyAny>, &str),
        (b, b_name): (&Bound<'_, PyAny>, &str),
        points: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Pairs> {
        let (a, b) = (arrays::real(a, a_name)?, arrays::real(b, b_name)?);
        let points = self.points_arg(points)?;
        let want3 = arrays::WANT3;
        let mut leads = vec![(a_name, a.rows_of(3, want3)?), (b_name, b.rows_of(3, want3)?)];
        if let Some(p) = &points {
            let k = self.position_len_();
            leads.push(("points", p.rows_of(k, &format!("({k},) for one point or (N, {k}) for one per direction pair"))?));
        }
        let lead = arrays::broadcast(&leads)?;
        let at = self.at(points.as_ref(), &lead)?;
        Ok(Pairs { a: a.vec3s(&lead), b: b.vec3s(&lead), at, lead })
    }

    /// `each(brdf, i)` for every pair `i < n` with the BRDF at its point, without the GIL, in parallel
    /// chunks.
    fn per_pair<T: Clone + Default + Send>(
        &self,
        py: Python<'_>,
        at: &At,
        n: usize,
        each: impl Fn(&dyn Brdf, usize) -> T + Sync,
    ) -> PyResult<Vec<T>> {
        py.detach(|| {
            par_fill(n, |r, out| {
                let start = r.start;
                self.for_each(at, r, |b, i| out[i - start] = each(b, i))
            })
        })
        .map_err(error::core)
    }

    pub(crate) fn kind(&self) -> &'static str {
        match &self.source {
            Source::Model(_) => "model",
            Source::Parametric(_) => "parametric",
            Source::Builtin(_) => "builtin",
            Source::Merl(_) => "merl",
            Source::NbrdfJson(_) => "nbrdf-json",
        }
    }
}

#[pymethods]
impl Model {
    /// Loads a BRDF file, chosen by extension: `.nbrdf` (a fitted model), `.json` (an NBRDF-json
    /// network) or `.binary` (a MERL table). The file is validated and copied.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        guard(|| {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
            let what = path.display().to_string();
            py.detach(|| {
                let source = match ext.as_str() {
                    "nbrdf" => Source::Model(ModelBuf::load(&path).map_err(error::core)?),
                    "json" => Source::NbrdfJson(NbrdfNetwork::load(&path).map_err(error::core)?),
                    "binary" => Source::Merl(MerlTable::read(&path).map_err(error::core)?),
                    _ => {
                        return Err(PyValueError::new_err(format!(
                            "{what}: unknown BRDF file type (expected .nbrdf, .json or .binary)"
                        )))
                    }
                };
                Model::new(source, what).map_err(error::core)
            })
        })
    }

    /// A BRDF from the bytes of a file: `format` is "nbrdf" (a model), "json" (an NBRDF-json network)
    /// or "binary" (a MERL table).
    #[staticmethod]
    #[pyo3(signature = (data, format = "nbrdf"))]
    fn from_bytes(py: Python<'_>, data: &Bound<'_, PyBytes>, format: &str) -> PyResult<Model> {
        guard(|| {
            let bytes = data.as_bytes().to_vec();
            let format = format.to_string();
            py.detach(|| {
                let source = match format.as_str() {
                    "nbrdf" => Source::Model(ModelBuf::from_bytes(&bytes).map_err(error::core)?),
                    "json" => Source::NbrdfJson(NbrdfNetwork::from_json_bytes(&bytes).map_err(error::core)?),
                    "binary" => Source::Merl(MerlTable::from_bytes(&bytes).map_err(error::core)?),
                    f => return Err(PyValueError::new_err(format!("unknown format {f:?} (expected \"nbrdf\", \"json\" or \"binary\")"))),
                };
                Model::new(source, format!("{} bytes of {format}", bytes.len())).map_err(error::core)
            })
        })
    }

    /// `f(wi, wo)` per pair, 1/sr, cosine not included: float32 of the arguments' broadcast leading
    /// shape followed by 3 ((N, 3) for (N, 3) directions, (3,) for single ones).
    #[pyo3(signature = (wi, wo, points = None))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        points: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        guard(|| {
            let Pairs { a: wi, b: wo, at, lead } = self.inputs((wi, "wi"), (wo, "wo"), points)?;
            let f = py.detach(|| self.eval_pairs(&at, &wi, &wo)).map_err(error::core)?;
            Ok(arrays::out3(py, &lead, f))
        })
    }

    /// Importance-samples `wi` for each view `wo` from three uniform numbers `u` in [0, 1) per row
    /// (`u[:, 0:2]` place the direction, `u[:, 2]` picks the lobe). Returns `(wi, weight, pdf)`:
    /// (N, 3), (N, 3) and (N,) float32 for N rows (the broadcast leading shape of `wo` and `u`; a
    /// single `wo` gives (3,), (3,) and a scalar), `weight = f cos / pdf`; a row where no direction was
    /// produced (`wo` below the horizon, a lobe reflected below it) is all zeros.
    #[pyo3(signature = (wo, u, points = None))]
    #[allow(clippy::type_complexity)]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wo: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        points: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(Bound<'py, PyArrayDyn<f32>>, Bound<'py, PyArrayDyn<f32>>, Bound<'py, PyAny>)> {
        guard(|| {
            let Pairs { a: wo, b: u, at, lead } = self.inputs((wo, "wo"), (u, "u"), points)?;
            let s: Vec<Sampled> = self.per_pair(py, &at, wo.len(), |b, i| b.sample(wo[i], u[i].to_array()).into())?;
            Ok((
                arrays::out3(py, &lead, s.iter().map(|s| s.wi).collect()),
                arrays::out3(py, &lead, s.iter().map(|s| s.weight).collect()),
                arrays::out1(py, &lead, s.iter().map(|s| s.pdf).collect())?,
            ))
        })
    }

    /// Density of `sample` at `wi` for the view `wo`, per unit solid angle: float32 of the arguments'
    /// broadcast leading shape ((N,) for (N, 3) directions, a scalar for single ones).
    #[pyo3(signature = (wi, wo, points = None))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        points: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        guard(|| {
            let Pairs { a: wi, b: wo, at, lead } = self.inputs((wi, "wi"), (wo, "wo"), points)?;
            let p = self.per_pair(py, &at, wi.len(), |b, i| b.pdf(wi[i], wo[i]))?;
            arrays::out1(py, &lead, p)
        })
    }

    /// The point inputs of an intrinsically encoded model at triangles `triangles` ((N, 3) vertex
    /// indices of the mesh the model was fitted on, any integer dtype) with barycentric weights `bary`
    /// ((N, 3) real), the two broadcast by numpy's rules, interpolated from the per-vertex table the
    /// file carries: (N, position_len) float32, what `points` takes.
    fn position_features<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        bary: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        guard(|| {
            let Source::Model(buf) = &self.source else {
                return Err(PyValueError::new_err(format!("a {} has no position features", self.kind())));
            };
            let (t, b) = (arrays::input(triangles, "triangles", Kind::Index)?, arrays::real(bary, "bary")?);
            let lead = arrays::broadcast(&[
                ("triangles", t.rows_of(3, "(3,) or (N, 3) vertex indices")?),
                ("bary", b.rows_of(3, "(3,) or (N, 3) barycentric weights")?),
            ])?;
            let (tri, bary) = (t.indices(&lead)?, b.rgbs(&lead));
            let n = bary.len();
            let model = buf.model();
            let k = model.position_len();
            let mut out = vec![0.0f32; n * k];
            py.detach(|| {
                out.par_chunks_mut(k.max(1)).zip(tri.par_chunks(3)).zip(&bary).try_for_each(|((o, t), b)| {
                    model.position_features([t[0], t[1], t[2]], *b, o)
                })
            })
            .map_err(error::core)?;
            debug_assert_eq!(out.len(), n * k);
            Ok(arrays::out(py, &lead, &[k], out))
        })
    }

    /// Whether `f(wi, wo) == f(wo, wi)` by construction (parametric models, models on the reciprocity
    /// map, MERL tables).
    #[getter]
    fn is_reciprocal(&self) -> bool {
        match &self.source {
            Source::Model(buf) => buf.model().is_reciprocal(),
            _ => self.fixed().is_some_and(|b| b.is_reciprocal()),
        }
    }

    /// "model", "merl", "nbrdf-json", "parametric" or "builtin".
    #[getter(kind)]
    fn kind_py(&self) -> &'static str {
        self.kind()
    }

    /// The parametric model's id ("lambert", "phong", "torrance-sparrow", "fmbrdf", "disney") for a
    /// parametric BRDF, else None.
    #[getter]
    fn parametric_kind(&self) -> Option<&'static str> {
        match &self.source {
            Source::Parametric(p) => Some(p.kind().id()),
            _ => None,
        }
    }

    /// Values each point input has: 0 for a BRDF that is the same everywhere, `k` for an intrinsic
    /// encoding, 3 (the point x, y, z) for an extrinsic one.
    #[getter]
    fn position_len(&self) -> usize {
        self.position_len_()
    }

    /// Whether the model's file carries a per-vertex table of intrinsic features (`position_features`).
    #[getter]
    fn has_position_table(&self) -> bool {
        matches!(&self.source, Source::Model(buf) if buf.header().n_vertices > 0)
    }

    /// Stored parameters: network weights (and per-object parameters), table entries, or the model's
    /// parameters.
    #[getter]
    fn n_parameters(&self) -> usize {
        match &self.source {
            Source::Model(buf) => {
                let h = buf.header();
                let object = match h.kind {
                    ModelKind::Parametric(k) => k.n_object(),
                    _ => 0,
                };
                h.n_weights() + object
            }
            Source::Merl(t) => t.raw().len(),
            Source::NbrdfJson(n) => n.widths().windows(2).map(|p| (p[0] + 1) * p[1]).sum(),
            Source::Parametric(p) => p.kind().n_raw() + p.kind().n_object(),
            Source::Builtin(_) => 0,
        }
    }

    fn __repr__(&self) -> String {
        let detail = match &self.source {
            Source::Model(buf) => format!("{:?}, position_len {}", buf.header().kind, buf.model().position_len()),
            Source::Parametric(p) => format!("{p:?}"),
            Source::Builtin(b) => b.id().to_string(),
            Source::Merl(_) | Source::NbrdfJson(_) => String::new(),
        };
        let sep = if detail.is_empty() || self.what.is_empty() { "" } else { ": " };
        format!("nbrdf.Model({}: {}{sep}{detail})", self.kind(), self.what)
    }
}

/// A fixed parametric or built-in BRDF.
fn fixed(source: Source, what: String) -> PyResult<Model> {
    Model::new(source, what).map_err(error::core)
}

/// Checks parametric parameters: finite, the albedos in [0, 1], the positive ones > 0.
fn check(model: &str, unit: &[(&str, &[f32])], positive: &[(&str, f32)]) -> PyResult<()> {
    for (name, v) in unit {
        if let Some(x) = v.iter().find(|x| !(0.0..=1.0).contains(*x)) {
            return Err(PyValueError::new_err(format!("{model}: {name} must lie in [0, 1], got {x}")));
        }
    }
    for (name, x) in positive {
        if !(x.is_finite() && *x > 0.0) {
            return Err(PyValueError::new_err(format!("{model}: {name} must be finite and > 0, got {x}")));
        }
    }
    Ok(())
}

/// Loads a MERL `.binary` table (nearest-bin lookup; sampled through a proxy fitted at load).
#[pyfunction]
pub(crate) fn merl(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
    guard(|| {
        let what = path.display().to_string();
        py.detach(|| Model::new(Source::Merl(MerlTable::read(&path).map_err(error::core)?), what).map_err(error::core))
    })
}

/// Loads an NBRDF-json network (Sztrajman et al. 2021; sampled through a proxy fitted at load).
#[pyfunction]
pub(crate) fn nbrdf_json(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
    guard(|| {
        let what = path.display().to_string();
        py.detach(|| Model::new(Source::NbrdfJson(NbrdfNetwork::load(&path).map_err(error::core)?), what).map_err(error::core))
    })
}

/// A built-in material: "two-lobe-metal", "clear-coat" or "velvet".
#[pyfunction]
pub(crate) fn builtin(id: &str) -> PyResult<Model> {
    let Some(b) = Builtin::from_id(id) else {
        let known: Vec<&str> = Builtin::ALL.iter().map(|b| b.id()).collect();
        return Err(PyValueError::new_err(format!("unknown built-in material {id:?} (known: {})", known.join(", "))));
    };
    fixed(Source::Builtin(b), String::new())
}

/// Lambert: `kd` (RGB albedo in [0, 1]).
#[pyfunction]
pub(crate) fn lambert(kd: [f32; 3]) -> PyResult<Model> {
    check("lambert", &[("kd", &kd)], &[])?;
    fixed(Source::Parametric(Parametric::Lambert(Lambert { kd })), String::new())
}

/// The energy-preserving modified Phong "RP": `kd`, `ks` (RGB, `kd + ks <= 1`), exponent `n`.
#[pyfunction]
pub(crate) fn phong(kd: [f32; 3], ks: [f32; 3], n: f32) -> PyResult<Model> {
    fixed(Source::Parametric(Parametric::Phong(Phong::new(kd, ks, n).map_err(error::core)?)), String::new())
}

/// Torrance-Sparrow: `kd`, `ks` (RGB in [0, 1]) and the Beckmann roughness `alpha > 0`.
#[pyfunction]
pub(crate) fn torrance_sparrow(kd: [f32; 3], ks: [f32; 3], alpha: f32) -> PyResult<Model> {
    check("torrance_sparrow", &[("kd", &kd), ("ks", &ks)], &[("alpha", alpha)])?;
    fixed(Source::Parametric(Parametric::TorranceSparrow(TorranceSparrow { kd, ks, alpha })), String::new())
}

/// The Fresnel microfacet BRDF (FMBRDF): `rho` (RGB), `ks` in [0, 1], and `alpha`, `beta`, `eta`,
/// `norm` > 0.
#[pyfunction]
pub(crate) fn fmbrdf(rho: [f32; 3], ks: f32, alpha: f32, beta: f32, eta: f32, norm: f32) -> PyResult<Model> {
    check("fmbrdf", &[("rho", &rho), ("ks", &[ks])], &[("alpha", alpha), ("beta", beta), ("eta", eta), ("norm", norm)])?;
    let p = FresnelMicrofacet { rho, ks, alpha, beta, eta, norm };
    fixed(Source::Parametric(Parametric::FresnelMicrofacet(p)), String::new())
}

/// Isotropic Disney (Burley 2012); every parameter in [0, 1].
#[pyfunction]
#[pyo3(signature = (base_color, subsurface = 0.0, metallic = 0.0, specular = 0.5, specular_tint = 0.0, roughness = 0.5,
                    sheen = 0.0, sheen_tint = 0.5, clearcoat = 0.0, clearcoat_gloss = 1.0))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn disney(
    base_color: [f32; 3],
    subsurface: f32,
    metallic: f32,
    specular: f32,
    specular_tint: f32,
    roughness: f32,
    sheen: f32,
    sheen_tint: f32,
    clearcoat: f32,
    clearcoat_gloss: f32,
) -> PyResult<Model> {
    let scalars = [subsurface, metallic, specular, specular_tint, roughness, sheen, sheen_tint, clearcoat, clearcoat_gloss];
    check("disney", &[("base_color", &base_color), ("every parameter", &scalars)], &[])?;
    let d = Disney { base_color, subsurface, metallic, specular, specular_tint, roughness, sheen, sheen_tint, clearcoat, clearcoat_gloss };
    fixed(Source::Parametric(Parametric::Disney(d)), String::new())
}

/// A parametric model from raw network outputs, as a parametric `.nbrdf` model's network predicts
/// them (docs/models.md: each raw value is mapped into its parameter's range, so any finite value is
/// valid): `kind` is "lambert", "phong", "torrance-sparrow", "fmbrdf" or "disney".
#[pyfunction]
#[pyo3(signature = (kind, raw, object = Vec::new()))]
pub(crate) fn parametric_from_raw(kind: &str, raw: Vec<f32>, object: Vec<f32>) -> PyResult<Model> {
    let k = ParametricKind::from_id(kind).ok_or_else(|| {
        let known: Vec<&str> = ParametricKind::ALL.iter().map(|k| k.id()).collect();
        PyValueError::new_err(format!("unknown parametric kind {kind:?} (known: {})", known.join(", ")))
    })?;
    if raw.len() != k.n_raw() || object.len() != k.n_object() {
        return Err(PyValueError::new_err(format!(
            "{kind} takes {} raw values and {} object parameters, got {} and {}",
            k.n_raw(),
            k.n_object(),
            raw.len(),
            object.len()
        )));
    }
    if raw.iter().chain(&object).any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!("{kind}: raw values must be finite")));
    }
    fixed(Source::Parametric(Parametric::from_raw(k, &raw, &object)), String::new())
}

/// The dense-layer kernel level in use ("avx512", "avx2", "neon" or "portable"); `NBRDF_KERNEL` set to
/// a level this CPU lacks is an error.
#[pyfunction]
pub(crate) fn kernel_level() -> PyResult<String> {
    nbrdf::kernels::requested().map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(nbrdf::kernels::level().to_string())
}
