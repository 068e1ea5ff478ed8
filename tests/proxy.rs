//! The sampling proxy of neural and measured BRDFs: its `sample` and `pdf` agree (a chi-square test on a
//! histogram of sampled directions, as in `tests/sampling.rs`), its pdf integrates to the probability
//! that a sample is produced, the estimator weight `f cos / pdf` is unbiased for the albedo, the fit finds
//! the lobe of a known BRDF, and the proxy survives the model file.

use nbrdf::builtin::Builtin;
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf::ModelBuf;
use nbrdf::measured::NbrdfNetwork;
use nbrdf::microfacet::{ggx_d, smith_ggx_g1_over_2cos};
use nbrdf::Brdf;
use nbrdf::sampling::proxy::DEFENSIVE;
use nbrdf::sampling::{fit_proxy, GgxLobe, Proxy};
use nbrdf::{Rgb, Vec3};

mod common;
use common::{albedo, check_sampler, dir, Sampler};

/// Samples `proxy` `n` times with `brdf` for the weight and checks it against its pdf
/// ([`common::check_sampler`]); returns the mean weight.
fn check(name: &str, proxy: &Proxy, brdf: &dyn Fn(Vec3, Vec3) -> Rgb, wo: Vec3, n: usize, seed: u64) -> [f64; 3] {
    let sampler = Sampler { sample: &|u| proxy.sample(wo, u, brdf), pdf: &|wi| proxy.pdf(wi, wo), eval: &|wi| brdf(wi, wo) };
    check_sampler(name, &sampler, n, seed).1
}

/// A Fresnel-free GGX microfacet BRDF, written out here independently of the fit.
fn ggx(wi: Vec3, wo: Vec3, alpha: f32) -> f32 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    let h = (wi + wo).normalize();
    ggx_d(h.z, 1.0 - h.z * h.z, alpha) * smith_ggx_g1_over_2cos(wi.z, alpha) * smith_ggx_g1_over_2cos(wo.z, alpha)
}

#[test]
fn proxy_sample_and_pdf_agree_and_weights_are_unbiased() {
    let metal = |wi: Vec3, wo: Vec3| Builtin::TwoLobeMetal.eval(wi, wo);
    let coat = |wi: Vec3, wo: Vec3| Builtin::ClearCoat.eval(wi, wo);
    type Reference<'a> = &'a (dyn Fn(Vec3, Vec3) -> Rgb + Sync);
    let cases: Vec<(&str, Proxy, Reference)> = vec![
        ("fitted two-lobe-metal", fit_proxy(metal), &metal),
        ("fitted clear-coat", fit_proxy(coat), &coat),
        ("hand-made", Proxy::new(0.3, [GgxLobe { weight: 0.5, alpha: 0.08 }, GgxLobe { weight: 0.2, alpha: 0.5 }]).unwrap(), &metal),
    ];
    std::thread::scope(|scope| {
        for (k, (name, proxy, brdf)) in cases.into_iter().enumerate() {
            scope.spawn(move || {
                for (t, theta) in [0.5f64, 1.3].into_iter().enumerate() {
                    let wo = dir(theta, 0.7);
                    let label = format!("{name} θo={theta}");
                    let mean = check(&label, &proxy, brdf, wo, 200_000, 11 + (2 * k + t) as u64);
                    // The cosine lobe covers the hemisphere, so E[f cos / pdf] is the albedo.
                    let a = albedo(brdf, wo, 768);
                    for c in 0..3 {
                        assert!((mean[c] - a[c]).abs() < 0.03 * a[c].max(0.05), "{label}: E[weight] {mean:?} vs albedo {a:?}");
                    }
                }
            });
        }
    });
}

#[test]
fn fit_finds_the_lobe_of_a_known_brdf() {
    // 10 % diffuse under a GGX lobe of α = 0.15 carrying 90 % of the albedo.
    let brdf = |wi: Vec3, wo: Vec3| [0.1 / core::f32::consts::PI + 0.9 * ggx(wi, wo, 0.15); 3];
    let p = fit_proxy(brdf);
    p.validate().unwrap();
    let main = p.lobes.iter().max_by(|a, b| a.weight.total_cmp(&b.weight)).unwrap();
    // The α grid steps by a factor 1.34; the fit must land on a neighbour of 0.15.
    assert!(main.alpha > 0.15 / 1.4 && main.alpha < 0.15 * 1.4, "{p:?}");
    // Selection probabilities: DEFENSIVE of cosine, the rest split 10 : 90 between the lobes.
    let spec: f32 = p.lobes.iter().map(|l| l.weight).sum();
    assert!((p.diffuse - (DEFENSIVE + 0.9 * 0.1)).abs() < 0.03 && (spec - 0.9 * 0.9).abs() < 0.03, "{p:?}");
}

#[test]
fn fit_of_a_lambertian_or_black_brdf_is_the_cosine_lobe() {
    let p = fit_proxy(|_, _| [0.3; 3]);
    assert!(p.diffuse > 0.99, "{p:?}");
    assert_eq!(fit_proxy(|_, _| [0.0; 3]), Proxy::COSINE);
    assert_eq!(fit_proxy(|_, _| [f32::NAN; 3]), Proxy::COSINE);
}

