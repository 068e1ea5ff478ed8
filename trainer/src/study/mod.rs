//! The comparison study of Sec. 6: every (scene, model variant) job is fitted and evaluated, and the
//! results are gathered into the tables of the paper (`report`).
//!
//! - [`config`]: what runs (scenes, variants, budgets); an embedded small default.
//! - [`evaluate`]: one fitted model, through the core evaluator, on its scene's test views.
//! - [`report`]: `REPORT.md`, `results.json`, `results.csv`.
//! - [`figures`]: the Pareto plots and the reference / rendering / FLIP-map PNGs.
//!
//! Layout of `--out`: `data/<scene>-<hash>/` (one synthesized data set per scene, reused while its
//! arguments hash the same), `cache/` (intrinsic eigenpairs), `jobs/<scene>/<model>/` (the fit's files
//! and `result.json`; a job whose `result.json` carries the current job hash is not run again),
//! `figures/` (PNGs linked from `REPORT.md`).

pub mod checks;
pub mod config;
pub mod evaluate;
pub mod figures;
pub mod report;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use config::{ModelSpec, SceneConfig, StudyConfig};
pub use evaluate::Evaluation;

use crate::commands::{data, fit};
use crate::dataset::{DataArgs, Dataset};
use crate::metrics::Lpips;
use crate::train::TrainOptions;
use crate::{Error, Result};

/// One finished job.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobResult {
    pub scene: String,
    /// The variant's name (`Config::name`).
    pub model: String,
    /// The job hash it was computed for (the cache key).
    pub hash: String,
    pub n_weights: usize,
    /// Size of the exported `.nbrdf` in bytes.
    pub size_bytes: u64,
    pub train_wall_s: f64,
    pub steps: usize,
    pub final_loss: f32,
    pub eval: Evaluation,
    /// The same fit re-encoded with f16 network weights (purely neural models; parametric models
    /// keep their few per-object values in f32 anyway): its evaluation and file size.
    #[serde(default)]
    pub eval_f16: Option<Evaluation>,
    #[serde(default)]
    pub size_bytes_f16: Option<u64>,
    /// The learning curve: training loss and mean test-view PSNR at ~20 points of the run (empty in
    /// results written before it was recorded).
    #[serde(default)]
    pub curve: Vec<crate::train::CurvePoint>,
    /// The scene's data set exposure (light intensity, median luminance, saturated share), when
    /// its description records one.
    #[serde(default)]
    pub exposure: Option<crate::dataset::spec::ExposureSpec>,
    /// The scene's ceiling: its clean reference scored against the captured images, the best any
    /// model can read against the capture (`None` without a ground truth, or written before).
    #[serde(default)]
    pub ceiling: Option<crate::metrics::ImageMetrics>,
    /// The same fit energy-bounded (`StudyConfig::energy_bound`): its evaluation, and the largest
    /// value of its albedo table (at most 1: the bound changed no value).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eval_bounded: Option<Evaluation>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo_bound_max: Option<f32>,
}

/// Which jobs this process runs: job `j` (in scene-major order) belongs to shard `j % count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// Parses `I/N` with `I < N`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("shard {s:?}: expected I/N"))?;
        let (index, count): (usize, usize) =
            (i.parse().map_err(|_| format!("shard {s:?}: bad I"))?, n.parse().map_err(|_| format!("shard {s:?}: bad N"))?);
        if count == 0 || index >= count {
            return Err(format!("shard {s:?}: need 0 <= I < N"));
        }
        Ok(Shard { index, count })
    }
}

/// Data set folder of a scene.
pub fn scene_dir(out: &Path, config: &StudyConfig, scene: &SceneConfig) -> PathBuf {
    out.join("data").join(format!("{}-{}", scene.id(), config.scene_hash(scene)))
}

/// Folder of one job.
pub fn job_dir(out: &Path, scene: &SceneConfig, model_name: &str) -> PathBuf {
    out.join("jobs").join(scene.id()).join(model_name.replace('+', "_"))
}

/// The jobs of a config in scene-major order: (scene index, model index) for every model that runs on
/// the scene ([`ModelSpec::runs_on`]); job `j` of this list belongs to shard `j % count`.
pub fn jobs(config: &StudyConfig) -> Vec<(usize, usize)> {
    (0..config.scenes.len())
        .flat_map(|s| (0..config.models.len()).filter(move |&m| config.models[m].runs_on(s)).map(move |m| (s, m)))
        .collect()
}

