//! `trainer bench-step`: milliseconds per training step (forward, backward and Adam) of each
//! architecture at batch 32768, and with `--torch` the same step in PyTorch side by side on the same machine and
//! thread count (docs/speed.md has the method and the figures).
//!
//! The PyTorch twin is `benches/torch_reference.py`. It does not transcribe our layer sizes: this
//! command writes every architecture's networks ([`ArchSpec`]) to a JSON file the script reads, so the
//! two sides cannot diverge. The script runs as one long-lived process answering one architecture at a
//! time, and each architecture is timed ours-then-PyTorch, so a load change on a shared machine hits
//! both sides of a ratio alike.
//!
//! The parametric models' formulas cannot travel in a spec, so the script transcribes them into torch
//! ops (the real `from_raw` activations and `eval`, as a PyTorch user would write them). To keep that
//! transcription from drifting, each parametric [`ArchSpec`] carries [`CheckSample`]s evaluated by the
//! core, and the script refuses to time a model whose transcription disagrees with them
//! (`python3 benches/torch_reference.py SPEC --check` runs that check alone).

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Instant;

use candle_core::Device;

use nbrdf::parametric::{Parametric, ParametricKind};
use nbrdf::Vec3;

use crate::engine::adam::{Adam, AdamParams};
use super::bench_host::{self, Host, ProductTiming};
use crate::models::{arch::layers, parametric::initial_object, Config, Inputs, Kind, Model, PositionEncoding, RawBatch};
use crate::engine::{batch_loss, Batch};
use crate::train::TrainOptions;
use crate::{toy, Error, Result};

/// Timing of one architecture.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepTiming {
    pub model: String,
    pub n_weights: usize,
    pub batch: usize,
    /// Forward + backward + Adam: the median over rounds of a round's mean step time.
    pub ms_per_step: f64,
    /// The fastest round's.
    pub ms_min: f64,
    /// Building the batch's network inputs on the CPU (angle map, encodings), not in `ms_per_step`.
    pub ms_inputs: f64,
    /// The flops of the step's dense products ([`product_flops`]) over the median step time.
    pub gflops: f64,
    /// PyTorch's median and fastest round for the same step (`--torch`), and the ratio of the medians.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torch_ms_per_step: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torch_ms_min: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
}

/// The goal: our step at most this fraction of PyTorch's, on the same host and thread count.
pub const TARGET_RATIO: f64 = 0.5;

/// The flops of a step's dense products for `config` at `batch` rows: per layer of `k` inputs and `m`
/// outputs, `2·batch·k·m` forward and as many for the weight gradient, and the gradient of the
/// layer's input where it has one to pass on (every layer but the first of a network on the batch's
/// inputs); `2` per multiply-add, as GFLOP/s figures count.
pub fn product_flops(config: &Config, batch: usize) -> f64 {
    let mut total = 0.0;
    for (i, net) in config.nets().iter().enumerate() {
        for (l, (k, m)) in layers(net).into_iter().enumerate() {
            // A head on a trunk passes its input's trunk part on at layer 0 too.
            let trunk = config.nets()[0];
            let passed = if l > 0 { k } else if i > 0 && trunk.n_out == 0 { (trunk.width as usize).min(k) } else { 0 };
            total += 2.0 * batch as f64 * (2 * k * m + passed * m) as f64;
        }
    }
    total
}

/// The median of `v` (the mean of the middle two for an even count).
fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// How long the side that just ran is left to go idle before the other is timed: OpenMP's worker
/// threads spin after a parallel region (the child runs with `OMP_WAIT_POLICY=PASSIVE`, but a build
/// may ignore it) and rayon's briefly.
const SETTLE: std::time::Duration = std::time::Duration::from_millis(300);

