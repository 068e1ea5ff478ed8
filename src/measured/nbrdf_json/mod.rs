//! NBRDF-json networks: the compact neural fits of measured BRDFs by Sztrajman et al. 2021 ("Neural BRDF
//! representation and importance sampling"), in the JSON layout of `../shared/data/README.md`.
//!
//! # Format (`../shared/data/README.md`)
//! ```text
//! { "name", "source", "input": "rusinkiewicz_half_diff_vectors", "output": "expm1_clamped",
//!   "layers": [ { "inputs", "outputs", "activation": "relu" | "none",
//!                 "weight": [[...] x outputs] (row-major, outputs x inputs), "bias": [...] }, ... ] }
//! ```
//! - Input `[hx, hy, hz, dx, dy, dz]`: the half vector with `φh = 0`, `(sin θh, 0, cos θh)`, and the
//!   difference vector `(sin θd cos φd, sin θd sin φd, cos θd)` ([`crate::angles::half_diff_vectors`]).
//! - Each layer computes `y_o = b_o + Σ_i W[o][i] x_i`, then its activation.
//! - Output `rgb = max(exp(y) - 1, 0)`: linear RGB in 1/sr, MERL's channel scales already applied.
//!
//! The published networks are 6-21-21-3 with ReLU; any consistent sizes up to [`MAX_WIDTH`] and
//! [`MAX_LAYERS`] are accepted, so evaluation runs in fixed stack arrays without allocating.
//! The networks are not reciprocal (they see `φd`, not `φd mod π`), as in the original.
//!
//! Evaluation runs the whole network in one call of the tiny-network kernel (`tiny.rs`: `TinyNet`,
//! AVX-512 where the CPU has it, the generic dense-layer kernels of [`crate::kernels`] elsewhere).

mod tiny;

pub(crate) use tiny::{half_diff_packet, TinyLayer, TinyNet, TINY_INPUTS, TINY_MAX_WIDTH, TINY_PACKET};

use alloc::string::{String, ToString};
use alloc::vec::Vec;

use serde::Deserialize;

use crate::angles::{half_diff_vectors, unit};
use crate::brdf::{Brdf, BsdfSample};
use crate::math::{load_pair, sanitize};
use crate::sampling::{fit_proxy, fit_view_proxy_around, Proxy, ViewProxy};
use crate::{Error, Rgb, Vec3, BLACK};

/// Widest layer accepted: the size of the evaluator's stack buffers (the published networks are 21
/// wide). Layers are padded to multiples of 8 (whole SIMD vectors).
pub const MAX_WIDTH: usize = 64;
const _: () = assert!(MAX_WIDTH <= TINY_MAX_WIDTH && INPUTS == TINY_INPUTS);
/// Most layers accepted.
pub const MAX_LAYERS: usize = 16;
/// Largest JSON text read, 64 MiB: the largest network accepted (16 layers 64 wide) is under 2 MB
/// of numbers, so this leaves room for any formatting while a wrong length is refused unread.
pub const MAX_JSON_BYTES: usize = 64 << 20;
/// Network input size: `[hx, hy, hz, dx, dy, dz]`.
pub const INPUTS: usize = 6;
/// Network output size: RGB.
pub const OUTPUTS: usize = 3;
/// The only `input` encoding of the format.
pub const INPUT_ENCODING: &str = "rusinkiewicz_half_diff_vectors";
/// The only `output` mapping of the format.
pub const OUTPUT_MAPPING: &str = "expm1_clamped";

/// A layer's activation (JSON field `activation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Activation {
    /// `"relu"`: `max(x, 0)`.
    Relu,
    /// `"none"`: the identity.
    Identity,
}

/// One dense layer: its activation, and where the tiny-network kernel finds it in [`NbrdfNetwork`]'s
/// `evaluator` buffer.
#[derive(Clone, Debug, PartialEq)]
struct Layer {
    activation: Activation,
    tiny: TinyLayer,
}

