//! HDR-FLIP (Andersson et al. 2021, "Visualizing Errors in Rendered High Dynamic Range Images") on the
//! *linear* renderings (paper Sec. 6, Tab. 1), through `flip-rs`, a port of NVIDIA's reference FLIP v1.7
//! that implements the HDR mode itself (tone mapping with ACES over a range of exposures, the per-pixel
//! maximum of LDR-FLIP over them).
//!
//! What this module adds is the exposure range. The reference tool derives it from the reference image:
//! start `log2(x_max / Y_max)`, stop `log2(x_max / Y_median)` (Andersson et al. 2021, Sec. 3.2), where
//! `x_max` is the tone-mapper input that maps to 0.85. On a rendering of an object against a black
//! background the median luminance is 0, the stop exposure becomes `+∞` (flip-rs clamps the median to
//! `f32::EPSILON`, i.e. about 23 extra stops), and the mean error is dominated by exposures so bright that
//! the object is white. So the luminance statistics here are taken over the *object* pixels (the mask)
//! with positive luminance only; see [`exposure_range`].

use flip_rs::{HdrOptions, Tonemapper, DEFAULT_PPD};
use nbrdf_scene::image::RgbImage;

use super::{check_pair, equalize_background, Mask};

/// Output of the ACES tone curve at the brightest exposure's maximum (Andersson et al. 2021, Sec. 3.2).
const TONEMAP_TARGET: f64 = 0.85;

/// ACES filmic fit coefficients as FLIP uses them (`FLIP::ToneMappingCoefficients`): the curve is
/// `(a x² + b x + c) / (d x² + e x + f)`, with the reference tool's pre-scale of 0.6 folded in.
const ACES: [f64; 6] = [0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14];

/// Largest exposure count `flip-rs` accepts.
const MAX_EXPOSURES: usize = flip_rs::MAX_EXPOSURES;

/// The exposure sweep of one evaluation, in stops (exposure `e` scales linear RGB by `2^e`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureRange {
    /// First exposure: maps the brightest reference pixel to `x_max`.
    pub start: f32,
    /// Last exposure: maps the median reference pixel to `x_max`.
    pub stop: f32,
    /// Number of equally spaced exposures, `max(2, ceil(stop - start))`.
    pub count: usize,
}

/// An HDR-FLIP evaluation: the per-pixel error map and its mean over the kept pixels.
#[derive(Clone, Debug)]
pub struct FlipResult {
    /// Mean of the error map over the kept pixels, in [0, 1]; NaN for an empty mask.
    pub mean: f64,
    /// Per-pixel error in [0, 1], row-major (0 wherever the backgrounds were made equal and no object
    /// error bleeds in).
    pub map: Vec<f32>,
    /// The exposures evaluated; `None` when both images are black and nothing was evaluated.
    pub exposures: Option<ExposureRange>,
}

/// Rec. 709 luminance of linear RGB, as FLIP's `color3::linearRGBToLuminance`.
#[inline]
pub fn luminance(p: [f32; 3]) -> f32 {
    0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
}

/// The ACES input `x_max` whose tone-mapped value is 0.85: the positive root of
/// `(a - 0.85 d) x² + (b - 0.85 e) x + (c - 0.85 f) = 0` (Andersson et al. 2021, Sec. 3.2;
/// `FLIP::solveSecondDegree`).
fn aces_x_max() -> f64 {
    let [a, b, c, d, e, f] = ACES;
    let (qa, qb, qc) = (a - TONEMAP_TARGET * d, b - TONEMAP_TARGET * e, c - TONEMAP_TARGET * f);
    let d1 = -0.5 * qb / qa;
    d1 + (d1 * d1 - qc / qa).sqrt()
}

