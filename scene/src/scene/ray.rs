//! Rays and ray–triangle hits.

use nbrdf::Vec3;

/// A ray `origin + t·dir` restricted to `t ∈ [tmin, tmax]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Direction; need not be unit, `t` is measured in its length.
    pub dir: Vec3,
    /// Nearest accepted parameter.
    pub tmin: f32,
    /// Farthest accepted parameter.
    pub tmax: f32,
}

impl Ray {
    /// A ray over `t ∈ [0, ∞)`.
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray { origin, dir, tmin: 0.0, tmax: f32::INFINITY }
    }

    /// The point at parameter `t`.
    ///
    /// ```
    /// use nbrdf_scene::scene::Ray;
    /// use nbrdf::Vec3;
    /// assert_eq!(Ray::new(Vec3::ZERO, Vec3::X).at(2.0), Vec3::new(2.0, 0.0, 0.0));
    /// ```
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// The closest intersection of a ray with a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Triangle index into [`Mesh::triangles`](super::Mesh::triangles).
    pub triangle: u32,
    /// Barycentric weight of the triangle's second corner.
    pub b1: f32,
    /// Barycentric weight of the third corner; the first has `1 - b1 - b2`.
    pub b2: f32,
    /// Ray parameter of the hit.
    pub t: f32,
}

/// Möller & Trumbore 1997, "Fast, minimum storage ray-triangle intersection": the ray parameter and
/// the barycentrics `(b1, b2)` of corners `p1`, `p2`, or `None` for a miss, a parallel ray or a
/// degenerate triangle. Both faces are hit (no back-face culling).
///
/// ```
/// use nbrdf_scene::scene::ray::intersect_triangle;
/// use nbrdf::Vec3;
/// let (t, b1, b2) = intersect_triangle(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 10.0,
///     [Vec3::ZERO, Vec3::X, Vec3::Y]).unwrap();
/// assert_eq!((t, b1, b2), (1.0, 0.25, 0.25));
/// ```
#[inline]
pub fn intersect_triangle(
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
    [p0, p1, p2]: [Vec3; 3],
) -> Option<(f32, f32, f32)> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pvec = dir.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tvec = origin - p0;
    let b1 = tvec.dot(pvec) * inv;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let b2 = dir.dot(qvec) * inv;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv;
    (t >= tmin && t <= tmax).then_some((t, b1, b2))
}
