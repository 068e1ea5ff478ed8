//! Evaluation of one fitted model on its scene's test views, through the core evaluator only (the
//! exported `.nbrdf`, as a renderer would use it):
//! - every test image is re-rendered with Eq. 9 (same camera, light and shadow visibility as the
//!   reference, no noise) and scored (PSNR, DSSIM, LPIPS, HDR-FLIP, object mask) against the clean
//!   reference where the data set has a ground truth — the same render of its material, so a perfect
//!   model scores +inf — and against the captured images otherwise; on semi-synthetic data the PSNR
//!   against the noisy capture is kept beside it, and [`ceiling`] scores the clean reference itself
//!   against the capture: the best any model can read there;
//! - the rendered BRDF values are compared with the stored raw ground-truth ones in cube-root RMSE, on
//!   lit pixels within the angle limit of [`brdf_rmse::keep`];
//! - reciprocity RMSE and the energy analysis use points and directions of the test samples;
//! - the evaluation cost is timed in-process on the reciprocity pairs: one query at a time (`eval`),
//!   and in batches of many directions at one point (`eval_many`).
//!
//! A file is held as it is ([`ModelBuf::from_bytes_as_is`]), so that an f16 file's timings are those
//! of its f16 rows (`ModelBuf::from_bytes` would widen it at load: the same values, at the f32 rows'
//! speed).

use std::time::Instant;

use nbrdf::ModelBuf;
use nbrdf_scene::image::{read_exr, RgbImage};
use nbrdf::model::{Model, Prepared};
use nbrdf_scene::scene::render::{render_view, RenderOptions, RenderedView, SurfaceSample};
use nbrdf_scene::scene::DirectionalLight;
use nbrdf::{Rgb, Vec3};
use serde::{Deserialize, Serialize};

use crate::dataset::material::Material;
use crate::dataset::{samples, Dataset, Split, View};
use crate::metrics::brdf_rmse::{self, CubeRootRmse};
use crate::metrics::energy::{self, EnergyConfig, EnergySummary, LightPair};
use crate::metrics::reciprocity::{reciprocity_rmse, DirectionPair};
use crate::metrics::{ImageMetrics, Lpips, PreparedReference};
use crate::{Error, Result};

/// What a model's test renderings were scored against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Reference {
    /// The noise-free Eq. 9 render of the data set's ground-truth material.
    Clean,
    /// The captured images: data without a ground truth (DiLiGenT-MV), and results written before
    /// clean references existed.
    #[default]
    Captured,
}

impl Reference {
    /// The word the report prints.
    pub fn name(self) -> &'static str {
        match self {
            Reference::Clean => "clean",
            Reference::Captured => "captured",
        }
    }
}

/// Everything measured on one fitted model.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evaluation {
    /// Image metrics averaged over the test images, against [`Evaluation::reference`].
    pub image: ImageMetrics,
    /// What [`Evaluation::image`] was scored against.
    #[serde(default)]
    pub reference: Reference,
    /// Mean PSNR (dB) against the captured (noisy) images, where `image` is against clean ones.
    #[serde(default)]
    pub captured_psnr: Option<f64>,
    pub brdf_rmse_cbrt: CubeRootRmse,
    pub reciprocity_rmse: f64,
    pub energy: EnergySummary,
    /// Mean nanoseconds per `eval` (one direction pair, point already prepared), single thread.
    pub eval_ns_per_query: f64,
    /// Mean nanoseconds per direction pair of `eval_many` (batches of [`BATCH`] pairs at one
    /// prepared point), single thread; absent in results written before it was measured.
    #[serde(default)]
    pub eval_batch_ns_per_query: Option<f64>,
    /// Mean nanoseconds per shading point of `prepare` (one point at a time) and of `prepare_many`
    /// (the energy samples' points at once), single thread: the per-point cost that `eval` adds to;
    /// absent in results written before they were measured.
    #[serde(default)]
    pub prepare_ns_per_point: Option<f64>,
    #[serde(default)]
    pub prepare_many_ns_per_point: Option<f64>,
}

