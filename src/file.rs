//! The `.nbrdf` model file: a versioned header followed by little-endian weights, loadable without a copy.
//!
//! # Layout (versions 1 and 2)
//! | bytes | content |
//! |---|---|
//! | 0..8 | magic `b"NBRDFMDL"` |
//! | 8..12 | format version, `u32` LE |
//! | 12..16 | header length `H`, `u32` LE |
//! | 16..16+H | [`ModelHeader`], postcard-encoded; it may end before its trailing optional fields (the sampling proxy, the mesh hash, the per-view sampling table, then the albedo bound), which then read as `None`; zero padding to a multiple of 4 |
//! | … | network weights in file order (`docs/models.md`), `f32` or `f16` LE per [`Precision`]; zero padding to a multiple of 4 |
//! | … | object parameters, `f32` LE ([`ModelHeader::n_object`]) |
//! | … | optional per-vertex position table, `f32` LE, `n_vertices × k` row-major (intrinsic encoding) |
//! | last 4 | CRC-32 (IEEE) of every preceding byte, `u32` LE |
//!
//! A file is version 2 exactly when its header carries an albedo bound ([`ModelHeader::albedo_bound`]):
//! the bound changes the model's values, so a reader that would ignore it must refuse the file instead.
//! Every other file is version 1, byte for byte as before the bound existed.
//!
//! Every section starts 4-byte aligned, so [`Model::from_bytes`](crate::Model::from_bytes) borrows the
//! weights in place when the buffer is 4-byte aligned on a little-endian machine;
//! [`ModelBuf`](crate::ModelBuf) (feature `alloc`) copies into
//! aligned storage otherwise. Loading validates everything a renderer relies on — magic, version, header
//! consistency (every network's shape against the model kind and input encodings), exact file size,
//! checksum, finite weights — and reports the first problem as an [`Error`] value. Nothing panics on a
//! malformed file; the fuzz target `model_file` holds that.
//!
//! This module is the format alone and imports nothing from its evaluator ([`crate::model`], which
//! reads files through it); the evaluator's types are at the crate root ([`crate::Model`],
//! [`crate::ModelBuf`], [`crate::Prepared`], [`crate::Weights`]).

use serde::{Deserialize, Serialize};

use crate::encoding::encoded_len;
use crate::mlp::{NetDesc, MAX_WIDTH};
use crate::parametric::ParametricKind;
use crate::Error;

/// File magic.
pub const MAGIC: [u8; 8] = *b"NBRDFMDL";
/// Newest format version this build writes and reads (2: the header may carry an albedo bound).
pub const VERSION: u32 = 2;
/// Most networks one model holds (the Additive Shared trunk and two heads).
pub const MAX_NETS: usize = 3;
/// Largest number of positional-encoding octaves, for angles and for the extrinsic position.
pub const MAX_FREQUENCIES: u8 = 16;
/// Largest intrinsic encoding size `k`.
pub const MAX_INTRINSIC: u16 = 4096;
/// Largest encoded angle input: Θ (4 values) with 16 octaves.
pub const MAX_ANGLE_INPUT: usize = encoded_len(4, MAX_FREQUENCIES as usize);
/// Largest extrinsic position encoding: xyz with 16 octaves.
pub const MAX_POSITION_INPUT: usize = encoded_len(3, MAX_FREQUENCIES as usize);
/// Largest model file read, 1 TiB: far above any real one (the networks are a few MB; a per-vertex
/// table of `k` = 4096 values on a 60-million-vertex mesh fills it), so that a length given beside
/// a pointer is refused before it is trusted.
pub const MAX_FILE_BYTES: u64 = 1 << 40;

/// Reciprocity strategy of a purely neural model (Sec. 4.3, Tab. 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Reciprocity {
    /// Rusinkiewicz angles `[θh, θd, φd]` as they are.
    None,
    /// Angles as for `None`; trained with random exchange of `wi` and `wo` (LitNeRF). Approximate.
    Swap,
    /// The map Θ of Eq. 6: reciprocal by construction, bit for bit.
    Exact,
}

impl Reciprocity {
    /// Number of angle values the network sees before encoding: 3, or 4 for Θ.
    #[inline]
    pub const fn n_angles(self) -> usize {
        match self {
            Reciprocity::Exact => 4,
            _ => 3,
        }
    }
}

