//! Importance sampling of a loaded [`Model`]: a parametric model samples its own lobes with the
//! parameters its network predicted at the point; a neural model samples the [`Proxy`] stored in its
//! file header (pure cosine sampling if the file has none) and evaluates the network for the weight.
//! Either way the pdf is the density actually sampled, so `weight = f cos θi / pdf` is unbiased.
//!
//! These methods live with the model rather than in [`crate::sampling`], which they use: the samplers
//! and the proxy sit below the model file and its evaluator, and import neither.

use super::{Model, Prepared};
use crate::sampling::{fit_proxy, BsdfSample, Proxy};
use crate::{Rgb, Vec3};

impl Model<'_> {
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
    /// let (model, p) = (buf.model(), buf.model().prepare(&[]));
    /// let wo = Vec3::new(0.2, 0.1, 0.9).normalize();
    /// let s = model.sample(&p, [0.3, 0.6, 0.2], wo).unwrap();
    /// assert_eq!(s.pdf, model.pdf(&p, wo, s.wi));
    /// ```
    #[inline]
    pub fn sample(&self, prepared: &Prepared, u: [f32; 3], wo: Vec3) -> Option<BsdfSample> {
        match prepared.parameters() {
            Some(params) if prepared.valid => params.sample(u, wo),
            _ => self.proxy().sample(u, wo, |wi, wo| self.eval(prepared, wi, wo)),
        }
    }

    /// Density of [`Model::sample`] at `wi` per unit solid angle.
    #[inline]
    pub fn pdf(&self, prepared: &Prepared, wo: Vec3, wi: Vec3) -> f32 {
        match prepared.parameters() {
            Some(params) if prepared.valid => params.pdf(wo, wi),
            _ => self.proxy().pdf(wo, wi),
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
        let n = points.len() as f32;
        fit_proxy(|wi, wo| {
            let mut f: Rgb = [0.0; 3];
            for p in points {
                let v = self.eval(p, wi, wo);
                (0..3).for_each(|c| f[c] += v[c] / n);
            }
            f
        })
    }
}
