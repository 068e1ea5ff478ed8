//! What a study checks before any work: the config's values, blamed on the config file and key; the
//! output folder, which a shard run may not take over from another study; and, for `study merge`,
//! the jobs and models no joined folder holds, named rather than dropped silently.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{jobs, Shard, StudyConfig};
use crate::commands::fit;
use crate::{Error, Result};

/// Most test pairs of the reciprocity RMSE and of the energy analysis, and most samples per energy
/// pair: each is an allocation (and minutes of work) sized by the config.
pub const MAX_PAIRS: usize = 10_000_000;
/// Most view samples per pair of the energy analysis.
pub const MAX_ENERGY_SAMPLES: usize = 10_000_000;

/// Checks every value of `config` that a run would otherwise find wrong only later; `source` names
/// where it came from (`study config FILE`), and each error names the key, its value and what is
/// allowed.
pub fn validate(config: &StudyConfig, source: &str) -> Result<()> {
    let key = |k: &str| format!("{source}: \"{k}\"");
    let bad = |k: &str, v: &dyn std::fmt::Display, allowed: &str| Err(Error::Invalid(format!("{} is {v}: {allowed}", key(k))));
    if let Some(scene) = config.scenes.first() {
        config.synth_args(scene, Path::new("unused")).check_as(&|k| key(k)).map_err(|e| Error::Invalid(e.to_string()))?;
    }
    if config.steps == 0 || config.steps > fit::MAX_STEPS {
        return bad("steps", &config.steps, &format!("allowed 1..={}", fit::MAX_STEPS));
    }
    if config.batch == 0 || config.batch > fit::MAX_BATCH {
        return bad("batch", &config.batch, &format!("allowed 1..={} pixels", fit::MAX_BATCH));
    }
    if !(config.lr.is_finite() && config.lr > 0.0) {
        return bad("lr", &config.lr, "must be finite and positive");
    }
    if !(config.lr_final.is_finite() && config.lr_final >= 0.0) {
        return bad("lr_final", &config.lr_final, "must be finite and non-negative");
    }
    for (k, v) in [("lambda_diffuse", config.lambda_diffuse), ("lambda_specular", config.lambda_specular)] {
        if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
            return bad(k, &v, "must be finite and non-negative");
        }
    }
    if config.pixel_stride == 0 {
        return bad("pixel_stride", &0, "at least 1 (every pixel)");
    }
    // None of them may be 0: a mean over no pairs or samples is NaN in every row.
    for (k, v, max) in [
        ("reciprocity_pairs", config.reciprocity_pairs, MAX_PAIRS),
        ("energy_pairs", config.energy_pairs, MAX_PAIRS),
        ("energy_samples", config.energy_samples, MAX_ENERGY_SAMPLES),
    ] {
        if v == 0 || v > max {
            return bad(k, &v, &format!("allowed 1..={max}"));
        }
    }
    // Every model spec resolves (known model, strategy, layer count, scenes) before any work.
    for (i, m) in config.models.iter().enumerate() {
        config.model_config(m).map_err(|e| Error::Invalid(format!("{}: {e}", key(&format!("models[{i}]")))))?;
    }
    Ok(())
}

/// What a finished run left in its folder: which shard it was and of which config. A shard run into
/// a folder of another study would replace that study's report with its own part.
#[derive(Serialize, Deserialize)]
struct RunRecord {
    /// `I/N`, or `None` for all jobs.
    shard: Option<String>,
    config: StudyConfig,
}

/// The record's file in the output folder.
const RECORD: &str = "study-run.json";

fn shard_name(s: Option<Shard>) -> Option<String> {
    s.map(|s| format!("{}/{}", s.index, s.count))
}

/// The shard and config of the study `out` holds, if any: its record, else (a folder written before
/// records existed) the config of its `results.json`, taken as unsharded.
fn previous(out: &Path) -> Result<Option<RunRecord>> {
    let record = out.join(RECORD);
    if record.exists() {
        return crate::json::read(&record, "study run record").map(Some);
    }
    let results = out.join("results.json");
    if !results.exists() {
        return Ok(None);
    }
    #[derive(Deserialize)]
    struct Saved {
        config: StudyConfig,
    }
    let saved: Saved = crate::json::read(&results, "study results file")?;
    Ok(Some(RunRecord { shard: None, config: saved.config }))
}

/// Refuses a shard run into a folder that holds an unsharded study, or shards of another config: its
/// `results.json` and `REPORT.md` would be replaced by this shard's part. Shards of the same config may
/// share a folder (a final unsharded run there writes the whole report); runs without `--shard` keep
/// reusing a folder (cached jobs; a changed config reruns what changed).
///
/// Also removes the temporary files that crashed runs left in `out` and its `figures/` (the data sets
/// and fits clean their own folders).
pub fn check_output(out: &Path, config: &StudyConfig, shard: Option<Shard>) -> Result<()> {
    check_out_folder(out)?;
    nbrdf::io::remove_stale_temps(out);
    nbrdf::io::remove_stale_temps(&out.join("figures"));
    // Only a shard run reads what the folder holds: an unsharded run replaces any report anyway.
    let Some(mine) = shard_name(shard) else { return Ok(()) };
    let Some(prev) = previous(out)? else { return Ok(()) };
    let refuse = |holds: String| {
        Err(Error::Invalid(format!(
            "--shard {mine} --out {}: the folder holds {holds}, whose results.json and REPORT.md this run would \
             replace; give each shard its own --out and join them with `trainer study merge`",
            out.display()
        )))
    };
    // Shards of one config share a folder by design (docs/study.md); anything else is another study.
    match &prev.shard {
        None => refuse("an unsharded study".into()),
        Some(s) if prev.config != *config => refuse(format!("shard {s} of a study with another config")),
        Some(_) => Ok(()),
    }
}

/// Refuses an `--out` that exists and is no folder, before any work (the study writes a folder).
pub fn check_out_folder(out: &Path) -> Result<()> {
    if out.exists() && !out.is_dir() {
        return Err(Error::Invalid(format!("--out {}: exists and is not a folder; the study writes a folder", out.display())));
    }
    Ok(())
}

/// Records which shard of which config `out` now holds (after its report is written).
pub fn record_output(out: &Path, config: &StudyConfig, shard: Option<Shard>) -> Result<()> {
    let record = RunRecord { shard: shard_name(shard), config: config.clone() };
    let path = out.join(RECORD);
    let json = serde_json::to_vec_pretty(&record).map_err(|e| Error::io(&path, e))?;
    crate::train::write_atomic(&path, &json)
}

/// Names, on stderr, every job of `config` that no joined folder has a result for: its rows are
/// missing from the merged report.
pub fn warn_missing_jobs(config: &StudyConfig, results: &[super::JobResult]) {
    for (s, m) in jobs(config) {
        let scene = config.scenes[s].id();
        let Ok(c) = config.model_config(&config.models[m]) else { continue };
        let name = c.name();
        if !results.iter().any(|r| r.scene == scene && r.model == name) {
            eprintln!("warning: study merge: no folder has a result for {scene} / {name}; its rows are missing from the report");
        }
    }
}
