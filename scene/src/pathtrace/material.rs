//! The one material of a path-traced scene: any [`Brdf`] of `nbrdf` with the importance sampling
//! that suits it. The integrator shades every hit through the [`Brdf`] trait of a [`Shading`].
//!
//! | BRDF | sampled with |
//! |---|---|
//! | parametric model, built-in material | its own lobes ([`nbrdf::sampling`]) |
//! | `.nbrdf` model | a parametric model's own lobes at the point; a neural model's stored per-view table (or proxy) |
//! | MERL table, NBRDF-json network | the per-view table fitted to it at load ([`nbrdf::sampling::fit_view_proxy`]) |
//!
//! [`Sampling::Cosine`] replaces all of that by cosine sampling, the baseline the tests compare with;
//! [`Sampling::Proxy`] samples a fitted BRDF through its single all-view proxy instead of its per-view
//! table, the sampler it replaced.

use std::string::String;
use std::sync::Arc;

use nbrdf::any::{self, AnyBrdf};
use nbrdf::brdf::{Brdf, BsdfSample};
use nbrdf::builtin::Builtin;
use nbrdf::file::PositionEncoding;
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::model::{ModelBuf, Prepared};
use nbrdf::parametric::Parametric;
use nbrdf::sampling::Proxy;
use crate::scene::Mesh;
use nbrdf::{Error, Rgb, Vec3, BLACK};

/// How directions are importance-sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The BRDF's own [`Brdf::sample`]: its lobes or its proxy (table in the module docs).
    #[default]
    Native,
    /// Cosine-weighted hemisphere sampling for every BRDF (the baseline).
    Cosine,
    /// The single all-view proxy of a neural model, MERL table or NBRDF-json network, as files and
    /// loaders did before the per-view table (for comparing the two); other BRDFs sample natively.
    Proxy,
}

/// A BRDF of `nbrdf` ([`AnyBrdf`], shared) with its sampler.
#[derive(Clone)]
pub struct Material {
    brdf: Arc<AnyBrdf<'static>>,
    sampling: Sampling,
    /// The mixture `sampling` samples instead of the BRDF's own sampler, worked out once.
    instead: Option<Proxy>,
}

impl core::fmt::Debug for Material {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Material {
    /// Any BRDF of `nbrdf`. Errors on a model with an intrinsic position encoding but no per-vertex
    /// table (the renderer has no eigenfunctions to interpolate).
    pub fn new(brdf: impl Into<Arc<AnyBrdf<'static>>>) -> Result<Self, Error> {
        let brdf = brdf.into();
        if let Some(m) = brdf.as_model() {
            let h = m.header();
            if matches!(h.position, PositionEncoding::Intrinsic { .. }) && h.n_vertices == 0 {
                return Err(Error::InvalidValue {
                    what: "model position encoding",
                    reason: "intrinsic encoding without a per-vertex table cannot be rendered on a new mesh",
                });
            }
        }
        Ok(Self::native(brdf))
    }

    /// `brdf` with its own sampler.
    fn native(brdf: Arc<AnyBrdf<'static>>) -> Self {
        Material { brdf, sampling: Sampling::Native, instead: None }
    }

    /// An analytic model with fixed parameters.
    pub fn parametric(p: Parametric) -> Self {
        Self::native(Arc::new(AnyBrdf::parametric(p)))
    }

    /// A built-in procedural material.
    pub fn builtin(b: Builtin) -> Self {
        Self::native(Arc::new(AnyBrdf::builtin(b)))
    }

    /// A MERL table (nearest lookup), sampled through its proxy.
    pub fn merl(t: MerlTable) -> Self {
        Self::native(Arc::new(AnyBrdf::merl(t)))
    }

    /// An NBRDF-json network, sampled through its proxy.
    pub fn nbrdf_json(n: NbrdfNetwork) -> Self {
        Self::native(Arc::new(AnyBrdf::nbrdf_json(n)))
    }

    /// A `.nbrdf` model (see [`Material::new`] for what is refused).
    pub fn model(buf: ModelBuf) -> Result<Self, Error> {
        Self::new(AnyBrdf::model(buf)?)
    }

    /// The BRDF.
    pub fn brdf(&self) -> &AnyBrdf<'static> {
        &self.brdf
    }

