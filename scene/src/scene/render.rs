//! The direct renderer of Eq. 9 for one view under a set of directional lights.
//!
//! Every pixel ray is cast once ([`GBuffer::cast`]); per light each hit is shaded as
//! `L = f(x, l, v) · L_i · I_s(x, l) · cos θ_l` in the local frame of the interpolated normal
//! ([`Frame`]). Only the effects the scene calls for are simulated, and [`RenderReport`] says which:
//!
//! - pixels that miss the mesh get no work at all;
//! - a light below the shading horizon (`cos θ_l ≤ 0`) gives 0 without a BRDF evaluation or a ray;
//! - a light behind the hit facet (`n_F · l ≤ 0`, possible where interpolated normals bend past the
//!   facet, the "shadow terminator") is blocked by that facet, again without a ray;
//! - shadow rays are cast only where something could block the light: never on a closed convex mesh
//!   (see [`convex`](super::convex), which proves that the facet test alone is then exact);
//! - the noise pass runs only for `σ > 0`.

use std::vec;
use std::vec::Vec;
use std::{format, string::String};

use rand::SeedableRng;
use rand_distr::Distribution;
use rayon::prelude::*;

use super::geometry::Geometry;
use super::{Camera, DirectionalLight, Frame, Hit, Ray};
use nbrdf::{Rgb, Vec3};

/// Whether shadow rays are cast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShadowPass {
    /// Cast them unless the mesh is convex (they could not change a pixel).
    #[default]
    Auto,
    /// Always cast them (to check that `Auto` skips exactly).
    Force,
    /// Never cast them: attached shadows only.
    Off,
}

/// Renderer settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Shadow-ray policy.
    pub shadows: ShadowPass,
    /// Standard deviation of the Gaussian noise added to the radiance (Sec. 5.3: `1e-3`); 0 for none.
    pub noise_sigma: f32,
    /// Seed of the noise; image `i` of the view draws from ChaCha8 stream `i` of this seed.
    pub seed: u64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { shadows: ShadowPass::Auto, noise_sigma: 0.0, seed: 0 }
    }
}

/// What a camera ray found: the hit, its surface point and normals, and the view direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    /// Triangle and barycentrics (the `x` of the trainer's samples).
    pub hit: Hit,
    /// World position.
    pub position: Vec3,
    /// Interpolated unit shading normal (Sec. 5.1).
    pub normal: Vec3,
    /// Unit normal of the hit facet, oriented to the shading normal's side.
    pub facet_normal: Vec3,
    /// Unit direction from the point toward the camera (`v`, `wo`).
    pub view: Vec3,
}

impl SurfaceSample {
    /// The local shading frame of this point.
    #[inline]
    pub fn frame(&self) -> Frame {
        Frame::from_normal(self.normal)
    }
}

/// First hits of every pixel of one view, row-major (`row * width + col`).
#[derive(Debug, Clone, PartialEq)]
pub struct GBuffer {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// One entry per pixel, `None` where the ray misses the mesh.
    pub samples: Vec<Option<SurfaceSample>>,
}

impl GBuffer {
    /// Casts one ray through every pixel centre (in parallel over rows).
    pub fn cast(geometry: &Geometry, camera: &Camera) -> Self {
        let (w, h) = (camera.width, camera.height);
        let samples = (0..h)
            .into_par_iter()
            .flat_map_iter(|row| (0..w).map(move |col| surface_sample(geometry, &camera.pixel_ray(col as f32, row as f32))))
            .collect();
        GBuffer { width: w, height: h, samples }
    }

    /// Pixels that hit the mesh.
    pub fn hits(&self) -> usize {
        self.samples.iter().filter(|s| s.is_some()).count()
    }
}

/// The surface sample of a ray, or `None` if it misses.
pub fn surface_sample(geometry: &Geometry, ray: &Ray) -> Option<SurfaceSample> {
    let mesh = &geometry.mesh;
    let hit = geometry.accel.intersect(ray)?;
    let normal = mesh.shading_normal(hit.triangle, hit.b1, hit.b2);
    let f = mesh.face_normal(hit.triangle);
    let facet_normal = if f.dot(normal) < 0.0 { -f } else { f };
    Some(SurfaceSample {
        hit,
        position: mesh.point(hit.triangle, hit.b1, hit.b2),
        normal,
        facet_normal,
        view: -ray.dir.normalize(),
    })
}

