//! The fused Linear(+ReLU) op of trainer/src/models/fused.rs against the same layer composed from
//! plain candle ops: outputs and every gradient, on random data with pre-activations exactly at the
//! ReLU kink, and a whole network (skip layer included) before and after the fusion.

use candle_core::{DType, Device, Tensor, Var};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer::models::{fused, network, Config, Inputs, Kind, Model, ParametricKind, PositionEncoding, RawBatch, Reciprocity};

/// `max |a - b| / max(max |b|, tiny)`: the 1e-5 relative criterion over a whole tensor.
fn rel_err(a: &Tensor, b: &Tensor) -> f32 {
    let a = a.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let b = b.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-30);
    a.iter().zip(&b).fold(0.0f32, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// The bit patterns of a tensor's values, for comparisons to the last bit.
fn bits(t: &Tensor) -> Vec<u32> {
    t.flatten_all().unwrap().to_vec1::<f32>().unwrap().into_iter().map(f32::to_bits).collect()
}

/// Whether the trainer's products run the AVX-512 kernels, which sum every output and every weight
/// gradient as one chain in row order whatever the blocking, so two paths through them agree bit for
/// bit. Below that level (`NBRDF_KERNEL`, or the CPU) the `gemm` crate sums in blocks that depend on
/// the shapes, and two paths agree only to the order bound [`order_bound`].
fn same_order() -> bool {
    nbrdf::kernels::detected() >= nbrdf::kernels::Level::Avx512
}

/// How far two sums of `n` terms in different orders may drift, relative to the largest entry of the
/// result: each is within γ_n ≈ n·u (u = ε/2) of the exact sum times the sum of the terms' magnitudes
/// (Higham, Accuracy and Stability, 3.1), so two orders within 2γ_n = n·ε of it; the factor 4 allows
/// for a condition (the terms' magnitudes over the largest result, through the layers a gradient
/// passes) of up to 4, where the toy data's gradients reach ~2.2. Zero where [`same_order`].
fn order_bound(n: usize) -> f32 {
    if same_order() {
        0.0
    } else {
        4.0 * n as f32 * f32::EPSILON
    }
}

fn random(rng: &mut ChaCha8Rng, n: usize) -> Vec<f32> {
    (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect()
}

/// The layer from candle ops with PyTorch's ReLU gradient convention (0 at the kink, like the fused
/// op; candle's own `relu` passes the gradient at exactly 0): `z ⊙ [z > 0]` with a constant mask.
fn reference(x: &Tensor, w: &Tensor, b: &Tensor, relu: bool) -> Tensor {
    let z = x.matmul(w).unwrap().broadcast_add(b).unwrap();
    if relu {
        let mask = z.detach().gt(0f32).unwrap().to_dtype(DType::F32).unwrap();
        (z * mask).unwrap()
    } else {
        z
    }
}

#[test]
fn fused_layer_matches_candle_composition() {
    let dev = Device::Cpu;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // Several 1024-row blocks (column sums) and 4096-row blocks (split-K weight gradient), the last
    // one partial.
    let (n, k, m) = (9000, 19, 23);
    let mut xs = random(&mut rng, n * k);
    let mut bs = random(&mut rng, m);
    // Exact zeros at the kink: zero input rows meet zero biases, so z = 0 exactly there.
    for r in (0..n).step_by(7) {
        xs[r * k..(r + 1) * k].fill(0.0);
    }
    for j in (0..m).step_by(3) {
        bs[j] = 0.0;
    }
    let x = Var::from_vec(xs, (n, k), &dev).unwrap();
    let w = Var::from_vec(random(&mut rng, k * m), (k, m), &dev).unwrap();
    let b = Var::from_vec(bs, (1, m), &dev).unwrap();
    let r = Tensor::from_vec(random(&mut rng, n * m), (n, m), &dev).unwrap();
    for relu in [true, false] {
        let y = fused::linear(x.as_tensor(), w.as_tensor(), b.as_tensor(), relu).unwrap();
        let y_ref = reference(x.as_tensor(), w.as_tensor(), b.as_tensor(), relu);
        assert!(rel_err(&y, &y_ref) < 1e-5, "relu {relu}: y {}", rel_err(&y, &y_ref));
        if relu {
            let zeros = y.flatten_all().unwrap().to_vec1::<f32>().unwrap().iter().filter(|v| **v == 0.0).count();
            assert!(zeros > n * m / 3, "the test must hit the kink and the negative side");
        }
        let g = (y * &r).unwrap().sum_all().unwrap().backward().unwrap();
        let g_ref = (y_ref * &r).unwrap().sum_all().unwrap().backward().unwrap();
        for (v, name) in [(&x, "dx"), (&w, "dW"), (&b, "db")] {
            let (a, e) = (g.get(v.as_tensor()).unwrap(), g_ref.get(v.as_tensor()).unwrap());
            assert!(rel_err(a, e) < 1e-5, "relu {relu}: {name} {}", rel_err(a, e));
        }
    }
}

/// A constant input gets no gradient, and the weight gradients are unchanged by skipping it.
#[test]
fn constant_input_skips_dx() {
    let dev = Device::Cpu;
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (n, k, m) = (300, 8, 5);
    let x = Tensor::from_vec(random(&mut rng, n * k), (n, k), &dev).unwrap();
    let w = Var::from_vec(random(&mut rng, k * m), (k, m), &dev).unwrap();
    let b = Var::from_vec(random(&mut rng, m), (1, m), &dev).unwrap();
    let y = fused::linear(&x, w.as_tensor(), b.as_tensor(), true).unwrap();
    let g = y.sum_all().unwrap().backward().unwrap();
    assert!(g.get(&x).is_none());
    let y_ref = reference(&x, w.as_tensor(), b.as_tensor(), true);
    let g_ref = y_ref.sum_all().unwrap().backward().unwrap();
    assert!(rel_err(g.get(w.as_tensor()).unwrap(), g_ref.get(w.as_tensor()).unwrap()) < 1e-5);
    assert!(rel_err(g.get(b.as_tensor()).unwrap(), g_ref.get(b.as_tensor()).unwrap()) < 1e-5);
}

/// A whole model (the Single MLP: 7 layers, skip concat into layer 2, softplus head) gives the same
/// loss and gradients as the unfused network `relu(x W + b)` written with candle ops.
#[test]
fn whole_network_matches_unfused() {
    let dev = Device::Cpu;
    let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 8 });
    let model = Model::init(config, 5, &dev).unwrap();
    let n = 1500;
    let obs = trainer::toy::observations(n, config.position, 9);
    let x = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
    let net = &model.nets[0];
    let out = net.forward(&x.joint, &x.ones).unwrap();
    // The unfused reference: candle's matmul, broadcast bias and relu (issue 4's graph).
    let mut h = x.joint.clone();
    for (l, layer) in net.layers.iter().enumerate() {
        let input = if l == net.desc.skip as usize && l > 0 { Tensor::cat(&[&h, &x.joint], 1).unwrap() } else { h };
        let z = input.matmul(layer.weight.as_tensor()).unwrap().broadcast_add(layer.bias.as_tensor()).unwrap();
        h = if l < net.desc.hidden as usize { z.relu().unwrap() } else { z };
    }
    assert!(rel_err(&out, &h) < 1e-5, "output {}", rel_err(&out, &h));
    let target = Tensor::from_vec(obs.radiance.iter().flatten().copied().collect::<Vec<f32>>(), (n, 3), &dev).unwrap();
    let loss = |o: &Tensor| (trainer::models::activation::softplus(o).unwrap() - &target).unwrap().sqr().unwrap().mean_all().unwrap();
    let (l, l_ref) = (loss(&out), loss(&h));
    let (lv, lv_ref) = (l.to_scalar::<f32>().unwrap(), l_ref.to_scalar::<f32>().unwrap());
    assert!((lv - lv_ref).abs() <= 1e-5 * lv_ref.abs(), "loss {lv} vs {lv_ref}");
    let (g, g_ref) = (l.backward().unwrap(), l_ref.backward().unwrap());
    for (i, v) in model.vars().iter().enumerate() {
        let (a, e) = (g.get(v.as_tensor()).unwrap(), g_ref.get(v.as_tensor()).unwrap());
        assert!(rel_err(a, e) < 1e-5, "variable {i}: {}", rel_err(a, e));
    }
}

