//! Additive Separate (Sec. 4.1.2, after NeRFactor): a diffuse network on the position (4 layers, skip to
//! the second, sigmoid / π) and a specular network on `[p, PE(a)]` (4 layers, skip to the second,
//! softplus; 6 outputs when enhanced, Eq. 8).

use super::split;
use crate::mlp::{self, partial, partial_packet, Net, Partial, PartialPacket, Weight, MAX_WIDTH, PACKET};
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

/// [`prepare`] for [`PACKET`] points, point `q`'s position input at `pos[q * stride..][..n]`: the
/// packet kernels, each point's [`prepare`] (see [`partial_packet`]).
#[inline]
pub fn prepare_packet<W: Weight>(diffuse: &Net<'_, W>, specular: &Net<'_, W>, pos: &[f32], stride: usize, n: usize) -> ([Rgb; PACKET], PartialPacket) {
    let mut d = [0.0f32; PACKET * MAX_WIDTH];
    mlp::eval_packet(diffuse, pos, stride, n, &mut d, MAX_WIDTH);
    (core::array::from_fn(|q| split::diffuse(&d[q * MAX_WIDTH..q * MAX_WIDTH + 3])), partial_packet(specular, pos, stride, n))
}
