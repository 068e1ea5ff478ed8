//! The bodies of the trainer's subcommands; `main.rs` only parses arguments and dispatches here.

pub mod bench_host;
pub mod bound;
pub mod bench_step;
pub mod compare;
pub mod data;
#[cfg(feature = "shader")]
pub mod export_shader;
pub mod fit;
pub mod models;

use crate::models::{Config, Kind, PositionEncoding, Reciprocity};
use crate::{Error, Result};

/// The direction layer counts (Tab. 2) a kind takes: the Single MLP splits its six hidden layers into
/// a position trunk and a head of `1..=6` (6: the paper's single network), the additive models give
/// their specular part `1..=16` layers (the model file's most hidden layers of a network).
pub fn direction_layers_range(kind: Kind) -> Option<std::ops::RangeInclusive<u8>> {
    match kind {
        Kind::Parametric(_) => None,
        Kind::SingleMlp => Some(1..=6),
        Kind::AdditiveSeparate | Kind::AdditiveShared => Some(1..=nbrdf::mlp::MAX_HIDDEN as u8),
    }
}

/// Refuses a direction layer count outside [`direction_layers_range`]; `name` is the flag or config
/// key. A count out of range would otherwise be clamped while the variant's name kept it.
pub fn check_direction_layers(kind: Kind, model: &str, n: Option<u8>, name: &str) -> Result<()> {
    let Some(n) = n else { return Ok(()) };
    match direction_layers_range(kind) {
        None => Err(Error::Invalid(format!("{name} applies to the purely neural models, not {model}"))),
        Some(r) if !r.contains(&n) => {
            Err(Error::Invalid(format!("{name} {n}: allowed {}..={} for {model}", r.start(), r.end())))
        }
        Some(_) => Ok(()),
    }
}

/// The model configuration of a typed request: checks what the kinds allow (`--enhanced` for the
/// additive models, the direction layers, the angle octaves), naming the flags.
pub fn config(
    kind: Kind,
    reciprocity: Reciprocity,
    enhanced: bool,
    position: PositionEncoding,
    angle_frequencies: u8,
    direction_layers: Option<u8>,
) -> Result<Config> {
    let model = crate::models::arch::kind_name(kind);
    if enhanced && !matches!(kind, Kind::AdditiveSeparate | Kind::AdditiveShared) {
        return Err(Error::Invalid(format!("--enhanced (Eq. 8) applies to the additive models, not {model}")));
    }
    check_direction_layers(kind, model, direction_layers, "--direction-layers")?;
    if angle_frequencies > nbrdf::file::MAX_FREQUENCIES {
        return Err(Error::Invalid(format!(
            "--angle-frequencies {angle_frequencies}: allowed 0..={} (the model file's limit)",
            nbrdf::file::MAX_FREQUENCIES
        )));
    }
    let mut c = Config::paper(kind, enhanced, reciprocity, position);
    c.angle_frequencies = angle_frequencies;
    c.direction_layers = direction_layers;
    Ok(c)
}
