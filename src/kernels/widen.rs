//! f16 weights widened to f32 a slice at a time: the conversion behind the f16 rows of the generic
//! kernels (`lanes.rs`), every f16 bias ([`super::Weight::widen`]) and the widening of an f16 model
//! file to f32 at load (`Model::to_f32`, which `ModelBuf` runs).
//!
//! The x86 levels run one loop over their lanes (`x86::widen_f16`: 16 values per AVX-512 `vcvtph2ps`,
//! 8 per AVX2 one), written here rather than taken from `half`'s `convert_to_f32_slice`, which
//! converts 8 values per `vcvtph2ps` at every level (docs/speed.md). All are exact (every f16 value is
//! an f32 value), so the level changes time, never bits.

#[cfg(target_arch = "x86_64")]
use super::Level;

/// `dst[i] = src[i] as f32` for `i < min(src.len(), dst.len())`; outside the crate, `Weight::widen`
/// of `half::f16`.
///
/// ```
/// use half::f16;
/// use nbrdf::kernels::Weight;
/// let src: Vec<f16> = [0.5f32, -2.0, 65504.0, 6e-8].iter().map(|&v| f16::from_f32(v)).collect();
/// let mut dst = [0.0f32; 4];
/// f16::widen(&src, &mut dst);
/// assert_eq!(dst, [0.5, -2.0, 65504.0, f16::from_f32(6e-8).to_f32()]);
/// ```
#[inline]
pub fn widen_f16(src: &[half::f16], dst: &mut [f32]) {
    let n = src.len().min(dst.len());
    let (src, dst) = (&src[..n], &mut dst[..n]);
    #[cfg(target_arch = "x86_64")]
    match super::level() {
        // SAFETY: `level()` is at most the detected level, so the CPU has the level's features;
        // both slices hold `n` values.
        Level::Avx512 => return unsafe { super::avx512::widen_f16(src, dst) },
        // SAFETY: as above (the AVX2 level includes F16C).
        Level::Avx2 => return unsafe { super::avx2::widen_f16(src, dst) },
        _ => {}
    }
    for (d, s) in dst.iter_mut().zip(src) {
        *d = s.to_f32();
    }
}

#[cfg(test)]
mod tests {
    /// Every f16 bit pattern, from an odd start and with a tail shorter than a vector, through each
    /// level this CPU has (called directly: the process-wide level is left alone) against `half`'s
    /// scalar conversion: the same bits, NaN for NaN.
    #[test]
    fn every_f16_value_widens_as_half_does() {
        let all: std::vec::Vec<half::f16> = (0..=u16::MAX).chain(0..21).map(half::f16::from_bits).collect();
        let src = &all[3..];
        let check = |name: &str, dst: &[f32]| {
            for (s, d) in src.iter().zip(dst) {
                let want = s.to_f32();
                assert!(d.to_bits() == want.to_bits() || (want.is_nan() && d.is_nan()), "{name}: {:#06x} gave {d:?}", s.to_bits());
            }
        };
        let mut dst = std::vec![f32::NAN; src.len()];
        super::widen_f16(src, &mut dst);
        check("dispatched", &dst);
        #[cfg(target_arch = "x86_64")]
        {
            if super::super::detected() >= super::Level::Avx2 {
                dst.fill(f32::NAN);
                // SAFETY: the CPU has the AVX2 level (F16C); equal lengths.
                unsafe { super::super::avx2::widen_f16(src, &mut dst) };
                check("avx2", &dst);
            }
            if super::super::detected() >= super::Level::Avx512 {
                dst.fill(f32::NAN);
                // SAFETY: the CPU has AVX-512; equal lengths.
                unsafe { super::super::avx512::widen_f16(src, &mut dst) };
                check("avx512", &dst);
            }
            for l in [super::Level::Avx2, super::Level::Avx512] {
                if super::super::detected() < l {
                    super::super::skipped("the f16 widening", l);
                }
            }
        }
        // The shorter slice bounds the conversion; nothing past it is written.
        let mut short = [7.0f32; 5];
        super::widen_f16(&src[..3], &mut short);
        assert_eq!(short[3..], [7.0, 7.0]);
    }
}
