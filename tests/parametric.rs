//! Properties of the parametric models and the built-in materials over their whole domain: finite and
//! non-negative everywhere, reciprocal, energy conserving where the model promises it, and equal to the
//! published formulas written out independently (in f64) at hand-picked points.

use nbrdf::builtin::Builtin;
use nbrdf::parametric::{Disney, EvalGrad, Lambert, Parametric, ParametricKind, Phong, TorranceSparrow, MAX_RAW};
use nbrdf::{Rgb, Vec3};
use proptest::prelude::*;
use std::f64::consts::PI;

// ---------------------------------------------------------------------------------------------------
// Helpers

/// A direction from spherical angles (θ from the normal, φ azimuth).
fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32)
}

/// Directional albedo `∫ f(wi, wo) cos θo dωo` by stratified (jittered) Monte Carlo, uniform in solid
/// angle: `n × n` strata in (cos θo, φo), pdf 1/(2π). Deterministic (fixed LCG jitter).
fn albedo(f: impl Fn(Vec3, Vec3) -> Rgb, wi: Vec3, n: usize) -> [f64; 3] {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut sum = [0.0f64; 3];
    for i in 0..n {
        for j in 0..n {
            let z = (i as f64 + rnd()) / n as f64;
            let phi = 2.0 * PI * (j as f64 + rnd()) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let wo = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            let v = f(wi, wo);
            for c in 0..3 {
                sum[c] += v[c] as f64 * z;
            }
        }
    }
    sum.map(|s| s * 2.0 * PI / (n * n) as f64)
}

fn assert_reciprocal(a: Rgb, b: Rgb, what: &str) {
    for c in 0..3 {
        let tol = 1e-6 * a[c].abs().max(b[c].abs());
        assert!((a[c] - b[c]).abs() <= tol, "{what}: channel {c}: {a:?} vs {b:?}");
    }
}

fn kind_strategy() -> impl Strategy<Value = ParametricKind> {
    prop::sample::select(ParametricKind::ALL.to_vec())
}

/// Any direction, including below and on the horizon and unnormalised.
fn any_direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
        // grazing
        (0.0f64..6.3, prop::sample::select(vec![1e-7f32, -1e-7, 0.0, 1e-30]))
            .prop_map(|(phi, z)| { Vec3::new(phi.cos() as f32, phi.sin() as f32, z) }),
    ]
}

/// A direction strictly in the upper hemisphere, grazing ones included.
fn upper_direction() -> impl Strategy<Value = Vec3> {
    (0.0f64..1.0, 0.0f64..6.3).prop_map(|(u, phi)| {
        let theta = u * (0.5 * PI - 1e-6);
        dir(theta, phi)
    })
}

fn raw_vec() -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop_oneof![4 => -12.0f32..12.0, 1 => prop::sample::select(vec![-1e4f32, 1e4, 0.0])],
        MAX_RAW,
    )
}

// ---------------------------------------------------------------------------------------------------
// Whole-domain properties

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn every_model_is_finite_and_non_negative(kind in kind_strategy(), raw in raw_vec(),
                                              obj in -5.0f32..15.0, wi in any_direction(), wo in any_direction()) {
        let m = Parametric::from_raw(kind, &raw, &[obj]);
        let f = m.eval(wi, wo);
        prop_assert!(f.iter().all(|v| v.is_finite() && *v >= 0.0), "{kind:?} {m:?} {wi} {wo}: {f:?}");
        if wi.z <= 0.0 || wo.z <= 0.0 {
            prop_assert_eq!(f, [0.0; 3]);
        }
    }

    #[test]
    fn every_model_is_reciprocal(kind in kind_strategy(), raw in raw_vec(), obj in -5.0f32..15.0,
                                 wi in upper_direction(), wo in upper_direction()) {
        let m = Parametric::from_raw(kind, &raw, &[obj]);
        assert_reciprocal(m.eval(wi, wo), m.eval(wo, wi), kind.name());
    }

    #[test]
    fn builtins_are_finite_non_negative_and_reciprocal(wi in any_direction(), wo in any_direction()) {
        for b in Builtin::ALL {
            let f = b.eval(wi, wo);
            prop_assert!(f.iter().all(|v| v.is_finite() && *v >= 0.0), "{b:?} {wi} {wo}: {f:?}");
            assert_reciprocal(f, b.eval(wo, wi), b.id());
        }
    }

    #[test]
    fn rp_parametrisation_always_conserves_energy(raw in raw_vec()) {
        let p = Phong::from_raw(&raw);
        for c in 0..3 {
            prop_assert!(p.kd[c] + p.ks[c] <= 1.0 + 1e-6, "{p:?}");
        }
    }
}