/// An NBRDF-json network, validated and ready to evaluate.
///
/// ```
/// use nbrdf::measured::NbrdfNetwork;
/// // One linear layer whose red output is ln 2: the BRDF is exp(ln 2) - 1 = 1 in red, 0 elsewhere.
/// let json = r#"{"input": "rusinkiewicz_half_diff_vectors", "output": "expm1_clamped", "layers": [
///     {"inputs": 6, "outputs": 3, "activation": "none",
///      "weight": [[0,0,0,0,0,0], [0,0,0,0,0,0], [0,0,0,0,0,0]], "bias": [0.6931472, 0, -5]}]}"#;
/// let net = NbrdfNetwork::from_json_str(json).unwrap();
/// let f = net.eval_angles(0.1, 0.2, 0.3);
/// assert!((f[0] - 1.0).abs() < 1e-6 && f[1] == 0.0 && f[2] == 0.0);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct NbrdfNetwork {
    name: String,
    layers: Vec<Layer>,
    /// The parameters rearranged for the tiny-network kernels ([`TinyNet`]): each layer's
    /// matrix transposed to `[inputs][outputs]` with the outputs zero-padded to whole vectors, then its
    /// bias (zero-padded too).
    evaluator: Vec<f32>,
    /// The layers as the kernels see them (`layers[l].tiny`, kept contiguous).
    tiny: Vec<TinyLayer>,
    /// The sampling proxy fitted to the network at construction.
    proxy: Proxy,
    /// The per-view sampling table fitted around `proxy` at construction; what sampling uses.
    view: ViewProxy,
}

/// The file as serde sees it; everything is validated afterwards so that each fault gets its own error.
#[derive(Deserialize)]
struct JsonNetwork {
    #[serde(default)]
    name: String,
    input: String,
    output: String,
    layers: Vec<JsonLayer>,
}

#[derive(Deserialize)]
struct JsonLayer {
    inputs: usize,
    outputs: usize,
    activation: String,
    weight: Vec<Vec<f32>>,
    bias: Vec<f32>,
}

impl NbrdfNetwork {
    /// Parses and validates an NBRDF-json document.
    ///
    /// Errors: [`Error::Parse`] for invalid JSON, a missing field or a wrong field type (NaN is not
    /// JSON, so a NaN weight is a parse error); [`Error::InvalidValue`] for an unknown `input`, `output`
    /// or `activation` or an empty `layers`; [`Error::SizeMismatch`] when a layer's declared sizes
    /// disagree with its weights or with its neighbours, or the network is not 6 → … → 3;
    /// [`Error::TooLarge`] beyond [`MAX_WIDTH`] or [`MAX_LAYERS`]; [`Error::NonFinite`] for a weight that
    /// overflows `f32`.
    pub fn from_json_str(json: &str) -> Result<Self, Error> {
        Self::from_json_bytes(json.as_bytes())
    }

    /// [`from_json_str`](Self::from_json_str) on raw bytes (which must be UTF-8 JSON).
    pub fn from_json_bytes(json: &[u8]) -> Result<Self, Error> {
        if json.len() > MAX_JSON_BYTES {
            return Err(Error::TooLarge { what: "NBRDF-json bytes", found: json.len(), max: MAX_JSON_BYTES });
        }
        // serde_json skips the bytes of fields it ignores without checking them; the whole
        // document must be UTF-8 all the same.
        if let Err(e) = core::str::from_utf8(json) {
            return Err(Error::Parse {
                what: "NBRDF-json".to_string(),
                message: alloc::format!("not UTF-8: invalid byte at offset {}", e.valid_up_to()),
            });
        }
        let doc: JsonNetwork = serde_json::from_slice(json).map_err(|e| Error::Parse {
            what: "NBRDF-json".to_string(),
            message: e.to_string(),
        })?;
        Self::validate(doc)
    }

    /// Loads an NBRDF-json file.
    ///
    /// Errors: [`Error::Io`] when the file cannot be read; every error of
    /// [`from_json_str`](Self::from_json_str), parse errors naming the file.
    #[cfg(feature = "std")]
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Self, Error> {
        let path = path.as_ref();
        // 64 MiB: the largest network accepted is under 2 MB of numbers; a device (`/dev/zero`) or a
        // wrong file is refused without filling the memory.
        let bytes = crate::io::read_at_most(path, MAX_JSON_BYTES as u64)?;
        Self::from_json_bytes(&bytes).map_err(|e| match e {
            Error::Parse { message, .. } => Error::Parse {
                what: alloc::format!("NBRDF-json file {}", path.display()),
                message,
            },
            other => other.context(alloc::format!("NBRDF-json file {}", path.display())),
        })
    }

