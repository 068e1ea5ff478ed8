//! Fitting a model to observations (Sec. 5.2): batches of pixels, the rendered radiance of Eq. 9, the
//! tone-mapped MSE of Eq. 10 (+ the Sec. 4.4 regularisers for enhanced models), Adam with an
//! exponentially decaying learning rate, checkpoints and resume, and a guard against non-finite losses.
//!
//! Determinism: the initial weights come from the seed, and the batch of step `t` (its pixel indices and
//! LitNeRF swap coin flips) from a ChaCha stream keyed by `(seed, t)`, so a resumed run draws the same
//! batches as an uninterrupted one. Results are bit-identical for a seed on one machine and thread count.

use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::{Device, Tensor};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::engine::adam::{Adam, AdamParams};
use crate::engine::{batch_loss, loss, Batch};
use crate::models::{Config, Inputs, Model, RawBatch, Reciprocity};
use crate::observations::{Filtered, Observations};
use crate::{Error, Result};

/// Pixels per batch: the paper's 2^15 colour values (Sec. 5.2) are 2^15 / 3 RGB pixels, rounded down.
pub const PAPER_BATCH_PIXELS: usize = (1 << 15) / 3;

/// Options of one fit.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct TrainOptions {
    pub steps: usize,
    /// Pixels per batch (3 colour values each).
    pub batch: usize,
    /// Initial learning rate.
    pub lr: f32,
    /// Learning rate at the last step; it decays exponentially from `lr`, `lr_t = lr (lr_final/lr)^(t/T)`.
    pub lr_final: f32,
    pub seed: u64,
    pub adam: AdamParams,
    /// Weight of the diffuse-vs-image L1 regulariser (enhanced models, Sec. 4.4).
    pub lambda_diffuse: f32,
    /// Weight of the specular sparsity L1 regulariser (enhanced models, Sec. 4.4).
    pub lambda_specular: f32,
    /// Radiance above this (per channel) is an outlier and not trained on.
    pub max_radiance: f32,
    /// Write a checkpoint every this many steps (0: only at the end).
    pub checkpoint_every: usize,
    /// Record the loss every this many steps.
    pub log_every: usize,
    /// Export the model energy-bounded: with an albedo bound fitted over points of the training data
    /// (docs/models.md, "Energy bound"), so that its albedo is at most 1 at every view.
    #[serde(default)]
    pub energy_bound: bool,
}

impl Default for TrainOptions {
    fn default() -> Self {
        TrainOptions {
            steps: 20_000,
            batch: PAPER_BATCH_PIXELS,
            lr: 1e-3,
            lr_final: 1e-4,
            seed: 0,
            adam: AdamParams::default(),
            // Small beside the data term once a fit is good, which larger weights outweighed
            // (docs/study.md, "The enhanced split").
            lambda_diffuse: 1e-4,
            lambda_specular: 1e-5,
            max_radiance: 1e4,
            checkpoint_every: 1000,
            log_every: 50,
            energy_bound: false,
        }
    }
}

impl TrainOptions {
    /// The Sec. 4.4 regularisers' weights.
    pub fn regularisers(&self) -> crate::engine::Regularisers {
        crate::engine::Regularisers { lambda_diffuse: self.lambda_diffuse, lambda_specular: self.lambda_specular }
    }

    /// Learning rate of step `t`.
    pub fn lr_at(&self, t: usize) -> f32 {
        let frac = t as f32 / self.steps.max(1) as f32;
        self.lr * (self.lr_final / self.lr).powf(frac)
    }
}

/// The training log written beside the model (JSON).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TrainLog {
    pub model: String,
    pub config: Option<Config>,
    pub options: Option<TrainOptions>,
    /// `(step, mean loss over the steps since the previous entry)`.
    pub loss: Vec<(usize, f32)>,
    /// Seconds spent in this run (a resumed run adds to the time before).
    pub wall_s: f64,
    /// Pixels per second of training.
    pub samples_per_s: f64,
    pub steps_done: usize,
    pub n_weights: usize,
    pub filtered: Option<FilteredLog>,
    /// The learning curve: the training loss and, where the caller probes, the held-out PSNR at
    /// [`RunSetup::curve_points`] evenly spaced steps (step 0 included); empty in logs written before.
    #[serde(default)]
    pub curve: Vec<CurvePoint>,
}

