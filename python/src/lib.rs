//! `nbrdf._nbrdf`: the Rust half of the `nbrdf` Python package. It evaluates, samples and queries the
//! density of every BRDF of the core over numpy arrays (the [`brdf::Model`] class), renders with the
//! core's path tracer, and runs the trainer's `synth`, `fit` and metrics; the Python half
//! (`python/nbrdf/`) adds argument handling, the type stubs and the Mitsuba 3 plugin.
//!
//! Every call copies its inputs while it holds the GIL, releases it for the work (`Python::detach`,
//! PyO3's name for `allow_threads`), and splits large batches across rayon's threads. Errors come back
//! as Python exceptions carrying the Rust error's message; a panic becomes a `RuntimeError` instead of
//! PyO3's `PanicException`, which `except Exception` would not catch.

mod arrays;
mod brdf;
mod error;
mod grad;
mod render;
mod train;

use pyo3::prelude::*;

#[pymodule]
fn _nbrdf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<brdf::Model>()?;
    m.add_function(wrap_pyfunction!(brdf::merl, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::nbrdf_json, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::builtin, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::from_spec, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::lambert, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::phong, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::torrance_sparrow, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::fmbrdf, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::disney, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::parametric_from_raw, m)?)?;
    m.add_function(wrap_pyfunction!(brdf::kernel_level, m)?)?;
    m.add_function(wrap_pyfunction!(grad::init_model, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(render::mesh, m)?)?;
    m.add_function(wrap_pyfunction!(train::synth, m)?)?;
    m.add_function(wrap_pyfunction!(train::fit, m)?)?;
    m.add_function(wrap_pyfunction!(train::study, m)?)?;
    m.add_function(wrap_pyfunction!(train::compare, m)?)?;
    m.add_function(wrap_pyfunction!(train::brdf_rmse, m)?)?;
    Ok(())
}