    fn validate(doc: JsonNetwork) -> Result<Self, Error> {
        if doc.input != INPUT_ENCODING {
            return Err(Error::InvalidValue {
                what: "NBRDF-json input",
                reason: "the only supported input is \"rusinkiewicz_half_diff_vectors\"",
            });
        }
        if doc.output != OUTPUT_MAPPING {
            return Err(Error::InvalidValue {
                what: "NBRDF-json output",
                reason: "the only supported output is \"expm1_clamped\"",
            });
        }
        if doc.layers.is_empty() {
            return Err(Error::InvalidValue {
                what: "NBRDF-json layers",
                reason: "no layers",
            });
        }
        if doc.layers.len() > MAX_LAYERS {
            return Err(Error::TooLarge {
                what: "NBRDF-json layer count",
                found: doc.layers.len(),
                max: MAX_LAYERS,
            });
        }
        let mut layers = Vec::with_capacity(doc.layers.len());
        let mut evaluator = Vec::new();
        let mut width = INPUTS;
        for (l, layer) in doc.layers.iter().enumerate() {
            if layer.outputs > MAX_WIDTH {
                return Err(Error::TooLarge {
                    what: "NBRDF-json layer outputs",
                    found: layer.outputs,
                    max: MAX_WIDTH,
                });
            }
            if layer.inputs != width {
                let what = if l == 0 {
                    "NBRDF-json first layer inputs (the 6 half/difference vector components)"
                } else {
                    "NBRDF-json layer inputs (the previous layer's outputs)"
                };
                return Err(Error::SizeMismatch {
                    what,
                    expected: width,
                    found: layer.inputs,
                });
            }
            if layer.weight.len() != layer.outputs {
                return Err(Error::SizeMismatch {
                    what: "NBRDF-json weight rows (the layer's outputs)",
                    expected: layer.outputs,
                    found: layer.weight.len(),
                });
            }
            if let Some(row) = layer.weight.iter().find(|r| r.len() != layer.inputs) {
                return Err(Error::SizeMismatch {
                    what: "NBRDF-json weight row length (the layer's inputs)",
                    expected: layer.inputs,
                    found: row.len(),
                });
            }
            if layer.bias.len() != layer.outputs {
                return Err(Error::SizeMismatch {
                    what: "NBRDF-json bias length (the layer's outputs)",
                    expected: layer.outputs,
                    found: layer.bias.len(),
                });
            }
            let activation = match layer.activation.as_str() {
                "relu" => Activation::Relu,
                "none" => Activation::Identity,
                _ => {
                    return Err(Error::InvalidValue {
                        what: "NBRDF-json layer activation",
                        reason: "expected \"relu\" or \"none\"",
                    })
                }
            };
            // serde converts an out-of-range number to an infinite f32 rather than failing.
            if let Some(index) = layer.weight.iter().flatten().position(|w| !w.is_finite()) {
                return Err(Error::NonFinite {
                    what: "NBRDF-json weight",
                    index,
                });
            }
            if let Some(index) = layer.bias.iter().position(|b| !b.is_finite()) {
                return Err(Error::NonFinite {
                    what: "NBRDF-json bias",
                    index,
                });
            }
            let padded = layer.outputs.div_ceil(8) * 8;
            let eval_offset = evaluator.len();
            evaluator.resize(eval_offset + (layer.inputs + 1) * padded, 0.0);
            for (o, row) in layer.weight.iter().enumerate() {
                for (i, w) in row.iter().enumerate() {
                    evaluator[eval_offset + i * padded + o] = *w;
                }
            }
            evaluator[eval_offset + layer.inputs * padded..][..layer.outputs].copy_from_slice(&layer.bias);
            layers.push(Layer {
                activation,
                tiny: TinyLayer {
                    inputs: layer.inputs,
                    outputs: layer.outputs,
                    padded,
                    offset: eval_offset,
                    relu: activation == Activation::Relu,
                },
            });
            width = layer.outputs;
        }
        if width != OUTPUTS {
            return Err(Error::SizeMismatch {
                what: "NBRDF-json last layer outputs (RGB)",
                expected: OUTPUTS,
                found: width,
            });
        }
        let tiny = layers.iter().map(|l| l.tiny).collect();
        let mut net = NbrdfNetwork { name: doc.name, layers, evaluator, tiny, proxy: Proxy::COSINE, view: ViewProxy::default() };
        net.proxy = fit_proxy(|wi, wo| net.eval(wi, wo));
        net.view = fit_view_proxy_around(|wi, wo| net.eval(wi, wo), &net.proxy);
        Ok(net)
    }

    /// The proxy [`Brdf::sample`] draws from: [`fit_proxy`] on the network, fitted once at load.
    pub fn proxy(&self) -> &Proxy {
        &self.proxy
    }

