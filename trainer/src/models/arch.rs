//! What a model is made of: its kind, inputs and networks (docs/models.md, Sec. 4.1), independent of
//! candle. [`Config`] names one variant of the study; its networks are those of the core's
//! `ModelHeader`, so the trainer and the file format cannot disagree on an architecture.

pub use nbrdf::file::{ModelHeader, ModelKind as Kind, PositionEncoding, Reciprocity};
pub use nbrdf::parametric::ParametricKind;

/// One dense network `Mlp(n_in, width, hidden, n_out, skip)` of docs/models.md: the core's own type, so
/// both sides agree on layer sizes and offsets by construction.
pub use nbrdf::mlp::NetDesc;

/// `(inputs, outputs)` of every layer of `net` in file order.
pub fn layers(net: &NetDesc) -> Vec<(usize, usize)> {
    (0..net.n_layers()).map(|l| (net.layer_inputs(l), net.layer_outputs(l))).collect()
}

/// One model variant: everything that fixes its architecture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Config {
    pub kind: Kind,
    /// Eq. 8 split (additive models only).
    pub enhanced: bool,
    pub reciprocity: Reciprocity,
    pub position: PositionEncoding,
    /// `F_a` of the angles' positional encoding.
    pub angle_frequencies: u8,
    /// Number of layers the directions pass through (Tab. 2); `None`: the paper's default of the kind.
    pub direction_layers: Option<u8>,
}

/// Default `F_a`: NeRF's 4 octaves for directions (Mildenhall et al. 2020). The paper's appendix value
/// is not in the text we have.
pub const DEFAULT_ANGLE_FREQUENCIES: u8 = 4;

impl Config {
    /// A variant with the paper's defaults for everything but the kind and its extension flags.
    pub fn paper(kind: Kind, enhanced: bool, reciprocity: Reciprocity, position: PositionEncoding) -> Self {
        Config { kind, enhanced, reciprocity, position, angle_frequencies: DEFAULT_ANGLE_FREQUENCIES, direction_layers: None }
    }

    /// The variant whose file header is `header` (kind, flags, encodings and networks), or `None` for a
    /// header the trainer does not build (another width, a hand-made layout).
    pub fn of_header(header: &ModelHeader) -> Option<Config> {
        let base = Config {
            kind: header.kind,
            enhanced: header.enhanced && header.kind.is_additive(),
            reciprocity: header.reciprocity,
            position: header.position,
            angle_frequencies: header.angle_frequencies,
            direction_layers: None,
        };
        core::iter::once(None)
            .chain((1..=6).map(Some))
            .map(|direction_layers| Config { direction_layers, ..base })
            .find(|c| c.header().nets() == header.nets())
    }

    /// The core's file header of this variant: `ModelHeader::paper` with the Tab. 2 layer count.
    pub fn header(&self) -> ModelHeader {
        let h = ModelHeader::paper(self.kind, self.enhanced, self.reciprocity, self.position, self.angle_frequencies);
        match self.direction_layers {
            Some(n) => h.with_direction_layers(n),
            None => h,
        }
    }

    /// Angle values before encoding: 3 Rusinkiewicz angles, or the 4 of Θ (Eq. 6).
    pub fn n_angles(&self) -> usize {
        self.reciprocity.n_angles()
    }

    /// `A = n_a (1 + 2 F_a)`.
    pub fn n_angle_features(&self) -> usize {
        nbrdf::encoding::encoded_len(self.n_angles(), self.angle_frequencies as usize)
    }

    /// Whether the model has a specular network with a Eq. 8 weight ξ.
    pub fn has_xi(&self) -> bool {
        self.enhanced && self.kind.is_additive()
    }

    /// The networks in file order (docs/models.md table), as the core's header lists them.
    pub fn nets(&self) -> Vec<NetDesc> {
        self.header().nets().to_vec()
    }

    /// Per-object parameters after the networks (FMBRDF's NDF normalisation, Sec. 4.1.1).
    pub fn n_object(&self) -> usize {
        self.header().n_object()
    }

