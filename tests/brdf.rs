//! The `Brdf` interface, checked the same way for every BRDF of the crate: parametric models, the
//! built-ins, a MERL table, an NBRDF-json network and `.nbrdf` models at a point. What a renderer
//! relies on: `is_reciprocal` tells the truth, `sample` and `pdf` describe one density (a chi-square
//! test), and every method is zero / `None` for directions below the horizon.

use nbrdf::builtin::Builtin;
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::parametric::{Parametric, ParametricKind, Phong, MAX_RAW};
use nbrdf::{Brdf, ModelBuf, Vec3};

mod common;
use common::{check_sampler, dir, Rng, Sampler};

/// A small NBRDF-json network (6 → 8 → 3) with deterministic weights.
fn json_network() -> NbrdfNetwork {
    let mut rng = Rng(5);
    let mut row = |n: usize| (0..n).map(|_| format!("{:.4}", rng.next() - 0.5)).collect::<Vec<_>>().join(",");
    let hidden: Vec<String> = (0..8).map(|_| format!("[{}]", row(6))).collect();
    let out: Vec<String> = (0..3).map(|_| format!("[{}]", row(8))).collect();
    let json = format!(
        r#"{{"input": "rusinkiewicz_half_diff_vectors", "output": "expm1_clamped", "layers": [
            {{"inputs": 6, "outputs": 8, "activation": "relu", "weight": [{}], "bias": [{}]}},
            {{"inputs": 8, "outputs": 3, "activation": "none", "weight": [{}], "bias": [0.5, 0.3, 0.6]}}]}}"#,
        hidden.join(","),
        row(8),
        out.join(",")
    );
    NbrdfNetwork::from_json_str(&json).unwrap()
}

/// `.nbrdf` files of the kinds whose reciprocity differs: Θ and plain neural models, random swap, a
/// parametric network.
fn model_files() -> Vec<(String, ModelBuf)> {
    let cases = [
        (ModelKind::SingleMlp, Reciprocity::Exact),
        (ModelKind::SingleMlp, Reciprocity::None),
        (ModelKind::AdditiveShared, Reciprocity::Swap),
        (ModelKind::Parametric(ParametricKind::Disney), Reciprocity::None),
    ];
    cases
        .into_iter()
        .map(|(kind, r)| {
            let h = ModelHeader::paper(kind, true, r, PositionEncoding::Uniform, 2);
            let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919 % 211) as f32 - 105.0) * 1.5e-3).collect();
            (format!("{kind:?} {r:?}"), ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap())
        })
        .collect()
}

/// Every BRDF of the crate, once, by name.
fn every_brdf(models: &[(String, ModelBuf)]) -> Vec<(String, Box<dyn Brdf + Sync + '_>)> {
    let mut all: Vec<(String, Box<dyn Brdf + Sync>)> = Vec::new();
    let mut rng = Rng(3);
    for kind in ParametricKind::ALL {
        let raw: Vec<f32> = (0..MAX_RAW).map(|_| rng.next() * 4.0 - 2.0).collect();
        all.push((kind.name().to_string(), Box::new(Parametric::from_raw(kind, &raw[..kind.n_raw()], &[0.3][..kind.n_object()]))));
    }
    for b in Builtin::ALL {
        all.push((b.id().to_string(), Box::new(b)));
    }
    all.push(("MERL table".into(), Box::new(MerlTable::tabulate(|wi, wo| Builtin::TwoLobeMetal.eval(wi, wo)))));
    all.push(("NBRDF-json".into(), Box::new(json_network())));
    for (name, buf) in models {
        all.push((name.clone(), Box::new(buf.model().at(&[]).unwrap())));
    }
    all
}

fn pairs(n: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Rng(17);
    let mut d = || dir((rng.next() as f64) * 1.5, (rng.next() as f64) * std::f64::consts::TAU);
    (0..n).map(|_| (d(), d())).collect()
}

