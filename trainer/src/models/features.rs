//! Network inputs of a batch: the angle map of the direction pair (Rusinkiewicz or Θ, with LitNeRF's
//! random swap in training) and the positional encodings, computed on the CPU once per batch; they
//! carry no gradient.

use candle_core::{Device, Result, Tensor};
use nbrdf::{angles, Vec3};
use rayon::prelude::*;

use super::arch::{Config, PositionEncoding, Reciprocity};

/// Positional encoding `PE(v, F)` of Mildenhall et al. 2020 (docs/models.md): per value
/// `[v, sin(2^0 v), cos(2^0 v), …, sin(2^(F-1) v), cos(2^(F-1) v)]`, appended to `out`. It calls the
/// core's [`nbrdf::encoding::positional_encoding`], so both sides feed the networks bitwise the same.
pub fn positional_encoding(values: &[f32], frequencies: u8, out: &mut Vec<f32>) {
    let start = out.len();
    let len = nbrdf::encoding::encoded_len(values.len(), frequencies as usize);
    out.resize(start + len, 0.0);
    nbrdf::encoding::positional_encoding(values, frequencies as usize, &mut out[start..]);
}

/// The angle input of one pair before encoding (docs/models.md "Angle input"), or `None` for a pair the
/// core evaluates to 0 (below the horizon, degenerate).
pub fn angle_input(reciprocity: Reciprocity, wi: Vec3, wo: Vec3) -> Option<Vec<f32>> {
    let (wi, wo) = angles::upper_hemisphere_pair(wi, wo)?;
    match reciprocity {
        Reciprocity::None | Reciprocity::Swap => angles::rusinkiewicz_angles(wi, wo).map(|a| a.to_vec()),
        Reciprocity::Exact => angles::theta_map(wi, wo).map(|a| a.to_vec()),
    }
}

/// One batch of network inputs (all `[N, ·]`, f32).
pub struct Inputs {
    /// `[N, P]`: the encoded position `p` (empty for uniform materials).
    pub position: Tensor,
    /// `[N, A]`: `PE(a, F_a)`.
    pub angles: Tensor,
    /// `[N, P + A]`: `[p, PE(a)]`, the input of networks that see both.
    pub joint: Tensor,
    /// `[N, 1]` of ones, the bias input.
    pub ones: Tensor,
    /// `[N, 1]`: 1 for a valid direction pair, 0 where the core returns black.
    pub valid: Tensor,
    /// The (possibly swapped) direction pairs `[wi, wo]`, for the parametric models.
    pub pairs: std::sync::Arc<Vec<[Vec3; 2]>>,
    pub n: usize,
}

/// Raw per-sample inputs: position values as the caller passes them (`n_raw` per row) and the pair.
pub struct RawBatch<'a> {
    /// Row-major `[N, config.position.input_len()]`.
    pub position: &'a [f32],
    pub wi: &'a [Vec3],
    pub wo: &'a [Vec3],
    /// Per sample: exchange `wi` and `wo` before the angle map (LitNeRF; only with `Reciprocity::Swap`).
    pub swap: Option<&'a [bool]>,
}

/// One block of encoded samples (see [`Inputs::build`]).
struct Encoded {
    pos: Vec<f32>,
    ang: Vec<f32>,
    joint: Vec<f32>,
    valid: Vec<f32>,
    pairs: Vec<[Vec3; 2]>,
}

