//! Neural models of every kind with fuzzer-chosen weights, point inputs and directions.
//!
//! A small valid model (`common::small_header`: every kind, f32 and f16, every reciprocity and position
//! encoding) gets seeded weights at a fuzzer-chosen scale (up to the format's limit: ±65504 for f16,
//! ±3.4e38 for f32, where activations overflow to inf) and fuzzer-chosen weight overrides. Invariants:
//! the diffuse term and every evaluation are finite and non-negative; exactly 0 off the upper
//! hemisphere; bitwise reciprocal for Θ networks and parametric models; a batch gives each pair the
//! bits of its single query, and `prepare_many` each point the evaluations of its own `prepare`. The
//! model is borrowed in place (`Model::from_bytes`: f16 weights run the f16 kernels); the `ModelBuf`
//! of the same file (an f16 one widened to f32 at load) gives the same bits.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use nbrdf::file::{encode, ModelKind, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf};

fuzz_target!(|input: (u8, u8, u64, u8, [f32; 3], [f32; 6], Vec<(u16, f32)>)| {
    let (shape, variant, seed, scale, point, dirs, patches) = input;
    let h = common::small_header(shape as usize, variant);
    let limit = if h.precision == Precision::F16 { 65504.0 } else { f32::MAX };
    let scale = [0.1, 1.0, 10.0, 1e3, limit][scale as usize % 5];
    let mut w = common::weights(&h, seed, scale);
    for (i, v) in patches {
        if !w.is_empty() {
            let n = w.len();
            w[i as usize % n] = v;
        }
    }
    // Non-finite weights, and f16 weights beyond ±65504, are export errors (tests/bad_input.rs).
    let Ok(bytes) = encode(&h, &w, None) else { return };
    let buf = ModelBuf::from_bytes(&bytes).expect("encode's output loads");
    let mut words = vec![0u32; bytes.len().div_ceil(4)];
    // SAFETY: u8 has no alignment requirement; the u32 storage is initialised.
    let aligned = unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), words.len() * 4) };
    aligned[..bytes.len()].copy_from_slice(&bytes);
    let model = Model::from_bytes(&aligned[..bytes.len()]).expect("encode's output loads in place");
    let len = model.position_len().min(3);
    // A wrong point length is an error, never a state.
    let Ok(prepared) = model.prepare(&point[..len]) else {
        assert_ne!(len, model.position_len(), "the right length prepares");
        return;
    };
    common::assert_valid_brdf(prepared.diffuse(), "diffuse term");
    let (wi, wo) = common::pair(dirs);
    let f = model.eval(&prepared, wi, wo);
    common::assert_valid_brdf(f, "model eval");
    let held = buf.model();
    let f_held = held.eval(&held.prepare(&point[..len]).unwrap(), wi, wo);
    assert!(common::same_bits(f, f_held), "ModelBuf ({:?} file): {f_held:?} vs in place {f:?}", h.precision);
    // Many points at once (packets of 16, the last overlapping the one before): each point's
    // evaluation has the bits of its own `prepare`.
    let k = model.position_len();
    let points: Vec<f32> = (0..17 * k).map(|i| point[i % k.max(1)] * [1.0, -0.5, 0.0, 2.0][(i / k.max(1)) % 4]).collect();
    let mut states = vec![prepared; 17];
    model.prepare_many(&points, &mut states).expect("17 points of position_len values");
    for (q, p) in states.iter().enumerate() {
        let one = model.prepare(&points[q * k..(q + 1) * k]).unwrap();
        let (a, b) = (model.eval(p, wi, wo), model.eval(&one, wi, wo));
        assert!(common::same_bits(a, b), "prepare_many point {q}: {a:?} vs {b:?}");
        assert!(common::same_bits(p.diffuse(), one.diffuse()), "prepare_many point {q}: diffuse");
    }
    // A batch (angles mapped 16 pairs at a time on AVX-512) gives each pair its own bits: the pair,
    // its swap and their components exchanged, over more than one packet.
    let swap_xy = |v: nbrdf::Vec3| nbrdf::Vec3::new(v.y, v.x, v.z);
    let cases = [(wi, wo), (wo, wi), (swap_xy(wi), swap_xy(wo)), (wi, wi)];
    let (bi, bo): (Vec<_>, Vec<_>) = (0..19).map(|k| cases[k % cases.len()]).unzip();
    let mut many = vec![[f32::NAN; 3]; bi.len()];
    model.eval_many(&prepared, &bi, &bo, &mut many);
    for (k, m) in many.iter().enumerate() {
        let one = model.eval(&prepared, bi[k], bo[k]);
        assert!(common::same_bits(*m, one), "batch pair {k} ({}, {}): {m:?} vs {one:?}", bi[k], bo[k]);
    }
    if !(common::above(wi) && common::above(wo)) {
        assert_eq!(f, [0.0; 3], "nonzero off the upper hemisphere");
    }
    if h.reciprocity == Reciprocity::Exact || matches!(h.kind, ModelKind::Parametric(_)) {
        assert!(common::same_bits(f, model.eval(&prepared, wo, wi)), "not reciprocal: {wi} {wo}");
    }
});
