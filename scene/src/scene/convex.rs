//! Convexity of a mesh: the test that lets the renderer skip shadow rays (Eq. 9) exactly.
//!
//! A closed mesh whose every vertex lies on the inner side of every face plane bounds a convex body
//! `P`. For such a mesh a point `x` on face `F` is lit by a directional light `l` exactly when the
//! light is in front of the facet, `n_F · l > 0`: the ray `x + s·l` then stays in the open outer
//! half-space of `F`'s plane, which `P` does not meet, and otherwise it enters `P` and must leave it
//! through the surface. The renderer uses that facet test for every mesh (see `render`), so for a
//! convex mesh the shadow rays add nothing and are skipped.

use std::collections::HashMap;

use super::Mesh;

/// Whether `mesh` is closed (every edge shared by exactly two triangles, with opposite orientations)
/// and convex: every vertex `p` satisfies `(p - a_F) · n_F ≤ tol` for every non-degenerate face `F`
/// with corner `a_F` and outward unit normal `n_F`, with `tol = 1e-5 × radius`.
///
/// A mesh wound inward, with duplicated seam vertices or any hole is reported non-convex: the answer
/// errs only on the side of casting shadow rays. The cost is `O(F·V)` for a convex mesh; a non-convex
/// one usually fails on an early face.
///
/// ```
/// use nbrdf_scene::scene::{builtin::BuiltinMesh, convex::is_convex};
/// assert!(is_convex(&BuiltinMesh::Sphere.mesh()));
/// assert!(!is_convex(&BuiltinMesh::Torus.mesh()));
/// ```
pub fn is_convex(mesh: &Mesh) -> bool {
    let mut edges: HashMap<(u32, u32), i32> = HashMap::with_capacity(mesh.triangles.len() * 3);
    for &[a, b, c] in &mesh.triangles {
        for (u, v) in [(a, b), (b, c), (c, a)] {
            // +1 for the edge in one direction, -1 in the other; a closed oriented manifold sums to 0
            // with exactly two uses.
            let e = edges.entry((u.min(v), u.max(v))).or_insert(0);
            *e += if u < v { 1 } else { -1 } * 100 + 1;
        }
    }
    // Each edge must be used once in each direction: (+100 + 1) + (-100 + 1) = 2.
    if edges.values().any(|&s| s != 2) {
        return false;
    }
    let tol = 1e-5 * mesh.radius();
    (0..mesh.triangles.len() as u32).all(|t| {
        let [a, b, c] = mesh.corners(t);
        let Some(n) = nbrdf::angles::unit((b - a).cross(c - a)) else { return true };
        mesh.positions.iter().all(|p| (*p - a).dot(n) <= tol)
    })
}
