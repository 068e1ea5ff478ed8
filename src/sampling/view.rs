//! A sampling proxy that follows the BRDF at every view angle: a table over `cos θo` of [`Proxy`]
//! mixtures, each fitted to the BRDF's slice at that view by minimising the variance of the weight.
//!
//! One fixed proxy ([`fit_proxy`](super::fit_proxy)) fits the BRDF's shape over all views, so a fabric
//! whose fitted GGX lobe looks "specular" wastes most samples at every view (on MERL beige-fabric its
//! weight variance is hundreds of times cosine sampling's), and a glossy material gets the lobe of its
//! average view. Here cell `j` (`cos θo ∈ (1 − (j+1)/N, 1 − j/N]`) holds the mixture that minimises
//! `Var[lum(f) cos θi / pdf]` at the cell's middle view; `sample` and `pdf` both use the cell of `wo`,
//! so the pdf is exact and costs what the single proxy's does. A table of mixtures (rather than a
//! network predicting lobe parameters, or a tabulated warp) keeps the pdf exact and cheap, is `no_std`
//! with fixed-size storage (16 × 5 floats in the model header), and each cell's fit is a small convex
//! problem.
//!
//! Each cell's fit: a dictionary of the cosine lobe and GGX visible-normal lobes of 20 roughnesses;
//! `wi` points drawn from their equal mixture `q` (stratified, deterministic); the second moment of the
//! weight, `S(w) = Σ g² / (q p_w)` with `g = lum(f) cos θi`, is convex in the mixture weights `w`. It is
//! minimised (safeguarded Newton) for the cosine lobe with each GGX lobe, then for the pairs among the
//! six best of those, inside each triangle and on its cosine-free edge; pure cosine sampling is a
//! candidate too. The winner of many candidates on one point set looks better there than it is, and a
//! peak narrower than the dictionary hides from its points, so the winner replaces the all-view proxy
//! only if its variance, estimated on draws **of that proxy**, is below [`MARGIN`] of the proxy's. The
//! cosine lobe keeps at least [`VIEW_DEFENSIVE`] of the mass (defensive sampling, Hesterberg 1995): the
//! pdf is positive wherever `f` can be.
//!
//! ```
//! use nbrdf::sampling::fit_view_proxy;
//! use nbrdf::builtin::Builtin;
//! use nbrdf::Vec3;
//! let brdf = |wi, wo| Builtin::TwoLobeMetal.eval(wi, wo);
//! let view = fit_view_proxy(brdf);
//! let wo = Vec3::new(0.5, 0.0, 0.8).normalize();
//! let s = view.sample(wo, [0.3, 0.8, 0.4], brdf).unwrap();
//! assert_eq!(s.pdf, view.pdf(s.wi, wo));
//! ```

use serde::{Deserialize, Serialize};

use super::fit::{alpha_of, N_A};
use super::proxy::{GgxLobe, Proxy};
use super::{finish, lum, valid_wo, BsdfSample};
use crate::math::INV_PI;
use crate::warp::{ggx_vndf_pdf, half_of, reflect_about, sample_ggx_vndf, square_to_cosine_hemisphere};
use crate::{Error, Rgb, Vec3};

/// Number of view cells the table holds: cell `j` covers `cos θo ∈ (1 − (j+1)/N, 1 − j/N]`.
pub const VIEW_NODES: usize = 16;

/// Smallest share of the cosine lobe in every cell.
pub const VIEW_DEFENSIVE: f32 = 0.02;

/// Fitting points drawn from each dictionary lobe.
const PER_LOBE: usize = 128;
/// Dictionary size: the cosine lobe and the `N_A` GGX roughnesses.
const DICT: usize = 1 + N_A;

/// Proxies over the view angle θo (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ViewProxy {
    /// The mixture of cell `j`, `cos θo ∈ (1 − (j+1)/N, 1 − j/N]`, fitted at the cell's middle view.
    pub nodes: [Proxy; VIEW_NODES],
}

impl Default for ViewProxy {
    fn default() -> Self {
        ViewProxy { nodes: [Proxy::COSINE; VIEW_NODES] }
    }
}

/// The cell of a view with `cos θo = cos_o`.
#[inline]
fn cell(cos_o: f32) -> usize {
    (((1.0 - cos_o) * VIEW_NODES as f32) as usize).min(VIEW_NODES - 1)
}