/// Directions per batch of the batched timing: as a renderer shading many light or view samples at
/// one surface point.
pub const BATCH: usize = 256;

/// The model's point input at a surface point: the stored intrinsic table interpolated at the hit, the
/// normalised-mesh position, or nothing.
fn point_input(model: &Model<'_>, ds: &Dataset, tri: u32, b1: f32, b2: f32, position: Vec3) -> Vec<f32> {
    let k = model.position_len();
    if model.header().n_vertices > 0 {
        let mut out = vec![0.0; k];
        let t = ds.geometry.mesh.triangles[tri as usize];
        // Indices come from the same mesh the table was built on; a mismatch leaves zeros.
        model.position_features(t, [1.0 - b1 - b2, b1, b2], &mut out).ok();
        out
    } else if k == 3 {
        position.to_array().to_vec()
    } else {
        Vec::new()
    }
}

fn prepare_at(model: &Model<'_>, ds: &Dataset, s: &SurfaceSample) -> Prepared {
    // `point_input` has the model's length, so the fallback (black) is never taken.
    model.prepare(&point_input(model, ds, s.hit.triangle, s.hit.b1, s.hit.b2, s.position)).unwrap_or_default()
}

/// `view` re-rendered with `model` under `lights` (Eq. 9): the reference's camera and shadow
/// visibility, no noise.
fn render_with(model: &Model<'_>, ds: &Dataset, view: &View, lights: &[DirectionalLight]) -> RenderedView {
    render_view(&ds.geometry, &view.camera, lights, |s, wi, wo| model.eval(&prepare_at(model, ds, s), wi, wo), &RenderOptions::default())
}

/// The lights of every image of `view`, in order.
fn lights_of(view: &View) -> Vec<DirectionalLight> {
    view.images.iter().map(|im| im.light).collect()
}

/// The clean references of `view` under `lights`: the noise-free Eq. 9 render of the ground truth,
/// with the capture's camera and shadows.
fn render_truth(truth: &Material, ds: &Dataset, view: &View, lights: &[DirectionalLight]) -> Result<Vec<RgbImage>> {
    let rendered = render_view(&ds.geometry, &view.camera, lights, |_, wi, wo| truth.eval(wi, wo), &RenderOptions::default());
    let cam = &view.camera;
    let images = rendered.images.into_iter().map(|im| RgbImage::from_data(cam.width, cam.height, im.radiance));
    images.collect::<std::result::Result<Vec<_>, _>>().map_err(Error::Core)
}

/// PSNR (sRGB, masked to the object) of `test` against `reference`, both linear: the study's PSNR.
fn masked_psnr(reference: &RgbImage, test: &RgbImage, mask: &[bool]) -> f64 {
    crate::metrics::psnr::psnr(&crate::metrics::to_srgb(reference), &crate::metrics::to_srgb(test), Some(mask))
}

/// The best score any model can reach on the test split of `ds`: its clean reference scored
/// against the captured images (every image metric), or `None` for data without a ground truth.
pub fn ceiling(ds: &Dataset, lpips: &std::result::Result<Lpips, String>) -> Result<Option<ImageMetrics>> {
    let Some(truth) = ds.ground_truth()? else { return Ok(None) };
    let mut scores = Vec::new();
    for view in ds.views.iter().filter(|v| v.split == Split::Test) {
        let clean = render_truth(truth, ds, view, &lights_of(view))?;
        for (im, clean) in view.images.iter().zip(&clean) {
            let captured = im.load()?;
            scores.push(PreparedReference::new(&captured, Some(&view.mask), lpips).evaluate(clean));
        }
    }
    Ok((!scores.is_empty()).then(|| ImageMetrics::mean(&scores)))
}