/// How the surface position enters the networks (Sec. 4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PositionEncoding {
    /// No position input: a spatially uniform material.
    Uniform,
    /// The first `k` non-constant Laplace–Beltrami eigenfunctions at the point (Koestler et al. 2022).
    Intrinsic {
        /// Number of eigenfunctions.
        k: u16,
    },
    /// Positional encoding of the point `x` in the unit sphere with `frequencies` octaves.
    Extrinsic {
        /// Number of octaves.
        frequencies: u8,
    },
}

impl PositionEncoding {
    /// Number of values the caller passes to [`Model::prepare`](crate::Model::prepare): 0, `k`, or 3.
    #[inline]
    pub const fn input_len(self) -> usize {
        match self {
            PositionEncoding::Uniform => 0,
            PositionEncoding::Intrinsic { k } => k as usize,
            PositionEncoding::Extrinsic { .. } => 3,
        }
    }

    /// Number of values the networks see, `P` of `docs/models.md`.
    #[inline]
    pub const fn encoded_len(self) -> usize {
        match self {
            PositionEncoding::Uniform => 0,
            PositionEncoding::Intrinsic { k } => k as usize,
            PositionEncoding::Extrinsic { frequencies } => encoded_len(3, frequencies as usize),
        }
    }
}

/// Storage precision of the network weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Precision {
    /// IEEE binary32.
    F32,
    /// IEEE binary16 (`half::f16`): half the size, evaluated in f32.
    F16,
}

impl Precision {
    /// Bytes per weight.
    #[inline]
    pub const fn size(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 => 2,
        }
    }
}

/// Which model a file holds (Sec. 4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ModelKind {
    /// A parametric model whose parameters an MLP predicts from the position (Sec. 4.1.1).
    Parametric(ParametricKind),
    /// One MLP from position and angles to RGB (Sec. 4.1.2).
    SingleMlp,
    /// Separate diffuse and specular MLPs (NeRFactor-style, Sec. 4.1.2).
    AdditiveSeparate,
    /// A shared spatial trunk with diffuse and specular heads (LitNeRF-style, Sec. 4.1.2).
    AdditiveShared,
}

impl ModelKind {
    /// Whether the model has the additive diffuse/specular split that Eq. 8 can enhance.
    #[inline]
    pub const fn is_additive(self) -> bool {
        matches!(self, ModelKind::AdditiveSeparate | ModelKind::AdditiveShared)
    }
}

/// Everything needed to interpret the weights: model kind, encodings, network shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ModelHeader {
    /// The model.
    pub kind: ModelKind,
    /// Eq. 8 split (additive models only).
    pub enhanced: bool,
    /// Angle parametrisation.
    pub reciprocity: Reciprocity,
    /// Positional-encoding octaves of the angles, `F_a`.
    pub angle_frequencies: u8,
    /// Position input.
    pub position: PositionEncoding,
    /// Weight storage.
    pub precision: Precision,
    /// Network shapes in file order; the first `n_nets` are used.
    pub nets: [NetDesc; MAX_NETS],
    /// Number of networks.
    pub n_nets: u8,
    /// Rows of the per-vertex position table (0: none); intrinsic encoding only.
    pub n_vertices: u32,
    /// Importance-sampling proxy of a neural model ([`crate::sampling::Proxy`], fitted at export with
    /// [`crate::sampling::fit_proxy`]); `None` samples the cosine lobe. Parametric models sample their
    /// own lobes and ignore it.
    pub proxy: Option<crate::sampling::Proxy>,
    /// `nbrdf_scene::scene::Mesh::content_hash` (crate `nbrdf-scene`) of the mesh the per-vertex table
    /// was fitted on; `None` for a model without a table, or one exported before the field existed (its
    /// header ends before it; only the vertex count is then checked). A renderer refuses the table on
    /// a mesh of another hash.
    pub mesh_hash: Option<u64>,
    /// The sampling mixtures per view angle of a neural model ([`crate::sampling::ViewProxy`], fitted at
    /// export with [`crate::sampling::fit_view_proxy`]); sampling uses it where present and [`proxy`]
    /// otherwise. Files written before it existed end before it; readers that predate it ignore it and
    /// sample with `proxy`, which every export still carries.
    ///
    /// [`proxy`]: ModelHeader::proxy
    pub view_proxy: Option<crate::sampling::ViewProxy>,
    /// The conservative albedo table of an energy-bounded model ([`crate::energy::AlbedoBound`]):
    /// evaluation divides `f` by `max(1, Â(θi), Â(θo))` per channel, so the albedo is ≤ 1 wherever `Â`
    /// bounds it. A file with it is version 2, which older readers refuse rather than evaluate
    /// without it.
    pub albedo_bound: Option<crate::energy::AlbedoBound>,
}

