//! The `.nbrdf` file and the neural evaluator: the forward pass of `docs/models.md` against an
//! independent reference, the prepare/eval split, exact reciprocity, f16 storage, and a specific error
//! for every malformed file.

use nbrdf::angles::{rusinkiewicz_angles, theta_map};
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf, Weights};
use nbrdf::parametric::ParametricKind;
use nbrdf::{Error, Vec3};

mod common;
use common::weights;

fn dir(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z).normalize()
}

/// Reference MLP, written from docs/models.md without the evaluator's tricks: explicit
/// concatenation for the skip, `[in][out]` indexing, f64 accumulation.
fn ref_mlp(w: &[f32], n_in: usize, width: usize, hidden: usize, n_out: usize, skip: usize, x: &[f64]) -> Vec<f64> {
    assert_eq!(x.len(), n_in);
    let mut off = 0;
    let mut h: Vec<f64> = x.to_vec();
    let layer = |off: &mut usize, input: &[f64], n_o: usize, act: bool| -> Vec<f64> {
        let n_i = input.len();
        let m = &w[*off..*off + n_i * n_o];
        let b = &w[*off + n_i * n_o..*off + (n_i + 1) * n_o];
        *off += (n_i + 1) * n_o;
        (0..n_o)
            .map(|o| {
                let s = b[o] as f64 + (0..n_i).map(|i| input[i] * m[i * n_o + o] as f64).sum::<f64>();
                if act { s.max(0.0) } else { s }
            })
            .collect()
    };
    for l in 0..hidden {
        let input: Vec<f64> = if skip != 0 && l == skip { h.iter().chain(x).copied().collect() } else { h };
        h = layer(&mut off, &input, width, true);
    }
    if n_out > 0 {
        h = layer(&mut off, &h, n_out, false);
    }
    assert_eq!(off, w.len(), "reference consumed every weight");
    h
}

fn ref_pe(v: &[f32], f: usize) -> Vec<f64> {
    let mut out = vec![];
    for &x in v {
        let x = x as f64;
        out.push(x);
        for k in 0..f {
            let a = x * (1u64 << k) as f64;
            out.push(a.sin());
            out.push(a.cos());
        }
    }
    out
}

fn softplus(x: f64) -> f64 {
    x.max(0.0) + (-x.abs()).exp().ln_1p()
}
fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn assert_close(got: [f32; 3], want: [f64; 3], what: &str) {
    for c in 0..3 {
        let err = (got[c] as f64 - want[c]).abs() / want[c].abs().max(1e-3);
        assert!(err < 2e-5, "{what}: channel {c}: got {} want {}", got[c], want[c]);
    }
}

/// `(wi, wo)` evaluated through the batched path, in the middle lane of a packet of other pairs.
fn eval_one_batched(model: &Model<'_>, prepared: &nbrdf::Prepared, wi: Vec3, wo: Vec3) -> [f32; 3] {
    let mut a: Vec<Vec3> = (0..11).map(|i| dir(0.1 * i as f32, 0.2, 0.9)).collect();
    let mut b = a.clone();
    b.reverse();
    a[5] = wi;
    b[5] = wo;
    let mut out = vec![[0.0f32; 3]; 11];
    model.eval_many(prepared, &a, &b, &mut out);
    out[5]
}

const DIRS: [(f32, f32, f32, f32, f32, f32); 4] = [
    (0.3, 0.1, 0.9, -0.5, 0.2, 0.7),
    (0.0, 0.0, 1.0, 0.6, 0.0, 0.8),
    (-0.2, 0.7, 0.3, 0.1, -0.3, 0.95),
    (0.9, 0.0, 0.05, 0.85, 0.1, 0.1),
];

