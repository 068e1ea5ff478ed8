//! Energy conservation by construction: an upper bound `Â(θ)` of a BRDF's directional albedo, and the
//! bounded BRDF `f_b(wi, wo) = f(wi, wo) / max(1, Â(θi), Â(θo))` (per channel) whose albedo is ≤ 1
//! at every view where `Â` bounds the albedo, and which is reciprocal wherever `f` is.
//!
//! Why it holds (docs/models.md, "Energy bound"): with `A(wo) = ∫ f(wi, wo) cos θi dwi ≤ Â(θo)`,
//! `A_b(wo) = ∫ f / max(1, Â(θi), Â(θo)) cos θi dwi ≤ A(wo) / max(1, Â(θo)) ≤ 1`, since the divisor is
//! at least `max(1, Â(θo))` for every `wi`. The divisor depends on `wi` and `wo` through one symmetric
//! `max` of the same table, so a bitwise reciprocal `f` stays bitwise reciprocal; where the albedo is
//! ≤ 1 at both angles the divisor is 1 and `f` is returned unchanged, bit for bit.
//!
//! `Â` is a table over `cos θ` in [`ALBEDO_CELLS`] cells (as [`crate::sampling::ViewProxy`]'s: cell `j`
//! covers `cos θ ∈ (1 − (j+1)/N, 1 − j/N]`), each the largest of an albedo curve ([`albedo_curve`]) at
//! the cell's edges and middle, with a relative [`MARGIN`] and the quadrature's own error estimate
//! added ([`AlbedoCurve::upper`]); over several surface points of a spatially varying model, the
//! largest of their curves ([`AlbedoBound::envelope`]).
//!
//! ```
//! use nbrdf::energy::{albedo_curve, AlbedoBound};
//! use nbrdf::Vec3;
//! // A white Lambertian surface scaled by 1.2: albedo 1.2 at every view.
//! let f = |_: Vec3, _: Vec3| [1.2 / core::f32::consts::PI; 3];
//! let curve = albedo_curve(|wi: &[Vec3], wo: &[Vec3], out: &mut [[f32; 3]]| {
//!     out.iter_mut().zip(wi.iter().zip(wo)).for_each(|(o, (&a, &b))| *o = f(a, b))
//! });
//! assert!((curve.albedo[10][1] - 1.2).abs() < 1e-3);
//! let bound = AlbedoBound::envelope([curve]);
//! let (wi, wo) = (Vec3::new(0.3, 0.0, 0.9).normalize(), Vec3::new(-0.1, 0.5, 0.6).normalize());
//! let fb = bound.apply(f(wi, wo), wi.z, wo.z);
//! assert!(fb[0] * core::f32::consts::PI <= 1.0);      // the albedo of f_b is at most 1
//! assert_eq!(fb, bound.apply(f(wo, wi), wo.z, wi.z)); // and the divisor is symmetric
//! ```

use serde::{Deserialize, Serialize};

use crate::{Error, Rgb, Vec3};

/// Cells of the bound over `cos θ`.
pub const ALBEDO_CELLS: usize = 32;

/// Views of an [`AlbedoCurve`]: node `k` at `cos θo = 1 − k / (2N)`, so that cell `j` has nodes
/// `2j`, `2j + 1` and `2j + 2`.
pub const CURVE_NODES: usize = 2 * ALBEDO_CELLS + 1;

/// Relative allowance of [`AlbedoCurve::upper`] for the albedo's variation between nodes.
pub const MARGIN: f32 = 0.01;

/// `cos θo` of the last node, which stands for the grazing view (a view exactly in the tangent plane
/// evaluates to 0; the albedo's limit there is approached continuously).
const GRAZING: f32 = 1.0 / 1024.0;

/// Half-vector rows of the quadrature over `θh` (spaced as `t²`, dense near the normal where
/// specular peaks are) and columns over `φh`.
const ROWS: usize = 48;
const COLUMNS: usize = 96;

