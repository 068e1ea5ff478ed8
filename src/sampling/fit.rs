//! Fitting a sampling [`Proxy`] to a BRDF known only through evaluations: what the trainer calls at
//! export, and what a renderer calls once per measured material.
//!
//! The BRDF's luminance `y = lum(f)` is evaluated on a fixed set of direction pairs, and an analytic
//! model `m = k_d / π + Σ_k k_k f_GGX(α_k)` is fitted to it, where `f_GGX(α) = D(h) G2(wi, wo) / (4 cos θi
//! cos θo)` is a Fresnel-free GGX microfacet BRDF (Walter et al. 2007, Eqs. 20, 33, 34) whose
//! visible-normal sampling density matches `f_GGX cos θi` up to the factor `G1(wi)` (Heitz 2018, Sec.
//! 2). The fit minimises the relative squared error `Σ_i ((m_i - y_i) / (y_i + ε))²` — relative, so
//! that a specular peak of 500/sr and a diffuse floor of 0.05/sr both matter — over non-negative
//! `k` (an exact non-negative least squares over the 3 unknowns by enumerating active sets) and over
//! pairs of α from a logarithmic grid. The lobes' selection probabilities are the fitted albedos `k`
//! (each lobe's albedo at normal incidence), mixed with [`DEFENSIVE`] of pure cosine sampling.
//!
//! The direction pairs follow the Rusinkiewicz parametrisation with θh spaced quadratically, as MERL
//! tabulates it (Matusik et al. 2003), so that narrow peaks near the mirror direction are resolved.

use super::proxy::{GgxLobe, Proxy, DEFENSIVE};
use super::lum;
use crate::angles::{from_rusinkiewicz, Rusinkiewicz};
use crate::math::{INV_PI, PI};
use crate::microfacet::{ggx_d, smith_ggx_g1_over_2cos};
use crate::{Rgb, Vec3};

/// θh samples, spaced `θh = ((i + ½)/N)² π/2`.
const N_H: usize = 32;
/// θd samples, uniform in (0, 0.45π).
const N_D: usize = 8;
/// φd samples, uniform in [0, π) (reciprocity and isotropy cover the rest).
const N_P: usize = 4;
/// Candidate GGX roughnesses, logarithmic from `ALPHA_LO` to 1.
pub(super) const N_A: usize = 20;
const ALPHA_LO: f32 = 0.004;

/// The candidate α of grid index `k`.
#[inline]
pub(super) fn alpha_of(k: usize) -> f32 {
    ALPHA_LO * libm::powf(1.0 / ALPHA_LO, k as f32 / (N_A - 1) as f32)
}

/// The `i`-th fitting direction pair `(wi, wo)`, both above the horizon, or `None` if the pair dips
/// below it (large θh with large θd).
fn pair(i: usize) -> Option<(Vec3, Vec3)> {
    let (ih, rest) = (i / (N_D * N_P), i % (N_D * N_P));
    let (id, ip) = (rest / N_P, rest % N_P);
    let t = (ih as f32 + 0.5) / N_H as f32;
    let r = Rusinkiewicz {
        theta_h: t * t * 0.5 * PI,
        phi_h: 0.0,
        theta_d: (id as f32 + 0.5) / N_D as f32 * 0.45 * PI,
        phi_d: ip as f32 / N_P as f32 * PI,
    };
    let (wi, wo) = from_rusinkiewicz(&r);
    (wi.z > 1e-3 && wo.z > 1e-3).then_some((wi, wo))
}

/// `f_GGX(α)` at a pair: `D G2 / (4 cos θi cos θo)` with separable Smith masking.
#[inline]
fn ggx_brdf(wi: Vec3, wo: Vec3, alpha: f32) -> f32 {
    let h = (wi + wo).normalize();
    ggx_d(h.z, h.x * h.x + h.y * h.y, alpha) * smith_ggx_g1_over_2cos(wi.z, alpha) * smith_ggx_g1_over_2cos(wo.z, alpha)
}

/// Weighted Gram sums of the basis `[1/π, f_GGX(α_0), …, f_GGX(α_{N_A-1})]` and the data.
struct Normal {
    /// `Σ w b_a b_b` over basis indices (0 = cosine lobe, 1 + k = α_k).
    gram: [[f64; N_A + 1]; N_A + 1],
    /// `Σ w b_a y`.
    rhs: [f64; N_A + 1],
    /// `Σ w y²`.
    yy: f64,
}

