//! Weight precision conversion (feature `alloc`): a model re-encoded as the `.nbrdf` file of the other
//! precision, f32 to f16 ([`Model::to_f16`]) and f16 to f32 ([`Model::to_f32`], what `ModelBuf` holds).

use super::{Model, Weights};
use crate::file::Precision;
use crate::Error;

impl<'a> Model<'a> {
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
    /// What [`ModelBuf`](super::ModelBuf) holds for an f16 file. Feature `alloc`.
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
}
