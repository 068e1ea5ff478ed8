//! Small models of every kind for the shader tests, made here with random weights: the paper's
//! architectures (`ModelHeader::paper`) narrowed to a few units, so that the weights stay inline.
#![allow(dead_code)]

use nbrdf::energy::{AlbedoBound, ALBEDO_CELLS};
use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::parametric::ParametricKind;
use nbrdf::sampling::{GgxLobe, Proxy, ViewProxy};

/// A 64-bit LCG (Knuth's MMIX constants): the same models on every run.
pub struct Rng(pub u64);

impl Rng {
    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}

/// One test model: its name and file bytes.
pub struct TestModel {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// `h` with every network `width` wide (the inputs of the heads that read a trunk follow).
pub fn narrow(h: ModelHeader, width: u16) -> ModelHeader {
    let h = h.with_width(width);
    h.validate().expect("narrowed header");
    h
}

/// He-scaled random weights for `h` (each layer's weights ~ U(-1, 1) sqrt(6 / inputs), biases small),
/// so that activations neither vanish nor explode through the layers; FMBRDF's object parameter is a
/// plausible log-normalisation.
pub fn weights(h: &ModelHeader, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut w = Vec::with_capacity(h.n_weights());
    for d in h.nets() {
        for l in 0..d.n_layers() {
            let (rows, n_out) = (d.layer_inputs(l), d.layer_outputs(l));
            let scale = (6.0 / rows.max(1) as f32).sqrt();
            for _ in 0..rows * n_out {
                w.push((2.0 * rng.next() - 1.0) * scale);
            }
            for _ in 0..n_out {
                w.push((2.0 * rng.next() - 1.0) * 0.3);
            }
        }
    }
    w.extend(std::iter::repeat_n(1.5, h.n_object()));
    w
}

/// The file of `h` with random weights, f32 or f16, intrinsic models with a small vertex table.
pub fn model(name: &str, h: ModelHeader, precision: Precision, seed: u64) -> TestModel {
    let mut h = h;
    h.precision = precision;
    let w = weights(&h, seed);
    let bytes = encode(&h, &w, None).expect("encode");
    TestModel { name: format!("{name} {precision:?}"), bytes }
}

/// Every model kind the exporter handles, small: the four parametric models (and Lambert), the Single
/// MLP with and without a trunk (NOL), the additive models plain and enhanced; reciprocity None, Swap
/// and Exact; uniform, intrinsic and extrinsic positions; f32 and f16 weights; with and without a
/// sampling proxy, some with a per-view sampling table.
pub fn all_models() -> Vec<TestModel> {
    let positions = [
        PositionEncoding::Uniform,
        PositionEncoding::Intrinsic { k: 5 },
        PositionEncoding::Extrinsic { frequencies: 2 },
    ];
    let proxy = Proxy::new(0.3, [GgxLobe { weight: 0.5, alpha: 0.2 }, GgxLobe { weight: 0.2, alpha: 0.05 }]).unwrap();
    // A per-view table whose cells differ, so that a shader reading the wrong cell shows.
    let mut view = ViewProxy::default();
    for (c, node) in view.nodes.iter_mut().enumerate() {
        let t = c as f32 / 15.0;
        *node = Proxy::new(0.1 + 0.8 * t, [GgxLobe { weight: 0.6 - 0.5 * t, alpha: 0.03 + 0.4 * t }, GgxLobe { weight: 0.3, alpha: 0.6 - 0.5 * t }]).unwrap();
    }
    // An energy bound whose cells differ per channel, above 1 in some and below in others, so that a
    // shader dividing by the wrong cell or channel shows.
    let mut bound = AlbedoBound { cells: [[0.0; 3]; ALBEDO_CELLS] };
    for (j, c) in bound.cells.iter_mut().enumerate() {
        let t = j as f32 / (ALBEDO_CELLS - 1) as f32;
        *c = [0.6 + 1.2 * t, 1.8 - 1.1 * t, if j % 3 == 0 { 2.5 } else { 0.7 }];
    }
    let mut out = Vec::new();
    let mut seed = 1;
    for (i, kind) in ParametricKind::ALL.into_iter().enumerate() {
        let mut h = ModelHeader::paper(ModelKind::Parametric(kind), false, Reciprocity::None, positions[i % 3], 0);
        let precision = if i % 2 == 0 { Precision::F32 } else { Precision::F16 };
        let mut name = format!("Parametric({}) {:?}", kind.id(), positions[i % 3]);
        if i % 2 == 1 {
            h = h.with_albedo_bound(bound);
            name.push_str(" bounded");
        }
        out.push(model(&name, narrow(h, 12), precision, seed));
        seed += 1;
    }
    let neural: [(ModelKind, bool, Option<u8>); 6] = [
        (ModelKind::SingleMlp, false, None),
        (ModelKind::SingleMlp, false, Some(2)),
        (ModelKind::AdditiveSeparate, false, None),
        (ModelKind::AdditiveSeparate, true, None),
        (ModelKind::AdditiveShared, false, None),
        (ModelKind::AdditiveShared, true, None),
    ];
    for (i, (kind, enhanced, nol)) in neural.into_iter().enumerate() {
        for (j, reciprocity) in [Reciprocity::None, Reciprocity::Swap, Reciprocity::Exact].into_iter().enumerate() {
            let position = positions[(i + j) % 3];
            let mut h = ModelHeader::paper(kind, enhanced, reciprocity, position, 3);
            if let Some(n) = nol {
                h = h.with_direction_layers(n);
            }
            if (i + j) % 2 == 0 {
                h = h.with_proxy(proxy);
            }
            if (i + j) % 4 == 0 {
                h = h.with_view_proxy(view);
            }
            if (i + j) % 3 == 1 {
                h = h.with_albedo_bound(bound);
            }
            let precision = if (i + j) % 2 == 1 { Precision::F16 } else { Precision::F32 };
            let name = format!(
                "{kind:?}{}{} {reciprocity:?} {position:?}{}",
                if enhanced { " enhanced" } else { "" },
                nol.map(|n| format!(" NOL {n}")).unwrap_or_default(),
                if h.albedo_bound.is_some() { " bounded" } else { "" }
            );
            out.push(model(&name, narrow(h, 12), precision, seed));
            seed += 1;
        }
    }
    out
}

/// An NBRDF-json network of the published shape 6-21-21-3 with random weights.
pub fn json_network(seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    let mut layer = |inputs: usize, outputs: usize, act: &str, scale: f32| {
        let rows: Vec<String> = (0..outputs)
            .map(|_| {
                let r: Vec<String> = (0..inputs).map(|_| format!("{}", (2.0 * rng.next() - 1.0) * scale)).collect();
                format!("[{}]", r.join(","))
            })
            .collect();
        let bias: Vec<String> = (0..outputs).map(|_| format!("{}", (2.0 * rng.next() - 1.0) * 0.2)).collect();
        format!(
            r#"{{"inputs":{inputs},"outputs":{outputs},"activation":"{act}","weight":[{}],"bias":[{}]}}"#,
            rows.join(","),
            bias.join(",")
        )
    };
    let layers = [layer(6, 21, "relu", 1.0), layer(21, 21, "relu", 0.5), layer(21, 3, "none", 0.5)];
    format!(
        r#"{{"name":"random","input":"rusinkiewicz_half_diff_vectors","output":"expm1_clamped","layers":[{}]}}"#,
        layers.join(",")
    )
    .into_bytes()
}