impl ModelHeader {
    /// The architecture of the paper (Sec. 4.1, `docs/models.md`) for a model kind and input encodings.
    ///
    /// ```
    /// use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact,
    ///                            PositionEncoding::Intrinsic { k: 64 }, 4);
    /// assert!(h.validate().is_ok());
    /// assert_eq!(h.nets().len(), 3);
    /// assert_eq!(h.nets()[2].n_in as usize, 128 + 4 * 9); // trunk features + PE(Θ)
    /// assert_eq!(h.nets()[2].n_out, 6);                   // f_s and ξ
    /// ```
    pub fn paper(
        kind: ModelKind,
        enhanced: bool,
        reciprocity: Reciprocity,
        position: PositionEncoding,
        angle_frequencies: u8,
    ) -> Self {
        let p = position.encoded_len() as u16;
        let a = encoded_len(reciprocity.n_angles(), angle_frequencies as usize) as u16;
        let enhanced = enhanced && kind.is_additive();
        let spec_out = if enhanced { 6 } else { 3 };
        let none = NetDesc::default();
        let (nets, n_nets) = match kind {
            ModelKind::Parametric(pk) => (
                [NetDesc { n_in: p, width: 128, hidden: 6, n_out: pk.n_raw() as u16, skip: 2 }, none, none],
                1,
            ),
            ModelKind::SingleMlp => {
                ([NetDesc { n_in: p + a, width: 128, hidden: 6, n_out: 3, skip: 2 }, none, none], 1)
            }
            ModelKind::AdditiveSeparate => (
                [
                    NetDesc { n_in: p, width: 128, hidden: 4, n_out: 3, skip: 1 },
                    NetDesc { n_in: p + a, width: 128, hidden: 4, n_out: spec_out, skip: 1 },
                    none,
                ],
                2,
            ),
            ModelKind::AdditiveShared => (
                [
                    NetDesc { n_in: p, width: 128, hidden: 5, n_out: 0, skip: 2 },
                    NetDesc { n_in: 128, width: 128, hidden: 1, n_out: 3, skip: 0 },
                    NetDesc { n_in: 128 + a, width: 128, hidden: 2, n_out: spec_out, skip: 0 },
                ],
                3,
            ),
        };
        ModelHeader {
            kind,
            enhanced,
            reciprocity,
            angle_frequencies,
            position,
            precision: Precision::F32,
            nets,
            n_nets,
            n_vertices: 0,
            proxy: None,
            mesh_hash: None,
            view_proxy: None,
            albedo_bound: None,
        }
    }

