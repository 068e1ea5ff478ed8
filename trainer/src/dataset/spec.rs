//! `dataset.json`: the one file that describes a semi-synthetic data set (mesh, material, cameras,
//! lights, split, noise, seed, and where every image lies), and its validation.

use std::path::{Path, PathBuf};

use nbrdf_scene::scene::{Camera, DirectionalLight};
use nbrdf::{Error, Vec3};
use serde::{Deserialize, Serialize};

use super::material::MaterialSpec;
use super::{err, Split};

/// Format tag written into every description.
pub const FORMAT: &str = "nbrdf-dataset";
/// Newest version this build reads and writes.
pub const VERSION: u32 = 1;

/// Where the mesh comes from; file meshes are normalised into the unit sphere like built-in ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum MeshSpec {
    /// A procedural mesh of `nbrdf_scene::scene::builtin`.
    Builtin {
        /// Its id (`sphere`, `torus`, `grooved`).
        id: String,
    },
    /// An OBJ or PLY file (absolute path, or relative to the description's folder).
    File {
        /// The file.
        path: PathBuf,
    },
}

/// The similarity that mapped the file mesh into the unit sphere.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NormalizationSpec {
    /// Bounding-box centre of the original mesh.
    pub center: [f32; 3],
    /// Scale applied after centring.
    pub scale: f32,
}

/// A directional light as stored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LightSpec {
    /// Unit world direction toward the light.
    pub direction: [f32; 3],
    /// RGB intensity `L_i`.
    pub intensity: [f32; 3],
}

/// One image: its light and files (relative to the description's folder).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageSpec {
    /// The light.
    pub light: LightSpec,
    /// Linear HDR radiance, OpenEXR.
    pub radiance: PathBuf,
    /// Raw ground-truth BRDF values `f(x, l, v)` (1/sr), OpenEXR.
    pub brdf: PathBuf,
    /// Lit, unshadowed pixels (`I_s · [cos θ_l > 0]`), 8-bit PNG.
    pub lit: PathBuf,
    /// The interreflected part of `radiance` (light over two or more surface vertices, without the
    /// noise; a path-traced estimate), OpenEXR; absent in a direct-only (Eq. 9) data set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indirect: Option<PathBuf>,
}

/// One view: a camera in the OpenCV convention and its images.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewSpec {
    /// Training or test view.
    pub split: Split,
    /// Intrinsics, row-major rows.
    #[serde(rename = "K")]
    pub k: [[f32; 3]; 3],
    /// World-to-camera rotation, row-major rows.
    #[serde(rename = "R")]
    pub r: [[f32; 3]; 3],
    /// World-to-camera translation.
    pub t: [f32; 3],
    /// Object mask (pixels whose ray hits the mesh), 8-bit PNG.
    pub mask: PathBuf,
    /// Images under each light.
    pub images: Vec<ImageSpec>,
}

/// Declared counts, checked against the lists so that a truncated or hand-edited file is caught.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    /// Views in all.
    pub views: usize,
    /// Training views.
    pub train_views: usize,
    /// Test views.
    pub test_views: usize,
    /// Images (lights) per training view.
    pub train_lights: usize,
    /// Images (lights) per test view.
    pub test_lights: usize,
}

/// The whole description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Format version.
    pub version: u32,
    /// The mesh.
    pub mesh: MeshSpec,
    /// How the mesh was normalised (identity for built-in meshes).
    pub normalization: NormalizationSpec,
    /// Ground-truth material.
    pub material: MaterialSpec,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Gaussian noise σ added to the radiance.
    pub noise_sigma: f32,
    /// Seed of cameras, lights and noise.
    pub seed: u64,
    /// Declared counts.
    pub counts: Counts,
    /// Views, in order.
    pub views: Vec<ViewSpec>,
    /// How bright the renders came out (absent in data sets written before it was recorded, and in
    /// captured ones).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure: Option<ExposureSpec>,
}

/// Radiance at which a channel counts as saturated: the top of the sRGB range the images are viewed
/// and scored in, where a camera's sensor would clip.
pub const SATURATED: f32 = 1.0;

/// The exposure of a rendered data set, over the object's pixels of every image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExposureSpec {
    /// Light intensity `L_i` every image was rendered with.
    pub light_intensity: f32,
    /// Median Rec. 709 luminance of the object's lit pixels (those a light reaches; noise included).
    pub median_luminance: f32,
    /// Share (0-1) of the object's lit pixels with a channel at or above [`SATURATED`].
    pub saturated_share: f64,
}

