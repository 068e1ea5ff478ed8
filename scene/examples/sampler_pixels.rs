//! What a sampler is worth in a rendered image: a sphere of a measured material under an environment
//! map, path-traced with the material's per-view sampling table, its single all-view proxy (the
//! sampler the table replaced) and cosine sampling, at equal time.
//!
//! ```text
//! cargo run --release -p nbrdf-scene --example sampler_pixels -- \
//!     --brdf json:../shared/data/nbrdf-merl/gold-metallic-paint.json --renders 8 --spp 16
//! ```
//!
//! Each sampler renders the same frame `--renders` times with different seeds, one render at a time,
//! the samplers taking turns (never two renders at once); the pixel variance is the variance of a
//! pixel's luminance over the renders, averaged over the frame, and the equal-time figure is that
//! variance times the mean seconds per render (what a fixed time budget leaves), relative to the
//! single proxy's. The environment is procedural (a sky gradient, a small sun and a bright window),
//! so that the BRDF's own sampling matters beside the environment's (the integrator combines both by
//! multiple importance sampling). docs/speed.md, "Sampling", has the method and the figures.

use clap::Parser;

use nbrdf::any::AnyBrdf;
use nbrdf_scene::image::RgbImage;
use nbrdf_scene::pathtrace::{render, Environment, Material, Options, Sampling, Scene};
use nbrdf_scene::scene::{builtin::BuiltinMesh, Camera, Geometry};

#[derive(Parser, Debug)]
#[command(about = "Pixel variance at equal time of the per-view sampling table, the single proxy and cosine sampling")]
struct Args {
    /// The material (any BRDF spec of `nbrdf::any`; a MERL table or NBRDF-json network for the comparison).
    #[arg(long)]
    brdf: String,
    /// Renders per sampler.
    #[arg(long, default_value_t = 8)]
    renders: u32,
    /// Samples per pixel of each render.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Image width and height.
    #[arg(long, default_value_t = 96)]
    size: u32,
    /// Surface vertices per path (1: direct lighting).
    #[arg(long, default_value_t = 2)]
    max_depth: u32,
}

/// A lat-long sky: a blue-to-white gradient over a dark ground, a small sun (radiance 2000, about
/// 1.5° across) and a bright window low in the sky.
fn environment() -> Result<Environment, String> {
    let (w, h) = (512u32, 256u32);
    let sun = nbrdf::Vec3::new(0.4, 0.75, -0.5).normalize();
    let window = nbrdf::Vec3::new(-0.8, 0.25, 0.3).normalize();
    let data = (0..w * h)
        .map(|i| {
            let d = nbrdf_scene::pathtrace::environment::from_uv([((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32]);
            let mut c = if d.y > 0.0 { [0.3 + 0.5 * (1.0 - d.y), 0.45 + 0.45 * (1.0 - d.y), 0.9] } else { [0.08, 0.07, 0.06] };
            if d.dot(sun) > 0.99991 {
                c = [2000.0, 1900.0, 1700.0];
            }
            if d.dot(window) > 0.995 {
                c = [40.0, 40.0, 38.0];
            }
            c
        })
        .collect();
    let image = RgbImage::from_data(w, h, data).map_err(|e| e.to_string())?;
    Environment::from_image(image).map_err(|e| e.to_string())
}

fn lum(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

fn main() -> Result<(), String> {
    let args = Args::parse();
    let geometry = Geometry::new(BuiltinMesh::Sphere.mesh()).map_err(|e| e.to_string())?;
    let env = environment()?;
    let camera = Camera::look_at(
        nbrdf::Vec3::new(0.0, 0.6, 3.4),
        nbrdf::Vec3::ZERO,
        nbrdf::Vec3::Y,
        40f32.to_radians(),
        args.size,
        args.size,
    )
    .map_err(|e| e.to_string())?;
    let brdf = std::sync::Arc::new(AnyBrdf::from_spec(&args.brdf).map_err(|e| format!("--brdf: {e}"))?);
    let samplers = [("per-view table", Sampling::Native), ("single proxy", Sampling::Proxy), ("cosine", Sampling::Cosine)];
    let materials: Vec<Material> =
        samplers.iter().map(|(_, s)| Material::new(brdf.clone()).map(|m| m.with_sampling(*s))).collect::<Result<_, _>>().map_err(|e| e.to_string())?;
    println!("{}: kernel level {}", materials[0].describe(), nbrdf::kernels::level().name());
    let n_pixels = (args.size * args.size) as usize;
    let mut sums = vec![(vec![0.0f64; n_pixels], vec![0.0f64; n_pixels], 0.0f64); samplers.len()];
    for r in 0..args.renders {
        for (k, material) in materials.iter().enumerate() {
            let scene = Scene { geometry: &geometry, material, lights: &[], env: Some(&env), camera: &camera };
            let options = Options { spp: args.spp, max_depth: args.max_depth, seed: 1 + r as u64, ..Options::default() };
            let out = render(&scene, &options, &|_| {});
            let (s, sq, t) = &mut sums[k];
            for (i, p) in out.image.data.iter().enumerate() {
                let l = lum(*p);
                s[i] += l;
                sq[i] += l * l;
            }
            *t += out.seconds;
        }
    }
    let n = args.renders as f64;
    let stats: Vec<(f64, f64)> = sums
        .iter()
        .map(|(s, sq, t)| {
            let var = s.iter().zip(sq).map(|(a, b)| (b / n - (a / n).powi(2)).max(0.0) * n / (n - 1.0)).sum::<f64>() / n_pixels as f64;
            (var, t / n)
        })
        .collect();
    let proxy = stats[1].0 * stats[1].1;
    println!("| sampler | s per render | mean pixel variance | equal-time variance vs single proxy |");
    println!("|---|---:|---:|---:|");
    for ((name, _), (var, secs)) in samplers.iter().zip(&stats) {
        println!("| {name} | {secs:.3} | {var:.4e} | {:.3} |", var * secs / proxy);
    }
    Ok(())
}