/// How a light reaches a surface sample: the indicator `I_s` of Eq. 9 with the reason it is 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Visibility {
    /// `cos θ_l ≤ 0` for the shading normal: no light arrives, no work done.
    BelowHorizon,
    /// The light is behind the hit facet itself (`n_F · l ≤ 0`).
    FacetBlocked,
    /// A shadow ray toward the light hit the mesh.
    Shadowed,
    /// The light arrives (`I_s = 1`); `ray` says whether a shadow ray was cast to know it.
    Lit {
        /// A shadow ray was cast.
        ray: bool,
    },
}

/// `I_s(x, l)` of Eq. 9: a secondary ray from the hit point toward the light, started `bias` off the
/// surface along the facet normal to avoid self-shadow acne (Sec. 5.1, Akenine-Möller et al.). With
/// `cast = false` (a convex mesh, or shadows off) no ray is cast and only the local tests apply.
#[inline]
pub fn visibility(geometry: &Geometry, s: &SurfaceSample, l: Vec3, cast: bool) -> Visibility {
    if s.normal.dot(l) <= 0.0 {
        return Visibility::BelowHorizon;
    }
    if s.facet_normal.dot(l) <= 0.0 {
        return Visibility::FacetBlocked;
    }
    if !cast {
        return Visibility::Lit { ray: false };
    }
    let ray = Ray::new(s.position + s.facet_normal * geometry.bias, l);
    if geometry.accel.occluded(&ray) {
        Visibility::Shadowed
    } else {
        Visibility::Lit { ray: true }
    }
}

/// One rendered image: the radiance under one light and what produced it, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct LightImage {
    /// `L_o` of Eq. 9, noise included.
    pub radiance: Vec<Rgb>,
    /// Raw ground-truth BRDF value `f(x, l, v)` wherever both directions are above the shading horizon
    /// (also in cast shadow), 0 elsewhere: the reference of the BRDF-space metric.
    pub brdf: Vec<Rgb>,
    /// `I_s · [cos θ_l > 0] · [cos θ_v > 0]`: the pixels that become training samples.
    pub lit: Vec<bool>,
}

/// Counts for one light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LightReport {
    /// Hits with the light below the shading horizon (no work).
    pub below_horizon: usize,
    /// Hits behind their own facet (no ray).
    pub facet_blocked: usize,
    /// Shadow rays cast.
    pub shadow_rays: usize,
    /// Shadow rays that hit the mesh.
    pub shadowed: usize,
    /// BRDF evaluations.
    pub brdf_evals: usize,
}

/// What the renderer simulated and what it skipped, and why.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderReport {
    /// Pixels (= primary rays cast).
    pub pixels: usize,
    /// Primary rays that hit the mesh; the rest get no further work.
    pub hits: usize,
    /// Hits seen from below their shading horizon (`cos θ_v ≤ 0`, near silhouettes): black, no BRDF call.
    pub view_below_horizon: usize,
    /// The mesh is closed and convex.
    pub convex: bool,
    /// Shadow rays were cast (the shadow pass ran).
    pub shadow_pass: bool,
    /// The noise pass ran (`σ > 0`).
    pub noise_pass: bool,
    /// Per light, in input order.
    pub lights: Vec<LightReport>,
}

impl RenderReport {
    /// Total shadow rays cast.
    pub fn shadow_rays(&self) -> usize {
        self.lights.iter().map(|l| l.shadow_rays).sum()
    }

    /// One line per effect: simulated or skipped, with the reason.
    pub fn summary(&self) -> String {
        let skipped_shadow = if self.shadow_pass {
            format!("shadow rays: {} cast, {} occluded", self.shadow_rays(), self.lights.iter().map(|l| l.shadowed).sum::<usize>())
        } else if self.convex {
            String::from("shadow rays: skipped (closed convex mesh: the facet test is exact)")
        } else {
            String::from("shadow rays: skipped (disabled)")
        };
        format!(
            "primary rays: {} ({} hit, {} missed: no work)\nshading: {} BRDF evaluations, {} light-below-horizon and {} facet-blocked pixels skipped, {} pixels seen below the horizon skipped\n{}\nnoise: {}",
            self.pixels,
            self.hits,
            self.pixels - self.hits,
            self.lights.iter().map(|l| l.brdf_evals).sum::<usize>(),
            self.lights.iter().map(|l| l.below_horizon).sum::<usize>(),
            self.lights.iter().map(|l| l.facet_blocked).sum::<usize>(),
            self.view_below_horizon,
            skipped_shadow,
            if self.noise_pass { "added" } else { "skipped (σ = 0)" },
        )
    }
}

