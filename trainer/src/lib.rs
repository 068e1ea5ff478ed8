//! `trainer`: fits the neural and parametric BRDFs of the paper from posed HDR images with candle on the
//! CPU, exports them to the core's `.nbrdf` files, and measures them. This library holds the commands'
//! bodies; `main.rs` only parses the command line.
//!
//! - [`dataset`]: the semi-synthetic renderer (`synth`), dataset loading, DiLiGenT-MV.
//! - [`models`]: candle twins of every core model (docs/models.md).
//! - [`observations`]: the training pixels, [`toy`]: an analytic stand-in for tests and benchmarks.
//! - [`engine`]: the training step (forward, Eq. 9 and 10, backward as one op over row blocks), its
//!   dense products at every CPU level, the composed loss it is checked against, Adam.
//! - [`train`]: the fitting loop with checkpoints.
//! - [`intrinsic`]: Laplace–Beltrami eigenfunctions for the intrinsic position encoding.
//! - [`metrics`]: PSNR, DSSIM, LPIPS, HDR-FLIP, BRDF-space RMSE, reciprocity and energy (Sec. 6).
//! - [`names`]: the names of model kinds, reciprocity strategies and position inputs (CLI, configs, Python).
//! - [`commands`]: the bodies of the `fit`, `models` and `bench-step` subcommands.
//! - [`staging`]: outputs written whole or not at all (staged folders and files, stale leftovers).
//! - [`study`]: the comparison of Sec. 6 (fit and evaluate every variant, write the report).

mod bits;
pub mod cancel;
pub mod commands;
pub mod dataset;
pub mod engine;
pub mod error;
pub mod intrinsic;
pub mod json;
pub mod metrics;
pub mod models;
pub mod names;
pub mod observations;
pub mod progress;
pub mod staging;
pub mod study;
pub mod toy;
pub mod train;

pub use error::{Error, Result};
