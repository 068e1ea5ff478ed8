//! Dense ReLU networks as WGSL functions: unrolled with the weights as literals (small networks), or as
//! loops over a storage buffer (large ones).
//!
//! Both forms compute `y_o = b_o + Σ_i x_i M[i][o]` per layer (`docs/models.md`), rows in input order,
//! so they agree with the core to the rounding of the sums' order: the same bound as between the
//! core's own kernel levels.

use std::fmt::Write;

use nbrdf::mlp::NetDesc;

/// Where one layer's inputs come from, concatenated in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Input {
    /// The network's input `x`.
    X,
    /// The previous layer's activation.
    H,
}

/// One dense layer: `matrix` is `[inputs][n_out]` row-major, then `bias` (`n_out`).
#[derive(Clone, Debug)]
pub(crate) struct Layer {
    pub inputs: Vec<Input>,
    pub n_out: usize,
    pub relu: bool,
    pub matrix: Vec<f32>,
    pub bias: Vec<f32>,
}

/// A network: layers in order; its output is the last layer's activation.
#[derive(Clone, Debug)]
pub(crate) struct Network {
    pub n_in: usize,
    pub layers: Vec<Layer>,
}

/// How the weights reach the shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Literals in unrolled code: no buffer to bind; for small networks.
    Inline,
    /// One `array<f32>` storage buffer at `@group(group) @binding(binding)`, filled with
    /// [`crate::Shader::weights`]; the networks run as loops over it.
    Buffer {
        /// Bind group.
        group: u32,
        /// Binding in the group.
        binding: u32,
    },
}

impl Network {
    /// The network of a `.nbrdf` file's [`NetDesc`] over its weights in file order (`docs/models.md`).
    pub fn from_desc(d: &NetDesc, w: &[f32]) -> Network {
        let (n_in, width) = (d.n_in as usize, d.width as usize);
        let mut layers = Vec::new();
        let mut off = 0;
        for l in 0..d.n_layers() {
            let (rows, n_out) = (d.layer_inputs(l), d.layer_outputs(l));
            let inputs = if l == 0 {
                vec![Input::X]
            } else if l < d.hidden as usize && d.skip != 0 && l == d.skip as usize {
                vec![Input::H, Input::X]
            } else {
                vec![Input::H]
            };
            let matrix = w[off..off + rows * n_out].to_vec();
            let bias = w[off + rows * n_out..off + (rows + 1) * n_out].to_vec();
            off += (rows + 1) * n_out;
            layers.push(Layer { inputs, n_out, relu: l < d.hidden as usize, matrix, bias });
        }
        debug_assert_eq!(layers.iter().map(|l| l.matrix.len() + l.bias.len()).sum::<usize>(), d.n_weights());
        let _ = width;
        Network { n_in, layers }
    }

    /// Number of values the network returns.
    pub fn n_out(&self) -> usize {
        self.layers.last().map_or(0, |l| l.n_out)
    }

    /// Weights and biases, all layers.
    pub fn n_weights(&self) -> usize {
        self.layers.iter().map(|l| l.matrix.len() + l.bias.len()).sum()
    }

    /// Multiply-adds of one evaluation.
    pub fn macs(&self) -> usize {
        self.layers.iter().map(|l| l.matrix.len()).sum()
    }

    /// The rows of a layer: the length of each input segment.
    fn segment_len(&self, layer: usize, input: Input) -> usize {
        match input {
            Input::X => self.n_in,
            Input::H => self.layers[layer - 1].n_out,
        }
    }

    /// The weights in the buffer layout (per layer the matrix then the bias), appended to `buf`;
    /// returns where they start.
    pub fn append_weights(&self, buf: &mut Vec<f32>) -> usize {
        let start = buf.len();
        for l in &self.layers {
            buf.extend_from_slice(&l.matrix);
            buf.extend_from_slice(&l.bias);
        }
        start
    }
}

/// A float literal that parses to exactly `w` (the `f` suffix makes naga read it as an f32).
pub(crate) fn lit(w: f32) -> String {
    format!("{w:?}f")
}

/// Writes `fn name(x: array<f32, n_in>) -> array<f32, n_out>` (no parameter when `n_in = 0`).
/// `offset` is where the network's weights start in the storage buffer (`Storage::Buffer`).
pub(crate) fn emit(out: &mut String, name: &str, net: &Network, storage: Storage, offset: usize) {
    let params = if net.n_in > 0 { format!("x_in: array<f32, {}>", net.n_in) } else { String::new() };
    let _ = writeln!(out, "fn {name}({params}) -> array<f32, {}> {{", net.n_out());
    match storage {
        Storage::Inline => emit_inline(out, net),
        Storage::Buffer { .. } => emit_loops(out, net, offset),
    }
    out.push_str("}\n\n");
}

