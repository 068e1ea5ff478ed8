//! [`ModelBuf`] (feature `alloc`): a model that owns its bytes, copied into cache-line-aligned storage
//! so that the per-query network's rows start on a 64-byte boundary; f16 files are widened at load.

use super::Model;
use crate::file::{ModelHeader, Precision, Sections};
use crate::Error;

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
    use crate::model::Weights;

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
