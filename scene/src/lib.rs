//! # nbrdf-scene
//!
//! What renders with the BRDFs of [`nbrdf`], kept out of that embeddable, `no_std` core: triangle meshes
//! (OBJ, PLY, procedural), BVH ray casting, pinhole cameras, directional lights, the direct renderer of
//! Eq. 9 that the image-based fits of Sec. 5 train against ([`scene`]), a path tracer ([`pathtrace`],
//! behind `scene/examples/path_tracer.rs`) and linear HDR images in and out as EXR and PNG ([`image`]).
//!
//! Errors are the core's [`nbrdf::Error`]; nothing of the core is re-exported, so BRDFs, vectors and
//! files are named through `nbrdf` itself.
//!
//! ```
//! use nbrdf::Vec3;
//! use nbrdf_scene::scene::{builtin::BuiltinMesh, Camera};
//! let mesh = BuiltinMesh::Sphere.mesh();
//! let camera = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 0.6, 8, 8).unwrap();
//! assert!(!mesh.triangles.is_empty() && camera.width == 8);
//! ```
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

pub mod image;
pub mod pathtrace;
pub mod scene;
