//! What `trainer bench-step` says about the host beside its step times: the CPU, the kernel level, the
//! load average before and after (other work swings a step time by 2× or more), the FMA peak measured
//! on every thread at once, and the throughput of the dense products of a step at the paper's shapes
//! as a share of that peak.

use std::time::Instant;

use rayon::prelude::*;

use crate::engine::dense::{self, Epilogue, Mat};

/// The host a run measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Host {
    /// The CPU's model name (`/proc/cpuinfo`), or "unknown CPU".
    pub cpu: String,
    /// The kernel level in use (`NBRDF_KERNEL` may lower it).
    pub level: &'static str,
    /// Threads of the step (rayon's pool).
    pub threads: usize,
    /// Register-only multiply-adds on every thread at once, GFLOP/s.
    pub fma_peak_gflops: f64,
    /// The 1-minute load average when the run started (Linux).
    pub load_before: Option<f64>,
}

impl Host {
    /// Reads the CPU and load, and measures the peak (a few hundred milliseconds).
    pub fn measure() -> Host {
        let load_before = load_average();
        let threads = rayon::current_num_threads();
        Host { cpu: cpu_name(), level: nbrdf::kernels::detected().name(), threads, fma_peak_gflops: peak(threads), load_before }
    }

    /// The warning to print when the load average shows other work on the host, if it does.
    pub fn busy(&self) -> Option<String> {
        let load = self.load_before?;
        (load > 0.5).then(|| {
            format!("the host's load average is {load:.2}: other work is running, and the timings below will be slower and noisier than on a quiet host")
        })
    }
}

/// The 1-minute load average, where the system says it.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

fn cpu_name() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let name = info.lines().find_map(|l| l.strip_prefix("model name").and_then(|r| r.split_once(':')).map(|(_, v)| v.trim().to_string()));
    name.unwrap_or_else(|| "unknown CPU".into())
}

/// The FMA peak of `threads` threads running at once, GFLOP/s.
fn peak(threads: usize) -> f64 {
    std::thread::scope(|s| {
        let runs: Vec<_> = (0..threads.max(1)).map(|_| s.spawn(dense::fma_peak_gflops)).collect();
        runs.into_iter().map(|r| r.join().unwrap_or(0.0)).sum()
    })
}

/// One product of a step timed alone.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProductTiming {
    /// What it is, in the step's terms.
    pub product: &'static str,
    /// `rows × inner × cols` of one layer.
    pub shape: [usize; 3],
    /// Layers timed in a row.
    pub layers: usize,
    pub ms: f64,
    pub gflops: f64,
    /// `gflops` over [`Host::fma_peak_gflops`].
    pub peak_share: f64,
}

/// Rows per task and per sweep, and hidden layers per network, as the step runs them
/// (`engine::network`, the paper's 128-wide networks).
const TASK_ROWS: usize = 1024;
const SWEEP_ROWS: usize = 256;
const DEPTH: usize = 6;

/// The three products of the paper's 128 → 128 hidden layers on `rows` rows, each timed alone the
/// way the step runs it: tasks of 1024 rows in parallel, and within a task sweeps of 256 rows through
/// [`DEPTH`] layers, each layer reading the block the one before it has just written (from L2).
/// Forward with bias and ReLU, the input gradient with the ReLU mask, and the weight gradient over a
/// sweep's activations and gradients (each task's partial sums added in task order). Best of
/// `repeats` runs.
pub fn products(rows: usize, repeats: usize, peak_gflops: f64) -> Vec<ProductTiming> {
    let w = 128;
    let fill = |n: usize, seed: u32| -> Vec<f32> { (0..n).map(|i| ((i as u32).wrapping_mul(2_654_435_761) ^ seed) as f32 / u32::MAX as f32 - 0.5).collect() };
    let (x, b, bias) = (fill(rows * w, 1), fill(w * w, 2), fill(w, 3));
    let tasks = rows.div_ceil(TASK_ROWS);
    let time = |f: &(dyn Fn() + Sync)| {
        (0..repeats.max(1))
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    // One task's sweeps: the first layer reads the batch's rows, the others the sweep's buffers.
    // SAFETY (the closures): `x` holds `rows` rows of 128 values, `b` 128 × 128, the buffers a sweep
    // of 128 values a row, each task its own.
    let layers = |mask: bool| {
        (0..tasks).into_par_iter().for_each(|t| unsafe {
            let (mut h, mut y) = (fill(SWEEP_ROWS * w, 5), vec![0.0f32; SWEEP_ROWS * w]);
            let m = fill(SWEEP_ROWS * w, 6);
            for r0 in (t * TASK_ROWS..((t + 1) * TASK_ROWS).min(rows)).step_by(SWEEP_ROWS) {
                let n = SWEEP_ROWS.min(rows - r0);
                for l in 0..DEPTH {
                    let input = if l == 0 { Mat::new(&x, w).at(r0, 0) } else { Mat::new(&h, w) };
                    let epi = if mask { Epilogue { mask: Some(Mat::new(&m, w)), ..Epilogue::STORE } } else { Epilogue { bias: Some(bias.as_ptr()), relu: true, ..Epilogue::STORE } };
                    dense::product(n, w, input, w, input, 0, Mat::new(&b, w), y.as_mut_ptr(), w, epi);
                    std::mem::swap(&mut h, &mut y);
                }
            }
            std::hint::black_box(&h);
        })
    };
    let forward = time(&|| layers(false));
    let backward = time(&|| layers(true));
    let weight = time(&|| {
        let parts: Vec<Vec<f32>> = (0..tasks)
            .into_par_iter()
            .map(|t| unsafe {
                let (a, g) = (fill(SWEEP_ROWS * w, 7), fill(SWEEP_ROWS * w, 8));
                let mut dw = vec![0.0f32; DEPTH * w * w];
                for r0 in (t * TASK_ROWS..((t + 1) * TASK_ROWS).min(rows)).step_by(SWEEP_ROWS) {
                    let n = SWEEP_ROWS.min(rows - r0);
                    for l in 0..DEPTH {
                        dense::weight_product(n, w, w, Mat::new(&a, w), Mat::new(&g, w), dw.as_mut_ptr().add(l * w * w), r0 > t * TASK_ROWS);
                    }
                }
                dw
            })
            .collect();
        let mut dw = vec![0.0f32; DEPTH * w * w];
        crate::engine::op::add_in_order(&mut dw, &parts);
        std::hint::black_box(dw);
    });
    let flops = 2.0 * (DEPTH * rows * w * w) as f64;
    [("forward x·W, bias, ReLU", forward), ("input gradient g·Wᵀ, ReLU mask", backward), ("weight gradient xᵀ·g", weight)]
        .into_iter()
        .map(|(product, ms)| {
            let gflops = flops / (ms * 1e6);
            ProductTiming { product, shape: [rows, w, w], layers: DEPTH, ms, gflops, peak_share: gflops / peak_gflops }
        })
        .collect()
}