#[test]
fn additive_shared_enhanced_matches_the_reference_forward_pass() {
    let k = 8;
    let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Intrinsic { k }, 3);
    let w = weights(h.n_weights(), 1, 0.15);
    let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    let model = buf.model();
    let p: Vec<f32> = (0..k).map(|i| (i as f32 * 0.37).sin()).collect();
    let prepared = model.prepare(&p).unwrap();

    let n = h.nets();
    let (w0, rest) = w.split_at(n[0].n_weights());
    let (w1, w2) = rest.split_at(n[1].n_weights());
    let pd: Vec<f64> = p.iter().map(|&x| x as f64).collect();
    let trunk = ref_mlp(w0, k as usize, 128, 5, 0, 2, &pd);
    let d = ref_mlp(w1, 128, 128, 1, 3, 0, &trunk);
    for (a, b, c, x, y, z) in DIRS {
        let (wi, wo) = (dir(a, b, c), dir(x, y, z));
        let theta = theta_map(wi, wo).unwrap();
        let input: Vec<f64> = trunk.iter().copied().chain(ref_pe(&theta, 3)).collect();
        let s = ref_mlp(w2, input.len(), 128, 2, 6, 0, &input);
        let want: [f64; 3] = std::array::from_fn(|c| {
            (1.0 - sigmoid(s[3 + c])) * sigmoid(d[c]) / std::f64::consts::PI + softplus(s[c])
        });
        assert_close(model.eval(&prepared, wi, wo), want, "additive shared");
        assert_close(eval_one_batched(&model, &prepared, wi, wo), want, "additive shared, batched");
    }
}

#[test]
fn single_mlp_and_additive_separate_match_the_reference() {
    let k = 5;
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate] {
        let h = ModelHeader::paper(kind, false, Reciprocity::None, PositionEncoding::Intrinsic { k }, 4);
        let w = weights(h.n_weights(), 2, 0.12);
        let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
        let model = buf.model();
        let p: Vec<f32> = (0..k).map(|i| 0.2 * i as f32 - 0.4).collect();
        let pd: Vec<f64> = p.iter().map(|&x| x as f64).collect();
        let prepared = model.prepare(&p).unwrap();
        for (a, b, c, x, y, z) in DIRS {
            let (wi, wo) = (dir(a, b, c), dir(x, y, z));
            let ang = ref_pe(&rusinkiewicz_angles(wi, wo).unwrap(), 4);
            let input: Vec<f64> = pd.iter().copied().chain(ang).collect();
            let want: [f64; 3] = match kind {
                ModelKind::SingleMlp => {
                    let o = ref_mlp(&w, input.len(), 128, 6, 3, 2, &input);
                    std::array::from_fn(|c| softplus(o[c]))
                }
                _ => {
                    let (wd, ws) = w.split_at(h.nets()[0].n_weights());
                    let d = ref_mlp(wd, k as usize, 128, 4, 3, 1, &pd);
                    let s = ref_mlp(ws, input.len(), 128, 4, 3, 1, &input);
                    std::array::from_fn(|c| sigmoid(d[c]) / std::f64::consts::PI + softplus(s[c]))
                }
            };
            assert_close(model.eval(&prepared, wi, wo), want, &format!("{kind:?}"));
            assert_close(eval_one_batched(&model, &prepared, wi, wo), want, &format!("{kind:?}, batched"));
        }
    }
}

#[test]
fn direction_layer_ablation_single_mlp_matches_trunk_plus_head() {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Extrinsic { frequencies: 2 }, 2)
        .with_direction_layers(3);
    let w = weights(h.n_weights(), 3, 0.12);
    let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    let model = buf.model();
    let x = [0.2f32, -0.5, 0.1];
    let prepared = model.prepare(&x).unwrap();
    let (wt, wh) = w.split_at(h.nets()[0].n_weights());
    let trunk = ref_mlp(wt, 15, 128, 3, 0, 0, &ref_pe(&x, 2));
    let (wi, wo) = (dir(0.3, 0.1, 0.9), dir(-0.5, 0.2, 0.7));
    let input: Vec<f64> = trunk.into_iter().chain(ref_pe(&theta_map(wi, wo).unwrap(), 2)).collect();
    let o = ref_mlp(wh, 128 + 20, 128, 3, 3, 0, &input);
    assert_close(model.eval(&prepared, wi, wo), std::array::from_fn(|c| softplus(o[c])), "NOL 3");
    assert_close(eval_one_batched(&model, &prepared, wi, wo), std::array::from_fn(|c| softplus(o[c])), "NOL 3, batched");
}

