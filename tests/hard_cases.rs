//! Hard cases stay numerically stable: every model of the crate on a dense grid of direction
//! pairs that includes the edges of the domain, with extreme parameters and weights.
//!
//! The grid holds normal incidence (θ = 0), grazing directions (θ → π/2, and z = 1e-7, 0 and -0 exactly),
//! directions below the horizon, unnormalised (huge, tiny, subnormal) vectors, the zero vector and NaN and
//! infinite components; every pair of them, plus for each direction the pairs wi = wo, wi = mirror of wo
//! about the normal and wi = -wo. Every model is checked for the contract the crate documents (lib.rs,
//! `Model::eval`, `parametric`): the value is finite and non-negative, exactly 0 where either direction is
//! degenerate or not strictly above the horizon, and reciprocal where the model promises it — bit for bit
//! for the parametric models, the Θ networks and the MERL lookups.

mod common;

use std::f32::consts::{FRAC_PI_2, PI};

use nbrdf::angles::unit;
use nbrdf::builtin::Builtin;
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf};
use nbrdf::measured::{Lookup, MerlTable, NbrdfNetwork};
use nbrdf::parametric::{
    Disney, FresnelMicrofacet, Lambert, Parametric, ParametricKind, Phong, TorranceSparrow, MAX_RAW,
};
use nbrdf::{Brdf, Rgb, Vec3, BLACK};

// -------------------------------------------------------------------------------------------------
// The grid

/// Directions with every kind of edge the evaluators must survive.
fn directions() -> Vec<Vec3> {
    let mut d = Vec::new();
    // A polar grid from the normal to just short of the horizon, at azimuths including the axes.
    let thetas = [0.0, 1e-6, 1e-3, 0.1, 0.4, 0.785, 1.1, 1.4, 1.55, FRAC_PI_2 - 1e-4, FRAC_PI_2 - 1e-6];
    let phis = [0.0, 0.5, FRAC_PI_2, 2.0, PI, 4.0, 1.5 * PI, 5.9];
    for &t in &thetas {
        for &p in &phis {
            let (st, ct) = t.sin_cos();
            let (sp, cp) = p.sin_cos();
            d.push(Vec3::new(st * cp, st * sp, ct));
        }
    }
    // The horizon itself: z = 1e-7 (valid, grazing), z = 0 and z = -0 (both must give 0).
    for p in [0.0f32, 1.0, 3.0] {
        for z in [1e-7, 0.0, -0.0] {
            d.push(Vec3::new(p.cos(), p.sin(), z));
        }
    }
    d.extend([
        // Below the horizon.
        Vec3::new(0.3, 0.2, -0.9),
        -Vec3::Z,
        // Unnormalised: huge, at the f32 limit, tiny and subnormal vectors of valid directions.
        Vec3::new(1e30, 0.0, 1e30),
        Vec3::splat(f32::MAX),
        Vec3::new(1e-20, -1e-20, 3e-20),
        Vec3::new(1e-40, 0.0, 1e-40),
        Vec3::new(0.0, 0.0, f32::from_bits(1)), // the smallest subnormal
        Vec3::splat(f32::from_bits(1)),
        Vec3::new(1e-40, 1.0, 1e-40), // a subnormal z: grazing
        // Degenerate: zero, NaN and infinite components.
        Vec3::ZERO,
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(0.0, 0.0, f32::NAN),
        Vec3::new(f32::INFINITY, 0.0, 1.0),
        Vec3::new(0.0, 0.0, f32::INFINITY),
        Vec3::splat(f32::NEG_INFINITY),
    ]);
    d
}

/// Every ordered pair of [`directions`], then wi = wo, wi = mirror(wo) and wi = -wo for each direction.
fn dense_pairs() -> Vec<(Vec3, Vec3)> {
    let d = directions();
    let mut pairs: Vec<(Vec3, Vec3)> = special_pairs(&d);
    for &wi in &d {
        for &wo in &d {
            pairs.push((wi, wo));
        }
    }
    pairs
}

/// wi = wo, wi = the mirror of wo about the normal, and wi = -wo, for every direction.
fn special_pairs(d: &[Vec3]) -> Vec<(Vec3, Vec3)> {
    let mut pairs = Vec::new();
    for &wo in d {
        pairs.push((wo, wo));
        pairs.push((Vec3::new(-wo.x, -wo.y, wo.z), wo));
        pairs.push((-wo, wo));
    }
    pairs
}

