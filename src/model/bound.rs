//! A model's energy bound ([`crate::energy`]): its albedo curve at a prepared point, and the bound
//! that the trainer stores in the header ([`ModelHeader::with_albedo_bound`](crate::file::ModelHeader::with_albedo_bound)).

use super::{Model, Prepared};
use crate::energy::{albedo_curve, AlbedoBound, AlbedoCurve};

impl<'a> Model<'a> {
    /// The albedo bound the model evaluates with, if it is an energy-bounded model.
    #[inline]
    pub fn albedo_bound(&self) -> Option<&AlbedoBound> {
        self.header.albedo_bound.as_ref()
    }

    /// The same networks without the albedo bound: the values the model had before it was bounded.
    #[inline]
    pub fn unbounded(&self) -> Model<'a> {
        let mut m = *self;
        m.header.albedo_bound = None;
        m
    }

    /// The directional albedo of the unbounded model at the point `p` over the view angle
    /// ([`albedo_curve`]; 65 views × 4608 evaluations, in packets).
    pub fn albedo_curve(&self, p: &Prepared) -> AlbedoCurve {
        let raw = self.unbounded();
        albedo_curve(|wi, wo, out| raw.eval_many(p, wi, wo, out))
    }

    /// The albedo bound of the unbounded model over the prepared `points` ([`AlbedoBound::envelope`]
    /// of their curves): a uniform model needs its one point; a spatially varying one is bounded at the
    /// points given, and wherever its albedo stays under their envelope (docs/models.md).
    ///
    /// ```
    /// use nbrdf::file::{encode, set_albedo_bound, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::{ModelBuf, Vec3};
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 2e-3 - 0.1).collect();
    /// let bytes = encode(&h, &w, None).unwrap();
    /// let model = ModelBuf::from_bytes(&bytes).unwrap();
    /// let p = model.model().prepare(&[]).unwrap();
    /// let bound = model.model().fit_albedo_bound(&[p]);
    /// let bounded = ModelBuf::from_bytes(&set_albedo_bound(&bytes, Some(bound)).unwrap()).unwrap();
    /// let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.5, 0.2, 0.7).normalize());
    /// let f = bounded.model().eval(&p, wi, wo);
    /// assert_eq!(f, bounded.model().eval(&p, wo, wi)); // still reciprocal, bit for bit
    /// assert_eq!(bounded.model().unbounded().eval(&p, wi, wo), model.model().eval(&p, wi, wo));
    /// ```
    pub fn fit_albedo_bound(&self, points: &[Prepared]) -> AlbedoBound {
        AlbedoBound::envelope(points.iter().map(|p| self.albedo_curve(p)))
    }
}
