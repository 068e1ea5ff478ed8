//! `trainer`: the command line. Each subcommand's body lives in the library.

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "trainer", version, about = "Fits and compares neural BRDFs (On Neural BRDFs)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a semi-synthetic data set (Sec. 5.3): a mesh, a ground-truth material, posed views and
    /// directional lights.
    Synth(trainer::dataset::synth::SynthArgs),
    /// Load a data set (semi-synthetic or DiLiGenT-MV) and report its views, images and samples.
    Inspect(trainer::dataset::DataArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Synth(args) => trainer::dataset::synth::run(&args).map(|_| ()),
        Command::Inspect(args) => trainer::dataset::inspect(&args),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
