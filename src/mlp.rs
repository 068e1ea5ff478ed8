//! Dense ReLU networks over borrowed weight slices, evaluated with stack arrays and no allocation.
//!
//! The layout is the contract of `docs/models.md`: `Mlp(n_in, W, H, n_out, S)` has `H` hidden layers of
//! width `W` (Linear + ReLU), hidden layer `S ≥ 1` takes `[h, x]` (input skip; `S = 0`: none), then an
//! output Linear to `n_out` values without activation (`n_out = 0`: no output layer, the last hidden
//! activation is the output). Each layer stores its matrix `[in][out]` row-major followed by its bias, so
//! `y = b + Σ_i x_i M[i]` runs as a sum of scaled rows whose inner loop over outputs vectorises.
//!
//! A network input is split into a *head* and a *tail*, `x = [head, tail]`. The head's contribution to
//! every layer that reads `x` (layer 0 and the skip layer) is computed once by [`partial`] — for the BRDF
//! networks the head is the position encoding, fixed per shading point — and [`forward`] adds only the
//! tail (the encoded angles) per direction pair.
//!
//! Each layer runs through a [`crate::kernels`] kernel chosen for the CPU at run time; [`forward_packet`]
//! evaluates [`PACKET`] queries at once, reading every weight row once per packet.

use serde::{Deserialize, Serialize};

use crate::kernels::{kernels, Chain, ChainLayer, Dense, Init, Segment, CHAIN_OUT_MAX, CHAIN_TAIL_MAX, CHAIN_WIDTH};
use crate::Error;

pub use crate::kernels::{Weight, PACKET};

/// Largest hidden width (and output count) the stack arrays hold.
pub const MAX_WIDTH: usize = 256;
/// Largest number of hidden layers of one network.
pub const MAX_HIDDEN: usize = 16;

/// Shape of one network: `Mlp(n_in, width, hidden, n_out, skip)` of `docs/models.md`.
///
/// ```
/// use nbrdf::mlp::NetDesc;
/// // The Single MLP of Sec. 4.1.2 on 64 position and 27 angle features.
/// let net = NetDesc { n_in: 91, width: 128, hidden: 6, n_out: 3, skip: 2 };
/// assert!(net.validate().is_ok());
/// assert_eq!(net.layer_inputs(2), 128 + 91);
/// assert_eq!(net.n_weights(), 91 * 128 + 128 + 4 * (128 * 128 + 128) + (219 * 128 + 128) + 128 * 3 + 3);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct NetDesc {
    /// Network input size.
    pub n_in: u16,
    /// Width of every hidden layer.
    pub width: u16,
    /// Number of hidden layers (Linear + ReLU).
    pub hidden: u8,
    /// Outputs of the final linear layer; 0 for none (the trunk networks).
    pub n_out: u16,
    /// 0-based hidden layer that also receives the network input; 0 for no skip.
    pub skip: u8,
}

impl NetDesc {
    /// Number of inputs of hidden layer `l` (`l = hidden` is the output layer).
    #[inline]
    pub const fn layer_inputs(&self, l: usize) -> usize {
        if l == 0 {
            self.n_in as usize
        } else if self.skip != 0 && l == self.skip as usize {
            self.width as usize + self.n_in as usize
        } else {
            self.width as usize
        }
    }

    /// Number of outputs of layer `l` (`l = hidden` is the output layer).
    #[inline]
    pub const fn layer_outputs(&self, l: usize) -> usize {
        if l < self.hidden as usize {
            self.width as usize
        } else {
            self.n_out as usize
        }
    }

    /// Number of layers with weights: the hidden ones plus the output layer if any.
    #[inline]
    pub const fn n_layers(&self) -> usize {
        self.hidden as usize + if self.n_out > 0 { 1 } else { 0 }
    }

    /// Offset of layer `l`'s matrix in the network's weights; its bias follows the matrix.
    #[inline]
    pub const fn layer_offset(&self, l: usize) -> usize {
        let mut off = 0;
        let mut i = 0;
        while i < l {
            off += (self.layer_inputs(i) + 1) * self.layer_outputs(i);
            i += 1;
        }
        off
    }

