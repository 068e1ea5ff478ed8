//! Parametric models driven by a network (Sec. 4.1.1): an MLP (6 layers of width 128, skip to the third)
//! predicts the raw parameters from the position; the model's own `from_raw` applies the sigmoid/softplus
//! ranges (and the 0.5 roughness pre-scale), once per shading point.

use crate::mlp::{self, Net, Weight, MAX_WIDTH, PACKET};
use crate::parametric::{Parametric, ParametricKind};

/// The parametric model at the point: `from_raw(kind, MLP(p), object)`.
#[inline]
pub fn prepare<W: Weight>(net: &Net<'_, W>, kind: ParametricKind, pos: &[f32], object: &[f32]) -> Parametric {
    let mut raw = [0.0f32; MAX_WIDTH];
    mlp::eval(net, pos, &mut raw);
    Parametric::from_raw(kind, &raw[..kind.n_raw()], object)
}

/// [`prepare`] for [`PACKET`] points, point `q`'s position input at `pos[q * stride..][..n]`: the
/// network in the packet kernels ([`mlp::eval_packet`]), each point's [`prepare`] bit for bit.
#[inline]
pub fn prepare_packet<W: Weight>(net: &Net<'_, W>, kind: ParametricKind, pos: &[f32], stride: usize, n: usize, object: &[f32]) -> [Parametric; PACKET] {
    let mut raw = [0.0f32; PACKET * MAX_WIDTH];
    mlp::eval_packet(net, pos, stride, n, &mut raw, MAX_WIDTH);
    core::array::from_fn(|q| Parametric::from_raw(kind, &raw[q * MAX_WIDTH..q * MAX_WIDTH + kind.n_raw()], object))
}
