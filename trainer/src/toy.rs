//! A small analytic training set: a spatially varying Blinn-Phong-like BRDF (Blinn 1977) seen under
//! random directions. It stands in for rendered data in tests and benchmarks.

use nbrdf::Vec3;
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::models::PositionEncoding;
use crate::observations::Observations;

/// A direction in the upper hemisphere, `z ≥ 0.1` so that neither is grazing.
fn random_up(rng: &mut impl Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(0.1..1.0));
        if v.length_squared() <= 1.0 && v.length_squared() > 1e-3 {
            return v.normalize();
        }
    }
}

/// The reference BRDF: diffuse albedo varying with the first position value plus a white lobe
/// `ks (n+2)/(2π) cos^n θh`, reciprocal by construction.
pub fn reference_brdf(position: &[f32], wi: Vec3, wo: Vec3) -> [f32; 3] {
    let t = position.first().copied().unwrap_or(0.0).clamp(-1.0, 1.0) * 0.5 + 0.5;
    let albedo = [0.2 + 0.6 * t, 0.5, 0.8 - 0.6 * t];
    let h = (wi + wo).normalize();
    let n = 40.0f32;
    let spec = 0.3 * (n + 2.0) / (2.0 * std::f32::consts::PI) * h.z.max(0.0).powf(n);
    albedo.map(|a| a / std::f32::consts::PI + spec)
}

/// `n` observations of [`reference_brdf`] under unit white light, with position values drawn
/// uniformly in [-1, 1] (`n_raw` of `position` per pixel).
pub fn observations(n: usize, position: PositionEncoding, seed: u64) -> Observations {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let np = position.input_len();
    let mut obs = Observations { n_position: np, ..Default::default() };
    for _ in 0..n {
        let p: Vec<f32> = (0..np).map(|_| rng.random_range(-1.0..1.0)).collect();
        let (wi, wo) = (random_up(&mut rng), random_up(&mut rng));
        let f = reference_brdf(&p, wi, wo);
        obs.radiance.push(f.map(|v| v * wi.z));
        obs.irradiance.push([1.0; 3]);
        obs.position.extend(p);
        obs.wi.push(wi);
        obs.wo.push(wo);
    }
    obs
}

/// Random valid direction pairs (for parity tests and benchmarks).
pub fn direction_pairs(n: usize, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| (random_up(&mut rng), random_up(&mut rng))).unzip()
}
