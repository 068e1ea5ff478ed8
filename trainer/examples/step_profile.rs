//! Breaks one training step of the Single MLP at batch 32768 into forward, backward and Adam, and times
//! the bias variants (ones-matmul vs broadcast add) in isolation.
use std::time::Instant;

use candle_core::{DType, Device, Tensor, Var};
use trainer::adam::{Adam, AdamParams};
use trainer::models::{Config, Inputs, Kind, Model, PositionEncoding, RawBatch, Reciprocity};
use trainer::train::{objective, Batch, TrainOptions};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() -> trainer::Result<()> {
    let n = 32768;
    let d = Device::Cpu;
    // A bare layer: x[N,128] · W[128,128] (+ bias two ways), forward + backward.
    let x = Tensor::randn(0f32, 1.0, (n, 128), &d)?;
    let w = Var::randn(0f32, 0.1, (128, 128), &d)?;
    let b = Var::randn(0f32, 0.1, (1, 128), &d)?;
    let ones = Tensor::ones((n, 1), DType::F32, &d)?;
    for rep in 0..3 {
        let t = Instant::now();
        let y = x.matmul(w.as_tensor())?;
        let f = ms(t);
        let t = Instant::now();
        let _g = y.sum_all()?.backward()?;
        let bw = ms(t);
        let t = Instant::now();
        let y = (x.matmul(w.as_tensor())? + ones.matmul(b.as_tensor())?)?;
        let f2 = ms(t);
        let t = Instant::now();
        let _g = y.sum_all()?.backward()?;
        let bw2 = ms(t);
        let t = Instant::now();
        let y = x.matmul(w.as_tensor())?.broadcast_add(b.as_tensor())?;
        let f3 = ms(t);
        let t = Instant::now();
        let _g = y.sum_all()?.backward()?;
        let bw3 = ms(t);
        println!("rep {rep}: no bias fwd {f:.1} bwd {bw:.1} | ones-matmul fwd {f2:.1} bwd {bw2:.1} | broadcast fwd {f3:.1} bwd {bw3:.1} ms");
    }
    let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 32 });
    let obs = trainer::toy::observations(n, config.position, 1);
    let model = Model::init(config, 0, &d)?;
    let inputs = Inputs::build(&config, &RawBatch { position: &obs.position, wi: &obs.wi, wo: &obs.wo, swap: None }, &d)?;
    let batch = Batch {
        inputs,
        incident: Tensor::ones((n, 3), DType::F32, &d)?,
        target: Tensor::ones((n, 3), DType::F32, &d)?.affine(0.5, 0.0)?,
    };
    let opts = TrainOptions::default();
    let vars = model.vars();
    let mut adam = Adam::new(&vars, AdamParams::default());
    for rep in 0..3 {
        let t = Instant::now();
        let loss = objective(&model, &batch, &opts)?;
        let f = ms(t);
        let t = Instant::now();
        let g = loss.backward()?;
        let bw = ms(t);
        let t = Instant::now();
        let g = Adam::gradients(&vars, &g)?;
        adam.step(&vars, &g, 1e-4)?;
        let a = ms(t);
        println!("single-mlp rep {rep}: forward {f:.1} backward {bw:.1} adam {a:.1} ms");
    }
    Ok(())
}