    /// Total number of weights and biases.
    #[inline]
    pub const fn n_weights(&self) -> usize {
        self.layer_offset(self.n_layers())
    }

    /// Length of the network output: `n_out`, or `width` for a trunk without output layer.
    #[inline]
    pub const fn output_len(&self) -> usize {
        if self.n_out > 0 {
            self.n_out as usize
        } else {
            self.width as usize
        }
    }

    /// Checks the shape against the evaluator's fixed limits.
    pub fn validate(&self) -> Result<(), Error> {
        if self.width == 0 || self.hidden == 0 {
            return Err(Error::InvalidValue {
                what: "network shape",
                reason: "width and hidden layer count must be positive",
            });
        }
        if self.width as usize > MAX_WIDTH {
            return Err(Error::TooLarge { what: "network width", found: self.width as usize, max: MAX_WIDTH });
        }
        if self.n_out as usize > MAX_WIDTH {
            return Err(Error::TooLarge { what: "network outputs", found: self.n_out as usize, max: MAX_WIDTH });
        }
        if self.hidden as usize > MAX_HIDDEN {
            return Err(Error::TooLarge { what: "hidden layers", found: self.hidden as usize, max: MAX_HIDDEN });
        }
        if self.skip as usize >= self.hidden as usize {
            return Err(Error::InvalidValue {
                what: "network skip layer",
                reason: "the skip must target a hidden layer after the first",
            });
        }
        Ok(())
    }
}

/// A network's shape with its weights (exactly `desc.n_weights()` of them).
#[derive(Clone, Copy, Debug)]
pub struct Net<'a, W> {
    /// Shape.
    pub desc: NetDesc,
    /// Weights in file order.
    pub weights: &'a [W],
}

/// The head's contribution to the layers that read the network input (layer 0 and the skip layer),
/// biases included: the per-shading-point part of [`forward`].
#[derive(Clone, Copy, Debug)]
pub struct Partial {
    /// Pre-activation of hidden layer 0 without the tail rows.
    pub layer0: [f32; MAX_WIDTH],
    /// Pre-activation contribution of the skip layer's bias and head rows.
    pub skip: [f32; MAX_WIDTH],
    /// Number of head values folded in.
    pub head_len: usize,
}

impl Default for Partial {
    fn default() -> Self {
        Partial { layer0: [0.0; MAX_WIDTH], skip: [0.0; MAX_WIDTH], head_len: 0 }
    }
}

/// A segment without inputs, for layers that read one.
#[inline(always)]
fn none<'a, W>() -> Segment<'a, W> {
    Segment { x: &[], stride: 0, n: 0, rows: &[] }
}

/// Folds the `head` (the first `head.len()` network inputs) into layer 0 and the skip layer.
///
/// ```
/// use nbrdf::mlp::{forward, partial, Net, NetDesc};
/// // 2 inputs -> 2 hidden (identity weights) -> 1 output summing them.
/// let desc = NetDesc { n_in: 2, width: 2, hidden: 1, n_out: 1, skip: 0 };
/// let w = [1.0f32, 0.0, 0.0, 1.0, /* bias */ 0.0, 0.0, /* out */ 1.0, 1.0, /* bias */ 0.5];
/// let net = Net { desc, weights: &w[..] };
/// let p = partial(&net, &[2.0]);         // head: first input
/// let mut out = [0.0f32; 1];
/// forward(&net, &p, &[3.0], &mut out);   // tail: second input
/// assert_eq!(out[0], 5.5);
/// ```
#[inline]
pub fn partial<W: Weight>(net: &Net<'_, W>, head: &[f32]) -> Partial {
    let k = kernels::<W>();
    let width = net.desc.width as usize;
    let head = &head[..head.len().min(net.desc.n_in as usize)];
    let mut p = Partial { head_len: head.len(), ..Partial::default() };
    let mut bias = [[0.0f32; MAX_WIDTH]; 2];
    let (l0, skip) = head_layers(net, head, 0, head.len(), &mut bias);
    k.one(&l0, &mut p.layer0[..width]);
    if let Some(ls) = skip {
        k.one(&ls, &mut p.skip[..width]);
    }
    p
}

