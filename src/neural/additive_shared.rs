//! Additive Shared (Sec. 4.1.2, after LitNeRF): a shared spatial trunk (5 layers of width 128, skip to
//! the third) feeding a diffuse head (one layer, sigmoid / π) and a specular head on
//! `[trunk, PE(a)]` (two layers, softplus; 6 outputs when enhanced, Eq. 8).

use super::split;
use crate::mlp::{self, partial, partial_packet, Net, Partial, PartialPacket, Weight, MAX_WIDTH, PACKET};
use crate::Rgb;

/// The angle-dependent half is the same for both additive architectures.
pub use super::split::{eval, eval_packet};

/// Trunk, diffuse head and the trunk part of the specular head: everything but the angles.
#[inline]
pub fn prepare<W: Weight>(
    trunk: &Net<'_, W>,
    diffuse: &Net<'_, W>,
    specular: &Net<'_, W>,
    pos: &[f32],
) -> (Rgb, Partial) {
    let mut t = [0.0f32; MAX_WIDTH];
    mlp::eval(trunk, pos, &mut t);
    let features = &t[..trunk.desc.output_len()];
    let mut d = [0.0f32; MAX_WIDTH];
    mlp::eval(diffuse, features, &mut d);
    (split::diffuse(&d[..3]), partial(specular, features))
}

/// [`prepare`] for [`PACKET`] points, point `q`'s position input at `pos[q * stride..][..n]`: the
/// packet kernels, each point's [`prepare`] (see [`partial_packet`]).
#[inline]
pub fn prepare_packet<W: Weight>(
    trunk: &Net<'_, W>,
    diffuse: &Net<'_, W>,
    specular: &Net<'_, W>,
    pos: &[f32],
    stride: usize,
    n: usize,
) -> ([Rgb; PACKET], PartialPacket) {
    let mut t = [0.0f32; PACKET * MAX_WIDTH];
    mlp::eval_packet(trunk, pos, stride, n, &mut t, MAX_WIDTH);
    let features = trunk.desc.output_len();
    let mut d = [0.0f32; PACKET * MAX_WIDTH];
    mlp::eval_packet(diffuse, &t, MAX_WIDTH, features, &mut d, MAX_WIDTH);
    (core::array::from_fn(|q| split::diffuse(&d[q * MAX_WIDTH..q * MAX_WIDTH + 3])), partial_packet(specular, &t, MAX_WIDTH, features))
}
