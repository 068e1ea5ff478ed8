//! `trainer fit`: fits one model variant to a dataset and writes the model (`.nbrdf`), its checkpoint
//! and the training log.

use std::path::{Path, PathBuf};

use candle_core::Device;

use crate::models::{Config, Model};
use crate::observations::Observations;
use crate::train::{self, Checkpoint, RunSetup, TrainOptions};
use crate::{Error, Result};

/// Where a fit writes its files.
pub struct Outputs {
    /// Training state (weights + Adam moments), `<name>.ckpt.json`.
    pub checkpoint: PathBuf,
    /// Training log, `<name>.log.json`.
    pub log: PathBuf,
    /// The fitted model for the core, `<name>.nbrdf`.
    pub model: PathBuf,
}

impl Outputs {
    /// The files of `config` in `dir`.
    pub fn in_dir(dir: &Path, config: &Config) -> Outputs {
        let name = config.name().replace('+', "_");
        Outputs {
            checkpoint: dir.join(format!("{name}.ckpt.json")),
            log: dir.join(format!("{name}.log.json")),
            model: dir.join(format!("{name}.nbrdf")),
        }
    }
}

/// Sanitizes `obs`, fits `config` (resuming from the checkpoint in `out_dir` when `resume`), and writes
/// the outputs. Returns the log.
pub fn run(
    config: Config,
    obs: Observations,
    opts: &TrainOptions,
    out_dir: &Path,
    resume: bool,
    progress: bool,
) -> Result<train::TrainLog> {
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    let outputs = Outputs::in_dir(out_dir, &config);
    let (obs, filtered) = obs.sanitize(opts.max_radiance)?;
    if filtered.non_finite + filtered.too_bright + filtered.below_horizon > 0 {
        eprintln!(
            "filtered out {} non-finite, {} brighter than {} and {} below-horizon pixels; {} remain",
            filtered.non_finite, filtered.too_bright, opts.max_radiance, filtered.below_horizon, filtered.kept
        );
    }
    let model = Model::init(config, opts.seed, &Device::Cpu)?;
    let resume = if resume && outputs.checkpoint.exists() { Some(Checkpoint::load(&outputs.checkpoint)?) } else { None };
    let mut log = train::fit(&model, &obs, opts, RunSetup { checkpoint: Some(outputs.checkpoint.clone()), resume, progress })?;
    log.filtered = Some((&filtered).into());
    crate::models::export::save(&model, &outputs.model, None)?;
    let log_json = serde_json::to_vec_pretty(&log).map_err(|e| Error::io(&outputs.log, e))?;
    train::write_atomic(&outputs.log, &log_json)?;
    Ok(log)
}