/// Times one configuration: one warm-up step, then `rounds` rounds of `steps` steps, each round
/// followed by the same round of PyTorch's step when `torch` is given, each side idle while the
/// other is timed. A side's figure is the median of its rounds' mean step times, with the fastest
/// beside it: on a host with other work the minimum is the least disturbed estimate, the median what
/// a user sees; alternating rounds exposes both sides to the same load.
fn time_config(config: &Config, batch: usize, steps: usize, rounds: usize, mut torch: Option<&mut Torch>) -> Result<StepTiming> {
    crate::train::keep_freed_memory();
    let device = Device::Cpu;
    let obs = toy::observations(batch, config.position, 7);
    let model = Model::init(*config, 0, &device)?;
    let t0 = Instant::now();
    let inputs = Inputs::build(config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &device)?;
    let ms_inputs = t0.elapsed().as_secs_f64() * 1e3;
    let incident: Vec<f32> = obs.wi.iter().flat_map(|w| [w.z; 3]).collect();
    let target: Vec<f32> = obs.radiance.iter().flatten().map(|&v| crate::engine::loss::gamma(v)).collect();
    let b = Batch {
        inputs,
        incident: candle_core::Tensor::from_vec(incident, (batch, 3), &device)?,
        target: candle_core::Tensor::from_vec(target, (batch, 3), &device)?,
    };
    let opts = TrainOptions::default();
    let vars = model.vars();
    let mut adam = Adam::new(&vars, AdamParams::default());
    let mut step = || -> Result<()> {
        let loss = batch_loss(&model, &b, opts.regularisers())?;
        let g = Adam::gradients(&vars, &loss.backward()?)?;
        adam.step(&vars, &g, 1e-4)?;
        Ok(())
    };
    step()?;
    let name = config.name();
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for _ in 0..rounds.max(1) {
        let t = Instant::now();
        for _ in 0..steps {
            step()?;
        }
        ours.push(t.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64);
        if let Some(py) = torch.as_deref_mut() {
            std::thread::sleep(SETTLE);
            match py.time(&name) {
                Ok(ms) => theirs.push(ms),
                Err(e) => {
                    eprintln!("PyTorch failed on {name}: {e}");
                    torch = None;
                }
            }
            std::thread::sleep(SETTLE);
        }
    }
    let ms = median(&ours);
    let torch_ms = (!theirs.is_empty()).then(|| median(&theirs));
    Ok(StepTiming {
        model: name,
        n_weights: config.n_weights(),
        batch,
        ms_per_step: ms,
        ms_min: ours.iter().copied().fold(f64::INFINITY, f64::min),
        ms_inputs,
        gflops: product_flops(config, batch) / (ms * 1e6),
        torch_ms_per_step: torch_ms,
        torch_ms_min: (!theirs.is_empty()).then(|| theirs.iter().copied().fold(f64::INFINITY, f64::min)),
        ratio: torch_ms.map(|t| ms / t),
    })
}

/// Everything a run measured: the host, the products alone, each architecture's step, and the
/// PyTorch build it was compared with.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchReport {
    pub host: Host,
    pub products: Vec<ProductTiming>,
    pub steps: Vec<StepTiming>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torch: Option<TorchBuild>,
    /// The 1-minute load average when the run ended.
    pub load_after: Option<f64>,
}

/// The PyTorch a run compared with.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TorchBuild {
    pub version: String,
    pub threads: usize,
}

/// The host, then the products and `steps` steps (after one warm-up step) of each configuration,
/// `rounds` rounds; with `torch` (the twin script) PyTorch's step in alternating rounds. Without
/// python3 or torch it says how to install it and times ours alone.
/// Most timed steps per round, and most rounds.
pub const MAX_REPEATS: usize = 100_000;

pub fn run(configs: &[Config], batch: usize, steps: usize, rounds: usize, torch: Option<&Path>) -> Result<BenchReport> {
    // Sizes checked before any allocation, naming the flag and what is allowed.
    if batch == 0 || batch > super::fit::MAX_BATCH {
        return Err(crate::Error::Invalid(format!("--batch {batch}: allowed 1..={} pixels", super::fit::MAX_BATCH)));
    }
    for (flag, v) in [("--steps", steps), ("--rounds", rounds)] {
        if v == 0 || v > MAX_REPEATS {
            return Err(crate::Error::Invalid(format!("{flag} {v}: allowed 1..={MAX_REPEATS}")));
        }
    }
    let host = Host::measure();
    if let Some(w) = host.busy() {
        eprintln!("warning: {w}");
    }
    let products = bench_host::products(batch, rounds.max(3), host.fma_peak_gflops);
    let mut twin = match torch {
        Some(script) => start_torch(configs, batch, steps, script)?,
        None => None,
    };
    let timings = configs.iter().map(|c| time_config(c, batch, steps, rounds, twin.as_mut())).collect::<Result<Vec<_>>>()?;
    let torch = twin.as_ref().map(|t| t.build.clone());
    drop(twin);
    Ok(BenchReport { host, products, steps: timings, torch, load_after: bench_host::load_average() })
}

