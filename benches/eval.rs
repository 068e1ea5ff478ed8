//! Evaluation cost of every model: ns per `eval` (one direction pair at a prepared point) and per
//! `prepare` (one shading point; at the best level also `prepare-many-1024`, 1 024 points at once),
//! f32 and f16 weights, single queries and batches of many directions at one point, at every kernel level this CPU has (`portable` is the pre-SIMD scalar path, the
//! baseline of the SIMD levels; the neural models' batches also with independent random directions,
//! `batch-1024-random`, and in calls of 32 pairs, `batch-32`, at the best level), plus the NBRDF-json networks, plus the neural models'
//! batched throughput with one thread per core (`eval-f32-N-threads`, wall time), and the floor that
//! L2 bandwidth puts under a single Single MLP query (`eval-floor`). Run: `cargo bench --bench eval`,
//! or e.g. `cargo bench --bench eval -- 'eval-f32/.*single-mlp'` for one model. Models load
//! through `ModelBuf::from_bytes_as_is`, so that f16 ones keep their f16 rows, which the kernels widen
//! as they read them (`from_bytes` widens an f16 file at load and then runs it as the f32 one).
//!
//! On Linux the clock is the thread's CPU time (`CLOCK_THREAD_CPUTIME_ID`), not wall time: the
//! development machine is shared by several compiling users, and CPU time stays meaningful while the
//! benchmark thread waits for a core. Set `NBRDF_BENCH_WALL=1` for wall time.

use std::hint::black_box;
use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nbrdf::kernels::{detected, set_level, Level};
use nbrdf::measured::NbrdfNetwork;
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::ModelBuf;
use nbrdf::parametric::ParametricKind;
use nbrdf::{Rgb, Vec3};

