//! What a model is made of: its kind, inputs and networks (docs/models.md, Sec. 4.1), independent of
//! candle. [`Config`] names one variant of the study; [`Config::nets`] lists its networks in file order.
//!
//! The network table here mirrors `ModelHeader::paper` of the core's file format; once that is in the
//! core, a test holds the two together.

/// Reciprocity strategy of Sec. 4.3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Reciprocity {
    /// Rusinkiewicz angles as they are.
    None,
    /// LitNeRF's random swap of `wi` and `wo` during training; evaluation as `None`.
    Swap,
    /// The exact map Θ of Eq. 6.
    Exact,
}

/// How the surface position enters the networks (docs/models.md "Inputs").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PositionEncoding {
    /// No position input: a uniform material.
    Uniform,
    /// `k` Laplace–Beltrami eigenfunctions (Koestler et al. 2022), passed in by the caller.
    Intrinsic { k: u16 },
    /// `PE(x, F)` of the point in the unit sphere.
    Extrinsic { frequencies: u8 },
}

impl PositionEncoding {
    /// Values the caller passes per sample (before the model's own encoding).
    pub fn n_raw(self) -> usize {
        match self {
            PositionEncoding::Uniform => 0,
            PositionEncoding::Intrinsic { k } => k as usize,
            PositionEncoding::Extrinsic { .. } => 3,
        }
    }

    /// `P`: values the networks see.
    pub fn n_features(self) -> usize {
        match self {
            PositionEncoding::Uniform => 0,
            PositionEncoding::Intrinsic { k } => k as usize,
            PositionEncoding::Extrinsic { frequencies } => 3 * (1 + 2 * frequencies as usize),
        }
    }
}

/// Parametric models of Sec. 4.1.1 (mirrors the core's `ParametricKind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ParametricKind {
    Lambert,
    Phong,
    TorranceSparrow,
    FresnelMicrofacet,
    Disney,
}

/// Model families of Sec. 4.1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Kind {
    Parametric(ParametricKind),
    SingleMlp,
    AdditiveSeparate,
    AdditiveShared,
}

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

/// Hidden width of every network (Sec. 4.1).
pub const WIDTH: u16 = 128;

/// Default `F_a`: NeRF's 4 octaves for directions (Mildenhall et al. 2020). The paper's appendix value
/// is not in the text we have.
pub const DEFAULT_ANGLE_FREQUENCIES: u8 = 4;

impl Config {
    /// A variant with the paper's defaults for everything but the kind and its extension flags.
    pub fn paper(kind: Kind, enhanced: bool, reciprocity: Reciprocity, position: PositionEncoding) -> Self {
        Config { kind, enhanced, reciprocity, position, angle_frequencies: DEFAULT_ANGLE_FREQUENCIES, direction_layers: None }
    }

    /// Angle values before encoding: 3 Rusinkiewicz angles, or the 4 of Θ (Eq. 6).
    pub fn n_angles(&self) -> usize {
        if self.reciprocity == Reciprocity::Exact {
            4
        } else {
            3
        }
    }

    /// `A = n_a (1 + 2 F_a)`.
    pub fn n_angle_features(&self) -> usize {
        self.n_angles() * (1 + 2 * self.angle_frequencies as usize)
    }

    /// Whether the model has a specular network with a Eq. 8 weight ξ.
    pub fn has_xi(&self) -> bool {
        self.enhanced && matches!(self.kind, Kind::AdditiveSeparate | Kind::AdditiveShared)
    }

    /// The networks in file order (docs/models.md table).
    pub fn nets(&self) -> Vec<NetDesc> {
        let p = self.position.n_features() as u16;
        let a = self.n_angle_features() as u16;
        let spec_out = if self.has_xi() { 6 } else { 3 };
        let net = |n_in, hidden, n_out, skip| NetDesc { n_in, width: WIDTH, hidden, n_out, skip };
        match self.kind {
            Kind::Parametric(k) => vec![net(p, 6, parametric_n_raw(k) as u16, 2)],
            Kind::SingleMlp => match self.direction_layers {
                None | Some(6) => vec![net(p + a, 6, 3, 2)],
                Some(n) => vec![net(p, 6 - n.min(6), 0, 0), net(WIDTH + a, n, 3, 0)],
            },
            Kind::AdditiveSeparate => {
                let n = self.direction_layers.unwrap_or(4);
                vec![net(p, 4, 3, 1), net(p + a, n, spec_out, if n >= 2 { 1 } else { 0 })]
            }
            Kind::AdditiveShared => {
                let n = self.direction_layers.unwrap_or(2);
                vec![net(p, 5, 0, 2), net(WIDTH, 1, 3, 0), net(WIDTH + a, n, spec_out, 0)]
            }
        }
    }

    /// Per-object parameters after the networks (FMBRDF's NDF normalisation, Sec. 4.1.1).
    pub fn n_object(&self) -> usize {
        match self.kind {
            Kind::Parametric(k) => parametric_n_object(k),
            _ => 0,
        }
    }

    /// All trainable values, in file order.
    pub fn n_weights(&self) -> usize {
        self.nets().iter().map(NetDesc::n_weights).sum::<usize>() + self.n_object()
    }

    /// Short name for the command line, logs and the study tables.
    pub fn name(&self) -> String {
        let base = match self.kind {
            Kind::Parametric(ParametricKind::Lambert) => "lambert",
            Kind::Parametric(ParametricKind::Phong) => "rp",
            Kind::Parametric(ParametricKind::TorranceSparrow) => "ts",
            Kind::Parametric(ParametricKind::FresnelMicrofacet) => "fmbrdf",
            Kind::Parametric(ParametricKind::Disney) => "disney",
            Kind::SingleMlp => "single-mlp",
            Kind::AdditiveSeparate => "additive-separate",
            Kind::AdditiveShared => "additive-shared",
        };
        let mut s = base.to_string();
        if self.has_xi() {
            s.push_str("+enhanced");
        }
        if !matches!(self.kind, Kind::Parametric(_)) {
            match self.reciprocity {
                Reciprocity::None => {}
                Reciprocity::Swap => s.push_str("+swap"),
                Reciprocity::Exact => s.push_str("+exact"),
            }
        }
        if let Some(n) = self.direction_layers {
            s.push_str(&format!("+nol{n}"));
        }
        s
    }
}

/// The kind named on the command line (`rp`, `ts`, `fmbrdf`, `disney`, `lambert`, `single-mlp`,
/// `additive-separate`, `additive-shared`).
pub fn parse_kind(name: &str) -> Option<Kind> {
    Some(match name {
        "lambert" => Kind::Parametric(ParametricKind::Lambert),
        "rp" | "phong" => Kind::Parametric(ParametricKind::Phong),
        "ts" | "torrance-sparrow" => Kind::Parametric(ParametricKind::TorranceSparrow),
        "fmbrdf" | "fresnel-microfacet" => Kind::Parametric(ParametricKind::FresnelMicrofacet),
        "disney" => Kind::Parametric(ParametricKind::Disney),
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

/// Raw network outputs of a parametric model; provisional until the core's tables land (they replace
/// this function).
pub fn parametric_n_raw(kind: ParametricKind) -> usize {
    super::parametric::n_raw(kind)
}

/// Per-object raw parameters of a parametric model.
pub fn parametric_n_object(kind: ParametricKind) -> usize {
    super::parametric::n_object(kind)
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