/// Progress over the jobs: an overall bar (`jobs done / total`, the current job as its message) when
/// `progress`, silent otherwise. The per-fit bar is hidden while this one is shown, so the two never
/// fight over the terminal; the overall bar ticks every second so a long fit still shows it is alive.
struct Progress(Option<indicatif::ProgressBar>);

impl Progress {
    fn new(total: usize, progress: bool) -> Self {
        Progress(progress.then(|| {
            let bar = indicatif::ProgressBar::new(total as u64);
            let style = indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} jobs  {msg}")
                .expect("valid template")
                .progress_chars("=> ");
            bar.set_style(style);
            bar.enable_steady_tick(std::time::Duration::from_secs(1));
            bar
        }))
    }

    /// A log line above the bar; plain stderr when the bar is hidden (stderr not a terminal, e.g. a
    /// log file), where indicatif would drop it.
    fn say(&self, line: String) {
        match &self.0 {
            Some(b) if b.is_hidden() => eprintln!("{line}"),
            Some(b) => b.println(line),
            None => {}
        }
    }

    fn doing(&self, what: String) {
        if let Some(b) = &self.0 {
            b.set_message(what);
        }
    }

    /// Runs `f` with the bar cleared, for work that draws its own bar (`synthesize`).
    fn aside<R>(&self, f: impl FnOnce() -> R) -> R {
        match &self.0 {
            Some(b) => b.suspend(f),
            None => f(),
        }
    }

    fn done(&self) {
        if let Some(b) = &self.0 {
            b.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(b) = &self.0 {
            b.finish_with_message("done");
        }
    }
}