impl ViewProxy {
    /// Checks every node ([`Proxy::validate`]).
    pub fn validate(&self) -> Result<(), Error> {
        self.nodes.iter().try_for_each(Proxy::validate)
    }

    /// The mixture of the view `wo`'s cell; `None` for a view that is not finite or not above the
    /// horizon.
    #[inline]
    pub fn at(&self, wo: Vec3) -> Option<&Proxy> {
        let wo = valid_wo(wo)?;
        Some(&self.nodes[cell(wo.z)])
    }

    /// A direction drawn for the view `wo` from the mixture of its cell.
    #[inline]
    pub fn sample_wi(&self, wo: Vec3, u: [f32; 3]) -> Option<Vec3> {
        self.at(wo)?.sample_wi(wo, u)
    }

    /// Density of [`ViewProxy::sample_wi`] per unit solid angle of `wi`: its cell's mixture's.
    #[inline]
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.at(wo).map_or(0.0, |p| p.pdf(wi, wo))
    }

    /// Samples and evaluates `brdf(wi, wo)` for the weight `f cos θi / pdf`, with the pdf of
    /// [`ViewProxy::pdf`].
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f32; 3], brdf: impl FnOnce(Vec3, Vec3) -> Rgb) -> Option<BsdfSample> {
        // [`Proxy::sample`] of the cell, normalising `wo` once for the lookup and the draw.
        let wo = valid_wo(wo)?;
        let node = &self.nodes[cell(wo.z)];
        let wi = node.sample_wi(wo, u)?;
        finish(wi, node.pdf(wi, wo), brdf(wi, wo))
    }
}

/// Fits a [`ViewProxy`] to `brdf(wi, wo)` (local frame, isotropic, 1/sr, linear RGB) from about
/// 16 × 5400 evaluations (module docs; some 0.2 s for an NBRDF network on one core). Where the BRDF is
/// zero or non-finite at a view, that cell samples the cosine lobe.
pub fn fit_view_proxy(brdf: impl Fn(Vec3, Vec3) -> Rgb) -> ViewProxy {
    let global = super::fit_proxy(&brdf);
    fit_view_proxy_around(brdf, &global)
}

/// [`fit_view_proxy`] given the all-view proxy `global` ([`fit_proxy`](super::fit_proxy) of the same
/// BRDF), which a cell keeps unless its own mixture is clearly better.
pub fn fit_view_proxy_around(brdf: impl Fn(Vec3, Vec3) -> Rgb, global: &Proxy) -> ViewProxy {
    let mut view = ViewProxy::default();
    for (j, node) in view.nodes.iter_mut().enumerate() {
        // The cell's middle view.
        let cos_o = 1.0 - (j as f32 + 0.5) / VIEW_NODES as f32;
        let wo = Vec3::new(libm::sqrtf(1.0 - cos_o * cos_o), 0.0, cos_o);
        *node = fit_node(&brdf, wo, global);
    }
    view
}

/// The fitting points of one view: each point's dictionary densities and its `g² / q`.
struct Points {
    /// `[point][lobe]` densities, lobe 0 the cosine lobe.
    basis: alloc_free::Rows,
    /// `g² / q` per point.
    c: alloc_free::Col,
    n: usize,
    /// The albedo estimate `(1/M) Σ g / q` over all `M` draws (those below the horizon count as 0).
    mean: f64,
}

impl Points {
    /// The variance of the weight under a mixture whose second moment on the points is `s`.
    fn variance(&self, s: f64) -> f64 {
        s / alloc_free::CAP as f64 - self.mean * self.mean
    }
}

/// Fixed-capacity storage of the fitting points (the core allocates nothing).
mod alloc_free {
    pub const CAP: usize = super::DICT * super::PER_LOBE;
    pub type Rows = [[f32; super::DICT]; CAP];
    pub type Col = [f32; CAP];
}

/// Density of dictionary lobe `l` at `wi` for the view `wo`.
#[inline]
fn lobe_pdf(l: usize, wi: Vec3, wo: Vec3) -> f32 {
    if l == 0 {
        return wi.z.max(0.0) * INV_PI;
    }
    match half_of(wo, wi) {
        Some((h, oh)) => ggx_vndf_pdf(wo, h, alpha_of(l - 1)) / (4.0 * oh),
        None => 0.0,
    }
}

