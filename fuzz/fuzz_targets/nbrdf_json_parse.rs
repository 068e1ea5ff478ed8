//! The NBRDF-json reader on arbitrary bytes: an error value or a network, never a panic; a network it
//! accepts evaluates finite and non-negative.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use nbrdf::measured::NbrdfNetwork;
use nbrdf::Vec3;

fuzz_target!(|data: &[u8]| {
    if let Ok(net) = NbrdfNetwork::from_json_bytes(data) {
        common::assert_valid_brdf(net.eval_angles(0.3, 0.2, 1.0), "eval_angles");
        common::assert_valid_brdf(net.eval(Vec3::new(0.3, 0.1, 0.9), Vec3::new(-0.5, 0.2, 0.6)), "eval");
    }
});
