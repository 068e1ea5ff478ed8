//! Lambertian reflection (Lambert 1760): `f = kd / π`, the diffuse reference of every other model.
//!
//! | raw index | parameter | range | activation |
//! |---|---|---|---|
//! | 0, 1, 2 | `kd` (R, G, B albedo) | [0, 1] | `sigmoid(raw)` |

use super::raw_at;
use crate::angles::upper_hemisphere_pair;
use crate::math::{logit, sanitize, sigmoid, INV_PI};
use crate::{Rgb, Vec3, BLACK};

/// A Lambertian BRDF with albedo `kd`: the albedo is exactly `kd` at every incidence.
///
/// ```
/// use nbrdf::{parametric::Lambert, Vec3};
/// let white = Lambert { kd: [1.0; 3] };
/// let f = white.eval(Vec3::new(0.3, 0.0, 0.9), Vec3::Z);
/// assert!((f[0] - core::f32::consts::FRAC_1_PI).abs() < 1e-7);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Diffuse albedo per channel, in [0, 1] for an energy-conserving surface.
    pub kd: Rgb,
}

impl Lambert {
    /// Raw network outputs this model reads.
    pub const N_RAW: usize = 3;

    /// Parameters from raw network outputs (table at the top of the file); missing or non-finite raw
    /// values count as 0.
    #[inline]
    pub fn from_raw(raw: &[f32]) -> Self {
        Self { kd: [0, 1, 2].map(|c| sigmoid(raw_at(raw, c))) }
    }

    /// Raw outputs that [`Lambert::from_raw`] maps back to these parameters (values in the open range
    /// (0, 1) round-trip; the ends are clamped to 1e-7 from them).
    #[inline]
    pub fn to_raw(&self) -> [f32; Self::N_RAW] {
        self.kd.map(logit)
    }

    /// `kd / π` for a valid pair, 0 below the horizon or for degenerate input.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        if upper_hemisphere_pair(wi, wo).is_none() {
            return BLACK;
        }
        sanitize(self.kd.map(|k| k * INV_PI))
    }
}
