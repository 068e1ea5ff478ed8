//! The extrinsic alternative to the intrinsic encoding: positional (Fourier) encoding of the 3D point
//! itself (Mildenhall et al. 2020, NeRF, Eq. 4), the baseline Koestler et al. 2022 compare against.
//!
//! Layout per value v (see `docs/models.md`, "Positional encoding"):
//! `[v, sin(2^0 v), cos(2^0 v), …, sin(2^(F-1) v), cos(2^(F-1) v)]`, blocks for x, y, z in that order,
//! `3 (1 + 2F)` values in all. The point is expected in the mesh's unit-sphere normalisation.

use super::Error;

/// Number of outputs of [`extrinsic_into`] for `frequencies` octaves: `3 (1 + 2F)`.
pub const fn extrinsic_len(frequencies: usize) -> usize {
    3 * (1 + 2 * frequencies)
}

/// Writes the positional encoding of `x` with `frequencies` octaves into `out`
/// (`out.len()` must be [`extrinsic_len`]`(frequencies)`).
///
/// `2^f · v` is formed by exact power-of-two scaling in `f32` (no rounding unless it overflows), so
/// the only rounding is that of `sin` and `cos`.
pub fn extrinsic_into(x: [f32; 3], frequencies: usize, out: &mut [f32]) -> Result<(), Error> {
    let expected = extrinsic_len(frequencies);
    if out.len() != expected {
        return Err(Error::OutputLength {
            expected,
            got: out.len(),
        });
    }
    let block = 1 + 2 * frequencies;
    for (v, chunk) in x.iter().zip(out.chunks_exact_mut(block)) {
        chunk[0] = *v;
        let mut scale = 1.0f32;
        for pair in chunk[1..].chunks_exact_mut(2) {
            let (s, c) = (scale * v).sin_cos();
            pair[0] = s;
            pair[1] = c;
            scale *= 2.0;
        }
    }
    Ok(())
}

/// [`extrinsic_into`] into a new vector.
pub fn extrinsic(x: [f32; 3], frequencies: usize) -> Vec<f32> {
    let mut out = vec![0.0; extrinsic_len(frequencies)];
    // The length is right by construction.
    let _ = extrinsic_into(x, frequencies, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_value_then_sin_cos_pairs_per_octave_in_xyz_order() {
        let x = [0.25f32, -0.5, 1.0];
        let e = extrinsic(x, 3);
        assert_eq!(e.len(), 21);
        for (j, v) in x.iter().map(|&v| f64::from(v)).enumerate() {
            let block = &e[7 * j..7 * j + 7];
            assert_eq!(f64::from(block[0]), v);
            for f in 0..3 {
                let arg = v * f64::from(1u32 << f);
                assert!((f64::from(block[1 + 2 * f]) - arg.sin()).abs() < 1e-6);
                assert!((f64::from(block[2 + 2 * f]) - arg.cos()).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn zero_frequencies_is_the_identity_and_a_wrong_length_is_an_error() {
        assert_eq!(extrinsic([1.0, 2.0, 3.0], 0), vec![1.0, 2.0, 3.0]);
        let mut short = [0.0; 8];
        assert!(matches!(
            extrinsic_into([0.0; 3], 1, &mut short),
            Err(Error::OutputLength { expected: 9, got: 8 })
        ));
    }
}
