//! How well the samplers of measured materials follow them: for every NBRDF-json fit of a MERL material
//! in `$NBRDF_DATA/nbrdf-merl` (default `../shared/data`), the variance of the one-sample albedo
//! estimate `f cos θi / pdf` at five view angles, at **equal time** (variance × seconds per sample,
//! sampling and evaluation counted), for three samplers: cosine-weighted, the single fitted proxy
//! (`fit_proxy`, what model files carried before the view table) and the view-conditioned proxy
//! (`fit_view_proxy`). The table is of the luminance estimate (what the samplers are fitted to); the
//! summary also gives the green channel alone. Prints one row per material and view, then the medians
//! and worst cases that docs/speed.md reports. Each view's three samplers are timed at that view,
//! taking turns in blocks of samples so that the host's drift is charged to all three alike.
//!
//! With `--models DIR` it measures the purely neural `.nbrdf` files under `DIR` instead (a study's
//! `jobs/` folder): each file's own proxy against the table fitted as the trainer now exports it.
//!
//! Run: `cargo run --release --example sampler_variance [-- SAMPLES [FILTER] [--models DIR]]` (default
//! 65536 samples per cell); single-threaded, so run it on a quiet host.

use std::time::Instant;

use std::path::{Path, PathBuf};

use nbrdf::file::ModelKind;
use nbrdf::measured::NbrdfNetwork;
use nbrdf::sampling::{fit_view_proxy_around, Proxy, ViewProxy};
use nbrdf::{BsdfSample, ModelBuf, Rgb, Vec3};

const VIEWS: [f32; 5] = [0.1, 0.5, 0.9, 1.2, 1.4];

/// PCG32 (O'Neill 2014): a reproducible stream of uniforms in [0, 1).
struct Pcg(u64);

impl Pcg {
    fn next(&mut self) -> f32 {
        let old = self.0;
        self.0 = old.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let x = (((old >> 18) ^ old) >> 27) as u32;
        let r = x.rotate_right((old >> 59) as u32);
        (r >> 8) as f32 / (1u32 << 24) as f32
    }
}

/// One sampler's running sums over its samples: luminance and green weights, and the time spent.
struct Estimate {
    rng: Pcg,
    n: usize,
    sum: [f64; 4],
    secs: f64,
}

impl Estimate {
    fn new(seed: u64) -> Self {
        Estimate { rng: Pcg(seed.wrapping_mul(0x9e3779b97f4a7c15) | 1), n: 0, sum: [0.0; 4], secs: 0.0 }
    }

    /// Draws `k` more samples, timing them as one block.
    fn block(&mut self, k: usize, mut sample: impl FnMut([f32; 3]) -> Option<BsdfSample>) {
        let mut s = self.sum;
        let start = Instant::now();
        for _ in 0..k {
            let u = [self.rng.next(), self.rng.next(), self.rng.next()];
            let w = sample(u).map_or([0.0; 3], |s| s.weight);
            let y = 0.2126 * w[0] as f64 + 0.7152 * w[1] as f64 + 0.0722 * w[2] as f64;
            let g = w[1] as f64;
            s = [s[0] + y, s[1] + y * y, s[2] + g, s[3] + g * g];
        }
        self.secs += start.elapsed().as_secs_f64();
        (self.sum, self.n) = (s, self.n + k);
    }

    fn mean(&self) -> f64 {
        self.sum[0] / self.n as f64
    }

    /// Variance of the luminance weight × seconds per sample.
    fn var_time(&self) -> f64 {
        self.variance(0) * self.secs_per_sample()
    }

    /// Variance of the green weight × seconds per sample.
    fn green_var_time(&self) -> f64 {
        self.variance(2) * self.secs_per_sample()
    }

    fn variance(&self, i: usize) -> f64 {
        let n = self.n as f64;
        (self.sum[i + 1] / n - (self.sum[i] / n).powi(2)).max(0.0)
    }

    fn secs_per_sample(&self) -> f64 {
        self.secs / self.n as f64
    }
}