/// The architectures timed by default: every distinct network layout of Tab. 1.
pub fn default_configs(position: PositionEncoding) -> Vec<Config> {
    crate::models::arch::study_variants(position, crate::models::Reciprocity::Exact)
}

/// One network for the PyTorch twin: the layers `(in, out)` in file order, ReLU after the first
/// `hidden`, layer `skip` (if ≥ 1) fed `[h, x]`, and what its input `x` is.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NetSpec {
    pub layers: Vec<(usize, usize)>,
    pub hidden: usize,
    pub skip: usize,
    /// The input, concatenated from these parts: `"position"`, `"angles"`, `"joint"` (a batch input of
    /// the named width) or `"net0"` (the output of the model's first network, the trunk).
    pub input: Vec<String>,
}

/// One architecture for the PyTorch twin: its networks and how their outputs become the BRDF.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ArchSpec {
    pub model: String,
    pub nets: Vec<NetSpec>,
    /// `"softplus"` (single MLP), `"additive"`, `"additive-enhanced"` (Eq. 8 with the Sec. 4.4
    /// regularisers) or `"parametric"` (the network's raw outputs through the model's formula).
    pub head: String,
    /// Widths of the batch inputs: `position`, `angles`, `joint`.
    pub widths: std::collections::BTreeMap<String, usize>,
    /// Parametric models only: which formula ([`ParametricKind::id`]), the initial per-object raw
    /// parameters ([`initial_object`]) and the core's values the script's transcription must reproduce.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parametric: Option<&'static str>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub object: Vec<f32>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub checks: Vec<CheckSample>,
}

/// One point where the script's transcription of a parametric model must match the core:
/// `f = Parametric::from_raw(kind, raw, object).eval(wi, wo)`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CheckSample {
    pub raw: Vec<f32>,
    pub object: Vec<f32>,
    pub wi: [f32; 3],
    pub wo: [f32; 3],
    pub f: [f32; 3],
}

/// Check samples per parametric architecture.
pub const N_CHECKS: usize = 16;

