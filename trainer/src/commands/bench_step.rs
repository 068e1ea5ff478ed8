//! `trainer bench-step`: milliseconds per training step (forward, backward and Adam) of each
//! architecture at batch 32768, the figure the performance issue compares with PyTorch.

use std::time::Instant;

use candle_core::Device;

use crate::adam::{Adam, AdamParams};
use crate::models::{Config, Inputs, Model, PositionEncoding, RawBatch};
use crate::train::{objective, Batch, TrainOptions};
use crate::{toy, Result};

/// Timing of one architecture.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepTiming {
    pub model: String,
    pub n_weights: usize,
    pub batch: usize,
    /// Mean over the timed steps, forward + backward + Adam.
    pub ms_per_step: f64,
    /// Building the batch's network inputs on the CPU (angle map, encodings), not in `ms_per_step`.
    pub ms_inputs: f64,
}

/// Times `steps` steps (after one warm-up step) of each configuration.
pub fn run(configs: &[Config], batch: usize, steps: usize) -> Result<Vec<StepTiming>> {
    let device = Device::Cpu;
    let mut out = Vec::new();
    for config in configs {
        let obs = toy::observations(batch, config.position, 7);
        let model = Model::init(*config, 0, &device)?;
        let t0 = Instant::now();
        let inputs = Inputs::build(config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &device)?;
        let ms_inputs = t0.elapsed().as_secs_f64() * 1e3;
        let incident: Vec<f32> = obs.wi.iter().flat_map(|w| [w.z; 3]).collect();
        let target: Vec<f32> = obs.radiance.iter().flatten().map(|&v| crate::loss::gamma(v)).collect();
        let b = Batch {
            inputs,
            incident: candle_core::Tensor::from_vec(incident, (batch, 3), &device)?,
            target: candle_core::Tensor::from_vec(target, (batch, 3), &device)?,
        };
        let opts = TrainOptions::default();
        let vars = model.vars();
        let mut adam = Adam::new(&vars, AdamParams::default());
        let mut step = || -> Result<()> {
            let loss = objective(&model, &b, &opts)?;
            let g = Adam::gradients(&vars, &loss.backward()?)?;
            adam.step(&vars, &g, 1e-4)?;
            Ok(())
        };
        step()?;
        let t = Instant::now();
        for _ in 0..steps {
            step()?;
        }
        out.push(StepTiming {
            model: config.name(),
            n_weights: config.n_weights(),
            batch,
            ms_per_step: t.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64,
            ms_inputs,
        });
    }
    Ok(out)
}

/// The architectures timed by default: every distinct network layout of Tab. 1.
pub fn default_configs(position: PositionEncoding) -> Vec<Config> {
    crate::models::arch::study_variants(position, crate::models::Reciprocity::Exact)
}
