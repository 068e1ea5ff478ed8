//! Structural similarity SSIM and the paper's DSSIM = (1 - SSIM) / 2 (Sec. 6, Tab. 1), on the
//! sRGB-encoded renderings.
//!
//! The parameters are those of Wang et al. 2004 ("Image quality assessment: from error visibility to
//! structural similarity", Sec. III-C): an 11×11 circular-symmetric Gaussian window with σ = 1.5 normalised
//! to unit sum, K1 = 0.01, K2 = 0.03, dynamic range L = 1. SSIM is computed per channel and the three
//! means are averaged. The map is evaluated only where the whole window lies inside the image ("valid"
//! filtering, as the authors' MATLAB `ssim_index.m` and scikit-image's crop of the border), so no padding
//! rule enters the value.

use nbrdf_scene::image::RgbImage;

use super::{check_pair, Mask};

/// Window side length (Wang et al. 2004, Sec. III-C).
pub const WINDOW: usize = 11;
/// Standard deviation of the Gaussian window in pixels (Wang et al. 2004, Sec. III-C).
pub const SIGMA: f64 = 1.5;
/// Stabiliser constant of the luminance term (Wang et al. 2004, Eq. 7).
pub const K1: f64 = 0.01;
/// Stabiliser constant of the contrast term (Wang et al. 2004, Eq. 9).
pub const K2: f64 = 0.03;