#[test]
fn exact_reciprocity_is_bitwise_for_every_neural_kind_and_absent_without_it() {
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
        for recip in [Reciprocity::Exact, Reciprocity::None] {
            let h = ModelHeader::paper(kind, kind.is_additive(), recip, PositionEncoding::Uniform, 4);
            let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights(), 4, 0.2), None).unwrap()).unwrap();
            let model = buf.model();
            let p = model.prepare(&[]).unwrap();
            let mut max_diff = 0.0f32;
            for i in 0..200 {
                let t = i as f32 * 0.731;
                let wi = dir(t.sin() * 0.7, (t * 1.3).cos() * 0.7, 0.3 + (t * 0.7).sin().abs());
                let wo = dir((t * 2.1).cos() * 0.6, (t * 0.4).sin() * 0.8, 0.2 + (t * 1.9).cos().abs());
                let (a, b) = (model.eval(&p, wi, wo), model.eval(&p, wo, wi));
                if recip == Reciprocity::Exact {
                    assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{kind:?} at {wi} {wo}");
                }
                max_diff = (0..3).map(|c| (a[c] - b[c]).abs()).fold(max_diff, f32::max);
            }
            if recip == Reciprocity::None {
                assert!(max_diff > 1e-4, "{kind:?}: random weights should not be reciprocal by accident");
            }
        }
    }
}

/// Weights, object parameters and the position table read back from a file are exactly what was
/// encoded, so a model can be written again (here with f16 weights) without knowing the file layout.
#[test]
fn a_model_reencodes_from_its_own_parts() {
    let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::FresnelMicrofacet), false, Reciprocity::None, PositionEncoding::Intrinsic { k: 2 }, 0);
    assert!(h.n_object() > 0, "FMBRDF carries object parameters");
    let w = weights(h.n_weights(), 9, 0.1);
    let table = [0.5f32, -1.0, 2.0, 0.25];
    let buf = ModelBuf::from_bytes(&encode(&h, &w, Some(&table)).unwrap()).unwrap();
    let m = buf.model();
    let Weights::F32(net) = m.weights() else { panic!("f32 file") };
    let n_net = h.n_weights() - h.n_object();
    assert_eq!((net, m.object_parameters(), m.position_table()), (&w[..n_net], &w[n_net..], &table[..]));

    let mut parts = net.to_vec();
    parts.extend_from_slice(m.object_parameters());
    let mut h16 = *m.header();
    h16.precision = Precision::F16;
    h16.n_vertices = 0;
    let f16_file = encode(&h16, &parts, Some(m.position_table())).unwrap();
    let buf16 = ModelBuf::from_bytes(&f16_file).unwrap();
    let m16 = buf16.model();
    assert_eq!((m16.object_parameters(), m16.position_table()), (m.object_parameters(), m.position_table()));
    assert_eq!(m16.header().n_vertices, 2);
    // Held widened to f32 (the same values), the model re-encodes to the f16 file it was loaded from.
    assert_eq!((buf16.file_precision(), m16.header().precision), (Precision::F16, Precision::F32));
    assert_eq!(m16.to_f16().unwrap(), f16_file);
}

#[test]
fn parametric_network_predicts_the_model_parameters() {
    let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::Phong), false, Reciprocity::None, PositionEncoding::Intrinsic { k: 4 }, 0);
    assert_eq!(h.nets()[0].n_out as usize, ParametricKind::Phong.n_raw());
    let w = weights(h.n_weights(), 5, 0.1);
    let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    let model = buf.model();
    let p = [0.1f32, 0.2, 0.3, 0.4];
    let prepared = model.prepare(&p).unwrap();
    let raw = ref_mlp(&w, 4, 128, 6, ParametricKind::Phong.n_raw(), 2, &p.map(|x| x as f64));
    let raw32: Vec<f32> = raw.iter().map(|&x| x as f32).collect();
    let direct = nbrdf::parametric::Parametric::from_raw(ParametricKind::Phong, &raw32, &[]);
    let (wi, wo) = (dir(0.3, 0.1, 0.9), dir(-0.3, -0.1, 0.9));
    let (a, b) = (model.eval(&prepared, wi, wo), direct.eval(wi, wo));
    for c in 0..3 {
        assert!((a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-3), "{a:?} vs {b:?}");
    }
    assert!(prepared.parameters().is_some());
}

