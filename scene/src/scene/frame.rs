//! The local shading frame: the one place where world directions become BRDF directions.
//!
//! The renderer and the trainer both build frames with [`Frame::from_normal`], so a direction pair seen
//! in a rendered image and the same pair fed to a model during fitting are bit-identical. The tangent is
//! arbitrary but deterministic; every BRDF here is isotropic, so its value does not depend on it.

use nbrdf::Vec3;

/// An orthonormal basis `(s, t, n)` with `n` the surface normal; local coordinates are `(·s, ·t, ·n)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent, `n × s`.
    pub t: Vec3,
    /// Unit normal, the local `+z`.
    pub n: Vec3,
}

impl Frame {
    /// The branchless basis of Duff et al. 2017, "Building an orthonormal basis, revisited" (JCGT 6(1)),
    /// continuous everywhere except across `n.z = 0⁻`. `n` must be unit length.
    ///
    /// ```
    /// use nbrdf_scene::scene::Frame;
    /// use nbrdf::Vec3;
    /// let n = Vec3::new(0.3, -0.5, 0.8).normalize();
    /// let f = Frame::from_normal(n);
    /// let l = Vec3::new(0.1, 0.2, 0.9).normalize();
    /// assert!((f.to_local(n) - Vec3::Z).length() < 1e-6);
    /// assert!((f.to_local(l).z - l.dot(n)).abs() < 1e-6); // cos θ_l
    /// assert!((f.to_world(f.to_local(l)) - l).length() < 1e-6);
    /// ```
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// World direction to local coordinates (normal = `+z`).
    #[inline]
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        Vec3::new(w.dot(self.s), w.dot(self.t), w.dot(self.n))
    }

    /// Local direction to world coordinates.
    #[inline]
    pub fn to_world(&self, w: Vec3) -> Vec3 {
        self.s * w.x + self.t * w.y + self.n * w.z
    }
}
