//! Differentiating a fitted model with respect to its weights, for renderers that optimise a BRDF
//! themselves (the Mitsuba plugin's `differentiable` mode): a `.nbrdf` model's weight vector, the same
//! model with other weights, a freshly initialised model, and `∂L/∂w` for a caller's `∂L/∂f` by the
//! trainer's backward pass ([`trainer::engine::vjp`]).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use nbrdf::any::AnyBrdf;
use nbrdf::file::Precision;
use trainer::engine::vjp::{self, Cotangents};
use trainer::models::export;
use trainer::names::{parse_kind, parse_position, parse_reciprocity};

use crate::arrays::{self, WANT3};
use crate::brdf::Model;
use crate::error::{self, guard};

/// The core model behind `m`, or a ValueError saying that this BRDF has no weights.
fn network<'a>(m: &'a Model, what: &str) -> PyResult<nbrdf::model::Model<'a>> {
    m.brdf.as_model().ok_or_else(|| {
        PyValueError::new_err(format!(
            "{what}: this {} has no network weights (only fitted .nbrdf models have)",
            m.kind()
        ))
    })
}

/// `Model.weights`: the weight vector in file order.
pub(crate) fn weights(m: &Model) -> PyResult<Vec<f32>> {
    Ok(export::core_weights(&network(m, "weights")?))
}

/// `Model.with_weights`: the same model (header, sampler, position table) with `w`, stored in single
/// precision, without the energy bound (it bounded the old weights' albedo).
pub(crate) fn with_weights(py: Python<'_>, m: &Model, w: &Bound<'_, PyAny>) -> PyResult<Model> {
    let core = network(m, "with_weights")?;
    let w = arrays::real(w, "weights")?;
    let n = core.header().n_weights();
    if w.shape() != [n] {
        return Err(w.shape_error(&format!("({n},), this model's weight count")));
    }
    let values = w.floats(&[]);
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!("weights[{i}] is {}, not a finite number", values[i])));
    }
    let mut header = *core.header();
    header.precision = Precision::F32;
    header.albedo_bound = None;
    let table = core.position_table();
    py.detach(|| {
        let bytes = nbrdf::file::encode(&header, &values, (!table.is_empty()).then_some(table)).map_err(error::core)?;
        Ok(Model::new(nbrdf::ModelBuf::from_bytes(&bytes).and_then(AnyBrdf::model).map_err(error::core)?, "new weights".into()))
    })
}

/// `Model.with_fitted_sampler`: the same model with its sampling proxies fitted anew to its present
/// weights, as the trainer's export fits them (over points of its position table, or of the unit
/// sphere for an extrinsic model).
pub(crate) fn with_fitted_sampler(py: Python<'_>, m: &Model) -> PyResult<Model> {
    let core = network(m, "with_fitted_sampler")?;
    let table = core.position_table();
    let (bound, hash) = (core.albedo_bound().copied(), core.header().mesh_hash);
    py.detach(|| {
        let model = export::from_core(&core).map_err(error::trainer)?;
        let mut bytes = export::encode(&model, (!table.is_empty()).then_some(table)).map_err(error::trainer)?;
        if let Some(h) = hash {
            bytes = nbrdf::file::record_mesh(&bytes, h).map_err(error::core)?;
        }
        if bound.is_some() {
            bytes = nbrdf::file::set_albedo_bound(&bytes, bound).map_err(error::core)?;
        }
        Ok(Model::new(nbrdf::ModelBuf::from_bytes(&bytes).and_then(AnyBrdf::model).map_err(error::core)?, "refitted sampler".into()))
    })
}

/// `Model.save`: the model's file, written atomically (a `.nbrdf` that the core, C, the shaders and
/// the path tracer load).
pub(crate) fn save(py: Python<'_>, m: &Model, path: std::path::PathBuf) -> PyResult<()> {
    let core = network(m, "save")?;
    let table = core.position_table();
    py.detach(|| {
        let bytes = nbrdf::file::encode(core.header(), &export::core_weights(&core), (!table.is_empty()).then_some(table))
            .map_err(error::core)?;
        nbrdf::file::save(&path, &bytes).map_err(error::core)
    })
}

