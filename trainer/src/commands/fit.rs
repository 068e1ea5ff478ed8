//! `trainer fit`: fits one model variant to a dataset and writes the model (`.nbrdf`), its checkpoint
//! and the training log.

use std::path::{Path, PathBuf};

use candle_core::Device;

use crate::models::{Config, Kind, Model, OutputStart, PositionEncoding, Reciprocity};
use crate::observations::Observations;
use super::data::PositionTable;
use crate::staging::{self, StagedFile};
use crate::train::{self, Checkpoint, RunSetup, TrainOptions, PAPER_BATCH_PIXELS};
use crate::{Error, Result};

/// The model variant a fit asks for: typed values (the command line parses its flags into them, the
/// Python package builds them from keyword arguments), checked together by [`super::config`].
#[derive(clap::Args, Clone, Debug)]
pub struct ModelArgs {
    /// rp, ts, fmbrdf, disney, lambert, single-mlp, additive-separate, additive-shared
    #[arg(long, value_parser = crate::names::kind_arg)]
    pub model: Kind,
    /// Reciprocity strategy of the purely neural models (Sec. 4.3): none, swap or exact
    #[arg(long, default_value = "exact", value_parser = crate::names::reciprocity_arg)]
    pub reciprocity: Reciprocity,
    /// The enhanced additive split of Eq. 8
    #[arg(long)]
    pub enhanced: bool,
    /// Position input: uniform, intrinsic:K (K eigenfunctions) or extrinsic:F (PE of xyz, F octaves)
    #[arg(long, default_value = "intrinsic:32", value_parser = crate::names::position_arg)]
    pub position: PositionEncoding,
    /// Octaves of the angles' positional encoding
    #[arg(long, default_value_t = crate::models::arch::DEFAULT_ANGLE_FREQUENCIES)]
    pub angle_frequencies: u8,
    /// Layers the directions pass through (Tab. 2); the paper's default per model when absent
    #[arg(long)]
    pub direction_layers: Option<u8>,
}

impl ModelArgs {
    /// `kind` with the defaults of the command line: exact reciprocity, 32 intrinsic eigenfunctions.
    pub fn new(kind: Kind) -> Self {
        FitArgs::new(kind).model
    }
}

/// Everything `trainer fit` takes: the one request the command line and the Python package
/// (`nbrdf.fit`) both build, run by [`run_args`].
#[derive(clap::Args, Clone, Debug)]
pub struct FitArgs {
    /// Semi-synthetic data set directory (written by `trainer synth`)
    #[arg(long, conflicts_with_all = ["toy", "diligent"])]
    pub data: Option<PathBuf>,
    /// A DiLiGenT-MV copy (the `mvpmsData` folder or its parent)
    #[arg(long, conflicts_with = "toy")]
    pub diligent: Option<PathBuf>,
    /// DiLiGenT-MV object: bear, buddha, cow, pot2 or reading
    #[arg(long, default_value = "bear")]
    pub object: String,
    /// Use every n-th masked pixel per image (1 = all)
    #[arg(long, default_value_t = 1)]
    pub pixel_stride: usize,
    /// Where the intrinsic encoding's eigenpairs are cached per mesh
    #[arg(long, default_value = "out/cache")]
    pub cache: PathBuf,
    /// Fit the built-in analytic toy set of this many pixels instead of a dataset
    #[arg(long)]
    pub toy: Option<usize>,
    #[command(flatten)]
    pub model: ModelArgs,
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 20_000)]
    pub steps: usize,
    /// Pixels per batch (default: the paper's 2^15 colour values)
    #[arg(long, default_value_t = PAPER_BATCH_PIXELS)]
    pub batch: usize,
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f32,
    #[arg(long, default_value_t = 1e-4)]
    pub lr_final: f32,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Weight of the diffuse-vs-image L1 regulariser (enhanced, Sec. 4.4)
    #[arg(long, default_value_t = 1e-4)]
    pub lambda_diffuse: f32,
    /// Weight of the specular sparsity L1 regulariser (enhanced, Sec. 4.4)
    #[arg(long, default_value_t = 1e-5)]
    pub lambda_specular: f32,
    #[arg(long, default_value_t = 1000)]
    pub checkpoint_every: usize,
    /// Continue from the checkpoint in --out
    #[arg(long)]
    pub resume: bool,
    /// Write the model energy-bounded: its albedo is at most 1 at every view (docs/models.md, "Energy
    /// bound"); reciprocal models stay exactly reciprocal
    #[arg(long)]
    pub energy_bound: bool,
}

