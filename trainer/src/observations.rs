//! Training observations: one lit, unshadowed pixel each (Sec. 5.1), in the local shading frame, as
//! plain arrays. The dataset loaders produce them; [`Observations::sanitize`] removes what would poison
//! the fit.

use nbrdf::Vec3;

/// Pixels seen under one directional light each (structure of arrays, one entry per pixel).
#[derive(Clone, Debug, Default)]
pub struct Observations {
    /// Raw position values per pixel (`n_position` each, row-major): intrinsic eigenfunctions or `x`.
    pub position: Vec<f32>,
    pub n_position: usize,
    /// Toward the light `l`, unit, local frame (normal = +z).
    pub wi: Vec<Vec3>,
    /// Toward the viewer `v`.
    pub wo: Vec<Vec3>,
    /// Light intensity `L_i` per pixel, linear RGB.
    pub irradiance: Vec<[f32; 3]>,
    /// Observed radiance `L_GT`, linear RGB (HDR).
    pub radiance: Vec<[f32; 3]>,
}

/// What [`Observations::sanitize`] removed.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Filtered {
    /// Non-finite radiance, irradiance, position or directions.
    pub non_finite: usize,
    /// Radiance or light intensity above the limit (HDR outliers: hot pixels, glints beyond calibration;
    /// `0 · ∞` in the gradient of a clamped highlight would be NaN).
    pub too_bright: usize,
    /// Light or view at or below the horizon, or a degenerate pair.
    pub below_horizon: usize,
    /// Kept.
    pub kept: usize,
}

impl Observations {
    /// Observations from per-pixel arrays as the dataset's `Samples` holds them (directions as
    /// `[x, y, z]` in the local frame) and the position values of each pixel (`n_position` per pixel:
    /// the intrinsic eigenfunctions interpolated at the hit, or the normalised hit point for the
    /// extrinsic encoding, or none).
    pub fn from_arrays(
        position: Vec<f32>,
        n_position: usize,
        wi: &[[f32; 3]],
        wo: &[[f32; 3]],
        irradiance: &[[f32; 3]],
        radiance: &[[f32; 3]],
    ) -> crate::Result<Observations> {
        let obs = Observations {
            position,
            n_position,
            wi: wi.iter().map(|&v| Vec3::from_array(v)).collect(),
            wo: wo.iter().map(|&v| Vec3::from_array(v)).collect(),
            irradiance: irradiance.to_vec(),
            radiance: radiance.to_vec(),
        };
        obs.check()?;
        Ok(obs)
    }

    /// The median over pixels and channels of the observed BRDF value `L_GT / (L_i cos θ_l)`, in 1/sr
    /// (Eq. 9 solved for `f`): how bright the material is away from its highlights, robust to them.
    /// `None` without a lit pixel.
    pub fn median_brdf(&self) -> Option<f32> {
        let mut f = Vec::with_capacity(3 * self.len());
        for ((wi, irradiance), radiance) in self.wi.iter().zip(&self.irradiance).zip(&self.radiance) {
            for (e, l) in irradiance.iter().zip(radiance) {
                let e = e * wi.z;
                if e > 0.0 && l.is_finite() {
                    f.push(l.max(0.0) / e);
                }
            }
        }
        if f.is_empty() {
            return None;
        }
        let mid = f.len() / 2;
        Some(*f.select_nth_unstable_by(mid, f32::total_cmp).1)
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.wi.len()
    }

    /// Whether there are no pixels.
    pub fn is_empty(&self) -> bool {
        self.wi.is_empty()
    }

    /// Checks that the arrays have one entry per pixel.
    pub fn check(&self) -> crate::Result<()> {
        let n = self.len();
        if self.wo.len() != n
            || self.irradiance.len() != n
            || self.radiance.len() != n
            || self.position.len() != n * self.n_position
        {
            return Err(crate::Error::Invalid(format!(
                "observation arrays disagree: {} wi, {} wo, {} irradiance, {} radiance, {} position values \
                 ({} per pixel)",
                n,
                self.wo.len(),
                self.irradiance.len(),
                self.radiance.len(),
                self.position.len(),
                self.n_position
            )));
        }
        Ok(())
    }

    /// Keeps only pixels that can enter the loss: all values finite, radiance at most `max_radiance`
    /// per channel, both directions strictly above the horizon. A non-finite or enormous target would
    /// make the loss or its gradient non-finite and so the weights NaN.
    pub fn sanitize(self, max_radiance: f32) -> crate::Result<(Observations, Filtered)> {
        self.check()?;
        let mut out = Observations { n_position: self.n_position, ..Default::default() };
        let mut f = Filtered::default();
        let finite3 = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
        for s in 0..self.len() {
            let pos = &self.position[s * self.n_position..(s + 1) * self.n_position];
            let (wi, wo) = (self.wi[s], self.wo[s]);
            if !finite3(&self.radiance[s])
                || !finite3(&self.irradiance[s])
                || !pos.iter().all(|x| x.is_finite())
                || !wi.is_finite()
                || !wo.is_finite()
            {
                f.non_finite += 1;
            } else if self.radiance[s].iter().chain(&self.irradiance[s]).any(|&x| x > max_radiance) {
                f.too_bright += 1;
            } else if nbrdf::angles::upper_hemisphere_pair(wi, wo).is_none()
                || nbrdf::angles::rusinkiewicz_angles(wi, wo).is_none()
            {
                f.below_horizon += 1;
            } else {
                out.position.extend_from_slice(pos);
                out.wi.push(wi);
                out.wo.push(wo);
                out.irradiance.push(self.irradiance[s]);
                out.radiance.push(self.radiance[s]);
            }
        }
        f.kept = out.len();
        Ok((out, f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The median BRDF value solves Eq. 9 for `f` per pixel and channel, skips unlit values, and a
    /// few bright highlights do not move it.
    #[test]
    fn median_brdf_is_radiance_over_irradiance() {
        let up = [0.0, 0.0, 1.0];
        let tilted = [0.6, 0.0, 0.8];
        let n = 9;
        let wi: Vec<[f32; 3]> = (0..n).map(|i| if i % 2 == 0 { up } else { tilted }).collect();
        let irradiance: Vec<[f32; 3]> = (0..n).map(|i| if i == 0 { [0.0; 3] } else { [2.0; 3] }).collect();
        // f = 0.05/sr everywhere but two highlights at 40/sr; the unlit pixel's radiance is ignored.
        let radiance: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let f = if i == 3 || i == 4 { 40.0 } else { 0.05 };
                [f * 2.0 * wi[i][2]; 3]
            })
            .collect();
        let obs = Observations::from_arrays(Vec::new(), 0, &wi, &wi, &irradiance, &radiance).unwrap();
        let m = obs.median_brdf().unwrap();
        assert!((m - 0.05).abs() < 1e-6, "{m}");
        let dark = Observations::from_arrays(Vec::new(), 0, &wi[..1], &wi[..1], &irradiance[..1], &radiance[..1]).unwrap();
        assert_eq!(dark.median_brdf(), None, "no lit pixel");
    }
}
