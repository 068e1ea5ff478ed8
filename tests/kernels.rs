//! The tiny-network kernels (`nbrdf::kernels::TinyNet`, the NBRDF-json evaluator) against a plain
//! scalar f64 reference on random networks and inputs, at every kernel level this CPU has, including
//! pre-activations that are exactly zero at the ReLU; and single queries against packets, bit for bit.
//! Batches of `.nbrdf` models with f16 weights, over the thread's f32 copy or widened per packet,
//! against the f32 model of the same values, bit for bit, at every level.

use nbrdf::file::{encode, ModelBuf, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf::model::Model;
use nbrdf::kernels::{set_level, Level, TinyLayer, TinyNet, TINY_INPUTS, TINY_PACKET};
use nbrdf::Vec3;
use std::sync::Mutex;

/// The level is process-wide: tests that set it take turns.
static LEVEL: Mutex<()> = Mutex::new(());

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }
}

/// A network of the given widths laid out as `TinyLayer` documents: weights dyadic (multiples of 1/64)
/// and inputs dyadic, so that the first layer's pre-activations are exact; the bias of every third
/// output of the first layer is chosen to make its pre-activation at `zero_at` exactly 0.
fn network(widths: &[usize], rng: &mut Rng, zero_at: &[f32; TINY_INPUTS]) -> (Vec<TinyLayer>, Vec<f32>) {
    let mut layers = Vec::new();
    let mut params = Vec::new();
    let mut x: Vec<f64> = zero_at.iter().map(|v| *v as f64).collect();
    for (l, w) in widths.windows(2).enumerate() {
        let (n_in, n_out) = (w[0], w[1]);
        let padded = n_out.div_ceil(8) * 8;
        let offset = params.len();
        params.resize(offset + (n_in + 1) * padded, 0.0);
        let mut y = vec![0.0f64; n_out];
        for o in 0..n_out {
            let mut s = 0.0f64;
            for i in 0..n_in {
                let v = (rng.next() * 64.0).round() / 64.0;
                params[offset + i * padded + o] = v;
                s += v as f64 * x[i];
            }
            let b = if l == 0 && o % 3 == 1 { -s as f32 } else { (rng.next() * 16.0).round() / 64.0 };
            assert!(b as f64 == -s || !(l == 0 && o % 3 == 1), "the zero bias is exact");
            params[offset + n_in * padded + o] = b;
            let relu = l + 2 < widths.len();
            y[o] = if relu { (s + b as f64).max(0.0) } else { s + b as f64 };
        }
        layers.push(TinyLayer { inputs: n_in, outputs: n_out, padded, offset, relu: l + 2 < widths.len() });
        x = y;
    }
    (layers, params)
}

fn reference(layers: &[TinyLayer], params: &[f32], input: &[f32; TINY_INPUTS]) -> [f64; 3] {
    let mut x: Vec<f64> = input.iter().map(|v| *v as f64).collect();
    for l in layers {
        x = (0..l.outputs)
            .map(|o| {
                let mut s = params[l.offset + l.inputs * l.padded + o] as f64;
                for (i, xi) in x.iter().enumerate() {
                    s += xi * params[l.offset + i * l.padded + o] as f64;
                }
                if l.relu { s.max(0.0) } else { s }
            })
            .collect();
    }
    [x[0].exp_m1(), x[1].exp_m1(), x[2].exp_m1()]
}

#[test]
fn tiny_networks_match_a_scalar_reference_and_packets_match_single_queries() {
    let _level = LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rng = Rng(0x2545f4914f6cdd1d);
    for widths in [&[6, 21, 21, 3][..], &[6, 3], &[6, 8, 3], &[6, 64, 17, 40, 3], &[6, 2, 3], &[6, 33, 3]] {
        // Dyadic inputs: the first one makes some pre-activations exactly zero.
        let inputs: Vec<[f32; TINY_INPUTS]> = (0..TINY_PACKET * 3)
            .map(|_| std::array::from_fn(|_| (rng.next() * 64.0).round() / 32.0))
            .collect();
        let (layers, params) = network(widths, &mut rng, &inputs[0]);
        let net = TinyNet { layers: &layers, params: &params };
        for level in Level::usable() {
            set_level(Some(level));
            for chunk in inputs.chunks(TINY_PACKET) {
                let x: [[f32; TINY_PACKET]; TINY_INPUTS] = std::array::from_fn(|f| std::array::from_fn(|q| chunk[q][f]));
                let mut packet = [[f32::NAN; TINY_PACKET]; 3];
                net.packet(&x, &mut packet);
                for (q, input) in chunk.iter().enumerate() {
                    let got = net.one(input);
                    // The clamped output is `sanitize` of the plain one, bit for bit, at every level.
                    assert_eq!(net.brdf(input).map(f32::to_bits), nbrdf::math::sanitize(got).map(f32::to_bits));
                    let want = reference(&layers, &params, input);
                    for c in 0..3 {
                        assert_eq!(got[c].to_bits(), packet[c][q].to_bits(), "{level:?} {widths:?}: single vs packet");
                        let tol = 1e-5 * want[c].abs().max(0.05);
                        assert!((got[c] as f64 - want[c]).abs() <= tol, "{level:?} {widths:?} q {q} c {c}: {} vs {}", got[c], want[c]);
                    }
                }
            }
        }
        set_level(None);
    }
}

