//! The trainer's work from Python: `synth` and `fit` build the trainer's typed requests
//! (`SynthArgs`, `FitArgs`) from keyword arguments — unset ones keep the request's defaults, which are
//! the command line's — and run them with the trainer's own checks; `compare` and `brdf_rmse` are the
//! study's metrics.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use nbrdf_scene::image::RgbImage;
use trainer::commands::fit::FitArgs;
use trainer::names::{parse_kind, parse_position, parse_reciprocity};
use trainer::dataset::synth::SynthArgs;
use trainer::metrics::{brdf_rmse::cube_root_rmse, ImageMetrics, Lpips, MaybeMetric};

use crate::arrays;
use crate::error::{self, guard};

/// A trainer parse error as `ValueError` naming the keyword argument.
fn named<T>(name: &str, r: trainer::Result<T>) -> PyResult<T> {
    r.map_err(|e| PyValueError::new_err(format!("{name}: {e}")))
}

/// Runs `work` on a thread of its own while this one, the caller's, waits without the GIL and, every
/// 50 ms, looks for Python's signals and hands `progress` (a callable, if any) the run's `(done,
/// total)` when it moved ([`trainer::progress`]): Ctrl-C or a notebook's interrupt — or an exception
/// from `progress` — asks the work to stop ([`trainer::cancel`]), waits for it to drop what it staged,
/// and raises.
fn interruptible<T: Send>(py: Python<'_>, progress: Option<&Bound<'_, PyAny>>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    // Nothing to report until the work starts its run (the last run's totals are not this one's).
    trainer::progress::start(0, 0);
    std::thread::scope(|s| {
        let worker = s.spawn(work);
        let mut shown = None;
        let report = |shown: &mut Option<(u64, u64)>| -> PyResult<()> {
            let now = trainer::progress::get();
            match progress {
                Some(callback) if *shown != Some(now) && now.1 > 0 => {
                    *shown = Some(now);
                    callback.call1(now).map(drop)
                }
                _ => Ok(()),
            }
        };
        while !worker.is_finished() {
            py.detach(|| std::thread::sleep(std::time::Duration::from_millis(50)));
            if let Err(stop) = py.check_signals().and_then(|()| report(&mut shown)) {
                trainer::cancel::request();
                let _ = py.detach(|| worker.join());
                trainer::cancel::clear();
                return Err(stop);
            }
        }
        // A panic in the work is re-raised here, inside `guard`, which reports it.
        let result = worker.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
        report(&mut shown)?;
        Ok(result)
    })
}

