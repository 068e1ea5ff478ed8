//! Peak signal-to-noise ratio of a test image against a reference (paper Sec. 6, Tab. 1), computed on the
//! sRGB-encoded renderings with peak value 1.

use nbrdf_scene::image::RgbImage;

use super::{check_pair, Mask};

/// PSNR in dB: `10 log10(peak² / MSE)` with the MSE over every channel of the pixels the mask keeps (all
/// pixels without a mask) and `peak = 1` (Huynh-Thu & Ghanbari 2008, "Scope of validity of PSNR in
/// image/video quality assessment", Eq. 1). Identical images give `+∞`; an empty mask gives NaN.
///
/// Masked pixels are *excluded* from the mean rather than counted as zero error, so the value does not
/// improve with the amount of black background around the object.
///
/// ```
/// use nbrdf_scene::image::RgbImage;
/// use trainer::metrics::psnr::psnr;
/// let a = RgbImage::from_data(2, 1, vec![[0.5; 3], [0.5; 3]]).unwrap();
/// let b = RgbImage::from_data(2, 1, vec![[0.6; 3], [0.4; 3]]).unwrap();
/// assert!((psnr(&a, &b, None) - 20.0).abs() < 1e-4); // MSE = 0.01
/// ```
pub fn psnr(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> f64 {
    let mse = mse(reference, test, mask);
    if mse == 0.0 {
        return f64::INFINITY;
    }
    -10.0 * mse.log10()
}

/// Mean squared error over every channel of the kept pixels, accumulated in `f64`.
pub fn mse(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> f64 {
    check_pair(reference, test, mask);
    let mut sum = 0.0f64;
    let mut count = 0usize;
    for (i, (r, t)) in reference.data.iter().zip(&test.data).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        for c in 0..3 {
            let d = f64::from(r[c]) - f64::from(t[c]);
            sum += d * d;
        }
        count += 3;
    }
    if count == 0 {
        return f64::NAN;
    }
    sum / count as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Uniform noise on [-a, a] has variance a²/3, so a flat grey image plus that noise has an expected
    /// PSNR of -10 log10(a²/3): 40 dB for a = sqrt(3)·0.01.
    #[test]
    fn psnr_of_known_uniform_noise() {
        let (w, h) = (256u32, 256u32);
        let a = 3.0f32.sqrt() * 0.01;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let reference = RgbImage::from_data(w, h, vec![[0.5; 3]; (w * h) as usize]).unwrap();
        let noisy = reference.data.iter().map(|p| p.map(|v| v + rng.random_range(-a..a))).collect();
        let test = RgbImage::from_data(w, h, noisy).unwrap();
        let value = psnr(&reference, &test, None);
        // 196608 samples: the MSE's relative standard error is sqrt(0.8/N) ≈ 0.2 %, i.e. < 0.01 dB.
        assert!((value - 40.0).abs() < 0.05, "PSNR {value}");
    }

    #[test]
    fn mask_excludes_background_instead_of_counting_it_as_perfect() {
        // Object pixel differs by 0.1 (MSE 0.01 → 20 dB); the background differs wildly but is masked.
        let reference = RgbImage::from_data(2, 1, vec![[0.5; 3], [0.0; 3]]).unwrap();
        let test = RgbImage::from_data(2, 1, vec![[0.6; 3], [1.0; 3]]).unwrap();
        let mask = [true, false];
        assert!((psnr(&reference, &test, Some(&mask)) - 20.0).abs() < 1e-4);
        assert_eq!(psnr(&reference, &reference, None), f64::INFINITY);
        assert!(psnr(&reference, &test, Some(&[false, false])).is_nan());
    }
}