#[test]
fn f16_files_are_half_the_size_and_evaluate_like_rounded_f32() {
    let mut h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 4);
    let w = weights(h.n_weights(), 6, 0.1);
    let f32_bytes = encode(&h, &w, None).unwrap();
    h.precision = Precision::F16;
    let f16_bytes = encode(&h, &w, None).unwrap();
    assert!(f16_bytes.len() < f32_bytes.len() * 55 / 100);
    let rounded: Vec<f32> = w.iter().map(|&x| half::f16::from_f32(x).to_f32()).collect();
    let mut h32 = h;
    h32.precision = Precision::F32;
    let (m16, m32) = (ModelBuf::from_bytes(&f16_bytes).unwrap(), ModelBuf::from_bytes(&encode(&h32, &rounded, None).unwrap()).unwrap());
    let (wi, wo) = (dir(0.3, 0.1, 0.9), dir(-0.5, 0.2, 0.7));
    let (a, b) = (m16.model().eval(&m16.model().prepare(&[]).unwrap(), wi, wo), m32.model().eval(&m32.model().prepare(&[]).unwrap(), wi, wo));
    assert_eq!(a, b);
    // Weights beyond the f16 range are refused at export instead of turning into infinities.
    let mut big = w.clone();
    big[10] = 1e6;
    assert!(matches!(encode(&h, &big, None), Err(Error::NonFinite { index: 10, .. })));
}

#[test]
fn model_buf_puts_the_per_query_network_on_a_cache_line_and_evaluates_as_in_place() {
    // The one-query kernels load rows of 128 weights as vectors; ModelBuf aligns the network that runs
    // per query (the last one), in every clone, and the values do not depend on where the bytes lie.
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
        let h = ModelHeader::paper(kind, true, Reciprocity::Exact, PositionEncoding::Uniform, 2);
        let bytes = encode(&h, &weights(h.n_weights(), 5, 0.2), None).unwrap();
        let at = Model::query_weights_offset_of(&bytes).unwrap();
        // A truncated file has no such offset: the loader's own error.
        assert!(matches!(Model::query_weights_offset_of(&bytes[..bytes.len() - 8]), Err(Error::Truncated { .. })));
        let buf = ModelBuf::from_bytes(&bytes).unwrap();
        let copy = buf.clone();
        for b in [&buf, &copy] {
            assert_eq!((b.as_bytes().as_ptr() as usize + at) % 64, 0, "{kind:?}");
            assert_eq!(b.as_bytes(), &bytes[..]);
        }
        // The same file 4 bytes off a cache line, borrowed in place.
        let mut words = vec![0u32; bytes.len().div_ceil(4) + 32];
        let base = words.as_ptr() as usize;
        let skew = ((64 - (base + at) % 64) % 64 + 4) % 64;
        // SAFETY: words has room for skew + bytes.len() bytes (skew < 64 < 32 words); u8 view of u32s.
        let raw = unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), words.len() * 4) };
        raw[skew..skew + bytes.len()].copy_from_slice(&bytes);
        let in_place = Model::from_bytes(&raw[skew..skew + bytes.len()]).unwrap();
        let (m, p, q) = (buf.model(), buf.model().prepare(&[]).unwrap(), in_place.prepare(&[]).unwrap());
        for (wi, wo) in [(dir(0.2, 0.1, 1.0), dir(-0.4, 0.3, 0.8)), (dir(0.7, 0.0, 0.3), dir(0.0, -0.6, 0.5))] {
            let (a, b) = (m.eval(&p, wi, wo), in_place.eval(&q, wi, wo));
            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{kind:?}");
        }
    }
}