/// The HDR-FLIP exposure range (Andersson et al. 2021, Sec. 3.2) from the luminances of the reference
/// pixels the mask keeps, ignoring zero (and negative) luminances so that background and fully shadowed
/// pixels cannot drive the median to 0. Falls back to the test image where the reference has no lit
/// pixel; `None` when neither has one (both black: nothing to compare).
pub fn exposure_range(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> Option<ExposureRange> {
    let lit = |img: &RgbImage| -> Vec<f32> {
        img.data
            .iter()
            .enumerate()
            .filter(|(i, _)| mask.is_none_or(|m| m[*i]))
            .map(|(_, p)| luminance(*p))
            .filter(|y| *y > 0.0 && y.is_finite())
            .collect()
    };
    let mut y = lit(reference);
    if y.is_empty() {
        y = lit(test);
    }
    if y.is_empty() {
        return None;
    }
    let y_max = y.iter().copied().fold(0.0f32, f32::max);
    // The reference tool's median: element len/2 in sorted order.
    let mid = y.len() / 2;
    let (_, &mut y_median, _) = y.select_nth_unstable_by(mid, f32::total_cmp);
    let x_max = aces_x_max();
    let start = (x_max / f64::from(y_max)).log2() as f32;
    let stop = (x_max / f64::from(y_median)).log2() as f32;
    let count = ((stop - start).ceil().max(2.0) as usize).min(MAX_EXPOSURES);
    Some(ExposureRange { start, stop, count })
}

/// HDR-FLIP between two linear RGB images at FLIP's default viewing condition (0.7 m from a 0.7 m wide
/// 4K monitor, [`DEFAULT_PPD`] ≈ 67 pixels per degree).
///
/// Masking: the test image's background is replaced by the reference's (so both agree off the object),
/// the exposure range comes from the object pixels ([`exposure_range`]), and the mean is taken over the
/// object pixels only. Error that FLIP's spatial filters spread from the object onto adjacent background
/// pixels is therefore not counted.
///
/// # Panics
/// If the images differ in size or hold non-finite values (a NaN rendering is a bug upstream).
pub fn hdr_flip(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> FlipResult {
    hdr_flip_at(reference, test, mask, DEFAULT_PPD)
}

/// [`hdr_flip`] at a given number of pixels per degree (see `flip_rs::pixels_per_degree`).
pub fn hdr_flip_at(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>, ppd: f32) -> FlipResult {
    check_pair(reference, test, mask);
    let n = reference.data.len();
    let test = equalize_background(reference, test, mask);
    let Some(range) = exposure_range(reference, &test, mask) else {
        return FlipResult { mean: mean_over(&vec![0.0; n], mask), map: vec![0.0; n], exposures: None };
    };
    let (w, h) = (reference.width as usize, reference.height as usize);
    let to_flip = |img: &RgbImage| {
        flip_rs::RgbImage::new(w, h, img.data.iter().flatten().copied().collect()).expect("image size checked above")
    };
    let mut options = HdrOptions::default();
    options.ppd = ppd;
    options.start_exposure = Some(range.start);
    options.stop_exposure = Some(range.stop);
    options.num_exposures = Some(range.count);
    options.tonemapper = Tonemapper::Aces;
    options.return_exposure_map = false;
    let result = flip_rs::hdr_flip(&to_flip(reference), &to_flip(&test), options)
        .unwrap_or_else(|e| panic!("HDR-FLIP failed: {e}"));
    let map = result.error_map.into_pixels();
    FlipResult { mean: mean_over(&map, mask), map, exposures: Some(range) }
}

/// The error map in FLIP's magma colour map, as sRGB-encoded values in [0, 1] (for the report's PNGs,
/// which must then be written without a second sRGB encoding).
pub fn colorize(map: &[f32], width: u32, height: u32) -> Vec<[f32; 3]> {
    flip_rs::ErrorMap::new(width as usize, height as usize, map.to_vec())
        .and_then(|m| m.colorize())
        .map(|img| img.pixels().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        .expect("map length matches the size")
}

fn mean_over(map: &[f32], mask: Mask<'_>) -> f64 {
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (i, &v) in map.iter().enumerate() {
        if mask.is_none_or(|m| m[i]) {
            sum += f64::from(v);
            count += 1;
        }
    }
    if count == 0 {
        f64::NAN
    } else {
        sum / count as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lit sphere-like gradient disc on a black background, radius r, plus its mask.
    fn disc(w: u32, h: u32, scale: f32) -> (RgbImage, Vec<bool>) {
        let (cx, cy, r) = (w as f32 / 2.0, h as f32 / 2.0, w.min(h) as f32 * 0.3);
        let mut data = Vec::new();
        let mut mask = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt() / r;
                let inside = d < 1.0;
                mask.push(inside);
                let v = if inside { scale * (1.0 - d * d) * (1.0 + 4.0 * (x as f32 / w as f32)) } else { 0.0 };
                data.push([v, 0.8 * v, 0.6 * v]);
            }
        }
        (RgbImage::from_data(w, h, data).unwrap(), mask)
    }

    #[test]
    fn identical_images_have_zero_flip() {
        let (img, mask) = disc(48, 40, 2.0);
        let r = hdr_flip(&img, &img, Some(&mask));
        assert_eq!(r.mean, 0.0);
        assert!(r.map.iter().all(|&v| v == 0.0));
        let r = hdr_flip(&img, &img, None);
        assert_eq!(r.mean, 0.0);
    }

    /// With a positive median, the range is exactly the reference tool's automatic one (flip-rs computes
    /// that itself when no endpoints are given), which checks the x_max root and the median.
    #[test]
    fn exposure_range_matches_reference_tool_without_background() {
        let data = (0..64 * 48).map(|i| [0.01 + (i % 97) as f32 * 0.05, 0.2, 0.05 * (i % 13) as f32]).collect();
        let img = RgbImage::from_data(64, 48, data).unwrap();
        let ours = exposure_range(&img, &img, None).unwrap();
        let to_flip =
            |img: &RgbImage| flip_rs::RgbImage::new(64, 48, img.data.iter().flatten().copied().collect()).unwrap();
        let auto = flip_rs::hdr_flip(&to_flip(&img), &to_flip(&img), HdrOptions::default()).unwrap().parameters;
        assert!((ours.start - auto.start_exposure).abs() < 1e-4, "{ours:?} vs {auto:?}");
        assert!((ours.stop - auto.stop_exposure).abs() < 1e-4, "{ours:?} vs {auto:?}");
        assert_eq!(ours.count, auto.num_exposures);
    }

    /// Mostly black background: the whole-image median is 0, but the object's exposures stay a few
    /// stops wide instead of the ~23 extra stops flip-rs would add from its epsilon.
    #[test]
    fn black_background_does_not_blow_up_the_exposure_range() {
        let (img, mask) = disc(64, 64, 1.0);
        assert!(mask.iter().filter(|m| !**m).count() > 64 * 64 / 2, "background is the majority");
        let r = exposure_range(&img, &img, Some(&mask)).unwrap();
        assert!(r.stop - r.start < 8.0, "{r:?}");
        assert!(r.start.is_finite() && r.stop.is_finite() && r.count >= 2);
        // All-black pair: nothing to compare, error 0, no exposure sweep.
        let black = RgbImage::new(16, 16);
        let res = hdr_flip(&black, &black, None);
        assert_eq!((res.mean, res.exposures), (0.0, None));
    }

    /// A larger (relative) error must give a larger FLIP, and the metric stays within [0, 1].
    #[test]
    fn flip_grows_with_the_error() {
        let (reference, mask) = disc(64, 64, 2.0);
        let scaled =
            |k: f32| RgbImage { data: reference.data.iter().map(|p| p.map(|v| v * k)).collect(), ..reference.clone() };
        let small = hdr_flip(&reference, &scaled(1.05), Some(&mask)).mean;
        let large = hdr_flip(&reference, &scaled(1.5), Some(&mask)).mean;
        assert!(0.0 < small && small < large && large <= 1.0, "{small} {large}");
        // Something wildly wrong in the background is not counted.
        let mut test = reference.clone();
        for (p, &m) in test.data.iter_mut().zip(&mask) {
            if !m {
                *p = [5.0; 3];
            }
        }
        assert_eq!(hdr_flip(&reference, &test, Some(&mask)).mean, 0.0);
    }
}

/// Agreement with NVIDIA's reference implementation on a pair of HDR images made from a formula.
#[cfg(test)]
mod reference_tests {
    use super::*;

    /// The pair of `benches/flip_reference.py`: exact f32 values (multiples of 1/64), a bright spot,
    /// and a test image equal to the reference on its left half.
    fn pair() -> (RgbImage, RgbImage) {
        const N: u32 = 48;
        let (mut reference, mut test) = (Vec::new(), Vec::new());
        for y in 0..N {
            for x in 0..N {
                let spot = (x as i32 - 20).pow(2) + (y as i32 - 28).pow(2) < 16;
                let r = [0, 1, 2].map(|c| if spot { 8.0 } else { (((x * 7 + y * 3 + c * 5) % 32) + 1) as f32 / 64.0 });
                let t = [0, 1, 2].map(|c| if spot { 6.0 } else { (((x * 5 + y * 11 + c * 3) % 32) + 1) as f32 / 64.0 });
                reference.push(r);
                test.push(if x < N / 2 { r } else { t });
            }
        }
        (RgbImage::from_data(N, N, reference).unwrap(), RgbImage::from_data(N, N, test).unwrap())
    }

    /// `flip_evaluator.evaluate(ref, test, "HDR")` (NVIDIA FLIP 1.7, pip package `flip-evaluator`)
    /// gives 0.14448481798171997 on this pair, with exposures -1.9167 to 3.0567 in 5 steps at 67.02
    /// pixels per degree; flip-rs with the exposure range derived here agrees to 1 %.
    #[test]
    fn hdr_flip_matches_nvidias_reference_tool() {
        const NVIDIA: f64 = 0.144_484_817_981_719_97;
        let (reference, test) = pair();
        let r = hdr_flip(&reference, &test, None);
        let range = r.exposures.unwrap();
        assert!((range.start - -1.916_702_7).abs() < 1e-3 && (range.stop - 3.056_674).abs() < 1e-3, "{range:?}");
        assert_eq!(range.count, 5);
        assert!((r.mean - NVIDIA).abs() < 0.01 * NVIDIA, "flip-rs {} vs NVIDIA {NVIDIA}", r.mean);
    }
}
