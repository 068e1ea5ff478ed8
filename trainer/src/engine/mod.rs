//! The training engine: what turns a batch into the gradient of every weight, fast.
//!
//! - [`dense`]: the dense products of a step with their epilogues, one kernel body over each CPU
//!   level's lanes;
//! - [`network`], [`trunked`]: a network's (or a trunk and its heads') passes on one block of rows;
//! - [`objective`]: Eq. 9, 10 and the Sec. 4.4 regularisers on a block, and their gradient;
//! - [`step`]: all of it as one candle op over the batch, the only training path;
//! - [`loss`]: Eq. 9 and 10 composed from candle ops, the definition the step is checked against;
//! - [`adam`]: the optimiser;
//! - [`vjp`]: the weights' gradient for an outside caller's `∂L/∂f` (a differentiable renderer).
//!
//! The engine reads the model twins of [`crate::models`] and is read by [`crate::train`]; nothing
//! here imports either of those layers' callers.

pub mod adam;
pub mod dense;
pub mod loss;
pub(crate) mod network;
pub mod objective;
pub(crate) mod op;
pub mod step;
pub(crate) mod trunked;
pub mod vjp;

use candle_core::Tensor;

use crate::models::Inputs;

pub use step::batch_loss;

/// A batch drawn for one step.
pub struct Batch {
    pub inputs: Inputs,
    /// `[B, 3]`: `L_i cos θ_l`.
    pub incident: Tensor,
    /// `[B, 3]`: `γ(L_GT)`.
    pub target: Tensor,
}

/// Weights of the Sec. 4.4 regularisers of an enhanced model (ignored for the others).
#[derive(Clone, Copy, Debug, Default)]
pub struct Regularisers {
    /// Of the diffuse-vs-image L1 term.
    pub lambda_diffuse: f32,
    /// Of the specular sparsity L1 term.
    pub lambda_specular: f32,
}