/// Runs (or reuses) the jobs of `shard` and returns their results, scene-major, in config order.
pub fn run(config: &StudyConfig, out: &Path, shard: Option<Shard>, progress: bool) -> Result<Vec<JobResult>> {
    if config.scenes.is_empty() || config.models.is_empty() {
        return Err(Error::Invalid("the study config needs at least one scene and one model".into()));
    }
    // Fail on a bad model spec before anything is rendered.
    let configs = config.models.iter().map(|m| config.model_config(m)).collect::<Result<Vec<_>>>()?;
    let lpips = Lpips::load_or_na(None);
    if let (Err(reason), true) = (&lpips, progress) {
        eprintln!("LPIPS: {reason}");
    }
    let defaults = TrainOptions::default();
    let opts = TrainOptions {
        steps: config.steps,
        batch: config.batch,
        lr: config.lr,
        lr_final: config.lr_final,
        seed: config.seed,
        lambda_diffuse: config.lambda_diffuse.unwrap_or(defaults.lambda_diffuse),
        lambda_specular: config.lambda_specular.unwrap_or(defaults.lambda_specular),
        checkpoint_every: config.steps.max(1),
        ..defaults
    };
    let mine: Vec<(usize, usize)> = jobs(config)
        .into_iter()
        .enumerate()
        .filter(|(j, _)| shard.is_none_or(|s| j % s.count == s.index))
        .map(|(_, job)| job)
        .collect();
    let bar = Progress::new(mine.len(), progress);
    let mut results = Vec::new();
    for (si, scene) in config.scenes.iter().enumerate() {
        let here: Vec<usize> = mine.iter().filter(|(s, _)| *s == si).map(|(_, m)| *m).collect();
        if here.is_empty() {
            continue;
        }
        let dir = scene_dir(out, config, scene);
        if !dir.join("dataset.json").exists() {
            bar.doing(format!("{}: synthesizing", scene.id()));
            bar.aside(|| crate::dataset::synth::synthesize(&config.synth_args(scene, &dir)))?;
        }
        let ds = Dataset::open(&dir)?;
        let args = DataArgs { dataset: Some(dir.clone()), diligent: None, object: String::new(), pixel_stride: config.pixel_stride };
        let mut training: Option<data::TrainingData> = None;
        // The scene's training pixels, loaded once, when a job first needs them.
        let load_training = |training: &mut Option<data::TrainingData>, position| -> Result<()> {
            if training.is_none() {
                bar.doing(format!("{}: loading the training pixels", scene.id()));
                *training = Some(data::load(&args, position, &out.join("cache"))?);
            }
            Ok(())
        };
        let mut test_views: Option<evaluate::TestViews> = None;
        let mut ceiling: Option<Option<crate::metrics::ImageMetrics>> = None;
        for m in here {
            crate::cancel::check()?;
            let (spec, model_config) = (&config.models[m], configs[m]);
            let name = model_config.name();
            let jdir = job_dir(out, scene, &name);
            let hash = config.job_hash(scene, spec);
            let result_path = jdir.join("result.json");
            if let Some(mut r) = read_result(&result_path).filter(|r| r.hash == hash) {
                // A result is reused only with the model files it scored, whole: a file cut short or
                // damaged since means the job runs again.
                match finished_models_load(&jdir, &model_config, spec) {
                    Ok(()) => {
                        if config.energy_bound && r.eval_bounded.is_none() {
                            // The bounded scores of a job finished without them: the same fit, bounded.
                            load_training(&mut training, model_config.position)?;
                            bar.doing(format!("{} / {name}: bounding and evaluating", scene.id()));
                            let model_path = fit::Outputs::in_dir(&jdir, &model_config).model;
                            let obs = &training.as_ref().expect("just loaded").obs;
                            let (e, max) = evaluate_bounded(&ds, &model_path, obs, &lpips, config)?;
                            (r.eval_bounded, r.albedo_bound_max) = (Some(e), Some(max));
                            let json = serde_json::to_vec_pretty(&r).map_err(|e| Error::io(&result_path, e))?;
                            crate::train::write_atomic(&result_path, &json)?;
                        }
                        bar.say(format!("{} / {name}: cached", scene.id()));
                        results.push(r);
                        bar.done();
                        continue;
                    }
                    Err(e) => bar.say(format!("{} / {name}: the finished job's model does not load ({e}); running it again", scene.id())),
                }
            }
            load_training(&mut training, model_config.position)?;
            let t = training.as_ref().expect("just loaded");
            bar.doing(format!("{} / {name}: fitting {} steps", scene.id(), config.steps));
            let table = t.position_table.as_ref();
            if test_views.is_none() {
                test_views = Some(evaluate::TestViews::load(&ds)?);
            }
            let views = test_views.as_ref().expect("just loaded");
            let mut probe = |m: &crate::models::Model| views.psnr_of(m, table.map(|t| t.values.as_slice()));
            let log = fit::run(model_config, t.obs.clone(), &opts, &jdir, None, false, table, Some(&mut probe))?;
            bar.doing(format!("{} / {name}: evaluating", scene.id()));
            let model_path = fit::Outputs::in_dir(&jdir, &model_config).model;
            let eval = evaluate::evaluate(&ds, &model_path, &lpips, config)?;
            let size_bytes = std::fs::metadata(&model_path).map_err(|e| Error::io(&model_path, e))?.len();
            let (eval_f16, size_bytes_f16) = if spec.is_parametric() {
                (None, None)
            } else {
                let buf = nbrdf::ModelBuf::load(&model_path).map_err(Error::Core)?;
                let path16 = model_path.with_extension("f16.nbrdf");
                let bytes = evaluate::to_f16(&buf)?;
                crate::train::write_atomic(&path16, &bytes)?;
                let f16 = evaluate::evaluate(&ds, &path16, &lpips, config)?;
                (Some(f16), Some(bytes.len() as u64))
            };
            let (eval_bounded, albedo_bound_max) = if config.energy_bound {
                bar.doing(format!("{} / {name}: bounding and evaluating", scene.id()));
                let (e, max) = evaluate_bounded(&ds, &model_path, &t.obs, &lpips, config)?;
                (Some(e), Some(max))
            } else {
                (None, None)
            };
            let r = JobResult {
                scene: scene.id(),
                model: name.clone(),
                hash,
                n_weights: log.n_weights,
                size_bytes,
                train_wall_s: log.wall_s,
                steps: log.steps_done,
                final_loss: log.loss.last().map(|l| l.1).unwrap_or(f32::NAN),
                eval,
                eval_f16,
                size_bytes_f16,
                curve: log.curve.clone(),
                exposure: ds.description.as_ref().and_then(|d| d.exposure),
                ceiling: match &ceiling {
                    Some(c) => c.clone(),
                    None => ceiling.insert(evaluate::ceiling(&ds, &lpips)?).clone(),
                },
                eval_bounded,
                albedo_bound_max,
            };
            let json = serde_json::to_vec_pretty(&r).map_err(|e| Error::io(&result_path, e))?;
            crate::train::write_atomic(&result_path, &json)?;
            bar.say(format!(
                "{} / {name}: {:.1} s, PSNR {:.2} dB, RMSE∛ {:.4}",
                scene.id(),
                r.train_wall_s,
                r.eval.image.psnr,
                r.eval.brdf_rmse_cbrt.value
            ));
            results.push(r);
            bar.done();
        }
    }
    bar.finish();
    Ok(results)
}