/// A thinner grid for the costly sweeps (networks of width 128, the 4096 Disney corners): every special
/// pair and every 23rd pair of the dense grid.
fn edge_pairs() -> Vec<(Vec3, Vec3)> {
    let d = directions();
    let mut pairs = special_pairs(&d);
    let dense = dense_pairs();
    pairs.extend(dense.iter().skip(3 * d.len()).step_by(23));
    pairs
}

// -------------------------------------------------------------------------------------------------
// The contract

/// What a model promises under the swap of `wi` and `wo`.
#[derive(Clone, Copy, Debug)]
enum Reciprocal {
    /// Nothing (non-reciprocal networks).
    No,
    /// Bit for bit.
    Bitwise,
    /// Within a relative tolerance.
    Within(f32),
}

/// Whether the crate's gate accepts `w`: finite, non-zero, strictly above the horizon once normalised.
fn above(w: Vec3) -> bool {
    unit(w).is_some_and(|u| u.z > 0.0)
}

/// Evaluates `f` on every pair and checks the contract; returns the number of evaluations.
fn sweep(name: &str, pairs: &[(Vec3, Vec3)], reciprocal: Reciprocal, f: impl Fn(Vec3, Vec3) -> Rgb) -> usize {
    for &(wi, wo) in pairs {
        let a = f(wi, wo);
        assert!(a.iter().all(|c| c.is_finite() && *c >= 0.0), "{name}: f({wi}, {wo}) = {a:?}");
        if !(above(wi) && above(wo)) {
            // Below the horizon, grazing at z = ±0, degenerate or non-finite: exactly 0 (lib.rs).
            assert_eq!(a, BLACK, "{name}: f({wi}, {wo}) must be 0");
        }
        let b = match reciprocal {
            Reciprocal::No => continue,
            _ => f(wo, wi),
        };
        match reciprocal {
            Reciprocal::Bitwise => {
                assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{name}: not reciprocal at ({wi}, {wo}): {a:?} vs {b:?}")
            }
            Reciprocal::Within(tol) => {
                for c in 0..3 {
                    let scale = a[c].abs().max(b[c].abs()).max(1e-6);
                    assert!((a[c] - b[c]).abs() <= tol * scale, "{name}: not reciprocal at ({wi}, {wo}): {a:?} vs {b:?}");
                }
            }
            Reciprocal::No => unreachable!(),
        }
    }
    pairs.len() * if matches!(reciprocal, Reciprocal::No) { 1 } else { 2 }
}

/// Raw values at every edge of `f32`: zeros, saturating and overflowing magnitudes, subnormals, NaN, ±inf.
const EXTREME: [f32; 16] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    20.0,
    -20.0,
    100.0,
    -100.0,
    1e30,
    -1e30,
    f32::MAX,
    f32::MIN,
    1e-40,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
];

/// A small deterministic generator (the tests must not depend on a random seed).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    /// Uniform in [-1, 1).
    fn unit(&mut self) -> f32 {
        (self.next() as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
    }
    fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[self.next() as usize % xs.len()]
    }
}

/// Raw parameter vectors for a parametric kind: every extreme value everywhere, every extreme value at
/// one index with the others at 0, and random mixtures of extremes.
fn raw_configs(kind: ParametricKind, rng: &mut Lcg) -> Vec<([f32; MAX_RAW], f32)> {
    let n = kind.n_raw();
    let mut out = Vec::new();
    for &v in &EXTREME {
        out.push(([v; MAX_RAW], v));
        for i in 0..n {
            let mut raw = [0.0; MAX_RAW];
            raw[i] = v;
            out.push((raw, 0.0));
        }
    }
    for _ in 0..64 {
        let mut raw = [0.0; MAX_RAW];
        raw.iter_mut().for_each(|r| *r = rng.pick(&EXTREME));
        out.push((raw, rng.pick(&EXTREME)));
    }
    out
}

// -------------------------------------------------------------------------------------------------
// The angle maps every model is built on

