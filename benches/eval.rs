//! Evaluation cost of every model: ns per `eval` (one direction pair at a prepared point) and per
//! `prepare` (one shading point), f32 and f16 weights, single queries and batches of many directions
//! at one point. Run: `cargo bench --bench eval`.

use std::hint::black_box;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nbrdf::file::{encode, ModelBuf, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::parametric::ParametricKind;
use nbrdf::{Rgb, Vec3};

fn weights(n: usize) -> Vec<f32> {
    let mut s = 0x9e3779b97f4a7c15u64;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.2
        })
        .collect()
}

fn directions(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut wi = Vec::with_capacity(n);
    let mut wo = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f32 * 0.618;
        wi.push(Vec3::new(t.sin() * 0.6, t.cos() * 0.5, 0.6).normalize());
        wo.push(Vec3::new((t * 1.7).cos() * 0.5, (t * 0.3).sin() * 0.7, 0.5).normalize());
    }
    (wi, wo)
}

/// The variants of the paper's Tab. 1 with the intrinsic encoding of 64 eigenfunctions.
fn variants() -> Vec<(String, ModelHeader)> {
    let pos = PositionEncoding::Intrinsic { k: 64 };
    let mut v: Vec<(String, ModelHeader)> = ParametricKind::ALL
        .iter()
        .map(|&k| (k.id().to_string(), ModelHeader::paper(ModelKind::Parametric(k), false, Reciprocity::None, pos, 0)))
        .collect();
    for (name, kind, enhanced) in [
        ("single-mlp", ModelKind::SingleMlp, false),
        ("additive-separate", ModelKind::AdditiveSeparate, false),
        ("additive-shared", ModelKind::AdditiveShared, false),
        ("additive-separate-enhanced", ModelKind::AdditiveSeparate, true),
        ("additive-shared-enhanced", ModelKind::AdditiveShared, true),
    ] {
        v.push((name.to_string(), ModelHeader::paper(kind, enhanced, Reciprocity::Exact, pos, 4)));
    }
    v
}

fn bench_models(c: &mut Criterion) {
    let p: Vec<f32> = (0..64).map(|i| (i as f32 * 0.1).sin()).collect();
    let (wi, wo) = directions(1024);
    for precision in [Precision::F32, Precision::F16] {
        let mut g = c.benchmark_group(format!("eval-{precision:?}").to_lowercase());
        for (name, mut h) in variants() {
            h.precision = precision;
            let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights()), None).unwrap()).unwrap();
            let m = buf.model();
            let prepared = m.prepare(&p);
            g.throughput(Throughput::Elements(1));
            g.bench_function(BenchmarkId::new("single", &name), |b| {
                let mut i = 0;
                b.iter(|| {
                    i = (i + 1) & 1023;
                    black_box(m.eval(&prepared, black_box(wi[i]), black_box(wo[i])))
                })
            });
            g.bench_function(BenchmarkId::new("prepare", &name), |b| b.iter(|| black_box(m.prepare(black_box(&p)))));
            g.throughput(Throughput::Elements(wi.len() as u64));
            let mut out: Vec<Rgb> = vec![[0.0; 3]; wi.len()];
            g.bench_function(BenchmarkId::new("batch-1024", &name), |b| {
                b.iter(|| m.eval_many(&prepared, black_box(&wi), black_box(&wo), &mut out))
            });
        }
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = bench_models
}
criterion_main!(benches);
