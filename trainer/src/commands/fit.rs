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
        Outputs::named(dir, &config.name())
    }

    /// The files of the variant named `name` ([`Config::name`]) in `dir`.
    pub fn named(dir: &Path, name: &str) -> Outputs {
        let name = name.replace('+', "_");
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
    position_table: Option<&[f32]>,
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
    crate::models::export::save(&model, &outputs.model, position_table)?;
    let log_json = serde_json::to_vec_pretty(&log).map_err(|e| Error::io(&outputs.log, e))?;
    train::write_atomic(&outputs.log, &log_json)?;
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{Kind, PositionEncoding, Reciprocity};

    /// `fit` filters bad pixels, writes a model the core loads, a checkpoint and a JSON log that records
    /// what was filtered; `--resume` continues where the checkpoint stopped.
    #[test]
    fn fit_writes_model_checkpoint_and_log() {
        let dir = std::env::temp_dir().join(format!("nbrdf-trainer-fit-{}", std::process::id()));
        let position = PositionEncoding::Extrinsic { frequencies: 1 };
        let config = Config::paper(Kind::AdditiveSeparate, true, Reciprocity::Exact, position);
        let mut obs = crate::toy::observations(300, position, 4);
        obs.radiance[0] = [f32::NAN; 3];
        obs.wo[1] = -obs.wo[1];
        let opts = TrainOptions { steps: 4, batch: 64, log_every: 2, checkpoint_every: 2, ..Default::default() };
        let log = run(config, obs.clone(), &opts, &dir, false, false, None).unwrap();
        let out = Outputs::in_dir(&dir, &config);
        let model = nbrdf::ModelBuf::load(&out.model).unwrap();
        // The architecture as configured, plus the sampling proxy fitted at export.
        let mut header = *model.header();
        assert!(header.proxy.take().is_some());
        assert_eq!(header, config.header());
        let written: train::TrainLog = serde_json::from_slice(&std::fs::read(&out.log).unwrap()).unwrap();
        assert_eq!(written.loss.len(), 2);
        let f = written.filtered.unwrap();
        assert_eq!((f.non_finite, f.below_horizon, f.kept), (1, 1, 298));
        assert!(log.samples_per_s > 0.0 && log.wall_s > 0.0);

        let more = TrainOptions { steps: 6, ..opts };
        let resumed = run(config, obs, &more, &dir, true, false, None).unwrap();
        assert_eq!((resumed.steps_done, resumed.loss.len()), (6, 3));
        std::fs::remove_dir_all(&dir).ok();
    }
}
