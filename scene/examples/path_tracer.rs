//! Path-traces one mesh with any BRDF of `nbrdf`: parametric, built-in, MERL, NBRDF-json or a fitted
//! `.nbrdf` model, under directional lights and an environment (EXR lat-long map or a constant colour).
//! The renderer is `nbrdf_scene::pathtrace`; this file is its command line.
//!
//! ```text
//! cargo run --release -p nbrdf-scene --example path_tracer -- --mesh sphere --brdf json:../shared/data/nbrdf-merl/chrome-steel.json \
//!     --env-color 1,1,1 --spp 64 --width 128 --height 128 --out chrome.exr
//! ```
//!
//! It prints which effects the scene calls for (and which it skips), the material's sampler, and the
//! paths per second of the run. Writes `--out` as OpenEXR and the same image as an sRGB PNG beside it.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};

use nbrdf_scene::pathtrace::{render, Environment, Material, Options, Sampling, Scene, MAX_DEPTH, MAX_SPP};
use nbrdf_scene::scene::{builtin::BuiltinMesh, Camera, DirectionalLight, Geometry, Mesh};
use nbrdf::{AnyBrdf, Error, Vec3};

#[derive(Parser, Debug)]
#[command(about = "Path-trace a mesh with a parametric, measured or neural BRDF")]
struct Args {
    /// Mesh: `sphere`, `torus`, `grooved`, or an OBJ/PLY file (scaled into the unit sphere).
    #[arg(long, default_value = "sphere")]
    mesh: String,
    /// BRDF spec (the grammar of `nbrdf::any`): `lambert:R,G,B`, `phong:KD×3,KS×3,N`,
    /// `torrance-sparrow:KD×3,KS×3,ALPHA`, `fmbrdf:…`, `disney:…`, `raw:KIND:V,...` (raw network outputs
    /// of any parametric kind), `builtin:ID`, `merl:FILE.binary`, `json:FILE.json`, `model:FILE.nbrdf`,
    /// or a file whose extension says which.
    #[arg(long, default_value = "lambert:0.8,0.8,0.8")]
    brdf: String,
    /// `native` (own lobes or fitted per-view table), `cosine`, or `proxy` (a fitted BRDF's single
    /// all-view proxy, the sampler the per-view table replaced).
    #[arg(long, default_value = "native")]
    sampling: String,
    /// Camera position.
    #[arg(long, default_value = "0,0.6,3.4", value_parser = parse_vec3)]
    eye: Vec3,
    /// Point the camera looks at.
    #[arg(long, default_value = "0,0,0", value_parser = parse_vec3)]
    target: Vec3,
    /// Up direction.
    #[arg(long, default_value = "0,1,0", value_parser = parse_vec3)]
    up: Vec3,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 40.0)]
    fov: f32,
    #[arg(long, default_value_t = 128)]
    width: u32,
    #[arg(long, default_value_t = 128)]
    height: u32,
    /// Directional light `DX,DY,DZ` or `DX,DY,DZ:R,G,B` (toward the light; repeatable).
    #[arg(long)]
    light: Vec<String>,
    /// Environment map: lat-long OpenEXR, `+y` up.
    #[arg(long, conflicts_with = "env_color")]
    env: Option<PathBuf>,
    /// Constant environment radiance `R,G,B` (1,1,1 with a white Lambertian is the furnace test).
    #[arg(long, value_parser = parse_vec3)]
    env_color: Option<Vec3>,
    /// Samples per pixel (1..=1048576).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Most surface vertices per path (where interreflections are simulated); 1..=1024, 1 is direct
    /// lighting only.
    #[arg(long, default_value_t = 8)]
    max_depth: u32,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Simulate every effect even where the scene cannot show it.
    #[arg(long)]
    force_all: bool,
    /// Output OpenEXR; a PNG is written beside it (the same path with `.png`). Both paths are checked
    /// before rendering.
    #[arg(long, default_value = "render.exr")]
    out: PathBuf,
    /// Exposure scale of the PNG: finite and > 0 (the EXR is written unscaled).
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
}

