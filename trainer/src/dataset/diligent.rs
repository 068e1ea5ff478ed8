//! The DiLiGenT-MV reader (Li et al. 2020, "Multi-view photometric stereo: a robust solution and
//! benchmark dataset for spatially varying isotropic materials"), as the paper uses it (Sec. 5.3).
//!
//! Layout read: `mvpmsData/<object>PNG/` with
//! - `Calib_Results.mat` (MATLAB v5): `KK` (3x3 intrinsics) and, per view `i = 1..`, `Rc_i` (3x3) and
//!   `Tc_i` (3x1) mapping world to camera, `Xc = Rc·Xw + Tc` (Bouguet's toolbox, OpenCV axes);
//! - `mesh_Gt.ply`: the ground-truth mesh, in the world frame of the calibration (not normalised);
//! - `view_01/ …`: `001.png …` (16-bit linear RGB), `mask.png`, `light_directions.txt` (one light per
//!   line, camera frame with `x` right, `y` up, `z` toward the camera) and `light_intensities.txt` (RGB
//!   per line; the images are divided by it per channel, so every light has intensity 1).
//!
//! Split (the paper does not give one): odd-numbered views (`view_01`, `view_03`, …) train, even ones
//! test; every light of a view is used.

use std::path::{Path, PathBuf};

use glam::Mat3;
use nbrdf_scene::scene::{Camera, DirectionalLight, Geometry, Mesh};
use nbrdf::{Error, Vec3};

use super::{err, Dataset, ImageRef, ImageSource, Split, View};

/// The five objects.
pub const OBJECTS: [&str; 5] = ["bear", "buddha", "cow", "pot2", "reading"];

/// Calibration of one object: shared intrinsics and per-view extrinsics.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// `KK`.
    pub k: Mat3,
    /// `Rc_1, Rc_2, …`.
    pub r: Vec<Mat3>,
    /// `Tc_1, Tc_2, …`.
    pub t: Vec<Vec3>,
}

/// The object folder: `root/mvpmsData/<object>PNG` or `root/<object>PNG`.
pub fn object_dir(root: &Path, object: &str) -> crate::Result<PathBuf> {
    if !OBJECTS.contains(&object) {
        return Err(crate::Error::from(err("DiLiGenT-MV object", format!("unknown object '{object}' (known: {})", OBJECTS.join(", ")))));
    }
    let name = format!("{object}PNG");
    for dir in [root.join("mvpmsData").join(&name), root.join(&name)] {
        if dir.is_dir() {
            return Ok(dir);
        }
    }
    Err(crate::Error::from(Error::io(root.join("mvpmsData").join(&name), &std::io::Error::from(std::io::ErrorKind::NotFound))))
}

fn mat_array(mat: &matfile::MatFile, path: &Path, name: &str, rows: usize, cols: usize) -> crate::Result<Vec<f32>> {
    let what = || path.display().to_string();
    let a = mat.find_by_name(name).ok_or_else(|| Error::Parse { what: what(), message: format!("no variable {name}") })?;
    if a.size() != &vec![rows, cols] {
        return Err(crate::Error::from(Error::Parse { what: what(), message: format!("{name} is {:?}, expected {rows}x{cols}", a.size()) }));
    }
    let v: Vec<f32> = match a.data() {
        matfile::NumericData::Double { real, .. } => real.iter().map(|&x| x as f32).collect(),
        matfile::NumericData::Single { real, .. } => real.clone(),
        _ => return Err(crate::Error::from(Error::Parse { what: what(), message: format!("{name} is not a floating-point array") })),
    };
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(crate::Error::from(Error::NonFinite { what: "Calib_Results.mat entry", index: i }));
    }
    Ok(v)
}

/// Reads `KK`, `Rc_i`, `Tc_i` for `i = 1..=views` (MATLAB stores matrices column-major, as glam does).
pub fn read_calibration(path: &Path, views: usize) -> crate::Result<Calibration> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
    let mat = matfile::MatFile::parse(std::io::BufReader::new(file))
        .map_err(|e| Error::Parse { what: path.display().to_string(), message: e.to_string() })?;
    let k = Mat3::from_cols_slice(&mat_array(&mat, path, "KK", 3, 3)?);
    let mut r = Vec::with_capacity(views);
    let mut t = Vec::with_capacity(views);
    for i in 1..=views {
        r.push(Mat3::from_cols_slice(&mat_array(&mat, path, &format!("Rc_{i}"), 3, 3)?));
        t.push(Vec3::from_slice(&mat_array(&mat, path, &format!("Tc_{i}"), 3, 1)?));
    }
    Ok(Calibration { k, r, t })
}

