//! Helpers shared by the fuzz targets (each target includes this file with `mod common;`).
#![allow(dead_code)]

use nbrdf::{Rgb, Vec3};

/// Six arbitrary floats (any bits: NaN, infinities, subnormals, huge) as a direction pair.
pub fn pair(v: [f32; 6]) -> (Vec3, Vec3) {
    (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
}

/// The contract of every BRDF evaluation: finite and non-negative, whatever the input.
pub fn assert_valid_brdf(f: Rgb, what: &str) {
    assert!(f.iter().all(|c| c.is_finite() && *c >= 0.0), "{what} gave {f:?}");
}
