//! Unidirectional path tracing (Kajiya 1986) with next-event estimation for directional lights and the
//! environment, multiple importance sampling of environment and BSDF samples with the power heuristic
//! (Veach 1997, Sec. 9.2.4, β = 2), Russian roulette (Arvo & Kirk 1990) and a bounce limit, over the
//! effects a [`Plan`] allows. Rows render in parallel (rayon); the random numbers are counter-based
//! ([`SampleRng`]), so an image depends only on the scene, the options and the seed.
//!
//! Random dimensions per pixel sample: 0–1 the pixel jitter, then per surface vertex `d` the six
//! dimensions from `2 + 6d`: environment sample (2), BSDF sample (3), Russian roulette (1). They are read
//! whether or not the plan uses them, so the skips of [`Plan::for_scene`] never shift a sequence.

use std::time::Instant;
use std::vec::Vec;

use rayon::prelude::*;

use super::environment::Environment;
use super::material::Material;
use super::plan::Plan;
use super::rng::SampleRng;
use nbrdf::brdf::Brdf;
use crate::image::RgbImage;
use crate::scene::render::{surface_sample, SurfaceSample};
use crate::scene::{Camera, DirectionalLight, Frame, Geometry, Ray};
use nbrdf::{Rgb, Vec3};

/// Everything that is rendered: one mesh with one material, lights, a camera.
pub struct Scene<'a> {
    /// The mesh with its BVH and convexity.
    pub geometry: &'a Geometry,
    /// Its material.
    pub material: &'a Material,
    /// Directional lights (may be empty).
    pub lights: &'a [DirectionalLight],
    /// The environment (or none).
    pub env: Option<&'a Environment>,
    /// The camera.
    pub camera: &'a Camera,
}

/// Most samples per pixel a front end accepts: beyond this a render takes days at any size.
pub const MAX_SPP: u32 = 1 << 20;
/// Most surface vertices per path a front end accepts.
pub const MAX_DEPTH: u32 = 1024;

/// Render settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Samples per pixel.
    pub spp: u32,
    /// Most surface vertices on a path (interreflecting scenes only).
    pub max_depth: u32,
    /// First vertex index at which Russian roulette may end a path.
    pub rr_depth: u32,
    /// Seed of the random numbers.
    pub seed: u64,
    /// Simulate every effect even where the scene cannot show it ([`Plan::everything`]).
    pub force_all: bool,
    /// Count only light that reached the camera over two or more surface vertices: the interreflected
    /// part, which an Eq. 9 (direct-only) render lacks.
    pub indirect_only: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options { spp: 16, max_depth: 8, rr_depth: 3, seed: 0, force_all: false, indirect_only: false }
    }
}

/// Work counters of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Pixel samples (paths) traced.
    pub paths: u64,
    /// Rays intersected with the scene: camera and continuation rays.
    pub rays: u64,
    /// Shadow rays.
    pub shadow_rays: u64,
    /// BRDF evaluations (sampling included).
    pub brdf_evals: u64,
}

impl core::ops::Add for Stats {
    type Output = Stats;
    fn add(self, o: Stats) -> Stats {
        Stats {
            paths: self.paths + o.paths,
            rays: self.rays + o.rays,
            shadow_rays: self.shadow_rays + o.shadow_rays,
            brdf_evals: self.brdf_evals + o.brdf_evals,
        }
    }
}

/// A rendered image with its per-pixel Monte Carlo error and what it cost.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Mean radiance per pixel.
    pub image: RgbImage,
    /// Variance of each pixel's mean (sample variance / spp), row-major.
    pub variance: Vec<Rgb>,
    /// The effects simulated.
    pub plan: Plan,
    /// Work done.
    pub stats: Stats,
    /// Wall-clock seconds of the pixel loop.
    pub seconds: f64,
}

impl Rendered {
    /// Paths per second of wall-clock time.
    pub fn samples_per_second(&self) -> f64 {
        self.stats.paths as f64 / self.seconds.max(1e-9)
    }
}

/// Power heuristic with β = 2 (Veach 1997, Eq. 9.13) for a sample of density `a` against `b`.
#[inline]
fn power(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

#[inline]
fn mul(a: Rgb, b: Rgb) -> Rgb {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

#[inline]
fn add_scaled(acc: &mut Rgb, v: Rgb, s: f32) {
    for c in 0..3 {
        acc[c] += v[c] * s;
    }
}

/// Renders the scene; `progress(rows)` is called as rows finish.
pub fn render(scene: &Scene, options: &Options, progress: &(dyn Fn(u64) + Sync)) -> Rendered {
    let g = scene.geometry;
    let plan = if options.force_all {
        Plan::everything(g.convex, scene.env.is_some(), options.max_depth)
    } else {
        Plan::for_scene(g.convex, scene.env.is_some(), scene.env.is_some_and(Environment::is_black), options.max_depth)
    };
    let (w, h) = (scene.camera.width, scene.camera.height);
    let spp = options.spp.max(1);
    let start = Instant::now();
    let rows: Vec<(Vec<Rgb>, Vec<Rgb>, Stats)> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut mean = Vec::with_capacity(w as usize);
            let mut var = Vec::with_capacity(w as usize);
            let mut stats = Stats::default();
            for col in 0..w {
                let pixel = row as u64 * w as u64 + col as u64;
                let (mut s1, mut s2) = ([0.0f64; 3], [0.0f64; 3]);
                for s in 0..spp {
                    let rng = SampleRng::new(options.seed, pixel, s as u64);
                    let ray = scene.camera.pixel_ray(col as f32 + rng.get(0) - 0.5, row as f32 + rng.get(1) - 0.5);
                    let l = trace(scene, &plan, options, ray, &rng, &mut stats);
                    for c in 0..3 {
                        s1[c] += l[c] as f64;
                        s2[c] += (l[c] as f64) * (l[c] as f64);
                    }
                }
                let n = spp as f64;
                let m = s1.map(|x| x / n);
                let v = core::array::from_fn(|c| {
                    if spp > 1 {
                        (((s2[c] / n - m[c] * m[c]).max(0.0)) * n / (n - 1.0) / n) as f32
                    } else {
                        0.0
                    }
                });
                mean.push(m.map(|x| x as f32));
                var.push(v);
            }
            progress(1);
            (mean, var, stats)
        })
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    let mut image = Vec::with_capacity((w * h) as usize);
    let mut variance = Vec::with_capacity((w * h) as usize);
    let mut stats = Stats::default();
    for (m, v, s) in rows {
        image.extend(m);
        variance.extend(v);
        stats = stats + s;
    }
    Rendered { image: RgbImage { width: w, height: h, data: image }, variance, plan, stats, seconds }
}

