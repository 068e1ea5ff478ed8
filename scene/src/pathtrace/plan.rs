//! Which light transport effects a scene calls for, decided from the scene before any pixel, and
//! printed: the renderer simulates only those.
//!
//! - **Shadow rays** only where geometry can block a light: never on a closed convex mesh, where the
//!   facet test `n_F · l > 0` alone decides visibility exactly ([`crate::scene::convex`]).
//! - **Interreflections** (bounce rays intersected with the scene, more than one surface vertex) only
//!   where geometry can see itself: never on a closed convex mesh, whose every outgoing ray escapes.
//! - **Environment sampling** only for an environment that emits something.
//! - **BSDF sampling** (the continuation of a path) only where a sampled direction can find light: an
//!   environment, or other surface points.
//!
//! So a single convex object under directional lights needs one vertex and no ray beyond the camera
//! ray; in an environment it needs one vertex, environment and BSDF samples, and no shadow ray.
//! [`Plan::everything`] turns every effect on, which is how the tests show that each skip leaves the
//! image unchanged.

use std::string::String;
use std::vec::Vec;

/// The effects to simulate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// The mesh is closed and convex.
    pub convex: bool,
    /// Cast shadow rays for light samples.
    pub shadow_rays: bool,
    /// Intersect continuation rays with the scene (interreflections).
    pub interreflections: bool,
    /// Sample the environment light (next-event estimation, with MIS).
    pub env_sampling: bool,
    /// Continue paths by sampling the BSDF.
    pub bsdf_sampling: bool,
    /// Most surface vertices on a path.
    pub max_depth: u32,
}

impl Plan {
    /// The effects the scene calls for (module docs), with at most `max_depth` vertices.
    pub fn for_scene(convex: bool, has_env: bool, env_black: bool, max_depth: u32) -> Self {
        let env = has_env && !env_black;
        Plan {
            convex,
            shadow_rays: !convex,
            interreflections: !convex,
            env_sampling: env,
            bsdf_sampling: env || !convex,
            max_depth: if convex { 1 } else { max_depth.max(1) },
        }
    }

    /// Every effect on, whatever the scene (to check that the skips change nothing).
    pub fn everything(convex: bool, has_env: bool, max_depth: u32) -> Self {
        Plan {
            convex,
            shadow_rays: true,
            interreflections: true,
            env_sampling: has_env,
            bsdf_sampling: true,
            max_depth: max_depth.max(1),
        }
    }

    /// One line per effect: simulated, or skipped and why.
    pub fn summary(&self) -> String {
        let mut lines: Vec<String> = Vec::new();
        let why_convex = "closed convex mesh";
        lines.push(if self.shadow_rays {
            String::from("shadow rays: cast")
        } else {
            std::format!("shadow rays: skipped ({why_convex}: the facet test is exact)")
        });
        lines.push(if self.interreflections {
            std::format!("interreflections: traced, up to {} surface vertices, Russian roulette", self.max_depth)
        } else {
            std::format!("interreflections: skipped ({why_convex}: every reflected ray escapes; one vertex)")
        });
        lines.push(if self.env_sampling {
            String::from("environment: importance-sampled, MIS (power heuristic) with BSDF samples")
        } else {
            String::from("environment: none or black, not sampled")
        });
        lines.push(if self.bsdf_sampling {
            String::from("BSDF sampling: on")
        } else {
            String::from("BSDF sampling: skipped (no environment and no other surface to reach: direct light only)")
        });
        lines.join("\n")
    }
}
