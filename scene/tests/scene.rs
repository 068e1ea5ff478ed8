//! Scenes: ray casting against analytic answers, cast shadows, Eq. 9 pixels, exact skipping, bad input.

use nbrdf_scene::image::{read_exr, read_png, srgb_decode, srgb_encode, write_exr, write_png16, RgbImage};
use nbrdf_scene::scene::builtin::BuiltinMesh;
use nbrdf_scene::scene::convex::is_convex;
use nbrdf_scene::scene::ray::intersect_triangle;
use nbrdf_scene::scene::render::{surface_sample, visibility};
use nbrdf_scene::scene::{
    render_view, Camera, DirectionalLight, Frame, Geometry, Mesh, Ray, RenderOptions, ShadowPass, SurfaceSample,
    Visibility,
};
use nbrdf::{Error, Rgb, Vec3};
use std::f32::consts::PI;
use std::path::PathBuf;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nbrdf-scene-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Lambertian with albedo 0.5: f = 0.5 / π.
fn lambert(_: &SurfaceSample, wi: Vec3, wo: Vec3) -> Rgb {
    if wi.z > 0.0 && wo.z > 0.0 { [0.5 / PI; 3] } else { [0.0; 3] }
}

/// Normalised Phong lobe ks (n+2)/(2π) cos^n α with α between wo and the mirror direction of wi, plus a
/// diffuse term: frame-independent, so it can be recomputed in world space.
fn phong_world(n: Vec3, l: Vec3, v: Vec3) -> Rgb {
    let r = 2.0 * n.dot(l) * n - l;
    let spec = 0.4 * (20.0 + 2.0) / (2.0 * PI) * r.dot(v).max(0.0).powf(20.0);
    [0.2 / PI + spec, 0.1 / PI + spec, 0.05 / PI + spec]
}

fn phong(_: &SurfaceSample, wi: Vec3, wo: Vec3) -> Rgb {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return [0.0; 3];
    }
    phong_world(Vec3::Z, wi, wo)
}

#[test]
fn sphere_hits_match_the_analytic_sphere() {
    let g = Geometry::new(BuiltinMesh::Sphere.mesh()).unwrap();
    for (x, y) in [(0.0, 0.0), (0.3, -0.2), (-0.6, 0.5), (0.1, 0.9)] {
        let ray = Ray::new(Vec3::new(x, y, 5.0), -Vec3::Z);
        let hit = g.accel.intersect(&ray).unwrap();
        let z = (1.0f32 - x * x - y * y).sqrt();
        // The icosphere (level 4) lies within 1.5e-3 of the unit sphere radially; along the ray the
        // distance error grows as 1 / cos of the incidence angle (= z).
        assert!((hit.t - (5.0 - z)).abs() < 1.5e-3 / z, "t = {} for z = {z}", hit.t);
        assert!((ray.at(hit.t).length() - 1.0).abs() < 1.5e-3);
        // Barycentrics reproduce the hit point exactly.
        let p = g.mesh.point(hit.triangle, hit.b1, hit.b2);
        assert!((p - ray.at(hit.t)).length() < 1e-5);
        assert!(hit.b1 >= 0.0 && hit.b2 >= 0.0 && hit.b1 + hit.b2 <= 1.0);
        // Interpolated vertex normals (exact on the vertices) approximate the radial direction.
        let n = g.mesh.shading_normal(hit.triangle, hit.b1, hit.b2);
        assert!((n - p.normalize()).length() < 1e-2, "normal {n} at {p}");
    }
    assert!(g.accel.intersect(&Ray::new(Vec3::new(1.2, 0.0, 5.0), -Vec3::Z)).is_none());
    // A ray starting inside hits the far side from within.
    let inner = g.accel.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
    assert!((inner.t - 1.0).abs() < 1.5e-3);
}

