//! Energy conservation by construction (`nbrdf::energy`, docs/models.md "Energy bound"): a model bounded
//! with its own albedo table reflects at most all the light at every view angle — checked by a
//! quadrature independent of the one the bound was fitted with, at view angles between its nodes —
//! keeps exact reciprocity bit for bit, evaluates the same one pair at a time and in packets, samples
//! with weights of the bounded values, and is a version-2 file that a version-1 reader refuses.

use nbrdf::energy::{albedo_at, AlbedoBound, ALBEDO_CELLS};
use nbrdf::file::{encode, set_albedo_bound, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf::parametric::ParametricKind;
use nbrdf::{Brdf, Error, ModelBuf, Prepared, Vec3};

mod common;
use common::{albedo, r3, weights};


/// The unbounded model file and the same file bounded over `points` (position inputs).
fn bounded_pair(h: &ModelHeader, seed: u64, scale: f32, points: &[Vec<f32>]) -> (ModelBuf, ModelBuf, Vec<Prepared>) {
    let bytes = encode(h, &weights(h.n_weights(), seed, scale), None).unwrap();
    let raw = ModelBuf::from_bytes(&bytes).unwrap();
    let prepared: Vec<Prepared> = points.iter().map(|p| raw.model().prepare(p).unwrap()).collect();
    let bound = raw.model().fit_albedo_bound(&prepared);
    let bounded = ModelBuf::from_bytes(&set_albedo_bound(&bytes, Some(bound)).unwrap()).unwrap();
    (raw, bounded, prepared)
}

/// Directions spread over the upper hemisphere (a Fibonacci spiral), grazing ones included.
fn directions(n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let z = 1.0 - (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f32 * 2.399_963;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// The cases: each purely neural kind on Θ, and an MLP predicting Torrance-Sparrow's parameters (32 wide, for
/// the forced portable kernels' sake), with weights large enough that the unbounded albedo passes 1
/// at some views and not at others.
fn cases() -> Vec<(&'static str, ModelHeader, f32)> {
    let pe = PositionEncoding::Extrinsic { frequencies: 1 };
    let paper = |kind, enhanced| ModelHeader::paper(kind, enhanced, Reciprocity::Exact, pe, 2).with_width(32);
    vec![
        ("single-mlp", paper(ModelKind::SingleMlp, false), 0.3),
        ("additive-separate-enhanced", paper(ModelKind::AdditiveSeparate, true), 0.3),
        ("additive-shared", paper(ModelKind::AdditiveShared, false), 0.3),
        ("torrance-sparrow", paper(ModelKind::Parametric(ParametricKind::TorranceSparrow), false), 0.8),
    ]
}

/// The mean sample weight over `n` draws (the albedo) and its standard error, per channel.
fn sampled_albedo(sample: &dyn Fn([f32; 3]) -> Option<nbrdf::BsdfSample>, n: usize, seed: u64) -> ([f64; 3], [f64; 3]) {
    let (mut sum, mut sq) = ([0.0f64; 3], [0.0f64; 3]);
    for i in 0..n {
        let Some(s) = sample(r3(i, seed as f64 * 0.618_034)) else { continue };
        for c in 0..3 {
            sum[c] += s.weight[c] as f64;
            sq[c] += (s.weight[c] as f64).powi(2);
        }
    }
    let mean = sum.map(|x| x / n as f64);
    let se = core::array::from_fn(|c| ((sq[c] / n as f64 - mean[c] * mean[c]).max(0.0) / n as f64).sqrt());
    (mean, se)
}

fn points() -> Vec<Vec<f32>> {
    vec![vec![0.3, -0.2, 0.5], vec![-0.6, 0.1, 0.2]]
}

/// At 41 views between and on the table's nodes, at every point the bound was fitted over, the bounded
/// model's albedo by an (n = 112)² quadrature in (cos θi, φi), and by its own importance sampling
/// (within 3 standard errors), is at most 1 + 1e-3 in every channel,
/// while the unbounded model's passes 1 somewhere (so the bound had work to do).
#[test]
fn bounded_models_reflect_at_most_the_light_they_receive() {
    std::thread::scope(|scope| {
        for (name, h, scale) in cases() {
            scope.spawn(move || {
                let (raw, bounded, prepared) = bounded_pair(&h, 7, scale, &points());
                let (raw, bounded) = (raw.model(), bounded.model());
                let mut worst_raw = 0.0f64;
                for p in &prepared {
                    for k in 0..41 {
                        let cos_o = 1.0 - (k as f32 + 0.37) / 41.0;
                        let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
                        let a = albedo(&|wi, wo| bounded.eval(p, wi, wo), wo, 112);
                        assert!(a.iter().all(|&c| c <= 1.0 + 1e-3), "{name}: albedo {a:?} at cos θo {cos_o}");
                        // And by the model's own importance sampling, which finds peaks a grid misses.
                        let (mean, se) = sampled_albedo(&|u| bounded.sample(p, wo, u), 4096, k as u64);
                        for c in 0..3 {
                            assert!(mean[c] - 3.0 * se[c] <= 1.0 + 1e-3, "{name}: sampled albedo {mean:?} ± {se:?} at cos θo {cos_o}");
                        }
                        if k % 4 == 0 {
                            let r = albedo(&|wi, wo| raw.eval(p, wi, wo), wo, 64);
                            worst_raw = r.iter().fold(worst_raw, |m, &c| m.max(c));
                        }
                    }
                }
                assert!(worst_raw > 1.05, "{name}: the unbounded model's largest albedo is only {worst_raw}");
                assert!(bounded.albedo_bound().unwrap().max() > 1.0, "{name}");
            });
        }
    });
}

/// Bounding keeps Θ's exact reciprocity bit for bit, one pair at a time and in packets; `eval_many`
/// gives `eval`'s bits; and where the table is at most 1 at both angles the value is the unbounded one.
#[test]
fn bounded_models_stay_bitwise_reciprocal_and_batch_like_single_queries() {
    let dirs = directions(97);
    for (name, h, scale) in cases() {
        let (raw, bounded, prepared) = bounded_pair(&h, 11, scale, &points()[..1]);
        let (raw, bounded, p) = (raw.model(), bounded.model(), &prepared[0]);
        let bound = *bounded.albedo_bound().unwrap();
        let (wi, wo): (Vec<Vec3>, Vec<Vec3>) =
            dirs.iter().flat_map(|&a| dirs.iter().step_by(7).map(move |&b| (a, b))).unzip();
        let mut many = vec![[0.0f32; 3]; wi.len()];
        let mut swapped = many.clone();
        bounded.eval_many(p, &wi, &wo, &mut many);
        bounded.eval_many(p, &wo, &wi, &mut swapped);
        let mut divided = 0;
        for i in 0..wi.len() {
            let f = bounded.eval(p, wi[i], wo[i]);
            assert_eq!(f, bounded.eval(p, wo[i], wi[i]), "{name}: reciprocity at pair {i}");
            assert_eq!(f, many[i], "{name}: eval_many at pair {i}");
            assert_eq!(f, swapped[i], "{name}: eval_many of the swapped pair {i}");
            let unbounded = raw.eval(p, wi[i], wo[i]);
            let (a, b) = (bound.at(wi[i].z), bound.at(wo[i].z));
            for c in 0..3 {
                let d = a[c].max(b[c]);
                if d <= 1.0 {
                    assert_eq!(f[c].to_bits(), unbounded[c].to_bits(), "{name}: pair {i} channel {c} changed under a bound ≤ 1");
                } else {
                    assert_eq!(f[c], unbounded[c] / d, "{name}: pair {i} channel {c}");
                    divided += 1;
                }
            }
        }
        assert!(divided > 0, "{name}: no value was divided");
    }
}

/// A bounded model samples the directions and pdf of the unbounded one, with its weight divided as
/// its values are (so `weight = f_b cos θi / pdf`); the mean weight is the bounded albedo.
#[test]
fn bounded_models_sample_their_bounded_values() {
    for (name, h, scale) in cases() {
        let (raw, bounded, _) = bounded_pair(&h, 3, scale, &points()[..1]);
        let brdf = bounded.model().at(&points()[0]).unwrap();
        let unbounded = raw.model().at(&points()[0]).unwrap();
        let bound = *bounded.model().albedo_bound().unwrap();
        for cos_o in [0.95f32, 0.5, 0.1] {
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let n: usize = 20_000;
            let mut mean = [0.0f64; 3];
            for i in 0..n {
                let u = r3(i, 0.0);
                let Some(s) = brdf.sample(wo, u) else { continue };
                let r = unbounded.sample(wo, u).unwrap();
                assert_eq!((s.wi, s.pdf), (r.wi, r.pdf), "{name}: the same draw");
                let f = brdf.eval(s.wi, wo);
                let ratio = bound.apply([1.0; 3], s.wi.z, wo.z);
                for c in 0..3 {
                    // Neural models evaluate the bounded f for the weight; parametric ones divide
                    // their lobes' weight: either way f_b cos / pdf, to rounding.
                    let expect = f[c] * s.wi.z / s.pdf;
                    let divided = r.weight[c] * ratio[c];
                    assert!((s.weight[c] - divided).abs() <= 1e-5 * divided.max(1e-6), "{name}: weight {:?} vs {:?} divided", s.weight, r.weight);
                    assert!((s.weight[c] - expect).abs() <= 1e-2 * expect.max(1e-3), "{name}: weight {:?} vs f cos / pdf {expect}", s.weight);
                    mean[c] += s.weight[c] as f64 / n as f64;
                }
            }
            // The half-vector rule of the bound resolves peaks that a grid in wi misses.
            let m = bounded.model();
            let p = m.prepare(&points()[0]).unwrap();
            let (a, _) = albedo_at(cos_o, |wi: &[Vec3], wo: &[Vec3], out: &mut [[f32; 3]]| m.eval_many(&p, wi, wo, out));
            let a = a.map(f64::from);
            for c in 0..3 {
                assert!((mean[c] - a[c]).abs() < 0.05 * a[c].max(0.05), "{name} cos θo {cos_o}: E[weight] {mean:?} vs albedo {a:?}");
            }
        }
    }
}

/// A bounded file is version 2; a version-1 reader would ignore the table and evaluate another
/// BRDF, so a file that claims version 1 with a bound is refused, and removing the bound gives the
/// original bytes back.
#[test]
fn a_bound_makes_a_version_two_file() {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let bytes = encode(&h, &weights(h.n_weights(), 1, 0.1), None).unwrap();
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 1, "an unbounded file stays version 1");
    let bounded = set_albedo_bound(&bytes, Some(AlbedoBound { cells: [[1.2, 0.9, 0.5]; ALBEDO_CELLS] })).unwrap();
    assert_eq!(u32::from_le_bytes(bounded[8..12].try_into().unwrap()), 2);
    assert_eq!(set_albedo_bound(&bounded, None).unwrap(), bytes);
    // The same bytes claiming version 1 (checksum mended, so only the version is wrong).
    let mut v1 = bounded.clone();
    v1[8..12].copy_from_slice(&1u32.to_le_bytes());
    let n = v1.len();
    let crc = crc32fast::hash(&v1[..n - 4]);
    v1[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert!(matches!(ModelBuf::from_bytes(&v1), Err(Error::InvalidValue { what: "model file version", .. })));
    // A table that is not finite is refused when it is set, so a file can never carry it.
    let bad = AlbedoBound { cells: [[f32::INFINITY, 1.0, 1.0]; ALBEDO_CELLS] };
    assert!(set_albedo_bound(&bytes, Some(bad)).is_err());
}
