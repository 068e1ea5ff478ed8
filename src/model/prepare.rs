//! Per-point preparation: [`Prepared`], what a model computes once per shading point, and
//! [`Model::prepare`] / [`Model::prepare_many`], which run the networks that read the position.

use super::{Model, Weights, MAX_POSITION_INPUT};
use crate::encoding::positional_encoding;
use crate::file::{ModelKind, PositionEncoding, MAX_NETS};
use crate::mlp::{Net, Partial, Weight, PACKET};
use crate::neural::{additive_separate, additive_shared, parametric_net, single_mlp};
use crate::parametric::Parametric;
use crate::{Error, Rgb, BLACK};

/// What [`Model::prepare`] computes once per shading point.
#[derive(Clone, Copy, Debug)]
pub struct Prepared {
    /// Position part of the direction network's layer 0 and skip layer.
    pub(crate) partial: Partial,
    /// Diffuse term `f_d(x)` of the additive models.
    pub(crate) diffuse: Rgb,
    /// Parameters of a parametric model at the point.
    pub(crate) params: Option<Parametric>,
    /// False for [`Prepared::default`], the state of no point: every evaluation then gives 0.
    pub(crate) valid: bool,
}

/// The state of no point: every evaluation gives 0 and every sample is the model's proxy's with
/// weight 0. What [`Model::prepare_many`]'s output starts as.
impl Default for Prepared {
    fn default() -> Self {
        Prepared { partial: Partial::default(), diffuse: BLACK, params: None, valid: false }
    }
}

impl Prepared {
    /// The parametric model's parameters at the point (parametric models only): what the network
    /// predicted, for inspection and for importance sampling.
    #[inline]
    pub fn parameters(&self) -> Option<&Parametric> {
        self.params.as_ref()
    }

    /// The diffuse term `f_d(x)` (additive models; 0 otherwise).
    #[inline]
    pub fn diffuse(&self) -> Rgb {
        self.diffuse
    }
}

impl<'a> Model<'a> {
    /// Precomputes everything that depends on the surface point: `p` is the intrinsic encoding at the
    /// point (`k` values), the point itself (`Extrinsic`, 3 values) or empty (`Uniform`).
    ///
    /// Errors when `p` does not hold [`Model::position_len`] values.
    pub fn prepare(&self, p: &[f32]) -> Result<Prepared, Error> {
        if p.len() != self.position_len() {
            return Err(Error::SizeMismatch { what: "point input", expected: self.position_len(), found: p.len() });
        }
        let mut prepared = Prepared::default();
        let mut enc = [0.0f32; MAX_POSITION_INPUT];
        let pos: &[f32] = match self.header.position {
            PositionEncoding::Extrinsic { frequencies } => {
                let n = positional_encoding(p, frequencies as usize, &mut enc);
                &enc[..n]
            }
            _ => p,
        };
        match self.weights {
            Weights::F32(w) => self.prepare_with(&self.nets(w), pos, &mut prepared),
            Weights::F16(w) => self.prepare_with(&self.nets(w), pos, &mut prepared),
        }
        prepared.valid = true;
        Ok(prepared)
    }