impl FitArgs {
    /// A fit of `model` with the command line's defaults (no data named yet).
    ///
    /// ```
    /// use trainer::commands::fit::FitArgs;
    /// use clap::Parser;
    /// #[derive(Parser)]
    /// struct Cli {
    ///     #[command(flatten)]
    ///     args: FitArgs,
    /// }
    /// // The typed request and the parsed command line agree on every default.
    /// let parsed = Cli::parse_from(["fit", "--model", "ts"]).args;
    /// let built = FitArgs::new(trainer::names::parse_kind("ts").unwrap());
    /// assert_eq!(format!("{parsed:?}"), format!("{built:?}"));
    /// ```
    pub fn new(model: Kind) -> Self {
        // The defaults are clap's, declared once on the fields above.
        #[derive(clap::Parser)]
        struct Defaults {
            #[command(flatten)]
            args: FitArgs,
        }
        let argv = ["fit", "--model", crate::models::arch::kind_name(model)];
        <Defaults as clap::Parser>::try_parse_from(argv).expect("every kind's name parses with the defaults").args
    }
}

/// Most pixels per batch: bounds the activations' memory (the paper's batch is 2^15 colour values).
pub const MAX_BATCH: usize = 1 << 20;
/// Most pixels of the built-in toy set (~170 bytes each).
pub const MAX_TOY: usize = 10_000_000;
/// Most training steps (the paper trains 20 000; the log and checkpoints grow with the count).
pub const MAX_STEPS: usize = 10_000_000;

/// `trainer fit`: loads the data the arguments name (or the toy set), fits, writes the files; returns
/// where they went and the log. `progress` draws a bar on stderr.
pub fn run_args(args: &FitArgs, progress: bool) -> Result<(Outputs, train::TrainLog)> {
    let created = !args.out.exists();
    let result = run_checked(args, progress);
    // A failed or interrupted fit leaves no folder it made; `remove_dir` removes only an empty one.
    if result.is_err() && created {
        std::fs::remove_dir(&args.out).ok();
    }
    result
}

/// [`run_args`] but for the cleanup of a folder it created.
fn run_checked(args: &FitArgs, progress: bool) -> Result<(Outputs, train::TrainLog)> {
    let m = &args.model;
    let config = super::config(m.model, m.reciprocity, m.enhanced, m.position, m.angle_frequencies, m.direction_layers)?;
    // Numbers checked before any work, naming the flag and what is allowed.
    let (lr, lr_final, batch) = (args.lr, args.lr_final, args.batch);
    if !(lr.is_finite() && lr > 0.0) {
        return Err(Error::Invalid(format!("--lr {lr}: must be finite and positive")));
    }
    if !(lr_final.is_finite() && lr_final >= 0.0) {
        return Err(Error::Invalid(format!("--lr-final {lr_final}: must be finite and non-negative")));
    }
    if args.steps == 0 || args.steps > MAX_STEPS {
        return Err(Error::Invalid(format!("--steps {}: allowed 1..={MAX_STEPS}", args.steps)));
    }
    if batch == 0 || batch > MAX_BATCH {
        return Err(Error::Invalid(format!("--batch {batch}: allowed 1..={MAX_BATCH} pixels")));
    }
    if let Some(n) = args.toy.filter(|&n| n == 0 || n > MAX_TOY) {
        return Err(Error::Invalid(format!("--toy {n}: allowed 1..={MAX_TOY} pixels")));
    }
    if args.pixel_stride == 0 {
        return Err(Error::Invalid("--pixel-stride 0: at least 1 (1 uses every masked pixel)".into()));
    }
    // The output folder and the resume point are checked before the data is loaded.
    if args.out.exists() && !args.out.is_dir() {
        return Err(Error::Invalid(format!("--out {}: exists and is not a folder; fit writes its files into a folder", args.out.display())));
    }
    staging::check_writable(&args.out)?;
    let outputs = Outputs::in_dir(&args.out, &config);
    let resume = if args.resume { resume_point(&outputs, &config, args.steps)? } else { None };
    let (obs, table) = match (&args.data, &args.diligent, args.toy) {
        (_, _, Some(n)) => (crate::toy::observations(n, config.position, args.seed), None),
        (None, None, None) => return Err(Error::Invalid("give --data DIR, --diligent PATH or --toy N".into())),
        (dataset, diligent, None) => {
            let data = crate::dataset::DataArgs {
                dataset: dataset.clone(),
                diligent: diligent.clone(),
                object: args.object.clone(),
                pixel_stride: args.pixel_stride,
            };
            let d = super::data::load(&data, config.position, &args.cache)?;
            (d.obs, d.position_table)
        }
    };
    let opts = TrainOptions {
        steps: args.steps,
        batch: args.batch,
        lr: args.lr,
        lr_final: args.lr_final,
        seed: args.seed,
        lambda_diffuse: args.lambda_diffuse,
        lambda_specular: args.lambda_specular,
        checkpoint_every: args.checkpoint_every,
        energy_bound: args.energy_bound,
        ..TrainOptions::default()
    };
    let log = run(config, obs, &opts, &args.out, resume, progress, table.as_ref(), None)?;
    Ok((outputs, log))
}