/// Samples per timed block: the three samplers take turns block by block, so a change in the host's
/// speed during a view is charged to all three alike.
const BLOCK: usize = 1024;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The ratios of every cell, for the summary.
#[derive(Default)]
struct Summary {
    vs_proxy: Vec<f64>,
    vs_cos: Vec<f64>,
    green_vs_proxy: Vec<f64>,
    green_vs_cos: Vec<f64>,
    own_vs_proxy: Vec<f64>,
    kept_vs_proxy: Vec<f64>,
    fit_ms: Vec<f64>,
}

/// The rows of one BRDF: each view's variance × time for the three samplers, timed at that view.
fn measure(sum: &mut Summary, name: &str, m: usize, n: usize, eval: &dyn Fn(Vec3, Vec3) -> Rgb, proxy: Proxy, view: &ViewProxy) {
    // A view where every sampler's variance is 0 (a black material) compares as equal.
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 1.0 };
    for (v, &theta) in VIEWS.iter().enumerate() {
        let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
        // The same seed gives the three samplers the same uniforms.
        let seed = (m * 16 + v) as u64;
        let [mut c, mut p, mut w] = [Estimate::new(seed), Estimate::new(seed), Estimate::new(seed)];
        for done in (0..n).step_by(BLOCK) {
            let k = BLOCK.min(n - done);
            c.block(k, |u| Proxy::COSINE.sample(wo, u, eval));
            p.block(k, |u| proxy.sample(wo, u, eval));
            w.block(k, |u| view.sample(wo, u, eval));
        }
        let (vc, vp, vv) = (c.var_time(), p.var_time(), w.var_time());
        if std::env::var_os("VERBOSE").is_some() {
            let ns = |e: &Estimate| e.secs_per_sample() * 1e9;
            eprintln!("{name} {theta}: var·t {vc:.3e} {vp:.3e} {vv:.3e}, ns {:.0} {:.0} {:.0}", ns(&c), ns(&p), ns(&w));
        }
        sum.vs_proxy.push(ratio(vv, vp));
        sum.vs_cos.push(ratio(vv, vc));
        sum.green_vs_proxy.push(ratio(w.green_var_time(), p.green_var_time()));
        sum.green_vs_cos.push(ratio(w.green_var_time(), c.green_var_time()));
        // Whether the view's cell kept the all-view proxy (then only the cell lookup differs).
        let own = view.at(wo).is_some_and(|cell| *cell != proxy);
        if own {
            sum.own_vs_proxy.push(ratio(vv, vp));
        } else {
            sum.kept_vs_proxy.push(ratio(vv, vp));
        }
        println!(
            "| {name} | {theta} | {} | {:.4} | {vc:.3e} | {vp:.3e} | {vv:.3e} | {:.3} | {:.3} |",
            if own { "own" } else { "kept" },
            c.mean(),
            ratio(vv, vp),
            ratio(vv, vc)
        );
    }
}

/// The `.nbrdf` files under `dir` (f32 copies), recursively, in no particular order.
fn model_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for p in entries.flatten().map(|e| e.path()) {
        if p.is_dir() {
            model_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "nbrdf") && !p.to_string_lossy().ends_with(".f16.nbrdf") {
            out.push(p);
        }
    }
}

