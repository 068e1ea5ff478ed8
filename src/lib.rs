//! # nbrdf
//!
//! Embeddable evaluation of the neural and parametric BRDFs compared in *On Neural BRDFs: A Thorough
//! Comparison of State-of-the-Art Approaches* (the paper). The crate is `#![no_std]` and evaluates every
//! model with fixed-size stack arrays and no allocation; the `alloc` feature adds readers that own their
//! data (MERL tables, NBRDF-json networks), `std` adds files (loading from a path, bounded reads, atomic
//! writes). Meshes, cameras, the renderers and images are the `nbrdf-scene` crate, built on this one.
//!
//! Evaluation has one arithmetic, f32. f16 model files are a storage format (half the weight bytes):
//! [`ModelBuf`] (`alloc`) widens their weights to f32 once at load and evaluates those, while a
//! [`Model`] over borrowed f16 bytes (`no_std`) widens each row as it reads it; both give the
//! same bits.
//!
//! Conventions (docs/architecture.md): directions are unit vectors in the local shading frame (normal = +z)
//! pointing away from the surface, `wi` toward the light and `wo` toward the viewer. A BRDF value is in
//! 1/sr, linear RGB. Below the horizon, degenerate or non-finite input evaluates to 0, never NaN.
//!
//! ```
//! use nbrdf::{angles, Vec3};
//! let wi = Vec3::new(0.3, 0.1, 0.9).normalize();
//! let wo = Vec3::new(-0.2, 0.4, 0.8).normalize();
//! // The reciprocity map of Sec. 4.3 is bitwise symmetric under the swap of wi and wo.
//! assert_eq!(angles::theta_map(wi, wo), angles::theta_map(wo, wi));
//! ```
#![no_std]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

#[cfg(feature = "alloc")]
pub mod any;
pub mod angles;
pub mod brdf;
pub mod builtin;
pub mod encoding;
pub mod energy;
pub mod error;
pub mod file;
#[cfg(feature = "std")]
pub mod io;
pub mod math;
#[cfg(feature = "alloc")]
pub mod measured;
pub mod kernels;
pub mod microfacet;
pub mod mlp;
pub mod model;
pub mod neural;
pub mod parametric;
pub(crate) mod real;
pub mod sampling;
pub mod warp;

#[cfg(feature = "alloc")]
pub use any::AnyBrdf;
pub use brdf::{Brdf, BsdfSample};
pub use error::Error;
pub use glam::Vec3;
#[cfg(feature = "alloc")]
pub use model::ModelBuf;
pub use model::{Model, Prepared, Weights};

/// Linear RGB triple, the value type of every BRDF (1/sr).
pub type Rgb = [f32; 3];

/// Black, the value of every BRDF below the horizon and for degenerate input.
pub const BLACK: Rgb = [0.0; 3];
