//! `trainer synth`: the semi-synthetic data set of Sec. 5.3.
//!
//! A mesh (normalised into the unit sphere) is seen from `views` cameras spread evenly on a sphere
//! around it (a Fibonacci lattice, turned by a seeded angle), alternately assigned to training and
//! test; each view is lit by directional lights drawn uniformly from the hemisphere facing its camera.
//! Every image is rendered with Eq. 9, gets Gaussian noise of σ, and is written with its raw BRDF
//! values and its lit mask; `dataset.json` describes it all. Same arguments and seed, same bytes.
//! With `--interreflections SPP`, each image also gets the light that bounces between parts of the
//! mesh, path traced (`nbrdf_scene::pathtrace`), added before the noise and written on its own.

use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
use nbrdf_scene::image::{write_exr, write_png_mask, write_png_srgb, RgbImage};
use nbrdf_scene::pathtrace::{render as pt_render, Material as PtMaterial, Options as PtOptions, Scene as PtScene};
use nbrdf_scene::scene::render::{add_noise, render_view, LightImage, RenderOptions, RenderReport, ShadowPass};
use nbrdf_scene::scene::{Camera, DirectionalLight, Frame, Geometry};
use nbrdf::{Error, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::material::MaterialSpec;
use crate::staging::StagedDir;
use super::spec::{self, Counts, DatasetFile, ExposureSpec, ImageSpec, LightSpec, NormalizationSpec, ViewSpec, SATURATED};
use super::{load_mesh, mesh_spec, Split};

/// Arguments of `synth` (paper defaults, Sec. 5.3).
#[derive(Debug, Clone, clap::Args)]
pub struct SynthArgs {
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Mesh: a built-in id (sphere, torus, grooved) or an OBJ/PLY file.
    #[arg(long, default_value = "sphere")]
    pub mesh: String,
    /// Ground-truth material: a built-in id (two-lobe-metal, clear-coat, velvet), a MERL .binary file,
    /// an NBRDF-json .json file (e.g. ../shared/data/nbrdf-merl/chrome.json), or lambert:R,G,B.
    #[arg(long, default_value = "two-lobe-metal")]
    pub material: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Views on the sphere around the object.
    #[arg(long, default_value_t = 20)]
    pub views: usize,
    /// How many of them are training views (the rest are test views).
    #[arg(long, default_value_t = 10)]
    pub train_views: usize,
    /// Lights per training view.
    #[arg(long, default_value_t = 30)]
    pub train_lights: usize,
    /// Lights per test view.
    #[arg(long, default_value_t = 12)]
    pub test_lights: usize,
    /// Standard deviation of the Gaussian noise on the HDR radiance.
    #[arg(long, default_value_t = 1e-3)]
    pub sigma: f32,
    /// Seed of cameras, lights and noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 40.0)]
    pub fov: f32,
    /// Light intensity L_i (all channels).
    #[arg(long, default_value_t = 1.0, conflicts_with = "target_median")]
    pub light_intensity: f32,
    /// Instead of --light-intensity: choose the intensity so that the median luminance of the
    /// object's lit pixels is this (0.1-0.3 looks like a well-exposed capture), but dimmer where that
    /// would saturate more than [`MAX_SATURATED`] of them, as a photographer exposes a glossy object:
    /// for its body, letting the highlights clip. Measured on a noise-free probe of four of the views.
    #[arg(long)]
    pub target_median: Option<f32>,
    /// Add the light that interreflects (two or more surface vertices), path traced with this many
    /// samples per pixel per image, to the Eq. 9 direct light; 0: direct light only (the paper's data).
    /// Only a mesh that sees itself has any; each image also gets its interreflected part alone.
    #[arg(long, default_value_t = 0)]
    pub interreflections: u32,
    /// Cast shadow rays even on a convex mesh (they change nothing; for checking).
    #[arg(long)]
    pub force_shadows: bool,
    /// Print what the renderer simulated and skipped for each view.
    #[arg(long)]
    pub verbose: bool,
    /// Draw no progress bar (the Python package passes it where stderr is no terminal, e.g. in a
    /// notebook, whose server may still have one).
    #[arg(long)]
    pub quiet: bool,
}

impl SynthArgs {
    /// The paper's defaults writing to `out`.
    pub fn new(out: impl Into<PathBuf>) -> Self {
        // The defaults are clap's, declared once on the fields above.
        #[derive(clap::Parser)]
        struct Defaults {
            #[command(flatten)]
            args: SynthArgs,
        }
        let mut args = <Defaults as clap::Parser>::try_parse_from(["synth", "--out", "."]).expect("the defaults parse").args;
        args.out = out.into();
        args
    }

    /// Checks every size and number before any work, with the flags named as on the command line.
    pub fn check(&self) -> crate::Result<()> {
        self.check_as(&|key| format!("--{}", key.replace('_', "-")))
    }

    /// [`check`](Self::check) with the fields named by `name` (a flag for the command line, a config
    /// file and key for the study): each error says the field, its value and what is allowed.
    pub fn check_as(&self, name: &dyn Fn(&str) -> String) -> crate::Result<()> {
        let bad = |key: &str, value: &dyn std::fmt::Display, allowed: String| Error::Context {
            what: format!("{} {value}", name(key)),
            message: allowed,
        };
        if self.size == 0 || self.size > MAX_SIZE {
            return Err(crate::Error::from(bad("size", &self.size, format!("allowed 1..={MAX_SIZE} pixels per side"))));
        }
        // Sizes are checked before anything is allocated or written: an absurd count is an error
        // naming the field, never an allocation abort hours in.
        for (key, v) in [("views", self.views), ("train_lights", self.train_lights), ("test_lights", self.test_lights)] {
            if v > MAX_COUNT {
                return Err(crate::Error::from(bad(key, &v, format!("at most {MAX_COUNT}"))));
            }
        }
        if self.interreflections > nbrdf_scene::pathtrace::MAX_SPP {
            let max = nbrdf_scene::pathtrace::MAX_SPP;
            return Err(crate::Error::from(bad("interreflections", &self.interreflections, format!("at most {max} samples per pixel"))));
        }
        if self.views == 0 {
            return Err(crate::Error::from(bad("views", &0, "need at least one view".into())));
        }
        if self.train_views > self.views {
            return Err(crate::Error::from(bad("train_views", &self.train_views, format!("at most the {} views", self.views))));
        }
        // A data set without training images fits nothing; test views without lights score nothing.
        if self.train_views == 0 {
            return Err(crate::Error::from(bad("train_views", &0, format!("allowed 1..={} (the views)", self.views))));
        }
        if self.train_lights == 0 {
            return Err(crate::Error::from(bad("train_lights", &0, format!("allowed 1..={MAX_COUNT}: a training view needs an image"))));
        }
        let test_views = self.views - self.train_views;
        if test_views > 0 && self.test_lights == 0 {
            return Err(crate::Error::from(bad(
                "test_lights",
                &0,
                format!("allowed 1..={MAX_COUNT} with {test_views} test views (give as many training views as views for none)"),
            )));
        }
        let images = self.train_views * self.train_lights + test_views * self.test_lights;
        if images > MAX_IMAGES {
            return Err(crate::Error::from(Error::Context {
                what: format!("{images} images (training views × {} + test views × {})", name("train_lights"), name("test_lights")),
                message: format!("at most {MAX_IMAGES} images"),
            }));
        }
        let bytes = images as f64 * (self.size as f64).powi(2) * BYTES_PER_PIXEL;
        if bytes > MAX_BYTES {
            return Err(crate::Error::from(Error::Context {
                what: format!("{images} images of {size}×{size} pixels ({})", name("size"), size = self.size),
                message: format!("~{:.0} GB bytes on disk (12 per pixel), at most {:.0} GB", bytes / 1e9, MAX_BYTES / 1e9),
            }));
        }
        if !(self.sigma.is_finite() && self.sigma >= 0.0) {
            return Err(crate::Error::from(bad("sigma", &self.sigma, "must be finite and non-negative".into())));
        }
        if !(self.fov > 0.0 && self.fov < 180.0) {
            return Err(crate::Error::from(bad("fov", &self.fov, "must lie in (0, 180) degrees".into())));
        }
        if !(self.light_intensity.is_finite() && self.light_intensity > 0.0) {
            return Err(crate::Error::from(bad("light_intensity", &self.light_intensity, "must be finite and positive".into())));
        }
        if let Some(m) = self.target_median.filter(|m| !(m.is_finite() && *m > 0.0 && *m <= 100.0)) {
            return Err(crate::Error::from(bad("target_median", &m, "must lie in (0, 100]".into())));
        }
        Ok(())
    }
}

/// Most pixels per image side.
pub const MAX_SIZE: u32 = 16_384;
/// Most views, and most lights per view.
pub const MAX_COUNT: usize = 10_000;
/// Most images in a data set.
pub const MAX_IMAGES: usize = 200_000;
/// Bytes a pixel takes on disk, a generous estimate (RGB f32 EXR before compression).
const BYTES_PER_PIXEL: f64 = 12.0;
/// Most bytes a data set may take on disk.
const MAX_BYTES: f64 = 200e9;

/// `splitmix64` finaliser (Steele et al. 2014): decorrelated per-view seeds from one seed.
fn mix(seed: u64, salt: u64) -> u64 {
    let mut z = seed.wrapping_add(salt.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Unit directions of a Fibonacci lattice (González 2010, "Measurement of areas on a sphere using
/// Fibonacci and latitude–longitude lattices"), turned about `z` by `phase`.
pub fn fibonacci_sphere(n: usize, phase: f32) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = phase + golden * i as f32;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// `train` views spread evenly among `n`: view `i` trains when `⌊(i+1)T/n⌋ > ⌊iT/n⌋`.
pub fn split_of(i: usize, train: usize, n: usize) -> Split {
    if (i + 1) * train / n > i * train / n { Split::Train } else { Split::Test }
}

/// `count` lights uniform over the hemisphere around `toward_camera` (solid-angle uniform:
/// `cos θ` uniform in `(0, 1]`).
pub fn hemisphere_lights(rng: &mut ChaCha8Rng, toward_camera: Vec3, count: usize, intensity: f32) -> Vec<DirectionalLight> {
    let frame = Frame::from_normal(toward_camera);
    (0..count)
        .map(|_| {
            let z = 1.0 - rng.random::<f32>();
            let phi = std::f32::consts::TAU * rng.random::<f32>();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = frame.to_world(Vec3::new(r * phi.cos(), r * phi.sin(), z));
            // `z > 0` and a unit frame: never zero.
            DirectionalLight::new(d, [intensity; 3]).expect("unit direction")
        })
        .collect()
}

/// Rec. 709 luminance of linear RGB.
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Longest side of the calibration probe: the median needs the object's shading, not its detail.
const PROBE_SIZE: u32 = 96;

/// Views the calibration probe renders.
const PROBE_VIEWS: usize = 4;

/// Share of the object's lit pixels a calibrated exposure lets saturate at most. A photographer
/// exposes a glossy object for its body and lets the highlights clip, since saturated pixels are
/// left out of the comparison; past a tenth of the lit surface, the body itself would clip.
pub const MAX_SATURATED: f32 = 0.10;

/// The light intensity that gives the object's lit pixels (those that return light, [`returns_light`])
/// a median luminance of `target` over the probe's images (noise-free, [`PROBE_VIEWS`] views of at
/// most [`PROBE_SIZE`]² pixels), or the dimmer one that saturates [`MAX_SATURATED`] of them: rendering
/// is linear in the intensity, so one probe at intensity 1 fixes both. Metering the lit pixels only
/// keeps a specular object, black wherever no highlight falls, from being refused or blown out.
fn calibrate_intensity(
    geometry: &Geometry,
    probes: &[(Camera, Vec<DirectionalLight>)],
    material: &super::material::Material,
    target: f32,
) -> crate::Result<f32> {
    let options = RenderOptions { noise_sigma: 0.0, ..RenderOptions::default() };
    let mut lit: Vec<[f32; 3]> = Vec::new();
    for (camera, lights) in probes {
        let unit: Vec<DirectionalLight> =
            lights.iter().filter_map(|l| DirectionalLight::new(l.direction, [1.0; 3])).collect();
        let probe = render_view(geometry, camera, &unit, |_, wi, wo| material.eval(wi, wo), &options);
        lit.extend(
            probe.images.iter().flat_map(|im| (0..im.lit.len()).filter(|&p| returns_light(im, p)).map(|p| im.radiance[p])),
        );
    }
    if lit.is_empty() {
        return Err(crate::Error::from(Error::Context {
            what: "--target-median".into(),
            message: "no object pixel receives light (a black material, or the mesh is not in view)".into(),
        }));
    }
    // Meter the body: the lit pixels' median luminance maps to the target.
    let median = ExposureSpec::median(&mut lit.iter().map(|c| luminance(*c)).collect::<Vec<_>>());
    // Clip at most MAX_SATURATED of them: the brightest channel at the (1 - MAX_SATURATED) quantile maps to SATURATED.
    let mut peak: Vec<f32> = lit.iter().map(|c| c[0].max(c[1]).max(c[2])).collect();
    let q = (((1.0 - MAX_SATURATED) * peak.len() as f32) as usize).min(peak.len() - 1);
    let bright = *peak.select_nth_unstable_by(q, f32::total_cmp).1;
    Ok((target / median).min(SATURATED / bright))
}

/// Whether pixel `p` is lit and its material sends some of that light to the camera (noise-free): the
/// pixels exposure is metered on. A mirror-like material is black at the others, as in a capture.
fn returns_light(img: &LightImage, p: usize) -> bool {
    img.lit[p] && luminance(img.brdf[p]) > 0.0
}

/// Lit object pixels sampled per image for the exposure statistics (a stride over them).
const STATS_PER_IMAGE: usize = 4096;

/// Renders and writes the data set; returns its description and one render report per view.
pub fn synthesize(args: &SynthArgs) -> crate::Result<(DatasetFile, Vec<RenderReport>)> {
    args.check()?;
    let cwd = std::env::current_dir().map_err(|e| Error::io(".", &e))?;
    let mut mesh_spec = mesh_spec(&args.mesh);
    if let spec::MeshSpec::File { path } = &mut mesh_spec {
        *path = std::fs::canonicalize(&*path).map_err(|e| Error::io(&*path, &e))?;
    }
    let material_spec = MaterialSpec::parse(&args.material)?.canonical()?;
    let material = material_spec.load(&cwd)?;
    let (mesh, norm) = load_mesh(&mesh_spec, &cwd)?;
    let geometry = Geometry::new(mesh).map_err(|e| e.context(format!("--mesh {}", args.mesh)))?;

    // Everything goes into a folder beside --out, which replaces --out only once complete: an
    // interrupted or failed run leaves the previous data set as it was.
    let staged = StagedDir::new(&args.out, "data set", holds_only_a_data_set)?;
    let out = staged.path();
    let n = args.views;
    let fov = args.fov.to_radians();
    let distance = 1.15 / (0.5 * fov).sin();
    let mut rng = ChaCha8Rng::seed_from_u64(mix(args.seed, 0));
    let dirs = fibonacci_sphere(n, std::f32::consts::TAU * rng.random::<f32>());
    let total: usize = (0..n)
        .map(|i| match split_of(i, args.train_views, n) {
            Split::Train => args.train_lights,
            Split::Test => args.test_lights,
        })
        .sum();
    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(total as u64) };
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} images, {elapsed} (eta {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message("synth");
    crate::progress::start(0, total as u64);

    // Meshes in OBJ files are mostly y-up: keep world +y up in the image where possible.
    let camera_of = |d: Vec3, size: u32| {
        let up = if d.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        Camera::look_at(d * distance, Vec3::ZERO, up, fov, size, size)
    };
    let lights_of = |i: usize, d: Vec3, intensity: f32| {
        let count = if split_of(i, args.train_views, n) == Split::Train { args.train_lights } else { args.test_lights };
        let mut light_rng = ChaCha8Rng::seed_from_u64(mix(args.seed, 1 + i as u64));
        hemisphere_lights(&mut light_rng, d, count, intensity)
    };
    let intensity = match args.target_median {
        None => args.light_intensity,
        Some(target) => {
            // A few views spread over the set: one view's highlights are not the object's.
            let count = PROBE_VIEWS.min(n);
            let probes = (0..count)
                .map(|k| {
                    let i = k * n / count;
                    Ok((camera_of(dirs[i], PROBE_SIZE.min(args.size))?, lights_of(i, dirs[i], 1.0)))
                })
                .collect::<crate::Result<Vec<_>>>()?;
            calibrate_intensity(&geometry, &probes, &material, target)?
        }
    };
    // The path tracer's copy of the material, for the interreflected light.
    let traced = if args.interreflections > 0 { Some(material.path_traced()?) } else { None };
    let mut luminances = Vec::new();
    let (mut saturated, mut lit_pixels) = (0usize, 0usize);

    let mut views = Vec::with_capacity(n);
    let mut reports = Vec::with_capacity(n);
    for (i, d) in dirs.iter().enumerate() {
        let split = split_of(i, args.train_views, n);
        let camera = camera_of(*d, args.size)?;
        let lights = lights_of(i, *d, intensity);
        let count = lights.len();
        let options = RenderOptions {
            shadows: if args.force_shadows { ShadowPass::Force } else { ShadowPass::Auto },
            // With interreflections, the noise goes on the sum of both parts, below.
            noise_sigma: if args.interreflections > 0 { 0.0 } else { args.sigma },
            seed: mix(args.seed, 10_000 + i as u64),
        };
        let mut rendered = render_view(&geometry, &camera, &lights, |_, wi, wo| material.eval(wi, wo), &options);
        let indirect = match &traced {
            Some(m) => {
                let parts = interreflected(&geometry, &camera, &lights, m, args.interreflections, mix(args.seed, 20_000 + i as u64));
                for (li, (img, part)) in rendered.images.iter_mut().zip(&parts).enumerate() {
                    for (r, q) in img.radiance.iter_mut().zip(part) {
                        *r = core::array::from_fn(|c| r[c] + q[c]);
                    }
                    if args.sigma > 0.0 {
                        add_noise(&mut img.radiance, args.sigma, options.seed, li as u64);
                    }
                }
                rendered.report.noise_pass = args.sigma > 0.0;
                Some(parts)
            }
            None => None,
        };
        let dir_rel = PathBuf::from(format!("views/{i:02}"));
        let dir = out.join(&dir_rel);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, &e))?;
        let mask: Vec<bool> = rendered.gbuffer.samples.iter().map(Option::is_some).collect();
        write_png_mask(dir.join("mask.png"), args.size, args.size, &mask)?;
        for img in &rendered.images {
            let lit: Vec<usize> = (0..mask.len()).filter(|&p| returns_light(img, p)).collect();
            let stride = lit.len().div_ceil(STATS_PER_IMAGE).max(1);
            saturated += lit.iter().filter(|&&p| img.radiance[p].iter().any(|&c| c >= SATURATED)).count();
            lit_pixels += lit.len();
            luminances.extend(lit.iter().step_by(stride).map(|&p| luminance(img.radiance[p])));
        }
        let mut images = Vec::with_capacity(count);
        for (li, (light, img)) in lights.iter().zip(&rendered.images).enumerate() {
            crate::cancel::check_core()?;
            let radiance = dir_rel.join(format!("{li:03}.exr"));
            let brdf = dir_rel.join(format!("{li:03}_brdf.exr"));
            let lit = dir_rel.join(format!("{li:03}_lit.png"));
            let rad_img = RgbImage::from_data(args.size, args.size, img.radiance.clone())?;
            write_exr(out.join(&radiance), &rad_img)?;
            write_exr(out.join(&brdf), &RgbImage::from_data(args.size, args.size, img.brdf.clone())?)?;
            write_png_mask(out.join(&lit), args.size, args.size, &img.lit)?;
            let indirect = match &indirect {
                Some(parts) => {
                    let path = dir_rel.join(format!("{li:03}_indirect.exr"));
                    write_exr(out.join(&path), &RgbImage::from_data(args.size, args.size, parts[li].clone())?)?;
                    Some(path)
                }
                None => None,
            };
            if li == 0 {
                write_png_srgb(dir.join("preview.png"), &rad_img, 1.0)?;
            }
            images.push(ImageSpec {
                light: LightSpec { direction: light.direction.to_array(), intensity: light.intensity },
                radiance,
                brdf,
                lit,
                indirect,
            });
            bar.inc(1);
            crate::progress::advance();
        }
        if args.verbose {
            bar.suspend(|| eprintln!("view {i:02} ({split:?}):\n{}", rendered.report.summary()));
        }
        views.push(ViewSpec {
            split,
            k: spec::rows(camera.k),
            r: spec::rows(camera.r),
            t: camera.t.to_array(),
            mask: dir_rel.join("mask.png"),
            images,
        });
        reports.push(rendered.report);
    }
    bar.finish();
    let file = DatasetFile {
        format: spec::FORMAT.into(),
        version: spec::VERSION,
        mesh: mesh_spec,
        normalization: NormalizationSpec { center: norm.center.to_array(), scale: norm.scale },
        material: material_spec,
        width: args.size,
        height: args.size,
        noise_sigma: args.sigma,
        seed: args.seed,
        counts: Counts {
            views: n,
            train_views: args.train_views,
            test_views: n - args.train_views,
            train_lights: args.train_lights,
            test_lights: args.test_lights,
        },
        views,
        exposure: Some(ExposureSpec {
            light_intensity: intensity,
            median_luminance: ExposureSpec::median(&mut luminances),
            saturated_share: saturated as f64 / lit_pixels.max(1) as f64,
        }),
    };
    file.validate()?;
    file.write(out)?;
    staged.commit()?;
    Ok((file, reports))
}

/// The interreflected radiance of each light's image (light over two or more surface vertices, the
/// part an Eq. 9 render lacks), path traced with `spp` samples per pixel; all black on a convex mesh.
fn interreflected(geometry: &Geometry, camera: &Camera, lights: &[DirectionalLight], material: &PtMaterial, spp: u32, seed: u64) -> Vec<Vec<[f32; 3]>> {
    lights
        .iter()
        .enumerate()
        .map(|(li, light)| {
            let scene = PtScene { geometry, material, lights: std::slice::from_ref(light), env: None, camera };
            let options = PtOptions { spp, seed: mix(seed, li as u64), indirect_only: true, ..PtOptions::default() };
            pt_render(&scene, &options, &|_| {}).image.data
        })
        .collect()
}

/// Whether `dir` holds nothing but what `synth` writes (so replacing it whole loses nothing else).
fn holds_only_a_data_set(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries.flatten().all(|e| matches!(e.file_name().to_str(), Some("dataset.json" | "views")))
    })
}

