//! Importance sampling of every parametric model (from arbitrary raw outputs) and built-in material.
//!
//! Invariants: a sample has a finite direction above the horizon, a finite pdf > 0 and a finite,
//! non-negative weight; for `u` in [0, 1] the direction is a unit vector (outside, `u` is out of contract
//! and only finiteness is required); `pdf(wi, wo)` is finite, ≥ 0, and 0 off the upper hemisphere.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use nbrdf::builtin::Builtin;
use nbrdf::parametric::{Parametric, ParametricKind, MAX_RAW};
use nbrdf::{Brdf, BsdfSample, Vec3};

fn check(name: &str, s: Option<BsdfSample>, u: [f32; 3], wo: Vec3) {
    let Some(s) = s else { return };
    assert!(common::above(wo), "{name}: a sample for the invalid wo {wo}");
    assert!(s.wi.is_finite() && s.wi.z > 0.0, "{name}: wi {}", s.wi);
    assert!(s.pdf.is_finite() && s.pdf > 0.0, "{name}: pdf {}", s.pdf);
    common::assert_valid_brdf(s.weight, name);
    if u[..2].iter().all(|x| (0.0..=1.0).contains(x)) {
        assert!((s.wi.length() - 1.0).abs() < 1e-4, "{name}: |wi| = {} for u = {u:?}", s.wi.length());
    }
}

fn check_pdf(name: &str, p: f32, wo: Vec3, wi: Vec3) {
    assert!(p.is_finite() && p >= 0.0, "{name}: pdf {p}");
    if !(common::above(wi) && common::above(wo)) {
        assert_eq!(p, 0.0, "{name}: pdf off the upper hemisphere");
    }
}

fuzz_target!(|input: (u8, [f32; MAX_RAW], f32, [f32; 3], [f32; 6])| {
    let (which, raw, object, u, dirs) = input;
    let (wi, wo) = common::pair(dirs);
    let kind = ParametricKind::ALL[which as usize % ParametricKind::ALL.len()];
    let m = Parametric::from_raw(kind, &raw[..kind.n_raw()], &[object][..kind.n_object()]);
    check(kind.name(), m.sample(wo, u), u, wo);
    check_pdf(kind.name(), m.pdf(wi, wo), wo, wi);

    let b = Builtin::ALL[which as usize % Builtin::ALL.len()];
    check(b.id(), b.sample(wo, u), u, wo);
    check_pdf(b.id(), b.pdf(wi, wo), wo, wi);
});
