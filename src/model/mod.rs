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
//! The module by concept: this file is the file view ([`Model`] over validated bytes, its header,
//! weights, object parameters and position table); `prepare.rs` the per-point state ([`Prepared`],
//! [`Model::prepare`], [`Model::prepare_many`]); `eval.rs` one direction pair ([`Model::eval`]);
//! `batch.rs` many pairs in packets ([`Model::eval_many`], [`Model::eval_many_soa`], the AVX-512
//! path); `convert.rs` the f16 / f32 files ([`Model::to_f16`], [`Model::to_f32`]); `buf.rs` the owned,
//! aligned storage ([`ModelBuf`]). Importance sampling of a model ([`Model::sample`], [`Model::pdf`],
//! [`Model::fit_proxy`]) and the model at one point as a [`Brdf`](crate::Brdf) ([`ModelAt`]) are in
//! `sampling.rs`, over the proxies of [`crate::sampling`]; the energy bound ([`Model::fit_albedo_bound`],
//! [`Model::unbounded`]) in `bound.rs`, over [`crate::energy`].

mod batch;
mod bound;
// `alloc` only, as every item in them is; gating the files too keeps their imports used without it.
#[cfg(feature = "alloc")]
mod buf;
#[cfg(feature = "alloc")]
mod convert;
mod eval;
mod prepare;
mod sampling;

#[cfg(feature = "alloc")]
pub use buf::ModelBuf;
pub use prepare::Prepared;
pub use sampling::ModelAt;

use crate::file::{ModelHeader, Precision, Sections, MAX_NETS};
use crate::mlp::{Net, NetDesc, Weight};
use crate::Error;

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
}
