//! The comparison study of Sec. 6: every (scene, model variant) job is fitted and evaluated, and the
//! results are gathered into the tables of the paper (`report`).
//!
//! - [`config`]: what runs (scenes, variants, budgets); an embedded small default.
//! - [`evaluate`]: one fitted model, through the core evaluator, on its scene's test views.
//! - [`report`]: `REPORT.md`, `results.json`, `results.csv`.
//!
//! Layout of `--out`: `data/<scene>-<hash>/` (one synthesized data set per scene, reused while its
//! arguments hash the same), `cache/` (intrinsic eigenpairs), `jobs/<scene>/<model>/` (the fit's files
//! and `result.json`; a job whose `result.json` carries the current job hash is not run again).

pub mod config;
pub mod evaluate;
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

/// Runs (or reuses) the jobs of `shard` and returns their results, scene-major, in config order.
pub fn run(config: &StudyConfig, out: &Path, shard: Option<Shard>, progress: bool) -> Result<Vec<JobResult>> {
    if config.scenes.is_empty() || config.models.is_empty() {
        return Err(Error::Invalid("the study config needs at least one scene and one model".into()));
    }
    // Fail on a bad model name before anything is rendered.
    let configs = config.models.iter().map(|m| config.model_config(m)).collect::<Result<Vec<_>>>()?;
    let lpips = Lpips::load_or_na(None);
    if let Err(reason) = &lpips {
        eprintln!("LPIPS: {reason}");
    }
    let opts = TrainOptions {
        steps: config.steps,
        batch: config.batch,
        lr: config.lr,
        lr_final: config.lr_final,
        seed: config.seed,
        checkpoint_every: config.steps.max(1),
        ..TrainOptions::default()
    };
    let mut results = Vec::new();
    let mut job = 0usize;
    for scene in &config.scenes {
        let mine: Vec<usize> = (0..configs.len())
            .filter(|_| {
                let take = shard.is_none_or(|s| job % s.count == s.index);
                job += 1;
                take
            })
            .collect();
        if mine.is_empty() {
            continue;
        }
        let dir = scene_dir(out, config, scene);
        if !dir.join("dataset.json").exists() {
            eprintln!("synthesizing {} into {}", scene.id(), dir.display());
            crate::dataset::synth::synthesize(&config.synth_args(scene, &dir)).map_err(Error::Core)?;
        }
        let ds = Dataset::open(&dir).map_err(Error::Core)?;
        let args = DataArgs { dataset: Some(dir.clone()), diligent: None, object: String::new(), pixel_stride: config.pixel_stride };
        let mut training: Option<data::TrainingData> = None;
        for m in mine {
            let (spec, model_config) = (&config.models[m], configs[m]);
            let name = model_config.name();
            let jdir = job_dir(out, scene, &name);
            let hash = config.job_hash(scene, spec);
            let result_path = jdir.join("result.json");
            if let Some(r) = read_result(&result_path).filter(|r| r.hash == hash) {
                eprintln!("{} / {name}: cached", scene.id());
                results.push(r);
                continue;
            }
            if training.is_none() {
                training = Some(data::load(&args, model_config.position, &out.join("cache"))?);
            }
            let t = training.as_ref().expect("just loaded");
            eprintln!("{} / {name}: fitting {} steps on {} pixels", scene.id(), config.steps, t.obs.len());
            let log = fit::run(model_config, t.obs.clone(), &opts, &jdir, false, progress, t.position_table.as_deref())?;
            let model_path = fit::Outputs::in_dir(&jdir, &model_config).model;
            let eval = evaluate::evaluate(&ds, &model_path, &lpips, config)?;
            let size_bytes = std::fs::metadata(&model_path).map_err(|e| Error::io(&model_path, e))?.len();
            let r = JobResult {
                scene: scene.id(),
                model: name,
                hash,
                n_weights: log.n_weights,
                size_bytes,
                train_wall_s: log.wall_s,
                steps: log.steps_done,
                final_loss: log.loss.last().map(|l| l.1).unwrap_or(f32::NAN),
                eval,
            };
            let json = serde_json::to_vec_pretty(&r).map_err(|e| Error::io(&result_path, e))?;
            crate::train::write_atomic(&result_path, &json)?;
            results.push(r);
        }
    }
    Ok(results)
}

fn read_result(path: &Path) -> Option<JobResult> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// Runs the study and writes the report into `out`; returns the results.
pub fn run_and_report(config: &StudyConfig, out: &Path, shard: Option<Shard>, progress: bool) -> Result<Vec<JobResult>> {
    let results = run(config, out, shard, progress)?;
    report::write(out, config, &results)?;
    Ok(results)
}
