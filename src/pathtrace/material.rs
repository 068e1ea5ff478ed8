//! The one material of a path-traced scene: any [`Brdf`] of the crate with the importance sampling
//! that suits it. The integrator shades every hit through the [`Brdf`] trait of a [`Shading`].
//!
//! | BRDF | sampled with |
//! |---|---|
//! | parametric model, built-in material | its own lobes ([`crate::sampling`]) |
//! | `.nbrdf` model | a parametric model's own lobes at the point; a neural model's stored proxy |
//! | MERL table, NBRDF-json network | the proxy fitted to it at load ([`crate::sampling::fit_proxy`]) |
//!
//! [`Sampling::Cosine`] replaces all of that by cosine sampling, the baseline the tests compare with.

use std::string::String;
use std::sync::Arc;

use crate::brdf::{Brdf, BsdfSample};
use crate::builtin::Builtin;
use crate::file::{ModelKind, PositionEncoding};
use crate::measured::{MerlTable, NbrdfNetwork};
use crate::model::{ModelAt, ModelBuf, Prepared};
use crate::parametric::Parametric;
use crate::sampling::Proxy;
use crate::scene::Mesh;
use crate::{Error, Rgb, Vec3, BLACK};

/// How directions are importance-sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The BRDF's own [`Brdf::sample`]: its lobes or its proxy (table in the module docs).
    #[default]
    Native,
    /// Cosine-weighted hemisphere sampling for every BRDF (the baseline).
    Cosine,
}

/// A BRDF with its sampler.
#[derive(Clone)]
pub struct Material {
    source: Source,
    sampling: Sampling,
    /// What the BRDF is and how it samples itself, for reports.
    what: String,
}

// One per material: its size does not matter, and boxing the model would add an indirection per hit.
#[allow(clippy::large_enum_variant)]
#[derive(Clone)]
enum Source {
    /// The same BRDF at every point.
    Fixed(Arc<dyn Brdf + Send + Sync>),
    /// A `.nbrdf` model, prepared per point; a spatially uniform one once, here.
    Model { buf: ModelBuf, uniform: Option<Prepared> },
}

impl core::fmt::Debug for Material {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// The proxy's lobes in one line.
fn proxy_line(p: &Proxy) -> String {
    std::format!(
        "proxy: cosine {:.2}, GGX {:.2} (α {:.3}), GGX {:.2} (α {:.3})",
        p.diffuse, p.lobes[0].weight, p.lobes[0].alpha, p.lobes[1].weight, p.lobes[1].alpha
    )
}

impl Material {
    /// Any BRDF, the same at every point, described as `what` in reports.
    pub fn new(brdf: impl Brdf + Send + Sync + 'static, what: impl Into<String>) -> Self {
        Material { source: Source::Fixed(Arc::new(brdf)), sampling: Sampling::Native, what: what.into() }
    }

    /// An analytic model with fixed parameters.
    pub fn parametric(p: Parametric) -> Self {
        Self::new(p, std::format!("parametric {}, sampled by own lobes", p.kind().name()))
    }

    /// A built-in procedural material.
    pub fn builtin(b: Builtin) -> Self {
        Self::new(b, std::format!("built-in {}, sampled by own lobes", b.id()))
    }

    /// A MERL table (nearest lookup), sampled through its proxy.
    pub fn merl(t: MerlTable) -> Self {
        let what = std::format!("MERL table, sampled by {}", proxy_line(t.proxy()));
        Self::new(t, what)
    }

    /// An NBRDF-json network, sampled through its proxy.
    pub fn nbrdf_json(n: NbrdfNetwork) -> Self {
        let what = std::format!("NBRDF-json {}, sampled by {}", n.name(), proxy_line(n.proxy()));
        Self::new(n, what)
    }

    /// A `.nbrdf` model. Errors on a model with an intrinsic position encoding but no per-vertex
    /// table (the renderer has no eigenfunctions to interpolate).
    pub fn model(buf: ModelBuf) -> Result<Self, Error> {
        let h = *buf.header();
        if matches!(h.position, PositionEncoding::Intrinsic { .. }) && h.n_vertices == 0 {
            return Err(Error::InvalidValue {
                what: "model position encoding",
                reason: "intrinsic encoding without a per-vertex table cannot be rendered on a new mesh",
            });
        }
        let what = match h.kind {
            ModelKind::Parametric(k) => std::format!(".nbrdf {} network, sampled by own lobes at each point", k.name()),
            k if h.proxy.is_some() => std::format!(".nbrdf {k:?}, sampled by {}", proxy_line(&buf.model().proxy())),
            k => std::format!(".nbrdf {k:?}, sampled by cosine (no proxy in the file)"),
        };
        let uniform = match h.position {
            PositionEncoding::Uniform => Some(buf.model().prepare(&[])?),
            _ => None,
        };
        Ok(Material { source: Source::Model { buf, uniform }, sampling: Sampling::Native, what })
    }

