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

use alloc::string::{String, ToString};
use alloc::vec::Vec;

use serde::Deserialize;

use crate::angles::{half_diff_vectors, rusinkiewicz_angles, upper_hemisphere_pair};
use crate::math::sanitize;
use crate::{Error, Rgb, Vec3, BLACK};

/// Widest layer accepted: the size of the evaluator's two stack buffers (zeroed on every evaluation, so
/// kept small; the published networks are 21 wide).
pub const MAX_WIDTH: usize = 64;
/// Most layers accepted.
pub const MAX_LAYERS: usize = 16;
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

/// One dense layer: its parameters are `weight` (`outputs × inputs`, row-major) then `bias` in
/// [`NbrdfNetwork`]'s parameter buffer, starting at `offset`.
#[derive(Clone, Debug, PartialEq)]
struct Layer {
    inputs: usize,
    outputs: usize,
    activation: Activation,
    offset: usize,
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
    params: Vec<f32>,
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
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, &e))?;
        Self::from_json_bytes(&bytes).map_err(|e| match e {
            Error::Parse { message, .. } => Error::Parse {
                what: alloc::format!("NBRDF-json file {}", path.display()),
                message,
            },
            other => other,
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
        let mut params = Vec::new();
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
            let weights = layer.weight.iter().flatten();
            if let Some(index) = weights.clone().position(|w| !w.is_finite()) {
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
            let offset = params.len();
            params.extend(weights);
            params.extend(&layer.bias);
            layers.push(Layer {
                inputs: layer.inputs,
                outputs: layer.outputs,
                activation,
                offset,
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
        Ok(NbrdfNetwork {
            name: doc.name,
            layers,
            params,
        })
    }

    /// The material name of the file (`""` where it has none).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Layer widths from input to output, e.g. `[6, 21, 21, 3]`.
    pub fn widths(&self) -> Vec<usize> {
        core::iter::once(INPUTS)
            .chain(self.layers.iter().map(|l| l.outputs))
            .collect()
    }

    /// Each layer's activation, in order.
    pub fn activations(&self) -> Vec<Activation> {
        self.layers.iter().map(|l| l.activation).collect()
    }

    /// The BRDF at (`wi`, `wo`): 0 below the horizon and for degenerate input. No allocation.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        let Some((wi, wo)) = upper_hemisphere_pair(wi, wo) else {
            return BLACK;
        };
        match rusinkiewicz_angles(wi, wo) {
            Some([theta_h, theta_d, phi_d]) => self.eval_angles(theta_h, theta_d, phi_d),
            None => BLACK,
        }
    }

    /// The BRDF at isotropic Rusinkiewicz angles: the network on `half_diff_vectors(θh, θd, φd)`, then
    /// `max(exp(y) - 1, 0)` (module docs). 0 for non-finite angles. No allocation.
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        if !(theta_h.is_finite() && theta_d.is_finite() && phi_d.is_finite()) {
            return BLACK;
        }
        let (h, d) = half_diff_vectors(theta_h, theta_d, phi_d);
        let mut x = [0.0f32; MAX_WIDTH];
        let mut y = [0.0f32; MAX_WIDTH];
        x[..INPUTS].copy_from_slice(&[h.x, h.y, h.z, d.x, d.y, d.z]);
        for layer in &self.layers {
            let (n_in, n_out) = (layer.inputs, layer.outputs);
            let weight = &self.params[layer.offset..layer.offset + n_in * n_out];
            let bias =
                &self.params[layer.offset + n_in * n_out..layer.offset + n_in * n_out + n_out];
            let input = &x[..n_in];
            for ((out, row), b) in y[..n_out]
                .iter_mut()
                .zip(weight.chunks_exact(n_in))
                .zip(bias)
            {
                let s = row.iter().zip(input).fold(*b, |acc, (w, v)| acc + w * v);
                *out = match layer.activation {
                    Activation::Relu => s.max(0.0),
                    Activation::Identity => s,
                };
            }
            core::mem::swap(&mut x, &mut y);
        }
        // expm1 is exp(y) - 1 without the cancellation near y = 0 (the dark, diffuse end).
        sanitize([libm::expm1f(x[0]), libm::expm1f(x[1]), libm::expm1f(x[2])])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(inputs: usize, outputs: usize, act: &str, w: f32, b: f32) -> String {
        let row = alloc::format!("[{}]", alloc::vec![w.to_string(); inputs].join(","));
        let weight = alloc::vec![row; outputs].join(",");
        let bias = alloc::vec![b.to_string(); outputs].join(",");
        alloc::format!(
            r#"{{"inputs":{inputs},"outputs":{outputs},"activation":"{act}","weight":[{weight}],"bias":[{bias}]}}"#
        )
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
