//! Helpers shared by the integration tests: model bytes in aligned storage (`tests/kernels.rs`,
//! `tests/hard_cases.rs`), and the sampling tests' checks (`tests/sampling.rs`, `tests/proxy.rs`): a
//! sampler against its own pdf by a chi-square test on a histogram of sampled directions (as pbrt's and
//! Mitsuba's BSDF tests do), the pdf's integral against the share of samples produced, the estimator
//! weight against `f cos / pdf`, and an independent quadrature of the directional albedo.
//!
//! Each test binary uses a different subset of these helpers.
#![allow(dead_code)]

use nbrdf::sampling::BsdfSample;
use nbrdf::{Rgb, Vec3};
use std::f64::consts::PI;

/// Point `i` of the R3 low-discrepancy sequence in the unit cube (Roberts 2018), shifted by `shift`:
/// three uniforms for `Brdf::sample`.
pub fn r3(i: usize, shift: f64) -> [f32; 3] {
    let r = |a: f64| ((i as f64 + 0.5 + shift) * a).fract() as f32;
    [r(0.819_172_513_396_164_4), r(0.671_043_606_703_789_2), r(0.549_700_477_901_970_4)]
}

/// Deterministic weights in [-scale, scale] (an LCG), for model files of any header.
pub fn weights(n: usize, seed: u64, scale: f32) -> Vec<f32> {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
        })
        .collect()
}

/// Bins in cos θ (equal solid angle).
pub const N_THETA: usize = 16;
pub const N_PHI: usize = 32;
/// Quadrature points per bin and axis.
pub const SUB: usize = 16;

/// A 64-bit LCG (Knuth's MMIX constants): fixed seeds, so the statistical tests never fail flakily.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32 // 24 bits: exactly representable, < 1
    }
}

/// The unit vector at polar angle `theta` and azimuth `phi`.
pub fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32)
}

/// Histogram bin of an upper-hemisphere direction.
pub fn bin_of(w: Vec3) -> usize {
    let t = ((w.z as f64) * N_THETA as f64).clamp(0.0, N_THETA as f64 - 1.0) as usize;
    let mut phi = (w.y as f64).atan2(w.x as f64);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    t * N_PHI + (phi / (2.0 * PI) * N_PHI as f64).clamp(0.0, N_PHI as f64 - 1.0) as usize
}

/// ∫ pdf over each bin (midpoint rule on SUB × SUB points in (cos θ, φ)); `pdf(wi)`.
pub fn expected_mass(pdf: &dyn Fn(Vec3) -> f32) -> Vec<f64> {
    expected_mass_at(pdf, SUB)
}

/// [`expected_mass`] on `sub × sub` points per bin: finer for the narrow lobes of fitted proxies.
pub fn expected_mass_at(pdf: &dyn Fn(Vec3) -> f32, sub: usize) -> Vec<f64> {
    let mut mass = vec![0.0; N_THETA * N_PHI];
    let dz = 1.0 / (N_THETA * sub) as f64;
    let dphi = 2.0 * PI / (N_PHI * sub) as f64;
    for i in 0..N_THETA * sub {
        let z = (i as f64 + 0.5) * dz;
        let r = (1.0 - z * z).sqrt();
        for j in 0..N_PHI * sub {
            let phi = (j as f64 + 0.5) * dphi;
            let wi = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            mass[(i / sub) * N_PHI + j / sub] += pdf(wi) as f64 * dz * dphi;
        }
    }
    mass
}

/// Directional albedo ∫ f(wi, wo) cos θi dωi by an `n` × `n` midpoint quadrature (independent of any
/// sampler).
pub fn albedo(f: &dyn Fn(Vec3, Vec3) -> Rgb, wo: Vec3, n: usize) -> [f64; 3] {
    let mut a = [0.0f64; 3];
    for i in 0..n {
        let z = (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..n {
            let phi = (j as f64 + 0.5) / n as f64 * 2.0 * PI;
            let v = f(Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32), wo);
            (0..3).for_each(|c| a[c] += v[c] as f64 * z);
        }
    }
    a.map(|x| x * 2.0 * PI / (n * n) as f64)
}

/// What [`check_sampler`] needs of a sampled BRDF at one view direction `wo`.
pub struct Sampler<'a> {
    /// Draws a direction from three uniforms.
    pub sample: &'a dyn Fn([f32; 3]) -> Option<BsdfSample>,
    /// The density of `sample` at `wi`.
    pub pdf: &'a dyn Fn(Vec3) -> f32,
    /// The BRDF `f(wi, wo)` the weight divides.
    pub eval: &'a dyn Fn(Vec3) -> Rgb,
}

