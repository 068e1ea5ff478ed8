//! The per-view sampling table of neural and measured BRDFs: for every kind that samples through it —
//! a `.nbrdf` neural model, a MERL table, an NBRDF-json network — `sample` and `pdf` agree at five
//! view angles (the chi-square test of `tests/sampling.rs`), the weight is unbiased for the albedo, and
//! the table survives the model file while files without it still sample through their single proxy.

use nbrdf::builtin::Builtin;
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::sampling::{fit_view_proxy, Proxy, ViewProxy, VIEW_NODES};
use nbrdf::{Brdf, ModelBuf, Rgb, Vec3};

mod common;
use common::{albedo, check_sampler_at, dir, Sampler};

/// The view angles of the sampler benchmark (docs/speed.md).
const VIEWS: [f64; 5] = [0.1, 0.5, 0.9, 1.2, 1.4];

/// Chi-square and weight checks of `brdf`'s own sampler at every view of [`VIEWS`]; the mean weight
/// must match the albedo by quadrature.
fn check_every_view(name: &str, brdf: &(dyn Brdf + Sync), n: usize, seed: u64) {
    for (k, &theta) in VIEWS.iter().enumerate() {
        let wo = dir(theta, 0.4);
        let label = format!("{name} θo={theta}");
        let sampler = Sampler { sample: &|u| brdf.sample(wo, u), pdf: &|wi| brdf.pdf(wi, wo), eval: &|wi| brdf.eval(wi, wo) };
        // 32² quadrature points per histogram bin: the tables' narrow lobes at grazing views need them.
        let (_, mean) = check_sampler_at(&label, &sampler, n, seed + k as u64, 32);
        let a = albedo(&|wi, wo| brdf.eval(wi, wo), wo, 512);
        // Peaked BRDFs have heavy-tailed weights at grazing views: a loose bound, against a gross bias.
        assert!((mean[1] - a[1]).abs() < 0.06 * a[1].max(0.05), "{label}: E[weight] {mean:?} vs albedo {a:?}");
    }
}

/// A built-in material sampled through a fitted table instead of its own lobes.
struct ThroughTable {
    material: Builtin,
    view: ViewProxy,
}

impl Brdf for ThroughTable {
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        self.material.eval(wi, wo)
    }
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<nbrdf::BsdfSample> {
        self.view.sample(wo, u, |wi, wo| self.material.eval(wi, wo))
    }
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.view.pdf(wi, wo)
    }
    fn is_reciprocal(&self) -> bool {
        true
    }
}

#[test]
fn fitted_tables_sample_what_their_pdf_says_at_every_view() {
    std::thread::scope(|scope| {
        for (k, material) in [Builtin::TwoLobeMetal, Builtin::ClearCoat, Builtin::Velvet].into_iter().enumerate() {
            scope.spawn(move || {
                let b = ThroughTable { material, view: fit_view_proxy(|wi, wo| material.eval(wi, wo)) };
                b.view.validate().unwrap();
                check_every_view(material.id(), &b, 100_000, 40 + 10 * k as u64);
            });
        }
    });
}

#[test]
fn a_merl_table_samples_through_its_view_table() {
    let table = MerlTable::tabulate(|wi, wo| Builtin::TwoLobeMetal.eval(wi, wo));
    assert_ne!(table.view_proxy(), &ViewProxy::default());
    let wo = dir(0.7, 0.0);
    let s = Brdf::sample(&table, wo, [0.2, 0.6, 0.9]).unwrap();
    assert_eq!(s.pdf, table.view_proxy().pdf(s.wi, wo));
    check_every_view("MERL table of two-lobe-metal", &table, 100_000, 60);
}

#[test]
fn nbrdf_json_networks_sample_through_their_view_table() {
    let root = std::env::var("NBRDF_DATA").unwrap_or_else(|_| String::from("../shared/data"));
    // Lobes of α ≈ 0.004 (chrome-steel's) are finer than the histogram's quadrature resolves; its
    // sample and pdf are compared one by one in tests/proxy.rs.
    for (k, name) in ["beige-fabric", "purple-paint"].into_iter().enumerate() {
        let path = std::path::Path::new(&root).join(format!("nbrdf-merl/{name}.json"));
        if !path.exists() {
            eprintln!("skipped: {} not found (set NBRDF_DATA to the shared data folder)", path.display());
            return;
        }
        let net = NbrdfNetwork::load(&path).unwrap();
        check_every_view(name, &net, 100_000, 70 + 10 * k as u64);
    }
}

#[test]
fn a_model_file_carries_its_view_table_and_older_files_sample_as_before() {
    let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let weights: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
    // Fitted at export, as the trainer does: both the single proxy and the table around it.
    let plain = ModelBuf::from_bytes(&encode(&h, &weights, None).unwrap()).unwrap();
    let point = plain.model().prepare(&[]).unwrap();
    let proxy = plain.model().fit_proxy(&[point]);
    let view = plain.model().fit_view_proxy(&[point], &proxy);
    let with_proxy = encode(&h.with_proxy(proxy), &weights, None).unwrap();
    let with_view = encode(&h.with_proxy(proxy).with_view_proxy(view), &weights, None).unwrap();
    let buf = ModelBuf::from_bytes(&with_view).unwrap();
    assert_eq!(buf.header().view_proxy, Some(view));
    let brdf = buf.model().at(&[]).unwrap();
    check_every_view("additive-shared model", &brdf, 100_000, 90);
    // A file without the table (every file written before it) samples through its proxy, as before.
    let old = ModelBuf::from_bytes(&with_proxy).unwrap();
    assert_eq!(old.header().view_proxy, None);
    let wo = dir(0.5, 0.3);
    let s = old.model().at(&[]).unwrap().sample(wo, [0.3, 0.7, 0.8]).unwrap();
    assert_eq!(s.pdf, proxy.pdf(s.wi, wo));
    // The table is the trailing field: the file with it is the older file plus the table's bytes.
    assert!(with_view.len() > with_proxy.len() + VIEW_NODES * 4);
}

#[test]
fn an_invalid_table_is_refused() {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    let weights = vec![0.01f32; h.n_weights()];
    let mut view = ViewProxy::default();
    view.nodes[3] = Proxy { diffuse: 0.0, ..Proxy::COSINE };
    let err = encode(&h.with_view_proxy(view), &weights, None).unwrap_err().to_string();
    assert!(err.contains("proxy"), "{err}");
}