/// Writes the energy-bounded copy of the fitted model at `model_path` (`<name>.bounded.nbrdf`, bounded
/// over the training pixels' points as `trainer fit --energy-bound` bounds it) and evaluates it; returns
/// the evaluation and the largest value of its albedo table.
fn evaluate_bounded(
    ds: &Dataset,
    model_path: &Path,
    obs: &crate::observations::Observations,
    lpips: &std::result::Result<Lpips, String>,
    config: &StudyConfig,
) -> Result<(evaluate::Evaluation, f32)> {
    let bytes = nbrdf::io::read(model_path)?;
    let points = crate::models::export::bound_points(&obs.position, obs.n_position);
    let (bounded, bound) = crate::models::export::with_energy_bound(&bytes, &points)?;
    let max = bound.max();
    let path = model_path.with_extension("bounded.nbrdf");
    crate::train::write_atomic(&path, &bounded)?;
    Ok((evaluate::evaluate(ds, &path, lpips, config)?, max))
}

/// For each scene, the reference next to the rendering of the best parametric and the best purely
/// neural Tab. 1 variant of that scene (by PSNR), with their FLIP maps (`figures::write_comparison`),
/// written under `out`. The data sets and fitted models are looked up in `roots` in order (the study's
/// own folder, or the shard folders that `study merge` joins); a case none of them holds is skipped.
pub fn comparisons(config: &StudyConfig, roots: &[PathBuf], out: &Path, results: &[JobResult]) -> Result<Vec<figures::Comparison>> {
    let mut figs = Vec::new();
    for scene in &config.scenes {
        let id = scene.id();
        let Some(dir) = roots.iter().map(|r| scene_dir(r, config, scene)).find(|d| d.join("dataset.json").exists()) else {
            continue;
        };
        let on_scene: Vec<&JobResult> = results
            .iter()
            .filter(|r| r.scene == id && r.eval.image.psnr.is_finite() && report::in_tab1(&r.model, config))
            .collect();
        let base = |r: &JobResult| r.model.split('+').next().unwrap_or_default().to_string();
        let best = |parametric: bool| {
            on_scene
                .iter()
                .filter(|r| config::is_parametric(&base(r)) == parametric)
                .max_by(|a, b| a.eval.image.psnr.total_cmp(&b.eval.image.psnr))
                .copied()
        };
        let mut ds = None;
        for r in [best(true), best(false)].into_iter().flatten() {
            let Some(model_path) = roots.iter().map(|root| fit::Outputs::named(&job_dir(root, scene, &r.model), &r.model).model).find(|p| p.exists()) else {
                eprintln!("warning: no folder holds the model file of {id} / {}; its comparison figure is left out", r.model);
                continue;
            };
            if ds.is_none() {
                ds = Some(Dataset::open(&dir)?);
            }
            let (reference, rendering, mask) = evaluate::first_test_image(ds.as_ref().expect("just opened"), &model_path)?;
            figs.push(figures::write_comparison(out, &id, &r.model, &reference, &rendering, &mask)?);
        }
    }
    Ok(figs)
}

fn read_result(path: &Path) -> Option<JobResult> {
    serde_json::from_slice(&crate::json::read_bytes(path).ok()?).ok()
}

/// Loads (and so validates: length, checksum, finite weights) the model files a finished job wrote
/// in `jdir`: the `.nbrdf` and, for a purely neural model, its f16 twin.
fn finished_models_load(jdir: &Path, model_config: &crate::models::Config, spec: &ModelSpec) -> Result<()> {
    let model_path = fit::Outputs::in_dir(jdir, model_config).model;
    nbrdf::ModelBuf::load(&model_path).map_err(|e| Error::Core(e.context(model_path.display())))?;
    if !spec.is_parametric() {
        let path16 = model_path.with_extension("f16.nbrdf");
        nbrdf::ModelBuf::load(&path16).map_err(|e| Error::Core(e.context(path16.display())))?;
    }
    Ok(())
}

/// Runs the study and writes the report into `out`; returns the results.
pub fn run_and_report(config: &StudyConfig, out: &Path, shard: Option<Shard>, progress: bool) -> Result<Vec<JobResult>> {
    checks::check_output(out, config, shard)?;
    let results = run(config, out, shard, progress)?;
    let figs = comparisons(config, &[out.to_path_buf()], out, &results)?;
    report::write(out, config, &results, &figs)?;
    checks::record_output(out, config, shard)?;
    Ok(results)
}
