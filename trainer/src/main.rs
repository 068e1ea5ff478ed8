//! `trainer`: the command line. Argument parsing only; each subcommand's body lives in the library.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use trainer::commands;
use trainer::train::{TrainOptions, PAPER_BATCH_PIXELS};

/// Most pixels per batch (the paper's is 2^15/3 colour values' worth; this bounds the activations' memory).
const MAX_BATCH: usize = 1 << 20;
/// Most pixels of the built-in toy set (~170 bytes each).
const MAX_TOY: usize = 10_000_000;

// Training allocates and frees batch-sized tensors every step; the system allocator returns them to the
// OS and page-faults them back in, mimalloc keeps them (issue 4 "Speed").
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(name = "trainer", version, about = "Fits and compares neural BRDFs (On Neural BRDFs)")]
struct Cli {
    /// With no subcommand, runs the study on its embedded default (`trainer study`).
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(clap::Args, Clone)]
struct ModelArgs {
    /// rp, ts, fmbrdf, disney, lambert, single-mlp, additive-separate, additive-shared
    #[arg(long)]
    model: String,
    /// Reciprocity strategy of the purely neural models (Sec. 4.3): none, swap or exact
    #[arg(long, default_value = "exact")]
    reciprocity: String,
    /// The enhanced additive split of Eq. 8
    #[arg(long)]
    enhanced: bool,
    /// Position input: uniform, intrinsic:K (K eigenfunctions) or extrinsic:F (PE of xyz, F octaves)
    #[arg(long, default_value = "intrinsic:32")]
    position: String,
    /// Octaves of the angles' positional encoding
    #[arg(long, default_value_t = trainer::models::arch::DEFAULT_ANGLE_FREQUENCIES)]
    angle_frequencies: u8,
    /// Layers the directions pass through (Tab. 2); the paper's default per model when absent
    #[arg(long)]
    direction_layers: Option<u8>,
}

#[derive(Subcommand)]
enum Command {
    /// Runs the comparison study (Sec. 6): fits and evaluates every (scene, variant) job and writes
    /// REPORT.md, results.json and results.csv; finished jobs are reused.
    Study(StudyArgs),
    /// Render a semi-synthetic data set (Sec. 5.3): a mesh, a ground-truth material, posed views and
    /// directional lights.
    Synth(trainer::dataset::synth::SynthArgs),
    /// Load a data set (semi-synthetic or DiLiGenT-MV) and report its views, images and samples.
    Inspect(trainer::dataset::DataArgs),
    /// Fit one model variant and write the model, checkpoint and training log
    Fit {
        /// Semi-synthetic data set directory (written by `trainer synth`)
        #[arg(long, conflicts_with_all = ["toy", "diligent"])]
        data: Option<PathBuf>,
        /// A DiLiGenT-MV copy (the `mvpmsData` folder or its parent)
        #[arg(long, conflicts_with = "toy")]
        diligent: Option<PathBuf>,
        /// DiLiGenT-MV object: bear, buddha, cow, pot2 or reading
        #[arg(long, default_value = "bear")]
        object: String,
        /// Use every n-th masked pixel per image (1 = all)
        #[arg(long, default_value_t = 1)]
        pixel_stride: usize,
        /// Where the intrinsic encoding's eigenpairs are cached per mesh
        #[arg(long, default_value = "out/cache")]
        cache: PathBuf,
        /// Fit the built-in analytic toy set of this many pixels instead of a dataset
        #[arg(long)]
        toy: Option<usize>,
        #[command(flatten)]
        model: ModelArgs,
        #[arg(long, default_value = "out")]
        out: PathBuf,
        #[arg(long, default_value_t = 20_000)]
        steps: usize,
        /// Pixels per batch (default: the paper's 2^15 colour values)
        #[arg(long, default_value_t = PAPER_BATCH_PIXELS)]
        batch: usize,
        #[arg(long, default_value_t = 1e-3)]
        lr: f32,
        #[arg(long, default_value_t = 1e-4)]
        lr_final: f32,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Weight of the diffuse-vs-image L1 regulariser (enhanced, Sec. 4.4)
        #[arg(long, default_value_t = 1e-2)]
        lambda_diffuse: f32,
        /// Weight of the specular sparsity L1 regulariser (enhanced, Sec. 4.4)
        #[arg(long, default_value_t = 1e-3)]
        lambda_specular: f32,
        #[arg(long, default_value_t = 1000)]
        checkpoint_every: usize,
        /// Continue from the checkpoint in --out
        #[arg(long)]
        resume: bool,
    },
    /// Write a fitted model (or an NBRDF-json network) as a self-contained GPU shader (docs/shader.md)
    ExportShader {
        /// The .nbrdf model or NBRDF-json network
        model: PathBuf,
        /// wgsl, glsl, hlsl, msl or spirv
        #[arg(long, default_value = "wgsl")]
        lang: String,
        /// The shader file; a storage buffer's weights go beside it as FILE.weights.bin
        #[arg(long)]
        out: PathBuf,
        /// inline, buffer or buffer:GROUP,BINDING (default: inline up to 16384 network weights)
        #[arg(long)]
        weights: Option<String>,
    },
    /// List every model variant with its parameter count
    Models {
        #[arg(long, default_value = "intrinsic:32")]
        position: String,
    },
    /// Milliseconds per training step (forward + backward + Adam) of each architecture
    BenchStep {
        #[arg(long, default_value_t = 32_768)]
        batch: usize,
        #[arg(long, default_value_t = 5)]
        steps: usize,
        #[arg(long, default_value = "intrinsic:32")]
        position: String,
        /// Also write the timings as JSON here
        #[arg(long)]
        json: Option<PathBuf>,
        /// Time the same step in PyTorch side by side (benches/torch_reference.py; `pip install torch`)
        #[arg(long)]
        torch: bool,
        /// The PyTorch twin script
        #[arg(long, default_value = "benches/torch_reference.py")]
        torch_script: PathBuf,
        /// Rounds of `steps` steps per architecture (alternating with PyTorch); the best round counts
        #[arg(long, default_value_t = 3)]
        rounds: usize,
        /// Only the architectures whose name contains one of these (comma-separated)
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
        /// Run each network layer by layer (one fused op per layer) instead of as one op, to time the
        /// difference
        #[arg(long)]
        per_layer: bool,
        /// Run the networks and the objective as separate ops (each network's activations of the
        /// whole batch kept for its backward pass) instead of one fused step per block of rows, to
        /// time the difference
        #[arg(long)]
        unfused_step: bool,
    },
}