    /// All trainable values, in file order.
    pub fn n_weights(&self) -> usize {
        self.header().n_weights()
    }

    /// Short name for the command line, logs and the study tables.
    pub fn name(&self) -> String {
        let base = kind_name(self.kind);
        let mut s = base.to_string();
        if self.has_xi() {
            s.push_str("+enhanced");
        }
        if !matches!(self.kind, Kind::Parametric(_)) && self.reciprocity != Reciprocity::None {
            s.push('+');
            s.push_str(reciprocity_name(self.reciprocity));
        }
        if let Some(n) = self.direction_layers {
            s.push_str(&format!("+nol{n}"));
        }
        s
    }
}

/// The short name of a kind in logs and the study tables (the paper's abbreviations `rp`, `ts`,
/// from the core's name table).
pub fn kind_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Parametric(k) => k.short_name(),
        Kind::SingleMlp => "single-mlp",
        Kind::AdditiveSeparate => "additive-separate",
        Kind::AdditiveShared => "additive-shared",
    }
}

/// The name of a reciprocity strategy on the command line, in configs and in variant names.
pub fn reciprocity_name(r: Reciprocity) -> &'static str {
    match r {
        Reciprocity::None => "none",
        Reciprocity::Swap => "swap",
        Reciprocity::Exact => "exact",
    }
}

/// The kind named on the command line: a parametric model by the core's name table
/// ([`ParametricKind::from_name`]: `lambert`, `rp`/`phong`, `ts`/`torrance-sparrow`, `fmbrdf`,
/// `disney`), or `single-mlp`, `additive-separate`, `additive-shared`.
pub fn parse_kind(name: &str) -> Option<Kind> {
    if let Some(k) = ParametricKind::from_name(name) {
        return Some(Kind::Parametric(k));
    }
    Some(match name {
        "single-mlp" => Kind::SingleMlp,
        "additive-separate" => Kind::AdditiveSeparate,
        "additive-shared" => Kind::AdditiveShared,
        _ => return None,
    })
}

/// The nine variants of Tab. 1 with a given position encoding and reciprocity strategy for the purely
/// neural ones.
pub fn study_variants(position: PositionEncoding, reciprocity: Reciprocity) -> Vec<Config> {
    use Kind::*;
    use ParametricKind::*;
    let mut v: Vec<Config> = [Phong, TorranceSparrow, FresnelMicrofacet, Disney]
        .into_iter()
        .map(|k| Config::paper(Parametric(k), false, Reciprocity::None, position))
        .collect();
    for (kind, enhanced) in [
        (SingleMlp, false),
        (AdditiveSeparate, false),
        (AdditiveShared, false),
        (AdditiveSeparate, true),
        (AdditiveShared, true),
    ] {
        v.push(Config::paper(kind, enhanced, reciprocity, position));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's Single MLP (6 x 128, skip to layer 3) on 16 eigenfunctions and PE(Θ, 4).
    #[test]
    fn single_mlp_layers_follow_docs() {
        let c = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 16 });
        let a = 4 * 9;
        let nets = c.nets();
        assert_eq!(nets.len(), 1);
        let l = layers(&nets[0]);
        assert_eq!(l.len(), 7);
        assert_eq!(l[0], (16 + a, 128));
        assert_eq!(l[2], (128 + 16 + a, 128), "skip to the third layer is S = 2");
        assert_eq!(l[6], (128, 3));
    }

    /// Tab. 2: the directions pass through `n` layers, the rest become a position-only trunk.
    #[test]
    fn direction_layers_split_single_mlp() {
        let mut c = Config::paper(Kind::SingleMlp, false, Reciprocity::None, PositionEncoding::Intrinsic { k: 8 });
        c.direction_layers = Some(3);
        let nets = c.nets();
        assert_eq!((nets[0].hidden, nets[0].n_out, nets[1].hidden), (3, 0, 3));
        assert_eq!(nets[1].n_in as usize, 128 + 27);
    }
}