/// One point of a learning curve.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CurvePoint {
    pub step: usize,
    /// Training seconds up to this step (the probes' own time excluded).
    pub wall_s: f64,
    /// Mean training loss over the steps since the previous point; `None` at step 0.
    pub train_loss: Option<f32>,
    /// What the probe measured on held-out data (the study: mean test-view PSNR in dB).
    pub test_psnr: Option<f64>,
}

/// The steps at which a curve of `points` intervals over `steps` steps is sampled: `0` and
/// `round(k·steps/points)` for `k = 1..=points`, without repeats.
pub fn curve_steps(steps: usize, points: usize) -> Vec<usize> {
    if points == 0 {
        return Vec::new();
    }
    let mut v: Vec<usize> = (0..=points).map(|k| (k * steps + points / 2) / points).collect();
    v.dedup();
    v
}

/// [`Filtered`] in the log.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FilteredLog {
    pub non_finite: usize,
    pub too_bright: usize,
    pub below_horizon: usize,
    pub kept: usize,
}

impl From<&Filtered> for FilteredLog {
    fn from(f: &Filtered) -> Self {
        FilteredLog { non_finite: f.non_finite, too_bright: f.too_bright, below_horizon: f.below_horizon, kept: f.kept }
    }
}

/// Everything needed to continue a fit: the model, optimiser and how far it got.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Checkpoint {
    pub config: Config,
    pub options: TrainOptions,
    /// Steps completed.
    pub step: usize,
    /// Model weights in file order.
    #[serde(with = "crate::bits::vec")]
    pub weights: Vec<f32>,
    pub adam: Adam,
    pub log: TrainLog,
}

impl Checkpoint {
    /// Writes atomically (temporary file, then rename) so a crash never leaves half a checkpoint.
    pub fn save(&self, path: &Path) -> Result<()> {
        let json = serde_json::to_vec(self).map_err(|e| Error::io(path, e))?;
        write_atomic(path, &json)
    }

    /// Reads a checkpoint written by [`Checkpoint::save`] and checks it ([`Checkpoint::check`]): one
    /// that does not hold (a run that diverged, a damaged or edited file) is refused, never resumed
    /// from.
    pub fn load(path: &Path) -> Result<Checkpoint> {
        let c: Checkpoint = crate::json::read(path, "trainer checkpoint")?;
        c.check().map_err(|m| Error::Invalid(format!("{}: {m}; it cannot be resumed", path.display())))?;
        Ok(c)
    }

