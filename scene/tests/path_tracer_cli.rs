//! The path tracer example (`scene/examples/path_tracer.rs`) against malformed command lines and files,
//! each written by the test: the run exits 1, the message names the flag or file and the value, and
//! an output file that existed before is byte for byte the same afterwards.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The example binary `cargo test` builds beside the test binaries (`target/<profile>/examples`).
fn path_tracer() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let profile_dir = exe.parent()?.parent()?;
    let bin = profile_dir.join("examples").join(format!("path_tracer{}", std::env::consts::EXE_SUFFIX));
    bin.is_file().then_some(bin)
}

#[test]
fn malformed_input_exits_1_names_the_flag_or_file_and_keeps_the_previous_render() {
    let Some(bin) = path_tracer() else {
        println!("SKIPPED: the path_tracer example is not built beside this test (run `cargo test -p nbrdf-scene`, which builds examples)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("render.exr");
    let before = b"an earlier render".to_vec();
    std::fs::write(&out, &before).unwrap();
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let bad_obj = write("broken.obj", b"v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    let bad_model = write("garbage.nbrdf", b"not a model file at all");
    let bad_json = write("weights.json", b"{\"layers\": [");
    let bad_env = write("sky.exr", b"not an exr");
    let endless = d.join("endless.json");
    std::os::unix::fs::symlink("/dev/zero", &endless).unwrap();
    let s = |p: &Path| p.display().to_string();
    // (arguments, what the message must contain)
    let cases: Vec<(Vec<String>, Vec<String>)> = vec![
        (vec!["--width".into(), "4294967295".into()], vec!["width".into(), "4294967295".into()]),
        (vec!["--width".into(), "100000".into(), "--height".into(), "100000".into()], vec!["100000".into()]),
        (vec!["--spp".into(), "4294967295".into()], vec!["--spp".into(), "4294967295".into()]),
        (vec!["--mesh".into(), s(&d.join("missing.obj"))], vec!["missing.obj".into()]),
        (vec!["--mesh".into(), s(&bad_obj)], vec!["broken.obj".into()]),
        (vec!["--brdf".into(), format!("model:{}", s(&bad_model))], vec!["garbage.nbrdf".into()]),
        (vec!["--brdf".into(), format!("json:{}", s(&bad_json))], vec!["weights.json".into()]),
        (vec!["--brdf".into(), "lambert:0.5,nan,0.5".into()], vec!["lambert".into()]),
        (vec!["--env".into(), s(&bad_env)], vec!["--env".into(), "sky.exr".into()]),
        (vec!["--sampling".into(), "psychic".into()], vec!["psychic".into()]),
        // Numbers with no image to give: refused, never rounded up to one sample or one bounce.
        (vec!["--spp".into(), "0".into()], vec!["--spp 0".into(), "1..=".into()]),
        (vec!["--max-depth".into(), "0".into()], vec!["--max-depth 0".into(), "direct lighting".into()]),
        (vec!["--exposure".into(), "nan".into()], vec!["--exposure NaN".into(), "finite".into()]),
        (vec!["--exposure=-1".into()], vec!["--exposure -1".into(), "> 0".into()]),
        (vec!["--light".into(), "nan,1,1".into()], vec!["--light nan,1,1".into(), "finite".into()]),
        (vec!["--light".into(), "0,1,1:1,-1,1".into()], vec!["--light 0,1,1:1,-1,1".into(), "intensity".into()]),
        // A degenerate pose is blamed on the pose's flags, not on the image size.
        (vec!["--eye".into(), "0,0,0".into(), "--target".into(), "0,0,0".into()], vec!["--eye".into(), "coincide".into()]),
        (vec!["--eye".into(), "0,3,0".into(), "--up".into(), "0,1,0".into()], vec!["--up".into(), "parallel".into()]),
        // Files that never end are read no further than their format's largest size.
        (vec!["--brdf".into(), format!("json:{}", s(&endless))], vec!["endless.json".into(), "bytes".into()]),
        (vec!["--brdf".into(), "merl:/dev/zero".into()], vec!["/dev/zero".into(), "bytes".into()]),
        (vec!["--fov".into(), "180".into()], vec!["--fov 180".into(), "(0, 180)".into()]),
        (vec!["--env-color".into(), "1,-1,1".into()], vec!["--env-color".into(), "≥ 0".into()]),
    ];
    for (args, needles) in cases {
        let mut cmd = Command::new(&bin);
        cmd.args(&args).args(["--light", "0,1,1", "--out"]).arg(&out).args(["--width", "16", "--height", "16"].iter().filter(|_| !args.iter().any(|a| a.starts_with("--width"))));
        if !args.iter().any(|a| a == "--spp") {
            cmd.args(["--spp", "1"]);
        }
        let run = cmd.output().unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}\n{stderr}");
        for n in &needles {
            assert!(stderr.contains(n.as_str()), "{args:?}: the message does not name {n:?}:\n{stderr}");
        }
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert_eq!(std::fs::read(&out).unwrap(), before, "{args:?} changed the earlier render");
    }
}

/// `--out x.exr` also writes `x.png`: both paths are checked before rendering, so a PNG path that is a
/// folder leaves the earlier EXR as it was; a good run replaces both and leaves no temporary file.
#[test]
fn both_outputs_are_checked_before_the_first_write() {
    let Some(bin) = path_tracer() else {
        println!("SKIPPED: the path_tracer example is not built beside this test");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("x.exr");
    std::fs::write(&exr, b"an earlier render").unwrap();
    std::fs::create_dir(dir.path().join("x.png")).unwrap();
    let render = |out: &Path| Command::new(&bin).args(["--light", "0,1,1", "--width", "8", "--height", "8", "--spp", "1", "--out"]).arg(out).output().unwrap();
    let run = render(&exr);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("x.png") && stderr.contains("is a folder") && stderr.contains("--out"), "{stderr}");
    assert_eq!(std::fs::read(&exr).unwrap(), b"an earlier render");

    std::fs::remove_dir(dir.path().join("x.png")).unwrap();
    let run = render(&exr);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(nbrdf_scene::image::read_exr(&exr).unwrap().width, 8);
    assert!(dir.path().join("x.png").is_file());
    let names: Vec<String> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names.len(), 2, "only the EXR and the PNG: {names:?}");
}