/// `Model::eval_many` on f16 weights widens the per-query network into a per-thread f32 copy once the
/// thread has evaluated four packets' worth of one `ModelBuf` in a row (`std`), later calls on it use
/// that copy whatever their size, and other calls widen each packet's rows. Every way a pair gets
/// the bits of the f32 model whose weights are the f16 values (the widening is exact and the kernels
/// are the f32 ones), at every level, whichever model the thread's copy held before (a large network, then a
/// smaller one, then another large one), on several threads at once, and with the copy turned off.
#[test]
fn f16_batches_widened_per_call_or_per_packet_give_the_bits_of_f32_weights() {
    let _level = LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rng = Rng(0x9e3779b97f4a7c15);
    let pos = PositionEncoding::Intrinsic { k: 6 };
    let models: Vec<(ModelKind, ModelBuf, ModelBuf)> = [ModelKind::SingleMlp, ModelKind::AdditiveShared, ModelKind::SingleMlp, ModelKind::AdditiveSeparate]
        .into_iter()
        .map(|kind| {
            let h = ModelHeader::paper(kind, kind.is_additive(), Reciprocity::Exact, pos, 4);
            let w: Vec<f32> = (0..h.n_weights()).map(|_| half::f16::from_f32(rng.next() * 0.3).to_f32()).collect();
            let f32_buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
            let f16_buf = ModelBuf::from_bytes(&f32_buf.model().to_f16().unwrap()).unwrap();
            (kind, f32_buf, f16_buf)
        })
        .collect();
    let n = 200; // over four packets, and not a multiple of one
    let mut dir = || {
        let v = Vec3::new(rng.next(), rng.next(), rng.next() + 0.3);
        v.normalize_or_zero()
    };
    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|_| (dir(), dir())).unzip();
    let point = [0.1, 0.5, -0.3, 0.2, 0.0, 0.9];
    for level in Level::usable() {
        set_level(Some(level));
        let check = || {
            for (kind, f32_buf, f16_buf) in &models {
                let (m32, m16) = (f32_buf.model(), f16_buf.model());
                let (p32, p16) = (m32.prepare(&point), m16.prepare(&point));
                let mut want = vec![[f32::NAN; 3]; n];
                m32.eval_many(&p32, &wi, &wo, &mut want);
                let chunked = || {
                    let mut out = vec![[f32::NAN; 3]; n];
                    for (k, out) in out.chunks_mut(40).enumerate() {
                        m16.eval_many(&p16, &wi[k * 40..], &wo[k * 40..], out);
                    }
                    out
                };
                // Small calls while the thread's copy holds another model (or none): per packet,
                // until this model's pairs in a row reach four packets (the second call).
                let before = chunked();
                let mut whole = vec![[f32::NAN; 3]; n];
                m16.eval_many(&p16, &wi, &wo, &mut whole);
                // Small calls on the model the copy holds: over the copy.
                let after = chunked();
                let nonzero = want.iter().filter(|f| **f != [0.0; 3]).count();
                assert!(nonzero > n / 2, "{kind:?}: most pairs are valid ({nonzero})");
                for i in 0..n {
                    let bits = want[i].map(f32::to_bits);
                    assert_eq!(before[i].map(f32::to_bits), bits, "{level:?} {kind:?} pair {i}: widened per packet");
                    assert_eq!(whole[i].map(f32::to_bits), bits, "{level:?} {kind:?} pair {i}: widened for the call");
                    assert_eq!(after[i].map(f32::to_bits), bits, "{level:?} {kind:?} pair {i}: the thread's copy");
                }
            }
            // Views of borrowed bytes have no identity: after a large call on one, a small call on
            // another (a second Single MLP of the same shape) widens its own rows.
            let (a, b) = (Model::from_bytes(models[0].2.as_bytes()).unwrap(), Model::from_bytes(models[2].2.as_bytes()).unwrap());
            let b32 = models[2].1.model();
            let mut big = vec![[0.0f32; 3]; n];
            a.eval_many(&a.prepare(&point), &wi, &wo, &mut big);
            let (mut small, mut want) = (vec![[f32::NAN; 3]; 40], vec![[f32::NAN; 3]; 40]);
            b.eval_many(&b.prepare(&point), &wi[..40], &wo[..40], &mut small);
            b32.eval_many(&b32.prepare(&point), &wi[..40], &wo[..40], &mut want);
            assert_eq!(small, want, "{level:?}: a borrowed model after another");
        };
        check();
        std::thread::scope(|s| {
            for _ in 0..3 {
                s.spawn(check);
            }
        });
        // With the per-thread copy turned off every call widens per packet: the same bits.
        assert!(nbrdf::model::set_f16_batch_copy(false));
        check();
        assert!(!nbrdf::model::set_f16_batch_copy(true));
    }
    set_level(None);
}