    /// The same header carrying the sampling proxy `proxy` (see [`ModelHeader::proxy`]).
    ///
    /// ```
    /// use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// use nbrdf::sampling::{GgxLobe, Proxy};
    /// let proxy = Proxy::new(0.3, [GgxLobe { weight: 0.7, alpha: 0.05 }, GgxLobe::NONE]).unwrap();
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2)
    ///     .with_proxy(proxy);
    /// assert_eq!(h.proxy, Some(proxy));
    /// assert!(h.validate().is_ok());
    /// ```
    pub fn with_proxy(mut self, proxy: crate::sampling::Proxy) -> Self {
        self.proxy = Some(proxy);
        self
    }

    /// The same header carrying the per-view sampling table `view` (see [`ModelHeader::view_proxy`]).
    pub fn with_view_proxy(mut self, view: crate::sampling::ViewProxy) -> Self {
        self.view_proxy = Some(view);
        self
    }

    /// The same header carrying the albedo bound `bound` (see [`ModelHeader::albedo_bound`]).
    pub fn with_albedo_bound(mut self, bound: crate::energy::AlbedoBound) -> Self {
        self.albedo_bound = Some(bound);
        self
    }

    /// The format version a file of this header is written as: 2 with an albedo bound, else 1.
    pub fn version(&self) -> u32 {
        if self.albedo_bound.is_some() {
            2
        } else {
            1
        }
    }

    /// The same architecture with every network `width` wide (the paper's is 128): a smaller model for
    /// a tight shading budget, or a quick test. Where a trunk feeds a head, the head's input follows.
    ///
    /// ```
    /// use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// let h = ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Uniform, 2)
    ///     .with_width(16);
    /// assert!(h.validate().is_ok());
    /// assert_eq!(h.nets()[2].n_in as usize, 16 + h.angle_input_len());
    /// ```
    pub fn with_width(mut self, width: u16) -> Self {
        let a = self.angle_input_len() as u16;
        for n in self.nets.iter_mut().take(self.n_nets as usize) {
            n.width = width;
        }
        match (self.kind, self.n_nets) {
            (ModelKind::SingleMlp, 2) => self.nets[1].n_in = width + a,
            (ModelKind::AdditiveShared, 3) => {
                self.nets[1].n_in = width;
                self.nets[2].n_in = width + a;
            }
            _ => {}
        }
        self
    }

    /// The same model with `nol` hidden layers after the angles enter: the "number of layers for the
    /// directions" of Tab. 2. Single MLP: a position-only trunk of `6 - nol` layers, then a head of `nol`
    /// layers on `[trunk, PE(a)]` (`nol ≥ 6` keeps the paper's single network). Additive Separate: the
    /// specular network gets `nol` hidden layers (skip kept only where it still lands inside). Additive
    /// Shared: the specular head gets `nol` layers. Parametric models have no direction layers and are
    /// returned unchanged.
    ///
    /// ```
    /// use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    /// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::None,
    ///                            PositionEncoding::Intrinsic { k: 32 }, 4)
    ///     .with_direction_layers(3);
    /// assert!(h.validate().is_ok());
    /// assert_eq!((h.nets()[0].hidden, h.nets()[1].hidden), (3, 3));
    /// ```
    pub fn with_direction_layers(mut self, nol: u8) -> Self {
        let nol = nol.max(1);
        match self.kind {
            ModelKind::Parametric(_) => {}
            ModelKind::SingleMlp => {
                let p = self.position.encoded_len() as u16;
                let a = encoded_len(self.reciprocity.n_angles(), self.angle_frequencies as usize) as u16;
                if nol >= 6 {
                    self.nets[0] = NetDesc { n_in: p + a, width: 128, hidden: 6, n_out: 3, skip: 2 };
                    self.nets[1] = NetDesc::default();
                    self.n_nets = 1;
                } else {
                    self.nets[0] = NetDesc { n_in: p, width: 128, hidden: 6 - nol, n_out: 0, skip: 0 };
                    self.nets[1] = NetDesc { n_in: 128 + a, width: 128, hidden: nol, n_out: 3, skip: 0 };
                    self.n_nets = 2;
                }
            }
            ModelKind::AdditiveSeparate => {
                let n = &mut self.nets[1];
                n.hidden = nol;
                if n.skip >= nol {
                    n.skip = 0;
                }
            }
            ModelKind::AdditiveShared => self.nets[2].hidden = nol,
        }
        self
    }

    /// The networks in file order.
    #[inline]
    pub fn nets(&self) -> &[NetDesc] {
        &self.nets[..(self.n_nets as usize).min(MAX_NETS)]
    }

    /// Per-object raw parameters after the networks (FMBRDF: its NDF normalisation).
    #[inline]
    pub const fn n_object(&self) -> usize {
        match self.kind {
            ModelKind::Parametric(pk) => pk.n_object(),
            _ => 0,
        }
    }

    /// Number of network weights (biases included), all networks together.
    #[inline]
    pub fn n_network_weights(&self) -> usize {
        self.nets().iter().map(NetDesc::n_weights).sum()
    }

    /// Number of values the trainer exports: all networks' weights in file order, then the object
    /// parameters (what [`encode`] takes as `weights`).
    #[inline]
    pub fn n_weights(&self) -> usize {
        self.n_network_weights() + self.n_object()
    }

    /// Length of the encoded angle input `A`.
    #[inline]
    pub const fn angle_input_len(&self) -> usize {
        encoded_len(self.reciprocity.n_angles(), self.angle_frequencies as usize)
    }

    /// Checks that the header describes a model this build can evaluate: known limits, and every
    /// network's shape consistent with the model kind and the input encodings.
    pub fn validate(&self) -> Result<(), Error> {
        if self.angle_frequencies > MAX_FREQUENCIES {
            return Err(Error::TooLarge {
                what: "angle encoding frequencies",
                found: self.angle_frequencies as usize,
                max: MAX_FREQUENCIES as usize,
            });
        }
        match self.position {
            PositionEncoding::Intrinsic { k } if k == 0 || k > MAX_INTRINSIC => {
                return Err(Error::InvalidValue {
                    what: "intrinsic encoding size k",
                    reason: "must be between 1 and 4096",
                })
            }
            PositionEncoding::Extrinsic { frequencies } if frequencies > MAX_FREQUENCIES => {
                return Err(Error::TooLarge {
                    what: "position encoding frequencies",
                    found: frequencies as usize,
                    max: MAX_FREQUENCIES as usize,
                })
            }
            _ => {}
        }
        if self.n_vertices > 0 && !matches!(self.position, PositionEncoding::Intrinsic { .. }) {
            return Err(Error::InvalidValue {
                what: "position table",
                reason: "only an intrinsic encoding carries a per-vertex table",
            });
        }
        if self.mesh_hash.is_some() && self.n_vertices == 0 {
            return Err(Error::InvalidValue {
                what: "mesh hash",
                reason: "only a model with a per-vertex table records its mesh",
            });
        }
        if self.enhanced && !self.kind.is_additive() {
            return Err(Error::InvalidValue {
                what: "enhanced flag",
                reason: "only additive models have the split of Eq. 8",
            });
        }
        if let Some(p) = &self.proxy {
            p.validate()?;
        }
        if let Some(p) = &self.view_proxy {
            p.validate()?;
        }
        if let Some(b) = &self.albedo_bound {
            b.validate()?;
        }
        if self.n_nets as usize > MAX_NETS || self.n_nets == 0 {
            return Err(Error::InvalidValue { what: "network count", reason: "must be 1 to 3" });
        }
        for net in self.nets() {
            net.validate()?;
        }
        let p = self.position.encoded_len();
        let a = self.angle_input_len();
        let spec = if self.enhanced { 6 } else { 3 };
        let n = self.nets();
        let expect = |i: usize, n_in: usize, n_out: usize, what: &'static str| -> Result<(), Error> {
            if n[i].n_in as usize != n_in {
                return Err(Error::SizeMismatch { what, expected: n_in, found: n[i].n_in as usize });
            }
            if n[i].n_out as usize != n_out {
                return Err(Error::SizeMismatch { what, expected: n_out, found: n[i].n_out as usize });
            }
            Ok(())
        };
        match (self.kind, n.len()) {
            (ModelKind::Parametric(pk), 1) => expect(0, p, pk.n_raw(), "parameter network"),
            (ModelKind::SingleMlp, 1) => expect(0, p + a, 3, "single MLP"),
            (ModelKind::SingleMlp, 2) => {
                expect(0, p, 0, "single MLP trunk")?;
                expect(1, n[0].width as usize + a, 3, "single MLP head")
            }
            (ModelKind::AdditiveSeparate, 2) => {
                expect(0, p, 3, "diffuse network")?;
                expect(1, p + a, spec, "specular network")
            }
            (ModelKind::AdditiveShared, 3) => {
                expect(0, p, 0, "shared trunk")?;
                expect(1, n[0].width as usize, 3, "diffuse head")?;
                expect(2, n[0].width as usize + a, spec, "specular head")
            }
            _ => Err(Error::InvalidValue { what: "network count", reason: "does not match the model kind" }),
        }?;
        // Both the position and the angle part must fit the evaluator's stack buffers.
        if a > MAX_ANGLE_INPUT {
            return Err(Error::TooLarge { what: "angle input", found: a, max: MAX_ANGLE_INPUT });
        }
        const { assert!(MAX_WIDTH >= 6) };
        Ok(())
    }
}