/// Evaluates the model file `model_path` on the test split of `ds` (see the module docs).
pub fn evaluate(
    ds: &Dataset,
    model_path: &std::path::Path,
    lpips: &std::result::Result<Lpips, String>,
    config: &super::StudyConfig,
) -> Result<Evaluation> {
    let held = ModelBuf::from_bytes_as_is(&nbrdf::io::read(model_path)?)?;
    let model = held.model();
    let eval = |p: &Prepared, wi: Vec3, wo: Vec3| model.eval(p, wi, wo);
    let ground_truth = ds.ground_truth()?;
    let mut image_metrics = Vec::new();
    let mut captured_psnr = Vec::new();
    let (mut pred_brdf, mut ref_brdf, mut keep) = (Vec::<Rgb>::new(), Vec::<Rgb>::new(), Vec::new());
    for view in ds.views.iter().filter(|v| v.split == Split::Test) {
        let cam = &view.camera;
        let rendered = render_with(&model, ds, view, &lights_of(view));
        let clean = ground_truth.map(|t| render_truth(t, ds, view, &lights_of(view))).transpose()?;
        for (j, (im, out)) in view.images.iter().zip(&rendered.images).enumerate() {
            let reference = im.load()?;
            let test = RgbImage::from_data(cam.width, cam.height, out.radiance.clone())?;
            match &clean {
                Some(clean) => {
                    image_metrics.push(PreparedReference::new(&clean[j], Some(&view.mask), lpips).evaluate(&test));
                    captured_psnr.push(masked_psnr(&reference, &test, &view.mask));
                }
                None => image_metrics.push(PreparedReference::new(&reference, Some(&view.mask), lpips).evaluate(&test)),
            }
            let Some(brdf_path) = &im.brdf else { continue };
            let truth = read_exr(brdf_path)?;
            for (p, g) in rendered.gbuffer.samples.iter().enumerate() {
                let (true, true, Some(g)) = (view.mask[p], out.lit[p], g) else { continue };
                let frame = g.frame();
                let (cl, cv) = (frame.to_local(im.light.direction).z, frame.to_local(g.view).z);
                pred_brdf.push(out.brdf[p]);
                ref_brdf.push(truth.data[p]);
                // As the paper: values of saturated reference pixels are left out.
                let saturated = reference.data[p].iter().any(|&c| c >= crate::dataset::spec::SATURATED);
                keep.push(brdf_rmse::keep(cl, cv, saturated));
            }
        }
    }
    if image_metrics.is_empty() {
        return Err(Error::Invalid("the data set has no test images".into()));
    }

    // Points and directions of the test split for the BRDF-space metrics.
    let s = samples(ds, Split::Test, 1)?;
    let recip_idx = energy::pick(s.len(), config.reciprocity_pairs, config.seed ^ 0x5eed);
    let energy_idx = energy::pick(s.len(), config.energy_pairs, config.seed ^ 0xe4e7);
    let input = |i: usize| {
        let [b1, b2] = s.barycentric[i];
        point_input(&model, ds, s.triangle[i], b1, b2, Vec3::from_array(s.position[i]))
    };
    let recip_prepared = recip_idx.iter().map(|&i| model.prepare(&input(i))).collect::<std::result::Result<Vec<_>, _>>()?;
    let pairs: Vec<DirectionPair> = recip_idx
        .iter()
        .enumerate()
        .map(|(k, &i)| DirectionPair { point: k, wi: Vec3::from_array(s.wi[i]), wo: Vec3::from_array(s.wo[i]) })
        .collect();
    let reciprocity = reciprocity_rmse(&pairs, |k, wi, wo| eval(&recip_prepared[k], wi, wo));

    let energy_inputs: Vec<Vec<f32>> = energy_idx.iter().map(|&i| input(i)).collect();
    let energy_prepared = energy_inputs.iter().map(|p| model.prepare(p)).collect::<std::result::Result<Vec<_>, _>>()?;
    let (prepare_ns_per_point, prepare_many_ns_per_point) = time_prepare(&model, &energy_inputs.concat());
    let light_pairs: Vec<LightPair> = energy_idx
        .iter()
        .enumerate()
        .map(|(k, &i)| LightPair { point: k, wi: Vec3::from_array(s.wi[i]) })
        .collect();
    let ecfg = EnergyConfig { samples: config.energy_samples, seed: config.seed, ..EnergyConfig::default() };
    let energy =
        energy::energy_analysis(&light_pairs, |k, wi, wo| eval(&energy_prepared[k], wi, wo), &ecfg);

    Ok(Evaluation {
        image: ImageMetrics::mean(&image_metrics),
        reference: if ground_truth.is_some() { Reference::Clean } else { Reference::Captured },
        captured_psnr: (!captured_psnr.is_empty()).then(|| captured_psnr.iter().sum::<f64>() / captured_psnr.len() as f64),
        brdf_rmse_cbrt: brdf_rmse::cube_root_rmse(&pred_brdf, &ref_brdf, &keep),
        reciprocity_rmse: reciprocity,
        energy,
        eval_ns_per_query: time_eval(&eval, &recip_prepared, &pairs),
        eval_batch_ns_per_query: Some(time_batches(&model, &recip_prepared, &pairs)),
        prepare_ns_per_point,
        prepare_many_ns_per_point,
    })
}

