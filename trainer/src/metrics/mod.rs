//! Metrics of the comparison study (paper Sec. 6, Tabs. 1-4), as plain functions over images, BRDF
//! values and closures, so that the study command can call them on any model.
//!
//! | metric | on | module | masked how |
//! |---|---|---|---|
//! | PSNR | sRGB renderings | [`psnr`] | MSE over object pixels only |
//! | DSSIM = (1 - SSIM)/2 | sRGB renderings | [`ssim`] | backgrounds made equal; map averaged over object-centred windows |
//! | LPIPS (AlexNet v0.1) | sRGB renderings | [`lpips`] | backgrounds made equal; whole frame (LPIPS's own spatial mean) |
//! | HDR-FLIP | linear renderings | [`flip`] | backgrounds made equal; exposures from object pixels; map averaged over object pixels |
//! | RMSE of cube roots | BRDF values | [`brdf_rmse`] | directions > 80° from the normal and saturated pixels dropped |
//! | reciprocity RMSE | BRDF values | [`reciprocity`] | - |
//! | energy (Eq. 4) | BRDF values | [`energy`] | - |
//!
//! The paper does not say how it masks; these choices keep the black background, which every model
//! renders perfectly, from inflating the image scores, while windowed metrics still see the silhouette.
//! "Backgrounds made equal" means the test image's background pixels are replaced by the reference's
//! ([`equalize_background`]); renderings of the same object share the silhouette, so nothing is lost.

pub mod brdf_rmse;
pub mod energy;
pub mod flip;
pub mod lpips;
pub mod psnr;
pub mod reciprocity;
pub mod ssim;

use std::fmt;

use nbrdf_scene::image::{srgb_encode, RgbImage};
use serde::{Deserialize, Serialize};

pub use self::lpips::Lpips;

/// An optional per-pixel object mask, row-major like the image: `true` = object.
pub type Mask<'a> = Option<&'a [bool]>;

/// Panics unless the two images (and the mask) have the same size: comparing renderings of different
/// sizes is a bug in the caller, not a data condition.
pub(crate) fn check_pair(a: &RgbImage, b: &RgbImage, mask: Mask<'_>) {
    assert!(
        a.width == b.width && a.height == b.height && a.data.len() == b.data.len(),
        "image sizes differ: {}×{} vs {}×{}",
        a.width,
        a.height,
        b.width,
        b.height
    );
    if let Some(m) = mask {
        assert_eq!(m.len(), a.data.len(), "mask size differs from the image's");
    }
}

/// Linear RGB to sRGB-encoded values in [0, 1] (IEC 61966-2-1 via `nbrdf_scene::image::srgb_encode`, which
/// clamps), the space the paper evaluates PSNR, DSSIM and LPIPS in.
pub fn to_srgb(linear: &RgbImage) -> RgbImage {
    RgbImage {
        width: linear.width,
        height: linear.height,
        data: linear.data.iter().map(|p| p.map(srgb_encode)).collect(),
    }
}

/// A copy of `test` whose pixels outside the mask are the reference's, so that both images agree off
/// the object (the identity without a mask).
pub fn equalize_background(reference: &RgbImage, test: &RgbImage, mask: Mask<'_>) -> RgbImage {
    check_pair(reference, test, mask);
    let Some(m) = mask else { return test.clone() };
    let data = test.data.iter().zip(&reference.data).zip(m).map(|((t, r), &keep)| if keep { *t } else { *r }).collect();
    RgbImage { width: test.width, height: test.height, data }
}

/// A number, or why it could not be computed (e.g. LPIPS without its weights). Serialises as the bare
/// number or as `{"na": "reason"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MaybeMetric {
    /// The value.
    Value(f64),
    /// Not available, with the reason (starting with "n/a").
    NotAvailable {
        /// Why, e.g. "n/a: weights not found at PATH".
        na: String,
    },
}

impl MaybeMetric {
    /// The value, if any.
    pub fn value(&self) -> Option<f64> {
        match self {
            MaybeMetric::Value(v) => Some(*v),
            MaybeMetric::NotAvailable { .. } => None,
        }
    }

    /// Mean of several (e.g. over views); not available if any is not, with the first reason.
    pub fn mean<'a>(items: impl IntoIterator<Item = &'a MaybeMetric>) -> MaybeMetric {
        let (mut sum, mut n) = (0.0, 0usize);
        for m in items {
            match m {
                MaybeMetric::Value(v) => {
                    sum += v;
                    n += 1;
                }
                na @ MaybeMetric::NotAvailable { .. } => return na.clone(),
            }
        }
        MaybeMetric::Value(if n == 0 { f64::NAN } else { sum / n as f64 })
    }
}

/// Table cell text: the value with 4 significant decimals, or "n/a".
impl fmt::Display for MaybeMetric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MaybeMetric::Value(v) => write!(f, "{v:.4}"),
            MaybeMetric::NotAvailable { .. } => f.write_str("n/a"),
        }
    }
}