/// Byte ranges of the sections of a validated file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Sections {
    pub weights: (usize, usize),
    pub object: (usize, usize),
    pub table: (usize, usize),
}

#[inline]
const fn align4(n: usize) -> usize {
    (n + 3) & !3
}

fn read_u32(bytes: &[u8], at: usize, what: &'static str) -> Result<u32, Error> {
    match bytes.get(at..at + 4) {
        Some(b) => Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        None => Err(Error::Truncated { what, needed: at + 4, got: bytes.len() }),
    }
}

/// Size arithmetic that cannot overflow into a wrong (accepted) size.
fn checked(a: usize, b: usize) -> Result<usize, Error> {
    a.checked_add(b).ok_or(Error::TooLarge { what: "file section", found: usize::MAX, max: u32::MAX as usize })
}

/// Parses and validates a whole file; returns the header and the section ranges.
pub(crate) fn parse(bytes: &[u8]) -> Result<(ModelHeader, Sections), Error> {
    if bytes.len() < 8 {
        return Err(Error::Truncated { what: "model file magic", needed: 8, got: bytes.len() });
    }
    if bytes[..8] != MAGIC {
        return Err(Error::BadMagic { what: "nbrdf model" });
    }
    let version = read_u32(bytes, 8, "model file version")?;
    if version == 0 || version > VERSION {
        return Err(Error::UnsupportedVersion { what: "nbrdf model", found: version, supported: VERSION });
    }
    let header_len = read_u32(bytes, 12, "model header length")? as usize;
    let header_end = checked(16, header_len)?;
    let header_bytes = bytes
        .get(16..header_end)
        .ok_or(Error::Truncated { what: "model header", needed: header_end, got: bytes.len() })?;
    let header = decode_header(header_bytes)?;
    header.validate()?;
    if header.version() > version {
        return Err(Error::InvalidValue {
            what: "model file version",
            reason: "a header with an albedo bound needs version 2",
        });
    }

    let weights_start = align4(header_end);
    let weights_len = header
        .n_network_weights()
        .checked_mul(header.precision.size())
        .ok_or(Error::TooLarge { what: "weights", found: usize::MAX, max: u32::MAX as usize })?;
    let weights_end = checked(weights_start, weights_len)?;
    let object_start = align4(weights_end);
    let object_end = checked(object_start, 4 * header.n_object())?;
    let table_values = (header.n_vertices as usize)
        .checked_mul(header.position.input_len())
        .and_then(|n| n.checked_mul(4))
        .ok_or(Error::TooLarge { what: "position table", found: usize::MAX, max: u32::MAX as usize })?;
    let table_end = checked(object_end, table_values)?;
    let total = checked(table_end, 4)?;
    if total as u64 > MAX_FILE_BYTES || bytes.len() as u64 > MAX_FILE_BYTES {
        let max = usize::try_from(MAX_FILE_BYTES).unwrap_or(usize::MAX);
        return Err(Error::TooLarge { what: "model file bytes", found: total.max(bytes.len()), max });
    }
    if bytes.len() < total {
        return Err(Error::Truncated { what: "model file", needed: total, got: bytes.len() });
    }
    if bytes.len() > total {
        return Err(Error::SizeMismatch { what: "model file size", expected: total, found: bytes.len() });
    }
    let stored = read_u32(bytes, table_end, "model checksum")?;
    let computed = crc32fast::hash(&bytes[..table_end]);
    if stored != computed {
        return Err(Error::ChecksumMismatch { stored, computed });
    }
    let sections = Sections {
        weights: (weights_start, weights_end),
        object: (object_start, object_end),
        table: (object_end, table_end),
    };
    check_finite(bytes, &header, &sections)?;
    Ok((header, sections))
}

