//! The dense network `Mlp(n_in, W, H, n_out, S)` of docs/models.md as candle variables.
//!
//! Each layer holds its matrix `[in][out]` and its bias `[1][out]` as two `Var`s whose buffers are the
//! layer's two blocks of the model file, so export is a copy ([`Mlp::write_weights`]).
//!
//! [`Mlp::forward`] composes candle ops: the definition that the training engine's fused step
//! (`crate::engine::step`) must meet, and what tests compare it with; training never runs it.

use candle_core::{DType, Device, Result, Tensor, Var};
use rand::{Rng, RngExt};

use super::arch::{layers, NetDesc};

/// One `Linear` layer: `y = x M + b`.
pub struct Linear {
    /// `[in, out]`, the file's row-major `[in][out]` block.
    pub weight: Var,
    /// `[1, out]`.
    pub bias: Var,
    n_in: usize,
}

impl Linear {
    /// PyTorch's `nn.Linear` default: weight and bias uniform in `±1/sqrt(fan_in)` (Kaiming/He uniform
    /// with `a = sqrt(5)`, He et al. 2015), from `rng` so that a seed fixes the initialisation.
    pub fn init(n_in: usize, n_out: usize, rng: &mut impl Rng, device: &Device) -> Result<Self> {
        let bound = if n_in > 0 { 1.0 / (n_in as f32).sqrt() } else { 1.0 };
        let mut draw = |n: usize| (0..n).map(|_| rng.random_range(-bound..bound)).collect::<Vec<f32>>();
        let weight = Var::from_vec(draw(n_in * n_out), (n_in, n_out), device)?;
        let bias = Var::from_vec(draw(n_out), (1, n_out), device)?;
        Ok(Linear { weight, bias, n_in })
    }

    /// `x M + 1 b`, through a ReLU when `relu` with PyTorch's gradient convention (0 at the kink, as
    /// the engine's backward pass; candle's own `relu` passes it at exactly 0): `z ⊙ [z > 0]` with a
    /// constant mask. `ones` is `[N, 1]` of ones for the batch, the input of a uniform material's layer.
    pub fn forward(&self, x: &Tensor, ones: &Tensor, relu: bool) -> Result<Tensor> {
        let z = if self.n_in == 0 { ones.matmul(self.bias.as_tensor())? } else { x.matmul(self.weight.as_tensor())?.broadcast_add(self.bias.as_tensor())? };
        if !relu {
            return Ok(z);
        }
        let mask = z.detach().gt(0f32)?.to_dtype(DType::F32)?;
        z * mask
    }
}

/// A network of docs/models.md.
pub struct Mlp {
    pub desc: NetDesc,
    pub layers: Vec<Linear>,
}

impl Mlp {
    /// Layers initialised in file order from `rng`.
    pub fn init(desc: NetDesc, rng: &mut impl Rng, device: &Device) -> Result<Self> {
        let layers = layers(&desc)
            .into_iter()
            .map(|(i, o)| Linear::init(i, o, rng, device))
            .collect::<Result<_>>()?;
        Ok(Mlp { desc, layers })
    }

    /// Adds `by` to the first `n` biases of the output layer: sets where an output nonlinearity starts.
    pub fn shift_output_bias(&self, n: usize, by: f32) -> Result<()> {
        let Some(last) = self.layers.last() else { return Ok(()) };
        let bias = last.bias.as_tensor();
        let mut v = bias.flatten_all()?.to_vec1::<f32>()?;
        v.iter_mut().take(n).for_each(|b| *b += by);
        last.bias.set(&Tensor::from_vec(v, bias.shape(), bias.device())?)
    }

    /// The layer that reads `[h, x]`: `S` when it is a hidden layer after the first and the network has
    /// an input to re-read.
    pub fn skip(&self) -> Option<usize> {
        let skip = self.desc.skip as usize;
        (skip >= 1 && skip < self.desc.hidden as usize && self.desc.n_in > 0).then_some(skip)
    }

    /// The network output: ReLU hidden layers, the skip input `[h, x]` at layer `S`, a linear output
    /// layer (or the last activation for a trunk with `n_out = 0`).
    pub fn forward(&self, x: &Tensor, ones: &Tensor) -> Result<Tensor> {
        let (hidden, skip) = (self.desc.hidden as usize, self.skip());
        let mut h = x.clone();
        for (l, layer) in self.layers.iter().enumerate() {
            let input = if skip == Some(l) { Tensor::cat(&[&h, x], 1)? } else { h };
            h = layer.forward(&input, ones, l < hidden)?;
        }
        Ok(h)
    }

    /// The variables in file order (matrix, bias, next layer ...).
    pub fn vars(&self) -> Vec<&Var> {
        self.layers.iter().flat_map(|l| [&l.weight, &l.bias]).collect()
    }

    /// Appends the weights in file order.
    pub fn write_weights(&self, out: &mut Vec<f32>) -> Result<()> {
        for v in self.vars() {
            out.extend(v.as_tensor().flatten_all()?.to_vec1::<f32>()?);
        }
        Ok(())
    }
}

/// Copies `values` (file order) into `vars`; returns how many were read.
pub fn read_into(vars: &[&Var], values: &[f32]) -> Result<usize> {
    let mut at = 0;
    for v in vars {
        let n = v.as_tensor().elem_count();
        let Some(chunk) = values.get(at..at + n) else {
            candle_core::bail!("weight vector too short: {} values for a model of more", values.len())
        };
        v.set(&Tensor::from_slice(chunk, v.as_tensor().shape(), v.as_tensor().device())?)?;
        at += n;
    }
    Ok(at)
}

/// `[n, 1]` of ones, the bias input of a batch.
pub fn ones(n: usize, device: &Device) -> Result<Tensor> {
    Tensor::ones((n, 1), DType::F32, device)
}
