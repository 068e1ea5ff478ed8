//! The path tracer and meshes of `nbrdf-scene` from Python: `render` draws one mesh with a BRDF the way
//! `scene/examples/path_tracer.rs` does (and returns each pixel's Monte Carlo variance, so that renderings
//! of other renderers can be compared within their error), `mesh` hands the same triangles to
//! another renderer.

use std::path::PathBuf;

use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;

use nbrdf_scene::pathtrace::{render as trace, Environment, Material, Options, Sampling, Scene, MAX_DEPTH, MAX_SPP};
use nbrdf_scene::scene::{builtin::BuiltinMesh, Camera, DirectionalLight, Geometry, Mesh};
use nbrdf::Vec3;

use crate::arrays;
use crate::brdf::Model;
use crate::error::{self, guard};

/// A built-in mesh id as it is, a file scaled into the unit sphere (as the path tracer example does).
fn load_mesh(spec: &str) -> Result<Mesh, nbrdf::Error> {
    match BuiltinMesh::from_id(spec) {
        Some(b) => Ok(b.mesh()),
        None => Ok(Mesh::load(spec)?.normalized().0),
    }
}

/// A material of the renderer from a BRDF (shared, not copied).
fn material(brdf: &Model) -> Result<Material, nbrdf::Error> {
    Material::new(brdf.brdf.clone())
}

/// The vertices (V, 3) float32, unit vertex normals (V, 3) float32 and counter-clockwise triangles
/// (T, 3) uint32 of `mesh` ("sphere", "torus", "grooved", or an OBJ/PLY file, scaled into the unit
/// sphere): the geometry `render` draws, for another renderer to draw too.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub(crate) fn mesh<'py>(
    py: Python<'py>,
    mesh: &str,
) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<u32>>)> {
    guard(|| {
        let spec = mesh.to_string();
        let m = py.detach(|| load_mesh(&spec)).map_err(error::core)?;
        let v = |x: &[Vec3]| Array2::from_shape_vec((x.len(), 3), x.iter().flat_map(|p| p.to_array()).collect()).expect("3 per row");
        let t = Array2::from_shape_vec((m.triangles.len(), 3), m.triangles.iter().flatten().copied().collect()).expect("3 per row");
        Ok((v(&m.positions).into_pyarray(py), v(&m.normals).into_pyarray(py), t.into_pyarray(py)))
    })
}

/// `x` as an integer in `lo..=hi`: `TypeError` for a non-integer, `OverflowError` for one past the
/// 128-bit range, `ValueError` outside `lo..=hi`, each naming `name`.
fn integer(x: &Bound<'_, PyAny>, name: &str, lo: u64, hi: u64) -> PyResult<u64> {
    let v: i128 = x.extract().map_err(|e: PyErr| {
        if e.is_instance_of::<PyOverflowError>(x.py()) {
            PyOverflowError::new_err(format!("{name} {x}: must lie in {lo}..={hi}"))
        } else {
            let ty = x.get_type().name().map(|n| n.to_string()).unwrap_or_default();
            PyTypeError::new_err(format!("{name}: expected an integer, got {ty}"))
        }
    })?;
    match u64::try_from(v) {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v),
        _ => Err(PyValueError::new_err(format!("{name} {v}: must lie in {lo}..={hi}"))),
    }
}

/// `lights` as (direction, RGB intensity) pairs: any array-like of shape (L, 2, 3), or an empty one.
fn light_pairs(lights: &Bound<'_, PyAny>) -> PyResult<Vec<([f32; 3], [f32; 3])>> {
    let a = arrays::real(lights, "lights")?;
    let want = "(L, 2, 3): (direction toward the light, RGB intensity) per light";
    match *a.shape() {
        [0] | [0, ..] => Ok(Vec::new()),
        [l, 2, 3] => Ok(a.floats(&[l, 2]).chunks_exact(6).map(|c| ([c[0], c[1], c[2]], [c[3], c[4], c[5]])).collect()),
        _ => Err(a.shape_error(want)),
    }
}

