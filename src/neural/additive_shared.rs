//! Additive Shared (Sec. 4.1.2, after LitNeRF): a shared spatial trunk (5 layers of width 128, skip to
//! the third) feeding a diffuse head (one layer, sigmoid / π) and a specular head on
//! `[trunk, PE(a)]` (two layers, softplus; 6 outputs when enhanced, Eq. 8).

use super::split;
use crate::mlp::{self, forward, forward_packet, partial, Net, Partial, Weight, MAX_WIDTH, PACKET};
use crate::Rgb;

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

/// `f_d + f_s`, or Eq. 8 when `enhanced`.
#[inline]
pub fn eval<W: Weight>(specular: &Net<'_, W>, f_d: Rgb, prepared: &Partial, angles: &[f32], enhanced: bool) -> Rgb {
    let mut s = [0.0f32; MAX_WIDTH];
    forward(specular, prepared, angles, &mut s);
    split::combine(f_d, &s, enhanced)
}

/// [`eval`] for [`PACKET`] queries: query `q`'s encoded angles at `angles[q * stride..][..n]`.
#[inline]
pub fn eval_packet<W: Weight>(
    specular: &Net<'_, W>,
    f_d: Rgb,
    prepared: &Partial,
    angles: &[f32],
    stride: usize,
    n: usize,
    enhanced: bool,
) -> [Rgb; PACKET] {
    const S: usize = super::single_mlp::OUT_STRIDE;
    let mut s = [0.0f32; PACKET * S];
    forward_packet(specular, prepared, angles, stride, n, &mut s, S);
    core::array::from_fn(|q| split::combine(f_d, &s[q * S..(q + 1) * S], enhanced))
}