/// Where a fit writes its files.
pub struct Outputs {
    /// Training state (weights + Adam moments) of the finished fit, `<name>.ckpt.json`.
    pub checkpoint: PathBuf,
    /// Training state while a run is under way, `<name>.partial.ckpt.json`: the run's own checkpoints
    /// go here, so the finished fit's files stay as they were until the run ends; `--resume` continues
    /// from it first. It becomes `checkpoint` when the run ends.
    pub partial_checkpoint: PathBuf,
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
            partial_checkpoint: dir.join(format!("{name}.partial.ckpt.json")),
            log: dir.join(format!("{name}.log.json")),
            model: dir.join(format!("{name}.nbrdf")),
        }
    }
}

/// Intervals of the learning curve every fit records (21 points with step 0).
pub const CURVE_POINTS: usize = 20;

/// The checkpoint `--resume` continues from and its file: an interrupted run's partial one, else the
/// finished fit's; checked against the configuration and `--steps` before any work.
pub fn resume_point(outputs: &Outputs, config: &Config, steps: usize) -> Result<Option<(Checkpoint, PathBuf)>> {
    let Some(path) = [&outputs.partial_checkpoint, &outputs.checkpoint].into_iter().find(|p| p.exists()) else {
        eprintln!("--resume: no checkpoint of {} in the output folder; starting from step 0", config.name());
        return Ok(None);
    };
    let c = Checkpoint::load(path)?;
    if c.config != *config {
        return Err(Error::Invalid(format!(
            "{}: a checkpoint of {}, not of {} (they differ in {}); --resume continues the same variant",
            path.display(),
            c.config.name(),
            config.name(),
            differences(&c.config, config)
        )));
    }
    if c.step > steps {
        return Err(Error::Invalid(format!(
            "{}: the checkpoint is at step {}, past --steps {steps}; give --steps {} or more to continue it",
            path.display(),
            c.step,
            c.step
        )));
    }
    if c.step == steps {
        eprintln!("{}: already at step {steps} (--steps); nothing to train, the model is exported again", path.display());
    }
    Ok(Some((c, path.clone())))
}

/// The flags in which the checkpoint's variant `was` differs from the asked one `is`, with both values:
/// two variants of one name differ in what the name leaves out (position input, angle octaves).
fn differences(was: &Config, is: &Config) -> String {
    let position = crate::names::position_name;
    let layers = |n: Option<u8>| n.map_or("the default".to_string(), |n| n.to_string());
    let mut d = Vec::new();
    if was.kind != is.kind {
        d.push(format!("--model ({} here, {} asked)", was.name(), is.name()));
    }
    if was.enhanced != is.enhanced {
        d.push(format!("--enhanced ({} here, {} asked)", was.enhanced, is.enhanced));
    }
    if was.reciprocity != is.reciprocity {
        d.push(format!("--reciprocity ({:?} here, {:?} asked)", was.reciprocity, is.reciprocity));
    }
    if was.position != is.position {
        d.push(format!("the position encoding, --position ({} here, {} asked)", position(was.position), position(is.position)));
    }
    if was.angle_frequencies != is.angle_frequencies {
        d.push(format!("--angle-frequencies ({} here, {} asked)", was.angle_frequencies, is.angle_frequencies));
    }
    if was.direction_layers != is.direction_layers {
        d.push(format!("--direction-layers ({} here, {} asked)", layers(was.direction_layers), layers(is.direction_layers)));
    }
    d.join(", ")
}

