//! Training observations from a data set (semi-synthetic or DiLiGenT-MV): the dataset's lit, unshadowed
//! pixels with the position input the model asks for (Sec. 4.2), and the per-vertex table that goes into
//! the exported model so a renderer can evaluate it on the mesh.

use std::path::Path;

use crate::dataset::{samples, DataArgs, Split};
use crate::intrinsic::IntrinsicEncoding;
use crate::models::PositionEncoding;
use crate::observations::Observations;
use crate::{Error, Result};

/// Most training pixels loaded from a data set (the paper's sets hold ~12 million).
pub const MAX_TRAINING_PIXELS: usize = 100_000_000;
/// Bytes a training pixel takes while loading (samples and observations), an upper estimate.
const BYTES_PER_PIXEL: f64 = 200.0;
/// Most values of a per-vertex intrinsic table (vertices × k): 1 GB of f32.
pub const MAX_TABLE_VALUES: usize = 1 << 28;

/// What `fit` trains on.
pub struct TrainingData {
    /// The observations, directions in the local shading frame.
    pub obs: Observations,
    /// Per-vertex intrinsic encoding for the model file; `None` for the other position inputs.
    pub position_table: Option<PositionTable>,
}

/// The per-vertex position input a model file carries, and the mesh it belongs to.
#[derive(Clone, Debug)]
pub struct PositionTable {
    /// `n_vertices × k`, row-major.
    pub values: Vec<f32>,
    /// [`nbrdf_scene::scene::Mesh::content_hash`] of the mesh (as loaded for the fit), recorded in the file
    /// so that a renderer refuses the table on another mesh.
    pub mesh_hash: u64,
}

/// Most masked pixels of the training split whose rays may miss the mesh before `fit` refuses the
/// data set: a tenth (a mask a pixel wider than the silhouette misses a few percent at most).
pub const MAX_MISSED_SHARE: f64 = 0.1;
/// Most masked pixels of one training view that may miss: half (a camera facing away misses all).
pub const MAX_MISSED_SHARE_PER_VIEW: f64 = 0.5;
/// Above this share of misses `fit` warns with the count.
pub const WARN_MISSED_SHARE: f64 = 0.01;

/// Warns when masked pixels' rays miss the mesh, and refuses the data set when too many do
/// ([`MAX_MISSED_SHARE`], [`MAX_MISSED_SHARE_PER_VIEW`]): its cameras, mesh or masks disagree, and
/// the pixels that remain would be trained on silently.
fn check_coverage(coverage: &[crate::dataset::Coverage], args: &DataArgs) -> Result<()> {
    let masked: usize = coverage.iter().map(|c| c.masked).sum();
    let missed: usize = coverage.iter().map(|c| c.missed).sum();
    let share = |missed: usize, masked: usize| missed as f64 / masked.max(1) as f64;
    let worst = coverage.iter().max_by(|a, b| share(a.missed, a.masked).total_cmp(&share(b.missed, b.masked)));
    let (Some(worst), true) = (worst, missed > 0) else { return Ok(()) };
    let source = match (&args.dataset, &args.diligent) {
        (Some(d), _) => d.join("dataset.json").display().to_string(),
        (None, Some(d)) => format!("{} ({})", d.display(), args.object),
        (None, None) => "the data set".into(),
    };
    let what = format!(
        "{source}: {missed} of the {masked} masked training pixels miss the mesh (view {} misses {} of {})",
        worst.view, worst.missed, worst.masked
    );
    if share(missed, masked) > MAX_MISSED_SHARE || share(worst.missed, worst.masked) > MAX_MISSED_SHARE_PER_VIEW {
        return Err(Error::Invalid(format!(
            "{what}; at most {:.0} % overall and {:.0} % of a view may: check the cameras (K, R, t), the mesh and the masks",
            100.0 * MAX_MISSED_SHARE,
            100.0 * MAX_MISSED_SHARE_PER_VIEW
        )));
    }
    if share(missed, masked) > WARN_MISSED_SHARE {
        eprintln!("warning: {what}; those pixels are not trained on");
    }
    Ok(())
}

/// Loads the training split of `args` and attaches the position input:
/// - `Uniform`: none;
/// - `Extrinsic`: the hit point in the unit sphere (the model encodes it);
/// - `Intrinsic { k }`: the `k` first non-constant Laplace–Beltrami eigenfunctions, each scaled to unit
///   range over the mesh (Koestler et al.'s default), interpolated barycentrically at the hit. The
///   eigenpairs are cached per mesh in `cache_dir`.
pub fn load(args: &DataArgs, position: PositionEncoding, cache_dir: &Path) -> Result<TrainingData> {
    let ds = args.open()?;
    let stride = args.pixel_stride.max(1);
    // Memory bounded before any image is read: every masked pixel of every training image, at most.
    let most: usize = ds
        .views
        .iter()
        .filter(|v| v.split == Split::Train)
        .map(|v| v.mask.iter().filter(|m| **m).count().div_ceil(stride) * v.images.len())
        .sum();
    if most > MAX_TRAINING_PIXELS {
        return Err(Error::Invalid(format!(
            "the data set has up to {most} training pixels (masked pixels × lights / --pixel-stride {stride}), \
             ~{:.0} GB in memory; at most {MAX_TRAINING_PIXELS}: raise --pixel-stride",
            most as f64 * BYTES_PER_PIXEL / 1e9
        )));
    }
    if let PositionEncoding::Intrinsic { k } = position {
        let values = ds.geometry.mesh.positions.len() * k as usize;
        if values > MAX_TABLE_VALUES {
            return Err(Error::Invalid(format!(
                "--position intrinsic:{k} on a mesh of {} vertices: {values} table values; at most {MAX_TABLE_VALUES}",
                ds.geometry.mesh.positions.len()
            )));
        }
    }
    let s = samples(&ds, Split::Train, stride)?;
    check_coverage(&s.coverage, args)?;
    if s.is_empty() {
        return Err(Error::Invalid("the data set's training split has no lit, unshadowed pixels".into()));
    }
    let (values, n_position, table) = match position {
        PositionEncoding::Uniform => (Vec::new(), 0, None),
        PositionEncoding::Extrinsic { .. } => (s.position.iter().flatten().copied().collect(), 3, None),
        PositionEncoding::Intrinsic { k } => {
            let k = k as usize;
            let mesh = &ds.geometry.mesh;
            let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
            let enc = IntrinsicEncoding::load_or_compute(cache_dir, &positions, &mesh.triangles, k)?;
            let table = enc.scaled_to_unit_range();
            let mut values = vec![0.0f32; s.len() * k];
            for (i, out) in values.chunks_exact_mut(k).enumerate() {
                let tri = mesh.triangles[s.triangle[i] as usize];
                let [b1, b2] = s.barycentric[i];
                let bary = [1.0 - b1 - b2, b1, b2];
                for (j, o) in out.iter_mut().enumerate() {
                    *o = (0..3).map(|c| bary[c] * table[tri[c] as usize * k + j]).sum();
                }
            }
            (values, k, Some(PositionTable { values: table, mesh_hash: mesh.content_hash() }))
        }
    };
    let obs = Observations::from_arrays(values, n_position, &s.wi, &s.wo, &s.intensity, &s.radiance)?;
    Ok(TrainingData { obs, position_table: table })
}
