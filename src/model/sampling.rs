//! Importance sampling of a loaded [`Model`]: a parametric model samples its own lobes with the
//! parameters its network predicted at the point; a neural model samples the [`ViewProxy`] stored in
//! its file header, or the single [`Proxy`] of files written before it (pure cosine sampling if the
//! file has neither), and evaluates the network for the weight.
//! Either way the pdf is the density actually sampled, so `weight = f cos θi / pdf` is unbiased.
//! [`ModelAt`] is the model at one prepared point: a [`Brdf`] like every other BRDF of the crate.
//!
//! These methods live with the model rather than in [`crate::sampling`], which they use: the samplers
//! and the proxy sit below the model file and its evaluator, and import neither.

use super::{Model, Prepared};
use crate::brdf::{Brdf, BsdfSample};
use crate::file::{ModelKind, Reciprocity};
use crate::sampling::{fit_proxy, fit_view_proxy_around, Proxy, ViewProxy};
use crate::{Error, Rgb, Vec3};

impl<'a> Model<'a> {
    /// Whether the model is reciprocal by construction: a parametric model (its formula is) or a
    /// neural model on the reciprocity map Θ (Sec. 4.3; bitwise). Random swapping only trains toward it.
    #[inline]
    pub fn is_reciprocal(&self) -> bool {
        matches!(self.header().kind, ModelKind::Parametric(_)) || self.header().reciprocity == Reciprocity::Exact
    }

    /// The model at the point `p` (see [`Model::prepare`]) as a [`Brdf`].
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::{Brdf, ModelBuf, Vec3};
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
    /// let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    /// let brdf = buf.model().at(&[]).unwrap();
    /// let wo = Vec3::new(0.2, 0.1, 0.9).normalize();
    /// let s = brdf.sample(wo, [0.3, 0.6, 0.2]).unwrap();
    /// assert_eq!(s.pdf, brdf.pdf(s.wi, wo));
    /// assert!(brdf.is_reciprocal());
    /// assert!(buf.model().at(&[0.5]).is_err()); // a uniform model has no point input
    /// ```
    #[inline]
    pub fn at(&self, p: &[f32]) -> Result<ModelAt<'a>, Error> {
        Ok(ModelAt { model: *self, prepared: self.prepare(p)? })
    }

    /// The sampling proxy of a neural model: the one stored in the file, else [`Proxy::COSINE`].
    #[inline]
    pub fn proxy(&self) -> Proxy {
        self.header().proxy.unwrap_or(Proxy::COSINE)
    }

    /// Samples `wi` for the view `wo` at a prepared point; `u` is three uniform numbers in [0, 1).
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::ModelBuf;
    /// use nbrdf::Vec3;
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
    /// let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    /// let (model, p) = (buf.model(), buf.model().prepare(&[]).unwrap());
    /// let wo = Vec3::new(0.2, 0.1, 0.9).normalize();
    /// let s = model.sample(&p, wo, [0.3, 0.6, 0.2]).unwrap();
    /// assert_eq!(s.pdf, model.pdf(&p, s.wi, wo));
    /// ```
    #[inline]
    pub fn sample(&self, prepared: &Prepared, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let brdf = |wi, wo| self.eval(prepared, wi, wo);
        match (prepared.parameters(), &self.header().view_proxy) {
            (Some(params), _) if prepared.valid => {
                // The lobes sample the unbounded formula; the weight takes the bound's divisor.
                let s = params.sample(wo, u)?;
                Some(BsdfSample { weight: self.bounded(s.weight, s.wi, wo), ..s })
            }
            (_, Some(view)) => view.sample(wo, u, brdf),
            _ => self.proxy().sample(wo, u, brdf),
        }
    }

    /// Density of [`Model::sample`] at `wi` per unit solid angle.
    #[inline]
    pub fn pdf(&self, prepared: &Prepared, wi: Vec3, wo: Vec3) -> f32 {
        match (prepared.parameters(), &self.header().view_proxy) {
            (Some(params), _) if prepared.valid => params.pdf(wi, wo),
            (_, Some(view)) => view.pdf(wi, wo),
            _ => self.proxy().pdf(wi, wo),
        }
    }

    /// Fits a proxy to this model averaged over the given prepared points (one point for a uniform
    /// material; a few representative surface points for a spatially varying one): what the trainer
    /// stores in the header at export ([`ModelHeader::with_proxy`](crate::file::ModelHeader::with_proxy)).
    /// No points gives [`Proxy::COSINE`].
    pub fn fit_proxy(&self, points: &[Prepared]) -> Proxy {
        if points.is_empty() {
            return Proxy::COSINE;
        }
        fit_proxy(|wi, wo| self.mean_over(points, wi, wo))
    }

    /// Fits the per-view sampling table to this model averaged over the given prepared points around
    /// its all-view proxy `global` ([`Model::fit_proxy`] of the same points): what the trainer stores
    /// beside it ([`ModelHeader::with_view_proxy`](crate::file::ModelHeader::with_view_proxy)). No points
    /// gives cosine sampling at every view.
    pub fn fit_view_proxy(&self, points: &[Prepared], global: &Proxy) -> ViewProxy {
        if points.is_empty() {
            return ViewProxy::default();
        }
        fit_view_proxy_around(|wi, wo| self.mean_over(points, wi, wo), global)
    }

    /// The model's mean value over `points`.
    fn mean_over(&self, points: &[Prepared], wi: Vec3, wo: Vec3) -> Rgb {
        let n = points.len() as f32;
        let mut f: Rgb = [0.0; 3];
        for p in points {
            let v = self.eval(p, wi, wo);
            (0..3).for_each(|c| f[c] += v[c] / n);
        }
        f
    }
}

/// A model at one prepared point: the [`Brdf`] a renderer shades a hit with. Cheap to copy (the
/// model borrows its weights; the prepared state is a few hundred bytes).
#[derive(Clone, Copy, Debug)]
pub struct ModelAt<'a> {
    /// The model.
    pub model: Model<'a>,
    /// Its state at the point ([`Model::prepare`]).
    pub prepared: Prepared,
}

impl Brdf for ModelAt<'_> {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        self.model.eval(&self.prepared, wi, wo)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        self.model.sample(&self.prepared, wo, u)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.model.pdf(&self.prepared, wi, wo)
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        self.model.is_reciprocal()
    }
}
