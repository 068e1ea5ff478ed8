//! Violation of Helmholtz reciprocity (paper Eq. 3, Sec. 6 "Reciprocity Mapping", Tab. 3): the RMSE
//! between `f(x, l, v)` and `f(x, v, l)` over the test pairs. Parametric models and the paper's
//! reciprocal input mapping give 0 by construction; plain neural models do not.

use nbrdf::{Rgb, Vec3};
use rayon::prelude::*;

/// One test pair: a surface point (an index the closure understands) and two local-frame directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionPair {
    /// Index of the surface point `x` (its position/latent code is the closure's business).
    pub point: usize,
    /// Direction toward the light `l`, local frame, unit.
    pub wi: Vec3,
    /// Direction toward the viewer `v`, local frame, unit.
    pub wo: Vec3,
}

/// `sqrt(mean over pairs and channels of (f(x, wi, wo) - f(x, wo, wi))²)` (paper Sec. 6: "the RMSE
/// between the BRDF values with changed positions"), in the BRDF's own units (1/sr), not scaled. `f` is
/// called as `f(point, wi, wo)`, in parallel. NaN for no pairs.
///
/// ```
/// use nbrdf::{parametric::Phong, Vec3};
/// use trainer::metrics::reciprocity::{reciprocity_rmse, DirectionPair};
/// let rp = Phong { kd: [0.2; 3], ks: [0.5; 3], n: 30.0 };
/// let pairs = [DirectionPair { point: 0, wi: Vec3::new(0.6, 0.0, 0.8), wo: Vec3::new(0.0, 0.28, 0.96) }];
/// assert_eq!(reciprocity_rmse(&pairs, |_, wi, wo| rp.eval(wi, wo)), 0.0); // symmetric by construction
/// ```
pub fn reciprocity_rmse<F>(pairs: &[DirectionPair], f: F) -> f64
where
    F: Fn(usize, Vec3, Vec3) -> Rgb + Sync,
{
    if pairs.is_empty() {
        return f64::NAN;
    }
    let sum: f64 = pairs
        .par_iter()
        .map(|p| {
            let a = f(p.point, p.wi, p.wo);
            let b = f(p.point, p.wo, p.wi);
            (0..3).map(|c| (f64::from(a[c]) - f64::from(b[c])).powi(2)).sum::<f64>()
        })
        .sum();
    (sum / (3 * pairs.len()) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_violation() {
        // f depends on the light direction only: f = cos θ_i in every channel, so swapping changes the
        // value by wi.z - wo.z: 1 - 0 for the first pair, 0 for the second. RMSE = sqrt(1/2).
        let pairs = [
            DirectionPair { point: 0, wi: Vec3::Z, wo: Vec3::X },
            DirectionPair { point: 1, wi: Vec3::new(0.6, 0.0, 0.8), wo: Vec3::new(0.0, 0.6, 0.8) },
        ];
        let value = reciprocity_rmse(&pairs, |_, wi, _| [wi.z; 3]);
        assert!((value - 0.5f64.sqrt()).abs() < 1e-7, "{value}");
        // The point index reaches the closure: a point-dependent but symmetric f has no violation.
        let sym = reciprocity_rmse(&pairs, |x, wi, wo| [x as f32 * wi.z * wo.z; 3]);
        assert_eq!(sym, 0.0);
        assert!(reciprocity_rmse(&[], |_, _, _| [0.0; 3]).is_nan());
    }
}