    /// The per-view sampling table [`Brdf::sample`] draws from ([`fit_view_proxy_around`] the
    /// [`proxy`](Self::proxy)); exported shaders sample the single proxy.
    pub fn view_proxy(&self) -> &ViewProxy {
        &self.view
    }

    /// The material name of the file (`""` where it has none).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Layer widths from input to output, e.g. `[6, 21, 21, 3]`.
    pub fn widths(&self) -> Vec<usize> {
        core::iter::once(INPUTS)
            .chain(self.layers.iter().map(|l| l.tiny.outputs))
            .collect()
    }

    /// Each layer's activation, in order.
    pub fn activations(&self) -> Vec<Activation> {
        self.layers.iter().map(|l| l.activation).collect()
    }

    /// The BRDF at (`wi`, `wo`): 0 below the horizon and for degenerate input. No allocation.
    ///
    /// Inlined, so that the directions reach the input transform, and its result the network kernel,
    /// in registers (see `TinyNet::brdf`).
    #[inline(always)]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        // With the kernel's register interface, 0.89x the time of `nbrdf-json/eval` (see `load_pair`).
        let (wi, wo) = load_pair(&wi, &wo);
        // `expm1` is exp(y) - 1 without the cancellation near y = 0 (the dark, diffuse end).
        match input(wi, wo) {
            Some(x) => self.tiny_net().brdf(&x),
            None => BLACK,
        }
    }

    /// [`eval`](Self::eval) for many direction pairs: `out[i] = eval(wi[i], wo[i])` for the common
    /// length of the slices, bit for bit. The pairs go through the input transform and the network in
    /// packets of 16 (one pair per vector lane). No allocation.
    pub fn eval_many(&self, wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) {
        let n = out.len().min(wi.len()).min(wo.len());
        let net = self.tiny_net();
        let mut y = [[0.0f32; TINY_PACKET]; OUTPUTS];
        for start in (0..n).step_by(TINY_PACKET) {
            let m = (n - start).min(TINY_PACKET);
            let (wi, wo, out) = (&wi[start..start + m], &wo[start..start + m], &mut out[start..start + m]);
            // Lanes past `m` stay 0 and are dropped.
            let mut a = [[0.0f32; TINY_PACKET]; 3];
            let mut b = [[0.0f32; TINY_PACKET]; 3];
            for q in 0..m {
                for c in 0..3 {
                    a[c][q] = wi[q][c];
                    b[c][q] = wo[q][c];
                }
            }
            let mut x = [[0.0f32; TINY_PACKET]; INPUTS];
            let (mut valid, slow) = half_diff_packet(&a, &b, m, &mut x);
            // The pairs outside the fast path's range, one by one (the same result as `eval`).
            for q in (0..m).filter(|q| slow >> q & 1 != 0) {
                if let Some(v) = input(wi[q], wo[q]) {
                    for (x, v) in x.iter_mut().zip(v) {
                        x[q] = v;
                    }
                    valid |= 1 << q;
                }
            }
            // Invalid lanes run through the network too (lanes are independent); their results
            // are dropped.
            net.packet(&x, &mut y);
            for (q, o) in out.iter_mut().enumerate() {
                *o = if valid >> q & 1 != 0 { sanitize([y[0][q], y[1][q], y[2][q]]) } else { BLACK };
            }
        }
    }

    /// The BRDF at isotropic Rusinkiewicz angles: the network on `half_diff_vectors(θh, θd, φd)`, then
    /// `max(exp(y) - 1, 0)` (module docs). 0 for non-finite angles. No allocation.
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        if !(theta_h.is_finite() && theta_d.is_finite() && phi_d.is_finite()) {
            return BLACK;
        }
        let (h, d) = half_diff_vectors(theta_h, theta_d, phi_d);
        self.tiny_net().brdf(&[h.x, h.y, h.z, d.x, d.y, d.z])
    }

    #[inline]
    fn tiny_net(&self) -> TinyNet<'_> {
        TinyNet { layers: &self.tiny, params: &self.evaluator }
    }
}