#[test]
fn position_table_interpolates_per_vertex_features() {
    let h = ModelHeader::paper(ModelKind::AdditiveSeparate, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 2 }, 1);
    let table = [0.0f32, 1.0, 10.0, 20.0, 100.0, 200.0]; // 3 vertices x k = 2
    let bytes = encode(&h, &weights(h.n_weights(), 7, 0.1), Some(&table)).unwrap();
    let buf = ModelBuf::from_bytes(&bytes).unwrap();
    assert_eq!(buf.header().n_vertices, 3);
    let mut out = [0.0f32; 2];
    buf.model().position_features([0, 1, 2], [0.5, 0.25, 0.25], &mut out).unwrap();
    assert_eq!(out, [0.5 * 0.0 + 0.25 * 10.0 + 0.25 * 100.0, 0.5 * 1.0 + 0.25 * 20.0 + 0.25 * 200.0]);
    assert!(matches!(buf.model().position_features([0, 1, 3], [1.0, 0.0, 0.0], &mut out), Err(Error::SizeMismatch { .. })));
}

#[test]
fn invalid_points_and_directions_evaluate_to_zero() {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 3 }, 2);
    let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights(), 8, 0.1), None).unwrap()).unwrap();
    let m = buf.model();
    // A point of the wrong length is an error; the state of no point evaluates to 0.
    assert!(matches!(m.prepare(&[1.0, 2.0]), Err(Error::SizeMismatch { what: "point input", expected: 3, found: 2 })));
    assert_eq!(m.eval(&nbrdf::Prepared::default(), Vec3::Z, Vec3::Z), [0.0; 3]);
    assert!(matches!(m.prepare(&[1.0]), Err(Error::SizeMismatch { what: "point input", expected: 3, found: 1 })));
    let p = m.prepare(&[0.1, 0.2, 0.3]).unwrap();
    assert!(m.eval(&p, Vec3::Z, Vec3::Z)[0] > 0.0);
    for (wi, wo) in [
        (Vec3::new(0.0, 0.0, -1.0), Vec3::Z),
        (Vec3::new(1.0, 0.0, 0.0), Vec3::Z),
        (Vec3::new(f32::NAN, 0.0, 1.0), Vec3::Z),
        (Vec3::ZERO, Vec3::Z),
    ] {
        assert_eq!(m.eval(&p, wi, wo), [0.0; 3]);
    }
    // A NaN point input never leaks out as NaN.
    let nan = m.prepare(&[f32::NAN, 0.0, 0.0]).unwrap();
    assert!(m.eval(&nan, Vec3::Z, Vec3::Z).iter().all(|c| c.is_finite()));
}

/// A valid reference file and its header length.
fn valid_file() -> (Vec<u8>, ModelHeader) {
    let h = ModelHeader::paper(ModelKind::AdditiveSeparate, true, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 4 }, 2);
    (encode(&h, &weights(h.n_weights(), 9, 0.1), None).unwrap(), h)
}