/// `trainer synth`: renders, then prints where it went and what was simulated.
pub fn run(args: &SynthArgs) -> crate::Result<DatasetFile> {
    let (file, reports) = synthesize(args)?;
    let shadow_rays: usize = reports.iter().map(|r| r.shadow_rays()).sum();
    let images: usize = file.views.iter().map(|v| v.images.len()).sum();
    println!("wrote {} views, {images} images to {}", file.views.len(), display(&args.out));
    if let Some(r) = reports.first() {
        println!("view 00:\n{}", r.summary());
    }
    println!("shadow rays in all views: {shadow_rays}");
    if let Some(e) = &file.exposure {
        println!(
            "light intensity {:.4}: median luminance of the lit object pixels {:.3}, {:.2}% of them saturated (a channel >= {SATURATED})",
            e.light_intensity,
            e.median_luminance,
            100.0 * e.saturated_share
        );
    }
    Ok(file)
}

fn display(p: &Path) -> String {
    p.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_has_the_paper_defaults_of_the_command_line() {
        let a = SynthArgs::new("data");
        assert_eq!(a.out, PathBuf::from("data"));
        // Sec. 5.3: 20 views, 10 of them training views with 30 lights each, 12 lights per test view, σ 1e-3.
        assert_eq!((a.size, a.views, a.train_views, a.train_lights, a.test_lights), (256, 20, 10, 30, 12));
        assert_eq!((a.sigma, a.light_intensity, a.target_median), (1e-3, 1.0, None));
        assert_eq!((a.mesh.as_str(), a.material.as_str()), ("sphere", "two-lobe-metal"));
        a.check().unwrap();
    }
}
