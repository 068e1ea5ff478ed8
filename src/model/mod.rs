//! A loaded model, ready to evaluate: the header of a `.nbrdf` file with typed views of its weights.
//!
//! Evaluation is split the way a renderer uses a BRDF (docs/architecture.md):
//! [`Model::prepare`] does everything that depends on the surface point only (the parameter network of a
//! parametric model, the diffuse network, the trunk, and the position part of the first and skip layers of
//! the direction network), and [`Model::eval`] adds the direction pair. Both run on stack arrays with no
//! allocation. [`Model::eval_many`] evaluates many pairs at one point in packets, bit for bit as `eval`,
//! and [`Model::prepare_many`] prepares many points of one model in packets, whose evaluations are
//! `prepare`'s bit for bit. Evaluation has one arithmetic, f32: f16 weights are a storage format,
//! widened to f32 once at load by [`ModelBuf`], or row by row as they are read by a [`Model`] over
//! borrowed f16 bytes; both give the same bits.
//!
//! ```
//! use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
//! use nbrdf::ModelBuf;
//! use nbrdf::Vec3;
//! let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact,
//!                            PositionEncoding::Extrinsic { frequencies: 2 }, 3);
//! let weights: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect();
//! let buf = ModelBuf::from_bytes(&encode(&h, &weights, None).unwrap()).unwrap();
//! let model = buf.model();
//! let point = model.prepare(&[0.1, -0.3, 0.5]).unwrap();
//! let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.5, 0.2, 0.7).normalize());
//! let f = model.eval(&point, wi, wo);
//! assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0));
//! assert_eq!(f, model.eval(&point, wo, wi)); // exact reciprocity, bit for bit
//! ```
//!
//! Importance sampling of a model ([`Model::sample`], [`Model::pdf`], [`Model::fit_proxy`]) and the
//! model at one point as a [`Brdf`](crate::Brdf) ([`ModelAt`]) are in `sampling.rs`, over the proxies
//! of [`crate::sampling`].

mod sampling;

pub use sampling::ModelAt;

use crate::angles::{rusinkiewicz_angles, theta_map, upper_hemisphere_pair};
use crate::encoding::positional_encoding;
use crate::file::{ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity, Sections, MAX_NETS};
use crate::math::sanitize;
use crate::mlp::{Net, NetDesc, Partial, Weight, PACKET};
use crate::neural::{additive_separate, additive_shared, parametric_net, single_mlp};
use crate::parametric::Parametric;
use crate::{Error, Rgb, Vec3, BLACK};

// The stack buffers are sized by the format's limits, which `file` checks at load.
pub use crate::file::{MAX_ANGLE_INPUT, MAX_POSITION_INPUT};

/// Largest number of per-object parameters.
pub const MAX_OBJECT: usize = 4;

/// Borrowed network weights in their stored precision.
#[derive(Clone, Copy, Debug)]
pub enum Weights<'a> {
    /// Single precision.
    F32(&'a [f32]),
    /// Half precision, widened to f32 as it is read.
    F16(&'a [half::f16]),
}

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

/// A validated model over borrowed bytes. Cheap to copy.
#[derive(Clone, Copy, Debug)]
pub struct Model<'a> {
    header: ModelHeader,
    weights: Weights<'a>,
    object: [f32; MAX_OBJECT],
    table: &'a [f32],
}

/// Reinterprets validated, aligned little-endian bytes as `T` values.
///
/// # Safety
/// `bytes` must be aligned for `T`, its length a multiple of `size_of::<T>()`, and every bit pattern a
/// valid `T` (true for f32 and f16).
#[cfg(target_endian = "little")]
unsafe fn cast_slice<T>(bytes: &[u8]) -> &[T] {
    debug_assert_eq!(bytes.as_ptr() as usize % core::mem::align_of::<T>(), 0);
    // SAFETY: guaranteed by the caller as documented above.
    unsafe { core::slice::from_raw_parts(bytes.as_ptr().cast::<T>(), bytes.len() / core::mem::size_of::<T>()) }
}