/// Reads a whitespace-separated table of `cols` numbers per non-empty line.
pub fn read_table(path: &Path, cols: usize) -> crate::Result<Vec<Vec<f32>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, &e))?;
    let mut rows = Vec::new();
    for (ln, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let row: Vec<f32> = line
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| Error::Parse { what: path.display().to_string(), message: format!("line {}: {e}", ln + 1) })?;
        if row.len() != cols || !row.iter().all(|x| x.is_finite()) {
            return Err(crate::Error::from(Error::Parse {
                what: path.display().to_string(),
                message: format!("line {}: expected {cols} finite numbers, found {}", ln + 1, row.len()),
            }));
        }
        rows.push(row);
    }
    Ok(rows)
}

/// A light direction given in DiLiGenT's camera frame (x right, y up, z toward the camera) in world
/// coordinates: `Rᵀ · diag(1, -1, -1) · l`, the flip taking it to the OpenCV camera axes.
///
/// ```
/// use trainer::dataset::diligent::light_to_world;
/// use nbrdf::Vec3;
/// // With R = I the camera looks along world +z, so a light "toward the camera" points along world -z.
/// let l = light_to_world(glam::Mat3::IDENTITY, Vec3::new(0.0, 0.0, 1.0));
/// assert_eq!(l, Vec3::new(0.0, 0.0, -1.0));
/// ```
pub fn light_to_world(r: Mat3, l_cam: Vec3) -> Vec3 {
    r.transpose() * Vec3::new(l_cam.x, -l_cam.y, -l_cam.z)
}

/// Opens one object of a DiLiGenT-MV copy.
pub fn open(root: &Path, object: &str) -> crate::Result<Dataset> {
    let dir = object_dir(root, object)?;
    let mut view_dirs: Vec<PathBuf> = (1..)
        .map(|i| dir.join(format!("view_{i:02}")))
        .take_while(|d| d.is_dir())
        .collect();
    if view_dirs.is_empty() {
        return Err(crate::Error::from(err("DiLiGenT-MV", format!("{} has no view_01 folder", dir.display()))));
    }
    view_dirs.shrink_to_fit();
    let calib = read_calibration(&dir.join("Calib_Results.mat"), view_dirs.len())?;
    let mesh = Mesh::load(dir.join("mesh_Gt.ply"))?;
    let geometry = Geometry::new(mesh)?;
    let mut views = Vec::with_capacity(view_dirs.len());
    for (vi, vd) in view_dirs.iter().enumerate() {
        let (w, h, mask) = nbrdf_scene::image::read_mask(vd.join("mask.png"))?;
        let camera = Camera::new(w, h, calib.k, calib.r[vi], calib.t[vi])?;
        let dirs = read_table(&vd.join("light_directions.txt"), 3)?;
        let ints = read_table(&vd.join("light_intensities.txt"), 3)?;
        if dirs.len() != ints.len() {
            return Err(crate::Error::from(Error::SizeMismatch {
                what: "DiLiGenT-MV light_intensities.txt lines (vs light_directions.txt)",
                expected: dirs.len(),
                found: ints.len(),
            }));
        }
        let mut images = Vec::with_capacity(dirs.len());
        for (li, (d, c)) in dirs.iter().zip(&ints).enumerate() {
            let path = vd.join(format!("{:03}.png", li + 1));
            if !path.is_file() {
                return Err(crate::Error::from(Error::io(&path, &std::io::Error::from(std::io::ErrorKind::NotFound))));
            }
            if !c.iter().all(|x| *x > 0.0) {
                return Err(crate::Error::from(err("DiLiGenT-MV light intensity", format!("{} line {}: must be positive", vd.display(), li + 1))));
            }
            let direction = light_to_world(calib.r[vi], Vec3::new(d[0], d[1], d[2]));
            let light = DirectionalLight::new(direction, [1.0; 3])
                .ok_or_else(|| err("DiLiGenT-MV light direction", format!("{} line {}: zero", vd.display(), li + 1)))?;
            images.push(ImageRef {
                light,
                source: ImageSource::DiligentPng { path, intensity: [c[0], c[1], c[2]] },
                brdf: None,
            });
        }
        let split = if vi % 2 == 0 { Split::Train } else { Split::Test };
        views.push(View { camera, split, mask, images });
    }
    Ok(Dataset { geometry, views, description: None, dir: None, truth: Default::default() })
}