#[test]
fn angle_maps_on_the_dense_grid_are_in_range_and_theta_is_bitwise_symmetric() {
    use nbrdf::angles::{rusinkiewicz_angles, theta_map};
    for (wi, wo) in dense_pairs() {
        let t = theta_map(wi, wo);
        // Θ is symmetric bit for bit, and defined for exactly the same pairs in both orders.
        assert_eq!(t.map(|t| t.map(f32::to_bits)), theta_map(wo, wi).map(|t| t.map(f32::to_bits)), "Θ({wi}, {wo})");
        if let Some([th, td, p, p_pi]) = t {
            assert!((0.0..=PI).contains(&th) && (0.0..=FRAC_PI_2).contains(&td), "Θ({wi}, {wo}) = {t:?}");
            assert!((0.0..PI).contains(&p) && p_pi == p + PI, "Θ({wi}, {wo}) = {t:?}");
        }
        if let Some([th, td, pd]) = rusinkiewicz_angles(wi, wo) {
            assert!((0.0..=PI).contains(&th) && (0.0..=FRAC_PI_2).contains(&td), "({wi}, {wo})");
            assert!((0.0..2.0 * PI).contains(&pd), "φd({wi}, {wo}) = {pd}");
        }
        // Only degenerate pairs lack angles: a zero or non-finite vector, or exactly opposite directions.
        if t.is_none() {
            if let (Some(a), Some(b)) = (unit(wi), unit(wo)) {
                assert!((a + b).length() < 1e-6, "no Θ for ({wi}, {wo})");
            }
        }
    }
}

// -------------------------------------------------------------------------------------------------
// Parametric models and built-in materials

#[test]
fn parametric_models_from_any_raw_parameters_are_finite_and_bitwise_reciprocal() {
    // `Parametric::from_raw` reads NaN/inf as 0 and saturates everything else into the parameter
    // ranges; whatever the network emits, the model must stay finite, ≥ 0 and exactly reciprocal
    // (`Model::eval` promises bitwise reciprocity for every parametric model).
    let pairs = edge_pairs();
    let mut rng = Lcg(7);
    let mut n = 0;
    for kind in ParametricKind::ALL {
        for (raw, object) in raw_configs(kind, &mut rng) {
            let m = Parametric::from_raw(kind, &raw[..kind.n_raw()], &[object][..kind.n_object()]);
            n += sweep(kind.name(), &pairs, Reciprocal::Bitwise, |wi, wo| m.eval(wi, wo));
        }
    }
    assert!(n > 100_000, "{n} evaluations");
}

#[test]
fn parametric_models_at_the_roughness_and_shape_limits_on_the_dense_grid() {
    let pairs = dense_pairs();
    let mut models: Vec<(String, Parametric)> = Vec::new();
    for kd in [0.0, 1.0] {
        models.push((format!("Lambert kd={kd}"), Parametric::Lambert(Lambert { kd: [kd; 3] })));
    }
    // Roughness → 0 (below the 1e-3 floor, the clamp must hold) and → 1 (and past it, and NaN).
    for alpha in [0.0, 1e-9, 1e-3, 0.01, 0.5, 1.0, 1.5, f32::NAN] {
        let m = TorranceSparrow { kd: [0.5; 3], ks: [1.0; 3], alpha };
        models.push((format!("TS α={alpha}"), Parametric::TorranceSparrow(m)));
    }
    // Phong exponents from a flat lobe to a mirror-like one (the largest softplus can produce).
    for n in [0.0, 1e-3, 1.0, 100.0, 1e4, 1e7, 1e30] {
        let m = Phong { kd: [0.0; 3], ks: [1.0; 3], n };
        models.push((format!("Phong n={n}"), Parametric::Phong(m)));
    }
    // The extreme FMBRDF shapes of the issue: α = 1e-3 (normalisation ~3e5), β = 0.5..4, η = 1.1..2.5.
    for alpha in [1e-3, 0.05, 1.0] {
        for beta in [0.5, 1.0, 2.0, 3.0, 4.0] {
            for eta in [1.1, 1.5, 2.0, 2.5] {
                let m = FresnelMicrofacet::new([1.0; 3], 1.0, alpha, beta, eta);
                models.push((format!("FMBRDF α={alpha} β={beta} η={eta}"), Parametric::FresnelMicrofacet(m)));
            }
        }
    }
    for roughness in [0.0, 1e-6, 1.0] {
        let m = Disney { base_color: [1.0; 3], specular: 1.0, clearcoat: 1.0, clearcoat_gloss: 1.0, roughness, ..Disney::default() };
        models.push((format!("Disney roughness={roughness}"), Parametric::Disney(m)));
    }
    let mut n = 0;
    for (name, m) in &models {
        n += sweep(name, &pairs, Reciprocal::Bitwise, |wi, wo| m.eval(wi, wo));
    }
    assert!(n > 1_000_000, "{n} evaluations");
}