/// A loaded BRDF, or `None` after saying on stderr why `path` is skipped.
fn loaded<T>(path: &Path, result: Result<T, nbrdf::Error>) -> Option<T> {
    result.map_err(|e| eprintln!("{}: {e}", path.display())).ok()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1 << 16);
    let filter = args.get(2).filter(|a| !a.starts_with("--")).cloned().unwrap_or_default();
    let models = args.iter().position(|a| a == "--models").and_then(|i| args.get(i + 1)).map(PathBuf::from);
    println!("kernel level {:?}, {n} samples per cell", nbrdf::kernels::level());
    println!("| BRDF | θo | cell | albedo (lum.) | var·t cosine | var·t proxy | var·t view | view / proxy | view / cosine |");
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|");
    let mut sum = Summary::default();
    if let Some(dir) = models {
        // Fitted models: the file's own proxy, and the table fitted as the trainer now exports it (over
        // eight rows of the position table); sampled at the first of those points.
        let mut files = Vec::new();
        model_files(&dir, &mut files);
        files.sort();
        files.retain(|p| p.to_string_lossy().contains(&filter));
        for (m, path) in files.iter().enumerate() {
            let Some(buf) = loaded(path, ModelBuf::load(path)) else { continue };
            let model = buf.model();
            let (Some(proxy), ModelKind::SingleMlp | ModelKind::AdditiveSeparate | ModelKind::AdditiveShared) =
                (model.header().proxy, model.header().kind)
            else {
                continue;
            };
            let k = model.position_len();
            let table = model.position_table();
            let rows = table.len().checked_div(k).unwrap_or(0);
            let points: Vec<_> = if rows == 0 {
                model.prepare(&[]).ok().into_iter().collect()
            } else {
                (0..8).filter_map(|i| model.prepare(&table[(i * rows / 8) * k..][..k]).ok()).collect()
            };
            let Some(&at) = points.first() else {
                eprintln!("{}: no surface point to sample at", path.display());
                continue;
            };
            let start = Instant::now();
            let view = model.fit_view_proxy(&points, &proxy);
            sum.fit_ms.push(start.elapsed().as_secs_f64() * 1e3);
            let eval = |wi, wo| model.eval(&at, wi, wo);
            let name = path.strip_prefix(&dir).unwrap_or(path).with_extension("").to_string_lossy().into_owned();
            measure(&mut sum, &name, m, n, &eval, proxy, &view);
        }
    } else {
        let root = std::env::var("NBRDF_DATA").unwrap_or_else(|_| "../shared/data".into());
        let dir = Path::new(&root).join("nbrdf-merl");
        let Ok(entries) = std::fs::read_dir(&dir) else {
            eprintln!("skipped: no {} (set NBRDF_DATA to the shared data folder)", dir.display());
            return;
        };
        let mut files: Vec<_> = entries.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "json")).collect();
        files.sort();
        files.retain(|p| p.to_string_lossy().contains(&filter));
        for (m, path) in files.iter().enumerate() {
            let Some(net) = loaded(path, NbrdfNetwork::load(path)) else { continue };
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            let eval = |wi, wo| net.eval(wi, wo);
            let start = Instant::now();
            // The table as the network's load fits it, around the proxy it already has.
            let view: ViewProxy = fit_view_proxy_around(eval, net.proxy());
            sum.fit_ms.push(start.elapsed().as_secs_f64() * 1e3);
            measure(&mut sum, &name, m, n, &eval, *net.proxy(), &view);
        }
    }
    if sum.vs_proxy.is_empty() {
        return;
    }
    let worst = |v: &[f64]| v.iter().copied().fold(0.0f64, f64::max);
    println!();
    println!("cells: {} ({} BRDFs × {} views)", sum.vs_proxy.len(), sum.vs_proxy.len() / VIEWS.len(), VIEWS.len());
    println!("view / proxy at equal time: median {:.3}, worst {:.3}", median(&mut sum.vs_proxy.clone()), worst(&sum.vs_proxy));
    println!(
        "cells with their own mixture: {} (view / proxy median {:.3}, worst {:.3}); the rest keep the proxy",
        sum.own_vs_proxy.len(),
        median(&mut sum.own_vs_proxy.clone()),
        worst(&sum.own_vs_proxy)
    );
    if !sum.kept_vs_proxy.is_empty() {
        println!(
            "cells that kept the proxy (same draws, view / proxy is the lookup's time): median {:.3}, worst {:.3}",
            median(&mut sum.kept_vs_proxy.clone()),
            worst(&sum.kept_vs_proxy)
        );
    }
    println!(
        "view / cosine at equal time: median {:.3}, worst {:.3}, cells over 2: {}",
        median(&mut sum.vs_cos.clone()),
        worst(&sum.vs_cos),
        sum.vs_cos.iter().filter(|&&r| r > 2.0).count()
    );
    println!(
        "green channel alone: view / proxy median {:.3}, worst {:.3}; view / cosine worst {:.3}",
        median(&mut sum.green_vs_proxy.clone()),
        worst(&sum.green_vs_proxy),
        worst(&sum.green_vs_cos)
    );
    println!("fit_view_proxy: median {:.1} ms per BRDF", median(&mut sum.fit_ms));
}