#[derive(clap::Args, Clone, Default)]
struct StudyArgs {
    /// Study config (JSON, see trainer::study::StudyConfig); the embedded small default when absent
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output folder: data sets, jobs and the report
    #[arg(long, default_value = "out/study")]
    out: PathBuf,
    /// Run only the jobs of shard I of N (job j belongs to shard j mod N)
    #[arg(long)]
    shard: Option<trainer::study::Shard>,
    #[command(subcommand)]
    action: Option<StudyAction>,
}

#[derive(Subcommand, Clone)]
enum StudyAction {
    /// Joins the results.json of several study outputs (e.g. shards run with different --out) and
    /// writes the report into --out
    Merge {
        /// The study output folders to join
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
    },
}

fn study(args: StudyArgs) -> trainer::Result<()> {
    if args.action.is_some() && (args.config.is_some() || args.shard.is_some()) {
        return Err(trainer::Error::Invalid("study merge takes only --out and the folders to join".into()));
    }
    let out = if args.out.as_os_str().is_empty() { PathBuf::from("out/study") } else { args.out };
    if let Some(StudyAction::Merge { dirs }) = &args.action {
        let (config, results) = trainer::study::report::merge(dirs)?;
        // The renderings come from the shard folders' data sets and fitted models.
        let figs = trainer::study::comparisons(&config, dirs, &out, &results)?;
        trainer::study::report::write(&out, &config, &results, &figs)?;
        println!("{} jobs from {} folders; report in {}", results.len(), dirs.len(), out.join("REPORT.md").display());
        return Ok(());
    }
    let config = match &args.config {
        Some(p) => trainer::study::StudyConfig::read(p)?,
        None => trainer::study::StudyConfig::default_small(),
    };
    let results = trainer::study::run_and_report(&config, &out, args.shard, true)?;
    println!("{} jobs; report in {}", results.len(), out.join("REPORT.md").display());
    Ok(())
}

