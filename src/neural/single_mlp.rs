//! Single MLP (Sec. 4.1.2): one network from `[p, PE(a)]` to RGB with a softplus output, 6 layers of
//! width 128 and an input skip to the third layer. With fewer direction layers (Tab. 2) a position-only
//! trunk runs first and the angles join the trunk's features.

use crate::math::softplus_slice;
use crate::mlp::{self, forward, forward_packet, partial, partial_packet, Net, Partial, PartialPacket, Weight, MAX_WIDTH, PACKET};
use crate::Rgb;

/// Position-only work: the position rows of the network (one network), or the trunk and the head's
/// trunk rows (two networks).
#[inline]
pub fn prepare<W: Weight>(nets: &[Net<'_, W>], pos: &[f32]) -> Partial {
    match nets {
        [trunk, head] => {
            let mut t = [0.0f32; MAX_WIDTH];
            mlp::eval(trunk, pos, &mut t);
            partial(head, &t[..trunk.desc.output_len()])
        }
        [net, ..] => partial(net, pos),
        [] => Partial::default(),
    }
}

/// [`prepare`] for [`PACKET`] points, point `q`'s position input at `pos[q * stride..][..n]`: the
/// packet kernels, each point's [`prepare`] (see [`partial_packet`]).
#[inline]
pub fn prepare_packet<W: Weight>(nets: &[Net<'_, W>], pos: &[f32], stride: usize, n: usize) -> Option<PartialPacket> {
    match nets {
        [trunk, head] => {
            let mut t = [0.0f32; PACKET * MAX_WIDTH];
            mlp::eval_packet(trunk, pos, stride, n, &mut t, MAX_WIDTH);
            Some(partial_packet(head, &t, MAX_WIDTH, trunk.desc.output_len()))
        }
        [net, ..] => Some(partial_packet(net, pos, stride, n)),
        [] => None,
    }
}

/// `softplus` of the network output for the encoded angles.
#[inline]
pub fn eval<W: Weight>(net: &Net<'_, W>, prepared: &Partial, angles: &[f32]) -> Rgb {
    let mut out = [0.0f32; MAX_WIDTH];
    forward(net, prepared, angles, &mut out);
    softplus_slice(&mut out[..3]);
    [out[0], out[1], out[2]]
}

/// [`eval`] for [`PACKET`] queries: query `q`'s encoded angles at `angles[q * stride..][..n]`.
#[inline]
pub fn eval_packet<W: Weight>(net: &Net<'_, W>, prepared: &Partial, angles: &[f32], stride: usize, n: usize) -> [Rgb; PACKET] {
    let mut out = [0.0f32; PACKET * OUT_STRIDE];
    forward_packet(net, prepared, angles, stride, n, &mut out, OUT_STRIDE);
    // The whole buffer, the unused lanes too: 8 vectors instead of 16 gathers of 3.
    softplus_slice(&mut out);
    core::array::from_fn(|q| {
        let o = &out[q * OUT_STRIDE..];
        [o[0], o[1], o[2]]
    })
}

/// Room per query for the raw outputs of a packet (3, or 6 when enhanced).
pub(crate) const OUT_STRIDE: usize = 8;
