//! Positional (Fourier) encoding of network inputs (Mildenhall et al. 2020, "NeRF", Eq. 4), used for the
//! Rusinkiewicz angles and for the extrinsic position encoding (Sec. 4.2).
//!
//! Layout, shared with the trainer (`docs/models.md`): per input value `v` the block
//! `[v, sin(2^0 v), cos(2^0 v), …, sin(2^(F-1) v), cos(2^(F-1) v)]`, blocks in input order. The raw value
//! is kept so that `F = 0` is the identity. Frequencies are powers of two without a factor π because the
//! inputs are angles in radians already.
//!
//! The sines and cosines are computed 16 at a time, vectorised where the CPU allows (`sincos.rs`:
//! [`sincos16`], [`sincos_octaves`]).

mod sincos;

#[cfg(target_arch = "x86_64")]
pub(crate) use sincos::sincos_vector;
pub use sincos::{sincos16, sincos_octaves};

/// Number of outputs of encoding `n` values with `frequencies` octaves: `n (1 + 2F)`.
///
/// ```
/// assert_eq!(nbrdf::encoding::encoded_len(3, 4), 27);
/// ```
#[inline]
pub const fn encoded_len(n: usize, frequencies: usize) -> usize {
    n * (1 + 2 * frequencies)
}

/// Writes `PE(values, frequencies)` into the front of `out` and returns the number of values written.
///
/// `out` must hold at least [`encoded_len`] values; a shorter slice is filled as far as it goes (no
/// panic) and the count written is returned, so callers check it against `encoded_len`.
///
/// Each octave is evaluated directly as `sincos(2^k v)` rather than by the double-angle recurrence,
/// which accumulates error at high octaves, 16 arguments at a time ([`sincos_octaves`],
/// within about an ulp of the true values); the trainer encodes through this function too.
///
/// ```
/// use nbrdf::encoding::positional_encoding;
/// let mut out = [0.0f32; 10];
/// let n = positional_encoding(&[0.5, 1.0], 2, &mut out);
/// assert_eq!(n, 10);
/// assert_eq!(out[0], 0.5);
/// assert!((out[1] - 0.5f32.sin()).abs() < 1e-7 && (out[4] - 1.0f32.cos()).abs() < 1e-7);
/// assert_eq!(out[5], 1.0);
/// ```
#[inline]
pub fn positional_encoding(values: &[f32], frequencies: usize, out: &mut [f32]) -> usize {
    let block = 1 + 2 * frequencies;
    // Whole blocks only.
    let n = values.len().min(out.len() / block);
    for (j, &v) in values[..n].iter().enumerate() {
        out[j * block] = v;
    }
    if frequencies == 0 {
        return n * block;
    }
    // The arguments `2^k v_j` in output order, 16 per batch.
    let (mut j, mut k) = (0, 0);
    for first in (0..n * frequencies).step_by(16) {
        let (s, c) = sincos_octaves(&values[..n], frequencies, first);
        for (s, c) in s.iter().zip(&c).take(n * frequencies - first) {
            let o = j * block + 1 + 2 * k;
            out[o] = *s;
            out[o + 1] = *c;
            k += 1;
            if k == frequencies {
                (j, k) = (j + 1, 0);
            }
        }
    }
    n * block
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_frequencies_is_identity() {
        let mut out = [9.0f32; 3];
        assert_eq!(positional_encoding(&[1.0, 2.0, 3.0], 0, &mut out), 3);
        assert_eq!(out, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn octave_k_is_sin_and_cos_of_2_to_the_k() {
        let mut out = [0.0f32; 9];
        positional_encoding(&[0.3], 4, &mut out);
        for k in 0..4 {
            let x = 0.3f32 * (1u32 << k) as f32;
            assert!((out[1 + 2 * k] - x.sin()).abs() < 1e-6);
            assert!((out[2 + 2 * k] - x.cos()).abs() < 1e-6);
        }
    }

    #[test]
    fn encodings_longer_than_one_vector_of_arguments_keep_their_layout() {
        // 4 values × 5 octaves = 20 arguments: one full batch of 16 and a partial one.
        let v = [0.3f32, 1.7, 2.9, 6.1];
        let mut out = [f32::NAN; 45];
        assert_eq!(positional_encoding(&v, 5, &mut out), 44);
        for (j, &x) in v.iter().enumerate() {
            assert_eq!(out[j * 11], x);
            for k in 0..5 {
                let a = (x * (1u32 << k) as f32) as f64;
                assert!((out[j * 11 + 1 + 2 * k] as f64 - libm::sin(a)).abs() < 1.5e-7, "sin, value {j} octave {k}");
                assert!((out[j * 11 + 2 + 2 * k] as f64 - libm::cos(a)).abs() < 1.5e-7, "cos, value {j} octave {k}");
            }
        }
        assert!(out[44].is_nan(), "nothing written past the blocks");
    }

    #[test]
    fn short_output_is_filled_by_whole_blocks_without_panic() {
        let mut out = [0.0f32; 4];
        assert_eq!(positional_encoding(&[0.1, 0.2], 1, &mut out), 3);
    }
}
