//! The C ABI from C99 and C++17: programs compiled with the system's C and C++ compilers (through the
//! `cc` crate) against `libnbrdf.a` evaluate, batch, sample and query densities for every built-in,
//! every parametric model, model files (f32, f16 borrowed in place, spatially varying), an NBRDF-json
//! network and a MERL table, and the values must be the Rust API's bit for bit. The programs also run
//! a chi-square test of sampling against the density and every error path (`tests/c/`).

use std::path::{Path, PathBuf};
use std::process::Command;

use nbrdf_core::builtin::Builtin;
use nbrdf_core::energy::{AlbedoBound, ALBEDO_CELLS};
use nbrdf_core::file::{encode, set_albedo_bound, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
use nbrdf_core::measured::{MerlTable, NbrdfNetwork};
use nbrdf_core::parametric::{Disney, FresnelMicrofacet, Lambert, Parametric, ParametricKind, Phong, TorranceSparrow};
use nbrdf_core::{Brdf, ModelBuf, Vec3};

/// A fresh scratch folder.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nbrdf-capi-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `target/<profile>/deps`, where cargo builds `libnbrdf.a` for this test run (the copy one level
/// up is refreshed by `cargo build` only).
fn lib_dir() -> PathBuf {
    std::env::current_exe().unwrap().parent().unwrap().to_path_buf()
}

/// `libnbrdf.a` as this source tree builds it. A staticlib is no dependency of the tests, so cargo
/// may not have built it for this run: build it (same profile and target folder; cargo has released
/// its lock by the time tests run) unless it is newer than every source.
fn built_library() -> PathBuf {
    let lib = lib_dir().join("libnbrdf.a");
    let status = Command::new(env!("CARGO"))
        .args(["build", "-q", "-p", "nbrdf-capi"])
        .args(if cfg!(debug_assertions) { &[][..] } else { &["--release"][..] })
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .expect("cargo runs");
    assert!(status.success(), "cargo build -p nbrdf-capi failed");
    // `cargo build` puts the fresh library one level up from this test's deps/ folder.
    let built = lib_dir().parent().unwrap().join("libnbrdf.a");
    if built.exists() { built } else { lib }
}

/// Compiles `source` (C or C++ by `cpp`) against the static library; `None` (with a SKIPPED line)
/// where the host has no such compiler.
fn compile(source: &str, cpp: bool, flags: &[&str], out: &Path) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = built_library();
    let compiler = cc::Build::new()
        .cargo_metadata(false)
        .cpp(cpp)
        .opt_level(1)
        .target(env!("NBRDF_CAPI_TARGET"))
        .host(env!("NBRDF_CAPI_HOST"))
        .try_get_compiler();
    let compiler = match compiler {
        Ok(c) => c,
        Err(e) => {
            println!("SKIPPED: no {} compiler: {e}", if cpp { "C++" } else { "C" });
            return None;
        }
    };
    let exe = out.join(Path::new(source).file_stem().unwrap());
    let mut cmd = compiler.to_command();
    cmd.args(flags).arg("-I").arg(dir.join("include")).arg(dir.join("tests/c").join(source)).arg("-o").arg(&exe).arg(&lib);
    if cfg!(target_os = "linux") {
        cmd.args(["-lpthread", "-ldl", "-lm"]);
    }
    let result = match cmd.output() {
        Ok(r) => r,
        Err(e) => {
            println!("SKIPPED: cannot run {:?}: {e}", compiler.path());
            return None;
        }
    };
    assert!(result.status.success(), "{source} does not compile:\n{}", String::from_utf8_lossy(&result.stderr));
    Some(exe)
}