/// The image metrics of one test view (or their mean over views), unscaled (the paper's tables scale
/// DSSIM, LPIPS and FLIP by 100).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageMetrics {
    /// PSNR in dB on sRGB; `inf` (JSON `null`) for a perfect match.
    pub psnr: f64,
    /// DSSIM on sRGB.
    pub dssim: f64,
    /// LPIPS on sRGB, or why not.
    pub lpips: MaybeMetric,
    /// Mean HDR-FLIP on linear.
    pub flip: f64,
    /// Number of views averaged.
    pub views: usize,
}

impl ImageMetrics {
    /// All image metrics of a test rendering against the reference, both **linear** RGB, masked as the
    /// module table says. `lpips` is the result of [`Lpips::load_or_na`]: loaded once per study, and its
    /// "n/a" reason is carried into the result instead of failing. To compare several models against
    /// one reference view, use [`PreparedReference`], which runs the reference through LPIPS once.
    pub fn evaluate(
        reference: &RgbImage,
        test: &RgbImage,
        mask: Mask<'_>,
        lpips: &Result<Lpips, String>,
    ) -> ImageMetrics {
        PreparedReference::new(reference, mask, lpips).evaluate(test)
    }

    /// The mean over views (the paper averages each metric over the test views of an object, then over
    /// objects). PSNR is averaged in dB, as the paper's tables do.
    /// No views give NaN everywhere.
    pub fn mean(items: &[ImageMetrics]) -> ImageMetrics {
        let n = if items.is_empty() { f64::NAN } else { items.len() as f64 };
        ImageMetrics {
            psnr: items.iter().map(|m| m.psnr).sum::<f64>() / n,
            dssim: items.iter().map(|m| m.dssim).sum::<f64>() / n,
            lpips: MaybeMetric::mean(items.iter().map(|m| &m.lpips)),
            flip: items.iter().map(|m| m.flip).sum::<f64>() / n,
            views: items.iter().map(|m| m.views).sum(),
        }
    }
}

/// One reference view, its mask and its LPIPS features, ready to score any number of test renderings.
pub struct PreparedReference<'a> {
    linear: &'a RgbImage,
    srgb: RgbImage,
    mask: Mask<'a>,
    lpips: Result<(&'a Lpips, self::lpips::LpipsFeatures), String>,
}

impl<'a> PreparedReference<'a> {
    /// Converts the **linear** reference to sRGB and computes its LPIPS features (or keeps the "n/a"
    /// reason: missing weights, or an image too small for AlexNet).
    pub fn new(reference: &'a RgbImage, mask: Mask<'a>, lpips: &'a Result<Lpips, String>) -> Self {
        if let Some(m) = mask {
            assert_eq!(m.len(), reference.data.len(), "mask size differs from the image's");
        }
        let srgb = to_srgb(reference);
        let lpips = match lpips {
            Ok(net) => net.prepare(&srgb).map(|f| (net, f)).map_err(|e| format!("n/a: {e}")),
            Err(reason) => Err(reason.clone()),
        };
        Self { linear: reference, srgb, mask, lpips }
    }

    /// [`ImageMetrics`] of one **linear** test rendering against this reference.
    pub fn evaluate(&self, test: &RgbImage) -> ImageMetrics {
        let test = equalize_background(self.linear, test, self.mask);
        let test_srgb = to_srgb(&test);
        let lpips = match &self.lpips {
            Ok((net, features)) => match net.distance_to(features, &test_srgb) {
                Ok(v) => MaybeMetric::Value(v),
                Err(e) => MaybeMetric::NotAvailable { na: format!("n/a: {e}") },
            },
            Err(reason) => MaybeMetric::NotAvailable { na: reason.clone() },
        };
        ImageMetrics {
            psnr: psnr::psnr(&self.srgb, &test_srgb, self.mask),
            dssim: ssim::dssim(&self.srgb, &test_srgb, self.mask),
            lpips,
            flip: flip::hdr_flip(self.linear, &test, self.mask).mean,
            views: 1,
        }
    }
}