#[test]
fn triangle_barycentrics_are_exact() {
    let tri = [Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0), Vec3::new(1.0, 4.0, 0.0)];
    // Point = 0.5 p0 + 0.25 p1 + 0.25 p2 = (1.5, 1.0, 0).
    let (t, b1, b2) = intersect_triangle(Vec3::new(1.5, 1.0, 2.0), -Vec3::Z, 0.0, 10.0, tri).unwrap();
    assert_eq!((t, b1, b2), (2.0, 0.25, 0.25));
    assert!(intersect_triangle(Vec3::new(3.5, 1.0, 2.0), -Vec3::Z, 0.0, 10.0, tri).is_none());
    assert!(intersect_triangle(Vec3::new(1.5, 1.0, 2.0), -Vec3::Z, 0.0, 1.0, tri).is_none()); // beyond tmax
    let mesh = Mesh::new(tri.to_vec(), vec![[0, 1, 2]]).unwrap();
    let g = Geometry::new(mesh).unwrap();
    let hit = g.accel.intersect(&Ray::new(Vec3::new(1.5, 1.0, -2.0), Vec3::Z)).unwrap();
    assert_eq!((hit.triangle, hit.t, hit.b1, hit.b2), (0, 2.0, 0.25, 0.25));
}

#[test]
fn camera_rays_and_projection_agree() {
    let cam = Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.1, 0.0, -0.2), Vec3::Y, 0.8, 40, 30).unwrap();
    for (c, r) in [(0.0, 0.0), (39.0, 29.0), (12.0, 7.0)] {
        let ray = cam.pixel_ray(c, r);
        assert_eq!(ray.origin, cam.center());
        let (px, depth) = cam.project(ray.at(2.5)).unwrap();
        assert!((px.x - c).abs() < 1e-3 && (px.y - r).abs() < 1e-3, "{px} vs ({c}, {r})");
        assert!(depth > 0.0);
    }
    // OpenCV convention: camera centre maps to the origin of camera coordinates.
    assert!((cam.r * cam.center() + cam.t).length() < 1e-5);
    // An invalid rotation is rejected.
    let bad = Camera::new(4, 4, cam.k, cam.r * 2.0, cam.t);
    assert!(matches!(bad, Err(Error::InvalidValue { what: "camera rotation R", .. })));
}

#[test]
fn frame_maps_the_normal_to_z_and_preserves_angles() {
    for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.8, -0.2).normalize(), Vec3::new(1e-8, 0.0, -1.0).normalize()] {
        let f = Frame::from_normal(n);
        assert!((f.to_local(n) - Vec3::Z).length() < 1e-6);
        assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(n).abs() < 1e-6 && (f.s.cross(f.t) - n).length() < 1e-5);
    }
}