impl ExposureSpec {
    /// Median of `v` (NaN for none; the upper middle value for an even count).
    pub fn median(v: &mut [f32]) -> f32 {
        if v.is_empty() {
            return f32::NAN;
        }
        let m = v.len() / 2;
        *v.select_nth_unstable_by(m, f32::total_cmp).1
    }
}

pub(crate) fn rows(m: glam::Mat3) -> [[f32; 3]; 3] {
    let t = m.transpose();
    [t.x_axis.to_array(), t.y_axis.to_array(), t.z_axis.to_array()]
}

pub(crate) fn from_rows(r: [[f32; 3]; 3]) -> glam::Mat3 {
    glam::Mat3::from_cols(Vec3::from(r[0]), Vec3::from(r[1]), Vec3::from(r[2])).transpose()
}

impl ViewSpec {
    /// The camera of this view.
    pub fn camera(&self, width: u32, height: u32) -> crate::Result<Camera> {
        Ok(Camera::new(width, height, from_rows(self.k), from_rows(self.r), Vec3::from(self.t))?)
    }
}

impl LightSpec {
    /// The light (direction normalised; a zero direction is an error).
    pub fn light(&self) -> crate::Result<DirectionalLight> {
        if !self.intensity.iter().all(|c| c.is_finite() && *c >= 0.0) {
            let message = "must be finite and non-negative".to_string();
            return Err(crate::Error::from(Error::Context { what: format!("intensity {:?}", self.intensity), message }));
        }
        let light = DirectionalLight::new(Vec3::from(self.direction), self.intensity).ok_or_else(|| Error::Context {
            what: format!("direction {:?}", self.direction),
            message: "zero or non-finite".into(),
        })?;
        Ok(light)
    }
}

impl DatasetFile {
    /// Reads and validates `dir/dataset.json`.
    pub fn read(dir: &Path) -> crate::Result<Self> {
        let path = dir.join("dataset.json");
        let bytes = nbrdf::io::read_at_most(&path, crate::json::MAX_JSON_BYTES)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            Error::io(&path, &std::io::Error::new(std::io::ErrorKind::InvalidData, format!("stream did not contain valid UTF-8 ({e})")))
        })?;
        let file: DatasetFile = serde_json::from_str(&text)
            .map_err(|e| Error::Parse { what: path.display().to_string(), message: e.to_string() })?;
        file.validate().map_err(|e| match e {
            crate::Error::Core(Error::Parse { what, message }) => {
                crate::Error::Core(Error::Parse { what: format!("{} ({what})", path.display()), message })
            }
            other => other,
        })?;
        Ok(file)
    }

    /// Checks format, version and that the declared counts match the lists.
    pub fn validate(&self) -> crate::Result<()> {
        if self.format != FORMAT {
            return Err(crate::Error::from(err("format", format!("expected \"{FORMAT}\", found \"{}\"", self.format))));
        }
        if self.version != VERSION {
            return Err(crate::Error::from(Error::UnsupportedVersion { what: "nbrdf data set", found: self.version, supported: VERSION }));
        }
        if self.width == 0 || self.height == 0 {
            return Err(crate::Error::from(err("image size", "width and height must be positive")));
        }
        if !(self.noise_sigma.is_finite() && self.noise_sigma >= 0.0) {
            return Err(crate::Error::from(err("noise_sigma", "must be finite and non-negative")));
        }
        let c = &self.counts;
        let count_err = |what: &str, expected: usize, found: usize| {
            err("counts", format!("{what}: declared {expected}, found {found}"))
        };
        if self.views.len() != c.views {
            return Err(crate::Error::from(count_err("views", c.views, self.views.len())));
        }
        let train = self.views.iter().filter(|v| v.split == Split::Train).count();
        if train != c.train_views {
            return Err(crate::Error::from(count_err("train_views", c.train_views, train)));
        }
        if self.views.len() - train != c.test_views {
            return Err(crate::Error::from(count_err("test_views", c.test_views, self.views.len() - train)));
        }
        for (i, v) in self.views.iter().enumerate() {
            let expected = match v.split {
                Split::Train => c.train_lights,
                Split::Test => c.test_lights,
            };
            if v.images.len() != expected {
                return Err(crate::Error::from(count_err(&format!("images of view {i} ({:?})", v.split), expected, v.images.len())));
            }
        }
        Ok(())
    }

    /// Writes `dir/dataset.json` atomically.
    pub fn write(&self, dir: &Path) -> crate::Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::Parse { what: "data set description".into(), message: e.to_string() })?;
        Ok(nbrdf::io::write_atomic(&dir.join("dataset.json"), text.as_bytes())?)
    }
}