fn parse_floats(s: &str, n: usize, what: &str) -> Result<Vec<f32>, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("{what}: `{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("{what}: expected {n} comma-separated numbers, got {}", v.len()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(format!("{what}: numbers must be finite"));
    }
    Ok(v)
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v = parse_floats(s, 3, "vector")?;
    Ok(Vec3::new(v[0], v[1], v[2]))
}

fn mesh_of(spec: &str) -> Result<Mesh, String> {
    if let Some(b) = BuiltinMesh::from_id(spec) {
        return Ok(b.mesh());
    }
    let mesh = Mesh::load(spec).map_err(|e| format!("mesh `{spec}`: {e}"))?;
    Ok(mesh.normalized().0)
}

fn brdf_of(spec: &str) -> Result<Material, String> {
    AnyBrdf::from_spec(spec).and_then(Material::new).map_err(|e| e.to_string())
}

fn light_of(spec: &str) -> Result<DirectionalLight, String> {
    let named = |e: String| format!("--light {spec}: {e}");
    let (d, c) = spec.split_once(':').unwrap_or((spec, "1,1,1"));
    let dir = parse_vec3(d).map_err(|e| named(format!("direction {e}")))?;
    let c = parse_floats(c, 3, "intensity").map_err(named)?;
    if c.iter().any(|x| *x < 0.0) {
        return Err(named("intensity must be ≥ 0".into()));
    }
    DirectionalLight::new(dir, [c[0], c[1], c[2]]).ok_or_else(|| named("zero direction".into()))
}

fn run(args: Args) -> Result<(), String> {
    nbrdf::kernels::requested().map_err(|e| e.to_string())?;
    let mesh = mesh_of(&args.mesh)?;
    let n_tris = mesh.triangles.len();
    let geometry = Geometry::new(mesh).map_err(|e| format!("--mesh {}: {e}", args.mesh))?;
    let sampling = match args.sampling.as_str() {
        "native" => Sampling::Native,
        "cosine" => Sampling::Cosine,
        "proxy" => Sampling::Proxy,
        s => return Err(format!("--sampling `{s}`: expected native, cosine or proxy")),
    };
    // Every size, number and output is checked before any work.
    if args.spp == 0 || args.spp > MAX_SPP {
        return Err(format!("--spp {}: allowed 1..={MAX_SPP} samples per pixel", args.spp));
    }
    if args.max_depth == 0 || args.max_depth > MAX_DEPTH {
        return Err(format!("--max-depth {}: allowed 1..={MAX_DEPTH} surface vertices (1: direct lighting only)", args.max_depth));
    }
    // A negative or zero scale has no image to show (every pixel black), NaN none at all.
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        return Err(format!("--exposure {}: must be finite and > 0", args.exposure));
    }
    let png = args.out.with_extension("png");
    if png == args.out {
        return Err(format!("--out {}: the PNG beside it would take the same name; give a .exr path", args.out.display()));
    }
    check_writable(&args.out).map_err(|e| format!("--out {}: {e}", args.out.display()))?;
    check_writable(&png).map_err(|e| format!("--out {}: the PNG beside it, {}, {e}", args.out.display(), png.display()))?;
    let fit_start = std::time::Instant::now();
    let material = brdf_of(&args.brdf)?.with_sampling(sampling);
    let fit_secs = fit_start.elapsed().as_secs_f64();
    material.check_mesh(&geometry.mesh).map_err(|e| format!("--brdf on --mesh {}: {e}", args.mesh))?;
    let lights: Vec<DirectionalLight> = args.light.iter().map(|l| light_of(l)).collect::<Result<_, _>>()?;
    let env = match (&args.env, args.env_color) {
        (Some(p), _) => Some(Environment::load_exr(p).map_err(|e| format!("--env {}: {e}", p.display()))?),
        (None, Some(c)) if c.min_element() >= 0.0 => Some(Environment::Constant(c.to_array())),
        (None, Some(c)) => return Err(format!("--env-color {c}: radiance must be ≥ 0")),
        (None, None) => None,
    };
    if lights.is_empty() && env.is_none() {
        return Err(String::from("no light: give --light, --env or --env-color"));
    }
    if !(args.fov > 0.0 && args.fov < 180.0) {
        return Err(format!("--fov {}: must lie in (0, 180) degrees", args.fov));
    }
    // The flags a camera error is about: the pose's, or the image size's.
    let camera = Camera::look_at(args.eye, args.target, args.up, args.fov.to_radians(), args.width, args.height).map_err(|e| match e {
        Error::InvalidValue { what: "camera look-at", .. } => {
            format!("--eye {} --target {} --up {}: {e}", args.eye, args.target, args.up)
        }
        _ => format!("--width {} --height {}: {e}", args.width, args.height),
    })?;
    let scene = Scene { geometry: &geometry, material: &material, lights: &lights, env: env.as_ref(), camera: &camera };
    let options = Options { spp: args.spp, max_depth: args.max_depth, seed: args.seed, force_all: args.force_all, ..Options::default() };

    println!("mesh: {} ({n_tris} triangles, {})", args.mesh, if geometry.convex { "closed convex" } else { "not convex" });
    println!("material: {} (set up in {:.3} s)", material.describe(), fit_secs);
    let bar = ProgressBar::new(args.height as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} rows  {elapsed} (eta {eta})").unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let out = render(&scene, &options, &|n| bar.inc(n));
    bar.finish_and_clear();
    println!("{}", out.plan.summary());
    println!(
        "{} paths in {:.3} s: {:.0} samples/s on {} threads ({} rays, {} shadow rays, {} BRDF evaluations)",
        out.stats.paths,
        out.seconds,
        out.samples_per_second(),
        rayon::current_num_threads(),
        out.stats.rays,
        out.stats.shadow_rays,
        out.stats.brdf_evals
    );
    write_both(&args.out, &png, &out.image, args.exposure)?;
    println!("wrote {} and {}", args.out.display(), png.display());
    Ok(())
}

