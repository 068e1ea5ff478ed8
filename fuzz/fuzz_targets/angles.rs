//! Angle mappings on arbitrary direction pairs: directions -> Rusinkiewicz -> directions.
//!
//! Invariants: every result is finite and in its documented range; where both directions are valid
//! (finite, non-zero) and not opposite, the round trip gives back the normalised directions; Θ is
//! bitwise symmetric under the swap of `wi` and `wo`, and `None` for exactly the same pairs.
#![no_main]

mod common;

use core::f32::consts::{FRAC_PI_2, PI, TAU};
use libfuzzer_sys::fuzz_target;
use nbrdf::angles::{from_rusinkiewicz, theta_map, to_rusinkiewicz, unit};

fuzz_target!(|v: [f32; 6]| {
    let (wi, wo) = common::pair(v);

    // Θ: bitwise symmetric, and defined for the same pairs in both orders.
    let t = theta_map(wi, wo);
    let t_swapped = theta_map(wo, wi);
    assert_eq!(t.map(|t| t.map(f32::to_bits)), t_swapped.map(|t| t.map(f32::to_bits)), "Θ not symmetric");
    if let Some([th, td, p, p_pi]) = t {
        assert!((0.0..=PI).contains(&th) && (0.0..=FRAC_PI_2).contains(&td), "Θ = {t:?}");
        assert!((0.0..PI).contains(&p) && p_pi == p + PI, "Θ = {t:?}");
    }

    let Some(r) = to_rusinkiewicz(wi, wo) else {
        // Only degenerate input has no angles: non-finite, zero, or exactly opposite directions.
        if let (Some(a), Some(b)) = (unit(wi), unit(wo)) {
            assert!((a + b).length() < 1e-6, "no angles for {a} {b}");
        }
        return;
    };
    assert!((0.0..=PI).contains(&r.theta_h) && (0.0..TAU).contains(&r.phi_h), "{r:?}");
    assert!((0.0..=FRAC_PI_2).contains(&r.theta_d) && (0.0..TAU).contains(&r.phi_d), "{r:?}");

    let (wi2, wo2) = from_rusinkiewicz(&r);
    assert!(wi2.is_finite() && wo2.is_finite(), "{r:?} -> {wi2} {wo2}");
    let (a, b) = (unit(wi).unwrap(), unit(wo).unwrap());
    // The half vector (wi + wo) / |wi + wo| loses precision as the pair nears opposition: the error
    // bound grows like ε / |wi + wo|.
    let s = (a + b).length();
    let tol = 1e-5 + 2e-6 / s;
    assert!((wi2 - a).length() <= tol, "wi {a} -> {r:?} -> {wi2} (|wi + wo| = {s})");
    assert!((wo2 - b).length() <= tol, "wo {b} -> {r:?} -> {wo2} (|wi + wo| = {s})");
});