/// Terms per statement of an unrolled sum: short expressions for every backend's parser.
const TERMS_PER_LINE: usize = 16;

fn emit_inline(out: &mut String, net: &Network) {
    for (l, layer) in net.layers.iter().enumerate() {
        for o in 0..layer.n_out {
            let acc = format!("s{l}_{o}");
            let _ = write!(out, "    var {acc} = {}", lit(layer.bias[o]));
            let mut row = 0;
            let mut terms = 0;
            for &input in &layer.inputs {
                for i in 0..net.segment_len(l, input) {
                    let w = layer.matrix[row * layer.n_out + o];
                    row += 1;
                    // A zero weight adds nothing but a rounding-free 0: leave it out.
                    if w == 0.0 {
                        continue;
                    }
                    if terms > 0 && terms % TERMS_PER_LINE == 0 {
                        let _ = write!(out, ";\n    {acc} = {acc}");
                    }
                    let x = match input {
                        Input::X => format!("x_in[{i}]"),
                        Input::H => format!("h{}_{i}", l - 1),
                    };
                    let _ = write!(out, " + {x} * {}", lit(w));
                    terms += 1;
                }
            }
            if layer.relu {
                let _ = writeln!(out, ";\n    let h{l}_{o} = max({acc}, 0.0);");
            } else {
                let _ = writeln!(out, ";\n    let h{l}_{o} = {acc};");
            }
        }
    }
    let last = net.layers.len() - 1;
    let values: Vec<String> = (0..net.n_out()).map(|o| format!("h{last}_{o}")).collect();
    let _ = writeln!(out, "    return array<f32, {}>({});", net.n_out(), values.join(", "));
}

/// One loop per layer over its outputs, each output's dot product written out in input order: Mesa's
/// llvmpipe (lavapipe) ends every loop of an invocation once 65 535 iterations have run in all
/// (`LP_MAX_TGSI_LOOP_ITERATIONS`), which an inner loop per weight row passed at width 128.
fn emit_loops(out: &mut String, net: &Network, offset: usize) {
    let width = net.layers.iter().map(|l| l.n_out).max().unwrap_or(1).max(1);
    if net.n_in > 0 {
        out.push_str("    let x = x_in;\n");
    }
    let _ = writeln!(out, "    var h: array<f32, {width}>;\n    var t: array<f32, {width}>;");
    let mut off = offset;
    for (l, layer) in net.layers.iter().enumerate() {
        let rows: usize = layer.inputs.iter().map(|&i| net.segment_len(l, i)).sum();
        let n = layer.n_out;
        let _ = writeln!(out, "    for (var o = 0u; o < {n}u; o++) {{");
        let _ = write!(out, "        var s = nbrdf_weights[{}u + o]", off + rows * n);
        let mut row = 0;
        let mut terms = 0;
        for &input in &layer.inputs {
            let src = if input == Input::X { "x" } else { "h" };
            for i in 0..net.segment_len(l, input) {
                if terms == TERMS_PER_LINE {
                    out.push_str(";\n        s = s");
                    terms = 0;
                }
                let _ = write!(out, " + {src}[{i}] * nbrdf_weights[{}u + o]", off + (row + i) * n);
                terms += 1;
            }
            row += net.segment_len(l, input);
        }
        let value = if layer.relu { "max(s, 0.0)" } else { "s" };
        let _ = writeln!(out, ";\n        t[o] = {value};\n    }}\n    h = t;");
        off += (rows + 1) * n;
    }
    let n = net.n_out();
    let _ = writeln!(out, "    var y: array<f32, {n}>;\n    for (var o = 0u; o < {n}u; o++) {{\n        y[o] = h[o];\n    }}\n    return y;");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_network_splits_into_its_layers_with_the_skip_layer_reading_h_then_x() {
        let d = NetDesc { n_in: 5, width: 4, hidden: 3, n_out: 2, skip: 1 };
        let w: Vec<f32> = (0..d.n_weights()).map(|i| i as f32).collect();
        let net = Network::from_desc(&d, &w);
        assert_eq!(net.layers.len(), 4);
        assert_eq!(net.layers[1].inputs, [Input::H, Input::X]);
        assert_eq!(net.layers[1].matrix.len(), (4 + 5) * 4);
        assert!(!net.layers[3].relu && net.layers[2].relu);
        assert_eq!(net.n_weights(), d.n_weights());
        let mut buf = vec![];
        net.append_weights(&mut buf);
        assert_eq!(buf, w, "the buffer layout is the file's");
    }

    #[test]
    fn literals_read_back_as_the_same_f32() {
        for w in [0.1f32, -1e-7, 3.4028235e38, 1.0, -0.0, f32::MIN_POSITIVE] {
            let s = lit(w);
            assert_eq!(s.trim_end_matches('f').parse::<f32>().unwrap().to_bits(), w.to_bits(), "{s}");
        }
    }
}