/// The network input `[h, d]` of a direction pair computed from the vectors without trigonometry (the
/// angles and `half_diff_vectors` cost libm calls per pair), equal to
/// `half_diff_vectors(rusinkiewicz_angles(wi, wo))` up to float rounding.
///
/// With the unnormalised half vector `h = wi + wo`, `q = h_x² + h_y²`, `r = √q` and `|h|`: the half
/// vector with `φh = 0` is `(ρ, 0, h_z / |h|)` with `ρ = r / |h| = sin θh`, and `d` is `wi` rotated by
/// `-φh` about z (`cos φh = h_x / r`, `sin φh = h_y / r`), then by `-θh` about y. Multiplied out,
/// with `a = h_x wi_x + h_y wi_y` and `b = h_x wi_y - h_y wi_x`:
/// ```text
/// d = ( (h_z a - q wi_z) / (r |h|),  b / r,  (a + h_z wi_z) / |h| )
/// ```
/// The numerators wait on no square root, and the two reciprocal square roots (`1 / r` and `1 / |h|`)
/// run side by side, so the dependent chain is one square-root-and-divide step and two
/// multiplications after `q`. `h_xy = 0` means `φh = 0`, as in `angles::to_rusinkiewicz`: `d` is `wi`
/// rotated by `-θh = 0`. [`half_diff_packet`] is the same computation on 16 pairs, bit
/// for bit.
#[inline(always)]
fn input(wi: Vec3, wo: Vec3) -> Option<[f32; INPUTS]> {
    let wi = unit(wi)?;
    let wo = unit(wo)?;
    if !(wi.z > 0.0 && wo.z > 0.0) {
        return None;
    }
    // Both directions are unit and above the horizon, so `h = wi + wo` has z > 0 and never vanishes.
    let (hx, hy, hz) = (wi.x + wo.x, wi.y + wo.y, wi.z + wo.z);
    let q = hx * hx + hy * hy;
    let inv_len = 1.0 / libm::sqrtf(q + hz * hz);
    let cos_h = hz * inv_len;
    let v = if q > 0.0 {
        let r = libm::sqrtf(q);
        let inv_r = 1.0 / r;
        let (a, b) = (hx * wi.x + hy * wi.y, hx * wi.y - hy * wi.x);
        [r * inv_len, 0.0, cos_h, (inv_len * inv_r) * (hz * a - q * wi.z), b * inv_r, inv_len * (a + hz * wi.z)]
    } else {
        [0.0, 0.0, cos_h, cos_h * wi.x, wi.y, cos_h * wi.z]
    };
    v.iter().all(|c| c.is_finite()).then_some(v)
}