/// The conservative albedo table of a bounded model (module docs): per cell of `cos θ`, per channel.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct AlbedoBound {
    /// `Â` of cell `j`, `cos θ ∈ (1 − (j+1)/N, 1 − j/N]`, per channel.
    pub cells: [Rgb; ALBEDO_CELLS],
}

// Bitwise equality and hashing, as the sampling proxy's, for the `Eq + Hash` model header.
impl PartialEq for AlbedoBound {
    fn eq(&self, other: &Self) -> bool {
        self.cells.iter().flatten().zip(other.cells.iter().flatten()).all(|(a, b)| a.to_bits() == b.to_bits())
    }
}
impl Eq for AlbedoBound {}
impl core::hash::Hash for AlbedoBound {
    fn hash<H: core::hash::Hasher>(&self, state: &mut H) {
        self.cells.iter().flatten().for_each(|a| a.to_bits().hash(state))
    }
}

/// The cell of a direction with `cos θ = cos`.
#[inline]
fn cell(cos: f32) -> usize {
    (((1.0 - cos) * ALBEDO_CELLS as f32) as usize).min(ALBEDO_CELLS - 1)
}

impl AlbedoBound {
    /// Checks that every value is finite and non-negative.
    pub fn validate(&self) -> Result<(), Error> {
        match self.cells.iter().flatten().position(|a| !a.is_finite() || *a < 0.0) {
            Some(_) => Err(Error::InvalidValue { what: "albedo bound", reason: "values must be finite and non-negative" }),
            None => Ok(()),
        }
    }

    /// `Â(θ)` per channel for a direction with `cos θ = cos`.
    #[inline]
    pub fn at(&self, cos: f32) -> Rgb {
        self.cells[cell(cos)]
    }

    /// `f / max(1, Â(θi), Â(θo))` per channel, with `cos_i`, `cos_o` the cosines of the unit
    /// directions; `f` itself, bit for bit, in every channel where both bounds are at most 1.
    #[inline]
    pub fn apply(&self, f: Rgb, cos_i: f32, cos_o: f32) -> Rgb {
        let (a, b) = (self.at(cos_i), self.at(cos_o));
        core::array::from_fn(|c| {
            // `max` is commutative on numbers: the same divisor for (wi, wo) and (wo, wi).
            let d = a[c].max(b[c]);
            if d > 1.0 {
                f[c] / d
            } else {
                f[c]
            }
        })
    }

    /// The bound over all `curves` (surface points of one model): per cell and channel, the largest
    /// [`AlbedoCurve::upper`] at the cell's three nodes over every curve. No curves gives all zeros.
    pub fn envelope(curves: impl IntoIterator<Item = AlbedoCurve>) -> Self {
        let mut cells = [[0.0f32; 3]; ALBEDO_CELLS];
        for curve in curves {
            for (j, cell) in cells.iter_mut().enumerate() {
                for k in 2 * j..=2 * j + 2 {
                    let u = curve.upper(k);
                    (0..3).for_each(|c| cell[c] = cell[c].max(u[c]));
                }
            }
        }
        AlbedoBound { cells }
    }

    /// The largest value of the table over cells and channels: the model's largest albedo bound
    /// (at most 1 means the bound changes no value).
    pub fn max(&self) -> f32 {
        self.cells.iter().flatten().fold(0.0, |m, &a| m.max(a))
    }
}

/// A BRDF's directional albedo `A(θo) = ∫ f(wi, wo) cos θi dwi` at the [`CURVE_NODES`] views, per channel,
/// with an estimate of the quadrature's error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlbedoCurve {
    /// The albedo at node `k` (`cos θo = 1 − k/(2N)`, the last at a grazing `cos θo` of 1/1024).
    pub albedo: [Rgb; CURVE_NODES],
    /// `|A − A'|` with `A'` the same integral on every other row and column (a rule of a quarter of
    /// the points): an overestimate of the error of `A`.
    pub error: [Rgb; CURVE_NODES],
}

