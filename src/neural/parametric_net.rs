//! Parametric models driven by a network (Sec. 4.1.1): an MLP (6 layers of width 128, skip to the third)
//! predicts the raw parameters from the position; the model's own `from_raw` applies the sigmoid/softplus
//! ranges (and the 0.5 roughness pre-scale), once per shading point.

use crate::mlp::{self, Net, Weight, MAX_WIDTH};
use crate::parametric::{Parametric, ParametricKind};

/// The parametric model at the point: `from_raw(kind, MLP(p), object)`.
#[inline]
pub fn prepare<W: Weight>(net: &Net<'_, W>, kind: ParametricKind, pos: &[f32], object: &[f32]) -> Parametric {
    let mut raw = [0.0f32; MAX_WIDTH];
    mlp::eval(net, pos, &mut raw);
    Parametric::from_raw(kind, &raw[..kind.n_raw()], object)
}
