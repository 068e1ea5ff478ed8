//! Environment lights: radiance arriving from infinitely far away in every direction, either one
//! constant colour (the white furnace) or a latitude-longitude HDR map.
//!
//! Map convention: world `+y` is up; pixel row `v` covers the polar angle `θ = π v / H` from `+y`, column
//! `u` the azimuth `φ = 2π u / W` measured from `+x` toward `+z`; direction
//! `(sin θ cos φ, cos θ, sin θ sin φ)`. Radiance is looked up nearest (constant per pixel), the same
//! piecewise-constant function the sampling distribution is built on, so sampling and evaluation agree.
//!
//! A map is importance-sampled by a 2D piecewise-constant distribution over its pixels proportional to
//! luminance × `sin θ` (pbrt-v3, Sec. 14.2.4): a point `(u, v)` with density `p(u, v)` has solid-angle
//! density `p(u, v) / (2π² sin θ)`. The constant environment samples the uniform sphere.

use super::distribution::Distribution2D;
use crate::image::RgbImage;
use nbrdf::math::{safe_sqrt, PI};
use nbrdf::{Error, Rgb, Vec3};

/// An environment light.
#[derive(Clone, Debug)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Rgb),
    /// A lat-long map with its sampling distribution.
    Map(EnvMap),
}

/// A lat-long environment map ready to sample.
#[derive(Clone, Debug)]
pub struct EnvMap {
    image: RgbImage,
    dist: Distribution2D,
}

/// A sampled light direction with its radiance and solid-angle density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit world direction toward the light.
    pub dir: Vec3,
    /// Radiance arriving along `-dir`.
    pub radiance: Rgb,
    /// Density per unit solid angle, > 0.
    pub pdf: f32,
}

#[inline]
fn lum(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl Environment {
    /// A lat-long map; errors on an empty image or on negative or non-finite radiance (named by pixel).
    pub fn from_image(image: RgbImage) -> Result<Self, Error> {
        let (w, h) = (image.width as usize, image.height as usize);
        if w == 0 || h == 0 {
            return Err(Error::InvalidValue { what: "environment map", reason: "image is empty" });
        }
        if let Some(i) = image.data.iter().position(|p| p.iter().any(|c| !(c.is_finite() && *c >= 0.0))) {
            return Err(Error::NonFinite { what: "environment map pixel (negative or not finite)", index: i });
        }
        let func: std::vec::Vec<f32> = (0..w * h)
            .map(|i| lum(image.data[i]) * libm::sinf(PI * ((i / w) as f32 + 0.5) / h as f32))
            .collect();
        Ok(Environment::Map(EnvMap { dist: Distribution2D::new(&func, w, h), image }))
    }

    /// Reads a lat-long OpenEXR map.
    pub fn load_exr(path: impl AsRef<std::path::Path>) -> Result<Self, Error> {
        Self::from_image(crate::image::read_exr(path)?)
    }

    /// Whether no radiance arrives from anywhere (then nothing needs to sample it).
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.iter().all(|&x| x <= 0.0),
            Environment::Map(m) => m.image.data.iter().all(|p| p.iter().all(|&x| x <= 0.0)),
        }
    }

    /// Radiance arriving from the unit direction `dir`.
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Rgb {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(m) => {
                let [u, v] = to_uv(dir);
                let (w, h) = (m.image.width, m.image.height);
                let col = ((u * w as f32) as u32).min(w - 1);
                let row = ((v * h as f32) as u32).min(h - 1);
                m.image.get(col, row)
            }
        }
    }

    /// A direction toward the environment for two uniform numbers, or `None` at a pole of the map
    /// (`sin θ = 0`, measure zero).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Option<LightSample> {
        match self {
            Environment::Constant(c) => {
                // Uniform sphere: z = 1 - 2u, density 1/(4π).
                let z = 1.0 - 2.0 * u[0];
                let r = safe_sqrt(1.0 - z * z);
                let (s, co) = libm::sincosf(2.0 * PI * u[1]);
                Some(LightSample { dir: Vec3::new(r * co, z, r * s), radiance: *c, pdf: 0.25 / PI })
            }
            Environment::Map(m) => {
                let uv = m.dist.sample(u);
                let dir = from_uv(uv);
                let pdf = self.pdf(dir);
                (pdf > 0.0).then(|| LightSample { dir, radiance: self.eval(dir), pdf })
            }
        }
    }

    /// Solid-angle density of [`Environment::sample`] at the unit direction `dir`.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => 0.25 / PI,
            Environment::Map(m) => {
                let uv = to_uv(dir);
                let sin_t = libm::sinf(PI * uv[1]);
                if sin_t <= 0.0 {
                    return 0.0;
                }
                m.dist.pdf(uv) / (2.0 * PI * PI * sin_t)
            }
        }
    }
}

/// Map coordinates `[u, v] ∈ [0, 1)²` of a unit direction (module docs).
#[inline]
pub fn to_uv(d: Vec3) -> [f32; 2] {
    let theta = nbrdf::math::safe_acos(d.y);
    let mut phi = libm::atan2f(d.z, d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    [(phi / (2.0 * PI)).min(1.0 - f32::EPSILON), (theta / PI).min(1.0 - f32::EPSILON)]
}

/// The unit direction of map coordinates `[u, v]` (inverse of [`to_uv`]).
///
/// ```
/// use nbrdf_scene::pathtrace::environment::{from_uv, to_uv};
/// let d = from_uv([0.3, 0.4]);
/// let uv = to_uv(d);
/// assert!((uv[0] - 0.3).abs() < 1e-5 && (uv[1] - 0.4).abs() < 1e-5);
/// assert!((from_uv([0.0, 0.0]).y - 1.0).abs() < 1e-6); // v = 0 is straight up
/// ```
#[inline]
pub fn from_uv(uv: [f32; 2]) -> Vec3 {
    let (st, ct) = libm::sincosf(PI * uv[1]);
    let (sp, cp) = libm::sincosf(2.0 * PI * uv[0]);
    Vec3::new(st * cp, ct, st * sp)
}
