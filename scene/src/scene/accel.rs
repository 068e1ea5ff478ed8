//! Ray casting against a mesh through a bounding volume hierarchy.
//!
//! The hierarchy is the compressed 8-wide BVH of `obvhs` (Ylitie et al. 2017, built by PLOC, Meister &
//! Bittner 2018). It was chosen over the `bvh` crate by `benches/scene.rs` (`--features compare-bvh`),
//! which measures both on the same rays. The triangle test is ours ([`intersect_triangle`]) so that
//! barycentrics come from the same computation as the distance.

use std::vec::Vec;

use super::ray::{intersect_triangle, Hit, Ray};
use super::Mesh;
use nbrdf::{Error, Vec3};

use obvhs_glam as og;

/// A BVH over the triangles of one mesh, answering closest-hit and any-hit queries.
pub struct Accel {
    bvh: obvhs::cwbvh::CwBvh,
    /// Number of mesh triangles (primitives may repeat after spatial splits).
    triangles: usize,
    /// Triangle corners in the BVH's primitive order.
    corners: Vec<[Vec3; 3]>,
    /// Mesh triangle index of each BVH primitive.
    ids: Vec<u32>,
}

impl core::fmt::Debug for Accel {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Accel").field("triangles", &self.triangles).field("primitives", &self.ids.len()).finish()
    }
}

#[inline]
fn to_og(v: Vec3) -> og::Vec3A {
    og::Vec3A::new(v.x, v.y, v.z)
}

/// A ray direction for obvhs, with `-0.0` turned into `+0.0` (`-0.0 + 0.0 = +0.0`): obvhs takes the
/// slab order from `d < 0` but the inverse from the sign bit, so a negative zero (as in `-Vec3::Z`)
/// would make every box test miss.
#[inline]
fn dir_to_og(d: Vec3) -> og::Vec3A {
    og::Vec3A::new(d.x + 0.0, d.y + 0.0, d.z + 0.0)
}

impl Accel {
    /// Builds the hierarchy over `mesh` (a valid [`Mesh`] is never empty).
    pub fn new(mesh: &Mesh) -> Result<Self, Error> {
        if mesh.triangles.len() >= u32::MAX as usize {
            return Err(Error::TooLarge {
                what: "mesh triangle count",
                found: mesh.triangles.len(),
                max: u32::MAX as usize - 1,
            });
        }
        let tris: Vec<obvhs::triangle::Triangle> = (0..mesh.triangles.len() as u32)
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                obvhs::triangle::Triangle { v0: to_og(a), v1: to_og(b), v2: to_og(c) }
            })
            .collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            obvhs::BvhBuildParams::medium_build(),
            &mut core::time::Duration::default(),
        );
        let ids: Vec<u32> = bvh.primitive_indices.clone();
        let corners = ids.iter().map(|&i| mesh.corners(i)).collect();
        Ok(Accel { bvh, corners, ids, triangles: mesh.triangles.len() })
    }

    /// The closest hit along `ray` within `[tmin, tmax]`, or `None`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !(ray.origin.is_finite() && ray.dir.is_finite()) || ray.dir == Vec3::ZERO {
            return None;
        }
        let r = obvhs::ray::Ray::new(to_og(ray.origin), dir_to_og(ray.dir), ray.tmin, ray.tmax);
        let mut rh = obvhs::ray::RayHit::none();
        let mut best: Option<Hit> = None;
        self.bvh.ray_traverse(r, &mut rh, |cur, id| {
            // `cur.tmax` shrinks to the closest hit so far; only a strictly closer one is reported.
            match intersect_triangle(ray.origin, ray.dir, ray.tmin, cur.tmax, self.corners[id]) {
                Some((t, b1, b2)) if t < cur.tmax => {
                    best = Some(Hit { triangle: self.ids[id], b1, b2, t });
                    t
                }
                _ => f32::INFINITY,
            }
        });
        best
    }

    /// Whether anything lies along `ray` within `[tmin, tmax]` (the shadow query; stops at the first hit).
    pub fn occluded(&self, ray: &Ray) -> bool {
        if !(ray.origin.is_finite() && ray.dir.is_finite()) || ray.dir == Vec3::ZERO {
            return false;
        }
        let r = obvhs::ray::Ray::new(to_og(ray.origin), dir_to_og(ray.dir), ray.tmin, ray.tmax);
        !self.bvh.ray_traverse_miss(r, |cur, id| {
            intersect_triangle(ray.origin, ray.dir, ray.tmin, cur.tmax, self.corners[id])
                .map_or(f32::INFINITY, |(t, _, _)| t)
        })
    }

    /// Number of mesh triangles.
    pub fn len(&self) -> usize {
        self.triangles
    }

    /// Never true for a hierarchy built from a valid mesh.
    pub fn is_empty(&self) -> bool {
        self.triangles == 0
    }
}
