//! Measured-material evaluation on arbitrary directions and angles: a MERL table (with invalid bins
//! below the horizon) by both lookups, and an NBRDF network; finite, non-negative, and exactly
//! reciprocal for the table.
#![no_main]

mod common;

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use nbrdf::measured::{Lookup, MerlTable, NbrdfNetwork};

fn table() -> &'static MerlTable {
    static TABLE: OnceLock<MerlTable> = OnceLock::new();
    // A sharp lobe (values up to ~1e4) over a diffuse base, so that interpolation meets large ratios.
    TABLE.get_or_init(|| MerlTable::tabulate(|wi, wo| {
        let h = (wi + wo).normalize();
        [0.1 + 1e4 * h.z.powi(4000), 0.2, 0.3 * wi.z]
    }))
}

fn network() -> &'static NbrdfNetwork {
    static NET: OnceLock<NbrdfNetwork> = OnceLock::new();
    NET.get_or_init(|| {
        let json = r#"{"input": "rusinkiewicz_half_diff_vectors", "output": "expm1_clamped", "layers": [
            {"inputs": 6, "outputs": 2, "activation": "relu",
             "weight": [[40, 0, 30, 1, 2, 3], [-3, 1, 0, 2, -1, 5]], "bias": [0.5, -1]},
            {"inputs": 2, "outputs": 3, "activation": "none",
             "weight": [[1, 2], [0.5, -1], [3, 0]], "bias": [0, 0.1, -80]}]}"#;
        NbrdfNetwork::from_json_str(json).expect("the fixed network is valid")
    })
}

fuzz_target!(|input: ([f32; 6], [f32; 3])| {
    let (v, angles) = input;
    let (wi, wo) = common::pair(v);
    let table = table();
    for lookup in [Lookup::Nearest, Lookup::Trilinear] {
        let f = table.eval_with(wi, wo, lookup);
        common::assert_valid_brdf(f, "MERL eval");
        let g = table.eval_with(wo, wi, lookup);
        assert_eq!(f.map(f32::to_bits), g.map(f32::to_bits), "MERL lookup not reciprocal");
        common::assert_valid_brdf(table.eval_angles(angles[0], angles[1], angles[2], lookup), "MERL angles");
    }
    let net = network();
    common::assert_valid_brdf(net.eval(wi, wo), "NBRDF eval");
    common::assert_valid_brdf(net.eval_angles(angles[0], angles[1], angles[2]), "NBRDF angles");
});