/// A rendered view: its first hits, one image per light, and the report.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedView {
    /// First hits of the pixel rays.
    pub gbuffer: GBuffer,
    /// One image per light, in input order.
    pub images: Vec<LightImage>,
    /// What was simulated.
    pub report: RenderReport,
}

/// Renders one view under each light with Eq. 9. `brdf(sample, wi, wo)` returns `f` in 1/sr for local
/// directions (normal = `+z`, `wi` toward the light, `wo` toward the viewer), like every BRDF of the
/// crate; the sample carries the surface point for spatially varying materials.
pub fn render_view<F>(
    geometry: &Geometry,
    camera: &Camera,
    lights: &[DirectionalLight],
    brdf: F,
    options: &RenderOptions,
) -> RenderedView
where
    F: Fn(&SurfaceSample, Vec3, Vec3) -> Rgb + Sync,
{
    let gbuffer = GBuffer::cast(geometry, camera);
    let cast = match options.shadows {
        ShadowPass::Auto => !geometry.convex,
        ShadowPass::Force => true,
        ShadowPass::Off => false,
    };
    let n = gbuffer.samples.len();
    let view_below_horizon = gbuffer.samples.iter().flatten().filter(|s| s.normal.dot(s.view) <= 0.0).count();
    let results: Vec<(LightImage, LightReport)> = lights
        .par_iter()
        .enumerate()
        .map(|(li, light)| {
            let mut img = LightImage { radiance: vec![[0.0; 3]; n], brdf: vec![[0.0; 3]; n], lit: vec![false; n] };
            let mut rep = LightReport::default();
            for (p, s) in gbuffer.samples.iter().enumerate() {
                let Some(s) = s else { continue };
                let vis = visibility(geometry, s, light.direction, cast);
                match vis {
                    Visibility::BelowHorizon => {
                        rep.below_horizon += 1;
                        continue;
                    }
                    Visibility::FacetBlocked => rep.facet_blocked += 1,
                    Visibility::Shadowed => {
                        rep.shadow_rays += 1;
                        rep.shadowed += 1
                    }
                    Visibility::Lit { ray } => rep.shadow_rays += ray as usize,
                }
                let frame = s.frame();
                let (wi, wo) = (frame.to_local(light.direction), frame.to_local(s.view));
                if wo.z <= 0.0 {
                    continue;
                }
                let f = nbrdf::math::sanitize(brdf(s, wi, wo));
                rep.brdf_evals += 1;
                img.brdf[p] = f;
                if let Visibility::Lit { .. } = vis {
                    img.lit[p] = true;
                    let c = wi.z;
                    img.radiance[p] = core::array::from_fn(|k| f[k] * light.intensity[k] * c);
                }
            }
            if options.noise_sigma > 0.0 {
                add_noise(&mut img.radiance, options.noise_sigma, options.seed, li as u64);
            }
            (img, rep)
        })
        .collect();
    let (images, light_reports) = results.into_iter().unzip();
    let report = RenderReport {
        pixels: n,
        hits: gbuffer.hits(),
        view_below_horizon,
        convex: geometry.convex,
        shadow_pass: cast,
        noise_pass: options.noise_sigma > 0.0,
        lights: light_reports,
    };
    RenderedView { gbuffer, images, report }
}

/// Adds `N(0, σ²)` to every channel of every pixel (Sec. 5.3), then clamps at 0 as a sensor would, so
/// that the tone mapping of Eq. 10 stays defined. Stream `stream` of ChaCha8 seeded with `seed` makes
/// the result independent of thread scheduling and platform.
pub fn add_noise(radiance: &mut [Rgb], sigma: f32, seed: u64, stream: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let Ok(normal) = rand_distr::Normal::new(0.0f32, sigma) else { return }; // σ non-finite: nothing to add
    for px in radiance {
        for c in px.iter_mut() {
            *c = (*c + normal.sample(&mut rng)).max(0.0);
        }
    }
}