/// `Model::prepare_many` runs the position networks 16 points at a time through the packet kernels:
/// every point's evaluations get the bits of `prepare` of that point, for every model kind (the
/// parametric ones, whose whole network runs per point; the Single MLP with its one network and with
/// a position trunk; both additive models), both weight types, every position encoding, at every
/// level, with zeros (which the one-query kernels skip and the dense packet kernel adds), a NaN and
/// 0, 5, 16 and 37 points (the last packet overlapping the one before).
#[test]
fn prepare_many_gives_each_point_the_evaluations_of_prepare() {
    let _level = LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rng = Rng(0x2545f4914f6cdd1d);
    let mut models = Vec::new();
    for pos in [PositionEncoding::Intrinsic { k: 6 }, PositionEncoding::Extrinsic { frequencies: 2 }, PositionEncoding::Uniform] {
        let mut headers: Vec<ModelHeader> = nbrdf::parametric::ParametricKind::ALL
            .iter()
            .map(|&k| ModelHeader::paper(ModelKind::Parametric(k), false, Reciprocity::None, pos, 0))
            .collect();
        for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
            headers.push(ModelHeader::paper(kind, kind.is_additive(), Reciprocity::Exact, pos, 2));
        }
        headers.push(ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::None, pos, 2).with_direction_layers(2));
        for h in headers {
            let w: Vec<f32> = (0..h.n_weights()).map(|_| rng.next() * 0.3).collect();
            let f32_buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
            let f16_buf = ModelBuf::from_bytes(&f32_buf.model().to_f16().unwrap()).unwrap();
            models.push(f32_buf);
            models.push(f16_buf);
        }
    }
    let pairs: Vec<(Vec3, Vec3)> = (0..6)
        .map(|_| (Vec3::new(rng.next(), rng.next(), rng.next() + 0.6).normalize(), Vec3::new(rng.next(), rng.next(), rng.next() + 0.6).normalize()))
        .collect();
    for level in Level::usable() {
        set_level(Some(level));
        for buf in &models {
            let m = buf.model();
            let k = m.position_len();
            let name = format!("{level:?} {:?} {:?} {:?}", m.header().kind, m.header().position, m.header().precision);
            for n in [0, 5, 16, 37] {
                let mut points: Vec<f32> = (0..n * k).map(|_| rng.next() * 2.0).collect();
                if n * k > 8 {
                    // A point with zeros (every other input), one with a NaN.
                    for v in points[k..2 * k].iter_mut().step_by(2) {
                        *v = 0.0;
                    }
                    points[3 * k - 1] = f32::NAN;
                }
                let mut many = vec![m.prepare(&[f32::NAN]); n];
                m.prepare_many(&points, &mut many).unwrap();
                for (i, p) in many.iter().enumerate() {
                    let one = m.prepare(&points[i * k..(i + 1) * k]);
                    assert_eq!(p.diffuse().map(f32::to_bits), one.diffuse().map(f32::to_bits), "{name}: point {i} of {n}, diffuse");
                    assert_eq!(format!("{:?}", p.parameters()), format!("{:?}", one.parameters()), "{name}: point {i} of {n}, parameters");
                    for &(wi, wo) in &pairs {
                        let (a, b) = (m.eval(p, wi, wo), m.eval(&one, wi, wo));
                        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{name}: point {i} of {n} at ({wi}, {wo})");
                        if i != 2 && !matches!(m.header().position, PositionEncoding::Uniform) {
                            assert!(a.iter().all(|c| c.is_finite()), "{name}: a finite value");
                        }
                    }
                }
                // Inputs that are not `n` points of `k` values: an error that names them, nothing written.
                if k > 0 {
                    let before: Vec<String> = many.iter().map(|p| format!("{p:?}")).collect();
                    let err = m.prepare_many(&points[..n * k - (n > 0) as usize], &mut many);
                    assert!(n == 0 || matches!(err, Err(nbrdf::Error::SizeMismatch { what, .. }) if what.contains("point")), "{name}: {err:?}");
                    assert_eq!(before, many.iter().map(|p| format!("{p:?}")).collect::<Vec<_>>(), "{name}: nothing written");
                }
            }
        }
    }
    set_level(None);
}

/// `NBRDF_KERNEL`, where set, is the level everything runs at (CI runs the suites once per level the
/// host has this way); a value the host cannot honour fails here instead of quietly testing the
/// native level again.
#[test]
fn the_level_nbrdf_kernel_asks_for_is_the_one_in_use() {
    let cpu = nbrdf::kernels::cpu_level();
    match nbrdf::kernels::requested() {
        Ok(Some(l)) => assert_eq!(nbrdf::kernels::detected(), l, "NBRDF_KERNEL={l} not honoured"),
        Ok(None) => assert_eq!(nbrdf::kernels::detected(), cpu),
        Err(e) => panic!("{e}"),
    }
    assert!(Level::ALL.contains(&nbrdf::kernels::detected()) && nbrdf::kernels::detected() <= cpu);
    println!("kernel level {} (CPU {cpu})", nbrdf::kernels::detected());
}