/// The layers of `net` that read its input, layer 0 and the skip layer (where there is one), over
/// the `n ≤ n_in` head inputs at `x` (`stride` apart for packets): their head rows from their biases
/// (widened into `bias`), no ReLU. What [`partial`] and [`partial_packet`] run.
#[inline(always)]
fn head_layers<'a, W: Weight>(
    net: &Net<'a, W>,
    x: &'a [f32],
    stride: usize,
    n: usize,
    bias: &'a mut [[f32; MAX_WIDTH]; 2],
) -> (Dense<'a, W>, Option<Dense<'a, W>>) {
    let d = &net.desc;
    let (width, n_in) = (d.width as usize, d.n_in as usize);
    let w0 = &net.weights[..(n_in + 1) * width];
    W::widen(&w0[n_in * width..], &mut bias[0][..width]);
    let skip_rows = (d.skip != 0).then(|| {
        let off = d.layer_offset(d.skip as usize);
        let rows = width + n_in;
        let ws = &net.weights[off..off + (rows + 1) * width];
        W::widen(&ws[rows * width..], &mut bias[1][..width]);
        &ws[width * width..]
    });
    let bias: &'a [[f32; MAX_WIDTH]; 2] = bias;
    let layer = |init: &'a [f32], rows| Dense { init: &init[..width], segs: [Segment { x, stride, n, rows }, none()], n_segs: 1, n_out: width, relu: false };
    (layer(&bias[0], w0), skip_rows.map(|rows| layer(&bias[1], rows)))
}

/// The network after `partial`, for one query (`Q = 1`, the one-query kernels) or a packet of
/// [`PACKET`] queries (`Q = PACKET`): query `q`'s tail at `tail[q * tail_stride..][..n_tail]`, its
/// `desc.output_len()` outputs at `out[q * out_stride..]`. Activations live in `h` and `t`
/// (`Q × width` values each, query after query).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn run<W: Weight, const Q: usize>(
    net: &Net<'_, W>,
    partial: &Partial,
    tail: &[f32],
    tail_stride: usize,
    n_tail: usize,
    out: &mut [f32],
    out_stride: usize,
    h: &mut [f32],
    t: &mut [f32],
) {
    let k = kernels::<W>();
    let layer = |l: &Dense<'_, W>, out: &mut [f32], os: usize| {
        if Q == 1 {
            k.one(l, out)
        } else {
            k.packet(l, out, os)
        }
    };
    let d = &net.desc;
    let width = d.width as usize;
    let n_in = d.n_in as usize;
    let head = partial.head_len;
    let n_tail = n_tail.min(n_in - head);
    let tail_seg = |rows| Segment { x: tail, stride: tail_stride, n: n_tail, rows };
    let mut bias = [0.0f32; MAX_WIDTH];

    let seg = tail_seg(&net.weights[head * width..(head + n_tail) * width]);
    let l0 = Dense { init: &partial.layer0[..width], segs: [seg, none()], n_segs: 1, n_out: width, relu: true };
    layer(&l0, h, width);

    let mut off = (n_in + 1) * width;
    let (mut h, mut t) = (h, t);
    for l in 1..d.hidden as usize {
        let hs = Segment { x: &h[..], stride: width, n: width, rows: &net.weights[off..off + width * width] };
        if d.skip as usize == l {
            let rows = width + n_in;
            let m = &net.weights[off..off + rows * width];
            let ts = tail_seg(&m[(width + head) * width..(width + head + n_tail) * width]);
            let ls = Dense { init: &partial.skip[..width], segs: [hs, ts], n_segs: 2, n_out: width, relu: true };
            layer(&ls, t, width);
            off += (rows + 1) * width;
        } else {
            W::widen(&net.weights[off + width * width..off + (width + 1) * width], &mut bias[..width]);
            let lh = Dense { init: &bias[..width], segs: [hs, none()], n_segs: 1, n_out: width, relu: true };
            layer(&lh, t, width);
            off += (width + 1) * width;
        }
        core::mem::swap(&mut h, &mut t);
    }

    debug_assert_eq!(off, d.layer_offset(d.hidden as usize));
    output_layer::<W, Q>(net, h, out, out_stride);
}