    /// Checks that the material can shade `mesh`: a model with a per-vertex position table must have
    /// been fitted on this mesh (otherwise its features would be read from the wrong vertices and shade
    /// wrongly, or black): as many vertices, and the same [`Mesh::content_hash`] where the file records
    /// one (files exported before the hash was stored record only the count). Other materials fit
    /// every mesh.
    pub fn check_mesh(&self, mesh: &Mesh) -> Result<(), Error> {
        if let Some(m) = self.brdf.as_model() {
            let h = m.header();
            let n = h.n_vertices as usize;
            if n > 0 && n != mesh.positions.len() {
                return Err(Error::SizeMismatch {
                    what: "mesh vertices (the model's per-vertex table was fitted on another mesh)",
                    expected: n,
                    found: mesh.positions.len(),
                });
            }
            if let Some(fitted) = h.mesh_hash.filter(|_| n > 0) {
                let found = mesh.content_hash();
                if found != fitted {
                    return Err(Error::Context {
                        what: "mesh".into(),
                        message: std::format!(
                            "the model's per-vertex table was fitted on another mesh with as many vertices \
                             (mesh hash {fitted:016x}, this mesh {found:016x}); render it on the mesh it was fitted on"
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// The same material sampled with `sampling`.
    pub fn with_sampling(mut self, sampling: Sampling) -> Self {
        self.sampling = sampling;
        self.instead = match sampling {
            Sampling::Native => None,
            Sampling::Cosine => Some(Proxy::COSINE),
            Sampling::Proxy => self.brdf.proxy(),
        };
        self
    }

    /// A one-line description for reports: the BRDF and its sampler.
    pub fn describe(&self) -> String {
        let what = self.brdf.describe();
        match self.sampling {
            Sampling::Native => what,
            Sampling::Cosine => {
                let what = what.split(", sampled").next().unwrap_or(&what);
                std::format!("{what}, sampled by cosine (forced)")
            }
            Sampling::Proxy => match self.instead {
                Some(_) => {
                    let what = what.split(", sampled").next().unwrap_or(&what);
                    std::format!("{what}, sampled by its single all-view proxy (forced)")
                }
                None => what,
            },
        }
    }

    /// The BRDF at a surface point: triangle `tri` with barycentrics `(b1, b2)` at world position `x`
    /// (for an extrinsic encoding the mesh should lie in the unit sphere, as in training).
    #[inline]
    pub fn point(&self, mesh: &Mesh, tri: u32, b1: f32, b2: f32, x: Vec3) -> Shading<'_> {
        let instead = self.instead;
        // A BRDF that is the same everywhere, or a model prepared once at load.
        if let Some(at) = self.brdf.at_prepared(None) {
            return Shading { at: Some(at), instead };
        }
        let prepared: Result<Prepared, Error> = match self.brdf.as_model().map(|m| m.header().position) {
            Some(PositionEncoding::Extrinsic { .. }) => self.brdf.prepare(&[x.x, x.y, x.z]),
            Some(PositionEncoding::Intrinsic { k }) => {
                let mut feat = [0.0f32; nbrdf::file::MAX_INTRINSIC as usize];
                let feat = &mut feat[..k as usize];
                let bary = [1.0 - b1 - b2, b1, b2];
                self.brdf.position_features(mesh.triangles[tri as usize], bary, feat).and_then(|()| self.brdf.prepare(feat))
            }
            _ => return Shading { at: None, instead },
        };
        // A mesh that does not match the model's table shades black.
        Shading { at: prepared.ok().and_then(|p| self.brdf.at_prepared(Some(&p))), instead }
    }
}

/// A material at one surface point: the [`Brdf`] the integrator shades with.
#[derive(Clone, Copy)]
pub struct Shading<'a> {
    /// None where a mesh does not match the model's per-vertex table: it shades black.
    at: Option<any::At<'a>>,
    /// A mixture to sample instead of the BRDF's own sampler (the cosine lobe, or its single proxy).
    instead: Option<Proxy>,
}

impl Brdf for Shading<'_> {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        self.at.map_or(BLACK, |b| b.eval(wi, wo))
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if let Some(proxy) = &self.instead {
            return proxy.sample(wo, u, |wi, wo| self.eval(wi, wo));
        }
        self.at.and_then(|b| b.sample(wo, u))
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if let Some(proxy) = &self.instead {
            return proxy.pdf(wi, wo);
        }
        self.at.map_or(0.0, |b| b.pdf(wi, wo))
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        self.at.is_none_or(|b| b.is_reciprocal())
    }
}
