//! The one material of a path-traced scene: any BRDF the crate evaluates, with the importance sampling
//! that suits it, behind one `eval`/`sample`/`pdf` surface.
//!
//! | BRDF | sampled with |
//! |---|---|
//! | parametric model, built-in material | its own lobes ([`crate::sampling`]) |
//! | `.nbrdf` model | a parametric model's own lobes at the point; a neural model's stored proxy |
//! | MERL table, NBRDF-json network | a proxy fitted here, once ([`crate::sampling::fit_proxy`]) |
//!
//! [`Sampling::Cosine`] replaces all of that by cosine sampling, the baseline the tests compare with.

use std::string::String;

use crate::builtin::Builtin;
use crate::file::PositionEncoding;
use crate::model::ModelBuf;
use crate::measured::{MerlTable, NbrdfNetwork};
use crate::model::Prepared;
use crate::parametric::Parametric;
use crate::sampling::{BsdfSample, Proxy};
use crate::scene::Mesh;
use crate::{Error, Rgb, Vec3};

/// A BRDF the renderer can shade with.
#[derive(Clone, Debug)]
pub enum Brdf {
    /// An analytic model with fixed parameters.
    Parametric(Parametric),
    /// A built-in procedural material.
    Builtin(Builtin),
    /// A MERL table (nearest lookup).
    Merl(MerlTable),
    /// An NBRDF-json network.
    NbrdfJson(NbrdfNetwork),
    /// A `.nbrdf` model file.
    Model(ModelBuf),
}

/// How directions are importance-sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The model's own lobes or its proxy (table in the module docs).
    #[default]
    Native,
    /// Cosine-weighted hemisphere sampling for every BRDF (the baseline).
    Cosine,
}

/// A BRDF with its sampler.
#[derive(Clone, Debug)]
pub struct Material {
    brdf: Brdf,
    proxy: Proxy,
    sampling: Sampling,
    /// The prepared state of a spatially uniform `.nbrdf` model, computed once instead of per hit.
    uniform: Option<Prepared>,
}

/// What a material needs to know about a surface point: the prepared state of a `.nbrdf` model.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    prepared: Option<Prepared>,
}

impl Material {
    /// A material with native sampling. Measured materials get their proxy fitted here; a `.nbrdf`
    /// model uses the proxy in its header. Errors on a model with an intrinsic position encoding but no
    /// per-vertex table (the renderer has no eigenfunctions to interpolate).
    pub fn new(brdf: Brdf) -> Result<Self, Error> {
        let proxy = match &brdf {
            Brdf::Merl(t) => t.fit_proxy(),
            Brdf::NbrdfJson(n) => n.fit_proxy(),
            Brdf::Model(m) => {
                let h = m.header();
                if matches!(h.position, PositionEncoding::Intrinsic { .. }) && h.n_vertices == 0 {
                    return Err(Error::InvalidValue {
                        what: "model position encoding",
                        reason: "intrinsic encoding without a per-vertex table cannot be rendered on a new mesh",
                    });
                }
                m.model().proxy()
            }
            Brdf::Parametric(_) | Brdf::Builtin(_) => Proxy::COSINE,
        };
        let uniform = match &brdf {
            Brdf::Model(m) if m.header().position == PositionEncoding::Uniform => Some(m.model().prepare(&[])),
            _ => None,
        };
        Ok(Material { brdf, proxy, sampling: Sampling::Native, uniform })
    }

    /// The same material sampled with `sampling`.
    pub fn with_sampling(mut self, sampling: Sampling) -> Self {
        self.sampling = sampling;
        self
    }

    /// The BRDF.
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The proxy used for measured and neural BRDFs ([`Proxy::COSINE`] for the others).
    pub fn proxy(&self) -> &Proxy {
        &self.proxy
    }

