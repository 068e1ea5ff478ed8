//! The training step (`trainer::engine::batch_loss`: forward, Eq. 9/10 and backward as one op over
//! row blocks) against its definition composed from candle ops (`Model::forward` and
//! `trainer::engine::loss`), for every model the trainer fits, and its determinism.

use candle_core::{DType, Device, Tensor};
use trainer::engine::adam::Adam;
use trainer::engine::{batch_loss, loss, Batch, Regularisers};
use trainer::models::{arch, Config, Inputs, Kind, Model, ParametricKind, PositionEncoding, RawBatch, Reciprocity};

/// The loss as candle ops: `Model::forward`, Eq. 9/10 and the Sec. 4.4 regularisers.
fn composed(model: &Model, batch: &Batch, reg: Regularisers) -> Tensor {
    let out = model.forward(&batch.inputs).unwrap();
    let mut total = loss::tone_mapped_mse(&loss::render(&out.f, &batch.incident).unwrap(), &batch.target).unwrap();
    if let (true, Some(d), Some(s)) = (model.config.has_xi(), &out.diffuse, &out.specular) {
        let rd = loss::diffuse_l1(&d.broadcast_mul(&batch.inputs.valid).unwrap(), &batch.incident, &batch.target).unwrap();
        let rs = loss::specular_l1(s, &batch.incident).unwrap();
        total = ((total + (rd * reg.lambda_diffuse as f64).unwrap()).unwrap() + (rs * reg.lambda_specular as f64).unwrap()).unwrap();
    }
    total
}

/// A batch of `n` toy samples whose incident light (0 to ~20) renders values below the sRGB knee, on
/// the curve and clipped at 1, with invalid pairs among them.
fn batch(config: &Config, n: usize, seed: u64) -> Batch {
    let dev = Device::Cpu;
    let obs = trainer::toy::observations(n, config.position, seed);
    let incident: Vec<f32> = (0..n).flat_map(|i| [(i % 7) as f32 * 3.0 * obs.wi[i].z.max(0.0); 3]).collect();
    let target: Vec<f32> = obs.radiance.iter().flatten().map(|&v| loss::gamma(v)).collect();
    let inputs = Inputs::build(config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
    Batch { inputs, incident: Tensor::from_vec(incident, (n, 3), &dev).unwrap(), target: Tensor::from_vec(target, (n, 3), &dev).unwrap() }
}

/// Every configuration the trainer fits: the study's variants (Tab. 1) under each reciprocity, every
/// parametric model, a uniform material (position-only networks without an input), and the Single
/// MLP whose directions enter after a position-only trunk (Tab. 2).
fn configs() -> Vec<Config> {
    let position = PositionEncoding::Intrinsic { k: 6 };
    let mut all = arch::study_variants(position, Reciprocity::Exact);
    all.extend(arch::study_variants(position, Reciprocity::Swap).into_iter().filter(|c| !matches!(c.kind, Kind::Parametric(_))));
    all.extend(ParametricKind::ALL.into_iter().map(|k| Config::paper(Kind::Parametric(k), false, Reciprocity::None, position)));
    for kind in [Kind::SingleMlp, Kind::AdditiveSeparate, Kind::AdditiveShared, Kind::Parametric(ParametricKind::Disney)] {
        all.push(Config::paper(kind, kind.is_additive(), Reciprocity::Exact, PositionEncoding::Uniform));
    }
    let mut split = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, position);
    split.direction_layers = Some(3);
    all.push(split);
    all
}