/// The core's values of `kind` at [`N_CHECKS`] fixed points. The directions cover the special cases of
/// the formulas (θh = 0 at and off the normal, grazing light and view down to cos θ = 1e-3, a pair below
/// the horizon) and then spread over the hemisphere; the raw values spread over -3..3, where training
/// lives, except two samples that saturate every activation: all -16 at a mirror pair, where the roughness
/// floor (`ALPHA_MIN`) sets the peak of the lobe, and all +12.
pub fn check_samples(config: &Config, kind: ParametricKind) -> Vec<CheckSample> {
    // A low-discrepancy sequence instead of an rng: the samples are the same in every build.
    let frac = |k: usize, g: f64| ((k as f64 + 1.0) * g).fract() as f32;
    let dir = |z: f32, phi: f32| {
        let s = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    // Negated tangent components: exactly θh = 0 in f32, whatever rounding `dir` did.
    let mirror = |w: Vec3| Vec3::new(-w.x, -w.y, w.z);
    let mut pairs = vec![
        (Vec3::Z, Vec3::Z),
        (dir(0.8, 0.4), mirror(dir(0.8, 0.4))),
        (dir(1e-3, 0.3), dir(0.7, 2.0)),
        (dir(0.6, 1.0), dir(1e-3, 4.0)),
        (dir(0.01, 0.5), dir(0.02, 3.9)),
        (dir(0.05, 1.2), mirror(dir(0.05, 1.2))),
        (dir(0.5, 0.0), dir(-0.3, 1.0)),
    ];
    let tau = std::f32::consts::TAU;
    while pairs.len() < N_CHECKS - 2 {
        let k = pairs.len();
        pairs.push((
            dir(0.05 + 0.95 * frac(k, 0.754_877_7), tau * frac(k, 0.569_840_3)),
            dir(0.05 + 0.95 * frac(k, 0.430_159_7), tau * frac(k, 0.245_122_3)),
        ));
    }
    // The two saturated samples below.
    pairs.push((dir(0.8, 2.5), mirror(dir(0.8, 2.5))));
    pairs.push((dir(0.4, 0.7), dir(0.9, 3.0)));
    let object0 = initial_object(config);
    pairs
        .into_iter()
        .enumerate()
        .map(|(s, (wi, wo))| {
            let raw: Vec<f32> = match s {
                s if s == N_CHECKS - 2 => vec![-16.0; kind.n_raw()],
                s if s == N_CHECKS - 1 => vec![12.0; kind.n_raw()],
                _ => (0..kind.n_raw()).map(|j| -3.0 + 6.0 * frac(s * kind.n_raw() + j, 0.618_034)).collect(),
            };
            // Training moves the object parameter off its initial value: ±2 (a factor e² on FMBRDF's N).
            let object: Vec<f32> =
                object0.iter().enumerate().map(|(j, &o)| o - 2.0 + 4.0 * frac(s + j, 0.414_213_6)).collect();
            let f = Parametric::from_raw(kind, &raw, &object).eval(wi, wo);
            CheckSample { raw, object, wi: wi.to_array(), wo: wo.to_array(), f }
        })
        .collect()
}

/// Everything the PyTorch twin needs: the batch, the threads and the architectures.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchSpec {
    pub batch: usize,
    pub steps: usize,
    pub threads: usize,
    /// Adam's learning rate and the regulariser weights of [`TrainOptions::default`].
    pub lr: f32,
    pub lambda_diffuse: f32,
    pub lambda_specular: f32,
    pub archs: Vec<ArchSpec>,
}

/// The networks of `config` as [`Model::forward`] wires them.
pub fn arch_spec(config: &Config) -> ArchSpec {
    let nets = config.nets();
    let inputs: Vec<&[&str]> = match config.kind {
        Kind::Parametric(_) => vec![&["position"]],
        Kind::SingleMlp if nets.len() == 1 => vec![&["joint"]],
        Kind::SingleMlp => vec![&["position"], &["net0", "angles"]],
        Kind::AdditiveSeparate => vec![&["position"], &["joint"]],
        Kind::AdditiveShared => vec![&["position"], &["net0"], &["net0", "angles"]],
    };
    let head = match config.kind {
        Kind::Parametric(_) => "parametric",
        Kind::SingleMlp => "softplus",
        _ if config.has_xi() => "additive-enhanced",
        _ => "additive",
    };
    let (p, a) = (config.position.encoded_len(), config.n_angle_features());
    let kind = match config.kind {
        Kind::Parametric(k) => Some(k),
        _ => None,
    };
    ArchSpec {
        model: config.name(),
        nets: nets
            .iter()
            .zip(inputs)
            .map(|(d, input)| NetSpec {
                layers: layers(d),
                hidden: d.hidden as usize,
                skip: d.skip as usize,
                input: input.iter().map(|s| s.to_string()).collect(),
            })
            .collect(),
        head: head.into(),
        widths: [("position", p), ("angles", a), ("joint", p + a)].into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
        parametric: kind.map(ParametricKind::id),
        object: if kind.is_some() { initial_object(config) } else { Vec::new() },
        checks: kind.map(|k| check_samples(config, k)).unwrap_or_default(),
    }
}

/// The spec of `configs` at this batch and candle's thread count.
pub fn bench_spec(configs: &[Config], batch: usize, steps: usize) -> BenchSpec {
    let o = TrainOptions::default();
    BenchSpec {
        batch,
        steps,
        threads: candle_core::utils::get_num_threads(),
        lr: 1e-4,
        lambda_diffuse: o.lambda_diffuse,
        lambda_specular: o.lambda_specular,
        archs: configs.iter().map(arch_spec).collect(),
    }
}