fn main() {
    if let Err(e) = run(Cli::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> trainer::Result<()> {
    nbrdf::kernels::requested().map_err(|e| trainer::Error::Invalid(e.to_string()))?;
    let Some(command) = cli.command else { return study(StudyArgs::default()) };
    match command {
        Command::Study(args) => study(args)?,
        Command::Synth(args) => {
            trainer::dataset::synth::run(&args).map_err(trainer::Error::Core)?;
        }
        Command::Inspect(args) => trainer::dataset::inspect(&args).map_err(trainer::Error::Core)?,
        Command::Fit {
            data,
            diligent,
            object,
            pixel_stride,
            cache,
            toy,
            model: m,
            out,
            steps,
            batch,
            lr,
            lr_final,
            seed,
            lambda_diffuse,
            lambda_specular,
            checkpoint_every,
            resume,
        } => {
            let config = commands::parse_config(
                &m.model,
                &m.reciprocity,
                m.enhanced,
                &m.position,
                m.angle_frequencies,
                m.direction_layers,
            )?;
            // Numbers checked before any work, naming the flag and what is allowed.
            if !(lr.is_finite() && lr > 0.0) {
                return Err(trainer::Error::Invalid(format!("--lr {lr}: must be finite and positive")));
            }
            if !(lr_final.is_finite() && lr_final >= 0.0) {
                return Err(trainer::Error::Invalid(format!("--lr-final {lr_final}: must be finite and non-negative")));
            }
            if batch == 0 || batch > MAX_BATCH {
                return Err(trainer::Error::Invalid(format!("--batch {batch}: allowed 1..={MAX_BATCH} pixels")));
            }
            if toy.is_some_and(|n| n == 0 || n > MAX_TOY) {
                return Err(trainer::Error::Invalid(format!("--toy {}: allowed 1..={MAX_TOY} pixels", toy.unwrap_or(0))));
            }
            let (obs, table) = match (data, diligent, toy) {
                (_, _, Some(n)) => (trainer::toy::observations(n, config.position, seed), None),
                (None, None, None) => {
                    return Err(trainer::Error::Invalid("give --data DIR, --diligent PATH or --toy N".into()))
                }
                (dataset, diligent, None) => {
                    let args = trainer::dataset::DataArgs { dataset, diligent, object, pixel_stride };
                    let d = commands::data::load(&args, config.position, &cache)?;
                    (d.obs, d.position_table)
                }
            };
            let opts = TrainOptions {
                steps,
                batch,
                lr,
                lr_final,
                seed,
                lambda_diffuse,
                lambda_specular,
                checkpoint_every,
                ..TrainOptions::default()
            };
            let log = commands::fit::run(config, obs, &opts, &out, resume, true, table.as_deref())?;
            let last = log.loss.last().map(|l| l.1).unwrap_or(f32::NAN);
            println!(
                "{}: {} steps, final loss {last:.4e}, {:.1} s, {:.0} pixels/s; files in {}",
                log.model,
                log.steps_done,
                log.wall_s,
                log.samples_per_s,
                out.display()
            );
        }
        Command::ExportShader { model, lang, out, weights } => commands::export_shader::run(&model, &lang, &out, weights.as_deref())?,
        Command::Models { position } => {
            print!("{}", commands::models::table(commands::parse_position(&position)?));
        }
        Command::BenchStep { batch, steps, position, json, torch, torch_script, rounds, only, per_layer, unfused_step } => {
            use commands::bench_step as bench;
            trainer::models::network::set_whole_network(!per_layer);
            trainer::models::step::set_fused_step(!unfused_step);
            let position = commands::parse_position(&position)?;
            let mut configs = bench::default_configs(position);
            if !only.is_empty() {
                configs.retain(|c| only.iter().any(|o| c.name().contains(o.as_str())));
            }
            let t = if torch {
                bench::run_with_torch(&configs, batch, steps, rounds, &torch_script)?
            } else {
                bench::run(&configs, batch, steps, rounds)?
            };
            bench::print_table(&t);
            if let Some(p) = json {
                let s = serde_json::to_vec_pretty(&t).map_err(|e| trainer::Error::io(&p, e))?;
                std::fs::write(&p, s).map_err(|e| trainer::Error::io(&p, e))?;
            }
        }
    }
    Ok(())
}
