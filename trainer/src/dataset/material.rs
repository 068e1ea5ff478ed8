//! Ground-truth materials of the semi-synthetic data set: what `--material` names, how the data set
//! file records it, and how it is evaluated.

use std::path::Path;

use nbrdf::{Error, Rgb, Vec3};
use serde::{Deserialize, Serialize};

use super::err;

/// A material as named on the command line and stored in `dataset.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum MaterialSpec {
    /// Lambertian reflector `f = albedo / π`: the analytic reference of the tests.
    Lambert {
        /// Diffuse albedo per channel, in `[0, 1]`.
        albedo: [f32; 3],
    },
}

impl MaterialSpec {
    /// Parses a command-line material: `lambert:R,G,B` (or `lambert:A`).
    ///
    /// ```
    /// use trainer::dataset::material::MaterialSpec;
    /// assert_eq!(MaterialSpec::parse("lambert:0.5").unwrap(), MaterialSpec::Lambert { albedo: [0.5; 3] });
    /// assert!(MaterialSpec::parse("velvet").is_err());
    /// ```
    pub fn parse(s: &str) -> Result<Self, Error> {
        if let Some(rest) = s.strip_prefix("lambert:") {
            let v: Vec<f32> = rest
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<Result<_, _>>()
                .map_err(|e| err("material", format!("lambert albedo '{rest}': {e}")))?;
            let albedo = match v[..] {
                [a] => [a; 3],
                [r, g, b] => [r, g, b],
                _ => return Err(err("material", format!("lambert takes 1 or 3 albedo values, got {}", v.len()))),
            };
            if !albedo.iter().all(|a| (0.0..=1.0).contains(a)) {
                return Err(err("material", "lambert albedo must lie in [0, 1]"));
            }
            return Ok(MaterialSpec::Lambert { albedo });
        }
        Err(err(
            "material",
            format!("unknown material '{s}': expected lambert:R,G,B"),
        ))
    }

    /// Loads what the spec refers to; relative paths are resolved against `base`.
    pub fn load(&self, _base: &Path) -> Result<Material, Error> {
        match self {
            MaterialSpec::Lambert { albedo } => Ok(Material::Lambert { albedo: *albedo }),
        }
    }
}

/// A loaded ground-truth material.
#[derive(Debug, Clone)]
pub enum Material {
    /// `albedo / π`.
    Lambert {
        /// Albedo per channel.
        albedo: [f32; 3],
    },
}

impl Material {
    /// `f(wi, wo)` in 1/sr for local directions (normal `+z`); 0 below the horizon.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        if nbrdf::angles::upper_hemisphere_pair(wi, wo).is_none() {
            return nbrdf::BLACK;
        }
        match self {
            Material::Lambert { albedo } => albedo.map(|a| a * std::f32::consts::FRAC_1_PI),
        }
    }
}