/// Direction pairs with three uniforms each, the hard cases first: below the horizon, grazing,
/// `wi = wo`, the mirror direction, the pole.
fn pairs() -> Vec<(Vec3, Vec3, [f32; 3])> {
    let d = |t: f32, p: f32| Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    let mut v = vec![
        (Vec3::new(0.3, 0.1, -0.5), d(0.4, 1.0), [0.5; 3]),
        (d(std::f32::consts::FRAC_PI_2 - 1e-4, 0.3), d(0.3, 2.0), [0.1, 0.9, 0.4]),
        (d(0.6, 1.1), d(0.6, 1.1), [0.7, 0.2, 0.8]),
        (d(0.7, 0.5), d(0.7, 0.5 + std::f32::consts::PI), [0.3, 0.3, 0.3]),
        (Vec3::Z, Vec3::Z, [0.0, 0.0, 0.0]),
    ];
    let mut s = 7u64;
    let mut r = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    while v.len() < 256 {
        let tau = std::f32::consts::TAU;
        v.push((d(r() * 1.55, r() * tau), d(r() * 1.55, r() * tau), [r(), r(), r()]));
    }
    v
}

/// A model file with deterministic weights.
fn model_bytes(kind: ModelKind, r: Reciprocity, position: PositionEncoding, with_proxy: bool) -> Vec<u8> {
    let h = ModelHeader::paper(kind, true, r, position, 2);
    let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 7919 % 211) as f32 - 105.0) * 1.5e-3).collect();
    let plain = encode(&h, &w, None).unwrap();
    if !with_proxy {
        return plain;
    }
    let buf = ModelBuf::from_bytes(&plain).unwrap();
    let proxy = buf.model().fit_proxy(&[buf.model().prepare(&[]).unwrap()]);
    encode(&h.with_proxy(proxy), &w, None).unwrap()
}