/// The output layer of `net` on the last hidden activations `h` (`Q × width`, query after query),
/// or those activations themselves for a trunk without one.
#[inline(always)]
fn output_layer<W: Weight, const Q: usize>(net: &Net<'_, W>, h: &[f32], out: &mut [f32], out_stride: usize) {
    let d = &net.desc;
    let width = d.width as usize;
    if d.n_out == 0 {
        for q in 0..Q {
            out[q * out_stride..q * out_stride + width].copy_from_slice(&h[q * width..(q + 1) * width]);
        }
        return;
    }
    let k = kernels::<W>();
    let n_out = d.n_out as usize;
    let off = d.layer_offset(d.hidden as usize);
    let m = &net.weights[off..off + (width + 1) * n_out];
    let mut bias = [0.0f32; MAX_WIDTH];
    W::widen(&m[width * n_out..], &mut bias[..n_out]);
    let hs = Segment { x: h, stride: width, n: width, rows: m };
    let lo = Dense { init: &bias[..n_out], segs: [hs, none()], n_segs: 1, n_out, relu: false };
    if Q == 1 {
        k.one(&lo, out)
    } else {
        k.packet(&lo, out, out_stride)
    }
}

/// Runs the network on `x = [head, tail]`, the head already folded into `partial`; writes
/// `desc.output_len()` values to the front of `out` (which must hold them; `MAX_WIDTH` always does).
#[inline]
pub fn forward<W: Weight>(net: &Net<'_, W>, partial: &Partial, tail: &[f32], out: &mut [f32]) {
    if forward_chain(net, partial, tail, out) {
        return;
    }
    let mut h = [0.0f32; MAX_WIDTH];
    let mut t = [0.0f32; MAX_WIDTH];
    run::<W, 1>(net, partial, tail, 0, tail.len(), out, 0, &mut h, &mut t);
}

/// [`forward`] in one kernel call ([`Chain`]) where the level has the kernel and the network its shape
/// (hidden width [`CHAIN_WIDTH`], at most [`CHAIN_OUT_MAX`] outputs); `false` where it ran nothing.
#[inline]
fn forward_chain<W: Weight>(net: &Net<'_, W>, partial: &Partial, tail: &[f32], out: &mut [f32]) -> bool {
    let k = kernels::<W>();
    let d = &net.desc;
    let (width, n_in, head) = (d.width as usize, d.n_in as usize, partial.head_len);
    let n_tail = tail.len().min(n_in - head);
    if !k.has_chain()
        || width != CHAIN_WIDTH
        || d.n_out as usize > CHAIN_OUT_MAX
        || d.hidden == 0
        || d.hidden as usize > MAX_HIDDEN
        || n_tail > CHAIN_TAIL_MAX
    {
        return false;
    }
    let w = net.weights;
    let mut hidden = [ChainLayer { init: Init::F32(&[]), rows: &[], tail_rows: None }; MAX_HIDDEN];
    for (l, hl) in hidden.iter_mut().enumerate().take(d.hidden as usize).skip(1) {
        let off = d.layer_offset(l);
        hl.rows = &w[off..off + width * width];
        if d.skip as usize == l {
            let t = off + (width + head) * width;
            hl.tail_rows = Some(&w[t..t + n_tail * width]);
            hl.init = Init::F32(&partial.skip[..width]);
        } else {
            hl.init = Init::Bias(&w[off + width * width..off + (width + 1) * width]);
        }
    }
    let n_out = d.n_out as usize;
    let out_layer = (n_out > 0).then(|| {
        let off = d.layer_offset(d.hidden as usize);
        (&w[off + width * n_out..off + (width + 1) * n_out], &w[off..off + width * n_out], n_out)
    });
    let chain = Chain {
        tail: &tail[..n_tail],
        first_init: &partial.layer0[..width],
        first_rows: &w[head * width..(head + n_tail) * width],
        hidden: &hidden[1..d.hidden as usize],
        out: out_layer,
    };
    k.chain(&chain, out)
}