/// The network, sampled through its proxy. Not reciprocal: its input, the difference vector in the
/// half-vector frame, changes under the swap of `wi` and `wo`, and nothing in training ties the two.
impl Brdf for NbrdfNetwork {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        NbrdfNetwork::eval(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        self.view.sample(wo, u, |wi, wo| NbrdfNetwork::eval(self, wi, wo))
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.view.pdf(wi, wo)
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angles::rusinkiewicz_angles;

    fn layer(inputs: usize, outputs: usize, act: &str, w: f32, b: f32) -> String {
        let row = alloc::format!("[{}]", alloc::vec![w.to_string(); inputs].join(","));
        let weight = alloc::vec![row; outputs].join(",");
        let bias = alloc::vec![b.to_string(); outputs].join(",");
        alloc::format!(
            r#"{{"inputs":{inputs},"outputs":{outputs},"activation":"{act}","weight":[{weight}],"bias":[{bias}]}}"#
        )
    }

    #[test]
    fn trigonometry_free_input_matches_the_angles() {
        for i in 0..500 {
            let t = i as f32 * 0.37;
            let wi = Vec3::new(libm::sinf(t) * 0.9, libm::cosf(1.7 * t) * 0.8, 0.05 + (i % 7) as f32 * 0.15).normalize();
            let wo = Vec3::new(libm::cosf(0.3 * t) * 0.7, libm::sinf(2.3 * t) * 0.9, 0.02 + (i % 5) as f32 * 0.2).normalize();
            let got = input(wi, wo).unwrap();
            let [th, td, pd] = rusinkiewicz_angles(wi, wo).unwrap();
            let (h, d) = half_diff_vectors(th, td, pd);
            let want = [h.x, h.y, h.z, d.x, d.y, d.z];
            for c in 0..INPUTS {
                assert!((got[c] - want[c]).abs() < 2e-5, "pair {i} component {c}: {got:?} vs {want:?}");
            }
        }
        assert_eq!(input(Vec3::Z, Vec3::Z), Some([0.0, 0.0, 1.0, 0.0, 0.0, 1.0]));
        assert_eq!(input(Vec3::new(0.0, 0.0, -1.0), Vec3::Z), None);
    }

    #[test]
    fn eval_many_equals_eval_bit_for_bit() {
        let json = alloc::format!(
            r#"{{"input":"{INPUT_ENCODING}","output":"{OUTPUT_MAPPING}","layers":[{},{},{}]}}"#,
            layer(6, 21, "relu", 0.31, -0.2),
            layer(21, 21, "relu", -0.05, 0.1),
            layer(21, 3, "none", 0.02, -0.1)
        );
        let net = NbrdfNetwork::from_json_str(&json).unwrap();
        let n = 37;
        let dir = |t: f32, z: f32| Vec3::new(libm::sinf(t) * 0.7, libm::cosf(1.3 * t) * 0.6, z).normalize();
        let wi: Vec<Vec3> = (0..n).map(|i| dir(i as f32, if i % 5 == 2 { -0.3 } else { 0.5 })).collect();
        let wo: Vec<Vec3> = (0..n).map(|i| dir(2.1 * i as f32 + 0.3, 0.4)).collect();
        let mut out = alloc::vec![[f32::NAN; 3]; n];
        net.eval_many(&wi, &wo, &mut out);
        for i in 0..n {
            assert_eq!(out[i].map(f32::to_bits), net.eval(wi[i], wo[i]).map(f32::to_bits), "pair {i}");
        }
        assert_eq!(out[2], BLACK);

        // The lanes the vector input transform hands back to the scalar one, and its edge cases:
        // vectors outside the one-division range, a half vector on the normal (h_xy = 0), directions
        // below or on the horizon, NaN, infinity, zero.
        let a = Vec3::new(0.3, -0.2, 0.9);
        let b = Vec3::new(-0.3, 0.2, 0.9);
        let special = [
            (a * 1e20, b),
            (a, b * 1e-20),
            (a * 3e-38, b * 1e35),
            (a, b),
            (Vec3::Z, Vec3::Z),
            (a, Vec3::new(0.5, 0.5, 0.0)),
            (a, Vec3::new(0.5, 0.5, -1e-30)),
            (Vec3::new(f32::NAN, 0.0, 1.0), b),
            (a, Vec3::new(0.0, f32::INFINITY, 1.0)),
            (Vec3::ZERO, b),
            (a, Vec3::new(1e-30, 0.0, 1e-30)),
            // Either side of the edges of the Taylor range `| |v|² - 1 | ≤ 2^-12`.
            (a.normalize() * 1.000_11, b.normalize() * 0.999_89),
            (a.normalize() * 1.000_13, b.normalize() * 0.999_87),
        ];
        for rot in 0..special.len() {
            let wi: Vec<Vec3> = (0..19).map(|i| if i % 2 == 0 { special[(i / 2 + rot) % special.len()].0 } else { dir(i as f32, 0.5) }).collect();
            let wo: Vec<Vec3> = (0..19).map(|i| if i % 2 == 0 { special[(i / 2 + rot) % special.len()].1 } else { dir(1.7 * i as f32, 0.3) }).collect();
            let mut out = alloc::vec![[f32::NAN; 3]; wi.len()];
            net.eval_many(&wi, &wo, &mut out);
            for i in 0..wi.len() {
                assert_eq!(out[i].map(f32::to_bits), net.eval(wi[i], wo[i]).map(f32::to_bits), "rotation {rot} pair {i}");
            }
        }
    }

    #[test]
    fn relu_then_linear_matches_hand_computation() {
        // Hidden: 2 units, each relu(0.5 Σx - 0.1); output: each 0.25 Σh.
        let json = alloc::format!(
            r#"{{"input":"{INPUT_ENCODING}","output":"{OUTPUT_MAPPING}","layers":[{},{}]}}"#,
            layer(6, 2, "relu", 0.5, -0.1),
            layer(2, 3, "none", 0.25, 0.0)
        );
        let net = NbrdfNetwork::from_json_str(&json).unwrap();
        assert_eq!(net.widths(), [6, 2, 3]);
        let (h, d) = half_diff_vectors(0.3, 0.4, 1.1);
        let sum = h.x + h.y + h.z + d.x + d.y + d.z;
        let hidden = (0.5 * sum - 0.1f32).max(0.0);
        let expect = libm::expm1f(0.25 * 2.0 * hidden);
        let f = net.eval_angles(0.3, 0.4, 1.1);
        for c in f {
            assert!(
                (c - expect).abs() < 1e-6 * expect.max(1.0),
                "{c} vs {expect}"
            );
        }
    }
}