/// `trainer synth`: renders the data set that the keyword arguments describe (`trainer synth`'s
/// flags; unset ones keep its defaults) into `out`; returns `out`. Interruptible; `progress` receives
/// `(images written, images)`.
#[pyfunction]
#[pyo3(signature = (out, *, mesh = None, material = None, size = None, views = None, train_views = None,
                    train_lights = None, test_lights = None, sigma = None, seed = None, fov = None,
                    light_intensity = None, target_median = None, force_shadows = false, interreflections = None,
                    quiet = false, progress = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn synth(
    py: Python<'_>,
    out: PathBuf,
    mesh: Option<PathBuf>,
    material: Option<String>,
    size: Option<u32>,
    views: Option<usize>,
    train_views: Option<usize>,
    train_lights: Option<usize>,
    test_lights: Option<usize>,
    sigma: Option<f32>,
    seed: Option<u64>,
    fov: Option<f32>,
    light_intensity: Option<f32>,
    target_median: Option<f32>,
    force_shadows: bool,
    interreflections: Option<u32>,
    quiet: bool,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<PathBuf> {
    guard(|| {
        if light_intensity.is_some() && target_median.is_some() {
            return Err(PyValueError::new_err("light_intensity and target_median exclude each other (target_median chooses the intensity)"));
        }
        let mut a = SynthArgs::new(out);
        if let Some(m) = mesh {
            a.mesh = m.to_string_lossy().into_owned();
        }
        a.material = material.unwrap_or(a.material);
        a.size = size.unwrap_or(a.size);
        a.views = views.unwrap_or(a.views);
        a.train_views = train_views.unwrap_or(a.train_views);
        a.train_lights = train_lights.unwrap_or(a.train_lights);
        a.test_lights = test_lights.unwrap_or(a.test_lights);
        a.sigma = sigma.unwrap_or(a.sigma);
        a.seed = seed.unwrap_or(a.seed);
        a.fov = fov.unwrap_or(a.fov);
        a.light_intensity = light_intensity.unwrap_or(a.light_intensity);
        a.interreflections = interreflections.unwrap_or(a.interreflections);
        (a.target_median, a.force_shadows, a.quiet) = (target_median, force_shadows, quiet);
        // The checks name the keyword arguments, not the command line's flags.
        a.check_as(&|key| key.to_string()).map_err(error::trainer)?;
        interruptible(py, progress.as_ref(), || trainer::dataset::synth::synthesize(&a))?.map_err(error::trainer)?;
        Ok(a.out)
    })
}

/// `trainer fit`: fits `model` as the keyword arguments ask (`trainer fit`'s flags; unset ones keep
/// its defaults); returns the model file and the training log as JSON text. `model`, `reciprocity` and
/// `position` are parsed by the trainer's own parsers. Interruptible; `bar` draws the trainer's
/// terminal bar, `progress` receives `(steps done, steps)`.
#[pyfunction]
#[pyo3(signature = (model, *, data = None, toy = None, diligent = None, object = None, out = None, steps = None,
                    batch = None, lr = None, lr_final = None, seed = None, reciprocity = None, enhanced = false,
                    position = None, angle_frequencies = None, direction_layers = None, lambda_diffuse = None,
                    lambda_specular = None, checkpoint_every = None, resume = false, pixel_stride = None,
                    cache = None, energy_bound = false, bar = false, progress = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    py: Python<'_>,
    model: &str,
    data: Option<PathBuf>,
    toy: Option<usize>,
    diligent: Option<PathBuf>,
    object: Option<String>,
    out: Option<PathBuf>,
    steps: Option<usize>,
    batch: Option<usize>,
    lr: Option<f32>,
    lr_final: Option<f32>,
    seed: Option<u64>,
    reciprocity: Option<&str>,
    enhanced: bool,
    position: Option<&str>,
    angle_frequencies: Option<u8>,
    direction_layers: Option<u8>,
    lambda_diffuse: Option<f32>,
    lambda_specular: Option<f32>,
    checkpoint_every: Option<usize>,
    resume: bool,
    pixel_stride: Option<usize>,
    cache: Option<PathBuf>,
    energy_bound: bool,
    bar: bool,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<(PathBuf, String)> {
    guard(|| {
        let given: Vec<&str> =
            [("data", data.is_some()), ("toy", toy.is_some()), ("diligent", diligent.is_some())].iter().filter(|g| g.1).map(|g| g.0).collect();
        if let [a, b, ..] = given[..] {
            return Err(PyValueError::new_err(format!("{a} and {b} exclude each other: fit one data set")));
        }
        let mut a = FitArgs::new(named("model", parse_kind(model))?);
        if let Some(r) = reciprocity {
            a.model.reciprocity = named("reciprocity", parse_reciprocity(r))?;
        }
        if let Some(p) = position {
            a.model.position = named("position", parse_position(p))?;
        }
        a.model.enhanced = enhanced;
        a.model.angle_frequencies = angle_frequencies.unwrap_or(a.model.angle_frequencies);
        a.model.direction_layers = direction_layers;
        (a.data, a.toy, a.diligent, a.resume, a.energy_bound) = (data, toy, diligent, resume, energy_bound);
        a.object = object.unwrap_or(a.object);
        a.out = out.unwrap_or(a.out);
        a.steps = steps.unwrap_or(a.steps);
        a.batch = batch.unwrap_or(a.batch);
        a.lr = lr.unwrap_or(a.lr);
        a.lr_final = lr_final.unwrap_or(a.lr_final);
        a.seed = seed.unwrap_or(a.seed);
        a.lambda_diffuse = lambda_diffuse.unwrap_or(a.lambda_diffuse);
        a.lambda_specular = lambda_specular.unwrap_or(a.lambda_specular);
        a.checkpoint_every = checkpoint_every.unwrap_or(a.checkpoint_every);
        a.pixel_stride = pixel_stride.unwrap_or(a.pixel_stride);
        a.cache = cache.unwrap_or(a.cache);
        let (outputs, log) =
            interruptible(py, progress.as_ref(), || trainer::commands::fit::run_args(&a, bar))?.map_err(error::trainer)?;
        let log = serde_json::to_string(&log).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((outputs.model, log))
    })
}

/// `trainer study`: the config file `config` (`None`: the embedded default) into `out`, with the
/// report; returns the jobs' results as JSON text. Interruptible between and within jobs (finished
/// jobs are kept and reused by the next run); `progress` receives each fit's `(steps done, steps)`.
#[pyfunction]
#[pyo3(signature = (config, out, bar, progress = None))]
pub(crate) fn study(py: Python<'_>, config: Option<PathBuf>, out: PathBuf, bar: bool, progress: Option<Bound<'_, PyAny>>) -> PyResult<String> {
    guard(|| {
        let config = match &config {
            Some(path) => trainer::study::StudyConfig::read(path).map_err(error::trainer)?,
            None => trainer::study::StudyConfig::default_small(),
        };
        let results =
            interruptible(py, progress.as_ref(), || trainer::study::run_and_report(&config, &out, None, bar))?.map_err(error::trainer)?;
        serde_json::to_string(&results).map_err(|e| PyValueError::new_err(e.to_string()))
    })
}

/// LPIPS networks loaded so far, by weights path (`None`: the default), with the reason where one
/// could not be: loading takes longer than a comparison.
#[allow(clippy::type_complexity)]
static LPIPS: Mutex<Vec<(Option<PathBuf>, Result<Lpips, String>)>> = Mutex::new(Vec::new());

fn lpips(path: Option<&Path>) -> Result<Lpips, String> {
    let mut cache = LPIPS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, l)) = cache.iter().find(|(p, _)| p.as_deref() == path) {
        return l.clone();
    }
    let l = Lpips::load_or_na(path);
    cache.push((path.map(Path::to_path_buf), l.clone()));
    l
}

