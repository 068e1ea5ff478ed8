//! Directional lights: the calibrated light sources of Sec. 5 (one per image).

use nbrdf::{Rgb, Vec3};

/// A light at infinity: every surface point sees it in the same direction with the same irradiance
/// scale, so Eq. 1 collapses to the single term of Eq. 9.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionalLight {
    /// Unit direction from the surface toward the light, in world coordinates.
    pub direction: Vec3,
    /// Radiance scale `L_i` per RGB channel.
    pub intensity: Rgb,
}

impl DirectionalLight {
    /// A light from `direction` (normalised here; `None` if zero or non-finite).
    ///
    /// ```
    /// use nbrdf_scene::scene::DirectionalLight;
    /// use nbrdf::Vec3;
    /// let l = DirectionalLight::new(Vec3::new(0.0, 0.0, 2.0), [1.0; 3]).unwrap();
    /// assert_eq!(l.direction, Vec3::Z);
    /// assert!(DirectionalLight::new(Vec3::ZERO, [1.0; 3]).is_none());
    /// ```
    #[inline]
    pub fn new(direction: Vec3, intensity: Rgb) -> Option<Self> {
        Some(DirectionalLight { direction: nbrdf::angles::unit(direction)?, intensity })
    }
}