#[test]
fn disney_with_every_weight_at_zero_and_one() {
    // All 2^12 corners of the parameter cube (base colour, subsurface, metallic, specular, tints,
    // roughness, sheen, clearcoat, gloss): black base colour (lum = 0, the tint fallback), roughness 0
    // (α at its floor), clearcoat gloss 1 (GTR1 at α = 0.001).
    let pairs = edge_pairs();
    let b = |mask: u32, i: u32| ((mask >> i) & 1) as f32;
    let mut n = 0;
    for mask in 0..(1u32 << 12) {
        let m = Disney {
            base_color: [b(mask, 0), b(mask, 1), b(mask, 2)],
            subsurface: b(mask, 3),
            metallic: b(mask, 4),
            specular: b(mask, 5),
            specular_tint: b(mask, 6),
            roughness: b(mask, 7),
            sheen: b(mask, 8),
            sheen_tint: b(mask, 9),
            clearcoat: b(mask, 10),
            clearcoat_gloss: b(mask, 11),
        };
        n += sweep(&format!("Disney {m:?}"), &pairs, Reciprocal::Bitwise, |wi, wo| m.eval(wi, wo));
    }
    assert!(n > 1_000_000, "{n} evaluations");
}

#[test]
fn builtin_materials_on_the_dense_grid() {
    // The built-ins promise reciprocity to rounding (their doc test uses a relative 1e-6).
    let pairs = dense_pairs();
    for m in Builtin::ALL {
        sweep(m.id(), &pairs, Reciprocal::Within(1e-6), |wi, wo| m.eval(wi, wo));
    }
}

#[test]
fn sampling_is_finite_on_the_grid_for_extreme_models_and_random_numbers() {
    // `u` is documented in [0, 1); a renderer's sampler produces 0, values a hair below 1 and, with a
    // naive float conversion, 1 itself. Inside that range a sample is a unit direction above the horizon;
    // outside it (negative, > 1, NaN: out of contract) a sample may be any direction above the horizon,
    // but its pdf and weight must still be finite.
    let us = [0.0, 1e-7, 0.25, 0.5, 0.999_999_94, 1.0, -0.5, 1.5, f32::NAN];
    let in_range = |u: f32| (0.0..=1.0).contains(&u);
    let mut models: Vec<(String, Box<dyn Brdf>)> = Vec::new();
    let mut rng = Lcg(11);
    for kind in ParametricKind::ALL {
        for (raw, object) in raw_configs(kind, &mut rng).into_iter().step_by(7) {
            let m = Parametric::from_raw(kind, &raw[..kind.n_raw()], &[object][..kind.n_object()]);
            models.push((format!("{} {raw:?}", kind.name()), Box::new(m)));
        }
    }
    for m in Builtin::ALL {
        models.push((m.id().to_string(), Box::new(m)));
    }
    let d = directions();
    let mut samples = 0;
    for (name, m) in &models {
        for &wo in &d {
            for &u0 in &us {
                for &u1 in &us {
                    for u2 in [0.0, 0.5, 0.999_999_94] {
                        let Some(s) = m.sample(wo, [u0, u1, u2]) else { continue };
                        samples += 1;
                        assert!(above(wo), "{name}: a sample for the invalid wo = {wo}");
                        assert!(s.wi.z > 0.0 && s.wi.is_finite(), "{name}: wi = {}", s.wi);
                        if in_range(u0) && in_range(u1) {
                            assert!((s.wi.length() - 1.0).abs() < 1e-4, "{name}: wi = {} for u = {:?}", s.wi, [u0, u1, u2]);
                        }
                        assert!(s.pdf.is_finite() && s.pdf > 0.0, "{name}: pdf {} at wo = {wo}", s.pdf);
                        assert!(s.weight.iter().all(|c| c.is_finite() && *c >= 0.0), "{name}: weight {:?}", s.weight);
                    }
                }
            }
            for &wi in d.iter().step_by(3) {
                let p = m.pdf(wi, wo);
                assert!(p.is_finite() && p >= 0.0, "{name}: pdf({wo}, {wi}) = {p}");
                if !(above(wi) && above(wo)) {
                    assert_eq!(p, 0.0, "{name}: pdf({wo}, {wi}) must be 0");
                }
            }
        }
    }
    assert!(samples > 10_000, "{samples} samples");
}

