//! A tour of the core API on the built-in models: BRDF values at characteristic direction pairs,
//! directional albedo (energy, Eq. 4) by stratified cosine-weighted quadrature, and the largest
//! reciprocity violation (Eq. 3) — for the parametric models of Sec. 4.1.1, the procedural
//! "measured-like" materials, and, when `../shared/data` (or `NBRDF_DATA`) is present, a few of the
//! measured MERL materials as NBRDF networks.
//!
//! Run: `cargo run --release --example brdf_table` (its first line names the kernel level in use;
//! `NBRDF_KERNEL=portable` forces the plain-Rust kernels, whose table agrees to ~1e-6 relative).

use nbrdf::builtin::Builtin;
use nbrdf::math::PI;
use nbrdf::measured::NbrdfNetwork;
use nbrdf::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, Phong, TorranceSparrow};
use nbrdf::warp::square_to_cosine_hemisphere;
use nbrdf::{Rgb, Vec3};

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn lum(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Directional albedo `∫ f(wi, wo) cos θo dwo` for light from `wi`, by an n×n stratified
/// cosine-weighted estimate (`π · mean f`).
fn albedo(f: &dyn Fn(Vec3, Vec3) -> Rgb, wi: Vec3, n: usize) -> f32 {
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
            let wo = square_to_cosine_hemisphere(u);
            sum += lum(f(wi, wo)) as f64;
        }
    }
    (PI as f64 * sum / (n * n) as f64) as f32
}

/// Largest relative reciprocity violation over a grid of direction pairs.
fn reciprocity(f: &dyn Fn(Vec3, Vec3) -> Rgb) -> f32 {
    let mut worst = 0.0f32;
    for ti in [5.0, 30.0, 55.0, 80.0] {
        for to in [10.0, 40.0, 70.0] {
            for po in [0.0, 90.0, 170.0, 260.0] {
                let (wi, wo) = (dir(ti, 20.0), dir(to, po));
                let (a, b) = (f(wi, wo), f(wo, wi));
                for c in 0..3 {
                    worst = worst.max((a[c] - b[c]).abs() / a[c].abs().max(b[c].abs()).max(1e-6));
                }
            }
        }
    }
    worst
}

fn main() {
    // The kernel level first: `NBRDF_KERNEL=portable|avx2|avx512|neon` forces one the CPU runs.
    match nbrdf::kernels::requested() {
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
        Ok(_) => println!("kernel level: {}", nbrdf::kernels::level()),
    }
    type Eval = Box<dyn Fn(Vec3, Vec3) -> Rgb>;
    let mut rows: Vec<(String, Eval)> = vec![
        ("Lambert (kd 0.8)".into(), Box::new(|a, b| Parametric::Lambert(Lambert { kd: [0.8; 3] }).eval(a, b))),
        (
            "RP (kd 0.4, ks 0.5, n 80)".into(),
            Box::new(|a, b| Parametric::Phong(Phong { kd: [0.4; 3], ks: [0.5; 3], n: 80.0 }).eval(a, b)),
        ),
        (
            "Torrance-Sparrow (α 0.2)".into(),
            Box::new(|a, b| {
                Parametric::TorranceSparrow(TorranceSparrow { kd: [0.3, 0.2, 0.1], ks: [0.9, 0.7, 0.4], alpha: 0.2 }).eval(a, b)
            }),
        ),
        (
            "FMBRDF (α 0.3, β 1.5, η 1.5)".into(),
            Box::new(|a, b| Parametric::FresnelMicrofacet(FresnelMicrofacet::new([0.5, 0.3, 0.2], 0.6, 0.3, 1.5, 1.5)).eval(a, b)),
        ),
        (
            "Disney (metallic 0.5, rough 0.3)".into(),
            Box::new(|a, b| {
                Parametric::Disney(Disney {
                    base_color: [0.8, 0.5, 0.2],
                    subsurface: 0.0,
                    metallic: 0.5,
                    specular: 0.5,
                    specular_tint: 0.0,
                    roughness: 0.3,
                    sheen: 0.0,
                    sheen_tint: 0.5,
                    clearcoat: 0.3,
                    clearcoat_gloss: 0.8,
                })
                .eval(a, b)
            }),
        ),
    ];
    for b in Builtin::ALL {
        rows.push((format!("built-in {}", b.id()), Box::new(move |x, y| b.eval(x, y))));
    }
    let data = std::env::var("NBRDF_DATA").unwrap_or_else(|_| "../shared/data".into());
    for name in ["chrome", "gold-metallic-paint", "blue-fabric"] {
        let path = std::path::Path::new(&data).join("nbrdf-merl").join(format!("{name}.json"));
        match NbrdfNetwork::load(&path) {
            Ok(net) => rows.push((format!("MERL {name} (NBRDF)"), Box::new(move |a, b| net.eval(a, b)))),
            Err(e) => eprintln!("skipping MERL {name}: {e}"),
        }
    }

    let pairs = [
        ("normal", dir(0.0, 0.0), dir(0.0, 0.0)),
        ("45°/mirror", dir(45.0, 0.0), dir(45.0, 180.0)),
        ("45°/off 20°", dir(45.0, 0.0), dir(25.0, 180.0)),
        ("60°/back", dir(60.0, 0.0), dir(60.0, 0.0)),
        ("85°/mirror", dir(85.0, 0.0), dir(85.0, 180.0)),
    ];
    println!("BRDF luminance f(wi, wo) [1/sr] at characteristic pairs (θi/θo in degrees):\n");
    print!("{:<36}", "model");
    for (n, ..) in &pairs {
        print!("{n:>12}");
    }
    println!("{:>10}{:>10}{:>10}{:>12}", "a(0°)", "a(45°)", "a(75°)", "recip.err");
    for (name, f) in &rows {
        print!("{name:<36}");
        for (_, wi, wo) in &pairs {
            print!("{:>12.4}", lum(f(*wi, *wo)));
        }
        let a: Vec<f32> = [0.0, 45.0, 75.0].iter().map(|&t| albedo(f.as_ref(), dir(t, 0.0), 256)).collect();
        println!("{:>10.4}{:>10.4}{:>10.4}{:>12.1e}", a[0], a[1], a[2], reciprocity(f.as_ref()));
    }
    println!(
        "\na(θ): directional albedo ∫ f cos θo dωo (Eq. 4; ≤ 1 conserves energy), 256² stratified cosine samples.\n\
         recip.err: largest relative |f(wi,wo) − f(wo,wi)| over a grid (Eq. 3). The NBRDF networks take φd\n\
         unfolded and are not reciprocal by construction; Θ-models (Sec. 4.3) are, bit for bit."
    );
}