/// `Model.weight_gradient`: `∂L/∂w` for `∂L/∂f = grad` at the pairs `(wi, wo)` (and `points`).
pub(crate) fn weight_gradient(
    py: Python<'_>,
    m: &Model,
    wi: &Bound<'_, PyAny>,
    wo: &Bound<'_, PyAny>,
    grad: &Bound<'_, PyAny>,
    points: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<f32>> {
    let core = network(m, "weight_gradient")?;
    if core.albedo_bound().is_some() {
        return Err(PyValueError::new_err(
            "weight_gradient: this model is energy-bounded, and the bound was fitted to its present weights; \
             differentiate the unbounded model (model.with_weights(model.weights)) and bound the result after the fit",
        ));
    }
    let (wi, wo, grad) = (arrays::real(wi, "wi")?, arrays::real(wo, "wo")?, arrays::real(grad, "grad")?);
    let k = core.position_len();
    let mut leads = vec![("wi", wi.rows_of(3, WANT3)?), ("wo", wo.rows_of(3, WANT3)?), ("grad", grad.rows_of(3, WANT3)?)];
    let points = match (points, k) {
        (None, 0) => None,
        (None, _) => return Err(PyValueError::new_err(format!("this model varies over the surface: pass points ({k} values per pair)"))),
        (Some(_), 0) => return Err(PyValueError::new_err("points given, but this model is the same at every point (position_len 0)")),
        (Some(p), _) => Some(arrays::real(p, "points")?),
    };
    if let Some(p) = &points {
        leads.push(("points", p.rows_of(k, &format!("({k},) or (N, {k})"))?));
    }
    let lead = arrays::broadcast(&leads)?;
    let position = points.map_or_else(Vec::new, |p| p.floats(&lead));
    let (wi, wo, grad) = (wi.vec3s(&lead), wo.vec3s(&lead), grad.rgbs(&lead));
    py.detach(|| {
        let model = export::from_core(&core).map_err(error::trainer)?;
        vjp::weight_gradient(&model, &Cotangents { position: &position, wi: &wi, wo: &wo, grad_f: &grad }).map_err(error::trainer)
    })
}

/// `nbrdf.init_model`: a freshly initialised model of the variant the arguments name (`fit`'s
/// `model`, `reciprocity`, `enhanced`, `position`, `angle_frequencies`, `direction_layers`), its
/// outputs starting where a fit of images of median `median` starts.
#[pyfunction]
#[pyo3(signature = (model, *, reciprocity = None, enhanced = false, position = None, angle_frequencies = None,
                    direction_layers = None, seed = 0, median = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn init_model(
    py: Python<'_>,
    model: &str,
    reciprocity: Option<&str>,
    enhanced: bool,
    position: Option<&str>,
    angle_frequencies: Option<u8>,
    direction_layers: Option<u8>,
    seed: u64,
    median: Option<f32>,
) -> PyResult<Model> {
    guard(|| {
        let named = |name: &str, e: trainer::Error| PyValueError::new_err(format!("{name}: {e}"));
        let mut a = trainer::commands::fit::ModelArgs::new(parse_kind(model).map_err(|e| named("model", e))?);
        if let Some(r) = reciprocity {
            a.reciprocity = parse_reciprocity(r).map_err(|e| named("reciprocity", e))?;
        }
        a.position = match position {
            Some(p) => parse_position(p).map_err(|e| named("position", e))?,
            // No mesh to take eigenfunctions of: the point itself.
            None => trainer::models::PositionEncoding::Extrinsic { frequencies: 6 },
        };
        if matches!(a.position, trainer::models::PositionEncoding::Intrinsic { .. }) {
            return Err(PyValueError::new_err(
                "position: an intrinsic model needs its mesh's per-vertex table, which only a fit writes; use \"extrinsic:F\" or \"uniform\"",
            ));
        }
        if median.is_some_and(|m| !(m.is_finite() && m > 0.0)) {
            return Err(PyValueError::new_err(format!("median must be a positive number, not {}", median.unwrap_or_default())));
        }
        let config = trainer::commands::config(
            a.model,
            a.reciprocity,
            enhanced,
            a.position,
            angle_frequencies.unwrap_or(a.angle_frequencies),
            direction_layers,
        )
        .map_err(error::trainer)?;
        let what = format!("initial {} (seed {seed})", config.name());
        py.detach(|| {
            let bytes = export::initial(config, seed, median).map_err(error::trainer)?;
            Ok(Model::new(nbrdf::ModelBuf::from_bytes(&bytes).and_then(AnyBrdf::model).map_err(error::core)?, what))
        })
    })
}