// -------------------------------------------------------------------------------------------------
// Neural models (`.nbrdf` files)

/// Every model kind with each reciprocity strategy, split and direction-layer ablation, with the
/// position encodings and angle frequencies (0 and the maximum 16 included) rotated through them.
fn headers() -> Vec<ModelHeader> {
    let positions = [
        PositionEncoding::Uniform,
        PositionEncoding::Intrinsic { k: 5 },
        PositionEncoding::Extrinsic { frequencies: 3 },
    ];
    let freqs = [0u8, 4, nbrdf::file::MAX_FREQUENCIES];
    let mut kinds: Vec<(ModelKind, bool, Reciprocity)> = ParametricKind::ALL
        .into_iter()
        .map(|k| (ModelKind::Parametric(k), false, Reciprocity::Exact))
        .collect();
    // `Swap` differs from `None` in training only; the evaluator treats them alike.
    for r in [Reciprocity::None, Reciprocity::Exact] {
        kinds.push((ModelKind::SingleMlp, false, r));
        for e in [false, true] {
            kinds.push((ModelKind::AdditiveSeparate, e, r));
            kinds.push((ModelKind::AdditiveShared, e, r));
        }
    }
    let mut out = Vec::new();
    for (i, (kind, enhanced, r)) in kinds.into_iter().enumerate() {
        let h = ModelHeader::paper(kind, enhanced, r, positions[i % 3], freqs[i % 3]);
        out.push(h);
        if i % 4 == 1 {
            out.push(h.with_direction_layers(1 + (i % 3) as u8));
        }
    }
    out
}

/// Weight sets that stress the forward pass: ordinary, large (activations grow layer by layer), and at
/// the limits of the storage format (f32: ±3.4e38; f16: ±65504 and subnormals), where the hidden
/// activations overflow to inf and inf - inf makes NaN inside the network.
fn weight_sets(n: usize, precision: Precision, seed: u64) -> Vec<(&'static str, Vec<f32>)> {
    let mut rng = Lcg(seed);
    let small: Vec<f32> = (0..n).map(|_| 0.1 * rng.unit()).collect();
    let large: Vec<f32> = (0..n).map(|_| 3.0 * rng.unit()).collect();
    let limits: &[f32] = match precision {
        // ±65504 is the largest finite f16; 6e-8 and 1e-5 are f16 subnormals.
        Precision::F16 => &[65504.0, -65504.0, 6e-8, -6e-8, 1e-5, 0.0, 1.0, -1.0],
        Precision::F32 => &[f32::MAX, f32::MIN, 1e-40, -1e-40, 0.0, 1.0, -1.0, 1e30],
    };
    let extreme: Vec<f32> = (0..n).map(|_| rng.pick(limits)).collect();
    let all_max: Vec<f32> = vec![limits[0]; n];
    vec![("small", small), ("large", large), ("format limits", extreme), ("all at the maximum", all_max)]
}

/// Point inputs for `prepare`: ordinary ones and ones with NaN, inf and huge values.
fn points(position: PositionEncoding) -> Vec<Vec<f32>> {
    let k = position.input_len();
    if k == 0 {
        return vec![vec![]];
    }
    let ordinary: Vec<f32> = (0..k).map(|i| 0.3 - 0.2 * i as f32).collect();
    let hostile: Vec<f32> = (0..k).map(|i| [f32::NAN, f32::INFINITY, 1e30, -1e-40, f32::NEG_INFINITY][i % 5]).collect();
    vec![ordinary, hostile]
}