impl Inputs {
    /// Encodes a batch for `config`.
    pub fn build(config: &Config, raw: &RawBatch, device: &Device) -> Result<Inputs> {
        let n = raw.wi.len();
        let n_raw = config.position.input_len();
        if raw.wo.len() != n || raw.position.len() != n * n_raw {
            candle_core::bail!(
                "batch sizes disagree: {} wi, {} wo, {} position values for {} per sample",
                n,
                raw.wo.len(),
                raw.position.len(),
                n_raw
            );
        }
        let p = config.position.encoded_len();
        let a = config.n_angle_features();
        // Blocks of samples encoded in parallel (the angle map and the sines of PE are a visible
        // share of a step on one core), then joined in order.
        const BLOCK: usize = 2048;
        let blocks: Vec<Encoded> = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .map(|b| {
                let samples = b * BLOCK..((b + 1) * BLOCK).min(n);
                let m = samples.len();
                let mut e = Encoded {
                    pos: Vec::with_capacity(m * p),
                    ang: Vec::with_capacity(m * a),
                    joint: Vec::with_capacity(m * (p + a)),
                    valid: Vec::with_capacity(m),
                    pairs: Vec::with_capacity(m),
                };
                let zeros = vec![0.0f32; config.n_angles()];
                for s in samples {
                    let row = &raw.position[s * n_raw..(s + 1) * n_raw];
                    let start = e.pos.len();
                    match config.position {
                        PositionEncoding::Extrinsic { frequencies } => positional_encoding(row, frequencies, &mut e.pos),
                        _ => e.pos.extend_from_slice(row),
                    }
                    let swap = config.reciprocity == Reciprocity::Swap && raw.swap.is_some_and(|m| m[s]);
                    let (wi, wo) = if swap { (raw.wo[s], raw.wi[s]) } else { (raw.wi[s], raw.wo[s]) };
                    let input = angle_input(config.reciprocity, wi, wo);
                    e.valid.push(if input.is_some() { 1.0f32 } else { 0.0 });
                    let start_a = e.ang.len();
                    positional_encoding(input.as_deref().unwrap_or(&zeros), config.angle_frequencies, &mut e.ang);
                    e.joint.extend_from_slice(&e.pos[start..]);
                    e.joint.extend_from_slice(&e.ang[start_a..]);
                    e.pairs.push([wi, wo]);
                }
                e
            })
            .collect();
        let (mut pos, mut ang, mut joint) =
            (Vec::with_capacity(n * p), Vec::with_capacity(n * a), Vec::with_capacity(n * (p + a)));
        let mut valid = Vec::with_capacity(n);
        let mut pairs = Vec::with_capacity(n);
        for e in blocks {
            pos.extend(e.pos);
            ang.extend(e.ang);
            joint.extend(e.joint);
            valid.extend(e.valid);
            pairs.extend(e.pairs);
        }
        Ok(Inputs {
            position: Tensor::from_vec(pos, (n, p), device)?,
            angles: Tensor::from_vec(ang, (n, a), device)?,
            joint: Tensor::from_vec(joint, (n, p + a), device)?,
            ones: super::mlp::ones(n, device)?,
            valid: Tensor::from_vec(valid, (n, 1), device)?,
            pairs: std::sync::Arc::new(pairs),
            n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `PE(v, 0)` is the identity and each octave adds one sin/cos pair.
    #[test]
    fn positional_encoding_layout() {
        let mut out = Vec::new();
        positional_encoding(&[0.5, -1.0], 2, &mut out);
        assert_eq!(out.len(), 2 * 5);
        assert_eq!(out[0], 0.5);
        assert!((out[1] - 0.5f32.sin()).abs() < 1e-7);
        assert!((out[4] - 1.0f32.cos()).abs() < 1e-7);
        assert_eq!(out[5], -1.0);
        let mut id = Vec::new();
        positional_encoding(&[0.25], 0, &mut id);
        assert_eq!(id, vec![0.25]);
    }

    /// Θ is the same for both orders of a pair, so the exact variant's input is swap-invariant.
    #[test]
    fn exact_angle_input_is_symmetric() {
        let wi = Vec3::new(0.3, -0.4, 0.8).normalize();
        let wo = Vec3::new(-0.5, 0.1, 0.7).normalize();
        assert_eq!(angle_input(Reciprocity::Exact, wi, wo), angle_input(Reciprocity::Exact, wo, wi));
        assert_ne!(angle_input(Reciprocity::None, wi, wo), angle_input(Reciprocity::None, wo, wi));
        assert_eq!(angle_input(Reciprocity::None, wi, -wo), None, "below the horizon");
    }

    /// LitNeRF's swap: a flagged sample sees the angles of `(wo, wi)`, an unflagged one `(wi, wo)`.
    #[test]
    fn swap_exchanges_flagged_pairs_only() {
        let c = Config::paper(
            crate::models::Kind::SingleMlp,
            false,
            Reciprocity::Swap,
            PositionEncoding::Uniform,
        );
        let wi = [Vec3::new(0.3, -0.4, 0.8).normalize(); 2];
        let wo = [Vec3::new(-0.5, 0.1, 0.7).normalize(); 2];
        let raw = RawBatch { position: &[], wi: &wi, wo: &wo, swap: Some(&[false, true]) };
        let x = Inputs::build(&c, &raw, &Device::Cpu).unwrap();
        let a = x.angles.to_vec2::<f32>().unwrap();
        let mut plain = Vec::new();
        positional_encoding(&angle_input(Reciprocity::None, wi[0], wo[0]).unwrap(), c.angle_frequencies, &mut plain);
        let mut swapped = Vec::new();
        positional_encoding(&angle_input(Reciprocity::None, wo[0], wi[0]).unwrap(), c.angle_frequencies, &mut swapped);
        assert_eq!(a[0], plain);
        assert_eq!(a[1], swapped);
        assert_ne!(plain, swapped);
    }
}
