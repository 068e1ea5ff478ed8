//! The model kernels at every level this CPU has (the NBRDF-json networks' tiny-network kernels are
//! checked beside them, in `src/measured/nbrdf_json/tiny.rs`):
//! `.nbrdf` models with f16 weights, widened at load (`ModelBuf`) or row by row as they are read
//! (`Model::from_bytes`), against the f32 model of the same values, bit for bit, at every level.

use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf, Prepared};
use nbrdf::kernels::{set_level, Level};
use nbrdf::Vec3;
use std::sync::Mutex;

mod common;
use common::{bytes, words};

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

/// An f16 file evaluates alike however it is held: a `ModelBuf` widens it to f32 once at load, a
/// `Model` over the borrowed f16 bytes (or `ModelBuf::from_bytes_as_is`) widens each row as its
/// kernels read it (one query, dense and sparse packets, the chain kernel), and all give every pair the bits of the f32 model whose
/// weights are the f16 values (the widening is exact and the f16 kernels sum in the f32 ones'
/// order): single queries, batches in one call and in calls of 40 pairs, `prepare` and
/// `prepare_many`, at every level, on several threads at once.
#[test]
fn f16_files_widened_at_load_or_row_by_row_give_the_bits_of_f32_weights() {
    let _level = LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rng = Rng(0x9e3779b97f4a7c15);
    let pos = PositionEncoding::Intrinsic { k: 6 };
    // (kind, the f32 model of the f16 values, the f16 file, its ModelBuf)
    let models: Vec<(ModelKind, ModelBuf, Vec<u32>, usize, ModelBuf)> = [ModelKind::SingleMlp, ModelKind::AdditiveShared, ModelKind::AdditiveSeparate]
        .into_iter()
        .map(|kind| {
            let h = ModelHeader::paper(kind, kind.is_additive(), Reciprocity::Exact, pos, 4);
            let w: Vec<f32> = (0..h.n_weights()).map(|_| half::f16::from_f32(rng.next() * 0.3).to_f32()).collect();
            let f32_buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
            let f16_file = f32_buf.model().to_f16().unwrap();
            let f16_buf = ModelBuf::from_bytes(&f16_file).unwrap();
            assert_eq!((f16_buf.file_precision(), f16_buf.header().precision), (Precision::F16, Precision::F32));
            assert_eq!(f16_buf.as_bytes(), f32_buf.as_bytes(), "{kind:?}: the widened file is the f32 one");
            (kind, f32_buf, words(&f16_file), f16_file.len(), f16_buf)
        })
        .collect();
    let n = 200; // over several packets, and not a multiple of one
    let mut dir = || {
        let v = Vec3::new(rng.next(), rng.next(), rng.next() + 0.3);
        v.normalize_or_zero()
    };
    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|_| (dir(), dir())).unzip();
    let points: Vec<f32> = (0..20 * 6).map(|i| ((i * 37 % 23) as f32 - 11.0) * 0.1).collect();
    for level in Level::usable() {
        set_level(Some(level));
        let check = || {
            for (kind, f32_buf, f16_words, len, f16_buf) in models.iter() {
                let borrowed = Model::from_bytes(&bytes(f16_words)[..*len]).unwrap();
                assert_eq!(borrowed.header().precision, Precision::F16);
                let as_is = ModelBuf::from_bytes_as_is(&bytes(f16_words)[..*len]).unwrap();
                assert_eq!((as_is.file_precision(), as_is.header().precision), (Precision::F16, Precision::F16));
                let m32 = f32_buf.model();
                let mut want_prepared = vec![Prepared::default(); 20];
                m32.prepare_many(&points, &mut want_prepared).unwrap();
                for (name, m) in [("ModelBuf", f16_buf.model()), ("borrowed f16", borrowed), ("ModelBuf as is", as_is.model())] {
                    let mut prepared = vec![Prepared::default(); 20];
                    m.prepare_many(&points, &mut prepared).unwrap();
                    for (q, (p, p32)) in prepared.iter().zip(&want_prepared).enumerate().step_by(7) {
                        let mut want = vec![[f32::NAN; 3]; n];
                        m32.eval_many(p32, &wi, &wo, &mut want);
                        let nonzero = want.iter().filter(|f| **f != [0.0; 3]).count();
                        assert!(nonzero > n / 2, "{kind:?}: most pairs are valid ({nonzero})");
                        let one = m.prepare(&points[q * 6..(q + 1) * 6]).unwrap();
                        let mut whole = vec![[f32::NAN; 3]; n];
                        m.eval_many(p, &wi, &wo, &mut whole);
                        let mut chunked = vec![[f32::NAN; 3]; n];
                        for (k, out) in chunked.chunks_mut(40).enumerate() {
                            m.eval_many(&one, &wi[k * 40..], &wo[k * 40..], out);
                        }
                        for i in 0..n {
                            let bits = want[i].map(f32::to_bits);
                            assert_eq!(whole[i].map(f32::to_bits), bits, "{level:?} {kind:?} {name} point {q} pair {i}: batch");
                            assert_eq!(chunked[i].map(f32::to_bits), bits, "{level:?} {kind:?} {name} point {q} pair {i}: calls of 40");
                            assert_eq!(m.eval(&one, wi[i], wo[i]).map(f32::to_bits), bits, "{level:?} {kind:?} {name} point {q} pair {i}: single");
                        }
                    }
                }
            }
        };
        check();
        std::thread::scope(|s| {
            for _ in 0..3 {
                s.spawn(check);
            }
        });
    }
    set_level(None);
}