#[test]
fn torus_shadow_indicator_at_known_points() {
    let g = Geometry::new(BuiltinMesh::Torus.mesh()).unwrap();
    assert!(!g.convex);
    // From the centre of the hole along +x we hit the inner equator at x = 0.4, normal -x.
    let s = surface_sample(&g, &Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
    assert!((s.position - Vec3::new(0.4, 0.0, 0.0)).length() < 1e-2);
    assert!((s.normal + Vec3::X).length() < 1e-2);
    // A light across the hole is blocked by the opposite inner side at x = -0.4.
    assert_eq!(visibility(&g, &s, -Vec3::X, true), Visibility::Shadowed);
    // Tilted upward by atan(0.5) the ray clears the far tube (top at z = 0.3): lit.
    assert_eq!(visibility(&g, &s, Vec3::new(-1.0, 0.0, 0.5).normalize(), true), Visibility::Lit { ray: true });
    // A light behind the surface needs no ray at all.
    assert_eq!(visibility(&g, &s, Vec3::X, true), Visibility::BelowHorizon);
    // The outer equator facing +x is lit from +x.
    let o = surface_sample(&g, &Ray::new(Vec3::new(3.0, 0.0, 0.0), -Vec3::X)).unwrap();
    assert!((o.position - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-2);
    assert_eq!(visibility(&g, &o, Vec3::X, true), Visibility::Lit { ray: true });
}

#[test]
fn rendered_pixel_equals_eq9_computed_independently() {
    let g = Geometry::new(BuiltinMesh::Sphere.mesh()).unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.9, 33, 33).unwrap();
    let light = DirectionalLight::new(Vec3::new(0.3, 0.4, 1.0), [2.0, 1.5, 1.0]).unwrap();
    let view = render_view(&g, &cam, &[light], phong, &RenderOptions::default());
    for (col, row) in [(16u32, 16u32), (20, 12), (10, 22)] {
        let ray = cam.pixel_ray(col as f32, row as f32);
        // Brute force over all triangles, without the BVH.
        let (tri, _t, b1, b2) = (0..g.mesh.triangles.len() as u32)
            .filter_map(|i| intersect_triangle(ray.origin, ray.dir, 0.0, f32::INFINITY, g.mesh.corners(i)).map(|(t, b1, b2)| (i, t, b1, b2)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        let [a, b, c] = g.mesh.triangles[tri as usize];
        let n = (g.mesh.normals[a as usize] * (1.0 - b1 - b2) + g.mesh.normals[b as usize] * b1 + g.mesh.normals[c as usize] * b2)
            .normalize();
        let v = -ray.dir;
        let l = light.direction;
        let cos = n.dot(l);
        assert!(cos > 0.0);
        let f = phong_world(n, l, v);
        let expected: Rgb = std::array::from_fn(|k| f[k] * light.intensity[k] * cos);
        let got = view.images[0].radiance[(row * 33 + col) as usize];
        for k in 0..3 {
            assert!((got[k] - expected[k]).abs() <= 1e-4 * expected[k].max(1.0), "pixel ({col},{row}) ch {k}: {got:?} vs {expected:?}");
        }
        assert!(view.images[0].lit[(row * 33 + col) as usize]);
    }
    // A corner pixel misses the sphere: black, not lit.
    assert_eq!(view.images[0].radiance[0], [0.0; 3]);
    assert!(!view.images[0].lit[0]);
}

fn lights_around(n: usize) -> Vec<DirectionalLight> {
    (0..n)
        .map(|i| {
            let phi = 2.0 * PI * i as f32 / n as f32;
            let theta = 0.2 + 1.2 * i as f32 / n as f32;
            DirectionalLight::new(Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()), [1.0; 3]).unwrap()
        })
        .collect()
}

#[test]
fn skipping_shadow_rays_on_a_convex_mesh_is_exact() {
    let g = Geometry::new(BuiltinMesh::Sphere.mesh()).unwrap();
    assert!(g.convex && is_convex(&g.mesh));
    let cam = Camera::look_at(Vec3::new(0.5, -0.4, 3.0), Vec3::ZERO, Vec3::Y, 0.8, 48, 48).unwrap();
    let lights = lights_around(6);
    let auto = render_view(&g, &cam, &lights, phong, &RenderOptions::default());
    let forced = render_view(&g, &cam, &lights, phong, &RenderOptions { shadows: ShadowPass::Force, ..Default::default() });
    assert!(!auto.report.shadow_pass && auto.report.shadow_rays() == 0);
    assert!(forced.report.shadow_pass && forced.report.shadow_rays() > 1000);
    assert_eq!(forced.report.lights.iter().map(|l| l.shadowed).sum::<usize>(), 0);
    assert_eq!(auto.images, forced.images, "bit-identical images");
    assert!(auto.report.summary().contains("skipped (closed convex mesh"));
}

#[test]
fn the_torus_casts_shadows() {
    let g = Geometry::new(BuiltinMesh::Torus.mesh()).unwrap();
    // Looking down the axis with a grazing light: the tube shadows the inner ring.
    let cam = Camera::look_at(Vec3::new(0.0, -1.0, 3.0), Vec3::ZERO, Vec3::Y, 0.8, 64, 64).unwrap();
    let lights = [DirectionalLight::new(Vec3::new(1.0, 0.0, 0.15), [1.0; 3]).unwrap()];
    let auto = render_view(&g, &cam, &lights, lambert, &RenderOptions::default());
    let off = render_view(&g, &cam, &lights, lambert, &RenderOptions { shadows: ShadowPass::Off, ..Default::default() });
    assert!(auto.report.shadow_pass);
    let shadowed = auto.report.lights[0].shadowed;
    assert!(shadowed > 10, "{}", auto.report.summary());
    // Exactly the pixels the shadow rays darken differ (a shadowed pixel seen from below its shading
    // horizon is black either way).
    let (a, o) = (&auto.images[0], &off.images[0]);
    let darkened = (0..a.lit.len()).filter(|&p| o.lit[p] && !a.lit[p]).count();
    let differ = (0..a.lit.len()).filter(|&p| a.radiance[p] != o.radiance[p]).count();
    assert!(darkened > 10 && darkened <= shadowed);
    assert_eq!(differ, darkened);
    assert!((0..a.lit.len()).all(|p| a.radiance[p] == o.radiance[p] || a.radiance[p] == [0.0; 3]));
}

#[test]
fn noise_is_deterministic_and_skipped_at_zero_sigma() {
    let g = Geometry::new(BuiltinMesh::Sphere.mesh()).unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 0.8, 16, 16).unwrap();
    let lights = lights_around(2);
    let opts = RenderOptions { noise_sigma: 0.01, seed: 7, ..Default::default() };
    let a = render_view(&g, &cam, &lights, lambert, &opts);
    let b = render_view(&g, &cam, &lights, lambert, &opts);
    let clean = render_view(&g, &cam, &lights, lambert, &RenderOptions::default());
    assert_eq!(a.images, b.images);
    assert!(a.report.noise_pass && !clean.report.noise_pass);
    let diff: Vec<f32> = a.images[0].radiance.iter().zip(&clean.images[0].radiance)
        .flat_map(|(x, y)| (0..3).map(move |k| x[k] - y[k])).filter(|d| *d != 0.0).collect();
    let rms = (diff.iter().map(|d| d * d).sum::<f32>() / diff.len() as f32).sqrt();
    assert!(rms > 0.003 && rms < 0.012, "noise rms {rms}");
    assert_ne!(a.images[0].radiance, a.images[1].radiance, "each image has its own stream");
}

#[test]
fn angle_weighted_normals_do_not_depend_on_the_triangulation() {
    // A unit cube corner is shared by one triangle of one face and two of another: angle weighting
    // still gives the symmetric diagonal, area or count weighting would not.
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let pos = vec![p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.), p(0., 0., 1.), p(1., 0., 1.), p(1., 1., 1.), p(0., 1., 1.)];
    let tris = vec![
        [0, 2, 1], [0, 3, 2], // z = 0
        [4, 5, 6], [4, 6, 7], // z = 1
        [0, 1, 5], [0, 5, 4], // y = 0
        [3, 6, 2], [3, 7, 6], // y = 1
        [0, 4, 7], [0, 7, 3], // x = 0
        [1, 2, 6], [1, 6, 5], // x = 1
    ];
    let m = Mesh::new(pos, tris).unwrap();
    let d = Vec3::splat(1.0).normalize();
    assert!((m.normals[6] - d).length() < 1e-6, "{}", m.normals[6]);
    assert!((m.normals[0] + d).length() < 1e-6, "{}", m.normals[0]);
    assert!(is_convex(&m));
}