/// [`forward`] for a packet of [`PACKET`] queries at one prepared point: query `q`'s tail is
/// `tails[q * tail_stride..][..n_tail]`, its `desc.output_len()` outputs go to `out[q * out_stride..]`.
///
/// Each weight row is read once per packet, and every query gets the same bits as [`forward`] on its
/// own tail (see [`crate::kernels`], "Determinism").
///
/// Panics when `tails` or `out` is too short for the packet.
#[inline]
pub fn forward_packet<W: Weight>(
    net: &Net<'_, W>,
    partial: &Partial,
    tails: &[f32],
    tail_stride: usize,
    n_tail: usize,
    out: &mut [f32],
    out_stride: usize,
) {
    // Only the `PACKET × width` values a packet's activations use are zeroed (not the 32 KB of both
    // buffers, the size of an L1 whose blocks of weights they would evict).
    let n = PACKET * (net.desc.width as usize).min(MAX_WIDTH);
    let (mut h, mut t) = (core::mem::MaybeUninit::<[f32; PACKET * MAX_WIDTH]>::uninit(), core::mem::MaybeUninit::<[f32; PACKET * MAX_WIDTH]>::uninit());
    run::<W, PACKET>(net, partial, tails, tail_stride, n_tail, out, out_stride, zeroed_prefix(&mut h, n), zeroed_prefix(&mut t, n));
}

/// The first `n` values of `buf` (at most its length), zeroed; the rest stays uninitialised.
#[inline(always)]
fn zeroed_prefix<const N: usize>(buf: &mut core::mem::MaybeUninit<[f32; N]>, n: usize) -> &mut [f32] {
    let n = n.min(N);
    let p = buf.as_mut_ptr().cast::<f32>();
    // SAFETY: `n ≤ N` floats of `buf`, written (all-zero bits are 0.0) before the slice is made.
    unsafe {
        core::ptr::write_bytes(p, 0, n);
        core::slice::from_raw_parts_mut(p, n)
    }
}

/// Runs the network on its whole input `x` (no precomputed head: all of `x` is the tail, so the skip
/// layer adds its rows after the hidden ones), one query; [`eval_packet`] gives each of its queries
/// these bits.
#[inline]
pub fn eval<W: Weight>(net: &Net<'_, W>, x: &[f32], out: &mut [f32]) {
    forward(net, &partial(net, &[]), x, out)
}

/// [`eval`] for [`PACKET`] queries (the packet kernels): query `q`'s input at `x[q * stride..][..n]`,
/// its `desc.output_len()` outputs at `out[q * out_stride..]`, each the bits of [`eval`] on that input.
/// What [`crate::model::Model::prepare_many`] runs the position networks with: every point its own
/// input, where [`forward_packet`]'s queries share one prepared point.
///
/// Panics when `x` or `out` is too short for the packet.
///
/// ```
/// use nbrdf::mlp::{eval, eval_packet, Net, NetDesc, PACKET};
/// let desc = NetDesc { n_in: 2, width: 4, hidden: 2, n_out: 1, skip: 1 };
/// let w: Vec<f32> = (0..desc.n_weights()).map(|i| ((i * 7 % 11) as f32 - 5.0) * 0.1).collect();
/// let net = Net { desc, weights: &w[..] };
/// let x: Vec<f32> = (0..2 * PACKET).map(|i| (i as f32 * 0.37).sin()).collect();
/// let mut many = [0.0f32; PACKET];
/// eval_packet(&net, &x, 2, 2, &mut many, 1);
/// for q in 0..PACKET {
///     let mut one = [0.0f32; 1];
///     eval(&net, &x[2 * q..2 * q + 2], &mut one);
///     assert_eq!(one[0].to_bits(), many[q].to_bits());
/// }
/// ```
#[inline]
pub fn eval_packet<W: Weight>(net: &Net<'_, W>, x: &[f32], stride: usize, n: usize, out: &mut [f32], out_stride: usize) {
    forward_packet(net, &partial(net, &[]), x, stride, n, out, out_stride)
}