/// `x` modulo 1 for `x ∈ [0, 2)`.
#[inline]
fn wrap(x: f32) -> f32 {
    if x >= 1.0 { x - 1.0 } else { x }
}

/// Van der Corput radical inverse in base 2.
#[inline]
fn radical_inverse(i: u32) -> f32 {
    (i.reverse_bits() >> 8) as f32 / (1u32 << 24) as f32
}

/// Where the points of a view come from: the dictionary's equal mixture (for fitting), or one proxy
/// (to check a fit on draws of the proxy it should replace).
#[derive(Clone, Copy)]
enum Source<'a> {
    Dictionary,
    Proxy(&'a Proxy),
}

/// Draws `CAP` points of the view `wo` from `source` into `pts` (stratified, deterministic), keeping each
/// point's dictionary densities and `g² / q`, `q` the source's density.
fn gather(brdf: &impl Fn(Vec3, Vec3) -> Rgb, wo: Vec3, source: Source<'_>, pts: &mut Points) {
    pts.n = 0;
    pts.mean = 0.0;
    for i in 0..alloc_free::CAP {
        let (l, s) = (i / PER_LOBE, i % PER_LOBE);
        // A fixed shift per stratum block (Cranley–Patterson) keeps the blocks' point sets apart.
        let shift = [radical_inverse(l as u32 * 7 + 3), radical_inverse(l as u32 * 13 + 5)];
        let u = [wrap((s as f32 + 0.5) / PER_LOBE as f32 + shift[0]), wrap(radical_inverse(s as u32) + shift[1])];
        let wi = match source {
            Source::Dictionary if l == 0 => square_to_cosine_hemisphere(u),
            Source::Dictionary => reflect_about(wo, sample_ggx_vndf(wo, alpha_of(l - 1), u)),
            Source::Proxy(p) => match p.sample_wi(wo, [u[0], u[1], (l as f32 + 0.5) / DICT as f32]) {
                Some(wi) => wi,
                None => continue,
            },
        };
        if !(wi.z > 1e-4 && wi.is_finite()) {
            continue;
        }
        let g = lum(crate::math::sanitize(brdf(wi, wo))).max(0.0) * wi.z;
        if g <= 0.0 {
            continue;
        }
        let row = &mut pts.basis[pts.n];
        for (k, b) in row.iter_mut().enumerate() {
            *b = lobe_pdf(k, wi, wo);
        }
        let q = match source {
            Source::Dictionary => row.iter().sum::<f32>() / DICT as f32,
            Source::Proxy(p) => p.pdf(wi, wo),
        };
        if !(q > 0.0 && q.is_finite()) {
            continue;
        }
        pts.c[pts.n] = g * g / q;
        pts.mean += (g / q) as f64 / alloc_free::CAP as f64;
        pts.n += 1;
    }
}

/// `Σ c / p` and its first two derivatives along `x`, for `p = a + x e` (`ae` gives `(a, e)` of a row).
#[inline]
fn moments_1d(pts: &Points, x: f64, ae: &impl Fn(&[f32; DICT]) -> (f64, f64)) -> (f64, f64, f64) {
    let (mut f, mut d1, mut d2) = (0.0, 0.0, 0.0);
    for i in 0..pts.n {
        let (a, e) = ae(&pts.basis[i]);
        let c = pts.c[i] as f64;
        let q = 1.0 / (a + x * e);
        f += c * q;
        d1 -= c * e * q * q;
        d2 += 2.0 * c * e * e * q * q * q;
    }
    (f, d1, d2)
}

/// Minimises the convex `S(x) = Σ c / (a + x e)` over `x ∈ [0, 1]` (every `a + x e > 0` there):
/// safeguarded Newton inside a bracket of the derivative's sign change. Returns `(x, S(x))`.
fn solve_1d(pts: &Points, ae: impl Fn(&[f32; DICT]) -> (f64, f64)) -> (f64, f64) {
    let (f0, g0, _) = moments_1d(pts, 0.0, &ae);
    if g0 >= 0.0 {
        return (0.0, f0);
    }
    let (f1, g1, _) = moments_1d(pts, 1.0, &ae);
    if g1 <= 0.0 {
        return (1.0, f1);
    }
    let (mut lo, mut hi, mut x) = (0.0f64, 1.0f64, 0.5f64);
    for _ in 0..NEWTON_STEPS {
        let (_, g, h) = moments_1d(pts, x, &ae);
        if g < 0.0 { lo = x } else { hi = x }
        let newton = x - g / h;
        x = if newton > lo && newton < hi && h > 0.0 { newton } else { 0.5 * (lo + hi) };
        if hi - lo < 1e-7 {
            break;
        }
    }
    (x, moments_1d(pts, x, &ae).0)
}