fn fix_crc(bytes: &mut [u8]) {
    let n = bytes.len() - 4;
    let crc = crc32fast::hash(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn every_malformed_file_gets_its_specific_error() {
    let (good, _) = valid_file();
    assert!(ModelBuf::from_bytes(&good).is_ok());

    // Truncated anywhere: magic, version, header, weights, checksum.
    for cut in [0, 5, 10, 14, 20, good.len() / 2, good.len() - 1] {
        assert!(matches!(ModelBuf::from_bytes(&good[..cut]), Err(Error::Truncated { .. })), "cut at {cut}");
    }
    let mut b = good.clone();
    b[0] = b'X';
    assert_eq!(ModelBuf::from_bytes(&b).unwrap_err(), Error::BadMagic { what: "nbrdf model" });

    for v in [0u32, nbrdf::file::VERSION + 1, u32::MAX] {
        let mut b = good.clone();
        b[8..12].copy_from_slice(&v.to_le_bytes());
        assert!(matches!(ModelBuf::from_bytes(&b), Err(Error::UnsupportedVersion { found, .. }) if found == v));
    }

    let mut b = good.clone();
    b.extend_from_slice(&[0; 4]);
    assert!(matches!(ModelBuf::from_bytes(&b), Err(Error::SizeMismatch { what: "model file size", .. })));

    let mut b = good.clone();
    let mid = b.len() / 2;
    b[mid] ^= 0x40;
    assert!(matches!(ModelBuf::from_bytes(&b), Err(Error::ChecksumMismatch { .. })));

    // NaN weight with a correct checksum: caught by the finiteness check, with its index.
    let mut b = good.clone();
    let header_len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    let w0 = (16 + header_len).div_ceil(4) * 4;
    b[w0 + 12..w0 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    fix_crc(&mut b);
    assert_eq!(ModelBuf::from_bytes(&b).unwrap_err(), Error::NonFinite { what: "network weights", index: 3 });

    // A header length pointing past the end.
    let mut b = good.clone();
    b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(ModelBuf::from_bytes(&b), Err(Error::Truncated { what: "model header", .. })));

    // Garbage header bytes.
    let mut b = good.clone();
    for x in &mut b[16..16 + header_len] {
        *x = 0xff;
    }
    fix_crc(&mut b);
    assert!(matches!(ModelBuf::from_bytes(&b), Err(Error::InvalidValue { what: "model header", .. })));

    // A header whose network shapes disagree with the model kind.
    let (_, mut h) = valid_file();
    h.nets[1].n_in += 1;
    assert!(matches!(h.validate(), Err(Error::SizeMismatch { what: "specular network", .. })));
    assert!(matches!(encode(&h, &vec![0.0; h.n_weights()], None), Err(Error::SizeMismatch { .. })));
    let (_, h) = valid_file();
    assert!(matches!(encode(&h, &[0.0; 3], None), Err(Error::SizeMismatch { what: "exported weights", .. })));
}

#[test]
fn zero_copy_load_borrows_aligned_bytes_and_refuses_misaligned_ones() {
    let (good, h) = valid_file();
    // u32 storage guarantees 4-byte alignment.
    let mut words = vec![0u32; good.len().div_ceil(4) + 1];
    let bytes: &mut [u8] = bytemuck_free_bytes(&mut words);
    bytes[..good.len()].copy_from_slice(&good);
    let model = Model::from_bytes(&bytes[..good.len()]).unwrap();
    assert_eq!(model.header(), &h);
    bytes.copy_within(0..good.len(), 1);
    assert_eq!(Model::from_bytes(&bytes[1..good.len() + 1]).unwrap_err(), Error::Misaligned);
}

fn bytemuck_free_bytes(words: &mut [u32]) -> &mut [u8] {
    // SAFETY: u8 has no alignment requirement and every byte of a u32 slice is initialised.
    unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), words.len() * 4) }
}

