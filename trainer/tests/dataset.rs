//! Data sets: the semi-synthetic writer and reader, samples against Eq. 9, bad descriptions, and the
//! DiLiGenT-MV reader on a small replica in the real layout.

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use nbrdf_scene::image::{write_png16, write_png_mask};
use nbrdf_scene::scene::builtin::BuiltinMesh;
use nbrdf_scene::scene::render::{render_view, RenderOptions};
use nbrdf_scene::scene::{Camera, DirectionalLight, Geometry};
use nbrdf::{Error, Vec3};
use trainer::dataset::synth::{synthesize, SynthArgs};
use trainer::dataset::{diligent, samples, Dataset, Split};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nbrdf-dataset-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn small(out: &Path, mesh: &str, sigma: f32, seed: u64) -> SynthArgs {
    SynthArgs {
        mesh: mesh.into(),
        material: "lambert:0.6,0.5,0.4".into(),
        size: 24,
        views: 4,
        train_views: 2,
        train_lights: 3,
        test_lights: 2,
        sigma,
        seed,
        ..SynthArgs::new(out)
    }
}

#[test]
fn synth_writes_a_described_deterministic_data_set() {
    let a = tmpdir("synth-a");
    let b = tmpdir("synth-b");
    let c = tmpdir("synth-c");
    let (file, reports) = synthesize(&small(&a, "torus", 1e-3, 5)).unwrap();
    synthesize(&small(&b, "torus", 1e-3, 5)).unwrap();
    synthesize(&small(&c, "torus", 1e-3, 6)).unwrap();
    assert_eq!(file.counts.views, 4);
    assert_eq!(file.views.iter().filter(|v| v.split == Split::Train).count(), 2);
    for v in &file.views {
        assert_eq!(v.images.len(), if v.split == Split::Train { 3 } else { 2 });
        for im in &v.images {
            assert!(a.join(&im.radiance).is_file() && a.join(&im.brdf).is_file() && a.join(&im.lit).is_file());
            // Lights lie in the hemisphere facing the camera.
            let cam = v.camera(24, 24).unwrap();
            assert!(Vec3::from(im.light.direction).dot(cam.center()) > 0.0);
        }
    }
    assert!(reports.iter().all(|r| r.noise_pass && r.shadow_pass), "torus: shadow rays and noise");
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read(&a, "dataset.json"), read(&b, "dataset.json"));
    assert_eq!(read(&a, "views/01/002.exr"), read(&b, "views/01/002.exr"), "same seed, same bytes");
    assert_ne!(read(&a, "dataset.json"), read(&c, "dataset.json"), "another seed, other lights");
    for d in [a, b, c] {
        std::fs::remove_dir_all(d).unwrap();
    }
}

#[test]
fn interreflections_add_the_path_traced_bounces_and_are_written_beside_each_image() {
    use nbrdf_scene::image::read_exr;
    // The same noise-free data set with and without the bounces: the radiance with them is the
    // direct-only radiance plus the interreflected part written beside it.
    for (mesh, sees_itself) in [("grooved", true), ("sphere", false)] {
        let (plain, bounced) = (tmpdir(&format!("direct-{mesh}")), tmpdir(&format!("bounced-{mesh}")));
        let args = SynthArgs { material: "lambert:0.8,0.8,0.8".into(), ..small(&plain, mesh, 0.0, 8) };
        let (direct, _) = synthesize(&args).unwrap();
        let (file, reports) = synthesize(&SynthArgs { out: bounced.clone(), interreflections: 8, ..args }).unwrap();
        assert!(reports.iter().all(|r| !r.noise_pass));
        assert!(direct.views.iter().flat_map(|v| &v.images).all(|im| im.indirect.is_none()));
        let mut indirect_sum = 0.0f64;
        for (v, w) in direct.views.iter().zip(&file.views) {
            for (a, b) in v.images.iter().zip(&w.images) {
                let (d, r) = (read_exr(plain.join(&a.radiance)).unwrap(), read_exr(bounced.join(&b.radiance)).unwrap());
                let part = read_exr(bounced.join(b.indirect.as_ref().expect("each image has its interreflected part"))).unwrap();
                for ((d, r), i) in d.data.iter().zip(&r.data).zip(&part.data) {
                    for c in 0..3 {
                        assert!(i[c] >= 0.0 && (r[c] - (d[c] + i[c])).abs() <= 1e-5 * r[c].abs().max(1.0), "{r:?} = {d:?} + {i:?}");
                    }
                    indirect_sum += f64::from(i[1]);
                }
            }
        }
        assert_eq!(indirect_sum > 0.0, sees_itself, "{mesh}: interreflected light {indirect_sum}");
        // Only the extra files differ from a direct-only set's description.
        assert_eq!(file.views.len(), direct.views.len());
        for d in [plain, bounced] {
            std::fs::remove_dir_all(d).unwrap();
        }
    }
}

