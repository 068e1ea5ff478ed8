//! `trainer`: fits neural and parametric BRDFs from images and runs the comparison study.
//!
//! The commands land with their issues; until then the binary only lists what the core can evaluate.

fn main() {
    println!("nbrdf trainer: the fitting commands are not built yet; see README.md");
    std::process::exit(2);
}