/// Draws `n` samples and checks them against the pdf: each sample's pdf equals `pdf()`, its weight is
/// `f cos / pdf`, the pdf integrates to the share of samples produced, and the histogram passes a
/// chi-square test. Returns (share produced, mean weight).
pub fn check_sampler(name: &str, s: &Sampler<'_>, n: usize, seed: u64) -> (f64, [f64; 3]) {
    check_sampler_at(name, s, n, seed, SUB)
}

/// [`check_sampler`] with the histogram's expected counts integrated on `sub × sub` points per bin.
pub fn check_sampler_at(name: &str, s: &Sampler<'_>, n: usize, seed: u64, sub: usize) -> (f64, [f64; 3]) {
    let mut rng = Rng(seed);
    let mut counts = vec![0.0f64; N_THETA * N_PHI];
    let (mut produced, mut weight_sum) = (0usize, [0.0f64; 3]);
    for _ in 0..n {
        let Some(smp) = (s.sample)([rng.next(), rng.next(), rng.next()]) else { continue };
        produced += 1;
        counts[bin_of(smp.wi)] += 1.0;
        let p = (s.pdf)(smp.wi);
        assert!((smp.pdf - p).abs() <= 1e-4 * p, "{name}: sampled pdf {} vs pdf() {p}", smp.pdf);
        let f = (s.eval)(smp.wi);
        for c in 0..3 {
            let w = f[c] * smp.wi.z / smp.pdf;
            assert!((smp.weight[c] - w).abs() <= 1e-4 * w.max(1e-6), "{name}: weight is not f cos / pdf");
            weight_sum[c] += smp.weight[c] as f64;
        }
    }
    let mass = expected_mass_at(s.pdf, sub);
    let total: f64 = mass.iter().sum();
    let frac = produced as f64 / n as f64;
    let sigma = (frac * (1.0 - frac) / n as f64).sqrt().max(1.0 / n as f64);
    assert!(total <= 1.0 + 2e-3, "{name}: ∫ pdf = {total}");
    assert!((total - frac).abs() < 5.0 * sigma + 2e-3, "{name}: ∫ pdf = {total}, produced {frac}");

    // Chi-square with bins of small expectation pooled (Mitsuba's ChiSquareTest does the same).
    let (mut chi2, mut dof, mut pool_obs, mut pool_exp) = (0.0, 0usize, 0.0, 0.0);
    for b in 0..mass.len() {
        let e = mass[b] * n as f64;
        if e < 5.0 {
            pool_obs += counts[b];
            pool_exp += e;
        } else {
            chi2 += (counts[b] - e).powi(2) / e;
            dof += 1;
        }
    }
    if pool_exp >= 5.0 {
        chi2 += (pool_obs - pool_exp).powi(2) / pool_exp;
        dof += 1;
    } else {
        // Too little mass to pool into a bin of its own: samples there must still be rare.
        assert!(pool_obs < 5.0 + 5.0 * pool_exp.sqrt() + 5.0, "{name}: {pool_obs} samples where the pdf has {pool_exp}");
    }
    let dof = dof.saturating_sub(1).max(1) as f64;
    // Upper 1 - 3e-5 quantile of χ²(dof) by the Wilson-Hilferty approximation (z = 4): with a few dozen
    // configurations a correct sampler fails with probability ~1e-3 (and the seeds are fixed).
    let k = 2.0 / (9.0 * dof);
    let limit = dof * (1.0 - k + 4.0 * k.sqrt()).powi(3);
    assert!(chi2 < limit, "{name}: χ² = {chi2:.1} > {limit:.1} with {dof} dof");
    (frac, weight_sum.map(|s| s / n as f64))
}

/// `bytes` in 4-byte aligned storage, as `Model::from_bytes` needs (the tail zero-padded).
pub fn words(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks(4)
        .map(|c| {
            let mut w = [0u8; 4];
            w[..c.len()].copy_from_slice(c);
            u32::from_ne_bytes(w)
        })
        .collect()
}

/// The bytes of `words`.
pub fn bytes(words: &[u32]) -> &[u8] {
    // SAFETY: u8 has no alignment requirement and every byte of a u32 slice is initialised.
    unsafe { std::slice::from_raw_parts(words.as_ptr().cast::<u8>(), words.len() * 4) }
}
