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
use std::sync::Arc;

use numpy::PyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;

use nbrdf::any::{self, AnyBrdf, Format};
use nbrdf::model::ModelAt;
use nbrdf::parametric::ParametricKind;
use nbrdf::{Brdf, BsdfSample, Prepared, Vec3};

use crate::arrays::{self, Input, Kind};
use crate::error::{self, guard};

/// Pairs per task of a parallel batch: large enough that a task's work (~0.1-3 ms) dwarfs rayon's
/// scheduling, small enough that two cores share a batch of a few thousand.
const CHUNK: usize = 1024;

/// A BRDF: a fitted `.nbrdf` model, a MERL table, an NBRDF-json network, a parametric model or a
/// built-in material. Directions are arrays of shape (3,) or (N, 3) (any real dtype, any array-like) in
/// the local shading frame (normal +z), `wi` toward the light, `wo` toward the viewer; values are in 1/sr without the cosine,
/// 0 below the horizon or for non-finite directions. Immutable; safe to share between threads.
#[pyclass(frozen, module = "nbrdf")]
pub struct Model {
    /// The core's BRDF, shared with the renderer without a copy.
    pub(crate) brdf: Arc<AnyBrdf<'static>>,
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
    pub(crate) fn new(brdf: AnyBrdf<'static>, what: String) -> Self {
        Model { brdf: Arc::new(brdf), what }
    }