/// Mean ns per point of `prepare` one point at a time and of `prepare_many` on all of `points` (the
/// inputs of `n` points back to back), each repeated to at least 16 384 points; `None` for a model
/// whose points have no input (nothing to prepare per point) or for no points.
fn time_prepare(model: &Model<'_>, points: &[f32]) -> (Option<f64>, Option<f64>) {
    let k = model.position_len();
    if k == 0 || points.len() < k {
        return (None, None);
    }
    let n = points.len() / k;
    let rounds = (16_384 / n).max(1);
    let mut out = vec![Prepared::default(); n];
    let mut sink = 0.0f32;
    let single = ns_per_round(rounds, |_| {
        for (i, o) in out.iter_mut().enumerate() {
            *o = model.prepare(std::hint::black_box(&points[i * k..(i + 1) * k])).unwrap_or_default();
        }
        sink += out[n / 2].diffuse()[0];
    }) / n as f64;
    let many = ns_per_round(rounds, |_| {
        // The length is right by construction; an error would leave `out` as it was.
        model.prepare_many(std::hint::black_box(&points[..n * k]), &mut out).ok();
        sink += out[n / 2].diffuse()[0];
    }) / n as f64;
    std::hint::black_box(sink);
    (Some(single), Some(many))
}

/// Mean ns per pair of `eval_many` over batches of [`BATCH`] of the pairs' directions, each batch at
/// the next prepared point, repeated to at least ~200k queries.
fn time_batches(model: &Model<'_>, prepared: &[Prepared], pairs: &[DirectionPair]) -> f64 {
    if pairs.is_empty() || prepared.is_empty() {
        return f64::NAN;
    }
    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = (0..BATCH).map(|i| (pairs[i % pairs.len()].wi, pairs[i % pairs.len()].wo)).unzip();
    let mut out = vec![[0.0f32; 3]; BATCH];
    model.eval_many(&prepared[0], &wi, &wo, &mut out);
    let rounds = (200_000 / BATCH).max(1);
    let mut sink = 0.0f32;
    let ns = ns_per_round(rounds, |r| {
        model.eval_many(&prepared[r % prepared.len()], std::hint::black_box(&wi), &wo, &mut out);
        sink += out[r % BATCH][1];
    }) / BATCH as f64;
    std::hint::black_box(sink);
    ns
}

