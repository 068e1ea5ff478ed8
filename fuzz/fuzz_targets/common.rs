//! Helpers shared by the fuzz targets (each target includes this file with `mod common;`).
#![allow(dead_code)]

use nbrdf::{Rgb, Vec3};

/// Six arbitrary floats (any bits: NaN, infinities, subnormals, huge) as a direction pair.
pub fn pair(v: [f32; 6]) -> (Vec3, Vec3) {
    (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
}

/// The contract of every BRDF evaluation: finite and non-negative, whatever the input.
pub fn assert_valid_brdf(f: Rgb, what: &str) {
    assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0), "{what} gave {f:?}");
}

use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::mlp::NetDesc;
use nbrdf::parametric::ParametricKind;

/// Number of model shapes [`small_header`] knows.
pub const N_SHAPES: usize = 12;

/// A valid header of every model kind with small networks (width 4, so a whole file is a few hundred
/// bytes and a fuzzer can reach every field; width 32, two AVX-512 vectors, where `variant & 0x80`):
/// shape `i` picks the kind; `variant` the precision, the reciprocity, the position encoding, the
/// angle octaves and the width.
pub fn small_header(i: usize, variant: u8) -> ModelHeader {
    let kind = match i % N_SHAPES {
        k @ 0..=4 => ModelKind::Parametric(ParametricKind::ALL[k]),
        5 | 6 => ModelKind::SingleMlp,
        7 | 8 => ModelKind::AdditiveSeparate,
        _ => ModelKind::AdditiveShared,
    };
    let enhanced = matches!(i % N_SHAPES, 8 | 10);
    let reciprocity = [Reciprocity::Exact, Reciprocity::None, Reciprocity::Swap][(variant % 3) as usize];
    let position = [
        PositionEncoding::Uniform,
        PositionEncoding::Intrinsic { k: 3 },
        PositionEncoding::Extrinsic { frequencies: 1 },
    ][((variant / 3) % 3) as usize];
    let precision = if variant & 0x10 != 0 { Precision::F16 } else { Precision::F32 };
    let freqs = [0u8, 1, 3, 16][((variant >> 5) & 3) as usize];
    let mut h = ModelHeader::paper(kind, enhanced, reciprocity, position, freqs);
    if i % N_SHAPES == 6 {
        h = h.with_direction_layers(2); // trunk + head
    }
    // Shrink every network to width 4 or 32, or keep 128 (the width of the sparse packet kernels) for
    // a quarter of the shape indices past the first N_SHAPES (shapes stay consistent: inputs that
    // were 128 trunk features become the width), and the skip to within the hidden layers.
    let width: u16 = if (i / N_SHAPES) % 4 == 3 {
        128
    } else if variant & 0x80 != 0 {
        32
    } else {
        4
    };
    let n = h.n_nets as usize;
    for j in 0..n {
        let d = h.nets[j];
        let reads_trunk = j > 0 && matches!((kind, n), (ModelKind::SingleMlp, 2) | (ModelKind::AdditiveShared, 3));
        let n_in = if reads_trunk { d.n_in - 128 + width } else { d.n_in };
        let hidden = d.hidden.min(3);
        let skip = if d.skip != 0 && d.skip < hidden { d.skip } else { 0 };
        h.nets[j] = NetDesc { n_in, width, hidden, n_out: d.n_out, skip };
    }
    ModelHeader { precision, ..h }
}

/// Deterministic weights in [-scale, scale] for `h`, as `encode` takes them.
pub fn weights(h: &ModelHeader, seed: u64, scale: f32) -> Vec<f32> {
    let mut s = seed ^ 0x9e37_79b9_7f4a_7c15;
    (0..h.n_weights())
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
        })
        .collect()
}

/// A valid model file of shape `i` (with a 2-row position table for the intrinsic encoding).
pub fn small_file(i: usize, variant: u8) -> Vec<u8> {
    let h = small_header(i, variant);
    let table: Vec<f32> = (0..2 * h.position.input_len()).map(|j| j as f32 * 0.25 - 0.5).collect();
    let table = matches!(h.position, PositionEncoding::Intrinsic { .. }).then_some(&table[..]);
    encode(&h, &weights(&h, i as u64, 0.5), table).expect("small headers are valid")
}

/// Bitwise equality of two values (NaN-safe).
pub fn same_bits(a: Rgb, b: Rgb) -> bool {
    a.map(f32::to_bits) == b.map(f32::to_bits)
}

/// Whether the crate's hemisphere gate accepts `w`.
pub fn above(w: Vec3) -> bool {
    nbrdf::angles::unit(w).is_some_and(|u| u.z > 0.0)
}