impl AlbedoCurve {
    /// The upper value the bound takes at node `k`: `A (1 + MARGIN) + error`.
    #[inline]
    pub fn upper(&self, k: usize) -> Rgb {
        core::array::from_fn(|c| self.albedo[k][c] * (1.0 + MARGIN) + self.error[k][c])
    }

    /// `cos θo` of node `k`.
    #[inline]
    pub fn node_cos(k: usize) -> f32 {
        (1.0 - k as f32 / (2 * ALBEDO_CELLS) as f32).max(GRAZING)
    }
}

/// The directional albedo of an isotropic BRDF at one view, `∫ f(wi, wo) cos θi dwi` per channel, and
/// the error estimate of [`AlbedoCurve::error`]. `eval(wi, wo, out)` evaluates a batch of pairs.
///
/// The integral runs over the half vector `h` (`wi = 2 (wo·h) h − wo`, `dwi = 4 (wo·h) dh`; Walter et
/// al. 2007, Eq. 14) on a product midpoint rule in `t = (2 θh / π)^(1/3)` and `φh`: the rows crowd toward
/// the normal, where an isotropic BRDF's specular peak lies at every view, and `wi` below the horizon
/// contributes 0.
pub fn albedo_at(cos_o: f32, mut eval: impl FnMut(&[Vec3], &[Vec3], &mut [Rgb])) -> (Rgb, Rgb) {
    let cos_o = cos_o.clamp(GRAZING, 1.0);
    let wo = Vec3::new(libm::sqrtf((1.0 - cos_o * cos_o).max(0.0)), 0.0, cos_o);
    let (mut fine, mut coarse) = ([0.0f64; 3], [0.0f64; 3]);
    let mut wi = [Vec3::Z; COLUMNS];
    let wos = [wo; COLUMNS];
    let mut weight = [0.0f64; COLUMNS];
    let mut out = [[0.0f32; 3]; COLUMNS];
    let dphi = 2.0 * core::f64::consts::PI / COLUMNS as f64;
    for row in 0..ROWS {
        // θh = (π/2) t³, dθh = (3π/2) t² dt.
        let t = (row as f64 + 0.5) / ROWS as f64;
        let theta_h = core::f64::consts::FRAC_PI_2 * t * t * t;
        let d_theta = 3.0 * core::f64::consts::FRAC_PI_2 * t * t / ROWS as f64;
        let (sin_h, cos_h) = (libm::sin(theta_h), libm::cos(theta_h));
        for (col, (w, q)) in wi.iter_mut().zip(weight.iter_mut()).enumerate() {
            let phi = (col as f64 + 0.5) * dphi;
            let h = [sin_h * libm::cos(phi), sin_h * libm::sin(phi), cos_h];
            let d = h[0] * wo.x as f64 + h[2] * wo.z as f64;
            let v = [2.0 * d * h[0] - wo.x as f64, 2.0 * d * h[1], 2.0 * d * h[2] - wo.z as f64];
            (*w, *q) = if d > 0.0 && v[2] > 0.0 {
                // f cos θi · 4 (wo·h) · sin θh dθh dφh.
                (Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32), v[2] * 4.0 * d * sin_h * d_theta * dphi)
            } else {
                (Vec3::Z, 0.0)
            };
        }
        eval(&wi, &wos, &mut out);
        for (col, (f, q)) in out.iter().zip(&weight).enumerate() {
            if *q == 0.0 {
                continue;
            }
            let keep = row % 2 == 0 && col % 2 == 0;
            for c in 0..3 {
                let v = if f[c].is_finite() { f[c] as f64 * q } else { 0.0 };
                fine[c] += v;
                if keep {
                    coarse[c] += 4.0 * v;
                }
            }
        }
    }
    (core::array::from_fn(|c| fine[c] as f32), core::array::from_fn(|c| (fine[c] - coarse[c]).abs() as f32))
}