/// Minimises `S(x) = Σ c / (b_0 + x_1 d_1 + x_2 d_2)` with `d_k = (1 − δ)(b_k − b_0)` over the inside of
/// the triangle `x ≥ 0, x_1 + x_2 ≤ 1` by damped Newton steps that stay inside (the edges are the
/// single-lobe and cosine-free problems, solved by [`solve_1d`]). Returns `(x, S)`.
fn solve_2d(pts: &Points, k1: usize, k2: usize) -> ([f64; 2], f64) {
    let r = 1.0 - VIEW_DEFENSIVE as f64;
    let eval = |x: [f64; 2], derivs: bool| {
        let (mut f, mut g, mut h) = (0.0, [0.0; 2], [0.0; 3]);
        for i in 0..pts.n {
            let row = &pts.basis[i];
            let b0 = row[0] as f64;
            let d = [r * (row[k1] as f64 - b0), r * (row[k2] as f64 - b0)];
            let q = 1.0 / (b0 + x[0] * d[0] + x[1] * d[1]);
            let c = pts.c[i] as f64;
            f += c * q;
            if derivs {
                let q2 = c * q * q;
                g[0] -= q2 * d[0];
                g[1] -= q2 * d[1];
                let q3 = 2.0 * q2 * q;
                h[0] += q3 * d[0] * d[0];
                h[1] += q3 * d[0] * d[1];
                h[2] += q3 * d[1] * d[1];
            }
        }
        (f, g, h)
    };
    let inside = |x: [f64; 2]| x[0] >= 0.0 && x[1] >= 0.0 && x[0] + x[1] <= 1.0;
    let mut x = [1.0 / 3.0; 2];
    let mut f = eval(x, false).0;
    for _ in 0..NEWTON_STEPS {
        let (_, g, h) = eval(x, true);
        let det = h[0] * h[2] - h[1] * h[1];
        if det.is_nan() || det <= 0.0 {
            break;
        }
        let step = [-(h[2] * g[0] - h[1] * g[1]) / det, -(h[0] * g[1] - h[1] * g[0]) / det];
        // Backtrack until the step stays inside and lowers S.
        let mut t = 1.0;
        let mut moved = false;
        for _ in 0..30 {
            let y = [x[0] + t * step[0], x[1] + t * step[1]];
            if inside(y) {
                let fy = eval(y, false).0;
                if fy < f {
                    moved = (f - fy) > 1e-9 * f;
                    x = y;
                    f = fy;
                    break;
                }
            }
            t *= 0.5;
        }
        if !moved {
            break;
        }
    }
    (x, f)
}

/// Newton iterations of each weight fit.
const NEWTON_STEPS: usize = 40;
/// GGX lobes of the best single-lobe fits that enter the pair search.
const PAIR_POOL: usize = 6;

/// The second moment of `proxy` on the points; `None` if one of its lobes is not a dictionary lobe.
fn second_moment(pts: &Points, proxy: &Proxy) -> Option<f64> {
    let mut lobes = [(0.0f64, 0usize); 2];
    for (l, g) in lobes.iter_mut().zip(&proxy.lobes) {
        if g.weight > 0.0 {
            *l = (g.weight as f64, 1 + (0..N_A).find(|&k| alpha_of(k) == g.alpha)?);
        }
    }
    let mut s = 0.0;
    for i in 0..pts.n {
        let row = &pts.basis[i];
        let p = proxy.diffuse as f64 * row[0] as f64 + lobes.iter().map(|&(w, k)| w * row[k] as f64).sum::<f64>();
        s += pts.c[i] as f64 / p;
    }
    Some(s)
}

/// A view's own mixture must beat the all-view `global` one by this factor in the variance estimated
/// on the all-view proxy's own draws to replace it: on peaked BRDFs that estimate is off by tens
/// of percent.
pub const MARGIN: f64 = 0.7;