#[test]
fn model_file_round_trips_its_proxy_and_samples_it() {
    let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let weights: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
    // Fit at export, as the trainer does: evaluate the model without a proxy, store the fit.
    let plain = ModelBuf::from_bytes(&encode(&h, &weights, None).unwrap()).unwrap();
    assert_eq!(plain.model().proxy(), Proxy::COSINE);
    let point = plain.model().prepare(&[]).unwrap();
    let proxy = plain.model().fit_proxy(&[point]);
    proxy.validate().unwrap();
    let buf = ModelBuf::from_bytes(&encode(&h.with_proxy(proxy), &weights, None).unwrap()).unwrap();
    assert_eq!(buf.header().proxy, Some(proxy));
    let (model, p) = (buf.model(), buf.model().prepare(&[]).unwrap());
    let wo = dir(0.6, 0.2);
    let s = model.sample(&p, wo, [0.3, 0.8, 0.5]).unwrap();
    assert_eq!(s.pdf, proxy.pdf(s.wi, wo));
    assert_eq!(model.pdf(&p, s.wi, wo), s.pdf);
    let f = model.eval(&p, s.wi, wo);
    assert!((s.weight[0] - f[0] * s.wi.z / s.pdf).abs() <= 1e-5 * s.weight[0].max(1e-6));
    // An invalid proxy is refused at export.
    let bad = Proxy { diffuse: 0.0, lobes: [GgxLobe { weight: 1.0, alpha: 0.1 }, GgxLobe::NONE] };
    assert!(encode(&h.with_proxy(bad), &weights, None).is_err());
}

#[test]
fn chrome_network_gets_a_sharp_lobe() {
    let dir_ = std::env::var("NBRDF_DATA").unwrap_or_else(|_| String::from("../shared/data"));
    let path = std::path::Path::new(&dir_).join("nbrdf-merl/chrome-steel.json");
    if !path.exists() {
        eprintln!("skipping: {} not found (set NBRDF_DATA)", path.display());
        return;
    }
    let net = NbrdfNetwork::load(&path).unwrap();
    let proxy = *net.proxy();
    proxy.validate().unwrap();
    let sharp = proxy.lobes.iter().filter(|l| l.alpha < 0.1).map(|l| l.weight).sum::<f32>();
    assert!(sharp > 0.5, "chrome-steel should be sampled mostly by a sharp lobe: {proxy:?}");
    let wo = dir(0.4, 1.0);
    // The network samples through its per-view table, fitted around that proxy (tests/view_proxy.rs).
    let s = net.sample(wo, [0.1, 0.9, 0.6]).unwrap();
    assert_eq!(s.pdf, net.view_proxy().pdf(s.wi, wo));
    assert_eq!(s.pdf, net.pdf(s.wi, wo));
}

#[test]
fn files_written_before_the_proxy_field_still_load() {
    // Rewrite a file as the previous header layout had it: without the proxy's trailing `None` byte.
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let weights: Vec<f32> = (0..h.n_weights()).map(|i| (i % 13) as f32 * 1e-2).collect();
    let new = encode(&h, &weights, None).unwrap();
    let len = u32::from_le_bytes(new[12..16].try_into().unwrap()) as usize;
    assert_eq!(new[16 + len - 1], 0, "a header without a proxy ends in postcard's None");
    let mut old = new[..12].to_vec();
    old.extend_from_slice(&((len - 1) as u32).to_le_bytes());
    old.extend_from_slice(&new[16..16 + len - 1]);
    old.resize((16 + len - 1).div_ceil(4) * 4, 0);
    old.extend_from_slice(&new[(16 + len).div_ceil(4) * 4..new.len() - 4]);
    let crc = crc32fast::hash(&old);
    old.extend_from_slice(&crc.to_le_bytes());
    let buf = ModelBuf::from_bytes(&old).unwrap();
    assert_eq!(buf.header(), &h);
    let (wi, wo) = (dir(0.3, 0.1), dir(0.5, 2.0));
    let (a, b) = (buf.model(), ModelBuf::from_bytes(&new).unwrap());
    assert_eq!(a.eval(&a.prepare(&[]).unwrap(), wi, wo), b.model().eval(&b.model().prepare(&[]).unwrap(), wi, wo));
}

#[test]
fn parametric_models_sample_their_own_lobes_not_the_proxy() {
    use nbrdf::parametric::ParametricKind;
    let h = ModelHeader::paper(
        ModelKind::Parametric(ParametricKind::Phong),
        false,
        Reciprocity::None,
        PositionEncoding::Extrinsic { frequencies: 2 },
        0,
    );
    let weights: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 31) % 97) as f32 * 1e-3 - 0.05).collect();
    // Even with a proxy in the header, the predicted Phong parameters drive sampling.
    let proxy = Proxy::new(0.5, [GgxLobe { weight: 0.5, alpha: 0.3 }, GgxLobe::NONE]).unwrap();
    let buf = ModelBuf::from_bytes(&encode(&h.with_proxy(proxy), &weights, None).unwrap()).unwrap();
    let model = buf.model();
    let p = model.prepare(&[0.2, -0.4, 0.6]).unwrap();
    let params = *p.parameters().unwrap();
    let wo = dir(0.7, 0.3);
    for u in [[0.1, 0.2, 0.3], [0.8, 0.5, 0.9], [0.4, 0.9, 0.6]] {
        assert_eq!(model.sample(&p, wo, u), params.sample(wo, u));
    }
    let wi = dir(0.4, 2.5);
    assert_eq!(model.pdf(&p, wi, wo), params.pdf(wi, wo));
    assert_ne!(model.pdf(&p, wi, wo), proxy.pdf(wi, wo));
}
