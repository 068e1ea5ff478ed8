//! `trainer`: the command line. Argument parsing only; each subcommand's body lives in the library.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use trainer::commands;

// Training allocates and frees batch-sized tensors every step; the system allocator returns them to the
// OS and page-faults them back in, mimalloc keeps them (docs/speed.md).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(name = "trainer", version, about = "Fits and compares neural BRDFs (On Neural BRDFs)")]
struct Cli {
    /// With no subcommand, runs the study on its embedded default (`trainer study`).
    #[command(subcommand)]
    command: Option<Command>,
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
    Fit(commands::fit::FitArgs),
    /// Make a fitted model energy-bounded without refitting it: its albedo at most 1 at every view,
    /// exact reciprocity kept (docs/models.md, "Energy bound"); --remove undoes it
    Bound(commands::bound::BoundArgs),
    /// Score a linear EXR rendering against a reference with the study's image metrics (PSNR, DSSIM,
    /// LPIPS, HDR-FLIP), optionally over an object mask
    Compare(commands::compare::CompareArgs),
    /// Write a fitted model (or an NBRDF-json network) as a self-contained GPU shader (docs/shader.md)
    #[cfg(feature = "shader")]
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
        #[arg(long, default_value = "intrinsic:32", value_parser = trainer::names::position_arg)]
        position: trainer::models::PositionEncoding,
    },
    /// Milliseconds per training step (forward + backward + Adam) of each architecture
    BenchStep {
        #[arg(long, default_value_t = 32_768)]
        batch: usize,
        #[arg(long, default_value_t = 5)]
        steps: usize,
        #[arg(long, default_value = "intrinsic:32", value_parser = trainer::names::position_arg)]
        position: trainer::models::PositionEncoding,
        /// Also write the timings as JSON here
        #[arg(long)]
        json: Option<PathBuf>,
        /// Time the same step in PyTorch side by side (benches/torch_reference.py; `pip install torch`)
        #[arg(long)]
        torch: bool,
        /// The PyTorch twin script
        #[arg(long, default_value = "benches/torch_reference.py")]
        torch_script: PathBuf,
        /// Rounds of `steps` steps per architecture (alternating with PyTorch); the median round counts
        #[arg(long, default_value_t = 3)]
        rounds: usize,
        /// Only the architectures whose name contains one of these (comma-separated)
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
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
    /// Joins the results.json of several study outputs (shards run with different --out, or studies
    /// whose configs differ only in their scenes) and writes the report into --out
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
        trainer::study::checks::check_out_folder(&out)?;
        let (config, results) = trainer::study::report::merge(dirs)?;
        trainer::study::checks::warn_missing_jobs(&config, &results);
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
    // First, before any thread starts: an interrupted run removes what it staged.
    trainer::staging::remove_staging_on_interrupt();
    let result = run(Cli::parse());
    if let Err(e) = &result {
        // An interrupt that removed the run's staged outputs caused this error: let it end the run.
        if !trainer::staging::interrupted() {
            eprintln!("error: {e}");
        }
    }
    trainer::staging::exit(i32::from(result.is_err()));
}

fn run(cli: Cli) -> trainer::Result<()> {
    nbrdf::kernels::requested().map_err(|e| trainer::Error::Invalid(e.to_string()))?;
    let Some(command) = cli.command else { return study(StudyArgs::default()) };
    match command {
        Command::Study(args) => study(args)?,
        Command::Synth(args) => {
            trainer::dataset::synth::run(&args)?;
        }
        Command::Inspect(args) => trainer::dataset::inspect(&args)?,
        Command::Fit(args) => {
            let (outputs, log) = commands::fit::run_args(&args, true)?;
            let last = log.loss.last().map(|l| l.1).unwrap_or(f32::NAN);
            println!(
                "{}: {} steps, final loss {last:.4e}, {:.1} s, {:.0} pixels/s; files in {}",
                log.model,
                log.steps_done,
                log.wall_s,
                log.samples_per_s,
                outputs.model.parent().unwrap_or(&outputs.model).display()
            );
        }
        Command::Bound(args) => {
            let b = commands::bound::run(&args)?;
            match b.max_albedo {
                Some(max) if max > 1.0 => println!(
                    "{}: bounded over {} surface point(s); the albedo bound reaches {max:.3}, so values are divided where it passes 1",
                    args.out.display(),
                    b.points
                ),
                Some(max) => println!(
                    "{}: bounded over {} surface point(s); the albedo bound stays at {max:.3} ≤ 1, so no value changes",
                    args.out.display(),
                    b.points
                ),
                None => println!("{}: the bound removed; the model's own values again", args.out.display()),
            }
        }
        Command::Compare(args) => commands::compare::run(&args)?,
        #[cfg(feature = "shader")]
        Command::ExportShader { model, lang, out, weights } => commands::export_shader::run(&model, &lang, &out, weights.as_deref())?,
        Command::Models { position } => {
            print!("{}", commands::models::table(position));
        }
        Command::BenchStep { batch, steps, position, json, torch, torch_script, rounds, only } => {
            use commands::bench_step as bench;
            let mut configs = bench::default_configs(position);
            if !only.is_empty() {
                // A name that matches nothing is a typo, not a request for an empty table.
                if let Some(o) = only.iter().find(|o| !configs.iter().any(|c| c.name().contains(o.as_str()))) {
                    let known: Vec<String> = configs.iter().map(|c| c.name()).collect();
                    return Err(trainer::Error::Invalid(format!(
                        "--only {o:?}: matches no architecture; known: {}",
                        known.join(", ")
                    )));
                }
                configs.retain(|c| only.iter().any(|o| c.name().contains(o.as_str())));
            }
            let t = bench::run(&configs, batch, steps, rounds, torch.then_some(torch_script.as_path()))?;
            bench::print_report(&t);
            if let Some(p) = json {
                let s = serde_json::to_vec_pretty(&t).map_err(|e| trainer::Error::io(&p, e))?;
                std::fs::write(&p, s).map_err(|e| trainer::Error::io(&p, e))?;
            }
        }
    }
    Ok(())
}
