//! Additive Separate (Sec. 4.1.2, after NeRFactor): a diffuse network on the position (4 layers, skip to
//! the second, sigmoid / π) and a specular network on `[p, PE(a)]` (4 layers, skip to the second,
//! softplus; 6 outputs when enhanced, Eq. 8).

use super::split;
use crate::mlp::{self, partial, Net, Partial, Weight, MAX_WIDTH};
use crate::Rgb;

/// The angle-dependent half is the same for both additive architectures.
pub use super::split::{eval, eval_packet};

/// The diffuse term at the point and the position part of the specular network.
#[inline]
pub fn prepare<W: Weight>(diffuse: &Net<'_, W>, specular: &Net<'_, W>, pos: &[f32]) -> (Rgb, Partial) {
    let mut d = [0.0f32; MAX_WIDTH];
    mlp::eval(diffuse, pos, &mut d);
    (split::diffuse(&d[..3]), partial(specular, pos))
}
