//! BRDF-space error for the semi-synthetic data (paper Sec. 6, Tab. 1 "RMSE ∛"): the RMSE between the
//! cube roots of predicted and ground-truth BRDF values, which Lavoué et al. 2021 ("Perceptual quality
//! of BRDF approximations: dataset and metrics") found to correlate well with perceived differences.
//! As they (and the paper) do, directions within 10° of the horizon are discarded, where measured and
//! fitted values are least reliable and dominated by grazing Fresnel peaks, and so are samples from
//! saturated pixels, whose ground truth was clipped.

use nbrdf::Rgb;

/// Largest angle from the normal, of either direction, that a sample may have (Lavoué et al. 2021;
/// paper Sec. 6: "we discard values close to the horizon").
pub const MAX_ANGLE_DEG: f32 = 80.0;

/// Whether a sample enters the RMSE: both `cos θ_i` and `cos θ_o` at least `cos 80°`, and the pixel it
/// came from not saturated.
///
/// ```
/// use trainer::metrics::brdf_rmse::keep;
/// assert!(keep(1.0, 0.5, false));
/// assert!(!keep(1.0, 0.1, false)); // θ_o ≈ 84°
/// assert!(!keep(1.0, 1.0, true));
/// ```
#[inline]
pub fn keep(cos_wi: f32, cos_wo: f32, saturated: bool) -> bool {
    let min_cos = MAX_ANGLE_DEG.to_radians().cos();
    !saturated && cos_wi >= min_cos && cos_wo >= min_cos
}

/// The cube-root RMSE and how many samples entered it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CubeRootRmse {
    /// `sqrt(mean over kept samples and channels of (∛pred - ∛ref)²)`; NaN when nothing is kept.
    pub value: f64,
    /// Number of kept samples (each contributes three channels).
    pub samples: usize,
}

/// RMSE of cube roots (Lavoué et al. 2021; paper Sec. 6) over the samples with `keep[i]` (see [`keep`]),
/// all three channels weighted equally. The cube root is the real, sign-preserving one, so a model that
/// predicts a negative value is penalised rather than producing NaN.
///
/// ```
/// use trainer::metrics::brdf_rmse::cube_root_rmse;
/// // ∛8 - ∛1 = 1 in every channel of one sample, and the other sample is exact: RMSE = sqrt(1/2).
/// let r = cube_root_rmse(&[[8.0; 3], [1.0; 3]], &[[1.0; 3], [1.0; 3]], &[true, true]);
/// assert!((r.value - 0.5f64.sqrt()).abs() < 1e-12);
/// ```
///
/// # Panics
/// If the three slices differ in length.
pub fn cube_root_rmse(predicted: &[Rgb], reference: &[Rgb], keep: &[bool]) -> CubeRootRmse {
    assert_eq!(predicted.len(), reference.len(), "predicted and reference BRDF values differ in count");
    assert_eq!(predicted.len(), keep.len(), "validity mask and BRDF values differ in count");
    let (mut sum, mut samples) = (0.0f64, 0usize);
    for ((p, r), _) in predicted.iter().zip(reference).zip(keep).filter(|(_, &k)| k) {
        for c in 0..3 {
            let d = f64::from(p[c]).cbrt() - f64::from(r[c]).cbrt();
            sum += d * d;
        }
        samples += 1;
    }
    let value = if samples == 0 { f64::NAN } else { (sum / (3 * samples) as f64).sqrt() };
    CubeRootRmse { value, samples }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_difference_and_exclusions() {
        // Kept: (27 vs 8) → ∛ diff 1 in R only; (0.001 vs 0.001) → 0. RMSE = sqrt(1 / 6).
        // Excluded: the grazing and the saturated samples, each with a huge error.
        let pred = [[27.0, 1.0, 1.0], [0.001; 3], [1000.0; 3], [1000.0; 3]];
        let gt = [[8.0, 1.0, 1.0], [0.001; 3], [0.0; 3], [0.0; 3]];
        let cos = [(1.0, 1.0), (0.9, 0.3), (0.05, 1.0), (1.0, 1.0)];
        let sat = [false, false, false, true];
        let k: Vec<bool> = cos.iter().zip(sat).map(|(&(i, o), s)| keep(i, o, s)).collect();
        assert_eq!(k, [true, true, false, false]);
        let r = cube_root_rmse(&pred, &gt, &k);
        assert_eq!(r.samples, 2);
        assert!((r.value - (1.0f64 / 6.0).sqrt()).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn angle_threshold_is_80_degrees() {
        let c = 80f32.to_radians().cos();
        assert!(keep(c + 1e-4, 1.0, false));
        assert!(!keep(1.0, c - 1e-4, false));
    }

    #[test]
    fn negative_predictions_are_penalised_not_nan() {
        let r = cube_root_rmse(&[[-1.0; 3]], &[[1.0; 3]], &[true]);
        assert!((r.value - 2.0).abs() < 1e-12);
        assert!(cube_root_rmse(&[[1.0; 3]], &[[1.0; 3]], &[false]).value.is_nan());
    }
}