/// Each header's model with random weights as an f32 and an f16 file, in 4-byte aligned words with
/// their lengths, for `Model::from_bytes`: borrowed, so that the f16 file's rows stay f16.
fn files_of(headers: &[ModelHeader], rng: &mut Rng) -> Vec<(Vec<u32>, usize)> {
    let mut files = Vec::new();
    for h in headers {
        let w: Vec<f32> = (0..h.n_weights()).map(|_| rng.next() * 0.3).collect();
        let f32_file = encode(h, &w, None).unwrap();
        let f16_file = ModelBuf::from_bytes(&f32_file).unwrap().model().to_f16().unwrap();
        files.push((words(&f32_file), f32_file.len()));
        files.push((words(&f16_file), f16_file.len()));
    }
    files
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
        models.extend(files_of(&headers, &mut rng));
    }
    let pairs: Vec<(Vec3, Vec3)> = (0..6)
        .map(|_| (Vec3::new(rng.next(), rng.next(), rng.next() + 0.6).normalize(), Vec3::new(rng.next(), rng.next(), rng.next() + 0.6).normalize()))
        .collect();
    for level in Level::usable() {
        set_level(Some(level));
        for (w, len) in &models {
            let m = Model::from_bytes(&bytes(w)[..*len]).unwrap();
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
                let mut many = vec![Prepared::default(); n];
                m.prepare_many(&points, &mut many).unwrap();
                for (i, p) in many.iter().enumerate() {
                    let one = m.prepare(&points[i * k..(i + 1) * k]).unwrap();
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

/// Every level a host runs gives every model kind the values of the portable level within the
/// cross-level bound (README, "CPUs and kernel levels"): the levels differ only in fusing each
/// multiply-add, so a layer's sum of K terms moves by at most K·u of its terms' magnitudes and a
/// paper-size network's output by ~1e-6 relative. Single queries and batches, f32 and f16 rows.
#[test]
fn every_level_agrees_with_the_portable_one_within_the_rounding_bound() {
    let _level = LEVEL.lock().unwrap_or_else(|e| e.into_inner());
    let mut rng = Rng(0x5851f42d4c957f2d);
    let pos = PositionEncoding::Intrinsic { k: 6 };
    let mut headers: Vec<ModelHeader> =
        nbrdf::parametric::ParametricKind::ALL.iter().map(|&k| ModelHeader::paper(ModelKind::Parametric(k), false, Reciprocity::None, pos, 0)).collect();
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
        headers.push(ModelHeader::paper(kind, kind.is_additive(), Reciprocity::Exact, pos, 4));
    }
    let files = files_of(&headers, &mut rng);
    let point: Vec<f32> = (0..6).map(|_| rng.next()).collect();
    let n = 100;
    let mut dir = || Vec3::new(rng.next(), rng.next(), rng.next() + 0.6).normalize();
    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|_| (dir(), dir())).unzip();
    let run = |m: &Model<'_>| {
        let p = m.prepare(&point[..m.position_len()]).unwrap();
        let single: Vec<[f32; 3]> = wi.iter().zip(&wo).map(|(a, b)| m.eval(&p, *a, *b)).collect();
        let mut batch = vec![[0.0f32; 3]; n];
        m.eval_many(&p, &wi, &wo, &mut batch);
        (single, batch)
    };
    let mut worst = 0.0f32;
    for (w, len) in &files {
        let m = Model::from_bytes(&bytes(w)[..*len]).unwrap();
        set_level(Some(Level::Portable));
        let (want, _) = run(&m);
        let scale = want.iter().flatten().fold(0.0f32, |a, v| a.max(v.abs())).max(1e-30);
        for level in Level::usable() {
            set_level(Some(level));
            let (single, batch) = run(&m);
            for (got, what) in [(&single, "single"), (&batch, "batch")] {
                let err = got.iter().flatten().zip(want.iter().flatten()).fold(0.0f32, |a, (g, e)| a.max((g - e).abs())) / scale;
                assert!(err <= 1e-5, "{level} {what} {:?} {:?}: {err:e} from the portable level", m.header().kind, m.header().precision);
                worst = worst.max(err);
            }
        }
    }
    set_level(None);
    println!("largest difference from the portable level, relative to the largest value: {worst:e}");
}
