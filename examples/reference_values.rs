//! Writes reference values of BRDFs through the Rust API, for bindings to compare with bit for bit
//! (the Python package's tests, `python/tests/test_values.py`): deterministic direction pairs,
//! uniform numbers and point inputs, then each BRDF's `eval`, `pdf` and `sample` results.
//!
//! ```text
//! cargo run --example reference_values -- OUT.bin N SPEC...
//! ```
//!
//! `SPEC` is `model:FILE.nbrdf`, `json:FILE.json`, `merl:FILE.binary`, `builtin:ID`, or
//! `KIND:V,...` with the parameters of a parametric model in natural units (`lambert:R,G,B`,
//! `phong:KD×3,KS×3,N`, `torrance-sparrow:KD×3,KS×3,ALPHA`, `fmbrdf:RHO×3,KS,ALPHA,BETA,ETA,NORM`,
//! `disney:` its 12 values). `OUT.bin` is little-endian: `u32 N`, then per spec `u32 k` (its
//! `position_len`) and the f32 arrays `wi[N×3] wo[N×3] u[N×3] points[N×k] eval[N×3] pdf[N]
//! sample_wi[N×3] sample_weight[N×3] sample_pdf[N] eval_at_point0[N×3]`: every query at its own
//! point, `eval_at_point0` every pair at point 0. A row whose sample produced no direction is zeros.

use std::io::Write;
use std::process::ExitCode;

use nbrdf::builtin::Builtin;
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, Phong, TorranceSparrow};
use nbrdf::{Brdf, ModelBuf, Vec3};

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

/// A BRDF named by a spec, and the model file for point inputs.
enum Source {
    Fixed(Box<dyn Brdf>),
    Model(ModelBuf),
}

fn floats(s: &str, n: usize) -> Result<Vec<f32>, String> {
    let v: Vec<f32> = s.split(',').map(|x| x.trim().parse::<f32>().map_err(|e| format!("`{x}`: {e}"))).collect::<Result<_, _>>()?;
    if v.len() == n { Ok(v) } else { Err(format!("expected {n} numbers, got {}", v.len())) }
}

fn source(spec: &str) -> Result<Source, String> {
    let (kind, rest) = spec.split_once(':').ok_or(format!("`{spec}`: expected KIND:ARGS"))?;
    let rgb = |v: &[f32]| [v[0], v[1], v[2]];
    let fixed = |b: Parametric| Ok(Source::Fixed(Box::new(b)));
    let e = |e: nbrdf::Error| e.to_string();
    match kind {
        "model" => Ok(Source::Model(ModelBuf::load(rest).map_err(e)?)),
        "json" => Ok(Source::Fixed(Box::new(NbrdfNetwork::load(rest).map_err(e)?))),
        "merl" => Ok(Source::Fixed(Box::new(MerlTable::read(rest).map_err(e)?))),
        "builtin" => Ok(Source::Fixed(Box::new(Builtin::from_id(rest).ok_or(format!("unknown built-in `{rest}`"))?))),
        "lambert" => fixed(Parametric::Lambert(Lambert { kd: rgb(&floats(rest, 3)?) })),
        "phong" => {
            let v = floats(rest, 7)?;
            fixed(Parametric::Phong(Phong::new(rgb(&v), rgb(&v[3..]), v[6]).map_err(e)?))
        }
        "torrance-sparrow" => {
            let v = floats(rest, 7)?;
            fixed(Parametric::TorranceSparrow(TorranceSparrow { kd: rgb(&v), ks: rgb(&v[3..]), alpha: v[6] }))
        }
        "fmbrdf" => {
            let v = floats(rest, 8)?;
            let p = FresnelMicrofacet { rho: rgb(&v), ks: v[3], alpha: v[4], beta: v[5], eta: v[6], norm: v[7] };
            fixed(Parametric::FresnelMicrofacet(p))
        }
        "disney" => {
            let v = floats(rest, 12)?;
            fixed(Parametric::Disney(Disney {
                base_color: rgb(&v),
                subsurface: v[3],
                metallic: v[4],
                specular: v[5],
                specular_tint: v[6],
                roughness: v[7],
                sheen: v[8],
                sheen_tint: v[9],
                clearcoat: v[10],
                clearcoat_gloss: v[11],
            }))
        }
        _ => Err(format!("`{spec}`: unknown kind `{kind}`")),
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
        let src = source(spec)?;
        let mut rng = Rng(0x5EED + s as u64);
        let wi: Vec<Vec3> = (0..n).map(|i| rng.direction(i)).collect();
        let wo: Vec<Vec3> = (0..n).map(|i| rng.direction(i + 3)).collect();
        let u: Vec<[f32; 3]> = (0..n).map(|_| [rng.next(), rng.next(), rng.next()]).collect();
        let k = match &src {
            Source::Model(buf) => buf.model().position_len(),
            Source::Fixed(_) => 0,
        };
        // Points in [-1, 1]^k: the normalised mesh's box for an extrinsic encoding.
        let points: Vec<f32> = (0..n * k).map(|_| 2.0 * rng.next() - 1.0).collect();
        // The BRDF at query i's point, and at point 0.
        let at = |i: usize| -> Result<Box<dyn Brdf + '_>, String> {
            match &src {
                Source::Fixed(b) => Ok(Box::new(&**b)),
                Source::Model(buf) => Ok(Box::new(buf.model().at(&points[i * k..(i + 1) * k]).map_err(|e| e.to_string())?)),
            }
        };
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
