//! `trainer models`: every model variant of the study with its parameter count.

use crate::models::arch::study_variants;
use crate::models::{Config, Kind, PositionEncoding, Reciprocity};

/// The variants listed: the nine of Tab. 1 (exact Θ for the neural ones), the other reciprocity
/// strategies and the NOL ablations of Tab. 2.
pub fn variants(position: PositionEncoding) -> Vec<Config> {
    let mut v = study_variants(position, Reciprocity::Exact);
    for r in [Reciprocity::None, Reciprocity::Swap] {
        for kind in [Kind::SingleMlp, Kind::AdditiveSeparate, Kind::AdditiveShared] {
            v.push(Config::paper(kind, false, r, position));
        }
    }
    for (kind, nol) in [(Kind::SingleMlp, 3), (Kind::AdditiveSeparate, 2), (Kind::AdditiveShared, 4)] {
        let mut c = Config::paper(kind, false, Reciprocity::Exact, position);
        c.direction_layers = Some(nol);
        v.push(c);
    }
    v
}

/// The table printed by the command.
pub fn table(position: PositionEncoding) -> String {
    let mut s = format!("{:<34} {:>10}  networks (n_in, width, hidden, n_out, skip)\n", "model", "parameters");
    for c in variants(position) {
        let nets: Vec<String> =
            c.nets().iter().map(|n| format!("({}, {}, {}, {}, {})", n.n_in, n.width, n.hidden, n.n_out, n.skip)).collect();
        s.push_str(&format!("{:<34} {:>10}  {}\n", c.name(), c.n_weights(), nets.join(" ")));
    }
    s
}
