//! Single MLP (Sec. 4.1.2): one network from `[p, PE(a)]` to RGB with a softplus output, 6 layers of
//! width 128 and an input skip to the third layer. With fewer direction layers (Tab. 2) a position-only
//! trunk runs first and the angles join the trunk's features.

use crate::math::softplus;
use crate::mlp::{self, forward, partial, Net, Partial, Weight, MAX_WIDTH};
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

/// `softplus` of the network output for the encoded angles.
#[inline]
pub fn eval<W: Weight>(net: &Net<'_, W>, prepared: &Partial, angles: &[f32]) -> Rgb {
    let mut out = [0.0f32; MAX_WIDTH];
    forward(net, prepared, angles, &mut out);
    [softplus(out[0]), softplus(out[1]), softplus(out[2])]
}