/// Mean SSIM over the channels: each channel's SSIM map (Wang et al. 2004, Eq. 13, local statistics by
/// Eqs. 14-16 under the Gaussian window) averaged over the window centres the mask keeps.
///
/// With a mask, only windows *centred* on object pixels count; windows straddling the silhouette still
/// see background pixels, so the caller should make the backgrounds equal first
/// ([`super::equalize_background`]) so that only the object's differences enter. Returns NaN when the
/// image is smaller than the window or the mask keeps no window centre.
///
/// ```
/// use nbrdf_scene::image::RgbImage;
/// use trainer::metrics::ssim::{dssim, ssim};
/// let img = RgbImage::from_data(16, 16, (0..256).map(|i| [(i % 7) as f32 / 7.0; 3]).collect()).unwrap();
/// assert!((ssim(&img, &img, None) - 1.0).abs() < 1e-12);
/// assert!(dssim(&img, &img, None).abs() < 1e-12);
/// ```
pub fn ssim(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> f64 {
    check_pair(reference, test, mask);
    let (w, h) = (reference.width as usize, reference.height as usize);
    if w < WINDOW || h < WINDOW {
        return f64::NAN;
    }
    let kernel = gaussian_kernel();
    let mut total = 0.0;
    for c in 0..3 {
        let x: Vec<f64> = reference.data.iter().map(|p| f64::from(p[c])).collect();
        let y: Vec<f64> = test.data.iter().map(|p| f64::from(p[c])).collect();
        total += mean_ssim_channel(&x, &y, w, h, &kernel, mask);
    }
    total / 3.0
}

/// DSSIM = (1 - SSIM) / 2, the paper's dissimilarity (Sec. 6, "Evaluation Metrics"): 0 for identical
/// images, at most 1.
pub fn dssim(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> f64 {
    (1.0 - ssim(reference, test, mask)) / 2.0
}

/// The normalised 1-D Gaussian; the 2-D window is its outer product, so filtering is separable.
fn gaussian_kernel() -> [f64; WINDOW] {
    let r = (WINDOW / 2) as f64;
    let mut k = [0.0; WINDOW];
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - r;
        *v = (-d * d / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = k.iter().sum();
    k.map(|v| v / sum)
}

/// "Valid" separable filtering: output `(w - 10) × (h - 10)`, element `(i, j)` centred on pixel
/// `(i + 5, j + 5)`.
fn filter_valid(img: &[f64], w: usize, h: usize, k: &[f64; WINDOW]) -> Vec<f64> {
    let (ow, oh) = (w - WINDOW + 1, h - WINDOW + 1);
    let mut rows = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            rows[y * ow + x] = (0..WINDOW).map(|t| k[t] * img[y * w + x + t]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..WINDOW).map(|t| k[t] * rows[(y + t) * ow + x]).sum();
        }
    }
    out
}

fn mean_ssim_channel(x: &[f64], y: &[f64], w: usize, h: usize, k: &[f64; WINDOW], mask: Mask<'_>) -> f64 {
    // Wang et al. 2004, Eqs. 7 and 9 with L = 1.
    let c1 = K1 * K1;
    let c2 = K2 * K2;
    let prod = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).collect::<Vec<_>>();
    let mu_x = filter_valid(x, w, h, k);
    let mu_y = filter_valid(y, w, h, k);
    let xx = filter_valid(&prod(x, x), w, h, k);
    let yy = filter_valid(&prod(y, y), w, h, k);
    let xy = filter_valid(&prod(x, y), w, h, k);
    let (ow, oh) = (w - WINDOW + 1, h - WINDOW + 1);
    let r = WINDOW / 2;
    let mut sum = 0.0;
    let mut count = 0usize;
    for j in 0..oh {
        for i in 0..ow {
            if mask.is_some_and(|m| !m[(j + r) * w + i + r]) {
                continue;
            }
            let o = j * ow + i;
            let (mx, my) = (mu_x[o], mu_y[o]);
            // Eqs. 14-16: weighted variances and covariance as E[x²] - μ² (population form, as the
            // authors' code; scikit-image's use_sample_covariance=False).
            let sx = xx[o] - mx * mx;
            let sy = yy[o] - my * my;
            let sxy = xy[o] - mx * my;
            sum += ((2.0 * mx * my + c1) * (2.0 * sxy + c2)) / ((mx * mx + my * my + c1) * (sx + sy + c2));
            count += 1;
        }
    }
    if count == 0 {
        return f64::NAN;
    }
    sum / count as f64
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The integer patterns also written out in the Python snippet that produced the reference values.
    pub(crate) fn pair(w: u32, h: u32) -> (RgbImage, RgbImage) {
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for r in 0..h as usize {
            for c in 0..w as usize {
                let a = [0, 1, 2].map(|ch| ((r * 73 + c * 151 + ch * 37) % 256) as f32 / 255.0);
                let b = [0, 1, 2].map(|ch| ((r * r * 7 + c * 13 + ch * 101) % 256) as f32 / 255.0);
                x.push(a);
                y.push([0, 1, 2].map(|ch| 0.7 * a[ch] + 0.3 * b[ch]));
            }
        }
        (RgbImage::from_data(w, h, x).unwrap(), RgbImage::from_data(w, h, y).unwrap())
    }

    #[test]
    fn identical_images_have_ssim_one() {
        let (x, _) = pair(32, 24);
        assert!((ssim(&x, &x, None) - 1.0).abs() < 1e-12);
    }

    /// Flat images a and b: every window has μ = a, b and σ = 0, so Eq. 13 reduces to the luminance
    /// term (2ab + C1) / (a² + b² + C1).
    #[test]
    fn flat_pair_reduces_to_luminance_term() {
        let (a, b) = (0.25f32, 0.5f32);
        let x = RgbImage::from_data(12, 12, vec![[a; 3]; 144]).unwrap();
        let y = RgbImage::from_data(12, 12, vec![[b; 3]; 144]).unwrap();
        let (a, b) = (f64::from(a), f64::from(b));
        let c1 = K1 * K1;
        let expected = (2.0 * a * b + c1) / (a * a + b * b + c1);
        assert!((ssim(&x, &y, None) - expected).abs() < 1e-9);
    }

    /// Reference values from scikit-image 0.26 `structural_similarity(x, y, gaussian_weights=True,
    /// sigma=1.5, use_sample_covariance=False, data_range=1)` per channel, averaged (the masked one
    /// averages the full map over the kept window centres: columns < 16, borders of 5 cropped).
    #[test]
    fn matches_scikit_image_on_a_known_pair() {
        let (x, y) = pair(32, 24);
        let value = ssim(&x, &y, None);
        assert!((value - 0.887_516_368_576_704_1).abs() < 1e-6, "SSIM {value}");
        let mask: Vec<bool> = (0..32 * 24).map(|i| i % 32 < 16).collect();
        let masked = ssim(&x, &y, Some(&mask));
        assert!((masked - 0.890_483_420_294_701_5).abs() < 1e-6, "masked SSIM {masked}");
        assert!((dssim(&x, &y, None) - (1.0 - 0.887_516_368_576_704_1) / 2.0).abs() < 1e-6);
    }

    #[test]
    fn too_small_or_fully_masked_is_nan() {
        let (x, y) = pair(10, 24);
        assert!(ssim(&x, &y, None).is_nan());
        let (x, y) = pair(12, 12);
        assert!(ssim(&x, &y, Some(&[false; 144])).is_nan());
    }
}