    /// Checks that the material can shade `mesh`: a model with a per-vertex position table must have
    /// been fitted on this mesh (otherwise its features would be read from the wrong vertices and shade
    /// wrongly, or black): as many vertices, and the same [`Mesh::content_hash`] where the file records
    /// one (files exported before the hash was stored record only the count). Other materials fit
    /// every mesh.
    pub fn check_mesh(&self, mesh: &Mesh) -> Result<(), Error> {
        if let Source::Model { buf, .. } = &self.source {
            let h = buf.header();
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
        self
    }

    /// A one-line description for reports: the BRDF and its sampler.
    pub fn describe(&self) -> String {
        match self.sampling {
            Sampling::Native => self.what.clone(),
            Sampling::Cosine => {
                let what = self.what.split(", sampled by").next().unwrap_or(&self.what);
                std::format!("{what}, sampled by cosine (forced)")
            }
        }
    }

    /// The BRDF at a surface point: triangle `tri` with barycentrics `(b1, b2)` at world position `x`
    /// (for an extrinsic encoding the mesh should lie in the unit sphere, as in training).
    #[inline]
    pub fn point(&self, mesh: &Mesh, tri: u32, b1: f32, b2: f32, x: Vec3) -> Shading<'_> {
        let cosine = self.sampling == Sampling::Cosine;
        let at = match &self.source {
            Source::Fixed(brdf) => At::Fixed(&**brdf),
            Source::Model { buf, uniform: Some(p) } => At::Model(ModelAt { model: buf.model(), prepared: *p }),
            Source::Model { buf, uniform: None } => {
                let model = buf.model();
                let prepared = match model.header().position {
                    PositionEncoding::Extrinsic { .. } => model.prepare(&[x.x, x.y, x.z]),
                    PositionEncoding::Intrinsic { k } => {
                        let mut feat = [0.0f32; crate::file::MAX_INTRINSIC as usize];
                        let bary = [1.0 - b1 - b2, b1, b2];
                        model
                            .position_features(mesh.triangles[tri as usize], bary, &mut feat)
                            .and_then(|()| model.prepare(&feat[..k as usize]))
                    }
                    PositionEncoding::Uniform => model.prepare(&[]),
                };
                // A mesh that does not match the model's table shades black.
                prepared.map_or(At::Black, |prepared| At::Model(ModelAt { model, prepared }))
            }
        };
        Shading { at, cosine }
    }
}

/// A material at one surface point: the [`Brdf`] the integrator shades with.
#[derive(Clone, Copy)]
pub struct Shading<'a> {
    at: At<'a>,
    /// Sample the cosine lobe instead of the BRDF's own sampler.
    cosine: bool,
}

// Lives on the stack for one hit; boxing the prepared model would allocate per hit.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
enum At<'a> {
    Fixed(&'a (dyn Brdf + Send + Sync)),
    Model(ModelAt<'a>),
    Black,
}

impl Brdf for Shading<'_> {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        match &self.at {
            At::Fixed(b) => b.eval(wi, wo),
            At::Model(m) => m.eval(wi, wo),
            At::Black => BLACK,
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if self.cosine {
            return Proxy::COSINE.sample(wo, u, |wi, wo| self.eval(wi, wo));
        }
        match &self.at {
            At::Fixed(b) => b.sample(wo, u),
            At::Model(m) => m.sample(wo, u),
            At::Black => None,
        }
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if self.cosine {
            return Proxy::COSINE.pdf(wi, wo);
        }
        match &self.at {
            At::Fixed(b) => b.pdf(wi, wo),
            At::Model(m) => m.pdf(wi, wo),
            At::Black => 0.0,
        }
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        match &self.at {
            At::Fixed(b) => b.is_reciprocal(),
            At::Model(m) => m.is_reciprocal(),
            At::Black => true,
        }
    }
}