/// Sanitizes `obs`, fits `config` (continuing from `resume`, a [`resume_point`], when given), and
/// writes the outputs. Records the learning curve's training loss at [`CURVE_POINTS`] intervals and,
/// with a `probe`, its held-out measure too. Returns the log.
///
/// All or nothing: the run's checkpoints go to [`Outputs::partial_checkpoint`], and the model, the
/// log and the final checkpoint are written completely under temporary names and renamed into place
/// together at the end, so an interrupted or failed run leaves the previous fit's files as they were.
/// Temporary files of crashed runs in `out_dir` are removed first.
#[allow(clippy::too_many_arguments)]
pub fn run(
    config: Config,
    obs: Observations,
    opts: &TrainOptions,
    out_dir: &Path,
    resume: Option<(Checkpoint, PathBuf)>,
    progress: bool,
    position_table: Option<&PositionTable>,
    probe: Option<train::Probe<'_>>,
) -> Result<train::TrainLog> {
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    nbrdf::io::remove_stale_temps(out_dir);
    let outputs = Outputs::in_dir(out_dir, &config);
    let (obs, filtered) = obs.sanitize(opts.max_radiance)?;
    if filtered.non_finite + filtered.too_bright + filtered.below_horizon > 0 {
        eprintln!(
            "filtered out {} non-finite, {} brighter than {} and {} below-horizon pixels; {} remain",
            filtered.non_finite, filtered.too_bright, opts.max_radiance, filtered.below_horizon, filtered.kept
        );
    }
    let start = OutputStart::for_median(obs.median_brdf());
    let model = Model::init_at(config, opts.seed, &Device::Cpu, start)?;
    let (resume, resumed_from) = resume.unzip();
    let setup = RunSetup { checkpoint: Some(outputs.partial_checkpoint.clone()), resume, resumed_from, progress, curve_points: CURVE_POINTS };
    let mut log = train::fit_probed(&model, &obs, opts, setup, probe)?;
    log.filtered = Some((&filtered).into());
    let mut bytes = crate::models::export::encode(&model, position_table.map(|t| t.values.as_slice()))?;
    if let Some(t) = position_table {
        bytes = nbrdf::file::record_mesh(&bytes, t.mesh_hash)?;
    }
    if opts.energy_bound {
        let points = crate::models::export::bound_points(&obs.position, obs.n_position);
        bytes = crate::models::export::with_energy_bound(&bytes, &points)?.0;
    }
    let log_json = serde_json::to_vec_pretty(&log).map_err(|e| Error::io(&outputs.log, e))?;
    let files = vec![
        StagedFile::new(&outputs.model, &bytes)?,
        StagedFile::new(&outputs.log, &log_json)?,
        StagedFile::existing(outputs.partial_checkpoint.clone(), &outputs.checkpoint),
    ];
    staging::commit_all(files)?;
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
        let log = run(config, obs.clone(), &opts, &dir, None, false, None, None).unwrap();
        let out = Outputs::in_dir(&dir, &config);
        let model = nbrdf::ModelBuf::load(&out.model).unwrap();
        // The architecture as configured, plus the sampling proxy and its per-view table fitted at export.
        let mut header = *model.header();
        assert!(header.proxy.take().is_some());
        assert!(header.view_proxy.take().is_some());
        assert_eq!(header, config.header());
        let written: train::TrainLog = serde_json::from_slice(&std::fs::read(&out.log).unwrap()).unwrap();
        assert_eq!(written.loss.len(), 2);
        let f = written.filtered.unwrap();
        assert_eq!((f.non_finite, f.below_horizon, f.kept), (1, 1, 298));
        assert!(log.samples_per_s > 0.0 && log.wall_s > 0.0);

        let more = TrainOptions { steps: 6, ..opts };
        let from = resume_point(&out, &config, 6).unwrap();
        assert!(from.as_ref().is_some_and(|(c, p)| c.step == 4 && *p == out.checkpoint));
        let resumed = run(config, obs, &more, &dir, from, false, None, None).unwrap();
        assert_eq!((resumed.steps_done, resumed.loss.len()), (6, 3));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// `--energy-bound` writes the model with its albedo table (a version-2 file): the same networks,
    /// whose values are the unbounded ones divided where the table passes 1.
    #[test]
    fn energy_bound_fits_write_a_bounded_model() {
        let dir = tempfile::tempdir().unwrap();
        let config = Config::paper(Kind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Uniform);
        let obs = crate::toy::observations(200, PositionEncoding::Uniform, 2);
        let opts = TrainOptions { steps: 2, batch: 64, energy_bound: true, ..Default::default() };
        run(config, obs, &opts, dir.path(), None, false, None, None).unwrap();
        let bytes = std::fs::read(Outputs::in_dir(dir.path(), &config).model).unwrap();
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 2);
        let model = nbrdf::ModelBuf::from_bytes(&bytes).unwrap();
        let m = model.model();
        let bound = *m.albedo_bound().expect("the bound is in the header");
        let p = m.prepare(&[]).unwrap();
        let (wi, wo) = (nbrdf::Vec3::new(0.3, 0.2, 0.9).normalize(), nbrdf::Vec3::new(-0.6, 0.1, 0.3).normalize());
        assert_eq!(m.eval(&p, wi, wo), bound.apply(m.unbounded().eval(&p, wi, wo), wi.z, wo.z));
    }

    /// A model fitted to a surface that reflects more light than it receives (the toy set's radiance
    /// ×6) has an albedo above 1; fitted with `--energy-bound` its albedo, by a grid quadrature in
    /// (cos θi, φi) that is not the bound's own, stays at most 1 at 33 views between the table's nodes.
    #[test]
    fn a_fitted_model_over_one_is_bounded_at_every_view() {
        let dir = tempfile::tempdir().unwrap();
        let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform);
        let mut obs = crate::toy::observations(2000, PositionEncoding::Uniform, 9);
        obs.radiance.iter_mut().for_each(|r| *r = r.map(|v| v * 6.0));
        let opts = TrainOptions { steps: 150, batch: 512, lr: 3e-3, energy_bound: true, ..Default::default() };
        run(config, obs, &opts, dir.path(), None, false, None, None).unwrap();
        let model = nbrdf::ModelBuf::load(Outputs::in_dir(dir.path(), &config).model).unwrap();
        let (m, p) = (model.model(), model.model().prepare(&[]).unwrap());
        let albedo = |f: &dyn Fn(nbrdf::Vec3, nbrdf::Vec3) -> nbrdf::Rgb, wo: nbrdf::Vec3| {
            let n = 96;
            let mut a = [0.0f64; 3];
            for i in 0..n {
                let z = (i as f64 + 0.5) / n as f64;
                for j in 0..n {
                    let phi = (j as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
                    let r = (1.0 - z * z).sqrt();
                    let v = f(nbrdf::Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32), wo);
                    (0..3).for_each(|c| a[c] += v[c] as f64 * z * std::f64::consts::TAU / (n * n) as f64);
                }
            }
            a
        };
        let mut worst_raw = 0.0f64;
        for k in 0..33 {
            let cos_o = 1.0 - (k as f32 + 0.41) / 33.0;
            let wo = nbrdf::Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let a = albedo(&|wi, wo| m.eval(&p, wi, wo), wo);
            assert!(a.iter().all(|&c| c <= 1.0 + 1e-3), "albedo {a:?} at cos θo {cos_o}");
            let raw = albedo(&|wi, wo| m.unbounded().eval(&p, wi, wo), wo);
            worst_raw = raw.iter().fold(worst_raw, |w, &c| w.max(c));
        }
        assert!(worst_raw > 1.1, "the fitted model's own albedo reaches only {worst_raw}");
    }
}