/// The best mixture of the cosine lobe and at most two GGX lobes for the view `wo`, or `global` (the
/// all-view proxy) unless that is clearly better.
fn fit_node(brdf: &impl Fn(Vec3, Vec3) -> Rgb, wo: Vec3, global: &Proxy) -> Proxy {
    // About 90 KB on the stack: the core allocates nothing.
    let mut pts = Points { basis: [[0.0; DICT]; alloc_free::CAP], c: [0.0; alloc_free::CAP], n: 0, mean: 0.0 };
    gather(brdf, wo, Source::Dictionary, &mut pts);
    if pts.n == 0 {
        return Proxy::COSINE;
    }
    let (d, r) = (VIEW_DEFENSIVE as f64, 1.0 - VIEW_DEFENSIVE as f64);
    // Weights (cosine, lobe 1, lobe 2) of the mixture and its second moment; cosine alone first.
    let s_cos = (0..pts.n).map(|i| pts.c[i] as f64 / pts.basis[i][0] as f64).sum::<f64>();
    let mut best = (s_cos, [1.0f64, 0.0, 0.0], [1usize, 1]);
    // Each GGX lobe with the cosine lobe: p = b0 + x (1 − δ)(b_k − b0).
    let mut singles = [(f64::INFINITY, 0usize); N_A];
    for (k, single) in singles.iter_mut().enumerate() {
        let l = 1 + k;
        let (x, s) = solve_1d(&pts, |row| (row[0] as f64, r * (row[l] as f64 - row[0] as f64)));
        *single = (s, l);
        if s < best.0 {
            best = (s, [1.0 - x, x, 0.0], [l, l]);
        }
    }
    singles.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    // Pairs among the best single lobes: the inside of each triangle and its cosine-free edge.
    for i in 0..PAIR_POOL {
        for j in i + 1..PAIR_POOL {
            let (l1, l2) = (singles[i].1, singles[j].1);
            let (x, s) = solve_1d(&pts, |row| {
                (d * row[0] as f64 + r * row[l2] as f64, r * (row[l1] as f64 - row[l2] as f64))
            });
            if s < best.0 {
                best = (s, [0.0, x, 1.0 - x], [l1, l2]);
            }
            let ([x1, x2], s) = solve_2d(&pts, l1, l2);
            if s < best.0 {
                best = (s, [1.0 - x1 - x2, x1, x2], [l1, l2]);
            }
        }
    }
    let (_, [w0, w1, w2], [l1, l2]) = best;
    // Lobes under 0.1 % of the mass would only cost a branch: dropped.
    let lobe = |w: f64, l: usize| {
        let m = (1.0 - VIEW_DEFENSIVE) * w as f32;
        if m < 1e-3 { GgxLobe::NONE } else { GgxLobe { weight: m, alpha: alpha_of(l - 1) } }
    };
    let Ok(own) = Proxy::new(VIEW_DEFENSIVE + (1.0 - VIEW_DEFENSIVE) * w0.max(0.0) as f32, [lobe(w1, l1), lobe(w2, l2)]) else {
        return *global;
    };
    // The winner of many candidates on one point set looks better there than it is, and a peak narrower
    // than the dictionary's lobes hides from its points: the fit must also beat the all-view proxy on
    // draws of that proxy, which reach every peak it samples.
    gather(brdf, wo, Source::Proxy(global), &mut pts);
    match (second_moment(&pts, &own), second_moment(&pts, global)) {
        (Some(s_own), Some(s_global)) if pts.variance(s_own) > MARGIN * pts.variance(s_global) => *global,
        _ => own,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_view_falls_in_one_cell() {
        assert_eq!((cell(1.0), cell(0.0)), (0, VIEW_NODES - 1));
        for j in 0..VIEW_NODES {
            assert_eq!(cell(1.0 - (j as f32 + 0.5) / VIEW_NODES as f32), j);
        }
    }

    #[test]
    fn a_lambertian_surface_is_sampled_by_its_cosine_at_every_view() {
        let view = fit_view_proxy(|_, _| [0.5; 3]);
        for n in &view.nodes {
            assert_eq!(n.diffuse, 1.0, "{n:?}");
        }
    }
}