/// Mean ns per single `eval` over the pairs, repeated to at least ~200k queries so the timer resolution
/// and the first cold calls do not dominate.
fn time_eval(eval: &impl Fn(&Prepared, Vec3, Vec3) -> Rgb, prepared: &[Prepared], pairs: &[DirectionPair]) -> f64 {
    if pairs.is_empty() {
        return f64::NAN;
    }
    let rounds = (200_000 / pairs.len()).max(1);
    let mut sink = 0.0f32;
    for p in pairs.iter().take(1000) {
        sink += eval(&prepared[p.point], p.wi, p.wo)[0];
    }
    let ns = ns_per_round(rounds, |_| {
        for p in pairs {
            sink += eval(&prepared[p.point], std::hint::black_box(p.wi), p.wo)[1];
        }
    }) / pairs.len() as f64;
    std::hint::black_box(sink);
    ns
}

/// Longest a timing loop runs: enough for ~200k queries at the SIMD levels (~0.3 s for the slowest
/// model), and a bound at the portable level, where the same count takes 10-20× as long.
const TIMING_BUDGET: std::time::Duration = std::time::Duration::from_millis(400);

/// Mean ns per call of `round(r)` over `rounds` calls, or over the calls made until
/// [`TIMING_BUDGET`] ran out (at least one).
fn ns_per_round(rounds: usize, mut round: impl FnMut(usize)) -> f64 {
    let t = Instant::now();
    let mut done = 0;
    while done < rounds.max(1) {
        round(done);
        done += 1;
        if t.elapsed() >= TIMING_BUDGET {
            break;
        }
    }
    t.elapsed().as_nanos() as f64 / done as f64
}

/// The test views of a data set, their references in sRGB loaded once: the learning curve's probe,
/// scored with the same PSNR (sRGB, masked to the object) as [`evaluate`], on renderings of the
/// training model exported as [`evaluate`] would read it (without the sampling proxy, which `eval`
/// does not use).
pub struct TestViews<'a> {
    ds: &'a Dataset,
    /// `(index into ds.views, sRGB reference per light)`.
    views: Vec<(usize, Vec<RgbImage>)>,
}