    /// What a checkpoint must hold to be resumed, or saved: as many weights as its variant has, all
    /// finite; Adam's hyper-parameters in their domain (β1, β2 in [0, 1), ε finite and > 0); moments
    /// of the weights' count, finite, the second ones ≥ 0. The error names the field and its value.
    pub fn check(&self) -> std::result::Result<(), String> {
        let n = self.config.n_weights();
        if self.weights.len() != n {
            return Err(format!("\"weights\" holds {} values, {} has {n}", self.weights.len(), self.config.name()));
        }
        if let Some(i) = self.weights.iter().position(|w| !w.is_finite()) {
            return Err(format!("weight {i} of the checkpoint is {}; a checkpoint must hold finite weights", self.weights[i]));
        }
        let AdamParams { beta1, beta2, eps } = self.adam.params;
        for (key, v) in [("beta1", beta1), ("beta2", beta2)] {
            if !(0.0..1.0).contains(&v) {
                return Err(format!("Adam's \"{key}\" is {v}; it must lie in [0, 1)"));
            }
        }
        if !(eps.is_finite() && eps > 0.0) {
            return Err(format!("Adam's \"eps\" is {eps}; it must be finite and > 0"));
        }
        for (key, moments) in [("m", &self.adam.m), ("v", &self.adam.v)] {
            let count: usize = moments.iter().map(Vec::len).sum();
            if count != n {
                return Err(format!("Adam's \"{key}\" holds {count} values, {} has {n} weights", self.config.name()));
            }
            let bad = moments.iter().flatten().position(|x| !x.is_finite() || key == "v" && *x < 0.0);
            if let Some(i) = bad {
                let x = moments.iter().flatten().nth(i).copied().unwrap_or(f32::NAN);
                return Err(format!("Adam's \"{key}\" value {i} is {x}; the moments must be finite (the second ones ≥ 0)"));
            }
        }
        Ok(())
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    nbrdf::io::write_atomic(path, bytes).map_err(Error::Core)
}

/// Per-pixel constants of the loss, precomputed once: `L_i cos θ_l` and `γ(L_GT)`.
struct Targets {
    incident: Vec<f32>,
    gamma: Vec<f32>,
}

impl Targets {
    fn new(obs: &Observations) -> Targets {
        let mut incident = Vec::with_capacity(3 * obs.len());
        let mut gamma = Vec::with_capacity(3 * obs.len());
        for s in 0..obs.len() {
            let cos_l = obs.wi[s].normalize().z.max(0.0);
            for c in 0..3 {
                incident.push(obs.irradiance[s][c] * cos_l);
                gamma.push(loss::gamma(obs.radiance[s][c]));
            }
        }
        Targets { incident, gamma }
    }
}

/// The batch of step `step`: indices drawn uniformly with replacement and the swap coin flips, both from
/// the `(seed, step)` stream.
fn draw_batch(config: &Config, obs: &Observations, targets: &Targets, opts: &TrainOptions, step: usize, device: &Device) -> Result<Batch> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    rng.set_stream(step as u64 + 1);
    let b = opts.batch.min(obs.len()).max(1);
    let idx: Vec<usize> = (0..b).map(|_| rng.random_range(0..obs.len())).collect();
    let swap: Vec<bool> = (0..b).map(|_| rng.random_bool(0.5)).collect();
    let np = obs.n_position;
    let mut position = Vec::with_capacity(b * np);
    let (mut wi, mut wo) = (Vec::with_capacity(b), Vec::with_capacity(b));
    let (mut inc, mut tgt) = (Vec::with_capacity(3 * b), Vec::with_capacity(3 * b));
    for &i in &idx {
        position.extend_from_slice(&obs.position[i * np..(i + 1) * np]);
        wi.push(obs.wi[i]);
        wo.push(obs.wo[i]);
        inc.extend_from_slice(&targets.incident[3 * i..3 * i + 3]);
        tgt.extend_from_slice(&targets.gamma[3 * i..3 * i + 3]);
    }
    let swap = (config.reciprocity == Reciprocity::Swap).then_some(swap.as_slice());
    let inputs = Inputs::build(config, &RawBatch { position: &position, wi: &wi, wo: &wo, swap }, device)?;
    Ok(Batch { inputs, incident: Tensor::from_vec(inc, (b, 3), device)?, target: Tensor::from_vec(tgt, (b, 3), device)? })
}

/// Tells mimalloc (the binary's allocator) never to return freed memory to the OS.
///
/// A step allocates and frees dozens of `[2^15, 128]` activation buffers; with mimalloc's default
/// 10 ms purge delay they go back to the OS between steps and come back as fresh pages that the kernel
/// zeroes on first touch (docs/speed.md). A training process wants the memory of its largest step kept. `mi_option_purge_delay` is option 15 in mimalloc v2 and v3
/// (include/mimalloc.h); `-1` disables purging.
pub fn keep_freed_memory() {
    // Links libmimalloc-sys, which defines the symbol, also into binaries that do not install mimalloc
    // as their global allocator (tests); there the call only configures an unused heap.
    use mimalloc as _;
    extern "C" {
        fn mi_option_set(option: std::ffi::c_int, value: std::ffi::c_long);
    }
    const MI_OPTION_PURGE_DELAY: std::ffi::c_int = 15;
    // The largest steps outgrow mimalloc's first 1 GiB arena; further arenas are reserved 4 GiB at a
    // time (option 23, `mi_option_arena_reserve`, in KiB, in the v2 sources libmimalloc-sys builds).
    // Reserved address space that is never touched costs no memory.
    const MI_OPTION_ARENA_RESERVE: std::ffi::c_int = 23;
    // SAFETY: mimalloc's documented option setter, thread-safe, with valid options and values.
    unsafe {
        mi_option_set(MI_OPTION_PURGE_DELAY, -1);
        mi_option_set(MI_OPTION_ARENA_RESERVE, 4 << 20);
    }
}