/// Uniform values in [0, 1) from a xorshift64 sequence started at `seed`.
fn uniform(mut s: u64) -> impl FnMut() -> f32 {
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn weights(n: usize) -> Vec<f32> {
    let mut u = uniform(0x9e3779b97f4a7c15);
    (0..n).map(|_| (u() - 0.5) * 0.2).collect()
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

/// `n` pairs drawn uniformly over the hemisphere (by area), independently: a batch whose neighbouring
/// queries have nothing in common but their point, the hard case for the sparse packets' pairs.
fn random_directions(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut u = uniform(0x2545f4914f6cdd1d);
    let mut dir = || {
        let (z, phi) = (u(), std::f32::consts::TAU * u());
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z.max(1e-4))
    };
    (0..n).map(|_| (dir(), dir())).unzip()
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

/// The kernel levels to compare: portable (the scalar "before") and every SIMD level the CPU has.
fn levels() -> Vec<(Level, &'static str)> {
    Level::usable().map(|l| (l, l.name())).collect()
}

/// Thread CPU time in ns (Linux), or wall time where `NBRDF_BENCH_WALL` is set or elsewhere.
struct Clock {
    wall: bool,
}

#[cfg(target_os = "linux")]
fn cpu_ns() -> u64 {
    #[repr(C)]
    struct Timespec {
        sec: i64,
        nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut t = Timespec { sec: 0, nsec: 0 };
    // SAFETY: `t` is a valid, writable timespec (two C longs on 64-bit Linux).
    unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.sec as u64 * 1_000_000_000 + t.nsec as u64
}

impl Clock {
    fn new() -> Self {
        Clock { wall: !cfg!(target_os = "linux") || std::env::var_os("NBRDF_BENCH_WALL").is_some() }
    }
    fn now(&self) -> u64 {
        #[cfg(target_os = "linux")]
        if !self.wall {
            return cpu_ns();
        }
        static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
        START.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
    }
}

impl Measurement for Clock {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        self.now()
    }
    fn end(&self, start: u64) -> u64 {
        self.now() - start
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        // Both clocks count nanoseconds, as wall time does.
        static WALL: WallTime = WallTime;
        WALL.formatter()
    }
}

fn bench_models(c: &mut Criterion<Clock>) {
    let p: Vec<f32> = (0..64).map(|i| (i as f32 * 0.1).sin()).collect();
    // 1 024 points' intrinsic features, neighbouring points alike (a smooth field over the surface).
    let points: Vec<f32> = (0..1024 * 64).map(|i| ((i % 64) as f32 * 0.1 + (i / 64) as f32 * 0.013).sin()).collect();
    let (wi, wo) = directions(1024);
    let (rwi, rwo) = random_directions(1024);
    for precision in [Precision::F32, Precision::F16] {
        let mut g = c.benchmark_group(format!("eval-{precision:?}").to_lowercase());
        for (name, mut h) in variants() {
            h.precision = precision;
            let buf = ModelBuf::from_bytes_as_is(&encode(&h, &weights(h.n_weights()), None).unwrap()).unwrap();
            let m = buf.model();
            for (level, lname) in levels() {
                set_level(Some(level));
                let prepared = m.prepare(&p).unwrap();
                g.throughput(Throughput::Elements(1));
                g.bench_function(BenchmarkId::new(format!("single/{lname}"), &name), |b| {
                    let mut i = 0;
                    b.iter(|| {
                        i = (i + 1) & 1023;
                        black_box(m.eval(&prepared, black_box(wi[i]), black_box(wo[i])))
                    })
                });
                g.bench_function(BenchmarkId::new(format!("prepare/{lname}"), &name), |b| {
                    b.iter(|| black_box(m.prepare(black_box(&p)).unwrap()))
                });
                if level == detected() {
                    // 1 024 points of one material at once (a wavefront's hits): the position
                    // networks in packets.
                    g.throughput(Throughput::Elements(points.len() as u64 / 64));
                    let mut many = vec![prepared; points.len() / 64];
                    g.bench_function(BenchmarkId::new(format!("prepare-many-1024/{lname}"), &name), |b| {
                        b.iter(|| m.prepare_many(black_box(&points), &mut many).unwrap())
                    });
                    g.throughput(Throughput::Elements(1));
                }
                g.throughput(Throughput::Elements(wi.len() as u64));
                let mut out: Vec<Rgb> = vec![[0.0; 3]; wi.len()];
                g.bench_function(BenchmarkId::new(format!("batch-1024/{lname}"), &name), |b| {
                    b.iter(|| m.eval_many(&prepared, black_box(&wi), black_box(&wo), &mut out))
                });
                if level == detected() && !matches!(h.kind, ModelKind::Parametric(_)) {
                    g.bench_function(BenchmarkId::new(format!("batch-1024-random/{lname}"), &name), |b| {
                        b.iter(|| m.eval_many(&prepared, black_box(&rwi), black_box(&rwo), &mut out))
                    });
                    // Calls of 32 pairs, as a renderer makes at a shading point, stepping through the
                    // directions.
                    g.throughput(Throughput::Elements(32));
                    let mut k = 0;
                    g.bench_function(BenchmarkId::new(format!("batch-32/{lname}"), &name), |b| {
                        b.iter(|| {
                            k = (k + 32) & 1023;
                            m.eval_many(&prepared, black_box(&wi[k..k + 32]), black_box(&wo[k..k + 32]), &mut out[..32])
                        })
                    });
                    g.throughput(Throughput::Elements(wi.len() as u64));
                }
            }
            set_level(None);
        }
        g.finish();
    }
}

/// A 6-21-21-3 NBRDF-json network (the published size) with deterministic weights.
fn nbrdf_json() -> NbrdfNetwork {
    let w = weights(6 * 21 + 21 + 21 * 21 + 21 + 21 * 3 + 3);
    let mut it = w.iter();
    let mut layer = |n_in: usize, n_out: usize, act: &str| {
        let rows: Vec<String> = (0..n_out)
            .map(|_| format!("[{}]", (0..n_in).map(|_| it.next().unwrap().to_string()).collect::<Vec<_>>().join(",")))
            .collect();
        let bias: Vec<String> = (0..n_out).map(|_| it.next().unwrap().to_string()).collect();
        format!(r#"{{"inputs":{n_in},"outputs":{n_out},"activation":"{act}","weight":[{}],"bias":[{}]}}"#, rows.join(","), bias.join(","))
    };
    let layers = [layer(6, 21, "relu"), layer(21, 21, "relu"), layer(21, 3, "none")].join(",");
    let json = format!(r#"{{"input":"rusinkiewicz_half_diff_vectors","output":"expm1_clamped","layers":[{layers}]}}"#);
    NbrdfNetwork::from_json_str(&json).unwrap()
}

fn bench_nbrdf_json(c: &mut Criterion<Clock>) {
    let net = nbrdf_json();
    let (wi, wo) = directions(1024);
    let mut g = c.benchmark_group("nbrdf-json");
    for (level, lname) in levels() {
        set_level(Some(level));
        g.throughput(Throughput::Elements(1));
        g.bench_function(BenchmarkId::new("eval", lname), |b| {
            let mut i = 0;
            b.iter(|| {
                i = (i + 1) & 1023;
                black_box(net.eval(black_box(wi[i]), black_box(wo[i])))
            })
        });
        g.throughput(Throughput::Elements(wi.len() as u64));
        let mut out: Vec<Rgb> = vec![[0.0; 3]; wi.len()];
        g.bench_function(BenchmarkId::new("eval_many-1024", lname), |b| {
            b.iter(|| net.eval_many(black_box(&wi), black_box(&wo), &mut out))
        });
        g.throughput(Throughput::Elements(1));
        g.bench_function(BenchmarkId::new("eval_angles", lname), |b| {
            let mut i = 0;
            b.iter(|| {
                i = (i + 1) & 1023;
                let t = i as f32 * 1e-3;
                black_box(net.eval_angles(black_box(0.3 + t), black_box(0.7 - t), black_box(1.0 + t)))
            })
        });
    }
    set_level(None);
    g.finish();
}

/// Batched evaluation over every core: the throughput a renderer sees when each of its threads
/// evaluates its own batch (the machine-wide figure, where the FLOP limit of the paper-size
/// Single MLP is quoted for the whole two-core machine). Wall time per query over all threads; each
/// thread owns its output and its own prepared point, as in a renderer.
fn bench_all_cores(c: &mut Criterion<WallTime>) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let p: Vec<f32> = (0..64).map(|i| (i as f32 * 0.1).sin()).collect();
    let (wi, wo) = directions(1024);
    let mut g = c.benchmark_group(format!("eval-f32-{threads}-threads"));
    g.throughput(Throughput::Elements((threads * 8 * wi.len()) as u64));
    for (name, h) in variants().into_iter().filter(|(n, _)| !ParametricKind::ALL.iter().any(|k| k.id() == n)) {
        let buf = ModelBuf::from_bytes(&encode(&h, &weights(h.n_weights()), None).unwrap()).unwrap();
        let m = buf.model();
        g.bench_function(BenchmarkId::new("batch-8x1024", &name), |b| {
            b.iter(|| {
                std::thread::scope(|s| {
                    for _ in 0..threads {
                        s.spawn(|| {
                            let prepared = m.prepare(&p).unwrap();
                            let mut out: Vec<Rgb> = vec![[0.0; 3]; wi.len()];
                            for _ in 0..8 {
                                m.eval_many(&prepared, black_box(&wi), black_box(&wo), &mut out);
                            }
                            black_box(out[0])
                        });
                    }
                })
            })
        });
    }
    g.finish();
}

/// The weight rows one Single MLP query reads, as byte offsets into its network's f32 weights: per
/// layer the rows of the nonzero inputs (the encoded angles of layer 0 and the skip layer, the nonzero
/// activations of the hidden layers, found by running the network's prefixes through `nbrdf::mlp`),
/// in the order the kernels read them. The output layer's rows (3 weights each) count one vector.
fn single_query_rows(h: &ModelHeader, w: &[f32], pos: &[f32], wi: Vec3, wo: Vec3) -> Vec<(usize, bool)> {
    use nbrdf::mlp::{forward, partial, Net, NetDesc};
    let d = h.nets[0];
    let (width, n_in) = (d.width as usize, d.n_in as usize);
    let angles = nbrdf::angles::theta_map(wi, wo).unwrap();
    let mut tail = vec![0.0f32; n_in - pos.len()];
    nbrdf::encoding::positional_encoding(&angles, h.angle_frequencies as usize, &mut tail);
    let net = |hidden: u8| Net { desc: NetDesc { hidden, n_out: 0, skip: if d.skip < hidden { d.skip } else { 0 }, ..d }, weights: w };
    let mut rows = Vec::new();
    let tail_rows = |rows: &mut Vec<(usize, bool)>, first_row: usize| {
        rows.extend(tail.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(i, _)| ((first_row + i) * width * 4, true)));
    };
    tail_rows(&mut rows, pos.len());
    for l in 1..=d.hidden as usize {
        let off = d.layer_offset(l);
        let mut act = [0.0f32; 256];
        let prefix = net(l as u8);
        forward(&prefix, &partial(&prefix, pos), &tail, &mut act);
        let row = if l < d.hidden as usize { width } else { d.n_out as usize } * 4;
        rows.extend(act[..width].iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(i, _)| (off * 4 + i * row, l < d.hidden as usize)));
        if l == d.skip as usize {
            tail_rows(&mut rows, off / width + width + pos.len());
        }
    }
    rows
}

/// Streams the listed rows (8 vectors of 16 f32, or 1 where `false`) into FMAs with no dependence
/// between rows: what the weight reads of a query cost with nothing else in the way.
///
/// # Safety
/// The CPU has AVX-512F; every row lies in `w`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn stream_rows(w: &[f32], rows: &[(usize, bool)]) -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm512_setzero_ps(); 8];
    let x = _mm512_set1_ps(0.5);
    let base = w.as_ptr().cast::<u8>();
    for &(off, full) in rows {
        // SAFETY: the row lies in `w` (contract).
        let r = unsafe { base.add(off).cast::<f32>() };
        // Constant trip counts, so that the accumulators stay in registers (a loop of `full ? 8 : 1`
        // steps kept them on the stack, each FMA waiting on the last one's store).
        if full {
            for (k, a) in acc.iter_mut().enumerate() {
                *a = _mm512_fmadd_ps(x, unsafe { _mm512_loadu_ps(r.add(16 * k)) }, *a);
            }
        } else {
            acc[0] = _mm512_fmadd_ps(x, unsafe { _mm512_loadu_ps(r) }, acc[0]);
        }
    }
    let s = acc.iter().fold(_mm512_setzero_ps(), |s, a| _mm512_add_ps(s, *a));
    _mm512_reduce_add_ps(s)
}

