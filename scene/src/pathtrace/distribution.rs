//! Piecewise-constant distributions in one and two dimensions, sampled by inverting their CDFs
//! (pbrt-v4, Sec. A.5.2 "Piecewise-Constant 1D Functions" and A.5.6 "2D functions"): what the
//! environment light samples its lat-long map with.

use std::vec::Vec;

/// A piecewise-constant density on [0, 1) with `n` equal cells.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// The density proportional to `func` (negative or non-finite entries count as 0). An all-zero
    /// function gets the uniform density, as in pbrt, so that sampling stays defined.
    pub fn new(func: &[f32]) -> Self {
        let n = func.len().max(1);
        let mut func: Vec<f32> = func.iter().map(|&f| if f.is_finite() && f > 0.0 { f } else { 0.0 }).collect();
        func.resize(n, 0.0);
        let mut cdf = Vec::with_capacity(n + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for f in &func {
            acc += *f as f64 / n as f64;
            cdf.push(acc as f32);
        }
        let integral = acc as f32;
        if integral > 0.0 {
            cdf.iter_mut().for_each(|c| *c /= integral);
        } else {
            func.iter_mut().for_each(|f| *f = 1.0);
            cdf.iter_mut().enumerate().for_each(|(i, c)| *c = i as f32 / n as f32);
        }
        *cdf.last_mut().unwrap() = 1.0;
        Distribution1D { integral: if integral > 0.0 { integral } else { 1.0 }, func, cdf }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Whether there are no cells (never: `new` makes at least one).
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫ func` over [0, 1) (1 for the uniform fallback).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// `x ∈ [0, 1)` with density [`Distribution1D::pdf`], and its cell.
    pub fn sample(&self, u: f32) -> (f32, usize) {
        // The last cell whose CDF start is ≤ u, skipping zero-width cells.
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(self.func.len() - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 { (u - self.cdf[i]) / width } else { 0.5 };
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / self.func.len() as f32).min(1.0 - f32::EPSILON);
        (x, i)
    }

    /// Density of `x` (of its cell), `func(x) / ∫ func`.
    pub fn pdf(&self, x: f32) -> f32 {
        self.func[self.cell(x)] / self.integral
    }

    /// The cell holding `x`, clamped into range.
    #[inline]
    pub fn cell(&self, x: f32) -> usize {
        ((x * self.func.len() as f32) as isize).clamp(0, self.func.len() as isize - 1) as usize
    }
}

/// A piecewise-constant density on [0, 1)² over a `width × height` grid, sampled as a marginal over
/// rows and a conditional within the row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The density proportional to `func` (`height` rows of `width` values, row-major).
    pub fn new(func: &[f32], width: usize, height: usize) -> Self {
        let rows: Vec<Distribution1D> =
            (0..height).map(|r| Distribution1D::new(&func[r * width..(r + 1) * width])).collect();
        let row_mass: Vec<f32> = (0..height)
            .map(|r| func[r * width..(r + 1) * width].iter().filter(|f| f.is_finite() && **f > 0.0).sum::<f32>() / width as f32)
            .collect();
        Distribution2D { marginal: Distribution1D::new(&row_mass), rows }
    }

    /// `(x, y)` in [0, 1)² with density [`Distribution2D::pdf`].
    pub fn sample(&self, u: [f32; 2]) -> [f32; 2] {
        let (y, r) = self.marginal.sample(u[1]);
        let (x, _) = self.rows[r].sample(u[0]);
        [x, y]
    }

    /// Density at `(x, y)`: marginal times conditional.
    pub fn pdf(&self, p: [f32; 2]) -> f32 {
        let r = self.marginal.cell(p[1]);
        self.marginal.pdf(p[1]) * self.rows[r].pdf(p[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_land_in_cells_in_proportion() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        assert_eq!(d.sample(0.1).1, 0);
        assert_eq!(d.sample(0.3).1, 2); // the zero cell is never chosen
        assert!((d.pdf(0.9) - 3.0 / (4.0 / 3.0)).abs() < 1e-6);
        // Inverting the CDF: u = 0.25 + 0.75 t maps to the start + t of the last cell.
        assert!((d.sample(0.625).0 - (2.0 + 0.5) / 3.0).abs() < 1e-6);
    }

    #[test]
    fn two_d_pdf_integrates_to_one() {
        let f = [1.0, 2.0, 0.0, 4.0, 0.5, 0.5];
        let d = Distribution2D::new(&f, 3, 2);
        let mut s = 0.0;
        for r in 0..2 {
            for c in 0..3 {
                s += d.pdf([(c as f32 + 0.5) / 3.0, (r as f32 + 0.5) / 2.0]) / 6.0;
            }
        }
        assert!((s - 1.0).abs() < 1e-6);
    }
}