/// Every model variant gives the same output and gradients with each network run as one op
/// (`fused::network`) as layer by layer (`fused::linear`): skip layers, trunks ending in a ReLU, and
/// the Additive Shared head, whose input (the trunk's output) needs a gradient.
#[test]
fn whole_network_op_matches_layer_by_layer_for_every_variant() {
    let dev = Device::Cpu;
    let position = PositionEncoding::Intrinsic { k: 6 };
    let n = 5000;
    let obs = trainer::toy::observations(n, position, 4);
    let mut configs = trainer::models::arch::study_variants(position, Reciprocity::Exact);
    let mut split = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, position);
    split.direction_layers = Some(3);
    configs.push(split);
    for (i, config) in configs.into_iter().enumerate() {
        let model = Model::init(config, 20 + i as u64, &dev).unwrap();
        let x = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
        let r = Tensor::from_vec(random(&mut ChaCha8Rng::seed_from_u64(i as u64), n * 3), (n, 3), &dev).unwrap();
        let run = |whole: bool| {
            network::set_whole_network(whole);
            let f = model.forward(&x).unwrap().f;
            network::set_whole_network(true);
            let g = (&f * &r).unwrap().sum_all().unwrap().backward().unwrap();
            (f, g)
        };
        let ((f, g), (f_ref, g_ref)) = (run(true), run(false));
        assert!(rel_err(&f, &f_ref) < 1e-5, "{}: f {}", config.name(), rel_err(&f, &f_ref));
        // A weight gradient sums the batch's `n` rows: in blocks here, whole per layer.
        let tol = order_bound(n).max(1e-5);
        for (j, v) in model.vars().iter().enumerate() {
            let (a, e) = (g.get(v.as_tensor()).unwrap(), g_ref.get(v.as_tensor()).unwrap());
            assert!(rel_err(a, e) < tol, "{}: variable {j}: {} (bound {tol:e})", config.name(), rel_err(a, e));
        }
    }
}