    /// The `points` argument checked against the BRDF: None where it takes none, else the input.
    fn points_arg<'py>(&self, points: Option<&Bound<'py, PyAny>>) -> PyResult<Option<Input<'py>>> {
        let k = self.brdf.position_len();
        let Some(model) = self.brdf.as_model() else {
            return match points {
                None => Ok(None),
                Some(_) => Err(PyValueError::new_err(format!("points given, but this {} is the same at every point", self.kind()))),
            };
        };
        match points {
            None if k == 0 => Ok(None),
            None => Err(PyValueError::new_err(format!(
                "this model varies over the surface: pass points ({k} values per point: {})",
                if model.header().n_vertices > 0 { "the intrinsic features, see position_features" } else { "the point x, y, z" }
            ))),
            Some(_) if k == 0 => Err(PyValueError::new_err("points given, but this model is the same at every point (position_len 0)")),
            Some(p) => Ok(Some(arrays::real(p, "points")?)),
        }
    }

    /// The BRDF at each pair of a call with the leading shape `lead`: one point (a `points` with a
    /// single row) is prepared once, more are read per pair.
    fn at(&self, points: Option<&Input<'_>>, lead: &[usize]) -> PyResult<At> {
        Ok(match points {
            None => At::Same(None),
            Some(p) if p.lead().iter().product::<usize>() == 1 => {
                At::Same(Some(self.brdf.prepare(&p.floats(p.lead())).map_err(error::core)?))
            }
            Some(p) => At::PerPair(p.floats(lead)),
        })
    }

    /// Runs `each(brdf, i)` for every pair `i` of `range`, with the BRDF at that pair's point.
    fn for_each(&self, at: &At, range: Range<usize>, mut each: impl FnMut(&dyn Brdf, usize)) -> Result<(), nbrdf::Error> {
        match at {
            At::Same(p) => {
                let brdf = self.brdf.at_prepared(p.as_ref()).expect("points_arg asks a varying model for points");
                range.for_each(|i| each(&brdf, i));
            }
            At::PerPair(points) => {
                let model = self.brdf.as_model().expect("points only for models");
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
        par_fill(wi.len(), |r, out| match at {
            // Many pairs at one point of a model: the packet kernels, with the bits of `eval`.
            At::Same(p) if self.brdf.as_model().is_some() => self.brdf.eval_many_prepared(p.as_ref(), &wi[r.clone()], &wo[r], out),
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
            let k = self.brdf.position_len();
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
        self.brdf.info().kind.id()
    }
}

#[pymethods]
impl Model {
    /// Loads a BRDF file, chosen by extension: `.nbrdf` (a fitted model), `.json` (an NBRDF-json
    /// network) or `.binary` (a MERL table). The file is validated and copied.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        guard(|| {
            let what = path.display().to_string();
            py.detach(|| Ok(Model::new(AnyBrdf::load(&path).map_err(error::core)?, what)))
        })
    }

    /// A BRDF from the bytes of a file: `format` is "nbrdf" (a model), "json" (an NBRDF-json network)
    /// or "binary" (a MERL table).
    #[staticmethod]
    #[pyo3(signature = (data, format = "nbrdf"))]
    fn from_bytes(py: Python<'_>, data: &Bound<'_, PyBytes>, format: &str) -> PyResult<Model> {
        guard(|| {
            let Some(f) = Format::from_extension(format) else {
                return Err(PyValueError::new_err(format!("unknown format {format:?} (expected \"nbrdf\", \"json\" or \"binary\")")));
            };
            let bytes = data.as_bytes().to_vec();
            let what = format!("{} bytes of {format}", bytes.len());
            py.detach(|| Ok(Model::new(AnyBrdf::from_bytes(&bytes, f).map_err(error::core)?, what)))
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
            let Some(model) = self.brdf.as_model() else {
                return Err(PyValueError::new_err(format!("a {} has no position features", self.kind())));
            };
            let (t, b) = (arrays::input(triangles, "triangles", Kind::Index)?, arrays::real(bary, "bary")?);
            let lead = arrays::broadcast(&[
                ("triangles", t.rows_of(3, "(3,) or (N, 3) vertex indices")?),
                ("bary", b.rows_of(3, "(3,) or (N, 3) barycentric weights")?),
            ])?;
            let (tri, bary) = (t.indices(&lead)?, b.rgbs(&lead));
            let n = bary.len();
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
        self.brdf.info().reciprocal
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
        self.brdf.as_parametric().map(|p| p.kind().id())
    }

    /// Values each point input has: 0 for a BRDF that is the same everywhere, `k` for an intrinsic
    /// encoding, 3 (the point x, y, z) for an extrinsic one.
    #[getter]
    fn position_len(&self) -> usize {
        self.brdf.position_len()
    }

    /// The albedo table of an energy-bounded model (`fit(..., energy_bound=True)`): an upper bound of
    /// the albedo per cell of cos θ (cell j: cos θ in (1 − (j+1)/32, 1 − j/32]) and channel, shape
    /// (32, 3); evaluation divides f by max(1, Â(θi), Â(θo)). `None` for an unbounded BRDF.
    #[getter]
    fn albedo_bound<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArrayDyn<f32>>> {
        let bound = *self.brdf.as_model()?.albedo_bound()?;
        Some(arrays::out3(py, &[bound.cells.len()], bound.cells.to_vec()))
    }

    /// Whether the model's file carries a per-vertex table of intrinsic features (`position_features`).
    #[getter]
    fn has_position_table(&self) -> bool {
        self.brdf.info().has_position_table
    }

    /// Stored parameters: network weights (and per-object parameters), table entries, or the model's
    /// parameters.
    #[getter]
    fn n_parameters(&self) -> usize {
        self.brdf.info().n_parameters
    }

    /// The network weights (and per-object parameters) of a fitted `.nbrdf` model in file order:
    /// (n_parameters,) float32, a copy. ValueError for a BRDF without a network of the trainer's.
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let w = crate::grad::weights(self)?;
        Ok(arrays::out(py, &[], &[w.len()], w))
    }

    /// The same model (networks, sampler, position table) with other `weights` ((n_parameters,),
    /// any real dtype, finite), stored in single precision. An energy bound is dropped: it bounded the
    /// old weights' albedo (bound the result again with `trainer bound`).
    fn with_weights(&self, py: Python<'_>, weights: &Bound<'_, PyAny>) -> PyResult<Model> {
        guard(|| crate::grad::with_weights(py, self, weights))
    }

    /// The same model with its importance-sampling proxies fitted anew to its present weights (as
    /// the trainer's export fits them): for a model whose weights were optimised elsewhere
    /// (`with_weights`, the Mitsuba plugin's `differentiable` mode) before it is saved.
    fn with_fitted_sampler(&self, py: Python<'_>) -> PyResult<Model> {
        guard(|| crate::grad::with_fitted_sampler(py, self))
    }

    /// Writes a fitted `.nbrdf` model (e.g. one made by `with_weights`) to `path`, atomically.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        guard(|| crate::grad::save(py, self, path))
    }

    /// `∂L/∂w`, (n_parameters,) float32, for a loss `L` whose derivative with respect to `f(wi, wo)`
    /// (`eval`'s values) is `grad` at each pair: the sum over pairs of `grad · ∂f/∂w`, by the trainer's
    /// backward pass. `wi`, `wo`, `grad` (and `points`) broadcast like `eval`'s arguments.
    #[pyo3(signature = (wi, wo, grad, points = None))]
    fn weight_gradient<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        grad: &Bound<'py, PyAny>,
        points: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        guard(|| {
            let g = crate::grad::weight_gradient(py, self, wi, wo, grad, points)?;
            Ok(arrays::out(py, &[], &[g.len()], g))
        })
    }

    fn __repr__(&self) -> String {
        let b = &self.brdf;
        let detail = match (b.as_model(), b.as_parametric(), b.as_builtin()) {
            (Some(m), _, _) => format!("{:?}, position_len {}", m.header().kind, m.position_len()),
            (_, Some(p), _) => format!("{p:?}"),
            (_, _, Some(b)) => b.id().to_string(),
            _ => String::new(),
        };
        let sep = if detail.is_empty() || self.what.is_empty() { "" } else { ": " };
        format!("nbrdf.Model({}: {}{sep}{detail})", self.kind(), self.what)
    }
}

/// A parametric model from its natural parameters, checked by the core.
fn params(kind: ParametricKind, v: &[f32]) -> PyResult<Model> {
    Ok(Model::new(AnyBrdf::from_params(kind, v).map_err(error::core)?, String::new()))
}