#[test]
fn short_or_empty_raw_slices_read_as_zeros() {
    for kind in ParametricKind::ALL {
        let a = Parametric::from_raw(kind, &[], &[]);
        let b = Parametric::from_raw(kind, &[0.0; MAX_RAW], &[0.0]);
        assert_eq!(a, b, "{kind:?}");
        let c = Parametric::from_raw(kind, &[f32::NAN; MAX_RAW], &[f32::INFINITY]);
        assert_eq!(c, b, "non-finite raw values count as 0 for {kind:?}");
    }
}

#[test]
fn extreme_regimes_stay_finite() {
    // Roughness and every weight at 0 and 1 (raw ±1e4), α floor, all β/η ends, grazing, wi = wo, mirror.
    let z = 1e-7f32;
    let g = (1.0 - z * z).sqrt();
    let pairs = [
        (Vec3::new(g, 0.0, z), Vec3::new(-g, 0.0, z)), // grazing mirror
        (Vec3::new(g, 0.0, z), Vec3::new(g, 0.0, z)),  // grazing, wi = wo
        (Vec3::new(g, 0.0, z), Vec3::new(0.0, g, z)),  // grazing, 90° apart
        (Vec3::Z, Vec3::Z),                            // normal, wi = wo (mirror too)
        (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8)),
        (Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.6, 0.0, 0.8)),
    ];
    for kind in ParametricKind::ALL {
        for bits in 0u32..(1 << 12) {
            if kind.n_raw() < 12 && bits >= (1 << kind.n_raw()) {
                break;
            }
            let raw: Vec<f32> = (0..MAX_RAW).map(|i| if bits >> i & 1 == 1 { 1e4 } else { -1e4 }).collect();
            for obj in [-80.0f32, 0.0, 80.0] {
                let m = Parametric::from_raw(kind, &raw, &[obj]);
                for (wi, wo) in pairs {
                    let f = m.eval(wi, wo);
                    assert!(f.iter().all(|v| v.is_finite() && *v >= 0.0), "{m:?} {wi} {wo}: {f:?}");
                }
            }
        }
    }
    for b in Builtin::ALL {
        for (wi, wo) in pairs {
            let f = b.eval(wi, wo);
            assert!(f.iter().all(|v| v.is_finite() && *v >= 0.0), "{b:?} {wi} {wo}: {f:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Energy

#[test]
fn white_lambert_has_albedo_one() {
    let white = Lambert { kd: [1.0; 3] };
    for theta in [0.0, 0.7, 1.4] {
        let a = albedo(|wi, wo| white.eval(wi, wo), dir(theta, 0.3), 256);
        for c in a {
            assert!((c - 1.0).abs() < 2e-3, "θi = {theta}: {a:?}");
        }
    }
}

#[test]
fn lambert_and_rp_albedo_at_most_one() {
    let lambert = Lambert::from_raw(&[3.0, 1.0, -2.0]);
    // kd + ks = 1 exactly in the first channel of each: the bound is tight at normal incidence.
    let rps = [
        Phong { kd: [0.0, 0.2, 0.5], ks: [1.0, 0.7, 0.3], n: 1.0 },
        Phong { kd: [0.3, 0.0, 0.1], ks: [0.7, 0.9, 0.2], n: 20.0 },
        Phong { kd: [0.1, 0.1, 0.1], ks: [0.9, 0.5, 0.1], n: 200.0 },
        Phong::from_raw(&[-1.0, 0.5, 2.0, 8.0, 8.0, 8.0, 3.0]),
    ];
    for theta in [0.0, 0.4, 0.9, 1.3, 1.55] {
        let wi = dir(theta, 1.1);
        let a = albedo(|wi, wo| lambert.eval(wi, wo), wi, 128);
        assert!(a.iter().all(|&c| c <= 1.0 + 2e-3), "Lambert θi = {theta}: {a:?}");
        for rp in &rps {
            let a = albedo(|wi, wo| rp.eval(wi, wo), wi, 512);
            assert!(a.iter().all(|&c| c <= 1.0 + 3e-3), "{rp:?} θi = {theta}: {a:?}");
        }
    }
    // At normal incidence the specular lobe's albedo is exactly ks (the (n+2)/2π normalisation).
    let rp = Phong { kd: [0.0; 3], ks: [1.0; 3], n: 20.0 };
    let a = albedo(|wi, wo| rp.eval(wi, wo), Vec3::Z, 512);
    assert!((a[0] - 1.0).abs() < 3e-3, "{a:?}");
}

#[test]
fn builtins_conserve_energy() {
    for b in Builtin::ALL {
        for theta in [0.0, 0.5, 1.0, 1.3, 1.5, 1.56] {
            let a = albedo(|wi, wo| b.eval(wi, wo), dir(theta, 0.4), 512);
            assert!(a.iter().all(|&c| c <= 1.0), "{} θi = {theta}: {a:?}", b.id());
            assert!(a.iter().all(|&c| c > 0.0), "{} θi = {theta}: {a:?}", b.id());
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Independent values: the published formulas written out in f64, not calling the code under test.

fn v64(w: Vec3) -> [f64; 3] {
    let l = ((w.x as f64).powi(2) + (w.y as f64).powi(2) + (w.z as f64).powi(2)).sqrt();
    [w.x as f64 / l, w.y as f64 / l, w.z as f64 / l]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn half(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    let l = dot(s, s).sqrt();
    s.map(|x| x / l)
}
fn close(got: Rgb, want: [f64; 3], rel: f64, what: &str) {
    for c in 0..3 {
        assert!(
            ((got[c] as f64) - want[c]).abs() <= rel * want[c].abs() + 1e-9,
            "{what} ch {c}: {got:?} vs {want:?}"
        );
    }
}

#[test]
fn rp_matches_lafortune_willems_at_hand_points() {
    let rp = Phong { kd: [0.2, 0.3, 0.1], ks: [0.5, 0.4, 0.6], n: 20.0 };
    // wi at 30° in the xz-plane; its mirror is at 30° on the other side; wo 35° from the normal, 12° off
    // the plane of incidence on the mirror side.
    let wi = dir(30f64.to_radians(), 0.0);
    let wo = dir(35f64.to_radians(), 192f64.to_radians());
    let r = [-(30f64.to_radians().sin()), 0.0, 30f64.to_radians().cos()];
    let cos_a = dot(r, v64(wo));
    let want = [0, 1, 2]
        .map(|c| [0.2, 0.3, 0.1][c] / PI + [0.5, 0.4, 0.6][c] * (20.0 + 2.0) / (2.0 * PI) * cos_a.powf(20.0));
    close(rp.eval(wi, wo), want, 1e-5, "RP");
    // Away from the lobe (cos α < 0) only the diffuse part is left.
    close(rp.eval(wi, dir(60f64.to_radians(), 0.0)), [0.2 / PI, 0.3 / PI, 0.1 / PI], 1e-6, "RP diffuse");
}

#[test]
fn torrance_sparrow_matches_cook_torrance_at_hand_points() {
    let ts = TorranceSparrow { kd: [0.4, 0.2, 0.1], ks: [0.9, 0.6, 0.3], alpha: 0.3 };
    for (wi, wo) in [
        (dir(0.5, 0.0), dir(0.6, 2.9)),
        (dir(1.2, 0.3), dir(1.3, 3.6)), // near grazing: V-cavity shadowing active
        (dir(0.2, 0.0), dir(0.9, 0.5)),
    ] {
        let (i, o) = (v64(wi), v64(wo));
        let h = half(i, o);
        let (ci, co, ch, cd) = (i[2], o[2], h[2], dot(i, h));
        let tan2 = (1.0 - ch * ch) / (ch * ch);
        let d = (-tan2 / 0.09).exp() / (PI * 0.09 * ch.powi(4));
        let g = 1f64.min(2.0 * ch * co / cd).min(2.0 * ch * ci / cd);
        let want = [0, 1, 2].map(|c| {
            let f0 = [0.9, 0.6, 0.3][c];
            let f = f0 + (1.0 - f0) * (1.0 - cd).powi(5);
            [0.4, 0.2, 0.1][c] / PI + d * g * f / (4.0 * ci * co)
        });
        close(ts.eval(wi, wo), want, 2e-5, "TS");
    }
}

/// BRDF Explorer's `disney.brdf` (isotropic), transcribed in f64 with `baseColor` taken as linear.
fn disney_reference(p: &Disney, l: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    let sqr = |x: f64| x * x;
    let schlick = |u: f64| (1.0 - u).clamp(0.0, 1.0).powi(5);
    let mix = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
    let gtr1 = |ndh: f64, a: f64| {
        if a >= 1.0 {
            return 1.0 / PI;
        }
        let a2 = a * a;
        (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * ndh * ndh))
    };
    let gtr2 = |ndh: f64, a: f64| {
        let a2 = a * a;
        a2 / (PI * sqr(1.0 + (a2 - 1.0) * ndh * ndh))
    };
    let smith = |ndv: f64, a: f64| 1.0 / (ndv + (a * a + ndv * ndv - a * a * ndv * ndv).sqrt());
    let h = half(l, v);
    let (ndl, ndv, ndh, ldh) = (l[2], v[2], h[2], dot(l, h));
    let c = p.base_color.map(|x| x as f64);
    let lum = 0.3 * c[0] + 0.6 * c[1] + 0.1 * c[2];
    let tint = if lum > 0.0 { c.map(|x| x / lum) } else { [1.0; 3] };
    let (r, m) = (p.roughness as f64, p.metallic as f64);
    let (fl, fv) = (schlick(ndl), schlick(ndv));
    let fd90 = 0.5 + 2.0 * ldh * ldh * r;
    let fd = mix(1.0, fd90, fl) * mix(1.0, fd90, fv);
    let fss90 = ldh * ldh * r;
    let fss = mix(1.0, fss90, fl) * mix(1.0, fss90, fv);
    let ss = 1.25 * (fss * (1.0 / (ndl + ndv) - 0.5) + 0.5);
    let a = (r * r).max(0.001);
    let ds = gtr2(ndh, a);
    let fh = schlick(ldh);
    let gs = smith(ndl, a) * smith(ndv, a);
    let dr = gtr1(ndh, mix(0.1, 0.001, p.clearcoat_gloss as f64));
    let fr = mix(0.04, 1.0, fh);
    let gr = smith(ndl, 0.25) * smith(ndv, 0.25);
    [0, 1, 2].map(|k| {
        let cspec0 = mix(p.specular as f64 * 0.08 * mix(1.0, tint[k], p.specular_tint as f64), c[k], m);
        let csheen = mix(1.0, tint[k], p.sheen_tint as f64);
        let fs = mix(cspec0, 1.0, fh);
        let fsheen = fh * p.sheen as f64 * csheen;
        ((1.0 / PI) * mix(fd, ss, p.subsurface as f64) * c[k] + fsheen) * (1.0 - m)
            + gs * fs * ds
            + 0.25 * p.clearcoat as f64 * gr * fr * dr
    })
}

#[test]
fn disney_matches_brdf_explorer_at_hand_points() {
    let materials = [
        Disney { base_color: [0.8, 0.3, 0.1], roughness: 0.5, specular: 0.5, ..Disney::default() },
        Disney {
            base_color: [0.2, 0.5, 0.9],
            subsurface: 0.7,
            metallic: 0.3,
            specular: 0.8,
            specular_tint: 0.4,
            roughness: 0.25,
            sheen: 0.9,
            sheen_tint: 0.6,
            clearcoat: 1.0,
            clearcoat_gloss: 0.8,
        },
        Disney { base_color: [0.9, 0.7, 0.3], metallic: 1.0, roughness: 0.1, ..Disney::default() },
    ];
    let pairs =
        [(dir(0.3, 0.0), dir(0.4, 3.0)), (dir(1.0, 0.5), dir(0.2, 2.0)), (dir(1.4, 0.0), dir(1.35, 3.3))];
    for p in &materials {
        for (wi, wo) in pairs {
            close(p.eval(wi, wo), disney_reference(p, v64(wi), v64(wo)), 1e-4, "Disney");
        }
    }
    // A point checked by hand: normal incidence and view, specular = metallic = sheen = clearcoat = 0.
    // F_L = F_V = F_H = 0, so Fd = 1 and the specular Fresnel Fs = lerp(Cspec0 = 0, 1, F_H) = 0:
    // f = baseColor / π exactly.
    let diffuse = Disney { base_color: [0.5, 0.25, 1.0], roughness: 0.5, ..Disney::default() };
    close(diffuse.eval(Vec3::Z, Vec3::Z), [0.5 / PI, 0.25 / PI, 1.0 / PI], 1e-6, "Disney diffuse");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    /// `to_raw` inverts `from_raw`: raw outputs in a range where the activations are not saturated come
    /// back from the parameters they produce.
    #[test]
    fn to_raw_inverts_from_raw(kind in kind_strategy(), raw in prop::collection::vec(-4.0f32..4.0, MAX_RAW),
                               obj in -2.0f32..12.0) {
        let m = Parametric::from_raw(kind, &raw, &[obj]);
        let (back, back_obj) = m.to_raw();
        // The roughness pre-activations go through sigmoid(0.5 x): a larger but still bounded error.
        for i in 0..kind.n_raw() {
            prop_assert!((back[i] - raw[i]).abs() < 2e-3, "{kind:?} raw[{i}]: {} vs {}", back[i], raw[i]);
        }
        if kind.n_object() == 1 {
            prop_assert!((back_obj[0] - obj).abs() < 1e-4);
        }
        prop_assert_eq!(Parametric::from_raw(kind, &back, &back_obj).kind(), kind);
    }
}

// ---------------------------------------------------------------------------------------------------
// Gradients: `eval_grad` is `eval` with exact derivatives. Their agreement with independent (f64) derivatives
// is checked in `src/parametric/grad_check.rs`, next to the crate-private generic formulas it evaluates.

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn eval_grad_is_finite_everywhere(kind in kind_strategy(),
                                      raw in prop::collection::vec(prop_oneof![
                                          3 => -50.0f32..50.0,
                                          1 => prop::sample::select(vec![-50.0f32, 50.0, 0.0, -1e4, 1e4, f32::NAN,
                                                                         f32::INFINITY, f32::NEG_INFINITY])],
                                          0..=MAX_RAW),
                                      obj in prop_oneof![-100.0f32..100.0, prop::sample::select(vec![f32::NAN, 80.0, -80.0])],
                                      wi in any_direction(), wo in any_direction()) {
        let g = Parametric::eval_grad(kind, &raw, &[obj], wi, wo);
        prop_assert_eq!(g.value.map(f32::to_bits), Parametric::from_raw(kind, &raw, &[obj]).eval(wi, wo).map(f32::to_bits));
        let all = g.d_raw.iter().chain(&g.d_object).flatten();
        prop_assert!(all.clone().all(|d| d.is_finite()), "{kind:?} {raw:?} {obj} {wi} {wo}: {g:?}");
        // Missing or non-finite raw values are constants; so is everything below the horizon.
        for j in 0..MAX_RAW {
            if !raw.get(j).is_some_and(|x| x.is_finite()) {
                prop_assert_eq!(g.d_raw[j], [0.0; 3]);
            }
        }
        if !obj.is_finite() {
            prop_assert_eq!(g.d_object[0], [0.0; 3]);
        }
        if wi.z <= 0.0 || wo.z <= 0.0 {
            prop_assert_eq!(g, EvalGrad { value: [0.0; 3], d_raw: [[0.0; 3]; MAX_RAW], d_object: [[0.0; 3]; 1] });
        }
        // A channel clamped to 0 by eval's guard has no derivative.
        for c in 0..3 {
            if g.value[c] == 0.0 {
                prop_assert!(all.clone().skip(c).step_by(3).all(|d| *d == 0.0));
            }
        }
    }
}