/// The cases the programs read (`cases.txt`: `KIND ARG|POINT`) with the Rust BRDF each must match.
/// The returned buffers keep the models alive.
fn write_cases(dir: &Path) -> (Vec<Box<dyn Brdf>>, Vec<ModelBuf>) {
    let mut lines = Vec::new();
    let mut expect: Vec<Box<dyn Brdf>> = Vec::new();
    for b in Builtin::ALL {
        lines.push(format!("builtin {}|", b.id()));
        expect.push(Box::new(b));
    }
    let natural: [(u32, Vec<f32>, Parametric); 5] = [
        (0, vec![0.2, 0.5, 0.8], Parametric::Lambert(Lambert { kd: [0.2, 0.5, 0.8] })),
        (1, vec![0.3, 0.2, 0.1, 0.5, 0.5, 0.5, 40.0], Parametric::Phong(Phong::new([0.3, 0.2, 0.1], [0.5; 3], 40.0).unwrap())),
        (2, vec![0.2, 0.1, 0.1, 0.7, 0.6, 0.5, 0.3], Parametric::TorranceSparrow(TorranceSparrow { kd: [0.2, 0.1, 0.1], ks: [0.7, 0.6, 0.5], alpha: 0.3 })),
        (
            3,
            vec![0.4, 0.3, 0.2, 0.6, 0.25, 1.5, 1.5, 1.0],
            Parametric::FresnelMicrofacet(FresnelMicrofacet { rho: [0.4, 0.3, 0.2], ks: 0.6, alpha: 0.25, beta: 1.5, eta: 1.5, norm: 1.0 }),
        ),
        (
            4,
            vec![0.8, 0.3, 0.2, 0.1, 0.3, 0.5, 0.2, 0.4, 0.3, 0.5, 0.2, 0.7],
            Parametric::Disney(Disney {
                base_color: [0.8, 0.3, 0.2],
                subsurface: 0.1,
                metallic: 0.3,
                specular: 0.5,
                specular_tint: 0.2,
                roughness: 0.4,
                sheen: 0.3,
                sheen_tint: 0.5,
                clearcoat: 0.2,
                clearcoat_gloss: 0.7,
            }),
        ),
    ];
    for (k, v, p) in natural {
        lines.push(format!("parametric {k} {}|", v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ")));
        expect.push(Box::new(p));
    }
    for (k, kind) in ParametricKind::ALL.into_iter().enumerate() {
        let raw: Vec<f32> = (0..kind.n_raw() + kind.n_object()).map(|i| ((i * 37 + k * 11) % 17) as f32 * 0.25 - 2.0).collect();
        lines.push(format!("raw {k} {}|", raw.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ")));
        expect.push(Box::new(Parametric::from_raw(kind, &raw[..kind.n_raw()], &raw[kind.n_raw()..])));
    }
    let mut bufs = Vec::new();
    let model = model_bytes(ModelKind::SingleMlp, Reciprocity::Exact, PositionEncoding::Uniform, true);
    std::fs::write(dir.join("model.nbrdf"), &model).unwrap();
    lines.push(format!("file {}|", dir.join("model.nbrdf").display()));
    bufs.push(ModelBuf::from_bytes(&model).unwrap());
    let f16 = ModelBuf::from_bytes(&model_bytes(ModelKind::AdditiveShared, Reciprocity::Exact, PositionEncoding::Uniform, true))
        .unwrap()
        .model()
        .to_f16()
        .unwrap();
    std::fs::write(dir.join("model16.nbrdf"), &f16).unwrap();
    lines.push(format!("borrow {}|", dir.join("model16.nbrdf").display()));
    bufs.push(ModelBuf::from_bytes_as_is(&f16).unwrap());
    let varying = model_bytes(
        ModelKind::Parametric(ParametricKind::Disney),
        Reciprocity::None,
        PositionEncoding::Extrinsic { frequencies: 2 },
        false,
    );
    std::fs::write(dir.join("varying.nbrdf"), &varying).unwrap();
    lines.push(format!("file {}|0.1 -0.2 0.3", dir.join("varying.nbrdf").display()));
    bufs.push(ModelBuf::from_bytes(&varying).unwrap());
    // An energy-bounded model (a version-2 file): a table above 1 in some cells and channels, so that
    // a value divided by the wrong cell shows.
    let mut bound = AlbedoBound { cells: [[0.0; 3]; ALBEDO_CELLS] };
    for (j, c) in bound.cells.iter_mut().enumerate() {
        let t = j as f32 / (ALBEDO_CELLS - 1) as f32;
        *c = [0.6 + 1.2 * t, 1.8 - 1.1 * t, if j % 3 == 0 { 2.5 } else { 0.7 }];
    }
    let bounded = set_albedo_bound(&model, Some(bound)).unwrap();
    std::fs::write(dir.join("bounded.nbrdf"), &bounded).unwrap();
    lines.push(format!("file {}|", dir.join("bounded.nbrdf").display()));
    bufs.push(ModelBuf::from_bytes(&bounded).unwrap());
    let points: [&[f32]; 4] = [&[], &[], &[0.1, -0.2, 0.3], &[]];
    // The model cases' Rust twins are made after `bufs` is complete (they borrow it).
    let json = r#"{"input": "rusinkiewicz_half_diff_vectors", "output": "expm1_clamped", "layers": [
        {"inputs": 6, "outputs": 4, "activation": "relu",
         "weight": [[0.5,-0.2,0.3,0.1,0.4,-0.3],[0.1,0.6,-0.2,0.3,-0.1,0.2],[-0.4,0.2,0.5,0.2,0.1,0.3],[0.2,0.2,0.2,-0.5,0.3,0.1]],
         "bias": [0.1, 0.2, -0.1, 0.3]},
        {"inputs": 4, "outputs": 3, "activation": "none",
         "weight": [[0.6,0.2,-0.3,0.4],[0.1,0.5,0.2,-0.2],[0.3,-0.1,0.4,0.2]], "bias": [0.2, 0.1, 0.3]}]}"#;
    std::fs::write(dir.join("net.json"), json).unwrap();
    lines.push(format!("file {}|", dir.join("net.json").display()));
    let table = MerlTable::tabulate(|wi, wo| Builtin::ClearCoat.eval(wi, wo));
    table.write(dir.join("table.binary")).unwrap();
    lines.push(format!("file {}|", dir.join("table.binary").display()));

    // What the error paths read.
    std::fs::write(dir.join("truncated.nbrdf"), &model[..model.len() / 2]).unwrap();
    let mut version = model.clone();
    version[8..12].copy_from_slice(&99u32.to_le_bytes());
    std::fs::write(dir.join("version.nbrdf"), version).unwrap();
    std::fs::write(dir.join("model.obj"), "v 0 0 0\n").unwrap();
    std::fs::write(dir.join("cases.txt"), lines.join("\n") + "\n").unwrap();

    let mut tail: Vec<Box<dyn Brdf>> = vec![Box::new(NbrdfNetwork::load(dir.join("net.json")).unwrap()), Box::new(table)];
    // Leak the buffers into 'static twins: the test process ends right after.
    let leaked: &'static [ModelBuf] = Box::leak(bufs.clone().into_boxed_slice());
    for (buf, p) in leaked.iter().zip(points) {
        expect.push(Box::new(buf.model().at(p).unwrap()));
    }
    expect.append(&mut tail);
    (expect, bufs)
}

/// Checks the values a program wrote (`out-i.f32`) against the Rust API, bit for bit.
fn compare(dir: &Path, expect: &[Box<dyn Brdf>], pairs: &[(Vec3, Vec3, [f32; 3])], program: &str) {
    for (i, brdf) in expect.iter().enumerate() {
        let bytes = std::fs::read(dir.join(format!("out-{i}.f32"))).unwrap_or_else(|e| panic!("{program}: case {i}: {e}"));
        let got: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        assert_eq!(got.len(), 15 * pairs.len(), "{program}: case {i}");
        for (k, &(wi, wo, u)) in pairs.iter().enumerate() {
            let o = &got[15 * k..15 * k + 15];
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let f = brdf.eval(wi, wo);
            assert_eq!(bits(&o[0..3]), bits(&f), "{program}: case {i}, pair {k}: eval");
            assert_eq!(bits(&o[3..6]), bits(&f), "{program}: case {i}, pair {k}: eval_many");
            match brdf.sample(wo, u) {
                Some(s) => {
                    assert_eq!(bits(&o[6..9]), bits(&s.wi.to_array()), "{program}: case {i}, pair {k}: sample wi");
                    assert_eq!(bits(&o[9..12]), bits(&s.weight), "{program}: case {i}, pair {k}: sample weight");
                    assert_eq!(o[12].to_bits(), s.pdf.to_bits(), "{program}: case {i}, pair {k}: sample pdf");
                    assert_eq!(o[13].to_bits(), brdf.pdf(s.wi, wo).to_bits(), "{program}: case {i}, pair {k}: pdf at the sample");
                }
                None => assert_eq!(bits(&o[6..13]), vec![0; 7], "{program}: case {i}, pair {k}: no sample"),
            }
            assert_eq!(o[14].to_bits(), brdf.pdf(wi, wo).to_bits(), "{program}: case {i}, pair {k}: pdf");
        }
    }
}

/// Runs one program on freshly written cases and compares its values.
fn run(source: &str, cpp: bool, flags: &[&str]) {
    let dir = scratch(source);
    let pairs = pairs();
    let flat: Vec<u8> = pairs.iter().flat_map(|(wi, wo, u)| [wi.to_array(), wo.to_array(), *u].concat()).flat_map(f32::to_le_bytes).collect();
    std::fs::write(dir.join("pairs.f32"), flat).unwrap();
    let (expect, _bufs) = write_cases(&dir);
    let Some(exe) = compile(source, cpp, flags, &dir) else { return };
    // `NBRDF_CAPI_RUNNER` runs the program under a checker, e.g. "valgrind --error-exitcode=1" (.ci/run).
    let runner = std::env::var("NBRDF_CAPI_RUNNER").unwrap_or_default();
    let mut words = runner.split_whitespace();
    let mut cmd = match words.next() {
        Some(tool) => {
            let mut c = Command::new(tool);
            c.args(words).arg(&exe);
            c
        }
        None => Command::new(&exe),
    };
    // Under a checker: memory errors only; the checker's CPU model may pick another kernel level,
    // whose rounding differs from this process's, and its slowness skips the chi-square test.
    if !runner.is_empty() {
        cmd.arg("quick");
    }
    let out = cmd.arg(&dir).output().unwrap();
    assert!(
        out.status.success(),
        "{source} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if runner.is_empty() {
        compare(&dir, &expect, &pairs, source);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn c99_program_gets_the_rust_values_and_every_error() {
    run("api_test.c", false, &["-std=c99", "-Wall", "-Wextra", "-Werror"]);
}

#[test]
fn cpp17_header_gets_the_rust_values_and_throws_on_errors() {
    run("api_test.cpp", true, &["-std=c++17", "-Wall", "-Wextra", "-Werror"]);
}
