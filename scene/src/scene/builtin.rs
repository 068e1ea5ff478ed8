//! Procedural meshes, so that the semi-synthetic data set and the tests need no files. Each fits the
//! unit sphere and is closed and outward-wound.

use std::collections::HashMap;
use std::vec;
use std::vec::Vec;

use core::f32::consts::{PI, TAU};

use super::Mesh;
use nbrdf::Vec3;

/// The built-in meshes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BuiltinMesh {
    /// Unit icosphere (icosahedron subdivided four times, 5120 triangles, within 1.5e-3 of the sphere) with exact sphere normals.
    /// Convex: the renderer casts no shadow rays on it.
    Sphere,
    /// Torus around `z` with radii 0.7 and 0.3 (8192 triangles) and exact normals; its inner ring
    /// shadows itself.
    Torus,
    /// A sphere cut by six meridional grooves, half the radius deep at the equator and narrow (radius
    /// `1 - 0.5 max(0, cos 6φ)⁴ sin²θ`, 24 576 triangles), angle-weighted normals: deep concavities
    /// with cast shadows and strong normal variation.
    Grooved,
}

impl BuiltinMesh {
    /// Every built-in mesh.
    pub const ALL: [BuiltinMesh; 3] = [BuiltinMesh::Sphere, BuiltinMesh::Torus, BuiltinMesh::Grooved];

    /// Stable name used on the command line and in data set files.
    pub fn id(self) -> &'static str {
        match self {
            BuiltinMesh::Sphere => "sphere",
            BuiltinMesh::Torus => "torus",
            BuiltinMesh::Grooved => "grooved",
        }
    }

    /// The mesh named `id`, if any.
    ///
    /// ```
    /// use nbrdf_scene::scene::builtin::BuiltinMesh;
    /// for m in BuiltinMesh::ALL { assert_eq!(BuiltinMesh::from_id(m.id()), Some(m)); }
    /// assert_eq!(BuiltinMesh::from_id("cube"), None);
    /// ```
    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.id() == id)
    }

    /// Builds the mesh.
    pub fn mesh(self) -> Mesh {
        match self {
            BuiltinMesh::Sphere => icosphere(4),
            BuiltinMesh::Torus => torus(0.7, 0.3, 128, 32),
            BuiltinMesh::Grooved => grooved(64, 192),
        }
    }
}

/// Loop-free midpoint subdivision of the icosahedron, vertices projected onto the unit sphere.
fn icosphere(levels: u32) -> Mesh {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        (-1.0, g, 0.0), (1.0, g, 0.0), (-1.0, -g, 0.0), (1.0, -g, 0.0),
        (0.0, -1.0, g), (0.0, 1.0, g), (0.0, -1.0, -g), (0.0, 1.0, -g),
        (g, 0.0, -1.0), (g, 0.0, 1.0), (-g, 0.0, -1.0), (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
        [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
        [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |a: u32, b: u32, p: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                (p.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let (ab, bc, ca) = (split(a, b, &mut p), split(b, c, &mut p), split(c, a, &mut p));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let normals = p.clone();
    Mesh { positions: p, normals, triangles: tris }
}

/// Torus `((R + r cos v) cos u, (R + r cos v) sin u, r sin v)` on an `nu × nv` grid.
fn torus(major: f32, minor: f32, nu: u32, nv: u32) -> Mesh {
    let mut positions = Vec::with_capacity((nu * nv) as usize);
    let mut normals = Vec::with_capacity((nu * nv) as usize);
    for i in 0..nu {
        let u = TAU * i as f32 / nu as f32;
        for j in 0..nv {
            let v = TAU * j as f32 / nv as f32;
            let n = Vec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
            positions.push(Vec3::new(major * u.cos(), major * u.sin(), 0.0) + n * minor);
            normals.push(n);
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut triangles = Vec::with_capacity((2 * nu * nv) as usize);
    for i in 0..nu {
        for j in 0..nv {
            // ∂p/∂u × ∂p/∂v points outward, so the (u, then v) winding is counter-clockwise outside.
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh { positions, normals, triangles }
}

/// The grooved sphere: `n_theta` rings between the poles, `n_phi` segments around.
fn grooved(n_theta: u32, n_phi: u32) -> Mesh {
    let radius = |theta: f32, phi: f32| {
        let g = (6.0 * phi).cos().max(0.0).powi(4);
        1.0 - 0.5 * g * theta.sin().powi(2)
    };
    let mut positions = vec![Vec3::Z]; // north pole
    for i in 1..n_theta {
        let theta = PI * i as f32 / n_theta as f32;
        for j in 0..n_phi {
            let phi = TAU * j as f32 / n_phi as f32;
            let d = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            positions.push(d * radius(theta, phi));
        }
    }
    positions.push(-Vec3::Z); // south pole
    let south = positions.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + (i - 1) * n_phi + (j % n_phi);
    let mut triangles = Vec::new();
    for j in 0..n_phi {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
        triangles.push([ring(n_theta - 1, j), south, ring(n_theta - 1, j + 1)]);
    }
    for i in 1..n_theta - 1 {
        for j in 0..n_phi {
            triangles.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            triangles.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    // Built from finite, non-degenerate geometry: construction cannot fail.
    Mesh::new(positions, triangles).expect("the grooved sphere is a valid mesh")
}