/// The Additive Shared op (trunk and both heads on one block of rows, the specular head reading the
/// trunk's features and the angles in place) gives the outputs of its three networks run one by one
/// as whole-network ops, with the specular head on the joined `[t, PE(a)]`, bit for bit; and their
/// gradients to rounding: the op continues the specular head's sums for `∂t` from the diffuse head's,
/// where candle adds the two finished sums.
#[test]
fn additive_shared_op_is_its_three_networks() {
    let dev = Device::Cpu;
    let position = PositionEncoding::Intrinsic { k: 6 };
    // Not a multiple of the row blocks, so that the last block, sweep and task are partial.
    let n = 2500;
    let obs = trainer::toy::observations(n, position, 9);
    for enhanced in [false, true] {
        let config = Config::paper(Kind::AdditiveShared, enhanced, Reciprocity::Exact, position);
        let model = Model::init(config, 3, &dev).unwrap();
        let x = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
        let n_nets = &model.nets;
        let r = Tensor::from_vec(random(&mut ChaCha8Rng::seed_from_u64(5), n * n_nets[1].desc.n_out as usize), (n, n_nets[1].desc.n_out as usize), &dev).unwrap();
        let k_s = n_nets[2].desc.n_out as usize;
        let r_s = Tensor::from_vec(random(&mut ChaCha8Rng::seed_from_u64(6), n * k_s), (n, k_s), &dev).unwrap();
        let loss = |d: &Tensor, s: &Tensor| ((d * &r).unwrap().sum_all().unwrap() + (s * &r_s).unwrap().sum_all().unwrap()).unwrap();
        let both = trainer::models::additive_shared::additive_shared(&x.position, &x.angles, &n_nets[0], &n_nets[1], &n_nets[2]).unwrap();
        let m_d = n_nets[1].desc.n_out as usize;
        let (d, s) = (both.narrow(1, 0, m_d).unwrap(), both.narrow(1, m_d, k_s).unwrap());
        let g = loss(&d, &s).backward().unwrap();
        let t = n_nets[0].forward(&x.position, &x.ones).unwrap();
        let d_ref = n_nets[1].forward(&t, &x.ones).unwrap();
        let s_ref = n_nets[2].forward(&Tensor::cat(&[&t, &x.angles], 1).unwrap(), &x.ones).unwrap();
        let g_ref = loss(&d_ref, &s_ref).backward().unwrap();
        if same_order() {
            assert!(bits(&d) == bits(&d_ref) && bits(&s) == bits(&s_ref), "{}: outputs differ", config.name());
        } else {
            // The specular head's inputs `[t, PE(a)]` are two operands here and one joined matrix
            // there: sums of at most a layer's width plus the angles' encoding.
            let width = x.angles.dim(1).unwrap() + 256;
            let tol = order_bound(width);
            assert!(rel_err(&d, &d_ref) <= tol && rel_err(&s, &s_ref) <= tol, "{}: outputs differ by {} and {} (bound {tol:e})", config.name(), rel_err(&d, &d_ref), rel_err(&s, &s_ref));
        }
        for (j, v) in model.vars().iter().enumerate() {
            let (a, e) = (g.get(v.as_tensor()).unwrap(), g_ref.get(v.as_tensor()).unwrap());
            // Variables 0.. are the trunk's (file order): only they see the two orders of `∂t`.
            let tol = if j < 2 * n_nets[0].layers.len() { 2e-6f32 } else { 0.0 }.max(order_bound(n));
            assert!(rel_err(a, e) <= tol, "{}: gradient of variable {j} differs by {} (bound {tol:e})", config.name(), rel_err(a, e));
        }
    }
}

