//! `trainer`: fits the neural and parametric BRDFs of the paper from posed HDR observations with candle
//! on the CPU, and exports them to the core's `.nbrdf` files.
//!
//! - [`models`]: candle twins of every core model (docs/models.md).
//! - [`observations`]: the training pixels, [`toy`]: an analytic stand-in for tests and benchmarks.
//! - [`loss`], [`adam`], [`train`]: Eq. 9 and 10, the optimiser, the fitting loop with checkpoints.
//! - [`intrinsic`]: Laplace–Beltrami eigenfunctions for the intrinsic position encoding.
//! - [`commands`]: the bodies of the `fit`, `models` and `bench-step` subcommands.

pub mod adam;
mod bits;
pub mod commands;
pub mod error;
pub mod intrinsic;
pub mod loss;
pub mod models;
pub mod observations;
pub mod toy;
pub mod train;

pub use error::{Error, Result};