/// Longest header accepted without its last trailing optional fields (a header is under 100 bytes
/// with none of them, about 450 with all but the albedo bound).
const MAX_LEGACY_HEADER: usize = 1024;

/// Optional fields at the end of the header, in order, each added after version 1 was released:
/// `proxy`, `mesh_hash`, `view_proxy`, then `albedo_bound`.
const TRAILING_OPTIONS: usize = 4;

/// How many of the trailing optional fields, counted from the last, are `None` in a row.
fn trailing_nones(h: &ModelHeader) -> usize {
    [h.albedo_bound.is_none(), h.view_proxy.is_none(), h.mesh_hash.is_none(), h.proxy.is_none()]
        .iter()
        .take_while(|none| **none)
        .count()
}

/// Decodes the postcard header. A header may end before any of its trailing optional fields (files
/// written before the field existed, and [`encode`], which leaves a trailing `None` out so that such
/// files stay byte-identical to before): the missing fields decode as `None` (postcard's `None` is the
/// single byte 0). Readers that predate a field ignore it: postcard stops after the fields it knows.
fn decode_header(bytes: &[u8]) -> Result<ModelHeader, Error> {
    let bad = Error::InvalidValue { what: "model header", reason: "not a valid header encoding" };
    match postcard::from_bytes::<ModelHeader>(bytes) {
        Ok(h) => Ok(h),
        Err(postcard::Error::DeserializeUnexpectedEnd) if bytes.len() + TRAILING_OPTIONS <= MAX_LEGACY_HEADER => {
            let mut buf = [0u8; MAX_LEGACY_HEADER];
            buf[..bytes.len()].copy_from_slice(bytes);
            for missing in 1..=TRAILING_OPTIONS {
                match postcard::from_bytes::<ModelHeader>(&buf[..bytes.len() + missing]) {
                    // Only the appended fields may be filled in, and only with `None`.
                    Ok(h) if trailing_nones(&h) >= missing => return Ok(h),
                    Err(postcard::Error::DeserializeUnexpectedEnd) => continue,
                    _ => return Err(bad),
                }
            }
            Err(bad)
        }
        Err(_) => Err(bad),
    }
}

