//! A mesh prepared for rendering: its BVH, its convexity and its ray offset, computed once.

use super::{convex::is_convex, Accel, Mesh};
use nbrdf::Error;

/// A mesh with everything the renderer needs to know about it ahead of the pixels.
#[derive(Debug)]
pub struct Geometry {
    /// The mesh.
    pub mesh: Mesh,
    /// Its BVH.
    pub accel: Accel,
    /// Closed and convex ([`is_convex`]): no shadow ray can hit it, so none is cast.
    pub convex: bool,
    /// Shadow-ray offset along the facet normal (Sec. 5.1, "shadow bias"): `1e-4` of the bounding
    /// radius, far above the `~1e-7` relative error of the hit point and far below any feature size.
    pub bias: f32,
}

impl Geometry {
    /// Builds the BVH and tests convexity.
    pub fn new(mesh: Mesh) -> Result<Self, Error> {
        let accel = Accel::new(&mesh)?;
        let convex = is_convex(&mesh);
        let bias = 1e-4 * mesh.radius();
        Ok(Geometry { mesh, accel, convex, bias })
    }
}