#[test]
fn samples_are_lit_pixels_and_satisfy_eq9() {
    let dir = tmpdir("samples");
    let (file, _) = synthesize(&small(&dir, "grooved", 0.0, 1)).unwrap();
    let ds = Dataset::open(&dir).unwrap();
    let s = samples(&ds, Split::Train, 1).unwrap();
    // Exactly the pixels the renderer marked lit, view by view.
    let lit: usize = file
        .views
        .iter()
        .filter(|v| v.split == Split::Train)
        .flat_map(|v| &v.images)
        .map(|im| nbrdf_scene::image::read_mask(dir.join(&im.lit)).unwrap().2.iter().filter(|&&b| b).count())
        .sum();
    assert!(lit > 100);
    assert_eq!(s.len(), lit);
    // Without noise, a Lambertian sample is albedo/π · L_i · cos θ_l with cos θ_l = wi.z.
    let albedo = [0.6, 0.5, 0.4];
    for i in 0..s.len() {
        let (wi, wo) = (s.wi[i], s.wo[i]);
        assert!(wi[2] > 0.0 && wo[2] > 0.0);
        for (k, a) in albedo.iter().enumerate() {
            let expected = a / PI * s.intensity[i][k] * wi[2];
            assert!((s.radiance[i][k] - expected).abs() < 1e-6, "sample {i}: {:?} vs {expected}", s.radiance[i]);
        }
        // x: barycentrics reproduce the position; the normal is unit.
        let p = ds.geometry.mesh.point(s.triangle[i], s.barycentric[i][0], s.barycentric[i][1]);
        assert!((p - Vec3::from(s.position[i])).length() < 1e-6);
        assert!((Vec3::from(s.normal[i]).length() - 1.0).abs() < 1e-5);
    }
    // A stride keeps a subset.
    let strided = samples(&ds, Split::Train, 3).unwrap();
    assert!(strided.len() < s.len() && strided.len() * 4 > s.len());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn edit_json(dir: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let p = dir.join("dataset.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
}

#[test]
fn bad_descriptions_and_files_fail_clearly() {
    let dir = tmpdir("bad");
    synthesize(&small(&dir, "sphere", 0.0, 2)).unwrap();
    let original = std::fs::read(dir.join("dataset.json")).unwrap();
    let restore = || std::fs::write(dir.join("dataset.json"), &original).unwrap();

    edit_json(&dir, |v| v["counts"]["train_lights"] = 5.into());
    let e = Dataset::open(&dir).unwrap_err().to_string();
    assert!(e.contains("dataset.json") && e.contains("declared 5, found 3"), "{e}");
    restore();

    edit_json(&dir, |v| v["counts"]["views"] = 7.into());
    let e = Dataset::open(&dir).unwrap_err().to_string();
    assert!(e.contains("views: declared 7, found 4"), "{e}");
    restore();

    edit_json(&dir, |v| v["version"] = 9.into());
    assert!(matches!(Dataset::open(&dir), Err(trainer::Error::Core(Error::UnsupportedVersion { found: 9, .. }))));
    restore();

    edit_json(&dir, |v| v["mesh"] = serde_json::json!({"kind": "builtin", "id": "teapot"}));
    assert!(Dataset::open(&dir).unwrap_err().to_string().contains("unknown built-in mesh 'teapot'"));
    restore();

    // A truncated radiance image is found when the samples are read, and named.
    let exr = dir.join("views/00/000.exr");
    let bytes = std::fs::read(&exr).unwrap();
    std::fs::write(&exr, &bytes[..bytes.len() / 3]).unwrap();
    let ds = Dataset::open(&dir).unwrap();
    let split = ds.views[0].split;
    let e = samples(&ds, split, 1).unwrap_err().to_string();
    assert!(e.contains("000.exr"), "{e}");
    std::fs::remove_file(&exr).unwrap();
    assert!(matches!(samples(&ds, split, 1), Err(trainer::Error::Core(Error::Io { .. }))));

    assert!(matches!(Dataset::open(&dir.join("nowhere")), Err(trainer::Error::Core(Error::Io { .. }))));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_convex_mesh_gives_the_same_samples_without_shadow_rays() {
    let dir = tmpdir("convex");
    let (_, reports) = synthesize(&small(&dir, "sphere", 0.0, 3)).unwrap();
    assert!(reports.iter().all(|r| !r.shadow_pass && r.shadow_rays() == 0 && !r.noise_pass));
    let forced = tmpdir("convex-forced");
    let (_, forced_reports) = synthesize(&SynthArgs { force_shadows: true, ..small(&forced, "sphere", 0.0, 3) }).unwrap();
    assert!(forced_reports.iter().all(|r| r.shadow_rays() > 0));
    for f in ["views/00/000.exr", "views/01/001.exr", "views/02/000_lit.png"] {
        assert_eq!(std::fs::read(dir.join(f)).unwrap(), std::fs::read(forced.join(f)).unwrap(), "{f}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&forced).unwrap();
}

/// A minimal MATLAB v5 (level 5 MAT-file) writer, enough for `Calib_Results.mat`: no crate writes the
/// format. Layout per MathWorks' "MAT-File Format" (2019): a 128-byte header, then one `miMATRIX`
/// element per variable holding array flags, dimensions, name and data sub-elements, each padded to 8
/// bytes.
mod mat5 {
    fn element(out: &mut Vec<u8>, ty: u32, data: &[u8]) {
        out.extend(ty.to_le_bytes());
        out.extend((data.len() as u32).to_le_bytes());
        out.extend(data);
        out.resize(out.len().next_multiple_of(8), 0);
    }

    fn matrix(out: &mut Vec<u8>, name: &str, class: u32, dims: [i32; 2], data_ty: u32, data: &[u8]) {
        let mut body = Vec::new();
        element(&mut body, 6, &[class.to_le_bytes(), 0u32.to_le_bytes()].concat()); // miUINT32 flags
        element(&mut body, 5, &[dims[0].to_le_bytes(), dims[1].to_le_bytes()].concat()); // miINT32 dims
        element(&mut body, 1, name.as_bytes()); // miINT8 name
        element(&mut body, data_ty, data);
        element(out, 14, &body); // miMATRIX
    }

    /// Double matrix `rows x cols` from column-major values.
    pub fn double(out: &mut Vec<u8>, name: &str, rows: i32, cols: i32, col_major: &[f64]) {
        let bytes: Vec<u8> = col_major.iter().flat_map(|x| x.to_le_bytes()).collect();
        matrix(out, name, 6, [rows, cols], 9, &bytes); // mxDOUBLE_CLASS, miDOUBLE
    }

    /// Character array (as Bouguet's toolbox stores e.g. `format_image`).
    pub fn chars(out: &mut Vec<u8>, name: &str, text: &str) {
        let bytes: Vec<u8> = text.encode_utf16().flat_map(|c| c.to_le_bytes()).collect();
        matrix(out, name, 4, [1, text.len() as i32], 4, &bytes); // mxCHAR_CLASS, miUINT16
    }

    pub fn header() -> Vec<u8> {
        let mut h = b"MATLAB 5.0 MAT-file, written by the nbrdf dataset test".to_vec();
        h.resize(116, b' ');
        h.extend([0u8; 8]); // no subsystem data
        h.extend(0x0100u16.to_le_bytes());
        h.extend(b"IM"); // little-endian
        h
    }
}

fn col_major(m: glam::Mat3) -> Vec<f64> {
    m.to_cols_array().iter().map(|&x| x as f64).collect()
}

#[test]
fn diligent_replica_reads_into_samples() {
    let root = tmpdir("diligent");
    let obj = root.join("mvpmsData/bearPNG");
    std::fs::create_dir_all(&obj).unwrap();
    // World in millimetres, as in DiLiGenT-MV: a sphere of radius 40 at (5, -3, 600).
    let center = Vec3::new(5.0, -3.0, 600.0);
    let unit = BuiltinMesh::Sphere.mesh();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        unit.positions.len(),
        unit.triangles.len()
    );
    for p in &unit.positions {
        let q = center + *p * 40.0;
        ply += &format!("{} {} {}\n", q.x, q.y, q.z);
    }
    for t in &unit.triangles {
        ply += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(obj.join("mesh_Gt.ply"), ply).unwrap();

    let (w, h) = (24u32, 20u32);
    let eyes = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(300.0, 0.0, 100.0)];
    let cams: Vec<Camera> = eyes.iter().map(|e| Camera::look_at(*e, center, -Vec3::Y, 0.15, w, h).unwrap()).collect();
    let mut mat = mat5::header();
    mat5::chars(&mut mat, "format_image", "png");
    mat5::double(&mut mat, "KK", 3, 3, &col_major(cams[0].k));
    for (i, c) in cams.iter().enumerate() {
        mat5::double(&mut mat, &format!("Rc_{}", i + 1), 3, 3, &col_major(c.r));
        mat5::double(&mut mat, &format!("Tc_{}", i + 1), 3, 1, &c.t.to_array().map(|x| x as f64));
    }
    std::fs::write(obj.join("Calib_Results.mat"), mat).unwrap();

    // Render the replica's images with the renderer itself, under world lights given to the reader
    // in DiLiGenT's camera frame.
    let mesh = nbrdf_scene::scene::Mesh::load(obj.join("mesh_Gt.ply")).unwrap();
    let geometry = Geometry::new(mesh).unwrap();
    let intensities = [[2.0f32, 1.5, 1.0], [0.8, 1.0, 1.2]];
    let albedo = 0.7f32;
    let mut world_lights = Vec::new();
    for (vi, cam) in cams.iter().enumerate() {
        let vd = obj.join(format!("view_{:02}", vi + 1));
        std::fs::create_dir_all(&vd).unwrap();
        let to_cam = (cam.center() - center).normalize();
        let lights: Vec<DirectionalLight> = [Vec3::new(0.3, 0.2, 0.0), Vec3::new(-0.2, 0.4, 0.0)]
            .iter()
            .map(|o| DirectionalLight::new(to_cam + *o, [1.0; 3]).unwrap())
            .collect();
        let rendered = render_view(&geometry, cam, &lights, |_, wi, wo| {
            if wi.z > 0.0 && wo.z > 0.0 { [albedo / PI; 3] } else { [0.0; 3] }
        }, &RenderOptions::default());
        let mask: Vec<bool> = rendered.gbuffer.samples.iter().map(Option::is_some).collect();
        write_png_mask(vd.join("mask.png"), w, h, &mask).unwrap();
        let (mut dirs, mut ints) = (String::new(), String::new());
        for (li, (l, img)) in lights.iter().zip(&rendered.images).enumerate() {
            let c = cam.r * l.direction; // OpenCV camera axes
            dirs += &format!("{} {} {}\n", c.x, -c.y, -c.z); // x right, y up, z toward the camera
            let e = intensities[li];
            ints += &format!("{} {} {}\n", e[0], e[1], e[2]);
            let codes: Vec<[u16; 3]> =
                img.radiance.iter().map(|p| std::array::from_fn(|k| (p[k] * e[k] * 65535.0).round() as u16)).collect();
            write_png16(vd.join(format!("{:03}.png", li + 1)), w, h, &codes).unwrap();
            world_lights.push(l.direction);
        }
        std::fs::write(vd.join("light_directions.txt"), dirs).unwrap();
        std::fs::write(vd.join("light_intensities.txt"), ints).unwrap();
    }

    // Either the mvpmsData folder or its parent may be given.
    let ds = diligent::open(&root, "bear").unwrap();
    assert!(diligent::open(&root.join("mvpmsData"), "bear").is_ok());
    assert_eq!(ds.views.len(), 2);
    assert_eq!((ds.views[0].split, ds.views[1].split), (Split::Train, Split::Test));
    for (vi, v) in ds.views.iter().enumerate() {
        assert_eq!((v.camera.width, v.camera.height), (w, h));
        assert!((v.camera.center() - eyes[vi]).length() < 1e-2);
        for (li, im) in v.images.iter().enumerate() {
            assert!((im.light.direction - world_lights[vi * 2 + li]).length() < 1e-5, "light back in world frame");
        }
    }
    let s = samples(&ds, Split::Train, 1).unwrap();
    assert!(s.len() > 50, "{} samples", s.len());
    for i in 0..s.len() {
        let expected = albedo / PI * s.wi[i][2];
        for k in 0..3 {
            // 16-bit quantisation of radiance × intensity, divided back.
            assert!((s.radiance[i][k] - expected).abs() < 2e-5, "{:?} vs {expected}", s.radiance[i]);
        }
    }

    // The command line reads the same copy.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["inspect", "--diligent"])
        .arg(&root)
        .args(["--object", "bear"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("views: 2 (1 train, 1 test), images: 4"), "{text}");
    assert!(text.contains(&format!("training samples (lit, unshadowed pixels): {}", s.len())), "{text}");

    // Broken copies fail with the file named.
    assert!(diligent::open(&root, "teddy").unwrap_err().to_string().contains("unknown object"));
    std::fs::write(obj.join("view_02/light_intensities.txt"), "1 1 1\n").unwrap();
    assert!(matches!(diligent::open(&root, "bear"), Err(trainer::Error::Core(Error::SizeMismatch { expected: 2, found: 1, .. }))));
    std::fs::remove_file(obj.join("view_01/002.png")).unwrap();
    let e = diligent::open(&root, "bear").unwrap_err().to_string();
    assert!(e.contains("002.png"), "{e}");
    std::fs::write(obj.join("Calib_Results.mat"), b"MATLAB 5.0 but cut").unwrap();
    let e = diligent::open(&root, "bear").unwrap_err().to_string();
    assert!(e.contains("Calib_Results.mat"), "{e}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn raw_brdf_images_hold_the_material_at_the_sample_directions() {
    // Built-in material, MERL table and (where the shared data is present) an NBRDF-json network.
    let dir = tmpdir("materials");
    let merl = dir.join("grey.binary");
    nbrdf::measured::MerlTable::tabulate(|_, _| [0.2, 0.1, 0.05]).write(&merl).unwrap();
    // Tests run in trainer/, so the default `../shared/data` of the workspace root is two levels up.
    let data = std::env::var("NBRDF_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    let chrome = data.join("nbrdf-merl/chrome.json");
    let mut materials = vec!["clear-coat".to_string(), merl.display().to_string()];
    if chrome.is_file() {
        materials.push(chrome.display().to_string());
    } else {
        eprintln!("skipping the NBRDF-json material: {} not found (set NBRDF_DATA)", chrome.display());
    }
    for (m, material) in materials.iter().enumerate() {
        let out = dir.join(format!("m{m}"));
        let args = SynthArgs { material: material.clone(), ..small(&out, "sphere", 0.0, 4) };
        let (file, _) = synthesize(&args).unwrap();
        let loaded = file.material.load(&out).unwrap();
        let ds = Dataset::open(&out).unwrap();
        let s = samples(&ds, Split::Train, 1).unwrap();
        assert!(s.len() > 100);
        let mut brdf_images = std::collections::HashMap::new();
        for i in 0..s.len() {
            let (v, im) = (s.view[i] as usize, s.image[i] as usize);
            let img = brdf_images
                .entry((v, im))
                .or_insert_with(|| nbrdf_scene::image::read_exr(ds.views[v].images[im].brdf.as_ref().unwrap()).unwrap());
            let stored = img.data[s.pixel[i] as usize];
            let f = loaded.eval(Vec3::from(s.wi[i]), Vec3::from(s.wo[i]));
            for k in 0..3 {
                assert_eq!(stored[k], f[k], "{material}: stored BRDF is the material's value");
                let expected = f[k] * s.intensity[i][k] * s.wi[i][2];
                assert!((s.radiance[i][k] - expected).abs() <= 1e-6 * expected.max(1.0), "{material}: Eq. 9");
            }
        }
        if m == 1 {
            // The constant table: 0.2 · cos θ_l, except near grazing where MERL bins whose centre lies
            // below the horizon hold no value (0).
            let ok = s.radiance.iter().zip(&s.wi).filter(|(r, wi)| (r[0] - 0.2 * wi[2]).abs() < 1e-6).count();
            let zero = s.radiance.iter().filter(|r| r[0] == 0.0).count();
            assert_eq!(ok + zero, s.len());
            assert!(ok * 10 > s.len() * 8, "{ok} of {}", s.len());
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn synth_command_line_writes_and_reports() {
    let dir = tmpdir("cli");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["synth", "--mesh", "torus", "--material", "velvet", "--size", "16", "--views", "2", "--train-views", "1"])
        .args(["--train-lights", "2", "--test-lights", "1", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("wrote 2 views, 3 images") && text.contains("shadow rays"), "{text}");
    let ds = Dataset::open(&dir).unwrap();
    assert_eq!(ds.views.iter().map(|v| v.images.len()).sum::<usize>(), 3);
    // A bad argument is a clear error and a failing exit status.
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["synth", "--material", "felt", "--out"])
        .arg(dir.join("x"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown material 'felt'"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_specular_object_is_exposed_for_its_body_like_a_capture() {
    // A mirror-like table: light only near the specular direction, black elsewhere, so more than half
    // of the object's pixels are 0 (as MERL chrome-steel on a mesh): metered on the lit ones.
    let dir = tmpdir("specular-exposure");
    let table = dir.join("mirror.binary");
    nbrdf::measured::MerlTable::tabulate(|wi, wo| {
        let h = (wi + wo).normalize();
        if h.z > 0.99 { [40.0; 3] } else { [0.0; 3] }
    })
    .write(&table)
    .unwrap();
    let data = std::env::var("NBRDF_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    let mut cases = vec![("sphere".to_string(), table.display().to_string())];
    let (chrome, spot, rocker) =
        (data.join("nbrdf-merl/chrome-steel.json"), data.join("meshes/spot.obj"), data.join("meshes/rocker-arm.obj"));
    if chrome.is_file() && spot.is_file() && rocker.is_file() {
        for mesh in [&spot, &rocker] {
            cases.push((mesh.display().to_string(), chrome.display().to_string()));
        }
    } else {
        eprintln!("skipping chrome-steel on spot and rocker-arm: {} not found (set NBRDF_DATA)", data.display());
    }
    for (i, (mesh, material)) in cases.iter().enumerate() {
        let out = dir.join(format!("c{i}"));
        let args = SynthArgs { material: material.clone(), target_median: Some(0.2), ..small(&out, mesh, 1e-3, 2) };
        let (file, _) = synthesize(&args).unwrap_or_else(|e| panic!("{mesh} / {material}: {e}"));
        let e = file.exposure.expect("a calibrated exposure is recorded");
        assert!(e.light_intensity.is_finite() && e.light_intensity > 0.0, "{mesh}: {e:?}");
        // Exposed like a capture: the body well above the noise, a tenth of the lit pixels clipped at
        // most (give or take the views the one-view probe did not see).
        assert!(e.median_luminance > 0.02, "{mesh} / {material}: {e:?}");
        assert!(e.saturated_share < 0.15, "{mesh} / {material}: {e:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