/// Whether a light in world direction `l` reaches the surface sample: above both the shading and the
/// facet plane (a direction behind the hit facet is blocked by it, as in the Eq. 9 renderer), and, where
/// the plan casts shadow rays, not occluded.
#[inline]
fn unoccluded(g: &Geometry, s: &SurfaceSample, l: Vec3, plan: &Plan, stats: &mut Stats) -> bool {
    if s.normal.dot(l) <= 0.0 || s.facet_normal.dot(l) <= 0.0 {
        return false;
    }
    if !plan.shadow_rays {
        return true;
    }
    stats.shadow_rays += 1;
    !g.accel.occluded(&Ray::new(s.position + s.facet_normal * g.bias, l))
}

/// Radiance along one camera ray.
fn trace(scene: &Scene, plan: &Plan, options: &Options, camera_ray: Ray, rng: &SampleRng, stats: &mut Stats) -> Rgb {
    let g = scene.geometry;
    let m = scene.material;
    stats.paths += 1;
    stats.rays += 1;
    let mut radiance: Rgb = [0.0; 3];
    let mut beta: Rgb = [1.0; 3];
    let mut dir = camera_ray.dir.normalize();
    let mut hit = surface_sample(g, &camera_ray);
    // Density of the BSDF sample that produced `dir`; `None` for the camera ray (no MIS).
    let mut bsdf_pdf: Option<f32> = None;
    let mut depth = 0u32;
    loop {
        // Light arriving at vertex `depth` reaches the camera over `depth + 1` vertices.
        let counts = !options.indirect_only || depth >= 1;
        let Some(s) = hit else {
            // Escaped: the environment, MIS-weighted against environment sampling (light that left
            // the vertex before, `depth - 1`).
            if let (Some(env), true) = (scene.env, !options.indirect_only || depth >= 2) {
                let le = env.eval(dir);
                let w = match bsdf_pdf {
                    Some(p) if plan.env_sampling => power(p, env.pdf(dir)),
                    _ => 1.0,
                };
                add_scaled(&mut radiance, mul(beta, le), w);
            }
            break;
        };
        let base = 2 + 6 * depth;
        let frame = Frame::from_normal(s.normal);
        let wo = frame.to_local(-dir);
        if wo.z <= 0.0 {
            break; // seen from below the shading horizon: black, as in the Eq. 9 renderer
        }
        let pt = m.point(&g.mesh, s.hit.triangle, s.hit.b1, s.hit.b2, s.position);
        // Next-event estimation: directional lights (delta: no MIS).
        for light in scene.lights.iter().filter(|_| counts) {
            if unoccluded(g, &s, light.direction, plan, stats) {
                let wi = frame.to_local(light.direction);
                let f = pt.eval(wi, wo);
                stats.brdf_evals += 1;
                add_scaled(&mut radiance, mul(mul(beta, f), light.intensity), wi.z);
            }
        }
        // Next-event estimation: the environment, MIS with the BSDF's density.
        if let (true, true, Some(env)) = (counts, plan.env_sampling, scene.env) {
            if let Some(ls) = env.sample([rng.get(base), rng.get(base + 1)]) {
                if unoccluded(g, &s, ls.dir, plan, stats) {
                    let wi = frame.to_local(ls.dir);
                    let f = pt.eval(wi, wo);
                    let w = power(ls.pdf, pt.pdf(wi, wo));
                    stats.brdf_evals += 1;
                    add_scaled(&mut radiance, mul(mul(beta, f), ls.radiance), wi.z * w / ls.pdf);
                }
            }
        }
        if !plan.bsdf_sampling {
            break;
        }
        // Continue the path by sampling the BSDF.
        let Some(bs) = pt.sample(wo, [rng.get(base + 2), rng.get(base + 3), rng.get(base + 4)]) else { break };
        stats.brdf_evals += 1;
        let wi_world = frame.to_world(bs.wi);
        if s.facet_normal.dot(wi_world) <= 0.0 {
            break; // into the hit facet itself
        }
        beta = mul(beta, bs.weight);
        if beta.iter().all(|&b| b <= 0.0) {
            break;
        }
        depth += 1;
        if depth >= options.rr_depth {
            let q = beta.iter().fold(0.0f32, |a, &b| a.max(b)).min(0.95);
            if rng.get(base + 5) >= q {
                break;
            }
            beta = beta.map(|b| b / q);
        }
        dir = wi_world.normalize();
        bsdf_pdf = Some(bs.pdf);
        let ray = Ray::new(s.position + s.facet_normal * g.bias, dir);
        hit = if plan.interreflections {
            stats.rays += 1;
            surface_sample(g, &ray)
        } else {
            None // convex: the ray leaves the object for good
        };
        if hit.is_some() && depth >= plan.max_depth {
            break; // bounce limit
        }
    }
    nbrdf::math::sanitize(radiance)
}
