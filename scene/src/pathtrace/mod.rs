//! A small path tracer that renders one mesh with any BRDF of `nbrdf` under
//! directional lights and an environment map, with importance sampling that works for neural BRDFs.
//! `scene/examples/path_tracer.rs` is its command line; the tests call it directly.
//!
//! - [`material`]: the BRDF and how it is sampled (own lobes, a fitted proxy, or cosine).
//! - [`environment`]: constant or lat-long environment light, importance-sampled.
//! - [`plan`]: which effects the scene calls for; only those are simulated.
//! - [`integrator`]: path tracing with next-event estimation, MIS, Russian roulette, rayon.
//!
//! ```
//! use nbrdf_scene::pathtrace::{environment::Environment, integrator::{render, Options, Scene},
//!                              material::Material};
//! use nbrdf::parametric::{Lambert, Parametric};
//! use nbrdf_scene::scene::{builtin::BuiltinMesh, Camera, Geometry};
//! use nbrdf::Vec3;
//! let geometry = Geometry::new(BuiltinMesh::Sphere.mesh()).unwrap();
//! let material = Material::parametric(Parametric::Lambert(Lambert { kd: [0.5; 3] }));
//! let camera = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 0.6, 8, 8).unwrap();
//! let env = Environment::Constant([1.0; 3]);
//! let scene = Scene { geometry: &geometry, material: &material, lights: &[], env: Some(&env), camera: &camera };
//! let out = render(&scene, &Options { spp: 4, ..Options::default() }, &|_| {});
//! assert!(!out.plan.shadow_rays && !out.plan.interreflections); // a convex sphere needs neither
//! let centre = out.image.get(4, 4)[0];
//! assert!((centre - 0.5).abs() < 0.2); // albedo × uniform radiance, up to Monte Carlo noise
//! ```

pub mod distribution;
pub mod environment;
pub mod integrator;
pub mod material;
pub mod plan;
pub mod rng;

pub use environment::Environment;
pub use integrator::{render, Options, Rendered, Scene, Stats, MAX_DEPTH, MAX_SPP};
pub use material::{Material, Sampling, Shading};
pub use plan::Plan;