/// The postcard header without its trailing `None`s, so that it ends as it did before those fields
/// existed (see `decode_header`): files without them stay byte-identical to older exports.
#[cfg(feature = "alloc")]
fn encode_header(header: &ModelHeader) -> Result<alloc::vec::Vec<u8>, Error> {
    let mut bytes = postcard::to_allocvec(header)
        .map_err(|_| Error::InvalidValue { what: "model header", reason: "cannot be encoded" })?;
    // The proxy's byte stays: version-1 exports always wrote it.
    for _ in 0..trailing_nones(header).min(TRAILING_OPTIONS - 1) {
        bytes.pop();
    }
    Ok(bytes)
}

/// NaN or infinite weights would poison every evaluation; reject them at load.
fn check_finite(bytes: &[u8], header: &ModelHeader, s: &Sections) -> Result<(), Error> {
    let w = &bytes[s.weights.0..s.weights.1];
    match header.precision {
        Precision::F32 => {
            for (i, c) in w.chunks_exact(4).enumerate() {
                if !f32::from_le_bytes([c[0], c[1], c[2], c[3]]).is_finite() {
                    return Err(Error::NonFinite { what: "network weights", index: i });
                }
            }
        }
        Precision::F16 => {
            for (i, c) in w.chunks_exact(2).enumerate() {
                if !half::f16::from_le_bytes([c[0], c[1]]).is_finite() {
                    return Err(Error::NonFinite { what: "network weights", index: i });
                }
            }
        }
    }
    for (what, (a, b)) in [("object parameters", s.object), ("position table", s.table)] {
        for (i, c) in bytes[a..b].chunks_exact(4).enumerate() {
            if !f32::from_le_bytes([c[0], c[1], c[2], c[3]]).is_finite() {
                return Err(Error::NonFinite { what, index: i });
            }
        }
    }
    Ok(())
}