/// The L2 floor of a single Single MLP query: the same model as `eval-f32/single/*/single-mlp`, its
/// weights in a 64-byte-aligned copy, and only the weight rows that a query reads streamed through
/// FMAs (`single_query_rows`), ~200 KB of the 360 KB. A single query cannot be faster than this plus
/// its angle map, encoding and output map; the ratio of the two is how close the kernel is.
fn bench_l2_floor(c: &mut Criterion<Clock>) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx512f") {
        let (_, h) = variants().into_iter().find(|(n, _)| n == "single-mlp").unwrap();
        let w = weights(h.n_weights());
        let p: Vec<f32> = (0..64).map(|i| (i as f32 * 0.1).sin()).collect();
        let (wi, wo) = directions(16);
        // An aligned copy, as `ModelBuf` places the per-query network.
        let mut aligned = vec![0.0f32; w.len() + 16];
        let shift = aligned.as_ptr().align_offset(64);
        aligned[shift..shift + w.len()].copy_from_slice(&w);
        let a = &aligned[shift..shift + w.len()];
        let queries: Vec<Vec<(usize, bool)>> = (0..16).map(|i| single_query_rows(&h, &w, &p, wi[i], wo[i])).collect();
        let kb = queries.iter().map(|q| q.iter().map(|r| if r.1 { 512 } else { 64 }).sum::<usize>()).sum::<usize>() / 16 / 1024;
        let mut g = c.benchmark_group("eval-floor");
        g.throughput(Throughput::Elements(1));
        g.bench_function(BenchmarkId::new("l2-rows", format!("single-mlp-{kb}KB")), |b| {
            let mut i = 0;
            // SAFETY: AVX-512F was detected; the rows come from the network's own layout.
            b.iter(|| {
                i = (i + 1) & 15;
                black_box(unsafe { stream_rows(a, &queries[i]) })
            })
        });
        g.finish();
    }
}

criterion_group! {
    name = all_cores;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench_all_cores
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(Clock::new()).sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = bench_models, bench_nbrdf_json, bench_l2_floor
}
criterion_main!(benches, all_cores);
