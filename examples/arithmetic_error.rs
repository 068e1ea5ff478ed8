//! What the faster arithmetics cost in accuracy and save in time, on a trained model: half precision
//! (f16 weights and sums), split bf16 (three or six bf16 products per f32 product on AMX tiles) and
//! bf16 (one bf16 product per f32 product on AVX512-BF16 vectors).
//!
//! ```text
//! cargo run --release --example arithmetic_error -- fitted.nbrdf
//! ```
//! The model (f32 weights, e.g. `trainer fit`'s output) is re-encoded with f16 weights
//! (`Model::to_f16`), then evaluated at 64 of its mesh's vertices (its stored intrinsic encoding; a
//! fixed point without one) for 1024 cosine-distributed direction pairs each, four ways: f32
//! weights, f16 weights in f32 arithmetic (`eval_many`), f16 weights in f16 arithmetic
//! (`eval_many_half`, `eval_half`), and f32 weights in split-bf16 arithmetic (`eval_many_in` with
//! `Arithmetic::SplitBf16` and `SplitBf16x6` after `ModelBuf::enable_bf16`) and bf16
//! (`Arithmetic::Bf16`, the same copy; single queries too, which should have their batch values'
//! bits). It prints the relative
//! differences of the colour values (RMS, 99th percentile, maximum; values below 1e-3 compared
//! absolutely) and the time per pair, best of three. Where the CPU lacks AVX512-FP16, AMX-BF16 or AVX512-BF16 those entry points are the f32
//! ones, and the program says so. As a yardstick for f32 rounding itself, the f32 model also runs on
//! the portable kernels (multiply, then add: the same sums rounded twice as often as with FMA).

use std::time::Instant;

use nbrdf::file::ModelBuf;
use nbrdf::mlp::Arithmetic;
use nbrdf::{Rgb, Vec3};

/// Relative differences `(b - a) / max(|a|, 1e-3)` of every colour value.
fn differences(a: &[Rgb], b: &[Rgb], out: &mut Vec<f64>) {
    for (a, b) in a.iter().zip(b) {
        for c in 0..3 {
            out.push(((b[c] - a[c]) / a[c].abs().max(1e-3)) as f64);
        }
    }
}

fn summary(name: &str, d: &mut [f64]) {
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    d.sort_by(|x, y| x.abs().total_cmp(&y.abs()));
    let p99 = d[d.len() * 99 / 100].abs();
    let max = d.last().map_or(0.0, |x| x.abs());
    println!("{name:<44} RMS {rms:.2e}   p99 {p99:.2e}   max {max:.2e}");
}