/// Serialises a model: `weights` holds all networks' weights in file order followed by the object
/// parameters ([`ModelHeader::n_weights`] values, as f32 whatever the header's precision); the
/// position table (`n_vertices × k`, intrinsic only) is optional and sets `n_vertices`.
///
/// ```
/// use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
/// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
/// let bytes = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
/// let model = nbrdf::ModelBuf::from_bytes(&bytes).unwrap();
/// assert_eq!(model.header(), &h);
/// ```
#[cfg(feature = "alloc")]
pub fn encode(
    header: &ModelHeader,
    weights: &[f32],
    position_table: Option<&[f32]>,
) -> Result<alloc::vec::Vec<u8>, Error> {
    use alloc::vec::Vec;
    let mut header = *header;
    let k = header.position.input_len();
    header.n_vertices = match position_table {
        Some(t) => {
            if k == 0 || t.len() % k != 0 || !matches!(header.position, PositionEncoding::Intrinsic { .. }) {
                return Err(Error::SizeMismatch {
                    what: "position table length (a multiple of the intrinsic k)",
                    expected: k,
                    found: t.len(),
                });
            }
            u32::try_from(t.len() / k)
                .map_err(|_| Error::TooLarge { what: "position table rows", found: t.len() / k, max: u32::MAX as usize })?
        }
        None => 0,
    };
    header.validate()?;
    if weights.len() != header.n_weights() {
        return Err(Error::SizeMismatch { what: "exported weights", expected: header.n_weights(), found: weights.len() });
    }
    if let Some(i) = weights.iter().position(|w| !w.is_finite()) {
        return Err(Error::NonFinite { what: "exported weights", index: i });
    }
    let (net_w, object) = weights.split_at(header.n_network_weights());
    let header_bytes = encode_header(&header)?;
    let mut out = Vec::with_capacity(16 + header_bytes.len() + weights.len() * 4 + 8);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&header.version().to_le_bytes());
    out.extend_from_slice(&(header_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&header_bytes);
    out.resize(align4(out.len()), 0);
    match header.precision {
        Precision::F32 => net_w.iter().for_each(|w| out.extend_from_slice(&w.to_le_bytes())),
        Precision::F16 => {
            for (i, w) in net_w.iter().enumerate() {
                let h = half::f16::from_f32(*w);
                if !h.is_finite() {
                    return Err(Error::NonFinite { what: "weights after f16 conversion (|w| > 65504)", index: i });
                }
                out.extend_from_slice(&h.to_le_bytes());
            }
        }
    }
    out.resize(align4(out.len()), 0);
    object.iter().for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
    if let Some(t) = position_table {
        if let Some(i) = t.iter().position(|w| !w.is_finite()) {
            return Err(Error::NonFinite { what: "position table", index: i });
        }
        t.iter().for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// The model file `bytes` with [`ModelHeader::mesh_hash`] set to `hash`: the mesh its per-vertex table
/// was fitted on. Everything after the header is kept byte for byte; the checksum is recomputed.
///
/// ```
/// use nbrdf::file::{encode, record_mesh, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
/// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 2 }, 2);
/// let bytes = encode(&h, &vec![0.01; h.n_weights()], Some(&[0.0; 8])).unwrap();
/// let stamped = record_mesh(&bytes, 42).unwrap();
/// assert_eq!(nbrdf::ModelBuf::from_bytes(&stamped).unwrap().header().mesh_hash, Some(42));
/// ```
#[cfg(feature = "alloc")]
pub fn record_mesh(bytes: &[u8], hash: u64) -> Result<alloc::vec::Vec<u8>, Error> {
    rewrite_header(bytes, |h| h.mesh_hash = Some(hash))
}

/// The model file `bytes` with [`ModelHeader::albedo_bound`] set to `bound` (`None` removes it): the
/// energy-bounded model of the same networks, or the unbounded one back. Everything after the header
/// is kept byte for byte; the version follows the header ([`ModelHeader::version`]).
///
/// ```
/// use nbrdf::energy::{AlbedoBound, ALBEDO_CELLS};
/// use nbrdf::file::{encode, set_albedo_bound, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
/// let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
/// let bytes = encode(&h, &vec![0.01; h.n_weights()], None).unwrap();
/// let bound = AlbedoBound { cells: [[1.5; 3]; ALBEDO_CELLS] };
/// let bounded = set_albedo_bound(&bytes, Some(bound)).unwrap();
/// assert_eq!(bounded[8], 2); // version 2: older readers refuse it rather than ignore the bound
/// assert_eq!(set_albedo_bound(&bounded, None).unwrap(), bytes);
/// ```
#[cfg(feature = "alloc")]
pub fn set_albedo_bound(bytes: &[u8], bound: Option<crate::energy::AlbedoBound>) -> Result<alloc::vec::Vec<u8>, Error> {
    rewrite_header(bytes, |h| h.albedo_bound = bound)
}

/// The model file `bytes` with its header changed by `change`; the sections after it byte for byte.
#[cfg(feature = "alloc")]
fn rewrite_header(bytes: &[u8], change: impl FnOnce(&mut ModelHeader)) -> Result<alloc::vec::Vec<u8>, Error> {
    use alloc::vec::Vec;
    let (mut header, sections) = parse(bytes)?;
    change(&mut header);
    header.validate()?;
    let header_bytes = encode_header(&header)?;
    let body = &bytes[sections.weights.0..sections.table.1];
    let mut out = Vec::with_capacity(16 + header_bytes.len() + 3 + body.len() + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&header.version().to_le_bytes());
    out.extend_from_slice(&(header_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&header_bytes);
    // Every section after the header starts 4-aligned, so the body keeps its layout after padding.
    out.resize(align4(out.len()), 0);
    out.extend_from_slice(body);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Writes bytes to `path` atomically: a temporary file in the same directory, then a rename, so an
/// interrupted write never leaves a half-written model where a complete one is expected.
#[cfg(feature = "std")]
pub fn save(path: impl AsRef<std::path::Path>, bytes: &[u8]) -> Result<(), Error> {
    crate::io::write_atomic(path.as_ref(), bytes)
}