/// Solves the `n × n` system `a x = b` (n ≤ 3) by Gaussian elimination with partial pivoting; `None`
/// if singular.
fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for c in 0..N {
        let p = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..N {
            let f = a[r][c] / a[c][c];
            let pivot = a[c];
            for (ark, ack) in a[r][c..].iter_mut().zip(&pivot[c..]) {
                *ark -= f * ack;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; N];
    for r in (0..N).rev() {
        let s: f64 = (r + 1..N).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

impl Normal {
    /// The best non-negative coefficients on the basis subset `idx` (its active sets enumerated) and
    /// their objective `Σ w (m - y)²`.
    fn nnls(&self, idx: [usize; 3]) -> ([f64; 3], f64) {
        let mut best = ([0.0; 3], self.yy);
        for mask in 1u32..8 {
            let sel: [bool; 3] = [mask & 1 != 0, mask & 2 != 0, mask & 4 != 0];
            let n = sel.iter().filter(|&&s| s).count();
            let cols: [usize; 3] = {
                let mut c = [0; 3];
                let mut j = 0;
                for (k, &on) in sel.iter().enumerate() {
                    if on {
                        c[j] = k;
                        j += 1;
                    }
                }
                c
            };
            let mut a = [[0.0; 3]; 3];
            let mut b = [0.0; 3];
            for r in 0..3 {
                for c in 0..3 {
                    a[r][c] = if r < n && c < n { self.gram[idx[cols[r]]][idx[cols[c]]] } else if r == c { 1.0 } else { 0.0 };
                }
                b[r] = if r < n { self.rhs[idx[cols[r]]] } else { 0.0 };
            }
            let Some(x) = solve(a, b) else { continue };
            if x[..n].iter().any(|&v| v < 0.0) {
                continue;
            }
            let mut coef = [0.0; 3];
            for j in 0..n {
                coef[cols[j]] = x[j];
            }
            // Σ w (m - y)² = yy - 2 xᵀr + xᵀ G x.
            let mut obj = self.yy;
            for a_ in 0..3 {
                obj -= 2.0 * coef[a_] * self.rhs[idx[a_]];
                for b_ in 0..3 {
                    obj += coef[a_] * coef[b_] * self.gram[idx[a_]][idx[b_]];
                }
            }
            if obj < best.1 {
                best = (coef, obj);
            }
        }
        best
    }
}

/// Fits a sampling proxy to the BRDF `brdf(wi, wo)` (local frame, 1/sr, linear RGB) from `32 × 8 × 4`
/// evaluations (module docs). A BRDF that is zero or non-finite everywhere gets [`Proxy::COSINE`].
///
/// ```
/// use nbrdf::sampling::fit_proxy;
/// use nbrdf::parametric::Lambert;
/// let proxy = fit_proxy(|wi, wo| Lambert { kd: [0.5; 3] }.eval(wi, wo));
/// assert!(proxy.diffuse > 0.99); // a Lambertian surface is sampled by its cosine
/// ```
pub fn fit_proxy(brdf: impl Fn(Vec3, Vec3) -> Rgb) -> Proxy {
    // Pass 1: the data, and the relative-error floor ε from their mean.
    let mut ys = [0.0f32; N_H * N_D * N_P];
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (i, y) in ys.iter_mut().enumerate() {
        if let Some((wi, wo)) = pair(i) {
            let v = lum(crate::math::sanitize(brdf(wi, wo)));
            *y = v;
            sum += v as f64;
            count += 1;
        }
    }
    if !(sum > 0.0 && sum.is_finite()) {
        return Proxy::COSINE;
    }
    let eps = 1e-3 * sum / count as f64 + 1e-6;
    // Pass 2: the weighted normal equations over every candidate α at once.
    let mut ne = Normal { gram: [[0.0; N_A + 1]; N_A + 1], rhs: [0.0; N_A + 1], yy: 0.0 };
    let mut basis = [0.0f64; N_A + 1];
    for (i, &y) in ys.iter().enumerate() {
        let Some((wi, wo)) = pair(i) else { continue };
        let y = y as f64;
        let w = 1.0 / ((y + eps) * (y + eps));
        basis[0] = INV_PI as f64;
        for k in 0..N_A {
            basis[1 + k] = ggx_brdf(wi, wo, alpha_of(k)) as f64;
        }
        for a in 0..=N_A {
            ne.rhs[a] += w * basis[a] * y;
            for b in a..=N_A {
                ne.gram[a][b] += w * basis[a] * basis[b];
            }
        }
        ne.yy += w * y * y;
    }
    for a in 0..=N_A {
        for b in 0..a {
            ne.gram[a][b] = ne.gram[b][a];
        }
    }
    // Pass 3: every pair of roughnesses (a single lobe is the pair's second coefficient at 0).
    let mut best = ([1.0, 0.0, 0.0], f64::INFINITY, [1.0f32; 2]);
    for a in 0..N_A {
        for b in a + 1..N_A {
            let (coef, obj) = ne.nnls([0, 1 + a, 1 + b]);
            if obj < best.1 {
                best = (coef, obj, [alpha_of(a), alpha_of(b)]);
            }
        }
    }
    let ([kd, k1, k2], _, [a1, a2]) = best;
    let total = kd + k1 + k2;
    if !(total > 0.0 && total.is_finite()) {
        return Proxy::COSINE;
    }
    // Lobes below 0.1 % of the albedo would only cost a wasted branch: dropped.
    let share = |k: f64| if k / total < 1e-3 { 0.0 } else { ((1.0 - DEFENSIVE as f64) * k / total) as f32 };
    let lobes = [GgxLobe { weight: share(k1), alpha: a1 }, GgxLobe { weight: share(k2), alpha: a2 }];
    Proxy::new(DEFENSIVE + share(kd), lobes).unwrap_or(Proxy::COSINE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_spans_the_documented_range() {
        assert!((alpha_of(0) - ALPHA_LO).abs() < 1e-7 && (alpha_of(N_A - 1) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn small_solve_inverts() {
        let x = solve([[2.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 4.0]], [3.0, 5.0, 5.0]).unwrap();
        assert!(x.iter().all(|v| (v - 1.0).abs() < 1e-12));
    }
}
