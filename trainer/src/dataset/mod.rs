//! Data sets for the fits (Sec. 5.3): the semi-synthetic renderer (`synth`), its reader, the
//! DiLiGenT-MV reader, and the training samples both turn into.
//!
//! Both kinds load into one in-memory form, [`Dataset`]: a mesh prepared for ray casting, and views
//! (a camera, a split, an object mask and images, each with its directional light). Images stay on
//! disk until [`samples()`] reads them, one at a time, keeping only lit, unshadowed pixels.

pub mod diligent;
pub mod material;
pub mod samples;
pub mod spec;
pub mod synth;

use std::path::{Path, PathBuf};

use nbrdf_scene::image::RgbImage;
use nbrdf_scene::scene::builtin::BuiltinMesh;
use nbrdf_scene::scene::{Camera, DirectionalLight, Geometry, Mesh};
use nbrdf::Error;
use serde::{Deserialize, Serialize};

pub use samples::{samples, Coverage, Samples};

/// A parse-style error with a free message.
pub(crate) fn err(what: &str, message: impl ToString) -> Error {
    Error::Parse { what: what.to_string(), message: message.to_string() }
}

/// Which part of the data set a view belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Fitted on.
    Train,
    /// Held out for the evaluation.
    Test,
}

/// Where an image's radiance comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ImageSource {
    /// Linear HDR OpenEXR (semi-synthetic data).
    Exr(PathBuf),
    /// DiLiGenT-MV 16-bit PNG: code values / 65535, then divided per channel by the light intensity.
    DiligentPng {
        /// The PNG.
        path: PathBuf,
        /// Calibrated RGB intensity of its light.
        intensity: [f32; 3],
    },
}

/// One image of a view.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRef {
    /// Its light; the radiance is in units where this light has intensity `light.intensity`.
    pub light: DirectionalLight,
    /// Radiance file.
    pub source: ImageSource,
    /// Raw ground-truth BRDF values, where known (semi-synthetic data).
    pub brdf: Option<PathBuf>,
}

impl ImageRef {
    /// The radiance file.
    pub fn path(&self) -> &Path {
        match &self.source {
            ImageSource::Exr(p) | ImageSource::DiligentPng { path: p, .. } => p,
        }
    }

    /// Reads the radiance (linear RGB).
    pub fn load(&self) -> crate::Result<RgbImage> {
        match &self.source {
            ImageSource::Exr(p) => Ok(nbrdf_scene::image::read_exr(p)?),
            ImageSource::DiligentPng { path, intensity } => {
                let mut img = nbrdf_scene::image::read_png(path)?;
                for px in &mut img.data {
                    for k in 0..3 {
                        px[k] /= intensity[k];
                    }
                }
                Ok(img)
            }
        }
    }
}

/// One posed view.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Its camera.
    pub camera: Camera,
    /// Training or test.
    pub split: Split,
    /// Object mask, row-major; only these pixels can become samples.
    pub mask: Vec<bool>,
    /// Its images.
    pub images: Vec<ImageRef>,
}

/// A data set in memory.
#[derive(Debug)]
pub struct Dataset {
    /// The mesh, its BVH and convexity.
    pub geometry: Geometry,
    /// The views.
    pub views: Vec<View>,
    /// The description, for semi-synthetic data sets.
    pub description: Option<spec::DatasetFile>,
    /// The folder the description's relative paths start from.
    pub dir: Option<PathBuf>,
    /// The ground-truth material once loaded: every evaluation of a scene reads it.
    truth: std::sync::OnceLock<Option<material::Material>>,
}

/// Resolves `--mesh`: a built-in id, or an OBJ/PLY path.
pub fn mesh_spec(arg: &str) -> spec::MeshSpec {
    match BuiltinMesh::from_id(arg) {
        Some(m) => spec::MeshSpec::Builtin { id: m.id().into() },
        None => spec::MeshSpec::File { path: PathBuf::from(arg) },
    }
}

/// Loads the mesh of a spec (relative paths against `base`) and normalises file meshes into the unit
/// sphere.
pub fn load_mesh(spec: &spec::MeshSpec, base: &Path) -> crate::Result<(Mesh, nbrdf_scene::scene::Normalization)> {
    match spec {
        spec::MeshSpec::Builtin { id } => {
            let m = BuiltinMesh::from_id(id).ok_or_else(|| {
                err("mesh", format!("unknown built-in mesh '{id}' (known: sphere, torus, grooved)"))
            })?;
            Ok((m.mesh(), nbrdf_scene::scene::Normalization { center: nbrdf::Vec3::ZERO, scale: 1.0 }))
        }
        spec::MeshSpec::File { path } => {
            let p = if path.is_absolute() { path.clone() } else { base.join(path) };
            let mesh = Mesh::load(&p).map_err(|e| e.context(format!("mesh file {}", p.display())))?;
            Ok(mesh.normalized())
        }
    }
}

