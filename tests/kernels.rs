//! The tiny-network kernels (`nbrdf::kernels::TinyNet`, the NBRDF-json evaluator) against a plain
//! scalar f64 reference on random networks and inputs, at every kernel level this CPU has, including
//! pre-activations that are exactly zero at the ReLU; and single queries against packets, bit for bit.

use nbrdf::kernels::{detected, set_level, Level, TinyLayer, TinyNet, TINY_INPUTS, TINY_PACKET};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }
}

/// A network of the given widths laid out as `TinyLayer` documents: weights dyadic (multiples of 1/64)
/// and inputs dyadic, so that the first layer's pre-activations are exact; the bias of every third
/// output of the first layer is chosen to make its pre-activation at `zero_at` exactly 0.
fn network(widths: &[usize], rng: &mut Rng, zero_at: &[f32; TINY_INPUTS]) -> (Vec<TinyLayer>, Vec<f32>) {
    let mut layers = Vec::new();
    let mut params = Vec::new();
    let mut x: Vec<f64> = zero_at.iter().map(|v| *v as f64).collect();
    for (l, w) in widths.windows(2).enumerate() {
        let (n_in, n_out) = (w[0], w[1]);
        let padded = n_out.div_ceil(8) * 8;
        let offset = params.len();
        params.resize(offset + (n_in + 1) * padded, 0.0);
        let mut y = vec![0.0f64; n_out];
        for o in 0..n_out {
            let mut s = 0.0f64;
            for i in 0..n_in {
                let v = (rng.next() * 64.0).round() / 64.0;
                params[offset + i * padded + o] = v;
                s += v as f64 * x[i];
            }
            let b = if l == 0 && o % 3 == 1 { -s as f32 } else { (rng.next() * 16.0).round() / 64.0 };
            assert!(b as f64 == -s || !(l == 0 && o % 3 == 1), "the zero bias is exact");
            params[offset + n_in * padded + o] = b;
            let relu = l + 2 < widths.len();
            y[o] = if relu { (s + b as f64).max(0.0) } else { s + b as f64 };
        }
        layers.push(TinyLayer { inputs: n_in, outputs: n_out, padded, offset, relu: l + 2 < widths.len() });
        x = y;
    }
    (layers, params)
}

fn reference(layers: &[TinyLayer], params: &[f32], input: &[f32; TINY_INPUTS]) -> [f64; 3] {
    let mut x: Vec<f64> = input.iter().map(|v| *v as f64).collect();
    for l in layers {
        x = (0..l.outputs)
            .map(|o| {
                let mut s = params[l.offset + l.inputs * l.padded + o] as f64;
                for (i, xi) in x.iter().enumerate() {
                    s += xi * params[l.offset + i * l.padded + o] as f64;
                }
                if l.relu { s.max(0.0) } else { s }
            })
            .collect();
    }
    [x[0].exp_m1(), x[1].exp_m1(), x[2].exp_m1()]
}

#[test]
fn tiny_networks_match_a_scalar_reference_and_packets_match_single_queries() {
    let mut rng = Rng(0x2545f4914f6cdd1d);
    for widths in [&[6, 21, 21, 3][..], &[6, 3], &[6, 8, 3], &[6, 64, 17, 40, 3], &[6, 2, 3], &[6, 33, 3]] {
        // Dyadic inputs: the first one makes some pre-activations exactly zero.
        let inputs: Vec<[f32; TINY_INPUTS]> = (0..TINY_PACKET * 3)
            .map(|_| std::array::from_fn(|_| (rng.next() * 64.0).round() / 32.0))
            .collect();
        let (layers, params) = network(widths, &mut rng, &inputs[0]);
        let net = TinyNet { layers: &layers, params: &params };
        for level in Level::ALL.into_iter().filter(|l| *l <= detected()) {
            set_level(Some(level));
            for chunk in inputs.chunks(TINY_PACKET) {
                let x: [[f32; TINY_PACKET]; TINY_INPUTS] = std::array::from_fn(|f| std::array::from_fn(|q| chunk[q][f]));
                let mut packet = [[f32::NAN; TINY_PACKET]; 3];
                net.packet(&x, &mut packet);
                for (q, input) in chunk.iter().enumerate() {
                    let got = net.one(input);
                    // The clamped output is `sanitize` of the plain one, bit for bit, at every level.
                    assert_eq!(net.brdf(input).map(f32::to_bits), nbrdf::math::sanitize(got).map(f32::to_bits));
                    let want = reference(&layers, &params, input);
                    for c in 0..3 {
                        assert_eq!(got[c].to_bits(), packet[c][q].to_bits(), "{level:?} {widths:?}: single vs packet");
                        let tol = 1e-5 * want[c].abs().max(0.05);
                        assert!((got[c] as f64 - want[c]).abs() <= tol, "{level:?} {widths:?} q {q} c {c}: {} vs {}", got[c], want[c]);
                    }
                }
            }
        }
        set_level(None);
    }
}
