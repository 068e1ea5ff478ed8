//! Pinhole cameras in the OpenCV convention, as calibrated data sets (DiLiGenT-MV) ship them.
//!
//! A world point `X` maps to camera coordinates `Xc = R·X + t` (camera `x` right, `y` down, `z`
//! forward) and to pixel coordinates `K·Xc / Xc.z`. Pixel centres sit at integer coordinates: pixel
//! `(col, row)` is the point `(col, row)` of the image plane, as in OpenCV and Bouguet's calibration
//! toolbox.

use nbrdf::{Error, Vec3};
use glam::{Mat3, Vec2};

use super::Ray;

/// Largest image side a camera accepts (pixels).
pub const MAX_SIDE: usize = 32_768;

/// Largest image a camera accepts: 64 Mpixel, 768 MB as the f32 RGB image a render holds.
pub const MAX_PIXELS: usize = 1 << 26;

/// A calibrated pinhole camera and its image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Intrinsics `[[fx, s, cx], [0, fy, cy], [0, 0, 1]]` (glam stores it column-major).
    pub k: Mat3,
    /// World-to-camera rotation.
    pub r: Mat3,
    /// World-to-camera translation.
    pub t: Vec3,
}

impl Camera {
    /// Checks the matrices (finite, `K` upper triangular with positive focal lengths, `R` a rotation
    /// within 1e-3) and the image size.
    pub fn new(width: u32, height: u32, k: Mat3, r: Mat3, t: Vec3) -> Result<Self, Error> {
        if width == 0 || height == 0 {
            return Err(Error::InvalidValue { what: "camera image size", reason: "width and height must be positive" });
        }
        // Checked before any image is allocated: an absurd size is an error, never an allocation abort.
        for (what, v) in [("camera image width", width), ("camera image height", height)] {
            if v as usize > MAX_SIDE {
                return Err(Error::TooLarge { what, found: v as usize, max: MAX_SIDE });
            }
        }
        if width as usize * height as usize > MAX_PIXELS {
            return Err(Error::TooLarge { what: "camera image pixels (width × height)", found: width as usize * height as usize, max: MAX_PIXELS });
        }
        if !(k.is_finite() && r.is_finite() && t.is_finite()) {
            return Err(Error::NonFinite { what: "camera K, R or t", index: 0 });
        }
        let kr = k.transpose(); // rows
        if kr.x_axis.x <= 0.0 || kr.y_axis.y <= 0.0 || kr.y_axis.x != 0.0 || kr.z_axis != Vec3::Z {
            return Err(Error::InvalidValue {
                what: "camera intrinsics K",
                reason: "expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0",
            });
        }
        let orth = (r * r.transpose() - Mat3::IDENTITY).abs().to_cols_array().iter().fold(0.0f32, |m, x| m.max(*x));
        if orth > 1e-3 || (r.determinant() - 1.0).abs() > 1e-3 {
            return Err(Error::InvalidValue { what: "camera rotation R", reason: "not a rotation matrix" });
        }
        Ok(Camera { width, height, k, r, t })
    }

    /// A camera at `eye` looking at `target`, with `up` pointing up in the image and the vertical field
    /// of view `fov_y` (radians); the principal point is the image centre.
    ///
    /// ```
    /// use nbrdf_scene::scene::Camera;
    /// use nbrdf::Vec3;
    /// let cam = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.7, 64, 48).unwrap();
    /// let (px, depth) = cam.project(Vec3::ZERO).unwrap();
    /// assert!((px.x - 31.5).abs() < 1e-4 && (px.y - 23.5).abs() < 1e-4 && (depth - 3.0).abs() < 1e-6);
    /// assert!(cam.project(Vec3::new(0.0, 0.5, 0.0)).unwrap().0.y < 23.5); // world up is image up
    /// ```
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_y: f32, width: u32, height: u32) -> Result<Self, Error> {
        let f = nbrdf::angles::unit(target - eye)
            .ok_or(Error::InvalidValue { what: "camera look-at", reason: "eye and target coincide" })?;
        let x = nbrdf::angles::unit(f.cross(up))
            .ok_or(Error::InvalidValue { what: "camera look-at", reason: "up is parallel to the view direction" })?;
        let y = f.cross(x);
        let r = Mat3::from_cols(x, y, f).transpose();
        let t = -(r * eye);
        if !(fov_y > 0.0 && fov_y < core::f32::consts::PI) {
            return Err(Error::InvalidValue { what: "camera field of view", reason: "must lie in (0, π)" });
        }
        let fy = 0.5 * height as f32 / (0.5 * fov_y).tan();
        let cx = 0.5 * (width as f32 - 1.0);
        let cy = 0.5 * (height as f32 - 1.0);
        let k = Mat3::from_cols(Vec3::new(fy, 0.0, 0.0), Vec3::new(0.0, fy, 0.0), Vec3::new(cx, cy, 1.0));
        Camera::new(width, height, k, r, t)
    }

    /// Camera centre in world coordinates, `-Rᵀt`.
    #[inline]
    pub fn center(&self) -> Vec3 {
        -(self.r.transpose() * self.t)
    }

    /// Unit viewing axis (camera `+z`) in world coordinates.
    #[inline]
    pub fn forward(&self) -> Vec3 {
        self.r.transpose() * Vec3::Z
    }

    /// The primary ray through pixel `(col, row)`: from the camera centre along `Rᵀ K⁻¹ (col, row, 1)`,
    /// normalised, so the hit distance is metric.
    #[inline]
    pub fn pixel_ray(&self, col: f32, row: f32) -> Ray {
        let d_cam = self.k.inverse() * Vec3::new(col, row, 1.0);
        Ray::new(self.center(), (self.r.transpose() * d_cam).normalize())
    }

    /// Pixel coordinates and depth `Xc.z` of a world point, `None` behind the camera.
    #[inline]
    pub fn project(&self, x: Vec3) -> Option<(Vec2, f32)> {
        let xc = self.r * x + self.t;
        if xc.z <= 0.0 {
            return None;
        }
        let p = self.k * (xc / xc.z);
        Some((Vec2::new(p.x, p.y), xc.z))
    }
}
