//! Writes reference values of BRDFs through the Rust API, for bindings to compare with bit for bit
//! (the Python package's tests, `python/tests/test_values.py`): deterministic direction pairs,
//! uniform numbers and point inputs, then each BRDF's `eval`, `pdf` and `sample` results.
//!
//! ```text
//! cargo run --example reference_values -- OUT.bin N SPEC...
//! ```
//!
//! `SPEC` is any spec of `nbrdf::any` (`model:FILE.nbrdf`, `json:FILE.json`, `merl:FILE.binary`,
//! `builtin:ID`, or `KIND:V,...` with the parameters of a parametric model in natural units). `OUT.bin` is little-endian: `u32 N`, then per spec `u32 k` (its
//! `position_len`) and the f32 arrays `wi[N×3] wo[N×3] u[N×3] points[N×k] eval[N×3] pdf[N]
//! sample_wi[N×3] sample_weight[N×3] sample_pdf[N] eval_at_point0[N×3]`: every query at its own
//! point, `eval_at_point0` every pair at point 0. A row whose sample produced no direction is zeros.

use std::io::Write;
use std::process::ExitCode;

use nbrdf::{AnyBrdf, Brdf, Vec3};

/// splitmix64 (Steele et al. 2014) as uniform f32 in [0, 1): the same stream on every platform.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A unit direction, mostly in the upper hemisphere: one in eight below it, one in eight grazing.
    fn direction(&mut self, i: usize) -> Vec3 {
        let z = match i % 8 {
            0 => -0.1 - 0.8 * self.next(),
            1 => 0.02 * self.next(),
            _ => 1.0 - self.next(),
        };
        let phi = std::f32::consts::TAU * self.next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

fn put(out: &mut Vec<u8>, values: impl IntoIterator<Item = f32>) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

fn run(args: &[String]) -> Result<(), String> {
    let [path, n, specs @ ..] = args else { return Err("usage: reference_values OUT.bin N SPEC...".into()) };
    let n: usize = n.parse().map_err(|e| format!("N: {e}"))?;
    let mut out = Vec::new();
    out.extend_from_slice(&(n as u32).to_le_bytes());
    for (s, spec) in specs.iter().enumerate() {
        let src = AnyBrdf::from_spec(spec).map_err(|e| e.to_string())?;
        let mut rng = Rng(0x5EED + s as u64);
        let wi: Vec<Vec3> = (0..n).map(|i| rng.direction(i)).collect();
        let wo: Vec<Vec3> = (0..n).map(|i| rng.direction(i + 3)).collect();
        let u: Vec<[f32; 3]> = (0..n).map(|_| [rng.next(), rng.next(), rng.next()]).collect();
        let k = src.position_len();
        // Points in [-1, 1]^k: the normalised mesh's box for an extrinsic encoding.
        let points: Vec<f32> = (0..n * k).map(|_| 2.0 * rng.next() - 1.0).collect();
        // The BRDF at query i's point, and at point 0.
        let at = |i: usize| src.at(&points[i * k..(i + 1) * k]).map_err(|e| e.to_string());
        let b0 = at(0)?;
        out.extend_from_slice(&(k as u32).to_le_bytes());
        put(&mut out, wi.iter().flat_map(|v| v.to_array()));
        put(&mut out, wo.iter().flat_map(|v| v.to_array()));
        put(&mut out, u.iter().flatten().copied());
        put(&mut out, points.iter().copied());
        let (mut eval, mut pdf, mut s_wi, mut s_weight, mut s_pdf, mut eval0) = (vec![], vec![], vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let b = at(i)?;
            eval.extend(b.eval(wi[i], wo[i]));
            pdf.push(b.pdf(wi[i], wo[i]));
            match b.sample(wo[i], u[i]) {
                Some(s) => {
                    s_wi.extend(s.wi.to_array());
                    s_weight.extend(s.weight);
                    s_pdf.push(s.pdf);
                }
                None => {
                    s_wi.extend([0.0; 3]);
                    s_weight.extend([0.0; 3]);
                    s_pdf.push(0.0);
                }
            }
            eval0.extend(b0.eval(wi[i], wo[i]));
        }
        for a in [eval, pdf, s_wi, s_weight, s_pdf, eval0] {
            put(&mut out, a);
        }
    }
    std::fs::File::create(path).and_then(|mut f| f.write_all(&out)).map_err(|e| format!("{path}: {e}"))
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