/// Path-traces `mesh` with `brdf` (see `nbrdf.render` in the package for the arguments); returns the
/// mean radiance per pixel and the variance of that mean, both (height, width, 3) float32.
#[pyfunction]
#[pyo3(signature = (brdf, mesh, eye, target, up, fov, width, height, lights, env_color, env, spp, max_depth, seed, sampling))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn render<'py>(
    py: Python<'py>,
    brdf: &Model,
    mesh: &str,
    eye: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    up: &Bound<'_, PyAny>,
    fov: f32,
    width: &Bound<'_, PyAny>,
    height: &Bound<'_, PyAny>,
    lights: &Bound<'_, PyAny>,
    env_color: Option<&Bound<'_, PyAny>>,
    env: Option<PathBuf>,
    spp: &Bound<'_, PyAny>,
    max_depth: &Bound<'_, PyAny>,
    seed: &Bound<'_, PyAny>,
    sampling: &str,
) -> PyResult<(Bound<'py, PyArray3<f32>>, Bound<'py, PyArray3<f32>>)> {
    guard(|| {
        // Integers are checked against the path tracer's limits before any work, naming the argument.
        // The ranges fit u32, so the narrowing casts are exact.
        let width = integer(width, "width", 1, 16384)? as u32;
        let height = integer(height, "height", 1, 16384)? as u32;
        let spp = integer(spp, "spp", 1, MAX_SPP.into())? as u32;
        let max_depth = integer(max_depth, "max_depth", 1, MAX_DEPTH.into())? as u32;
        let seed = integer(seed, "seed", 0, u64::MAX)?;
        let (eye, target, up) = (arrays::vec3(eye, "eye")?, arrays::vec3(target, "target")?, arrays::vec3(up, "up")?);
        let env_color = env_color.map(|c| arrays::vec3(c, "env_color")).transpose()?;
        let lights = light_pairs(lights)?;
        let sampling = match sampling {
            "native" => Sampling::Native,
            "cosine" => Sampling::Cosine,
            s => return Err(PyValueError::new_err(format!("sampling {s:?}: expected \"native\" or \"cosine\""))),
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(PyValueError::new_err(format!("fov {fov}: must lie in (0, 180) degrees")));
        }
        let lights: Vec<DirectionalLight> = lights
            .iter()
            .map(|(d, c)| {
                if c.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(PyValueError::new_err(format!("light intensity {c:?}: must be finite and >= 0")));
                }
                DirectionalLight::new(Vec3::from_array(*d), *c)
                    .ok_or_else(|| PyValueError::new_err(format!("light direction {d:?}: zero or not finite")))
            })
            .collect::<PyResult<_>>()?;
        if env_color.is_some_and(|c| c.iter().any(|x| !(x.is_finite() && *x >= 0.0))) {
            return Err(PyValueError::new_err("env_color: radiance must be finite and >= 0"));
        }
        if lights.is_empty() && env_color.is_none() && env.is_none() {
            return Err(PyValueError::new_err("no light: give lights, env_color or env"));
        }
        let mesh = mesh.to_string();
        let rendered = py
            .detach(|| -> Result<_, nbrdf::Error> {
                let geometry = Geometry::new(load_mesh(&mesh)?)?;
                let material = material(brdf)?.with_sampling(sampling);
                material.check_mesh(&geometry.mesh)?;
                let env = match (&env, env_color) {
                    (Some(p), _) => Some(Environment::load_exr(p)?),
                    (None, Some(c)) => Some(Environment::Constant(c)),
                    (None, None) => None,
                };
                let camera =
                    Camera::look_at(Vec3::from_array(eye), Vec3::from_array(target), Vec3::from_array(up), fov.to_radians(), width, height)?;
                let scene = Scene { geometry: &geometry, material: &material, lights: &lights, env: env.as_ref(), camera: &camera };
                let options = Options { spp, max_depth, seed, ..Options::default() };
                Ok(trace(&scene, &options, &|_| {}))
            })
            .map_err(error::core)?;
        let (w, h) = (width as usize, height as usize);
        let image = Array3::from_shape_vec((h, w, 3), rendered.image.data.into_flattened()).expect("h×w pixels");
        let variance = Array3::from_shape_vec((h, w, 3), rendered.variance.into_flattened()).expect("h×w pixels");
        Ok((image.into_pyarray(py), variance.into_pyarray(py)))
    })
}