#[cfg(feature = "std")]
#[test]
fn load_names_the_missing_path_and_save_is_atomic() {
    let dir = std::env::temp_dir().join(format!("nbrdf-model-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("missing.nbrdf");
    let err = ModelBuf::load(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.nbrdf"), "{err}");
    let (good, h) = valid_file();
    let path = dir.join("m.nbrdf");
    nbrdf::file::save(&path, &good).unwrap();
    assert_eq!(ModelBuf::load(&path).unwrap().header(), &h);
    // No temporary file is left beside it.
    let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".tmp")).collect();
    assert!(leftovers.is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

/// Pseudo-random direction pairs, about a quarter of them invalid (below the horizon, zero, NaN).
fn pairs(n: usize, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let r = weights(6 * n, seed, 1.0);
    let mut wi = vec![];
    let mut wo = vec![];
    for (i, c) in r.chunks_exact(6).enumerate() {
        let mut a = Vec3::new(c[0], c[1], c[2].abs() + 0.05);
        let mut b = Vec3::new(c[3], c[4], c[5].abs() + 0.05);
        match i % 13 {
            3 => a.z = -a.z,
            7 => b = Vec3::ZERO,
            11 => a.x = f32::NAN,
            12 => b.z = -0.0,
            _ => {}
        }
        wi.push(a.normalize_or_zero());
        wo.push(b.normalize_or_zero());
    }
    (wi, wo)
}

#[test]
fn batched_evaluation_equals_single_queries_bit_for_bit() {
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
        for (recip, enhanced, precision) in [
            (Reciprocity::Exact, true, Precision::F32),
            (Reciprocity::None, false, Precision::F16),
            (Reciprocity::Swap, kind.is_additive(), Precision::F32),
        ] {
            let mut h = ModelHeader::paper(kind, enhanced && kind.is_additive(), recip, PositionEncoding::Intrinsic { k: 6 }, 3);
            h.precision = precision;
            let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights(), 9, 0.15), None).unwrap()).unwrap();
            let model = buf.model();
            let p = model.prepare(&[0.1, 0.5, -0.3, 0.2, 0.0, 0.9]).unwrap();
            let n = 203; // not a multiple of the packet size
            let (wi, wo) = pairs(n, 21);
            let mut many = vec![[f32::NAN; 3]; n];
            model.eval_many(&p, &wi, &wo, &mut many);
            let mut zeros = 0;
            for i in 0..n {
                let single = model.eval(&p, wi[i], wo[i]);
                assert_eq!(many[i].map(f32::to_bits), single.map(f32::to_bits), "{kind:?} {recip:?} {precision:?} pair {i}");
                zeros += (single == [0.0; 3]) as usize;
            }
            assert!(zeros >= n / 5, "the invalid pairs evaluate to 0");
            // Only valid pairs: whole packets straight from the encoder (Θ on AVX-512), the same bits.
            let (vi, vo): (Vec<Vec3>, Vec<Vec3>) = (0..n).filter(|&i| many[i] != [0.0; 3]).map(|i| (wi[i], wo[i])).unzip();
            let mut valid = vec![[f32::NAN; 3]; vi.len()];
            model.eval_many(&p, &vi, &vo, &mut valid);
            for (i, f) in valid.iter().enumerate() {
                assert_eq!(f.map(f32::to_bits), model.eval(&p, vi[i], vo[i]).map(f32::to_bits), "{kind:?} {recip:?} valid pair {i}");
            }
            if recip == Reciprocity::Exact {
                let mut swapped = vec![[0.0f32; 3]; n];
                model.eval_many(&p, &wo, &wi, &mut swapped);
                assert_eq!(many, swapped, "{kind:?}: exact reciprocity in batches");
            }
            // The structure-of-arrays entry point gives the same values.
            let split = |v: &[Vec3]| -> [Vec<f32>; 3] { [v.iter().map(|d| d.x).collect(), v.iter().map(|d| d.y).collect(), v.iter().map(|d| d.z).collect()] };
            let (a, b) = (split(&wi), split(&wo));
            let (mut r, mut g, mut bl) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
            model.eval_many_soa(&p, [&a[0], &a[1], &a[2]], [&b[0], &b[1], &b[2]], [&mut r, &mut g, &mut bl]);
            for i in 0..n {
                assert_eq!([r[i], g[i], bl[i]].map(f32::to_bits), many[i].map(f32::to_bits), "SoA pair {i}");
            }
        }
    }
}

/// A `ModelBuf` (which holds an f16 file widened to f32) and `Model::from_bytes` over a caller's
/// 4-aligned buffer (the file's weights in place, f16 rows widened as the kernels read them) give the
/// same bits, single queries and batches.
#[test]
fn model_buf_and_a_caller_buffer_evaluate_alike() {
    for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
        for precision in [Precision::F32, Precision::F16] {
            let mut h = ModelHeader::paper(kind, kind.is_additive(), Reciprocity::Exact, PositionEncoding::Intrinsic { k: 6 }, 3);
            h.precision = precision;
            let bytes = encode(&h, &weights(h.n_weights(), 5, 0.15), None).unwrap();
            let buf = ModelBuf::from_bytes(&bytes).unwrap();
            let mut words = vec![0u32; bytes.len().div_ceil(4)];
            for (w, c) in words.iter_mut().zip(bytes.chunks(4)) {
                let mut b = [0u8; 4];
                b[..c.len()].copy_from_slice(c);
                *w = u32::from_ne_bytes(b);
            }
            // SAFETY: `words` holds at least `bytes.len()` initialised bytes.
            let aligned = unsafe { std::slice::from_raw_parts(words.as_ptr().cast::<u8>(), bytes.len()) };
            let (a, b) = (buf.model(), Model::from_bytes(aligned).unwrap());
            let point = [0.1, 0.5, -0.3, 0.2, 0.0, 0.9];
            let (pa, pb) = (a.prepare(&point).unwrap(), b.prepare(&point).unwrap());
            assert_eq!(b.header().precision, precision);
            let (wi, wo) = pairs(203, 3);
            let (mut ma, mut mb) = (vec![[0.0; 3]; 203], vec![[0.0; 3]; 203]);
            a.eval_many(&pa, &wi, &wo, &mut ma);
            b.eval_many(&pb, &wi, &wo, &mut mb);
            for i in 0..203 {
                let bits = ma[i].map(f32::to_bits);
                assert_eq!(mb[i].map(f32::to_bits), bits, "{kind:?} {precision:?} pair {i}: batches");
                assert_eq!(a.eval(&pa, wi[i], wo[i]).map(f32::to_bits), bits, "{kind:?} {precision:?} pair {i}: ModelBuf single");
                assert_eq!(b.eval(&pb, wi[i], wo[i]).map(f32::to_bits), bits, "{kind:?} {precision:?} pair {i}: borrowed single");
            }
            assert!(ma.iter().filter(|f| **f != [0.0; 3]).count() > 203 / 2, "{kind:?}: most pairs are valid");
        }
    }
}