/// Network weights of `precision` over validated, aligned little-endian bytes.
///
/// # Safety
/// As [`cast_slice`] for the precision's element type.
#[cfg(target_endian = "little")]
unsafe fn weights_of(precision: Precision, bytes: &[u8]) -> Weights<'_> {
    // SAFETY: guaranteed by the caller; f32 and f16 accept every bit pattern.
    unsafe {
        match precision {
            Precision::F32 => Weights::F32(cast_slice::<f32>(bytes)),
            Precision::F16 => Weights::F16(cast_slice::<half::f16>(bytes)),
        }
    }
}

impl<'a> Model<'a> {
    /// Validates a model file in place and borrows its weights without copying.
    ///
    /// The buffer must be 4-byte aligned ([`Error::Misaligned`] otherwise: load through
    /// [`ModelBuf`] instead, which copies into aligned storage). Every malformed file gives an error
    /// that names the problem (see [`crate::file`]).
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let (header, sections) = crate::file::parse(bytes)?;
        if !(bytes.as_ptr() as usize).is_multiple_of(4) {
            return Err(Error::Misaligned);
        }
        Self::from_parsed(bytes, header, &sections)
    }

    /// Where the weights of the network that runs per query (the last network) start in the model
    /// file `bytes`, in bytes from its start; the file is validated first.
    ///
    /// For callers that keep a model in their own buffer ([`Model::from_bytes`], e.g. `no_std`): place
    /// the file so that `buffer address + offset` is a multiple of 64 (and the buffer stays 4-byte
    /// aligned) and single queries run as fast as through [`ModelBuf`], which does this itself.
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::{Model, ModelBuf};
    /// let h = ModelHeader::paper(ModelKind::AdditiveSeparate, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// let bytes = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
    /// let at = Model::query_weights_offset_of(&bytes).unwrap();
    /// // ModelBuf puts the specular network on a cache line.
    /// let buf = ModelBuf::from_bytes(&bytes).unwrap();
    /// assert_eq!((buf.as_bytes().as_ptr() as usize + at) % 64, 0);
    /// ```
    pub fn query_weights_offset_of(bytes: &[u8]) -> Result<usize, Error> {
        let (header, sections) = crate::file::parse(bytes)?;
        Ok(Self::query_weights_offset(&header, &sections))
    }

    /// See [`Model::query_weights_offset_of`].
    pub(crate) fn query_weights_offset(header: &ModelHeader, sections: &Sections) -> usize {
        Self::query_weights_range(header, sections).start
    }

    /// The bytes of the per-query (last) network's weights in the file.
    pub(crate) fn query_weights_range(header: &ModelHeader, sections: &Sections) -> core::ops::Range<usize> {
        let nets = header.nets();
        let (before, last) = nets.split_at(nets.len().saturating_sub(1));
        let start = sections.weights.0 + before.iter().map(NetDesc::n_weights).sum::<usize>() * header.precision.size();
        start..start + last.iter().map(NetDesc::n_weights).sum::<usize>() * header.precision.size()
    }

    #[cfg(target_endian = "little")]
    pub(crate) fn from_parsed(bytes: &'a [u8], header: ModelHeader, s: &Sections) -> Result<Self, Error> {
        // SAFETY: `parse` checked the section bounds; sections start at multiples of 4 of a 4-aligned
        // buffer and hold whole elements.
        let weights = unsafe { weights_of(header.precision, &bytes[s.weights.0..s.weights.1]) };
        let mut object = [0.0f32; MAX_OBJECT];
        let obj = &bytes[s.object.0..s.object.1];
        if obj.len() / 4 > MAX_OBJECT {
            return Err(Error::TooLarge { what: "object parameters", found: obj.len() / 4, max: MAX_OBJECT });
        }
        for (o, c) in object.iter_mut().zip(obj.chunks_exact(4)) {
            *o = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        }
        // SAFETY: as above.
        let table = unsafe { cast_slice::<f32>(&bytes[s.table.0..s.table.1]) };
        Ok(Model { header, weights, object, table })
    }

    #[cfg(not(target_endian = "little"))]
    pub(crate) fn from_parsed(_: &'a [u8], _: ModelHeader, _: &Sections) -> Result<Self, Error> {
        Err(Error::InvalidValue { what: "host byte order", reason: "model files are read on little-endian hosts only" })
    }

    /// The model's header.
    #[inline]
    pub fn header(&self) -> &ModelHeader {
        &self.header
    }

    /// The weights in their stored precision.
    #[inline]
    pub fn weights(&self) -> Weights<'a> {
        self.weights
    }

    /// The per-object parameters (FMBRDF's NDF normalisation; empty for the other models).
    #[inline]
    pub fn object_parameters(&self) -> &[f32] {
        &self.object[..self.header.n_object()]
    }

    /// The stored per-vertex position encoding, `n_vertices` rows of [`Model::position_len`] values
    /// (empty when the file carries none). With [`Model::weights`] and
    /// [`Model::object_parameters`] this is everything [`crate::file::encode`] needs to write the
    /// model again, e.g. with other weight precision.
    #[inline]
    pub fn position_table(&self) -> &'a [f32] {
        self.table
    }

    /// Number of point values [`Model::prepare`] expects (0, the intrinsic `k`, or 3 for xyz).
    #[inline]
    pub fn position_len(&self) -> usize {
        self.header.position.input_len()
    }

    /// Interpolates the stored per-vertex intrinsic encoding at barycentric coordinates `bary` of the
    /// triangle `tri` into `out` (`k` values), for renderers that have the mesh but not the eigenfunctions.
    ///
    /// Errors when the file carries no table, a vertex index is out of range, or `out` is too short.
    pub fn position_features(&self, tri: [u32; 3], bary: [f32; 3], out: &mut [f32]) -> Result<(), Error> {
        let k = self.position_len();
        let n = self.header.n_vertices as usize;
        if n == 0 {
            return Err(Error::InvalidValue { what: "position table", reason: "the model file carries none" });
        }
        if out.len() < k {
            return Err(Error::SizeMismatch { what: "position feature buffer", expected: k, found: out.len() });
        }
        if let Some(&v) = tri.iter().find(|&&v| v as usize >= n) {
            return Err(Error::SizeMismatch { what: "vertex index (table rows)", expected: n, found: v as usize });
        }
        let rows = tri.map(|v| &self.table[v as usize * k..(v as usize + 1) * k]);
        for (j, o) in out[..k].iter_mut().enumerate() {
            *o = bary[0] * rows[0][j] + bary[1] * rows[1][j] + bary[2] * rows[2][j];
        }
        Ok(())
    }

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

    /// Evaluates the BRDF at a prepared point for the pair (`wi`, `wo`) in the local frame.
    ///
    /// Returns 0 below the horizon, for degenerate or non-finite directions, and for an invalid
    /// prepared state; never NaN or infinity. With [`Reciprocity::Exact`] (and for every parametric
    /// model) `eval(p, wi, wo) == eval(p, wo, wi)` bit for bit.
    // Inlined into its callers' loops: a parametric query (~70 ns) took ~1.15x the time as a call.
    #[inline(always)]
    pub fn eval(&self, prepared: &Prepared, wi: Vec3, wo: Vec3) -> Rgb {
        // 0.83x the time of an FMBRDF query in a loop of independent ones (see `load_pair`).
        let (wi, wo) = crate::math::load_pair(&wi, &wo);
        if !prepared.valid {
            return BLACK;
        }
        if let Some(params) = &prepared.params {
            return match upper_hemisphere_pair(wi, wo) {
                Some((wi, wo)) => params.eval(wi, wo),
                None => BLACK,
            };
        }
        let mut enc = [0.0f32; MAX_ANGLE_INPUT];
        let Some(n) = self.encode_pair(wi, wo, &mut enc) else {
            return BLACK;
        };
        let f = match self.weights {
            Weights::F32(w) => self.eval_with(&self.nets(w), prepared, &enc[..n]),
            Weights::F16(w) => self.eval_with(&self.nets(w), prepared, &enc[..n]),
        };
        sanitize(f)
    }

    /// The encoded angle input `PE(a)` of a direction pair (`docs/models.md`), written to the front of
    /// `enc`; `None` where the pair evaluates to 0.
    #[inline]
    fn encode_pair(&self, wi: Vec3, wo: Vec3, enc: &mut [f32]) -> Option<usize> {
        let (wi, wo) = upper_hemisphere_pair(wi, wo)?;
        let mut angles = [0.0f32; 4];
        let n_angles = match self.header.reciprocity {
            Reciprocity::Exact => {
                angles = theta_map(wi, wo)?;
                4
            }
            Reciprocity::None | Reciprocity::Swap => {
                angles[..3].copy_from_slice(&rusinkiewicz_angles(wi, wo)?);
                3
            }
        };
        Some(positional_encoding(&angles[..n_angles], self.header.angle_frequencies as usize, enc))
    }

    /// Evaluates many direction pairs at one prepared point: `out[i] = eval(prepared, wi[i], wo[i])`
    /// for the common length of the three slices, bit for bit.
    ///
    /// The valid pairs are gathered into packets of [`crate::mlp::PACKET`] that run through each layer
    /// together (every weight row read once per packet): for the paper-size Single MLP 1.2-1.3x
    /// (Zen 4) to 1.5x (Intel Xeon) faster per pair than [`Model::eval`], where single queries are
    /// bound by streaming the weights from L2 and packets by the FMA rate (see `docs/speed.md`).
    ///
    /// f16 weights cost no more than f32 ones where a [`ModelBuf`] holds them (widened at load); a
    /// [`Model`] over borrowed f16 bytes widens the rows each packet uses, allocating nothing. Both
    /// give the same bits.
    pub fn eval_many(&self, prepared: &Prepared, wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) {
        let n = out.len().min(wi.len()).min(wo.len());
        self.eval_many_by(prepared, n, |i| (wi[i], wo[i]), |i, f| out[i] = f);
    }

    /// The model re-encoded with f16 network weights ([`Precision::F16`]: half the weight bytes), as
    /// the bytes of a `.nbrdf` file. Object parameters and the position table stay f32, as the file
    /// format keeps them; the header is unchanged apart from the precision. Feature `alloc`.
    ///
    /// Errors: [`Error::InvalidValue`] when the weights are f16 already; [`Error::NonFinite`] for a
    /// weight beyond ±65504 (it would round to infinity).
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
    /// use nbrdf::ModelBuf;
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// let f32_file = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
    /// let f16_file = ModelBuf::from_bytes(&f32_file).unwrap().model().to_f16().unwrap();
    /// assert_eq!(ModelBuf::from_bytes(&f16_file).unwrap().file_precision(), Precision::F16);
    /// assert!(f16_file.len() < f32_file.len());
    /// assert!(nbrdf::Model::from_bytes(&f16_file).unwrap().to_f16().is_err());
    /// ```
    #[cfg(feature = "alloc")]
    pub fn to_f16(&self) -> Result<alloc::vec::Vec<u8>, Error> {
        let Weights::F32(net) = self.weights else {
            return Err(Error::InvalidValue { what: "model precision", reason: "the weights are f16 already" });
        };
        let mut weights = net.to_vec();
        weights.extend_from_slice(self.object_parameters());
        let mut header = self.header;
        header.precision = Precision::F16;
        // `encode` sets the vertex count from the table.
        header.n_vertices = 0;
        let table = self.position_table();
        crate::file::encode(&header, &weights, (!table.is_empty()).then_some(table))
    }

    /// The model re-encoded with f32 network weights ([`Precision::F32`]), as the bytes of a `.nbrdf`
    /// file: every f16 value is an f32, so the weights are the same values, and the header (kind,
    /// shapes, proxy), object parameters and position table are unchanged apart from the precision.
    /// What [`ModelBuf`] holds for an f16 file. Feature `alloc`.
    ///
    /// Errors: [`Error::InvalidValue`] when the weights are f32 already.
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
    /// use nbrdf::{Model, Weights};
    /// let mut h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// h.precision = Precision::F16;
    /// let f16_file = encode(&h, &vec![0.1; h.n_weights()], None).unwrap();
    /// let f32_file = Model::from_bytes(&f16_file).unwrap().to_f32().unwrap();
    /// let wide = Model::from_bytes(&f32_file).unwrap();
    /// assert_eq!(wide.header().precision, Precision::F32);
    /// let Weights::F32(w) = wide.weights() else { unreachable!() };
    /// assert!(w.iter().all(|&v| v == half::f16::from_f32(0.1).to_f32()));
    /// assert_eq!(wide.to_f16().unwrap(), f16_file); // and back, to the byte
    /// # assert!(wide.to_f32().is_err());
    /// ```
    #[cfg(feature = "alloc")]
    pub fn to_f32(&self) -> Result<alloc::vec::Vec<u8>, Error> {
        let Weights::F16(net) = self.weights else {
            return Err(Error::InvalidValue { what: "model precision", reason: "the weights are f32 already" });
        };
        let mut weights = alloc::vec![0.0f32; net.len()];
        crate::kernels::widen_f16(net, &mut weights);
        weights.extend_from_slice(self.object_parameters());
        let mut header = self.header;
        header.precision = Precision::F32;
        // `encode` sets the vertex count from the table.
        header.n_vertices = 0;
        let table = self.position_table();
        crate::file::encode(&header, &weights, (!table.is_empty()).then_some(table))
    }

    /// [`Model::eval_many`] over directions as structure of arrays: pair `i` is
    /// `wi = (wi[0][i], wi[1][i], wi[2][i])`, `wo` likewise, and its RGB goes to
    /// `(out[0][i], out[1][i], out[2][i])`, for the common length of all nine slices.
    pub fn eval_many_soa(&self, prepared: &Prepared, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let n = wi.iter().chain(&wo).map(|s| s.len()).chain(out.iter().map(|s| s.len())).min().unwrap_or(0);
        let [r, g, b] = out;
        self.eval_many_by(
            prepared,
            n,
            |i| (Vec3::new(wi[0][i], wi[1][i], wi[2][i]), Vec3::new(wo[0][i], wo[1][i], wo[2][i])),
            |i, f| {
                r[i] = f[0];
                g[i] = f[1];
                b[i] = f[2];
            },
        );
    }

    /// The batched evaluation behind [`Model::eval_many`]: `pair(i)` gives the directions of query `i`,
    /// `put(i, f)` takes its value; every query `i < n` is put exactly once.
    #[inline]
    fn eval_many_by(
        &self,
        prepared: &Prepared,
        n: usize,
        pair: impl Fn(usize) -> (Vec3, Vec3),
        mut put: impl FnMut(usize, Rgb),
    ) {
        if !prepared.valid || prepared.params.is_some() {
            for i in 0..n {
                let (a, b) = pair(i);
                put(i, self.eval(prepared, a, b));
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if crate::kernels::level() == crate::kernels::Level::Avx512 {
            return self.eval_many_theta16(prepared, n, pair, put);
        }
        let mut enc = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut index = [0usize; PACKET];
        let mut filled = 0;
        let mut len = 0;
        for i in 0..n {
            let (a, b) = pair(i);
            let slot = &mut enc[filled * MAX_ANGLE_INPUT..(filled + 1) * MAX_ANGLE_INPUT];
            match self.encode_pair(a, b, slot) {
                Some(l) => {
                    len = l;
                    index[filled] = i;
                    filled += 1;
                }
                None => put(i, BLACK),
            }
            if filled == PACKET || (i + 1 == n && filled > 0) {
                for (&i, f) in index[..filled].iter().zip(self.run_packet(prepared, &enc, len)) {
                    put(i, sanitize(f));
                }
                filled = 0;
            }
        }
    }

    /// The [`PACKET`] pairs encoded in `enc` (`MAX_ANGLE_INPUT` apart, `len` values each) through the
    /// model's networks ([`Model::eval_packet_with`] over its weights).
    #[inline]
    fn run_packet(&self, prepared: &Prepared, enc: &[f32], len: usize) -> [Rgb; PACKET] {
        match self.weights {
            Weights::F32(w) => self.eval_packet_with(&self.nets(w), prepared, enc, len),
            Weights::F16(w) => self.eval_packet_with(&self.nets(w), prepared, enc, len),
        }
    }

    /// [`Model::eval_many_by`] on AVX-512: the pairs mapped (Θ, or the Rusinkiewicz angles) and
    /// encoded 16 at a time (`angles::theta16`, the bits of [`Model::encode_pair`] in every lane; the
    /// pairs it leaves to the scalar code encoded by that), the valid ones gathered into packets as there.
    #[cfg(target_arch = "x86_64")]
    fn eval_many_theta16(
        &self,
        prepared: &Prepared,
        n: usize,
        pair: impl Fn(usize) -> (Vec3, Vec3),
        mut put: impl FnMut(usize, Rgb),
    ) {
        let frequencies = self.header.angle_frequencies as usize;
        let exact = self.header.reciprocity == Reciprocity::Exact;
        let len = self.header.angle_input_len();
        let run = |enc: &[f32]| self.run_packet(prepared, enc, len);
        // 16 encoded rows, and the packet the valid ones are gathered into where some are not.
        let mut stage = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut enc = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut index = [0usize; PACKET];
        let mut filled = 0;
        let mut i = 0;
        while i < n {
            let m = (n - i).min(16);
            let (mut wi, mut wo) = ([Vec3::Z; 16], [Vec3::Z; 16]);
            for q in 0..m {
                (wi[q], wo[q]) = pair(i + q);
            }
            // SAFETY: the level is AVX-512 (checked by the caller); `m ≤ 16`; at most `MAX_FREQUENCIES`
            // octaves, so a row's `len` values fit the `MAX_ANGLE_INPUT` between rows.
            let (valid, scalar) = unsafe { crate::angles::theta16::encode16(&wi, &wo, m, exact, frequencies, &mut stage, MAX_ANGLE_INPUT) };
            if filled == 0 && valid == 0xffff {
                // A whole packet of valid pairs: straight from the rows.
                for (q, f) in run(&stage).into_iter().enumerate() {
                    put(i + q, sanitize(f));
                }
                i += m;
                continue;
            }
            for q in 0..m {
                let slot = &mut enc[filled * MAX_ANGLE_INPUT..(filled + 1) * MAX_ANGLE_INPUT];
                let ok = if valid & (1 << q) != 0 {
                    slot[..len].copy_from_slice(&stage[q * MAX_ANGLE_INPUT..q * MAX_ANGLE_INPUT + len]);
                    true
                } else {
                    scalar & (1 << q) != 0 && self.encode_pair(wi[q], wo[q], slot).is_some()
                };
                if !ok {
                    put(i + q, BLACK);
                    continue;
                }
                index[filled] = i + q;
                filled += 1;
                if filled == PACKET {
                    for (&k, f) in index.iter().zip(run(&enc)) {
                        put(k, sanitize(f));
                    }
                    filled = 0;
                }
            }
            i += m;
        }
        if filled > 0 {
            for (&k, f) in index[..filled].iter().zip(run(&enc)) {
                put(k, sanitize(f));
            }
        }
    }

    /// Views of the networks over the weights, in file order.
    #[inline]
    fn nets<W: Weight>(&self, w: &'a [W]) -> [Net<'a, W>; MAX_NETS] {
        let mut nets = [Net { desc: NetDesc::default(), weights: &w[..0] }; MAX_NETS];
        let mut off = 0;
        for (net, desc) in nets.iter_mut().zip(self.header.nets()) {
            let n = desc.n_weights();
            *net = Net { desc: *desc, weights: &w[off..off + n] };
            off += n;
        }
        nets
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

    #[inline]
    fn eval_with<W: Weight>(&self, nets: &[Net<'a, W>; MAX_NETS], p: &Prepared, angles: &[f32]) -> Rgb {
        let enhanced = self.header.enhanced;
        match self.header.kind {
            ModelKind::Parametric(_) => BLACK,
            ModelKind::SingleMlp => single_mlp::eval(&nets[self.header.n_nets as usize - 1], &p.partial, angles),
            ModelKind::AdditiveSeparate => additive_separate::eval(&nets[1], p.diffuse, &p.partial, angles, enhanced),
            ModelKind::AdditiveShared => additive_shared::eval(&nets[2], p.diffuse, &p.partial, angles, enhanced),
        }
    }

    /// [`Model::eval_with`] for the [`PACKET`] queries encoded in `enc` (`MAX_ANGLE_INPUT` apart,
    /// `n` values each); lanes past the filled ones hold stale inputs whose results are discarded.
    #[inline]
    fn eval_packet_with<W: Weight>(&self, nets: &[Net<'a, W>; MAX_NETS], p: &Prepared, enc: &[f32], n: usize) -> [Rgb; PACKET] {
        let enhanced = self.header.enhanced;
        let s = MAX_ANGLE_INPUT;
        match self.header.kind {
            ModelKind::Parametric(_) => [BLACK; PACKET],
            ModelKind::SingleMlp => single_mlp::eval_packet(&nets[self.header.n_nets as usize - 1], &p.partial, enc, s, n),
            ModelKind::AdditiveSeparate => {
                additive_separate::eval_packet(&nets[1], p.diffuse, &p.partial, enc, s, n, enhanced)
            }
            ModelKind::AdditiveShared => additive_shared::eval_packet(&nets[2], p.diffuse, &p.partial, enc, s, n, enhanced),
        }
    }
}

/// A model that owns its bytes (feature `alloc`): the loader for files read from disk or buffers of
/// unknown alignment.
///
/// An f16 file is widened to the equivalent f32 file once, at load ([`Model::to_f32`]: the same
/// values, header, object parameters and position table), so that its evaluations run over f32 rows
/// at f32 speed, for twice the memory of the f16 weights. They give the bits of a [`Model`] over the
/// f16 bytes themselves, whose kernels widen each row to f32 and sum in the same order. The buffer is
/// then the f32 file's: [`ModelBuf::header`], [`ModelBuf::as_bytes`] and [`ModelBuf::model`] say
/// [`Precision::F32`]; [`ModelBuf::file_precision`] says what was loaded, and [`Model::to_f16`] gives
/// the f16 file back byte for byte.
///
/// The bytes are placed so that the weights of the network that runs per query (the last one: the
/// Single MLP, the additive models' specular network or head) start on a 64-byte boundary (a cache
/// line, one AVX-512 vector), whatever the file's own layout: the one-query kernels load whole rows of
/// 128 weights as vectors, and a row that straddles cache lines costs each of its loads two lines (on
/// this project's Zen 4 machine ~12% of a single Single MLP query). The file format only promises
/// 4-byte alignment (`file` module docs); `Model::from_bytes` on a caller's buffer gets the same speed
/// when the caller aligns the same offset ([`Model::query_weights_offset_of`]).
///
/// ```
/// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
/// use nbrdf::ModelBuf;
/// let mut h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
/// h.precision = Precision::F16;
/// let f16_file = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
/// let buf = ModelBuf::from_bytes(&f16_file).unwrap();
/// assert_eq!((buf.file_precision(), buf.header().precision), (Precision::F16, Precision::F32));
/// assert_eq!(buf.model().to_f16().unwrap(), f16_file);
/// ```
#[cfg(feature = "alloc")]
#[derive(Clone, Debug)]
pub struct ModelBuf {
    lines: alloc::vec::Vec<CacheLine>,
    /// Where the file starts in `lines`, in bytes (a multiple of 4, below 64).
    shift: usize,
    len: usize,
    header: ModelHeader,
    sections: Sections,
    /// The precision of the file loaded (`header` is the one held: f32 unless held as it is).
    file_precision: Precision,
}

/// 64 bytes aligned to 64: the storage unit of a [`ModelBuf`], so that its allocation (and every
/// clone's) starts on a cache line.
#[cfg(feature = "alloc")]
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct CacheLine([u8; 64]);

#[cfg(feature = "alloc")]
impl CacheLine {
    /// Lines holding `bytes` from byte `shift` of the first (zeros around them).
    fn copy_of(bytes: &[u8], shift: usize) -> alloc::vec::Vec<CacheLine> {
        let mut lines = alloc::vec![CacheLine([0; 64]); (shift + bytes.len()).div_ceil(64)];
        // SAFETY: as in `bytes`, and the lines are borrowed mutably.
        let store = unsafe { core::slice::from_raw_parts_mut(lines.as_mut_ptr().cast::<u8>(), lines.len() * 64) };
        store[shift..shift + bytes.len()].copy_from_slice(bytes);
        lines
    }

    /// The bytes of consecutive lines.
    fn bytes(lines: &[CacheLine]) -> &[u8] {
        // SAFETY: `CacheLine` is `repr(C)` over a `[u8; 64]` with no padding (its alignment divides 64),
        // so a slice of lines is `64 × len` initialised bytes; u8 has no alignment requirement.
        unsafe { core::slice::from_raw_parts(lines.as_ptr().cast::<u8>(), lines.len() * 64) }
    }
}

#[cfg(feature = "alloc")]
impl ModelBuf {
    /// Copies `bytes` into storage whose per-query network starts on a 64-byte boundary, and validates
    /// them as a model file; an f16 file is stored widened to f32 (see [`ModelBuf`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        let held = Self::from_bytes_as_is(bytes)?;
        if held.header.precision == Precision::F32 {
            return Ok(held);
        }
        let wide = held.model().to_f32()?;
        let (header, sections) = crate::file::parse(&wide)?;
        Ok(ModelBuf { file_precision: Precision::F16, ..Self::placed(&wide, header, sections)? })
    }

    /// Copies `bytes` as [`ModelBuf::from_bytes`] does, but holds an f16 file as it is: its rows stay
    /// f16 and the kernels widen them as they read them (the same bits as the widened file, half its
    /// weight memory, batches ~1.1–1.2× the time; `docs/speed.md`). For an f32 file the same as
    /// `from_bytes`.
    ///
    /// ```
    /// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
    /// use nbrdf::ModelBuf;
    /// let mut h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
    /// h.precision = Precision::F16;
    /// let f16_file = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
    /// let buf = ModelBuf::from_bytes_as_is(&f16_file).unwrap();
    /// assert_eq!((buf.file_precision(), buf.header().precision), (Precision::F16, Precision::F16));
    /// assert_eq!(buf.as_bytes(), &f16_file[..]);
    /// ```
    pub fn from_bytes_as_is(bytes: &[u8]) -> Result<Self, Error> {
        let (header, sections) = crate::file::parse(bytes)?;
        Self::placed(bytes, header, sections)
    }

    /// The validated file `bytes` (of `header` and `sections`) copied so that its per-query network
    /// starts on a 64-byte boundary (f32; an f16 one may start mid-word, 2 bytes short of a line).
    fn placed(bytes: &[u8], header: ModelHeader, sections: Sections) -> Result<Self, Error> {
        let shift = (64 - Model::query_weights_offset(&header, &sections) % 64) % 64;
        // Shifts are whole words, keeping the 4-byte alignment that `Model` needs for every section.
        let shift = shift & !3;
        let lines = CacheLine::copy_of(bytes, shift);
        let buf = ModelBuf { lines, shift, len: bytes.len(), header, sections, file_precision: header.precision };
        // Surface host-dependent failures (byte order) here rather than at every `model()` call.
        Model::from_parsed(buf.bytes(), header, &sections)?;
        Ok(buf)
    }

    /// Reads and validates a model file; errors name the path or the problem.
    #[cfg(feature = "std")]
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Self, Error> {
        Self::from_bytes(&crate::io::read(path.as_ref())?)
    }

    fn bytes(&self) -> &[u8] {
        &CacheLine::bytes(&self.lines)[self.shift..self.shift + self.len]
    }

    /// The bytes of the file held, e.g. to write them elsewhere: those loaded, or for an f16 file
    /// the f32 file it was widened to ([`Model::to_f16`] gives the f16 one back).
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes()
    }

    /// The header of the file held ([`Precision::F32`] for an f16 file widened by `from_bytes`).
    pub fn header(&self) -> &ModelHeader {
        &self.header
    }

    /// The precision of the file loaded: [`Precision::F16`] for an f16 file, held widened to f32 (or
    /// as it is, [`ModelBuf::from_bytes_as_is`]).
    pub fn file_precision(&self) -> Precision {
        self.file_precision
    }

    /// The evaluator over this buffer (no re-validation; cheap).
    pub fn model(&self) -> Model<'_> {
        match Model::from_parsed(self.bytes(), self.header, &self.sections) {
            Ok(m) => m,
            // `from_bytes` ran the same conversion on the same bytes and header successfully.
            Err(_) => unreachable!("ModelBuf was validated at construction"),
        }
    }
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use crate::file::{encode, ModelKind, PositionEncoding, Reciprocity};

    /// The per-query network's weights start on a cache line in every `ModelBuf`, f16 files (held
    /// widened to f32) included.
    #[test]
    fn model_buf_puts_the_per_query_network_on_a_cache_line() {
        for kind in [ModelKind::SingleMlp, ModelKind::AdditiveSeparate, ModelKind::AdditiveShared] {
            for precision in [Precision::F32, Precision::F16] {
                let mut h = ModelHeader::paper(kind, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 64 }, 4);
                h.precision = precision;
                let buf = ModelBuf::from_bytes(&encode(&h, &alloc::vec![0.01; h.n_weights()], None).unwrap()).unwrap();
                assert_eq!(buf.file_precision(), precision);
                let model = buf.model();
                let Weights::F32(w) = model.weights else { panic!("{kind:?} {precision:?}: a ModelBuf holds f32 weights") };
                let last = h.nets().len() - 1;
                assert_eq!(model.nets(w)[last].weights.as_ptr() as usize % 64, 0, "{kind:?} {precision:?}");
            }
        }
    }
}
