//! Ground-truth materials of the semi-synthetic data set: what `--material` names, how the data set
//! file records it, and how it is evaluated.

use std::path::{Path, PathBuf};

use nbrdf::builtin::Builtin;
use nbrdf::measured::{MerlTable, NbrdfNetwork};
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
    /// A procedural measured-like material of `nbrdf::builtin`.
    Builtin {
        /// Its id.
        id: String,
    },
    /// A MERL `.binary` table (Matusik et al. 2003), evaluated with the reference nearest-bin lookup.
    Merl {
        /// The file (absolute, or relative to the data set folder).
        path: PathBuf,
    },
    /// An NBRDF-json network (Sztrajman et al. 2021), e.g. `../shared/data/nbrdf-merl/*.json`.
    NbrdfJson {
        /// The file (absolute, or relative to the data set folder).
        path: PathBuf,
    },
}

impl MaterialSpec {
    /// Parses a command-line material: `lambert:R,G,B` (or `lambert:A`), a built-in id (optionally
    /// `builtin:ID`), or a file: `*.binary` is a MERL table, `*.json` an NBRDF-json network.
    ///
    /// ```
    /// use trainer::dataset::material::MaterialSpec;
    /// assert_eq!(MaterialSpec::parse("lambert:0.5").unwrap(), MaterialSpec::Lambert { albedo: [0.5; 3] });
    /// assert_eq!(MaterialSpec::parse("velvet").unwrap(), MaterialSpec::Builtin { id: "velvet".into() });
    /// assert!(matches!(MaterialSpec::parse("x/chrome.json").unwrap(), MaterialSpec::NbrdfJson { .. }));
    /// assert!(MaterialSpec::parse("felt").is_err());
    /// ```
    pub fn parse(s: &str) -> crate::Result<Self> {
        if let Some(rest) = s.strip_prefix("lambert:") {
            let v: Vec<f32> = rest
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<Result<_, _>>()
                .map_err(|e| err("material", format!("lambert albedo '{rest}': {e}")))?;
            let albedo = match v[..] {
                [a] => [a; 3],
                [r, g, b] => [r, g, b],
                _ => return Err(crate::Error::from(err("material", format!("lambert takes 1 or 3 albedo values, got {}", v.len())))),
            };
            if !albedo.iter().all(|a| (0.0..=1.0).contains(a)) {
                return Err(crate::Error::from(err("material", "lambert albedo must lie in [0, 1]")));
            }
            return Ok(MaterialSpec::Lambert { albedo });
        }
        let id = s.strip_prefix("builtin:").unwrap_or(s);
        if let Some(b) = Builtin::from_id(id) {
            return Ok(MaterialSpec::Builtin { id: b.id().into() });
        }
        let path = PathBuf::from(s);
        match path.extension().and_then(|e| e.to_str()) {
            Some("binary") => Ok(MaterialSpec::Merl { path }),
            Some("json") => Ok(MaterialSpec::NbrdfJson { path }),
            _ => Err(crate::Error::from(err(
                "material",
                format!(
                    "unknown material '{s}': expected lambert:R,G,B, a built-in ({}), a MERL .binary or an NBRDF .json file",
                    Builtin::ALL.map(|b| b.id()).join(", ")
                ),
            ))),
        }
    }

    /// The spec with file paths made absolute (for `dataset.json`, so that it does not depend on the
    /// working directory of whoever reads it).
    pub fn canonical(&self) -> crate::Result<Self> {
        let abs = |p: &PathBuf| std::fs::canonicalize(p).map_err(|e| Error::io(p, &e));
        Ok(match self {
            MaterialSpec::Merl { path } => MaterialSpec::Merl { path: abs(path)? },
            MaterialSpec::NbrdfJson { path } => MaterialSpec::NbrdfJson { path: abs(path)? },
            other => other.clone(),
        })
    }

    /// Loads what the spec refers to; relative paths are resolved against `base`.
    pub fn load(&self, base: &Path) -> crate::Result<Material> {
        let resolve = |p: &PathBuf| if p.is_absolute() { p.clone() } else { base.join(p) };
        Ok(match self {
            MaterialSpec::Lambert { albedo } => Material::Lambert { albedo: *albedo },
            MaterialSpec::Builtin { id } => Material::Builtin(
                Builtin::from_id(id).ok_or_else(|| err("material", format!("unknown built-in material '{id}'")))?,
            ),
            MaterialSpec::Merl { path } => Material::Merl(Box::new(MerlTable::read(resolve(path))?)),
            MaterialSpec::NbrdfJson { path } => Material::NbrdfJson(Box::new(NbrdfNetwork::load(resolve(path))?)),
        })
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
    /// A built-in procedural material.
    Builtin(Builtin),
    /// A MERL table.
    Merl(Box<MerlTable>),
    /// An NBRDF-json network.
    NbrdfJson(Box<NbrdfNetwork>),
}

impl Material {
    /// The same material for the path tracer.
    pub fn path_traced(&self) -> crate::Result<nbrdf_scene::pathtrace::Material> {
        use nbrdf_scene::pathtrace::Material as Pt;
        Ok(match self {
            Material::Lambert { albedo } => {
                Pt::new(nbrdf::any::AnyBrdf::from_params(nbrdf::parametric::ParametricKind::Lambert, albedo)?)?
            }
            Material::Builtin(b) => Pt::builtin(*b),
            Material::Merl(t) => Pt::merl((**t).clone()),
            Material::NbrdfJson(n) => Pt::nbrdf_json((**n).clone()),
        })
    }

    /// `f(wi, wo)` in 1/sr for local directions (normal `+z`); 0 below the horizon.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        if nbrdf::angles::upper_hemisphere_pair(wi, wo).is_none() {
            return nbrdf::BLACK;
        }
        match self {
            Material::Lambert { albedo } => albedo.map(|a| a * std::f32::consts::FRAC_1_PI),
            Material::Builtin(b) => b.eval(wi, wo),
            Material::Merl(t) => t.eval(wi, wo),
            Material::NbrdfJson(n) => n.eval(wi, wo),
        }
    }
}