    /// [`Model::prepare`] for many points at once: point `i`'s input is `points[i * k..(i + 1) * k]`
    /// (`k` = [`Model::position_len`]) and `out[i]` gets its prepared state. Every evaluation from
    /// `out[i]` gives the bits of one from `prepare` of that point (the per-point values may differ
    /// from `prepare`'s in the sign of a zero sum, which no evaluation sees).
    ///
    /// The networks that read the position run [`PACKET`] points at a time through the packet
    /// kernels, as [`Model::eval_many`] runs direction pairs: what pays where a renderer shades many
    /// points of one material (a wavefront's hits), above all for the parametric models, whose whole
    /// 6-layer network runs per point. Fewer than [`PACKET`] points are prepared one by one. No
    /// allocation; up to ~150 KB of stack (the activations of a packet).
    ///
    /// Errors, writing nothing, when `points` does not hold `out.len()` inputs of `k` values.
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::ModelBuf;
    /// use nbrdf::parametric::ParametricKind;
    /// use nbrdf::Vec3;
    /// let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::Disney), false, Reciprocity::None,
    ///                            PositionEncoding::Intrinsic { k: 8 }, 0);
    /// let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 37 % 101) as f32 - 50.0) * 1e-3).collect();
    /// let buf = ModelBuf::from_bytes(&encode(&h, &w, None).unwrap()).unwrap();
    /// let model = buf.model();
    /// let points: Vec<f32> = (0..40 * 8).map(|i| (i as f32 * 0.21).sin()).collect(); // 40 points
    /// let mut prepared = vec![nbrdf::Prepared::default(); 40];
    /// model.prepare_many(&points, &mut prepared).unwrap();
    /// let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.4, 0.8).normalize());
    /// for (i, p) in prepared.iter().enumerate() {
    ///     let one = model.prepare(&points[i * 8..(i + 1) * 8]).unwrap();
    ///     assert_eq!(model.eval(p, wi, wo).map(f32::to_bits), model.eval(&one, wi, wo).map(f32::to_bits));
    /// }
    /// assert!(model.prepare_many(&points[1..], &mut prepared).is_err());
    /// ```
    pub fn prepare_many(&self, points: &[f32], out: &mut [Prepared]) -> Result<(), Error> {
        let k = self.position_len();
        if points.len() != out.len() * k {
            return Err(Error::SizeMismatch { what: "point inputs (points × position_len)", expected: out.len() * k, found: points.len() });
        }
        if k == 0 {
            // One state for every point: nothing depends on the point.
            out.fill(self.prepare(&[])?);
            return Ok(());
        }
        if out.len() < PACKET {
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.prepare(&points[i * k..(i + 1) * k])?;
            }
            return Ok(());
        }
        let mut enc = [0.0f32; PACKET * MAX_POSITION_INPUT];
        let mut start = 0;
        while start < out.len() {
            // The last packet ends at the last point, overlapping the one before (those points get
            // the same values again): every packet is whole, and no input is copied to pad one.
            let first = start.min(out.len() - PACKET);
            let x = &points[first * k..(first + PACKET) * k];
            let (pos, stride, n): (&[f32], usize, usize) = match self.header.position {
                PositionEncoding::Extrinsic { frequencies } => {
                    let mut n = 0;
                    for q in 0..PACKET {
                        n = positional_encoding(&x[q * k..(q + 1) * k], frequencies as usize, &mut enc[q * MAX_POSITION_INPUT..(q + 1) * MAX_POSITION_INPUT]);
                    }
                    (&enc, MAX_POSITION_INPUT, n)
                }
                _ => (x, k, k),
            };
            let out = &mut out[first..first + PACKET];
            match self.weights {
                Weights::F32(w) => self.prepare_packet_with(&self.nets(w), pos, stride, n, out),
                Weights::F16(w) => self.prepare_packet_with(&self.nets(w), pos, stride, n, out),
            }
            start = first + PACKET;
        }
        Ok(())
    }

    #[inline]
    fn prepare_with<W: Weight>(&self, nets: &[Net<'a, W>; MAX_NETS], pos: &[f32], out: &mut Prepared) {
        let n_obj = self.header.n_object();
        match self.header.kind {
            ModelKind::Parametric(kind) => {
                out.params = Some(parametric_net::prepare(&nets[0], kind, pos, &self.object[..n_obj]));
            }
            ModelKind::SingleMlp => {
                out.partial = single_mlp::prepare(&nets[..self.header.n_nets as usize], pos);
            }
            ModelKind::AdditiveSeparate => {
                (out.diffuse, out.partial) = additive_separate::prepare(&nets[0], &nets[1], pos);
            }
            ModelKind::AdditiveShared => {
                (out.diffuse, out.partial) = additive_shared::prepare(&nets[0], &nets[1], &nets[2], pos);
            }
        }
    }

    /// [`Model::prepare_with`] for the [`PACKET`] points whose position inputs lie at
    /// `pos[q * stride..][..n]`, into `out` (`PACKET` states).
    #[inline]
    fn prepare_packet_with<W: Weight>(&self, nets: &[Net<'a, W>; MAX_NETS], pos: &[f32], stride: usize, n: usize, out: &mut [Prepared]) {
        let n_obj = self.header.n_object();
        let (mut diffuse, mut partials, mut params) = ([BLACK; PACKET], None, [None; PACKET]);
        match self.header.kind {
            ModelKind::Parametric(kind) => {
                params = parametric_net::prepare_packet(&nets[0], kind, pos, stride, n, &self.object[..n_obj]).map(Some);
            }
            ModelKind::SingleMlp => partials = single_mlp::prepare_packet(&nets[..self.header.n_nets as usize], pos, stride, n),
            ModelKind::AdditiveSeparate => {
                let (d, p) = additive_separate::prepare_packet(&nets[0], &nets[1], pos, stride, n);
                (diffuse, partials) = (d, Some(p));
            }
            ModelKind::AdditiveShared => {
                let (d, p) = additive_shared::prepare_packet(&nets[0], &nets[1], &nets[2], pos, stride, n);
                (diffuse, partials) = (d, Some(p));
            }
        }
        // In place: a `Prepared` is 2 KB, and copies of whole ones cost more than the writes.
        for (q, o) in out.iter_mut().enumerate().take(PACKET) {
            match &partials {
                Some(p) => p.write(q, &mut o.partial),
                None => o.partial = Partial::default(),
            }
            (o.diffuse, o.params, o.valid) = (diffuse[q], params[q], true);
        }
    }
}
