//! Importance sampling agrees with its own pdf (a chi-square test on a histogram of sampled directions,
//! as in pbrt's and Mitsuba's BSDF tests), the pdf integrates to the probability that a sample is
//! produced (1 for lobes that cannot leave the hemisphere), and the estimator weight is unbiased for
//! the directional albedo.

use nbrdf::builtin::Builtin;
use nbrdf::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, Phong, TorranceSparrow};
use nbrdf::{Brdf, Vec3};

mod common;
use common::{albedo, check_sampler, dir, expected_mass, Sampler};

/// Draws `n` samples of `m` at `wo` and checks them against its pdf ([`common::check_sampler`]);
/// returns (share produced, mean weight).
fn check_model(name: &str, m: &(dyn Brdf + Sync), wo: Vec3, n: usize, seed: u64) -> (f64, [f64; 3]) {
    let sampler = Sampler { sample: &|u| m.sample(wo, u), pdf: &|wi| m.pdf(wi, wo), eval: &|wi| m.eval(wi, wo) };
    check_sampler(name, &sampler, n, seed)
}

fn parametric_models() -> Vec<(&'static str, Parametric)> {
    vec![
        ("lambert", Parametric::Lambert(Lambert { kd: [0.2, 0.5, 0.8] })),
        ("phong n=10", Parametric::Phong(Phong { kd: [0.3, 0.2, 0.1], ks: [0.6, 0.5, 0.4], n: 10.0 })),
        ("phong n=60", Parametric::Phong(Phong { kd: [0.05; 3], ks: [0.9; 3], n: 60.0 })),
        (
            "ts",
            Parametric::TorranceSparrow(TorranceSparrow {
                kd: [0.2, 0.1, 0.1],
                ks: [0.8, 0.6, 0.5],
                alpha: 0.3,
            }),
        ),
        (
            "fmbrdf",
            Parametric::FresnelMicrofacet(FresnelMicrofacet::new([0.5, 0.3, 0.2], 0.9, 0.25, 1.2, 1.6)),
        ),
        (
            "disney all lobes",
            Parametric::Disney(Disney {
                base_color: [0.6, 0.3, 0.2],
                subsurface: 0.5,
                metallic: 0.2,
                specular: 0.7,
                specular_tint: 0.3,
                roughness: 0.5,
                sheen: 0.5,
                sheen_tint: 0.5,
                clearcoat: 1.0,
                clearcoat_gloss: 0.0,
            }),
        ),
        (
            "disney metal",
            Parametric::Disney(Disney {
                base_color: [0.9, 0.6, 0.3],
                metallic: 1.0,
                roughness: 0.45,
                ..Disney::default()
            }),
        ),
    ]
}

#[test]
fn sample_and_pdf_agree_and_weights_are_unbiased() {
    // 400k samples detect, e.g., a Phong lobe sampled with exponent n + 0.5 (χ² ≈ 780 against a limit
    // of 650); the configurations run on scoped threads.
    let n = 400_000;
    std::thread::scope(|scope| {
        let mut all: Vec<(&str, Box<dyn Brdf + Send + Sync>)> =
            parametric_models().into_iter().map(|(n, m)| (n, Box::new(m) as Box<dyn Brdf + Send + Sync>)).collect();
        all.extend(Builtin::ALL.map(|b| (b.id(), Box::new(b) as Box<dyn Brdf + Send + Sync>)));
        for (k, (name, m)) in all.into_iter().enumerate() {
            scope.spawn(move || {
                for (t, theta) in [0.5f64, 1.3].into_iter().enumerate() {
                    let wo = dir(theta, 0.7);
                    let label = format!("{name} θo={theta}");
                    let (_, mean) = check_model(&label, m.as_ref(), wo, n, 1 + (k * 3 + t) as u64);
                    // E[weight] = ∫ f cos θi dωi wherever the pdf covers f (every mixture here has full
                    // support).
                    let a = albedo(&|wi, wo| m.eval(wi, wo), wo, 512);
                    for c in 0..3 {
                        assert!(
                            (mean[c] - a[c]).abs() < 0.02 * a[c].max(0.05),
                            "{label}: E[weight] {mean:?} vs albedo {a:?}"
                        );
                    }
                }
            });
        }
    });
}

#[test]
fn cosine_lobe_pdf_integrates_to_one() {
    let m = Parametric::Lambert(Lambert { kd: [1.0; 3] });
    let total: f64 = expected_mass(&|wi| m.pdf(wi, dir(0.4, 0.0))).iter().sum();
    assert!((total - 1.0).abs() < 1e-4, "{total}");
}

#[test]
fn below_horizon_wo_gives_nothing() {
    for (_, m) in parametric_models() {
        assert!(m.sample(Vec3::new(0.3, 0.0, -0.5), [0.5, 0.5, 0.5]).is_none());
        assert_eq!(m.pdf(Vec3::Z, Vec3::new(0.3, 0.0, -0.5)), 0.0);
        assert_eq!(m.pdf(Vec3::new(0.3, 0.0, -0.5), Vec3::Z), 0.0);
    }
    for b in Builtin::ALL {
        assert!(b.sample(Vec3::new(0.3, 0.0, -0.5), [0.5, 0.5, 0.5]).is_none());
        assert_eq!(b.pdf(Vec3::new(0.3, 0.0, -0.5), Vec3::Z), 0.0);
    }
}

#[test]
fn samples_stay_finite_in_extreme_regimes() {
    use nbrdf::parametric::{ParametricKind, MAX_RAW};
    let z = 1e-7f32;
    let wos = [Vec3::Z, Vec3::new((1.0 - z * z).sqrt(), 0.0, z), dir(1.2, 0.4)];
    let us = [0.0f32, 1e-7, 0.5, 0.999_999_9];
    for kind in ParametricKind::ALL {
        for bits in 0u32..64 {
            // Six raw outputs at ±1e4 in turn (roughness 0/1, weights 0/1, ...), the rest at 0.
            let raw: Vec<f32> = (0..MAX_RAW)
                .map(|i| {
                    if i < 6 {
                        if bits >> i & 1 == 1 {
                            1e4
                        } else {
                            -1e4
                        }
                    } else {
                        ((bits + i as u32) % 3) as f32 * 1e4 - 1e4
                    }
                })
                .collect();
            let m = Parametric::from_raw(kind, &raw, &[0.0]);
            for wo in wos {
                for u0 in us {
                    for u1 in us {
                        for u2 in [0.1f32, 0.6, 0.95] {
                            if let Some(s) = m.sample(wo, [u0, u1, u2]) {
                                assert!(
                                    s.wi.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite(),
                                    "{m:?} {wo}: {s:?}"
                                );
                                assert!(
                                    s.weight.iter().all(|w| w.is_finite() && *w >= 0.0),
                                    "{m:?} {wo}: {s:?}"
                                );
                            }
                            let p = m.pdf(dir(0.3, u0 as f64 * 6.0), wo);
                            assert!(p.is_finite() && p >= 0.0);
                        }
                    }
                }
            }
        }
    }
    for b in Builtin::ALL {
        for wo in wos {
            for u0 in us {
                for u1 in us {
                    for u2 in [0.1f32, 0.6, 0.95] {
                        if let Some(s) = b.sample(wo, [u0, u1, u2]) {
                            assert!(s.wi.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite(), "{b:?} {wo}: {s:?}");
                            assert!(s.weight.iter().all(|w| w.is_finite() && *w >= 0.0), "{b:?} {wo}: {s:?}");
                        }
                    }
                }
            }
        }
    }
}