/// [`albedo_at`] at every node of an [`AlbedoCurve`]: 65 views × 4608 evaluations.
pub fn albedo_curve(mut eval: impl FnMut(&[Vec3], &[Vec3], &mut [Rgb])) -> AlbedoCurve {
    let mut curve = AlbedoCurve { albedo: [[0.0; 3]; CURVE_NODES], error: [[0.0; 3]; CURVE_NODES] };
    for k in 0..CURVE_NODES {
        (curve.albedo[k], curve.error[k]) = albedo_at(AlbedoCurve::node_cos(k), &mut eval);
    }
    curve
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::Builtin;
    use crate::Brdf;

    fn batch<B: Brdf>(b: &B) -> impl FnMut(&[Vec3], &[Vec3], &mut [Rgb]) + '_ {
        move |wi, wo, out| out.iter_mut().zip(wi.iter().zip(wo)).for_each(|(o, (&a, &c))| *o = b.eval(a, c))
    }

    /// The quadrature integrates a Lambertian surface exactly enough at every view, grazing included.
    #[test]
    fn lambertian_albedo_is_its_reflectance() {
        let lambert = |_: Vec3, _: Vec3| [0.8 / core::f32::consts::PI; 3];
        let mut eval = |wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]| {
            out.iter_mut().zip(wi.iter().zip(wo)).for_each(|(o, (&a, &b))| *o = lambert(a, b))
        };
        for cos in [1.0, 0.7, 0.3, 0.05, 0.0] {
            let (a, e) = albedo_at(cos, &mut eval);
            assert!((a[0] - 0.8).abs() < 2e-3, "cos θo {cos}: albedo {a:?}");
            assert!(e[0] < 1e-2, "cos θo {cos}: error estimate {e:?}");
        }
    }

    /// A sharp metal's albedo from the half-vector rule agrees with its own importance sampler.
    #[test]
    fn specular_albedo_matches_importance_sampling() {
        let metal = Builtin::TwoLobeMetal;
        for cos in [0.9f32, 0.5, 0.15] {
            let (a, _) = albedo_at(cos, batch(&metal));
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let n: usize = 200_000;
            let mut sum = [0.0f64; 3];
            for i in 0..n {
                // The R3 low-discrepancy sequence (Roberts 2018).
                let r = |a: f64| ((i as f64 + 0.5) * a).fract() as f32;
                let u = [r(0.819_172_513_396_164_4), r(0.671_043_606_703_789_2), r(0.549_700_477_901_970_4)];
                if let Some(s) = metal.sample(wo, u) {
                    (0..3).for_each(|c| sum[c] += s.weight[c] as f64);
                }
            }
            for c in 0..3 {
                let mc = sum[c] / n as f64;
                assert!((a[c] as f64 - mc).abs() < 0.01 * mc.max(0.05), "cos θo {cos} channel {c}: quadrature {} vs sampled {mc}", a[c]);
            }
        }
    }

    /// The bound divides only where the table exceeds 1, and the same for either order of the pair.
    #[test]
    fn apply_is_symmetric_and_identity_below_one() {
        let mut cells = [[0.5f32; 3]; ALBEDO_CELLS];
        cells[3] = [1.25, 0.9, 2.0];
        let bound = AlbedoBound { cells };
        let f = [0.3, 0.2, 0.1];
        let cos_hot = 1.0 - 3.5 / ALBEDO_CELLS as f32;
        assert_eq!(bound.apply(f, 0.99, 0.98), f);
        assert_eq!(bound.apply(f, cos_hot, 0.98), [0.3 / 1.25, 0.2, 0.1 / 2.0]);
        assert_eq!(bound.apply(f, cos_hot, 0.98), bound.apply(f, 0.98, cos_hot));
    }

    #[test]
    fn validate_rejects_non_finite_and_negative_values() {
        let mut bound = AlbedoBound { cells: [[0.5; 3]; ALBEDO_CELLS] };
        assert!(bound.validate().is_ok());
        bound.cells[7][1] = f32::NAN;
        assert!(bound.validate().is_err());
        bound.cells[7][1] = -0.1;
        assert!(bound.validate().is_err());
    }
}
