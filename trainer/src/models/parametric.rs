//! Candle twins of the parametric models of Sec. 4.1.1 (RP, Torrance-Sparrow, FMBRDF, Disney).
//!
//! They mirror the core's `src/parametric` tables (raw output → parameter) exactly; until that module
//! is merged, the raw-output counts below are the paper's parameter lists and `eval` reports that the
//! twin is missing rather than guessing a formula.

use candle_core::{Result, Tensor};

use super::arch::{Config, Kind, ParametricKind};
use super::features::Inputs;

/// Initial object parameters.
pub fn initial_object(config: &Config) -> Vec<f32> {
    vec![0.0; config.n_object()]
}

/// The BRDF `[N, 3]` of the raw network outputs `raw` `[N, n_raw]`.
pub fn eval(kind: ParametricKind, _raw: &Tensor, _object: Option<&Tensor>, _x: &Inputs) -> Result<Tensor> {
    let _ = Kind::Parametric(kind);
    candle_core::bail!("the candle twin of {kind:?} is not built yet: it waits for the core's src/parametric")
}

/// `Ok` when the twin of `config`'s parametric model exists.
pub fn eval_available(config: &Config) -> Result<()> {
    match config.kind {
        Kind::Parametric(k) => candle_core::bail!("the candle twin of {k:?} waits for the core's src/parametric"),
        _ => Ok(()),
    }
}