/// The training step as one op (forward, objective and backward on each block of rows,
/// `models::step`) gives the loss and every weight's gradient of the network ops followed by the
/// objective op, bit for bit: the Single MLP, both additive models, plain and enhanced (with their
/// regularisers), and every parametric model, on a batch that ends in a partial block.
#[test]
fn fused_step_is_the_network_and_objective_ops_bit_for_bit() {
    use trainer::models::step;
    use trainer::objective::objective;
    use trainer::train::{Batch, TrainOptions};
    let dev = Device::Cpu;
    let position = PositionEncoding::Intrinsic { k: 6 };
    let n = 2500;
    let obs = trainer::toy::observations(n, position, 12);
    // Incident light from 0 to ~20: rendered values below the sRGB knee, on the curve and clipped.
    let incident: Vec<f32> = (0..n).flat_map(|i| [(i % 7) as f32 * 3.0 * obs.wi[i].z.max(0.0); 3]).collect();
    let target: Vec<f32> = obs.radiance.iter().flatten().map(|&v| trainer::loss::gamma(v)).collect();
    let opts = TrainOptions { lambda_diffuse: 0.3, lambda_specular: 0.2, ..Default::default() };
    let parametric = ParametricKind::ALL.into_iter().map(|k| (Kind::Parametric(k), false));
    for (kind, enhanced) in [(Kind::SingleMlp, false), (Kind::AdditiveSeparate, false), (Kind::AdditiveSeparate, true), (Kind::AdditiveShared, false), (Kind::AdditiveShared, true)].into_iter().chain(parametric) {
        let reciprocity = if matches!(kind, Kind::Parametric(_)) { Reciprocity::None } else { Reciprocity::Exact };
        let config = Config::paper(kind, enhanced, reciprocity, position);
        let model = Model::init(config, 8, &dev).unwrap();
        let inputs = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
        let batch = Batch { inputs, incident: Tensor::from_vec(incident.clone(), (n, 3), &dev).unwrap(), target: Tensor::from_vec(target.clone(), (n, 3), &dev).unwrap() };
        let run = |fused: bool| {
            step::set_fused_step(fused);
            let loss = objective(&model, &batch, &opts).unwrap();
            step::set_fused_step(true);
            let g = loss.backward().unwrap();
            (loss.to_scalar::<f32>().unwrap(), g)
        };
        let ((loss, g), (loss_ref, g_ref)) = (run(true), run(false));
        let name = config.name();
        assert!(loss > 0.0, "{name}");
        assert_eq!(loss.to_bits(), loss_ref.to_bits(), "{name}: loss {loss} vs {loss_ref}");
        for (j, v) in model.vars().iter().enumerate() {
            let (a, e) = (g.get(v.as_tensor()).unwrap(), g_ref.get(v.as_tensor()).unwrap());
            if model.object.as_ref().is_some_and(|o| o.as_tensor().id() == v.as_tensor().id()) {
                // FMBRDF's per-object parameter: a sum over the whole batch, which the parametric op
                // reduces in rayon's order and the fused step in row order.
                assert!(rel_err(a, e) < 1e-5, "{name}: object parameter differs by {}", rel_err(a, e));
            } else {
                assert!(bits(a) == bits(e), "{name}: variable {j} differs by {}", rel_err(a, e));
            }
        }
    }
}

/// The fused step names a batch whose constants do not match its inputs instead of reading past them.
#[test]
fn fused_step_rejects_a_mismatched_batch() {
    use trainer::objective::objective;
    use trainer::train::{Batch, TrainOptions};
    let dev = Device::Cpu;
    let position = PositionEncoding::Intrinsic { k: 6 };
    let n = 300;
    let obs = trainer::toy::observations(n, position, 3);
    for kind in [Kind::SingleMlp, Kind::AdditiveShared, Kind::Parametric(ParametricKind::Disney)] {
        let config = Config::paper(kind, false, Reciprocity::Exact, position);
        let model = Model::init(config, 1, &dev).unwrap();
        let inputs = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &dev).unwrap();
        // One incident row short.
        let batch = Batch { inputs, incident: Tensor::ones((n - 1, 3), DType::F32, &dev).unwrap(), target: Tensor::zeros((n, 3), DType::F32, &dev).unwrap() };
        let e = objective(&model, &batch, &TrainOptions::default()).unwrap_err().to_string();
        assert!(e.contains("fused-step") && e.contains(&format!("{} incident", 3 * (n - 1))) && e.contains(&format!("for {n} samples")), "{}: {e}", config.name());
    }
}
