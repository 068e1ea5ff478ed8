//! The additive diffuse/specular split of Sec. 4.1.2 and its enhancement (Sec. 4.4, Eq. 8).

use crate::math::{map_outputs, sanitize, sigmoid_slice, INV_PI};
use crate::mlp::{forward, forward_packet, Net, Partial, Weight, MAX_WIDTH, PACKET};
use crate::Rgb;

/// Lambertian diffuse term from the diffuse network's raw outputs: `σ(d) / π` (Sec. 4.1.2), so the
/// albedo lies in (0, 1).
///
/// ```
/// let f_d = nbrdf::neural::split::diffuse(&[0.0, 0.0, 0.0]);
/// assert!((f_d[0] - 0.5 / core::f32::consts::PI).abs() < 1e-7);
/// ```
#[inline]
pub fn diffuse(raw: &[f32]) -> Rgb {
    // A network whose activations overflowed (inf - inf inside it, e.g. f16 weights near ±65504) emits
    // NaN, and sigmoid(NaN) is NaN: like every degenerate value of the crate it reads as 0, so that
    // `Prepared::diffuse` never hands a renderer NaN (tests/hard_cases.rs).
    // Through the same map as the trainer's sigmoid op, so the candle twin's `f_d` is this one's bits.
    let mut s = [raw[0], raw[1], raw[2]];
    sigmoid_slice(&mut s);
    sanitize([s[0] * INV_PI, s[1] * INV_PI, s[2] * INV_PI])
}

/// Combines the diffuse term with the specular network's raw outputs `s`.
///
/// Plain split: `f = f_d + softplus(s[0..3])`. Enhanced (Eq. 8): `ξ = σ(s[3..6])` and
/// `f = (1 - ξ) ∘ f_d + softplus(s[0..3])`, light reflected at the surface no longer available to the
/// diffuse (subsurface) part.
///
/// ```
/// use nbrdf::neural::split::combine;
/// let f_d = [0.2, 0.2, 0.2];
/// let plain = combine(f_d, &[-30.0, -30.0, -30.0], false);
/// assert!((plain[0] - 0.2).abs() < 1e-6);
/// // ξ → 1 removes the diffuse part entirely.
/// let enhanced = combine(f_d, &[-30.0, -30.0, -30.0, 30.0, 30.0, 30.0], true);
/// assert!(enhanced[0] < 1e-6);
/// ```
#[inline]
pub fn combine(f_d: Rgb, s: &[f32], enhanced: bool) -> Rgb {
    let mut m = [0.0f32; 6];
    let n = if enhanced { 6 } else { 3 };
    m[..n].copy_from_slice(&s[..n]);
    map_split(&mut m, enhanced);
    mix(f_d, &m, enhanced)
}

// `map_outputs` picks a value's map by its index modulo 8.
const _: () = assert!(super::single_mlp::OUT_STRIDE == 8);

/// The maps of [`combine`] on raw outputs in place, 8 per query: softplus of `s[0..3]`, and when
/// enhanced the sigmoid `ξ` of `s[3..6]`.
#[inline]
fn map_split(s: &mut [f32], enhanced: bool) {
    map_outputs(s, 0b111, if enhanced { 0b111_000 } else { 0 });
}

/// [`combine`] of outputs already mapped by [`map_split`].
#[inline]
fn mix(f_d: Rgb, m: &[f32], enhanced: bool) -> Rgb {
    core::array::from_fn(|c| {
        let keep = if enhanced { 1.0 - m[3 + c] } else { 1.0 };
        keep * f_d[c] + m[c]
    })
}

/// The specular network of an additive model on the encoded angles, combined with `f_d` by
/// [`combine`]: `f_d + f_s`, or Eq. 8 when `enhanced`. Shared by both additive architectures.
#[inline]
pub fn eval<W: Weight>(specular: &Net<'_, W>, f_d: Rgb, prepared: &Partial, angles: &[f32], enhanced: bool) -> Rgb {
    let mut s = [0.0f32; MAX_WIDTH];
    forward(specular, prepared, angles, &mut s);
    map_split(&mut s[..8], enhanced);
    mix(f_d, &s, enhanced)
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
    map_split(&mut s, enhanced);
    core::array::from_fn(|q| mix(f_d, &s[q * S..(q + 1) * S], enhanced))
}