impl Dataset {
    /// Opens a semi-synthetic data set written by `synth`: reads and checks `dataset.json`, the mesh
    /// and every view's mask; radiance images are read later by [`samples()`].
    pub fn open(dir: &Path) -> crate::Result<Self> {
        let file = spec::DatasetFile::read(dir)?;
        let description = dir.join("dataset.json");
        let (mesh, _) = load_mesh(&file.mesh, dir)?;
        let geometry = Geometry::new(mesh).map_err(|e| e.context(format!("{}: mesh", description.display())))?;
        let mut views = Vec::with_capacity(file.views.len());
        for (i, v) in file.views.iter().enumerate() {
            let at = |field: &str| format!("{}: views[{i}].{field}", description.display());
            let camera = v.camera(file.width, file.height).map_err(|e| e.context(at("K/R/t (camera)")))?;
            let (w, h, mask) = nbrdf_scene::image::read_mask(dir.join(&v.mask))?;
            if (w, h) != (file.width, file.height) {
                return Err(crate::Error::from(err(
                    "data set mask",
                    format!("view {i}: {} is {w}x{h}, the description says {}x{}", v.mask.display(), file.width, file.height),
                )));
            }
            let images = v
                .images
                .iter()
                .enumerate()
                .map(|(j, im)| {
                    Ok(ImageRef {
                        light: im.light.light().map_err(|e| e.context(at(&format!("images[{j}].light ({})", im.radiance.display()))))?,
                        source: ImageSource::Exr(dir.join(&im.radiance)),
                        brdf: Some(dir.join(&im.brdf)),
                    })
                })
                .collect::<crate::Result<_>>()?;
            views.push(View { camera, split: v.split, mask, images });
        }
        Ok(Dataset { geometry, views, description: Some(file), dir: Some(dir.to_path_buf()), truth: Default::default() })
    }

    /// The ground-truth material of a semi-synthetic data set, which renders its noise-free (clean)
    /// reference images; `None` for captured data, which has only its images.
    /// Loaded once; a failed load is reported and tried again on the next call.
    pub fn ground_truth(&self) -> crate::Result<Option<&material::Material>> {
        if let Some(truth) = self.truth.get() {
            return Ok(truth.as_ref());
        }
        let loaded = match (&self.description, &self.dir) {
            (Some(d), Some(dir)) => Some(
                d.material
                    .load(dir)
                    .map_err(|e| e.context(format!("{}: the ground-truth material", dir.join("dataset.json").display())))?,
            ),
            _ => None,
        };
        Ok(self.truth.get_or_init(|| loaded).as_ref())
    }
}

/// Command-line choice of a data set, shared by every command that reads one.
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// A semi-synthetic data set folder (with `dataset.json`).
    #[arg(long, conflicts_with = "diligent", required_unless_present = "diligent")]
    pub dataset: Option<PathBuf>,
    /// A DiLiGenT-MV copy: the `mvpmsData` folder or the folder that holds it.
    #[arg(long)]
    pub diligent: Option<PathBuf>,
    /// DiLiGenT-MV object: bear, buddha, cow, pot2 or reading.
    #[arg(long, default_value = "bear")]
    pub object: String,
    /// Use every n-th masked pixel per image (1 = all).
    #[arg(long, default_value_t = 1)]
    pub pixel_stride: usize,
}

impl DataArgs {
    /// Loads the chosen data set.
    pub fn open(&self) -> crate::Result<Dataset> {
        match (&self.dataset, &self.diligent) {
            (Some(d), _) => Dataset::open(d),
            (None, Some(root)) => diligent::open(root, &self.object),
            (None, None) => Err(crate::Error::from(err("data set", "give --dataset DIR or --diligent PATH"))),
        }
    }
}

/// `trainer inspect`: loads a data set and prints its size and the samples of its training split.
pub fn inspect(args: &DataArgs) -> crate::Result<()> {
    if args.pixel_stride == 0 {
        return Err(crate::Error::from(err("--pixel-stride 0", "at least 1 (1 uses every masked pixel)")));
    }
    let ds = args.open()?;
    let train = ds.views.iter().filter(|v| v.split == Split::Train).count();
    println!(
        "mesh: {} vertices, {} triangles, {}",
        ds.geometry.mesh.positions.len(),
        ds.geometry.mesh.triangles.len(),
        if ds.geometry.convex { "convex" } else { "not convex" }
    );
    println!(
        "views: {} ({} train, {} test), images: {}",
        ds.views.len(),
        train,
        ds.views.len() - train,
        ds.views.iter().map(|v| v.images.len()).sum::<usize>()
    );
    let s = samples(&ds, Split::Train, args.pixel_stride)?;
    println!("training samples (lit, unshadowed pixels): {}", s.len());
    Ok(())
}
