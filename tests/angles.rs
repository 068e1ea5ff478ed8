//! The angle maps over their whole domain: round trips, the bitwise symmetry of Θ (Sec. 4.3), ranges,
//! and agreement with an independent rotation-based Rusinkiewicz transform (Rusinkiewicz 1998).

use nbrdf::angles::{
    from_rusinkiewicz, half_diff, rusinkiewicz_angles, theta_map, to_rusinkiewicz, unit, Rusinkiewicz,
};
use nbrdf::Vec3;
use proptest::prelude::*;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

fn any_vec() -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0, -6i32..6)
        .prop_map(|(x, y, z, e)| Vec3::new(x, y, z) * 10f32.powi(e))
}

fn upper() -> impl Strategy<Value = Vec3> {
    (0.0f32..TAU, 0.0f32..FRAC_PI_2).prop_map(|(p, t)| Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

/// Rusinkiewicz's own construction, in f64: rotate `wi` by -φh about z, then by -θh about y.
fn reference(wi: Vec3, wo: Vec3) -> (f64, f64, f64) {
    let (a, b) = (wi.as_dvec3().normalize(), wo.as_dvec3().normalize());
    let h = (a + b).normalize();
    let th = h.z.clamp(-1.0, 1.0).acos();
    let ph = h.y.atan2(h.x);
    let rz = |v: glam::DVec3, ang: f64| glam::DVec3::new(v.x * ang.cos() - v.y * ang.sin(), v.x * ang.sin() + v.y * ang.cos(), v.z);
    let ry = |v: glam::DVec3, ang: f64| glam::DVec3::new(v.x * ang.cos() + v.z * ang.sin(), v.y, -v.x * ang.sin() + v.z * ang.cos());
    let d = ry(rz(a, -ph), -th);
    let mut pd = d.y.atan2(d.x);
    if pd < 0.0 {
        pd += std::f64::consts::TAU;
    }
    (th, d.z.clamp(-1.0, 1.0).acos(), pd)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn theta_map_is_bitwise_symmetric_for_any_input(a in any_vec(), b in any_vec()) {
        let (x, y) = (theta_map(a, b), theta_map(b, a));
        prop_assert_eq!(x.map(|t| t.map(f32::to_bits)), y.map(|t| t.map(f32::to_bits)));
        if let Some(t) = x {
            prop_assert!(t.iter().all(|v| v.is_finite()));
            prop_assert!(t[0] >= 0.0 && t[0] <= PI);
            prop_assert!(t[1] >= 0.0 && t[1] <= FRAC_PI_2 + 1e-6);
            prop_assert!(t[2] >= 0.0 && t[2] < PI);
            prop_assert_eq!(t[3], t[2] + PI);
        }
    }

    #[test]
    fn rusinkiewicz_round_trip_returns_the_directions(wi in upper(), wo in upper()) {
        let r = to_rusinkiewicz(wi, wo).unwrap();
        prop_assert!(r.phi_h >= 0.0 && r.phi_h < TAU && r.phi_d >= 0.0 && r.phi_d < TAU);
        let (a, b) = from_rusinkiewicz(&r);
        prop_assert!((a - wi).length() < 2e-5, "wi {} -> {}", wi, a);
        prop_assert!((b - wo).length() < 2e-5, "wo {} -> {}", wo, b);
    }

    #[test]
    fn angles_agree_with_the_rotation_construction(wi in upper(), wo in upper()) {
        let ang = rusinkiewicz_angles(wi, wo).unwrap();
        let (th, td, pd) = reference(wi, wo);
        prop_assert!((ang[0] as f64 - th).abs() < 1e-4);
        prop_assert!((ang[1] as f64 - td).abs() < 1e-4);
        // φd is undefined (and unstable) where θd → 0 or θh → 0; compare only where it is well defined.
        if td > 1e-2 && th > 1e-2 {
            let dp = (ang[2] as f64 - pd).abs();
            prop_assert!(dp.min(std::f64::consts::TAU - dp) < 1e-3, "φd {} vs {}", ang[2], pd);
        }
    }

    #[test]
    fn swapping_the_pair_shifts_phi_d_by_pi(wi in upper(), wo in upper()) {
        let (a, b) = (rusinkiewicz_angles(wi, wo).unwrap(), rusinkiewicz_angles(wo, wi).unwrap());
        prop_assert_eq!((a[0], a[1]), (b[0], b[1]));
        if a[1] > 1e-3 {
            let d = (a[2] - b[2]).rem_euclid(TAU);
            prop_assert!((d - PI).abs() < 1e-4, "{} vs {}", a[2], b[2]);
        }
    }

    #[test]
    fn half_diff_vectors_are_unit_and_d_is_wi_in_the_half_frame(wi in upper(), wo in upper()) {
        let (h, d) = half_diff(wi, wo).unwrap();
        prop_assert!((h.length() - 1.0).abs() < 1e-5 && (d.length() - 1.0).abs() < 1e-5);
        // d.z = cos θd = wi · h.
        prop_assert!((d.z - wi.dot(h)).abs() < 1e-5);
    }

    #[test]
    fn unit_never_returns_non_finite_or_non_unit_vectors(v in any_vec()) {
        if let Some(u) = unit(v) {
            prop_assert!((u.length() - 1.0).abs() < 1e-6);
        }
    }
}

#[test]
fn hard_cases_have_their_documented_results() {
    // θh = 0: φh is undefined and reported as 0.
    let r = to_rusinkiewicz(Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8)).unwrap();
    assert_eq!((r.theta_h, r.phi_h), (0.0, 0.0));
    // wi = wo: θd = 0, φd reported as 0.
    let w = Vec3::new(0.3, -0.2, 0.9).normalize();
    let r = to_rusinkiewicz(w, w).unwrap();
    assert_eq!((r.theta_d, r.phi_d), (0.0, 0.0));
    // Unnormalised input is normalised, each vector on its own.
    assert_eq!(theta_map(w * 7.0, Vec3::Z * 1e-30), theta_map(w, Vec3::Z));
    // wi = -wo, zero, NaN and infinite input: None, never NaN.
    for (a, b) in [
        (Vec3::X, -Vec3::X),
        (Vec3::ZERO, Vec3::Z),
        (Vec3::new(f32::NAN, 0.0, 1.0), Vec3::Z),
        (Vec3::new(0.0, f32::INFINITY, 1.0), Vec3::Z),
    ] {
        assert!(theta_map(a, b).is_none() && to_rusinkiewicz(a, b).is_none());
    }
    // Grazing: z = 0 and z = -0 parametrise like any other direction (the BRDF gate rejects them).
    let g = theta_map(Vec3::new(1.0, 0.0, -0.0), Vec3::new(0.0, 1.0, 0.0)).unwrap();
    assert!((g[0] - FRAC_PI_2).abs() < 1e-6);
    // Denormal components do not underflow the normalisation.
    let tiny = Vec3::new(1e-40, 0.0, 1e-40);
    assert!((unit(tiny).unwrap() - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6);
    let _ = Rusinkiewicz::default();
}