/// The partials of [`PACKET`] points ([`partial_packet`]), point after point at the network's width:
/// [`PartialPacket::write`] puts one into a [`Partial`] (2 KB each: written in place, not returned
/// in an array of them, whose copies took ~13% of a packet's prepare).
#[derive(Clone, Debug)]
pub struct PartialPacket {
    layer0: [f32; PACKET * MAX_WIDTH],
    skip: [f32; PACKET * MAX_WIDTH],
    width: usize,
    has_skip: bool,
    head_len: usize,
}

impl PartialPacket {
    /// Point `q`'s partial into `p` (all of it: the values past the width are zero, as in [`partial`]).
    #[inline]
    pub fn write(&self, q: usize, p: &mut Partial) {
        let w = self.width;
        p.layer0[..w].copy_from_slice(&self.layer0[q * w..(q + 1) * w]);
        p.layer0[w..].fill(0.0);
        if self.has_skip {
            p.skip[..w].copy_from_slice(&self.skip[q * w..(q + 1) * w]);
            p.skip[w..].fill(0.0);
        } else {
            p.skip.fill(0.0);
        }
        p.head_len = self.head_len;
    }
}

/// [`partial`] for [`PACKET`] points (the packet kernel): point `q`'s head at
/// `heads[q * stride..][..n]`. Each partial is [`partial`]'s for that head but for the sign of a zero
/// sum (the packet kernel adds the zero inputs that the one-query kernel skips), which the ReLU after
/// it erases (see [`crate::kernels`], "Determinism"): evaluations from either give the same bits.
///
/// Panics when `heads` is too short for the packet.
///
/// ```
/// use nbrdf::mlp::{forward, partial, partial_packet, Net, NetDesc, Partial, PACKET};
/// let desc = NetDesc { n_in: 3, width: 4, hidden: 2, n_out: 1, skip: 1 };
/// let w: Vec<f32> = (0..desc.n_weights()).map(|i| ((i * 5 % 13) as f32 - 6.0) * 0.1).collect();
/// let net = Net { desc, weights: &w[..] };
/// let heads: Vec<f32> = (0..2 * PACKET).map(|i| (i as f32 * 0.7).cos()).collect();
/// let many = partial_packet(&net, &heads, 2, 2); // two head inputs a point, the third is the tail
/// for q in 0..PACKET {
///     let mut p = Partial::default();
///     many.write(q, &mut p);
///     let (mut a, mut b) = ([0.0f32; 1], [0.0f32; 1]);
///     forward(&net, &p, &[0.5], &mut a);
///     forward(&net, &partial(&net, &heads[2 * q..2 * q + 2]), &[0.5], &mut b);
///     assert_eq!(a[0].to_bits(), b[0].to_bits());
/// }
/// ```
#[inline]
pub fn partial_packet<W: Weight>(net: &Net<'_, W>, heads: &[f32], stride: usize, n: usize) -> PartialPacket {
    let k = kernels::<W>();
    let d = &net.desc;
    let width = (d.width as usize).min(MAX_WIDTH);
    let n = n.min(d.n_in as usize);
    let mut p = PartialPacket { layer0: [0.0; PACKET * MAX_WIDTH], skip: [0.0; PACKET * MAX_WIDTH], width, has_skip: d.skip != 0, head_len: n };
    let mut bias = [[0.0f32; MAX_WIDTH]; 2];
    let (l0, skip) = head_layers(net, heads, stride, n, &mut bias);
    k.packet(&l0, &mut p.layer0, width);
    if let Some(ls) = skip {
        k.packet(&ls, &mut p.skip, width);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference forward pass written independently: explicit concatenation, [out][in] loops.
    fn reference(desc: &NetDesc, w: &[f32], x: &[f32]) -> [f32; MAX_WIDTH] {
        let mut h: [f32; MAX_WIDTH] = [0.0; MAX_WIDTH];
        let mut input = [0.0f32; 2 * MAX_WIDTH];
        let mut cur_len;
        input[..x.len()].copy_from_slice(x);
        cur_len = x.len();
        let mut off = 0;
        for l in 0..desc.n_layers() {
            let n_i = desc.layer_inputs(l);
            let n_o = desc.layer_outputs(l);
            if l > 0 && desc.skip as usize == l {
                input[cur_len..cur_len + x.len()].copy_from_slice(x);
                cur_len += x.len();
            }
            assert_eq!(cur_len, n_i);
            let mut y = [0.0f32; MAX_WIDTH];
            for o in 0..n_o {
                let mut s = w[off + n_i * n_o + o];
                for i in 0..n_i {
                    s += input[i] * w[off + i * n_o + o];
                }
                y[o] = if l < desc.hidden as usize { s.max(0.0) } else { s };
            }
            off += (n_i + 1) * n_o;
            input[..n_o].copy_from_slice(&y[..n_o]);
            cur_len = n_o;
            h = y;
        }
        h
    }

    fn weights(n: usize, seed: u32) -> [f32; 4096] {
        let mut w = [0.0f32; 4096];
        let mut s = seed;
        for v in w.iter_mut().take(n) {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            *v = ((s >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 0.8;
        }
        w
    }

    #[test]
    fn forward_with_skip_and_head_split_matches_reference() {
        let desc = NetDesc { n_in: 5, width: 8, hidden: 4, n_out: 3, skip: 2 };
        desc.validate().unwrap();
        let w = weights(desc.n_weights(), 7);
        let net = Net { desc, weights: &w[..desc.n_weights()] };
        let x = [0.3, -0.2, 0.9, 0.1, -0.7];
        let want = reference(&desc, &w, &x);
        for head in 0..=5 {
            let p = partial(&net, &x[..head]);
            let mut out = [0.0f32; MAX_WIDTH];
            forward(&net, &p, &x[head..], &mut out);
            for o in 0..3 {
                assert!((out[o] - want[o]).abs() < 1e-5, "head {head}: {} vs {}", out[o], want[o]);
            }
        }
    }

    #[test]
    fn trunk_without_output_layer_returns_last_activation() {
        let desc = NetDesc { n_in: 3, width: 6, hidden: 3, n_out: 0, skip: 1 };
        let w = weights(desc.n_weights(), 3);
        let net = Net { desc, weights: &w[..desc.n_weights()] };
        let x = [0.5, 0.25, -1.0];
        let want = reference(&desc, &w, &x);
        let mut out = [0.0f32; MAX_WIDTH];
        eval(&net, &x, &mut out);
        assert_eq!(desc.output_len(), 6);
        for o in 0..6 {
            assert!((out[o] - want[o]).abs() < 1e-6);
            assert!(out[o] >= 0.0);
        }
    }

    #[test]
    fn f16_weights_evaluate_like_their_f32_values() {
        let desc = NetDesc { n_in: 4, width: 8, hidden: 2, n_out: 2, skip: 1 };
        let w = weights(desc.n_weights(), 11);
        let w16: [half::f16; 4096] = core::array::from_fn(|i| half::f16::from_f32(w[i]));
        let w32: [f32; 4096] = core::array::from_fn(|i| w16[i].to_f32());
        let x = [0.1, 0.2, 0.3, 0.4];
        let (mut a, mut b) = ([0.0f32; MAX_WIDTH], [0.0f32; MAX_WIDTH]);
        eval(&Net { desc, weights: &w16[..desc.n_weights()] }, &x, &mut a);
        eval(&Net { desc, weights: &w32[..desc.n_weights()] }, &x, &mut b);
        assert_eq!(a[..2], b[..2]);
    }

    #[test]
    fn shapes_beyond_the_stack_capacity_are_rejected() {
        let wide = NetDesc { n_in: 3, width: 512, hidden: 2, n_out: 3, skip: 0 };
        assert!(matches!(wide.validate(), Err(Error::TooLarge { what: "network width", .. })));
        let bad_skip = NetDesc { n_in: 3, width: 8, hidden: 2, n_out: 3, skip: 2 };
        assert!(matches!(bad_skip.validate(), Err(Error::InvalidValue { .. })));
    }
}
