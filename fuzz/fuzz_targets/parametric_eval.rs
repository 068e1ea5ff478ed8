//! Every parametric model from arbitrary raw network outputs, and every built-in material, on arbitrary
//! direction pairs. Invariants: finite and non-negative; exactly 0 off the upper hemisphere; the
//! parametric models bitwise reciprocal (`Model::eval` promises it), the built-ins to a relative 1e-6
//! (their documented tolerance). `eval_grad` (the trainer's backward pass) returns `eval`'s value bit
//! for bit and only finite derivatives.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use nbrdf::builtin::Builtin;
use nbrdf::parametric::{Parametric, ParametricKind, MAX_RAW};

fuzz_target!(|input: (u8, [f32; MAX_RAW], f32, [f32; 6])| {
    let (which, raw, object, dirs) = input;
    let (wi, wo) = common::pair(dirs);
    let kind = ParametricKind::ALL[which as usize % ParametricKind::ALL.len()];
    let m = Parametric::from_raw(kind, &raw[..kind.n_raw()], &[object][..kind.n_object()]);
    let f = m.eval(wi, wo);
    common::assert_valid_brdf(f, kind.name());
    if !(common::above(wi) && common::above(wo)) {
        assert_eq!(f, [0.0; 3], "{}: nonzero off the upper hemisphere", kind.name());
    }
    assert!(common::same_bits(f, m.eval(wo, wi)), "{} not reciprocal: {m:?} {wi} {wo}", kind.name());
    let g = Parametric::eval_grad(kind, &raw[..kind.n_raw()], &[object][..kind.n_object()], wi, wo);
    assert!(common::same_bits(g.value, f), "{}: eval_grad's value {:?} is not eval's {f:?}", kind.name(), g.value);
    assert!(
        g.d_raw.iter().chain(&g.d_object).flatten().all(|d| d.is_finite()),
        "{}: non-finite derivative at raw {raw:?} object {object} {wi} {wo}: {g:?}",
        kind.name()
    );

    let b = Builtin::ALL[which as usize % Builtin::ALL.len()];
    let (f, g) = (b.eval(wi, wo), b.eval(wo, wi));
    common::assert_valid_brdf(f, b.id());
    for c in 0..3 {
        assert!((f[c] - g[c]).abs() <= 1e-6 * f[c].max(g[c]).max(1e-6), "{} not reciprocal: {f:?} {g:?}", b.id());
    }
});