/// Where a fit writes its checkpoint and what it reports.
#[derive(Clone, Debug, Default)]
pub struct RunSetup {
    /// Checkpoint file (written every `checkpoint_every` steps and at the end).
    pub checkpoint: Option<PathBuf>,
    /// Continue from this checkpoint: its weights, Adam moments, step and log. The run uses the options
    /// given to [`fit`]; with the same options it ends bit-identical to an uninterrupted run.
    pub resume: Option<Checkpoint>,
    /// The file `resume` was read from: the last good checkpoint until the run writes its own.
    pub resumed_from: Option<PathBuf>,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// Intervals of the learning curve ([`curve_steps`]); 0 records none.
    pub curve_points: usize,
}

/// Measures the model on held-out data for the learning curve (the study renders its test views).
pub type Probe<'a> = &'a mut dyn FnMut(&Model) -> Result<f64>;

/// Fits `model` to `obs` (already sanitized) and returns its log. On a non-finite loss or gradient the
/// weights keep their last finite values and the error names the last checkpoint.
pub fn fit(model: &Model, obs: &Observations, opts: &TrainOptions, setup: RunSetup) -> Result<TrainLog> {
    fit_probed(model, obs, opts, setup, None)
}

/// [`fit`], calling `probe` at the learning curve's steps ([`RunSetup::curve_points`]); its time is
/// not counted as training time.
pub fn fit_probed(model: &Model, obs: &Observations, opts: &TrainOptions, setup: RunSetup, mut probe: Option<Probe<'_>>) -> Result<TrainLog> {
    obs.check()?;
    if obs.is_empty() {
        return Err(Error::Invalid("no training observations left to fit".into()));
    }
    if obs.n_position != model.config.position.input_len() {
        return Err(Error::Invalid(format!(
            "observations carry {} position values per pixel, {} expects {}",
            obs.n_position,
            model.config.name(),
            model.config.position.input_len()
        )));
    }
    keep_freed_memory();
    let device = Device::Cpu;
    let vars = model.vars();
    let (mut adam, mut step, mut log) = match setup.resume {
        Some(c) => {
            if c.config != model.config {
                return Err(Error::Invalid(format!("checkpoint is of {}, not {}", c.config.name(), model.config.name())));
            }
            if c.step > opts.steps {
                return Err(Error::Invalid(format!("the checkpoint is at step {}, past the {} steps asked for", c.step, opts.steps)));
            }
            // Checked at load against the variant; the moments' split into variables is checked here,
            // where the variables are known (a wrong split would index out of bounds in the update).
            let sizes: Vec<usize> = vars.iter().map(|v| v.as_tensor().elem_count()).collect();
            for (key, moments) in [("m", &c.adam.m), ("v", &c.adam.v)] {
                let split: Vec<usize> = moments.iter().map(Vec::len).collect();
                if split != sizes {
                    let from = setup.resumed_from.as_ref().map_or("the checkpoint".to_string(), |p| p.display().to_string());
                    return Err(Error::Invalid(format!(
                        "{from}: Adam's \"{key}\" is split into variables of {split:?} values, {} has {sizes:?}",
                        model.config.name()
                    )));
                }
            }
            model.set_weights(&c.weights)?;
            (c.adam, c.step, c.log)
        }
        None => (
            Adam::new(&vars, opts.adam),
            0,
            TrainLog { model: model.config.name(), config: Some(model.config), n_weights: model.config.n_weights(), ..Default::default() },
        ),
    };
    log.options = Some(opts.clone());
    let targets = Targets::new(obs);
    let bar = if setup.progress { ProgressBar::new(opts.steps as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(model.config.name());
    bar.set_position(step as u64);
    crate::progress::start(step as u64, opts.steps as u64);
    let start = Instant::now();
    let wall_before = log.wall_s;
    let mut probing = std::time::Duration::ZERO;
    let mut pixels = 0usize;
    let (mut acc, mut acc_n) = (0.0f64, 0usize);
    let curve_at = curve_steps(opts.steps, setup.curve_points);
    let (mut curve_acc, mut curve_n) = (0.0f64, 0usize);
    let mut record = |step: usize, train_loss: Option<f32>, probing: &mut std::time::Duration, log: &mut TrainLog| -> Result<()> {
        if !curve_at.contains(&step) || log.curve.last().is_some_and(|c| c.step >= step) {
            return Ok(());
        }
        let t = Instant::now();
        let test_psnr = probe.as_mut().map(|p| p(model)).transpose()?;
        *probing += t.elapsed();
        let wall_s = wall_before + (start.elapsed() - *probing).as_secs_f64();
        log.curve.push(CurvePoint { step, wall_s, train_loss, test_psnr });
        Ok(())
    };
    record(step, None, &mut probing, &mut log)?;
    // Only a checkpoint this run resumed from (checked finite at load) or wrote itself is good; a file
    // that merely exists at the checkpoint path may be another run's.
    let mut last_good = setup.resumed_from.clone();
    // Never persists a state that cannot be resumed: non-finite weights or moments stop the run, and
    // the last good checkpoint stays as it was.
    let write = |step: usize, adam: &Adam, log: &TrainLog, last_good: &Option<PathBuf>| -> Result<()> {
        if let Some(path) = &setup.checkpoint {
            let c = Checkpoint { config: model.config, options: opts.clone(), step, weights: model.weights()?, adam: adam.clone(), log: log.clone() };
            if c.check().is_err() {
                return Err(Error::NonFinite { step, what: "weights or optimiser state", last_good: last_good.clone() });
            }
            c.save(path)?;
        }
        Ok(())
    };
    while step < opts.steps {
        crate::cancel::check()?;
        let batch = draw_batch(&model.config, obs, &targets, opts, step, &device)?;
        let loss_t = batch_loss(model, &batch, opts.regularisers())?;
        let loss = loss_t.to_scalar::<f32>()?;
        if !loss.is_finite() {
            return Err(Error::NonFinite { step, what: "loss", last_good });
        }
        let grads = Adam::gradients(&vars, &loss_t.backward()?)?;
        if !grads.iter().flatten().all(|g| g.is_finite()) {
            return Err(Error::NonFinite { step, what: "gradient", last_good });
        }
        adam.step(&vars, &grads, opts.lr_at(step))?;
        step += 1;
        pixels += batch.inputs.n;
        acc += loss as f64;
        acc_n += 1;
        curve_acc += loss as f64;
        curve_n += 1;
        if curve_at.contains(&step) {
            record(step, Some((curve_acc / curve_n.max(1) as f64) as f32), &mut probing, &mut log)?;
            (curve_acc, curve_n) = (0.0, 0);
        }
        let secs = (start.elapsed() - probing).as_secs_f64();
        if step % opts.log_every.max(1) == 0 || step == opts.steps {
            log.loss.push((step, (acc / acc_n as f64) as f32));
            bar.set_message(format!("loss {:.3e}  {:.0} px/s", acc / acc_n as f64, pixels as f64 / secs.max(1e-9)));
            (acc, acc_n) = (0.0, 0);
        }
        bar.set_position(step as u64);
        crate::progress::set(step as u64);
        log.steps_done = step;
        log.wall_s = wall_before + secs;
        log.samples_per_s = pixels as f64 / secs.max(1e-9);
        if opts.checkpoint_every > 0 && step % opts.checkpoint_every == 0 && step < opts.steps {
            write(step, &adam, &log, &last_good)?;
            last_good = setup.checkpoint.clone();
        }
    }
    write(step, &adam, &log, &last_good)?;
    bar.finish_and_clear();
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{Kind, OutputStart, ParametricKind, PositionEncoding};
    use crate::toy;

    fn small_opts(steps: usize) -> TrainOptions {
        TrainOptions { steps, batch: 128, lr: 2e-3, lr_final: 2e-3, log_every: 10, checkpoint_every: 0, ..Default::default() }
    }

    fn config(kind: Kind, enhanced: bool, r: Reciprocity) -> Config {
        let mut c = Config::paper(kind, enhanced, r, PositionEncoding::Intrinsic { k: 2 });
        c.angle_frequencies = 2;
        c
    }

    fn mean_loss(model: &Model, obs: &Observations, opts: &TrainOptions) -> f32 {
        let o = TrainOptions { batch: obs.len(), ..opts.clone() };
        let b = draw_batch(&model.config, obs, &Targets::new(obs), &o, 0, &Device::Cpu).unwrap();
        batch_loss(model, &b, o.regularisers()).unwrap().to_scalar::<f32>().unwrap()
    }

    /// A short fit lowers the loss of every variant (parametric and purely neural, each reciprocity
    /// strategy).
    #[test]
    fn fitting_lowers_the_loss_of_every_variant() {
        let obs = toy::observations(2000, PositionEncoding::Intrinsic { k: 2 }, 1);
        let opts = small_opts(100);
        for c in [
            config(Kind::SingleMlp, false, Reciprocity::Exact),
            config(Kind::SingleMlp, false, Reciprocity::Swap),
            config(Kind::AdditiveSeparate, false, Reciprocity::None),
            config(Kind::AdditiveShared, false, Reciprocity::Exact),
            config(Kind::AdditiveSeparate, true, Reciprocity::Exact),
            config(Kind::AdditiveShared, true, Reciprocity::Exact),
            config(Kind::Parametric(ParametricKind::Phong), false, Reciprocity::None),
            config(Kind::Parametric(ParametricKind::TorranceSparrow), false, Reciprocity::None),
            config(Kind::Parametric(ParametricKind::FresnelMicrofacet), false, Reciprocity::None),
            config(Kind::Parametric(ParametricKind::Disney), false, Reciprocity::None),
        ] {
            let model = Model::init(c, 3, &Device::Cpu).unwrap();
            let before = mean_loss(&model, &obs, &opts);
            let log = fit(&model, &obs, &opts, RunSetup::default()).unwrap();
            let after = mean_loss(&model, &obs, &opts);
            assert!(after < 0.5 * before, "{}: loss {before} -> {after}", c.name());
            assert_eq!(log.steps_done, 100);
            assert!(log.loss.iter().all(|l| l.1.is_finite()));
        }
    }

    /// A dark material under bright lights, as MERL grease-covered steel in the MERL study (median BRDF
    /// 1.4e-3/sr, lights 31× unit): from the fixed dark start the specular logit of Additive Separate
    /// sinks until softplus' slope vanishes and the fit stalls near a diffuse-only loss; from its data's
    /// start ([`OutputStart::for_median`]) the same fit follows the highlight.
    #[test]
    fn a_dark_material_fits_from_its_data_start() {
        let mut obs = toy::observations(1000, PositionEncoding::Intrinsic { k: 2 }, 4);
        for (l, e) in obs.radiance.iter_mut().zip(&mut obs.irradiance) {
            *l = l.map(|v| v * 0.01 * 30.0);
            *e = e.map(|v| v * 30.0);
        }
        let c = config(Kind::AdditiveSeparate, false, Reciprocity::Exact);
        // Small enough for the portable kernel level in CI: the stall sets in within 100 steps.
        let opts = TrainOptions { steps: 120, batch: 256, lr: 1e-3, lr_final: 1e-3, log_every: 40, checkpoint_every: 0, ..Default::default() };
        let fit_from = |start| {
            let model = Model::init_at(c, 0, &Device::Cpu, start).unwrap();
            fit(&model, &obs, &opts, RunSetup::default()).unwrap();
            mean_loss(&model, &obs, &opts)
        };
        let start = OutputStart::for_median(obs.median_brdf());
        assert_ne!(start, OutputStart::DARK);
        let (stalled, fitted) = (fit_from(OutputStart::DARK), fit_from(start));
        assert!(fitted < 0.2 * stalled, "loss {fitted} from the data's start, {stalled} from the fixed one");
    }

    /// The same seed gives the same weights; a run resumed from its checkpoint ends bit-identical to an
    /// uninterrupted one.
    #[test]
    fn deterministic_and_resumable() {
        let dir = std::env::temp_dir().join(format!("nbrdf-trainer-resume-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ckpt = dir.join("a.ckpt.json");
        let obs = toy::observations(500, PositionEncoding::Intrinsic { k: 2 }, 2);
        let c = config(Kind::AdditiveShared, false, Reciprocity::Swap);
        let straight = Model::init(c, 5, &Device::Cpu).unwrap();
        fit(&straight, &obs, &small_opts(20), RunSetup::default()).unwrap();

        let first = Model::init(c, 5, &Device::Cpu).unwrap();
        fit(&first, &obs, &small_opts(10), RunSetup { checkpoint: Some(ckpt.clone()), ..Default::default() }).unwrap();
        let resumed = Model::init(c, 99, &Device::Cpu).unwrap();
        let setup = RunSetup { resume: Some(Checkpoint::load(&ckpt).unwrap()), ..Default::default() };
        let log = fit(&resumed, &obs, &small_opts(20), setup).unwrap();
        assert_eq!(log.steps_done, 20);
        assert_eq!(straight.weights().unwrap(), resumed.weights().unwrap());
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A NaN target stops the fit with an error naming the step and the last good checkpoint, and the
    /// weights (and that checkpoint) stay finite; sanitizing the data removes the cause.
    #[test]
    fn non_finite_loss_stops_and_keeps_the_last_good_checkpoint() {
        let dir = std::env::temp_dir().join(format!("nbrdf-trainer-nan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ckpt = dir.join("b.ckpt.json");
        let c = config(Kind::SingleMlp, false, Reciprocity::Exact);
        let model = Model::init(c, 1, &Device::Cpu).unwrap();
        let good = toy::observations(64, PositionEncoding::Intrinsic { k: 2 }, 3);
        let opts = TrainOptions { batch: 64, ..small_opts(5) };
        fit(&model, &good, &opts, RunSetup { checkpoint: Some(ckpt.clone()), ..Default::default() }).unwrap();
        let saved = Checkpoint::load(&ckpt).unwrap();

        let mut bad = good.clone();
        for i in (0..64).step_by(4) {
            bad.radiance[i] = [f32::NAN, 0.1, 0.1];
        }
        bad.radiance[1] = [0.1, 1e30, 0.1];
        let setup = RunSetup { checkpoint: Some(ckpt.clone()), resume: Some(saved.clone()), resumed_from: Some(ckpt.clone()), ..Default::default() };
        let err = fit(&model, &bad, &TrainOptions { steps: 10, ..opts.clone() }, setup).unwrap_err();
        match &err {
            Error::NonFinite { step: 5, what: "loss", last_good: Some(p) } => assert_eq!(p, &ckpt),
            e => panic!("unexpected {e}"),
        }
        assert!(err.to_string().contains("last good checkpoint"));
        assert_eq!(model.weights().unwrap(), saved.weights, "no update from the NaN step");
        assert_eq!(Checkpoint::load(&ckpt).unwrap().step, 5);

        let (clean, filtered) = bad.sanitize(1e4).unwrap();
        assert_eq!((filtered.non_finite, filtered.too_bright, filtered.kept), (16, 1, 47));
        fit(&model, &clean, &TrainOptions { steps: 10, ..opts }, RunSetup::default()).unwrap();
        assert!(model.weights().unwrap().iter().all(|w| w.is_finite()));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A state that would turn the weights NaN (an infinite Adam β1, past the checks at load) stops
    /// the run before its checkpoint is written: the file on disk stays the last good one.
    #[test]
    fn a_non_finite_state_is_never_saved() {
        let dir = tempfile::tempdir().unwrap();
        let ckpt = dir.path().join("c.ckpt.json");
        let c = config(Kind::SingleMlp, false, Reciprocity::Exact);
        let model = Model::init(c, 1, &Device::Cpu).unwrap();
        let obs = toy::observations(64, PositionEncoding::Intrinsic { k: 2 }, 3);
        let opts = TrainOptions { batch: 64, ..small_opts(2) };
        fit(&model, &obs, &opts, RunSetup { checkpoint: Some(ckpt.clone()), ..Default::default() }).unwrap();
        let good = std::fs::read(&ckpt).unwrap();
        let mut state = Checkpoint::load(&ckpt).unwrap();
        state.adam.params.beta1 = f32::INFINITY;
        assert!(state.check().unwrap_err().contains("beta1"));
        let setup = RunSetup { checkpoint: Some(ckpt.clone()), resume: Some(state), resumed_from: Some(ckpt.clone()), ..Default::default() };
        let err = fit(&model, &obs, &TrainOptions { steps: 3, ..opts }, setup).unwrap_err();
        assert!(matches!(&err, Error::NonFinite { step: 3, last_good: Some(p), .. } if *p == ckpt), "{err}");
        assert_eq!(std::fs::read(&ckpt).unwrap(), good, "the last good checkpoint is unchanged");
    }
}