#[test]
fn is_reciprocal_tells_the_truth() {
    let models = model_files();
    for (name, brdf) in every_brdf(&models) {
        let (wi, wo) = (dir(0.3, 0.1), dir(0.5, 2.0));
        assert!(brdf.eval(wi, wo).iter().any(|&c| c > 0.0), "{name}: a BRDF that is 0 proves nothing");
        let worst = pairs(2000)
            .into_iter()
            .map(|(wi, wo)| {
                let (a, b) = (brdf.eval(wi, wo), brdf.eval(wo, wi));
                (0..3).map(|c| (a[c] - b[c]).abs() / a[c].abs().max(b[c].abs()).max(1e-6)).fold(0.0f32, f32::max)
            })
            .fold(0.0f32, f32::max);
        if brdf.is_reciprocal() {
            // Rounding of formulas written in wi and wo separately (the Θ models: bitwise).
            assert!(worst <= 2e-5, "{name} says it is reciprocal; relative asymmetry {worst}");
        } else {
            assert!(worst > 1e-3, "{name} says it is not reciprocal, yet f(wi, wo) = f(wo, wi) everywhere ({worst})");
        }
    }
    // The Θ model is exactly symmetric, bit for bit.
    let theta = models[0].1.model().at(&[]).unwrap();
    for (wi, wo) in pairs(500) {
        assert_eq!(theta.eval(wi, wo).map(f32::to_bits), theta.eval(wo, wi).map(f32::to_bits));
    }
}

#[test]
fn sample_and_pdf_describe_one_density_for_every_brdf() {
    let models = model_files();
    for (name, brdf) in every_brdf(&models) {
        for (k, wo) in [dir(0.3, 0.5), dir(1.2, 2.0)].into_iter().enumerate() {
            let sampler = Sampler {
                sample: &|u| brdf.sample(wo, u),
                pdf: &|wi| brdf.pdf(wi, wo),
                eval: &|wi| brdf.eval(wi, wo),
            };
            check_sampler(&format!("{name} at wo = {wo}"), &sampler, 20_000, 7 + k as u64);
        }
    }
}

#[test]
fn below_the_horizon_every_brdf_gives_nothing() {
    let models = model_files();
    let (up, down) = (dir(0.4, 1.0), Vec3::new(0.3, 0.2, -0.9).normalize());
    for (name, brdf) in every_brdf(&models) {
        assert_eq!(brdf.eval(down, up), [0.0; 3], "{name}");
        assert_eq!(brdf.eval(up, down), [0.0; 3], "{name}");
        assert_eq!(brdf.pdf(down, up), 0.0, "{name}");
        assert_eq!(brdf.pdf(up, down), 0.0, "{name}");
        assert!(brdf.sample(down, [0.3, 0.6, 0.5]).is_none(), "{name}");
        assert!(brdf.eval(up, Vec3::splat(f32::NAN)).iter().all(|&c| c == 0.0), "{name}");
    }
}

#[test]
fn phong_refuses_parameters_that_create_energy() {
    assert!(Phong::new([0.5; 3], [0.5; 3], 10.0).is_ok());
    for (kd, ks, n, needle) in [
        ([0.6, 0.2, 0.2], [0.5, 0.2, 0.2], 10.0, "kd + ks"),
        ([-0.1; 3], [0.5; 3], 10.0, "[0, 1]"),
        ([0.2; 3], [f32::NAN; 3], 10.0, "[0, 1]"),
        ([0.2; 3], [0.5; 3], -1.0, "exponent"),
        ([0.2; 3], [0.5; 3], f32::INFINITY, "exponent"),
    ] {
        let err = Phong::new(kd, ks, n).unwrap_err().to_string();
        assert!(err.contains(needle), "{kd:?} {ks:?} {n}: {err}");
    }
    // What the network's raw outputs map to always passes.
    let mut rng = Rng(9);
    for _ in 0..1000 {
        let raw: Vec<f32> = (0..Phong::N_RAW).map(|_| rng.next() * 40.0 - 20.0).collect();
        let p = Phong::from_raw(&raw);
        assert!(Phong::new(p.kd, p.ks, p.n).is_ok(), "{p:?}");
    }
}