/// Writes the EXR and the PNG under temporary names beside them, then renames both into place, so
/// that a failure of either leaves the earlier pair as it was.
fn write_both(exr: &Path, png: &Path, image: &nbrdf_scene::image::RgbImage, exposure: f32) -> Result<(), String> {
    let temp = |p: &Path| {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        p.with_file_name(format!("{}{name}", nbrdf::io::temp_prefix()))
    };
    let (exr_tmp, png_tmp) = (temp(exr), temp(png));
    let written = nbrdf_scene::image::write_exr(&exr_tmp, image)
        .and_then(|_| nbrdf_scene::image::write_png_srgb(&png_tmp, image, exposure))
        .map_err(|e| e.to_string())
        .and_then(|_| std::fs::rename(&exr_tmp, exr).map_err(|e| format!("{}: {e}", exr.display())))
        .and_then(|_| std::fs::rename(&png_tmp, png).map_err(|e| format!("{}: {e}", png.display())));
    std::fs::remove_file(&exr_tmp).ok();
    std::fs::remove_file(&png_tmp).ok();
    written
}

/// Fails unless `out` can be written: its folder exists and accepts a new file (probed and removed),
/// and `out` is no folder, so that a long render never ends in an unwritable path and no output is
/// replaced before every other one is known to be writable. The error says why, for the caller to name
/// the flag.
fn check_writable(out: &std::path::Path) -> Result<(), String> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!("the folder {} does not exist", dir.display()));
    }
    if out.is_dir() {
        return Err("is a folder".into());
    }
    tempfile::NamedTempFile::new_in(dir)
        .map(drop)
        .map_err(|e| format!("cannot write in {}: {e}", dir.display()))
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