/// An (H, W, 3) image of real linear RGB values (any real dtype or array-like, read as float32).
fn image(x: &Bound<'_, PyAny>, name: &str) -> PyResult<RgbImage> {
    let a = arrays::real(x, name)?;
    let want = "(H, W, 3) with H, W > 0 (linear RGB)";
    let (h, w) = match *a.rows_of(3, want)? {
        [h, w] if h > 0 && w > 0 => (h, w),
        _ => return Err(a.shape_error(want)),
    };
    let pixels = a.rgbs(&[h, w]);
    RgbImage::from_data(w as u32, h as u32, pixels).map_err(error::core)
}

/// The study's image metrics of a **linear** test rendering against the reference (masked the way
/// the study masks, `trainer::metrics`): a dict of psnr (dB on sRGB; inf when equal), dssim, lpips
/// (None, with the reason in lpips_na, where the weights are missing or the image is too small) and
/// flip (mean HDR-FLIP).
#[pyfunction]
#[pyo3(signature = (reference, test, mask = None, lpips_weights = None))]
pub(crate) fn compare<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    test: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    lpips_weights: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let (r, t) = (image(reference, "reference")?, image(test, "test")?);
        if (r.width, r.height) != (t.width, t.height) {
            return Err(PyValueError::new_err(format!(
                "reference is {}×{} but test is {}×{} (width×height)",
                r.width, r.height, t.width, t.height
            )));
        }
        let mask: Option<Vec<bool>> = match mask {
            None => None,
            Some(m) => {
                let m = arrays::input(m, "mask", arrays::Kind::Bool)?;
                let hw = [r.height as usize, r.width as usize];
                if m.shape() != hw {
                    return Err(PyValueError::new_err(format!(
                        "mask has shape {}; the images are {}",
                        arrays::shape_str(m.shape()),
                        arrays::shape_str(&hw)
                    )));
                }
                Some(m.bools(&hw))
            }
        };
        let m = py.detach(|| {
            let net = lpips(lpips_weights.as_deref());
            ImageMetrics::evaluate(&r, &t, mask.as_deref(), &net)
        });
        let d = PyDict::new(py);
        d.set_item("psnr", m.psnr)?;
        d.set_item("dssim", m.dssim)?;
        match m.lpips {
            MaybeMetric::Value(v) => d.set_item("lpips", v)?,
            MaybeMetric::NotAvailable { na } => {
                d.set_item("lpips", py.None())?;
                d.set_item("lpips_na", na)?;
            }
        }
        d.set_item("flip", m.flip)?;
        Ok(d)
    })
}

/// The study's BRDF-space error: RMSE of the cube roots of (N, 3) real values, over the rows `keep`
/// ((N,) booleans) marks (all when None); the three broadcast by numpy's rules over the rows. Returns
/// (rmse, rows used).
#[pyfunction]
#[pyo3(signature = (predicted, reference, keep = None))]
pub(crate) fn brdf_rmse(
    py: Python<'_>,
    predicted: &Bound<'_, PyAny>,
    reference: &Bound<'_, PyAny>,
    keep: Option<&Bound<'_, PyAny>>,
) -> PyResult<(f64, usize)> {
    guard(|| {
        let (p, r) = (arrays::real(predicted, "predicted")?, arrays::real(reference, "reference")?);
        let keep = keep.map(|k| arrays::input(k, "keep", arrays::Kind::Bool)).transpose()?;
        let want = "(N, 3) (or (3,) for one row)";
        let mut leads = vec![("predicted", p.rows_of(3, want)?), ("reference", r.rows_of(3, want)?)];
        leads.extend(keep.as_ref().map(|k| ("keep", k.shape())));
        let lead = arrays::broadcast(&leads)?;
        let (p, r) = (p.rgbs(&lead), r.rgbs(&lead));
        let keep = keep.map_or_else(|| vec![true; p.len()], |k| k.bools(&lead));
        let e = py.detach(|| cube_root_rmse(&p, &r, &keep));
        Ok((e.value, e.samples))
    })
}
