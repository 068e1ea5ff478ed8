//! An NBRDF-json network (Sztrajman et al. 2021) as WGSL: the half/difference-vector input, the
//! network, `expm1` clamped, and sampling through a proxy.

use nbrdf::measured::nbrdf_json::{Activation, NbrdfNetwork};
use nbrdf::sampling::{Proxy, ViewProxy};
use serde::Deserialize;

use crate::model::emit_proxy_sampling;
use crate::network::{self, Input, Layer, Network, Storage};
use crate::{Body, Error};

#[derive(Deserialize)]
struct JsonNetwork {
    layers: Vec<JsonLayer>,
}

#[derive(Deserialize)]
struct JsonLayer {
    weight: Vec<Vec<f32>>,
    bias: Vec<f32>,
}

/// The network of a JSON document the core's loader accepted (`net`), its weights transposed to the
/// `[in][out]` rows of the shader's layers.
pub(crate) fn network(net: &NbrdfNetwork, json: &[u8], source: &str) -> Result<Network, Error> {
    let doc: JsonNetwork = serde_json::from_slice(json).map_err(|e| Error::Model {
        source: source.to_string(),
        error: nbrdf::Error::Parse { what: "NBRDF-json".into(), message: e.to_string() },
    })?;
    let widths = net.widths();
    let activations = net.activations();
    let mut layers = Vec::new();
    for (l, layer) in doc.layers.iter().enumerate() {
        let (n_in, n_out) = (widths[l], widths[l + 1]);
        let mut matrix = vec![0.0f32; n_in * n_out];
        for (o, row) in layer.weight.iter().enumerate() {
            for (i, &w) in row.iter().enumerate() {
                matrix[i * n_out + o] = w;
            }
        }
        let inputs = vec![if l == 0 { Input::X } else { Input::H }];
        layers.push(Layer { inputs, n_out, relu: activations[l] == Activation::Relu, matrix, bias: layer.bias.clone() });
    }
    Ok(Network { n_in: widths[0], layers })
}

/// The shader body of a network, sampling through `view` where given, else through `proxy`.
pub(crate) fn body(net: &Network, proxy: &Proxy, view: Option<&ViewProxy>, storage: Storage) -> Body {
    let mut code = String::new();
    let mut buffer = Vec::new();
    let start = match storage {
        Storage::Buffer { .. } => net.append_weights(&mut buffer),
        Storage::Inline => 0,
    };
    network::emit(&mut code, "nbrdf_net0", net, storage, start);
    code.push_str(
        "fn nbrdf_eval(wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {\n\
         \x20   let x = nbrdf_json_input(wi, wo);\n\
         \x20   if (!x.ok) {\n        return vec3<f32>(0.0);\n    }\n\
         \x20   let y = nbrdf_net0(x.x);\n\
         \x20   return vec3<f32>(nbrdf_expm1_clamped(y[0]), nbrdf_expm1_clamped(y[1]), nbrdf_expm1_clamped(y[2]));\n}\n\n",
    );
    emit_proxy_sampling(&mut code, proxy, view, "", "");
    Body { code, buffer, position_len: 0, macs: net.macs(), parametric: false, json: true }
}