    /// A one-line description for reports: the BRDF and its sampler.
    pub fn describe(&self) -> String {
        let proxy = |p: &Proxy| {
            std::format!(
                "proxy: cosine {:.2}, GGX {:.2} (α {:.3}), GGX {:.2} (α {:.3})",
                p.diffuse, p.lobes[0].weight, p.lobes[0].alpha, p.lobes[1].weight, p.lobes[1].alpha
            )
        };
        let (what, native) = match &self.brdf {
            Brdf::Parametric(p) => (std::format!("parametric {}", p.kind().name()), String::from("own lobes")),
            Brdf::Builtin(b) => (std::format!("built-in {}", b.id()), String::from("own lobes")),
            Brdf::Merl(_) => (String::from("MERL table"), proxy(&self.proxy)),
            Brdf::NbrdfJson(n) => (std::format!("NBRDF-json {}", n.name()), proxy(&self.proxy)),
            Brdf::Model(m) => match m.header().kind {
                crate::file::ModelKind::Parametric(k) => {
                    (std::format!(".nbrdf {} network", k.name()), String::from("own lobes at each point"))
                }
                k => (
                    std::format!(".nbrdf {k:?}"),
                    if m.header().proxy.is_some() { proxy(&self.proxy) } else { String::from("no proxy in file: cosine") },
                ),
            },
        };
        match self.sampling {
            Sampling::Native => std::format!("{what}, sampled by {native}"),
            Sampling::Cosine => std::format!("{what}, sampled by cosine (forced)"),
        }
    }

    /// Prepares the material at a surface point: triangle `tri` with barycentrics `(b1, b2)` at world
    /// position `x` (for an extrinsic encoding the mesh should lie in the unit sphere, as in training).
    #[inline]
    pub fn point(&self, mesh: &Mesh, tri: u32, b1: f32, b2: f32, x: Vec3) -> ShadingPoint {
        let Brdf::Model(buf) = &self.brdf else { return ShadingPoint { prepared: None } };
        if self.uniform.is_some() {
            return ShadingPoint { prepared: self.uniform };
        }
        let model = buf.model();
        let prepared = match model.header().position {
            PositionEncoding::Uniform => model.prepare(&[]),
            PositionEncoding::Extrinsic { .. } => model.prepare(&[x.x, x.y, x.z]),
            PositionEncoding::Intrinsic { k } => {
                let mut feat = [0.0f32; crate::file::MAX_INTRINSIC as usize];
                let bary = [1.0 - b1 - b2, b1, b2];
                match model.position_features(mesh.triangles[tri as usize], bary, &mut feat) {
                    Ok(()) => model.prepare(&feat[..k as usize]),
                    // A mesh that does not match the table: an invalid state that shades black.
                    Err(_) => model.prepare(&[]),
                }
            }
        };
        ShadingPoint { prepared: Some(prepared) }
    }

    /// The BRDF value at a point for local directions.
    #[inline]
    pub fn eval(&self, pt: &ShadingPoint, wi: Vec3, wo: Vec3) -> Rgb {
        match &self.brdf {
            Brdf::Parametric(p) => p.eval(wi, wo),
            Brdf::Builtin(b) => b.eval(wi, wo),
            Brdf::Merl(t) => t.eval(wi, wo),
            Brdf::NbrdfJson(n) => n.eval(wi, wo),
            Brdf::Model(m) => match &pt.prepared {
                Some(p) => m.model().eval(p, wi, wo),
                None => [0.0; 3],
            },
        }
    }

    /// Samples `wi` for the view `wo` (three uniform numbers).
    #[inline]
    pub fn sample(&self, pt: &ShadingPoint, u: [f32; 3], wo: Vec3) -> Option<BsdfSample> {
        if self.sampling == Sampling::Cosine {
            return Proxy::COSINE.sample(u, wo, |wi, wo| self.eval(pt, wi, wo));
        }
        match &self.brdf {
            Brdf::Parametric(p) => p.sample(u, wo),
            Brdf::Builtin(b) => b.sample(u, wo),
            Brdf::Merl(_) | Brdf::NbrdfJson(_) => self.proxy.sample(u, wo, |wi, wo| self.eval(pt, wi, wo)),
            Brdf::Model(m) => m.model().sample(pt.prepared.as_ref()?, u, wo),
        }
    }

    /// Density of [`Material::sample`] at `wi`.
    #[inline]
    pub fn pdf(&self, pt: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        if self.sampling == Sampling::Cosine {
            return Proxy::COSINE.pdf(wo, wi);
        }
        match &self.brdf {
            Brdf::Parametric(p) => p.pdf(wo, wi),
            Brdf::Builtin(b) => b.pdf(wo, wi),
            Brdf::Merl(_) | Brdf::NbrdfJson(_) => self.proxy.pdf(wo, wi),
            Brdf::Model(m) => pt.prepared.as_ref().map_or(0.0, |p| m.model().pdf(p, wo, wi)),
        }
    }
}