impl<'a> TestViews<'a> {
    /// Loads the references of every test view of `ds`: the clean ones where it has a ground truth.
    pub fn load(ds: &'a Dataset) -> Result<TestViews<'a>> {
        let truth = ds.ground_truth()?;
        let mut views: Vec<(usize, Vec<RgbImage>)> = Vec::new();
        for (i, view) in ds.views.iter().enumerate().filter(|(_, v)| v.split == Split::Test) {
            let refs = match truth {
                Some(t) => render_truth(t, ds, view, &lights_of(view))?,
                None => view.images.iter().map(|im| im.load()).collect::<std::result::Result<Vec<_>, _>>()?,
            };
            views.push((i, refs.iter().map(crate::metrics::to_srgb).collect()));
        }
        if views.iter().all(|(_, r)| r.is_empty()) {
            return Err(Error::Invalid("the data set has no test images".into()));
        }
        Ok(TestViews { ds, views })
    }

    /// Mean test-image PSNR (dB) of the model file `bytes`.
    pub fn psnr(&self, bytes: &[u8]) -> Result<f64> {
        let buf = ModelBuf::from_bytes(bytes)?;
        let model = buf.model();
        let (mut sum, mut n) = (0.0, 0usize);
        for (i, refs) in &self.views {
            let view = &self.ds.views[*i];
            let rendered = render_with(&model, self.ds, view, &lights_of(view));
            for (reference, out) in refs.iter().zip(&rendered.images) {
                let test = RgbImage::from_data(view.camera.width, view.camera.height, out.radiance.clone())?;
                sum += crate::metrics::psnr::psnr(reference, &crate::metrics::to_srgb(&test), Some(&view.mask));
                n += 1;
            }
        }
        Ok(sum / n as f64)
    }

    /// [`TestViews::psnr`] of a training model, its per-vertex `position_table` travelling with it.
    pub fn psnr_of(&self, model: &crate::models::Model, position_table: Option<&[f32]>) -> Result<f64> {
        let bytes = nbrdf::file::encode(&model.config.header(), &model.weights()?, position_table)?;
        self.psnr(&bytes)
    }
}

/// The first image of the first test view: reference (clean where the data set has a ground truth), the model's rendering (Eq. 9, as in
/// [`evaluate`]) and the object mask.
pub fn first_test_image(ds: &Dataset, model_path: &std::path::Path) -> Result<(RgbImage, RgbImage, Vec<bool>)> {
    let buf = ModelBuf::load(model_path)?;
    let model = buf.model();
    let view = ds
        .views
        .iter()
        .find(|v| v.split == Split::Test && !v.images.is_empty())
        .ok_or_else(|| Error::Invalid("the data set has no test images".into()))?;
    let im = &view.images[0];
    let rendered = render_with(&model, ds, view, &[im.light]);
    let reference = match ds.ground_truth()? {
        Some(truth) => render_truth(truth, ds, view, &[im.light])?.swap_remove(0),
        None => im.load()?,
    };
    let test = RgbImage::from_data(view.camera.width, view.camera.height, rendered.images[0].radiance.clone())
        ?;
    Ok((reference, test, view.mask.clone()))
}

/// The bytes of `buf` re-encoded with f16 network weights ([`nbrdf::Model::to_f16`]), for the
/// f32-versus-f16 comparison without retraining; checked to keep the header apart from the precision.
pub fn to_f16(buf: &ModelBuf) -> Result<Vec<u8>> {
    let out = buf.model().to_f16()?;
    let check = ModelBuf::from_bytes(&out)?;
    let header = buf.header();
    if check.header().n_vertices != header.n_vertices || check.header().nets() != header.nets() {
        return Err(Error::Invalid("f16 re-encoding changed the model header".into()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};

    /// The f16 copy of a model with object parameters and a position table evaluates within f16
    /// rounding of the f32 one, is smaller, and keeps the table (same point features).
    #[test]
    fn f16_copy_matches_the_f32_model() {
        let k = 4u16;
        let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Intrinsic { k }, 3);
        let weights: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
        let table: Vec<f32> = (0..5 * k as usize).map(|i| (i as f32 * 0.37).sin()).collect();
        let buf = ModelBuf::from_bytes(&encode(&h, &weights, Some(&table)).unwrap()).unwrap();
        let f16_file = to_f16(&buf).unwrap();
        assert!(f16_file.len() < buf.as_bytes().len());
        // Held as the study evaluates it: f16 rows as they are.
        let b16 = ModelBuf::from_bytes_as_is(&f16_file).unwrap();
        let (m32, m16) = (buf.model(), b16.model());
        assert_eq!(m16.header().precision, Precision::F16);
        let mut f32_feat = vec![0.0; k as usize];
        let mut f16_feat = vec![0.0; k as usize];
        m32.position_features([0, 1, 2], [0.2, 0.3, 0.5], &mut f32_feat).unwrap();
        m16.position_features([0, 1, 2], [0.2, 0.3, 0.5], &mut f16_feat).unwrap();
        assert_eq!(f32_feat, f16_feat);
        let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.5, 0.2, 0.7).normalize());
        let (a, b) = (m32.eval(&m32.prepare(&f32_feat).unwrap(), wi, wo), m16.eval(&m16.prepare(&f16_feat).unwrap(), wi, wo));
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-2 * a[c].abs().max(1e-2), "{a:?} vs {b:?}");
        }
        // A ModelBuf of the f16 file (widened at load) gives the in-place bits, and converts back to
        // the same file.
        let wide = ModelBuf::from_bytes(&f16_file).unwrap();
        let mw = wide.model();
        assert_eq!(mw.eval(&mw.prepare(&f16_feat).unwrap(), wi, wo).map(f32::to_bits), b.map(f32::to_bits));
        assert_eq!(to_f16(&wide).unwrap(), f16_file);
    }
}