#[test]
fn neural_models_of_every_kind_and_precision_with_extreme_weights() {
    // Networks of width 128 are the costly part: every special pair and a thin slice of the grid.
    let d = directions();
    let mut pairs = special_pairs(&d);
    pairs.extend(dense_pairs().iter().skip(3 * d.len()).step_by(97));
    let mut n = 0;
    for (i, h) in headers().into_iter().enumerate() {
        for precision in [Precision::F32, Precision::F16] {
            let h = ModelHeader { precision, ..h };
            for (what, w) in weight_sets(h.n_weights(), precision, i as u64) {
                let name = format!("{:?} {:?} {:?} {:?} {what}", h.kind, h.reciprocity, h.position, precision);
                let bytes = match encode(&h, &w, None) {
                    Ok(b) => b,
                    Err(e) => panic!("{name}: encode failed: {e}"),
                };
                let buf = ModelBuf::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
                // The file borrowed in place: an f16 one runs the f16 kernels (a `ModelBuf` holds it
                // widened to f32, whose batches are checked against these below).
                let words = common::words(&bytes);
                let model = Model::from_bytes(&common::bytes(&words)[..bytes.len()]).unwrap_or_else(|e| panic!("{name}: {e}"));
                let reciprocal = if h.reciprocity == Reciprocity::Exact || matches!(h.kind, ModelKind::Parametric(_)) {
                    Reciprocal::Bitwise
                } else {
                    Reciprocal::No
                };
                let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
                for p in points(h.position) {
                    let prepared = model.prepare(&p).unwrap();
                    let d = prepared.diffuse();
                    assert!(d.iter().all(|c| c.is_finite() && *c >= 0.0), "{name}: diffuse {d:?} at {p:?}");
                    n += sweep(&format!("{name} at {p:?}"), &pairs, reciprocal, |wi, wo| model.eval(&prepared, wi, wo));
                    // Batches (Θ: encoded 16 pairs at a time on AVX-512) give every pair's own bits.
                    let mut batch = vec![[f32::NAN; 3]; pairs.len()];
                    model.eval_many(&prepared, &wi, &wo, &mut batch);
                    for (k, f) in batch.iter().enumerate() {
                        let one = model.eval(&prepared, wi[k], wo[k]);
                        assert_eq!(f.map(f32::to_bits), one.map(f32::to_bits), "{name}: batch f({}, {}) at {p:?}", wi[k], wo[k]);
                    }
                    let mut held = vec![[f32::NAN; 3]; pairs.len()];
                    buf.model().eval_many(&buf.model().prepare(&p).unwrap(), &wi, &wo, &mut held);
                    for (k, (a, b)) in held.iter().zip(&batch).enumerate() {
                        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{name}: ModelBuf batch f({}, {}) at {p:?}", wi[k], wo[k]);
                    }
                }
                // A point of the wrong length is an error; the state of no point evaluates to 0.
                let wrong = vec![0.5; h.position.input_len() + 1];
                assert!(model.prepare(&wrong).is_err(), "{name}");
                assert_eq!(model.eval(&Default::default(), Vec3::new(0.1, 0.2, 0.9), Vec3::Z), BLACK, "{name}");
            }
        }
    }
    assert!(n > 100_000, "{n} evaluations");
}

#[test]
fn f16_weights_that_round_to_infinity_are_rejected_at_encode() {
    // 65520 is the first value that rounds to +inf in f16: the export must refuse it rather than write a
    // file whose weights are inf (the loader would reject that file, but the error belongs at export).
    let h = ModelHeader { precision: Precision::F16, ..ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2) };
    let mut w = vec![0.01; h.n_weights()];
    w[17] = 65520.0;
    assert!(matches!(encode(&h, &w, None), Err(nbrdf::Error::NonFinite { index: 17, .. })));
    w[17] = 65504.0;
    assert!(encode(&h, &w, None).is_ok());
}

/// `Model::to_f16` of an f32 model with a weight f16 cannot hold names it, like the export, and of
/// an f16 model says so; the f32 model stays as it was. `Model::to_f32` of an f32 model says so too.
#[test]
fn to_f16_rejects_weights_beyond_the_f16_range_and_f16_models() {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let mut w = vec![0.01; h.n_weights()];
    w[17] = 1e5;
    let bytes = encode(&h, &w, None).unwrap();
    let buf = nbrdf::ModelBuf::from_bytes(&bytes).unwrap();
    assert!(matches!(buf.model().to_f16(), Err(nbrdf::Error::NonFinite { index: 17, .. })));
    assert_eq!(buf.as_bytes(), &bytes[..]);
    w[17] = 0.5;
    let half = nbrdf::ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap().model().to_f16().unwrap();
    let words = common::words(&half);
    let half = Model::from_bytes(&common::bytes(&words)[..half.len()]).unwrap();
    assert!(matches!(half.to_f16(), Err(nbrdf::Error::InvalidValue { what: "model precision", .. })));
    assert!(matches!(buf.model().to_f32(), Err(nbrdf::Error::InvalidValue { what: "model precision", .. })));
}