/// Loads a MERL `.binary` table (nearest-bin lookup; sampled through a proxy fitted at load).
#[pyfunction]
pub(crate) fn merl(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
    guard(|| {
        let what = path.display().to_string();
        py.detach(|| Ok(Model::new(AnyBrdf::load_as(&path, Format::Merl).map_err(error::core)?, what)))
    })
}

/// Loads an NBRDF-json network (Sztrajman et al. 2021; sampled through a proxy fitted at load).
#[pyfunction]
pub(crate) fn nbrdf_json(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
    guard(|| {
        let what = path.display().to_string();
        py.detach(|| Ok(Model::new(AnyBrdf::load_as(&path, Format::NbrdfJson).map_err(error::core)?, what)))
    })
}

/// A BRDF from a spec, the path tracer's `--brdf` syntax: `lambert:R,G,B`, `phong:KD×3,KS×3,N`,
/// `torrance-sparrow:KD×3,KS×3,ALPHA`, `fmbrdf:RHO×3,KS,ALPHA,BETA,ETA,NORM`, `disney:` its 12 values,
/// `raw:KIND:V,...`, `builtin:ID`, `merl:FILE`, `json:FILE`, `model:FILE`, or a `.nbrdf`, `.binary`
/// or `.json` file (the grammar is the core's `nbrdf::any`).
#[pyfunction]
pub(crate) fn from_spec(py: Python<'_>, spec: &str) -> PyResult<Model> {
    guard(|| {
        let spec = spec.to_string();
        py.detach(|| Ok(Model::new(AnyBrdf::from_spec(&spec).map_err(error::core)?, spec.clone())))
    })
}

/// A built-in material: "two-lobe-metal", "clear-coat" or "velvet".
#[pyfunction]
pub(crate) fn builtin(id: &str) -> PyResult<Model> {
    Ok(Model::new(AnyBrdf::builtin_id(id).map_err(error::core)?, String::new()))
}

/// Lambert: `kd` (RGB albedo in [0, 1]).
#[pyfunction]
pub(crate) fn lambert(kd: [f32; 3]) -> PyResult<Model> {
    params(ParametricKind::Lambert, &kd)
}

/// The energy-preserving modified Phong "RP": `kd`, `ks` (RGB, `kd + ks <= 1`), exponent `n`.
#[pyfunction]
pub(crate) fn phong(kd: [f32; 3], ks: [f32; 3], n: f32) -> PyResult<Model> {
    params(ParametricKind::Phong, &[kd[0], kd[1], kd[2], ks[0], ks[1], ks[2], n])
}

/// Torrance-Sparrow: `kd`, `ks` (RGB in [0, 1]) and the Beckmann roughness `alpha > 0`.
#[pyfunction]
pub(crate) fn torrance_sparrow(kd: [f32; 3], ks: [f32; 3], alpha: f32) -> PyResult<Model> {
    params(ParametricKind::TorranceSparrow, &[kd[0], kd[1], kd[2], ks[0], ks[1], ks[2], alpha])
}

/// The Fresnel microfacet BRDF (FMBRDF): `rho` (RGB), `ks` in [0, 1], and `alpha`, `beta`, `eta`,
/// `norm` > 0.
#[pyfunction]
pub(crate) fn fmbrdf(rho: [f32; 3], ks: f32, alpha: f32, beta: f32, eta: f32, norm: f32) -> PyResult<Model> {
    params(ParametricKind::FresnelMicrofacet, &[rho[0], rho[1], rho[2], ks, alpha, beta, eta, norm])
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
    let [r, g, b] = base_color;
    params(
        ParametricKind::Disney,
        &[r, g, b, subsurface, metallic, specular, specular_tint, roughness, sheen, sheen_tint, clearcoat, clearcoat_gloss],
    )
}

/// A parametric model from raw network outputs, as a parametric `.nbrdf` model's network predicts
/// them (docs/models.md: each raw value is mapped into its parameter's range, so any finite value is
/// valid): `kind` is "lambert", "phong", "torrance-sparrow", "fmbrdf" or "disney" (or "rp", "ts").
#[pyfunction]
#[pyo3(signature = (kind, raw, object = Vec::new()))]
pub(crate) fn parametric_from_raw(kind: &str, raw: Vec<f32>, object: Vec<f32>) -> PyResult<Model> {
    let k = any::parametric_kind(kind).map_err(error::core)?;
    Ok(Model::new(AnyBrdf::from_raw(k, &raw, &object).map_err(error::core)?, String::new()))
}

/// The dense-layer kernel level in use ("avx512", "avx2", "neon" or "portable"); `NBRDF_KERNEL` set to
/// a level this CPU lacks is an error.
#[pyfunction]
pub(crate) fn kernel_level() -> PyResult<String> {
    nbrdf::kernels::requested().map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(nbrdf::kernels::level().to_string())
}