/// Seconds of the fastest of three runs of `f`.
fn best_of_three(mut f: impl FnMut()) -> f64 {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::MAX, f64::min)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: arithmetic_error MODEL.nbrdf (f32 weights)")?;
    let mut b32 = ModelBuf::load(&path)?;
    // The bf16 copy serves only the bf16 arithmetics; every other path reads the file's weights.
    b32.enable_bf16();
    let m32 = b32.model();
    let b16 = ModelBuf::from_bytes(&m32.to_f16()?)?;
    let m16 = b16.model();
    if !m16.half_math() {
        println!("half arithmetic does not apply here (needs AVX512-FP16 and a neural model): the half entry points are the f32 ones");
    }
    if !m32.amx() {
        println!("split-bf16 arithmetic does not apply here (needs AMX-BF16 and a neural model of width 32k): it is f32");
    }
    if !m32.bf16() {
        println!("bf16 arithmetic does not apply here (needs AVX512-BF16 and a neural model of width 32k): it is f32");
    }
    let n_vertices = m32.header().n_vertices;
    let mut seed = 0x2545f4914f6cdd1du64;
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = 1024;
    let (mut storage, mut math, mut total, mut single, mut split, mut split6, mut split1) = (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut rounding = vec![];
    let mut times = [0.0f64; 10];
    // bf16 single queries whose bits differ from their batch value (they should not: `bf16_rows`).
    let mut bf16_single_differ = 0usize;
    for v in 0..64u32 {
        let mut point = vec![0.1f32; m32.position_len()];
        if n_vertices > 0 {
            let vertex = (v * 7919) % n_vertices;
            m32.position_features([vertex; 3], [1.0, 0.0, 0.0], &mut point)?;
        }
        let (p32, p16) = (m32.prepare(&point), m16.prepare(&point));
        let mut direction = || {
            let (u, phi) = (uniform(), std::f32::consts::TAU * uniform());
            Vec3::new(u.sqrt() * phi.cos(), u.sqrt() * phi.sin(), (1.0 - u).max(1e-4).sqrt())
        };
        let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|_| (direction(), direction())).unzip();
        let (mut f32_w, mut f16_w, mut half, mut one) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let (mut tiled, mut tiled6, mut bf16) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        times[0] += best_of_three(|| m32.eval_many(&p32, &wi, &wo, &mut f32_w));
        times[1] += best_of_three(|| m16.eval_many(&p16, &wi, &wo, &mut f16_w));
        times[2] += best_of_three(|| m16.eval_many_half(&p16, &wi, &wo, &mut half));
        let mut sink = 0.0;
        times[3] += best_of_three(|| wi.iter().zip(&wo).for_each(|(a, b)| sink += m32.eval(&p32, *a, *b)[0]));
        times[4] += best_of_three(|| wi.iter().zip(&wo).for_each(|(a, b)| sink += m16.eval(&p16, *a, *b)[0]));
        times[5] += best_of_three(|| one.iter_mut().zip(wi.iter().zip(&wo)).for_each(|(o, (a, b))| *o = m16.eval_half(&p16, *a, *b)));
        times[6] += best_of_three(|| m32.eval_many_in(Arithmetic::SplitBf16, &p32, &wi, &wo, &mut tiled));
        times[7] += best_of_three(|| m32.eval_many_in(Arithmetic::SplitBf16x6, &p32, &wi, &wo, &mut tiled6));
        times[8] += best_of_three(|| m32.eval_many_in(Arithmetic::Bf16, &p32, &wi, &wo, &mut bf16));
        let mut bf16_one = vec![[0.0; 3]; n];
        times[9] += best_of_three(|| bf16_one.iter_mut().zip(wi.iter().zip(&wo)).for_each(|(o, (a, b))| *o = m32.eval_in(Arithmetic::Bf16, &p32, *a, *b)));
        bf16_single_differ += bf16_one.iter().zip(&bf16).filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits)).count();
        std::hint::black_box(sink);
        differences(&f32_w, &f16_w, &mut storage);
        differences(&f16_w, &half, &mut math);
        differences(&f32_w, &half, &mut total);
        differences(&f16_w, &one, &mut single);
        differences(&f32_w, &tiled, &mut split);
        differences(&f32_w, &tiled6, &mut split6);
        differences(&f32_w, &bf16, &mut split1);
        let mut portable = vec![[0.0; 3]; n];
        nbrdf::kernels::set_level(Some(nbrdf::kernels::Level::Portable));
        m32.eval_many(&p32, &wi, &wo, &mut portable);
        nbrdf::kernels::set_level(None);
        differences(&f32_w, &portable, &mut rounding);
    }
    println!("{} colour values at 64 points:", storage.len());
    summary("f16 weights against f32 weights", &mut storage);
    summary("half arithmetic against f16 weights (batch)", &mut math);
    summary("half arithmetic against f32 weights (batch)", &mut total);
    summary("half arithmetic against f16 weights (single)", &mut single);
    summary("split bf16 (bf16x3) against f32 (batch)", &mut split);
    summary("split bf16 (bf16x6) against f32 (batch)", &mut split6);
    summary("bf16 against f32 (batch)", &mut split1);
    summary("f32 without FMA against f32 (batch)", &mut rounding);
    let per = |t: f64| t / (64 * n) as f64 * 1e6;
    println!("µs per pair, batches of {n}: f32 {:.3}, f16 {:.3}, f16 half arithmetic {:.3} ({:.2}x f32)", per(times[0]), per(times[1]), per(times[2]), times[2] / times[0]);
    println!(
        "µs per pair, batches of {n}: bf16x3 {:.3} ({:.2}x f32), bf16x6 {:.3} ({:.2}x f32), bf16 {:.3} ({:.2}x f32)",
        per(times[6]),
        times[6] / times[0],
        per(times[7]),
        times[7] / times[0],
        per(times[8]),
        times[8] / times[0]
    );
    println!("µs per pair, single queries: f32 {:.3}, f16 {:.3}, f16 half arithmetic {:.3} ({:.2}x f32)", per(times[3]), per(times[4]), per(times[5]), times[5] / times[3]);
    println!(
        "µs per pair, single queries: bf16 {:.3} ({:.2}x f32); {bf16_single_differ} of {} pairs differ in bits from their bf16 batch value",
        per(times[9]),
        times[9] / times[3],
        64 * n
    );
    Ok(())
}