/// The running PyTorch twin (`torch_reference.py --serve`).
struct Torch {
    build: TorchBuild,
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Torch {
    /// Starts `python3 script spec --serve` and waits for its ready line; `Err` with the reason when
    /// python3 or torch is missing.
    fn start(script: &Path, spec: &Path) -> std::result::Result<Torch, String> {
        let mut child = Command::new("python3")
            .arg(script)
            .arg(spec)
            .arg("--serve")
            // Idle threads sleep instead of spinning into our rounds.
            .env("OMP_WAIT_POLICY", "PASSIVE")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot run python3 ({e})"))?;
        let stdin = child.stdin.take().ok_or("no stdin")?;
        let mut stdout = BufReader::new(child.stdout.take().ok_or("no stdout")?);
        let mut line = String::new();
        stdout.read_line(&mut line).map_err(|e| e.to_string())?;
        if line.trim().is_empty() {
            let _ = child.wait();
            return Err(format!("{} exited without answering (its error is above)", script.display()));
        }
        let v: serde_json::Value = serde_json::from_str(&line).map_err(|_| format!("unexpected reply {line:?}"))?;
        if let Some(e) = v.get("error") {
            let _ = child.wait();
            return Err(e.as_str().unwrap_or("error").to_string());
        }
        let build = TorchBuild { version: v["torch"].as_str().unwrap_or("?").to_string(), threads: v["threads"].as_u64().unwrap_or(0) as usize };
        Ok(Torch { build, child, stdin, stdout })
    }

    /// PyTorch's ms per step of the architecture `model` of the spec.
    fn time(&mut self, model: &str) -> std::result::Result<f64, String> {
        writeln!(self.stdin, "{model}").and_then(|_| self.stdin.flush()).map_err(|e| e.to_string())?;
        let mut line = String::new();
        self.stdout.read_line(&mut line).map_err(|e| e.to_string())?;
        let v: serde_json::Value = serde_json::from_str(&line).map_err(|_| format!("unexpected reply {line:?}"))?;
        if let Some(e) = v.get("error") {
            return Err(e.as_str().unwrap_or("error").to_string());
        }
        v["ms_per_step"].as_f64().ok_or_else(|| format!("no timing in {line:?}"))
    }
}

impl Drop for Torch {
    fn drop(&mut self) {
        // End of input ends the script's loop.
        let _ = writeln!(self.stdin);
        let _ = self.child.wait();
    }
}

/// The PyTorch twin serving `configs`, or `None` (said on stderr) where python3 or torch is missing.
fn start_torch(configs: &[Config], batch: usize, steps: usize, script: &Path) -> Result<Option<Torch>> {
    let spec = bench_spec(configs, batch, steps);
    let spec_path = std::env::temp_dir().join(format!("nbrdf-bench-spec-{}.json", std::process::id()));
    let json = serde_json::to_vec_pretty(&spec).map_err(|e| Error::io(&spec_path, e))?;
    std::fs::write(&spec_path, json).map_err(|e| Error::io(&spec_path, e))?;
    // Kept after the run, so that `python3 benches/torch_reference.py SPEC` can time PyTorch alone.
    eprintln!("architectures for the PyTorch twin: {}", spec_path.display());
    Ok(match Torch::start(script, &spec_path) {
        Ok(t) => Some(t),
        Err(e) => {
            eprintln!("PyTorch reference unavailable: {e}\n  install it with `pip install torch`; timing ours only");
            None
        }
    })
}

/// Prints a [`BenchReport`]: the host, the products, the steps.
pub fn print_report(r: &BenchReport) {
    let h = &r.host;
    println!("host: {} · kernel level {} · {} threads · FMA peak {:.0} GFLOP/s (measured) · load average {}", h.cpu, h.level, h.threads, h.fma_peak_gflops, h.load_before.map_or("?".into(), |l| format!("{l:.2}")));
    if let Some(t) = &r.torch {
        println!("PyTorch {} on {} threads, rounds alternating (one side idle while the other runs)", t.version, t.threads);
    }
    println!("\n{:<34} {:>27} {:>9} {:>9} {:>7}", "product (hidden layers)", "layers × rows × inner × cols", "ms", "GFLOP/s", "peak");
    for p in &r.products {
        let shape = format!("{} × {} × {} × {}", p.layers, p.shape[0], p.shape[1], p.shape[2]);
        println!("{:<34} {:>27} {:>9.2} {:>9.0} {:>6.0}%", p.product, shape, p.ms, p.gflops, 100.0 * p.peak_share);
    }
    let torch = r.steps.iter().any(|t| t.torch_ms_per_step.is_some());
    print!("\n{:<34} {:>10} {:>7} {:>9} {:>9} {:>9} {:>7} {:>9}", "model", "parameters", "batch", "ms/step", "ms min", "GFLOP/s", "peak", "ms inputs");
    if torch {
        print!(" {:>9} {:>9} {:>7} {:>7}", "torch ms", "torch min", "ratio", "goal");
    }
    println!();
    for t in &r.steps {
        let share = 100.0 * t.gflops / h.fma_peak_gflops;
        print!("{:<34} {:>10} {:>7} {:>9.1} {:>9.1} {:>9.0} {:>6.0}% {:>9.1}", t.model, t.n_weights, t.batch, t.ms_per_step, t.ms_min, t.gflops, share, t.ms_inputs);
        if let (Some(ms), Some(min), Some(ratio)) = (t.torch_ms_per_step, t.torch_ms_min, t.ratio) {
            let mark = if ratio <= TARGET_RATIO { "met" } else { "missed" };
            print!(" {ms:>9.1} {min:>9.1} {ratio:>7.2} {TARGET_RATIO:>4} {mark}");
        }
        println!();
    }
    println!("\nms/step: median over rounds (ms min: the fastest); torch likewise; ratio: of the medians.");
    if let (Some(a), Some(b)) = (h.load_before, r.load_after) {
        if a.max(b) > 0.5 {
            println!("load average {a:.2} before, {b:.2} after: other work shared the host; time again on a quiet one.");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::Reciprocity;

    /// The PyTorch twin's transcription of every parametric model reproduces the core's values
    /// (`torch_reference.py SPEC --check`), and a value it does not reproduce fails the check, named.
    /// One script run, since importing torch dominates the time; skipped without python3 or torch.
    #[test]
    fn torch_transcription_matches_the_core() {
        let configs: Vec<Config> = ParametricKind::ALL
            .into_iter()
            .map(|k| Config::paper(Kind::Parametric(k), false, Reciprocity::None, PositionEncoding::Uniform))
            .collect();
        let mut spec = bench_spec(&configs, 1024, 1);
        let mut drifted = spec.archs.iter().find(|a| a.parametric == Some("disney")).unwrap().clone();
        drifted.model = "drifted".into();
        drifted.checks[3].f[1] *= 1.001;
        spec.archs.push(drifted);

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("spec.json");
        std::fs::write(&path, serde_json::to_vec(&spec).unwrap()).unwrap();
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benches/torch_reference.py");
        let Ok(out) = Command::new("python3").arg(&script).arg(&path).arg("--check").output() else {
            eprintln!("skipped: needs python3 with torch (`pip install torch`)");
            return;
        };
        let text = String::from_utf8_lossy(&out.stdout);
        if text.contains("cannot import torch") {
            eprintln!("skipped: {}", text.trim());
            return;
        }
        let v: serde_json::Value = serde_json::from_str(text.trim())
            .unwrap_or_else(|_| panic!("{text}{}", String::from_utf8_lossy(&out.stderr)));
        for a in &spec.archs[..configs.len()] {
            assert!(v["checked"][&a.model].is_number(), "{} not checked: {text}", a.model);
        }
        let errors = v["errors"].as_array().unwrap_or_else(|| panic!("the drifted value passed: {text}"));
        assert_eq!(errors.len(), 1, "{text}");
        assert!(errors[0].as_str().unwrap().starts_with("drifted: ") && text.contains("sample 3 of"), "{text}");
        assert!(!out.status.success());
    }
}