#[test]
fn batched_parametric_models_and_invalid_points_match_single_queries() {
    let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::Phong), false, Reciprocity::None, PositionEncoding::Intrinsic { k: 4 }, 0);
    let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights(), 5, 0.1), None).unwrap()).unwrap();
    let model = buf.model();
    let (wi, wo) = pairs(40, 3);
    for p in [model.prepare(&[0.1, 0.2, 0.3, 0.4]).unwrap(), nbrdf::Prepared::default()] {
        let mut many = vec![[f32::NAN; 3]; 40];
        model.eval_many(&p, &wi, &wo, &mut many);
        for i in 0..40 {
            assert_eq!(many[i], model.eval(&p, wi[i], wo[i]));
        }
    }
}

/// The mesh a table was fitted on travels in the header beside the proxy, covered by the checksum; a
/// model without a table records no mesh.
#[test]
fn the_fitted_mesh_hash_round_trips_and_needs_a_table() {
    use nbrdf::file::record_mesh;
    use nbrdf::sampling::{GgxLobe, Proxy};
    let proxy = Proxy::new(0.4, [GgxLobe { weight: 0.6, alpha: 0.1 }, GgxLobe::NONE]).unwrap();
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 3 }, 2)
        .with_proxy(proxy);
    let w: Vec<f32> = (0..h.n_weights()).map(|i| (i % 7) as f32 * 1e-2).collect();
    let table: Vec<f32> = (0..5 * 3).map(|i| i as f32 * 0.05).collect();
    let plain = encode(&h, &w, Some(&table)).unwrap();
    let stamped = record_mesh(&plain, 0x0123_4567_89ab_cdef).unwrap();
    let (a, b) = (nbrdf::ModelBuf::from_bytes(&plain).unwrap(), nbrdf::ModelBuf::from_bytes(&stamped).unwrap());
    assert_eq!(a.header().mesh_hash, None);
    assert_eq!(b.header().mesh_hash, Some(0x0123_4567_89ab_cdef));
    assert_eq!(b.header().proxy, Some(proxy));
    assert_eq!(ModelHeader { mesh_hash: None, ..*b.header() }, *a.header());
    // Re-encoding the stamped header gives the stamped file again.
    assert_eq!(encode(b.header(), &w, Some(&table)).unwrap(), stamped);
    // Any flipped bit of the hash is caught.
    let len = u32::from_le_bytes(stamped[12..16].try_into().unwrap()) as usize;
    let mut bad = stamped.clone();
    bad[16 + len - 2] ^= 0x10;
    assert!(nbrdf::ModelBuf::from_bytes(&bad).is_err());
    // No table, no mesh.
    let uniform = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let bytes = encode(&uniform, &vec![0.0; uniform.n_weights()], None).unwrap();
    assert!(record_mesh(&bytes, 1).is_err());
}