// -------------------------------------------------------------------------------------------------
// Measured materials

#[test]
fn merl_tables_from_tabulate_are_finite_and_bitwise_reciprocal_in_both_lookups() {
    // A table with invalid (negative) bins below the horizon and a near-mirror lobe, as `tabulate` builds
    // it from a built-in material.
    let table = MerlTable::tabulate(|wi, wo| Builtin::TwoLobeMetal.eval(wi, wo));
    let pairs = dense_pairs();
    for lookup in [Lookup::Nearest, Lookup::Trilinear] {
        sweep(&format!("MERL {lookup:?}"), &pairs, Reciprocal::Bitwise, |wi, wo| table.eval_with(wi, wo, lookup));
        // Angles straight from a caller: out of range, negative, huge, non-finite.
        for &a in &EXTREME {
            for &b in &[0.0, 0.7, FRAC_PI_2, PI, -1.0, 1e9] {
                for (th, td, pd) in [(a, b, b), (b, a, b), (b, b, a)] {
                    let f = table.eval_angles(th, td, pd, lookup);
                    assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0), "MERL angles ({th}, {td}, {pd}) = {f:?}");
                }
            }
        }
    }
}

/// The shared data directory (`NBRDF_DATA`, default `../shared/data`), if present.
fn data_dir() -> Option<std::path::PathBuf> {
    let dir = std::path::PathBuf::from(std::env::var("NBRDF_DATA").unwrap_or_else(|_| "../shared/data".into()));
    dir.join("nbrdf-merl").is_dir().then_some(dir)
}

#[test]
fn published_nbrdf_networks_are_finite_on_the_dense_grid() {
    let Some(dir) = data_dir() else {
        eprintln!("skipping: no NBRDF-json data (set NBRDF_DATA to the shared data directory)");
        return;
    };
    let mut files: Vec<_> = std::fs::read_dir(dir.join("nbrdf-merl"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    let pairs = dense_pairs();
    // These networks see Rusinkiewicz angles with φd in [0, 2π) and promise no reciprocity.
    for path in files.iter().step_by(5) {
        let net = NbrdfNetwork::load(path).unwrap_or_else(|e| panic!("{e}"));
        sweep(&path.display().to_string(), &pairs, Reciprocal::No, |wi, wo| net.eval(wi, wo));
        // The batched kernel (16-query packets, vector input transform and expm1) on the same edge
        // pairs gives the single query's values bit for bit, below-horizon zeros included.
        let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
        let mut batch = vec![[f32::NAN; 3]; pairs.len()];
        net.eval_many(&wi, &wo, &mut batch);
        for (k, (&(a, b), f)) in pairs.iter().zip(&batch).enumerate() {
            let one = net.eval(a, b);
            assert!(f.iter().zip(&one).all(|(x, y)| x.to_bits() == y.to_bits()), "{} pair {k}: {f:?} vs {one:?}", path.display());
        }
        for &a in &EXTREME {
            let f = net.eval_angles(a, 0.3, a);
            assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0), "{}: angles {a} = {f:?}", path.display());
        }
    }
}

#[test]
fn overflowing_diffuse_network_reads_as_zero_not_nan() {
    // Regression: with weights at f32's limits the diffuse network's activations overflow, the
    // inf - inf inside it gives NaN, and `Prepared::diffuse` returned NaN (eval itself was sanitised, but
    // a renderer reading the diffuse term, e.g. for a diffuse-only pass, got NaN).
    let h = ModelHeader::paper(ModelKind::AdditiveSeparate, false, Reciprocity::None, PositionEncoding::Uniform, 0);
    for seed in 0..32 {
        let (_, w) = weight_sets(h.n_weights(), Precision::F32, seed).swap_remove(2);
        let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
        let model = buf.model();
        let p = model.prepare(&[]).unwrap();
        assert!(p.diffuse().iter().all(|c| c.is_finite() && *c >= 0.0), "seed {seed}: {:?}", p.diffuse());
        let f = model.eval(&p, Vec3::new(0.2, 0.1, 0.9), Vec3::new(-0.3, 0.0, 0.8));
        assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0), "seed {seed}: {f:?}");
    }
}