/// Every number the study reports for one evaluated model (on one object or averaged over objects).
/// A metric that does not apply is `None`: BRDF RMSE needs ground-truth BRDF values (semi-synthetic data
/// only), reciprocity is 0 by construction for parametric models and the reciprocal mapping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetricSet {
    /// Model variant name as the study labels it.
    pub model: String,
    /// Image metrics over the test views (Tab. 1).
    pub image: Option<ImageMetrics>,
    /// RMSE of cube roots of the BRDF values (Tab. 1 "RMSE ∛").
    pub brdf_rmse_cbrt: Option<brdf_rmse::CubeRootRmse>,
    /// RMSE of the reciprocity violation (Tab. 3).
    pub reciprocity_rmse: Option<f64>,
    /// Energy-conservation analysis (Tab. 4).
    pub energy: Option<energy::EnergySummary>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evaluate_identical_renderings() {
        let data: Vec<[f32; 3]> = (0..48 * 40).map(|i| [(i % 17) as f32 / 8.0, 0.3, (i % 5) as f32 * 0.1]).collect();
        let img = RgbImage::from_data(48, 40, data).unwrap();
        let no_lpips = Err("n/a: weights not found at X".to_string());
        let m = ImageMetrics::evaluate(&img, &img, None, &no_lpips);
        assert_eq!(m.psnr, f64::INFINITY);
        assert!(m.dssim.abs() < 1e-12 && m.flip == 0.0);
        assert_eq!(m.lpips, MaybeMetric::NotAvailable { na: "n/a: weights not found at X".into() });
        assert_eq!(m.lpips.to_string(), "n/a");
    }

    /// The full pipeline with the real LPIPS weights: masked, identical objects score perfectly whatever
    /// the backgrounds, and a brighter object scores worse on every metric.
    #[test]
    fn evaluate_masked_pair_with_lpips() {
        let lpips = Lpips::load_or_na(None);
        if let Err(reason) = &lpips {
            eprintln!("skipping: {reason}");
            return;
        }
        let (w, h) = (48u32, 40u32);
        let mask: Vec<bool> = (0..w * h).map(|i| (10..38).contains(&(i % w)) && (8..32).contains(&(i / w))).collect();
        let object = |k: f32, bg: f32| {
            let data = (0..w * h)
                .map(|i| if mask[i as usize] { [k * (0.2 + (i % 7) as f32 * 0.1), k * 0.4, k * 0.1] } else { [bg; 3] })
                .collect();
            RgbImage::from_data(w, h, data).unwrap()
        };
        let reference = object(1.0, 0.0);
        let prepared = PreparedReference::new(&reference, Some(&mask), &lpips);
        let same = prepared.evaluate(&object(1.0, 0.7));
        assert_eq!(same.psnr, f64::INFINITY);
        assert_eq!((same.dssim, same.flip), (0.0, 0.0));
        assert_eq!(same.lpips, MaybeMetric::Value(0.0));
        let brighter = prepared.evaluate(&object(1.3, 0.0));
        assert!(brighter.psnr.is_finite() && brighter.dssim > 0.0 && brighter.flip > 0.0, "{brighter:?}");
        assert!(brighter.lpips.value().unwrap() > 0.0);
        assert_eq!(brighter, ImageMetrics::evaluate(&reference, &object(1.3, 0.0), Some(&mask), &lpips));
    }

    #[test]
    fn background_is_made_equal_before_comparing() {
        let reference = RgbImage::from_data(2, 1, vec![[0.5; 3], [0.0; 3]]).unwrap();
        let test = RgbImage::from_data(2, 1, vec![[0.6; 3], [9.0; 3]]).unwrap();
        let eq = equalize_background(&reference, &test, Some(&[true, false]));
        assert_eq!(eq.data, vec![[0.6; 3], [0.0; 3]]);
        // Linear values above 1 clip to white, as on a display.
        let srgb = to_srgb(&RgbImage::from_data(1, 1, vec![[2.0, 0.0, 1.0]]).unwrap()).data[0];
        assert!((srgb[0] - 1.0).abs() < 1e-6 && srgb[1] == 0.0 && (srgb[2] - 1.0).abs() < 1e-6, "{srgb:?}");
    }

    #[test]
    fn metric_set_serialises_with_na_reason() {
        let set = MetricSet {
            model: "single-mlp".into(),
            image: Some(ImageMetrics {
                psnr: 30.0,
                dssim: 0.01,
                lpips: MaybeMetric::NotAvailable { na: "n/a: weights not found at P".into() },
                flip: 0.05,
                views: 2,
            }),
            brdf_rmse_cbrt: None,
            reciprocity_rmse: Some(0.25),
            energy: None,
        };
        let json = serde_json::to_string(&set).unwrap();
        assert!(json.contains(r#""lpips":{"na":"n/a: weights not found at P"}"#), "{json}");
        assert_eq!(serde_json::from_str::<MetricSet>(&json).unwrap(), set);
        let v = MaybeMetric::mean([&MaybeMetric::Value(1.0), &MaybeMetric::Value(2.0)]);
        assert_eq!(v, MaybeMetric::Value(1.5));
        assert_eq!(serde_json::to_string(&v).unwrap(), "1.5");
        let views =
            [set.image.clone().unwrap(), ImageMetrics { psnr: 40.0, dssim: 0.03, ..set.image.clone().unwrap() }];
        let mean = ImageMetrics::mean(&views);
        assert_eq!((mean.psnr, mean.views), (35.0, 4));
        assert!((mean.dssim - 0.02).abs() < 1e-12 && mean.lpips.value().is_none());
        assert!(ImageMetrics::mean(&[]).psnr.is_nan());
    }
}