/// `max |a - b| / max |b|` over a gradient.
fn rel_err(a: &[f32], b: &[f32]) -> f32 {
    let scale = b.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-30);
    a.iter().zip(b).fold(0.0f32, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// How far two evaluations of the same sums in different orders may drift, relative to the largest
/// entry: a sum of `n` terms in floating point is within γ_n ≈ n·u (u = ε/2) of the exact one,
/// relative to the sum of the terms' magnitudes (Higham, Accuracy and Stability, Thm. 3.1 and
/// Eq. 3.5), so two orders are within n·ε of each other. A weight gradient sums the batch's rows of
/// products that each come through the layers above (the network's widths), so `n` is the rows plus
/// the widths; the factor 4 allows for the terms' magnitudes exceeding the largest entry (cancellation
/// in the sums over rows, measured up to ~2.2 on these batches).
fn order_bound(rows: usize, widths: usize) -> f32 {
    4.0 * (rows + widths) as f32 * f32::EPSILON
}

/// For every model, the step's loss and the gradient of every weight are the composed definition's,
/// to the bound the different order of the sums allows (candle's products sum in `gemm`'s blocks, the
/// step along its rows, and the loss is a mean in f32 there and a sum of f64 block sums here), on a
/// batch that ends in a partial block of rows.
#[test]
fn step_meets_its_composed_definition_for_every_model() {
    let n = 2500;
    let reg = Regularisers { lambda_diffuse: 0.3, lambda_specular: 0.2 };
    for (i, config) in configs().into_iter().enumerate() {
        let model = Model::init(config, 8 + i as u64, &Device::Cpu).unwrap();
        let b = batch(&config, n, 12);
        let (want, got) = (composed(&model, &b, reg), batch_loss(&model, &b, reg).unwrap());
        let (w, g) = (want.to_scalar::<f32>().unwrap(), got.to_scalar::<f32>().unwrap());
        let name = config.name() + if config.position == PositionEncoding::Uniform { " (uniform)" } else { "" };
        assert!(w > 0.0 && (w - g).abs() <= order_bound(3 * n, 0) * w, "{name}: loss {g} vs {w}");
        let vars = model.vars();
        let gw = Adam::gradients(&vars, &want.backward().unwrap()).unwrap();
        let gg = Adam::gradients(&vars, &got.backward().unwrap()).unwrap();
        let widths: usize = model.nets.iter().flat_map(|net| arch::layers(&net.desc)).map(|(k, _)| k).sum();
        let bound = order_bound(n, widths);
        for (v, (a, e)) in gg.iter().zip(&gw).enumerate() {
            assert!(e.iter().any(|x| *x != 0.0) || a.iter().all(|x| *x == 0.0), "{name} var {v}: a gradient where the definition has none");
            assert!(rel_err(a, e) <= bound, "{name} var {v}: {} off (bound {bound:e})", rel_err(a, e));
        }
    }
}

/// A step's sums run over fixed blocks of rows added in block order, so its loss and gradients are
/// the same bits on one thread as on several, at every kernel level.
#[test]
fn step_is_the_same_bits_on_any_number_of_threads() {
    let position = PositionEncoding::Intrinsic { k: 6 };
    for kind in [Kind::SingleMlp, Kind::AdditiveShared, Kind::Parametric(ParametricKind::TorranceSparrow)] {
        let config = Config::paper(kind, kind.is_additive(), Reciprocity::Exact, position);
        let model = Model::init(config, 3, &Device::Cpu).unwrap();
        let b = batch(&config, 3000, 5);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let l = batch_loss(&model, &b, Regularisers::default()).unwrap();
                let g = Adam::gradients(&model.vars(), &l.backward().unwrap()).unwrap();
                (l.to_scalar::<f32>().unwrap().to_bits(), g.iter().flatten().map(|v| v.to_bits()).collect::<Vec<u32>>())
            })
        };
        assert!(run(1) == run(3), "{}", config.name());
    }
}

/// The step names a batch whose constants do not match its inputs instead of reading past them.
#[test]
fn step_rejects_a_mismatched_batch() {
    let dev = Device::Cpu;
    let n = 300;
    for kind in [Kind::SingleMlp, Kind::AdditiveShared, Kind::Parametric(ParametricKind::Disney)] {
        let config = Config::paper(kind, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 6 });
        let model = Model::init(config, 1, &dev).unwrap();
        let mut b = batch(&config, n, 3);
        // One incident row short.
        b.incident = Tensor::ones((n - 1, 3), DType::F32, &dev).unwrap();
        let e = batch_loss(&model, &b, Regularisers::default()).unwrap_err().to_string();
        assert!(e.contains("fused-step") && e.contains(&format!("{} incident", 3 * (n - 1))) && e.contains(&format!("for {n} samples")), "{}: {e}", config.name());
    }
}
