//! Scenes for the image-based fits of Sec. 5: triangle meshes (OBJ, PLY, procedural), BVH ray casting,
//! pinhole cameras, directional lights, cast shadows and the direct renderer of Eq. 9.
//!
//! Everything here works in one world space. Meshes read from files keep their own coordinates (a
//! calibrated data set such as DiLiGenT-MV places its cameras in them); [`Mesh::normalized`] maps a mesh
//! into the unit sphere for the semi-synthetic data set and returns the similarity it applied.
//!
//! ```
//! use nbrdf_scene::scene::{builtin::BuiltinMesh, Accel, Ray};
//! use nbrdf::Vec3;
//! let mesh = BuiltinMesh::Sphere.mesh();
//! let accel = Accel::new(&mesh).unwrap();
//! let hit = accel.intersect(&Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z)).unwrap();
//! assert!((hit.t - 4.0).abs() < 1e-2); // the tessellated unit sphere, seen along -z
//! ```

pub mod accel;
pub mod builtin;
pub mod camera;
pub mod convex;
pub mod frame;
pub mod geometry;
pub mod light;
pub mod mesh;
pub mod ray;
pub mod render;

pub use accel::Accel;
pub use camera::Camera;
pub use frame::Frame;
pub use light::DirectionalLight;
pub use mesh::{Mesh, Normalization};
pub use ray::{Hit, Ray};
pub use geometry::Geometry;
pub use render::{render_view, GBuffer, LightImage, RenderOptions, RenderReport, RenderedView, ShadowPass, SurfaceSample, Visibility};