#[test]
fn obj_and_ply_load_and_bad_meshes_fail_clearly() {
    let dir = tmpdir("meshes");
    let ok = "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(dir.join("tet.obj"), ok).unwrap();
    let tet = Mesh::load(dir.join("tet.obj")).unwrap();
    assert_eq!((tet.positions.len(), tet.triangles.len()), (4, 4));
    assert!(is_convex(&tet));
    let (n, t) = tet.normalized();
    assert!((n.positions.iter().map(|p| p.length()).fold(0.0, f32::max) - 1.0).abs() < 1e-6);
    assert_eq!(t.center, Vec3::splat(1.0));

    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n2 0 0\n0 2 0\n0 0 2\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    std::fs::write(dir.join("tet.ply"), ply).unwrap();
    // Same triangles (tobj orders OBJ vertices by first use, so compare corner positions).
    let from_ply = Mesh::load(dir.join("tet.ply")).unwrap();
    for t in 0..4 {
        assert_eq!(from_ply.corners(t), tet.corners(t));
    }

    // The same tetrahedron as triangle strips (Stanford's format), separated by -1: two triangles
    // (the second flipped back to the strip's winding), one, and one with a repeated vertex whose
    // degenerate second triangle is dropped.
    let strips = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n0 0 0\n2 0 0\n0 2 0\n0 0 2\n13 2 0 3 1 -1 1 2 3 -1 0 2 1 1\n";
    std::fs::write(dir.join("tet-strips.ply"), strips).unwrap();
    let from_strips = Mesh::load(dir.join("tet-strips.ply")).unwrap();
    assert_eq!(from_strips.triangles, vec![[2, 0, 3], [3, 0, 1], [1, 2, 3], [0, 2, 1]]);
    assert!(is_convex(&from_strips), "outward winding throughout");

    let cases: [(&str, &str, &str); 7] = [
        ("no-faces.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n", "no 'face' or 'tristrips' element"),
        ("line.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "2 corners"),
        ("empty.obj", "# nothing\n", "no triangles"),
        ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "degenerate"),
        ("range.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n", "OBJ"),
        ("nan.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", ""),
        ("range.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "vertex index"),
    ];
    for (name, text, needle) in cases {
        std::fs::write(dir.join(name), text).unwrap();
        let err = Mesh::load(dir.join(name)).unwrap_err().to_string();
        assert!(err.contains(needle), "{name}: {err}");
    }
    match Mesh::load(dir.join("missing.obj")) {
        Err(Error::Io { kind, path, .. }) => {
            assert_eq!(kind, std::io::ErrorKind::NotFound);
            assert!(path.ends_with("missing.obj"));
        }
        other => panic!("{other:?}"),
    }
    assert!(Mesh::load(dir.join("tet.stl")).unwrap_err().to_string().contains("unknown mesh format"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn shared_meshes_load_into_the_unit_sphere() {
    let root = PathBuf::from(std::env::var("NBRDF_DATA").unwrap_or_else(|_| "../shared/data".into()));
    let path = root.join("meshes/spot.obj");
    if !path.exists() {
        eprintln!("skipping: {} not found (set NBRDF_DATA to the shared data folder)", path.display());
        return;
    }
    let (m, _) = Mesh::load(&path).unwrap().normalized();
    assert!((m.radius() - 1.0).abs() < 1e-3);
    assert!(m.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    let g = Geometry::new(m).unwrap();
    assert!(!g.convex, "spot the cow has concavities");
    // The cow is seen from the front: the centre ray hits something within the unit sphere.
    let hit = g.accel.intersect(&Ray::new(Vec3::new(0.0, 0.0, 3.0), -Vec3::Z)).unwrap();
    assert!(hit.t > 1.9 && hit.t < 4.0);
}

#[test]
fn grooved_mesh_is_closed_and_concave() {
    let g = Geometry::new(BuiltinMesh::Grooved.mesh()).unwrap();
    assert!(!g.convex);
    // Along +x (φ = 0, the middle of a groove) the equator lies at radius 0.5.
    let hit = g.accel.intersect(&Ray::new(Vec3::new(3.0, 0.0, 0.0), -Vec3::X)).unwrap();
    assert!((hit.t - 2.5).abs() < 1e-3, "{}", hit.t);
}

#[test]
fn exr_and_png_round_trip_and_truncation_fails() {
    let dir = tmpdir("images");
    let data: Vec<Rgb> = (0..12).map(|i| [i as f32 * 0.5, 1e-4 * i as f32, 500.0 + i as f32]).collect();
    let img = RgbImage::from_data(4, 3, data).unwrap();
    write_exr(dir.join("a.exr"), &img).unwrap();
    assert_eq!(read_exr(dir.join("a.exr")).unwrap(), img);
    let bytes = std::fs::read(dir.join("a.exr")).unwrap();
    std::fs::write(dir.join("cut.exr"), &bytes[..bytes.len() / 2]).unwrap();
    let err = read_exr(dir.join("cut.exr")).unwrap_err();
    assert!(err.to_string().contains("cut.exr"), "{err}");
    assert!(matches!(read_exr(dir.join("none.exr")), Err(Error::Io { .. })));
    // 16-bit PNG: code values come back divided by 65535.
    let codes: Vec<[u16; 3]> = (0..6).map(|i| [i * 10000, 65535 - i, 1]).collect();
    write_png16(dir.join("b.png"), 3, 2, &codes).unwrap();
    let back = read_png(dir.join("b.png")).unwrap();
    for (c, p) in codes.iter().zip(&back.data) {
        for k in 0..3 {
            assert_eq!(p[k], c[k] as f32 / 65535.0);
        }
    }
    // No temporary files are left behind.
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().starts_with(".nbrdf-tmp")));
    // The sRGB transfer functions invert each other on 8-bit codes.
    for code in 0..=255u32 {
        let y = code as f32 / 255.0;
        assert!((srgb_encode(srgb_decode(y)) - y).abs() < 1e-5);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
