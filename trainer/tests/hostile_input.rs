//! Malformed inputs against every trainer command (`synth`, `inspect`, `fit`, `study`), each written
//! by the test: the run exits 1, the message names the file and the field (or the flag or config key)
//! and the value, and an output that existed before is byte for byte the same afterwards. Also what
//! used to pass silently: NaN pixels are counted, and a model records the mesh it was fitted on.

use std::path::{Path, PathBuf};
use std::process::Command;

use trainer::dataset::synth::{synthesize, SynthArgs};

mod common;
use common::snapshot;

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, &dest).unwrap();
        }
    }
}

/// A data set of 2 views (view 1 trains), 16×16 pixels.
fn tiny_data_set(out: &Path) {
    let args = SynthArgs {
        material: "lambert:0.5".into(),
        size: 16,
        views: 2,
        train_views: 1,
        train_lights: 2,
        test_lights: 1,
        quiet: true,
        ..SynthArgs::new(out)
    };
    synthesize(&args).unwrap();
}

/// One malformed run: the arguments, the strings its message must hold, the folder it must leave as
/// it was.
struct Case {
    args: Vec<String>,
    names: Vec<String>,
    keep: PathBuf,
}

fn case(args: &[&str], names: &[&str], keep: &Path) -> Case {
    Case { args: args.iter().map(|s| s.to_string()).collect(), names: names.iter().map(|s| s.to_string()).collect(), keep: keep.into() }
}

fn check(cases: &[Case]) {
    for c in cases {
        let before = snapshot(&c.keep);
        let out = Command::new(env!("CARGO_BIN_EXE_trainer")).args(&c.args).output().unwrap();
        let message = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{:?}: exit status; {message}", c.args);
        for name in &c.names {
            assert!(message.contains(name.as_str()), "{:?}: the message names {name:?}: {message}", c.args);
        }
        assert_eq!(snapshot(&c.keep), before, "{:?}: {} is unchanged", c.args, c.keep.display());
    }
}

fn edit_json(path: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(path, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
}

/// `bytes` (JSON, compact or pretty) with an invalid UTF-8 byte inside the first string value.
fn with_invalid_utf8(bytes: &[u8]) -> Vec<u8> {
    let colon = bytes.iter().position(|&c| c == b':').unwrap();
    let quote = colon + bytes[colon..].iter().position(|&c| c == b'"').unwrap();
    let mut b = bytes.to_vec();
    b.insert(quote + 1, 0xff);
    b
}

#[test]
fn synth_and_inspect_name_the_file_the_field_and_the_value() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let good = d.join("good");
    tiny_data_set(&good);

    // Material and mesh files with wrong content.
    let utf8 = d.join("bad-utf8.json");
    std::fs::write(&utf8, b"{\"name\": \"\xff\", \"layers\": []}").unwrap();
    // A 6-4-3 NBRDF-json network with a weight beyond f32 (1e39).
    let overflow = d.join("overflow.json");
    let net = serde_json::json!({
        "input": "rusinkiewicz_half_diff_vectors",
        "output": "expm1_clamped",
        "layers": [
            {"inputs": 6, "outputs": 4, "activation": "relu", "weight": vec![vec![0.1; 6]; 4], "bias": vec![0.0; 4]},
            {"inputs": 4, "outputs": 3, "activation": "none", "weight": vec![vec![0.2; 4]; 3], "bias": vec![-0.1; 3]},
        ]
    });
    std::fs::write(&overflow, net.to_string().replacen("0.2", "1e39", 1)).unwrap();
    let merl = d.join("huge.binary");
    let mut m = Vec::with_capacity(12 + 8 * 3 * 90 * 90 * 180);
    for n in [90i32, 90, 180] {
        m.extend_from_slice(&n.to_le_bytes());
    }
    for i in 0..3 * 90 * 90 * 180 {
        m.extend_from_slice(&(if i == 5 { 1e300f64 } else { 0.01 }).to_le_bytes());
    }
    std::fs::write(&merl, m).unwrap();
    let obj = d.join("no-faces.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    let endless = d.join("endless.json");
    std::os::unix::fs::symlink("/dev/zero", &endless).unwrap();
    let foreign = d.join("notes");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("mine.txt"), "not a data set").unwrap();

    let synth = |extra: &[&str]| {
        let mut a = vec!["synth", "--quiet", "--size", "16", "--views", "2", "--train-views", "1", "--train-lights", "1", "--test-lights", "1"];
        a.extend_from_slice(extra);
        a.iter().map(|x| x.to_string()).collect::<Vec<_>>()
    };
    let g = s(&good);
    let mut cases = vec![
        Case { args: synth(&["--out", &g, "--material", &s(&utf8)]), names: vec![s(&utf8), "UTF-8".into()], keep: good.clone() },
        Case { args: synth(&["--out", &g, "--material", &s(&overflow)]), names: vec![s(&overflow), "weight".into(), "NaN or infinite".into()], keep: good.clone() },
        Case { args: synth(&["--out", &g, "--material", &s(&merl)]), names: vec![s(&merl), "index 5".into(), "1e300".into()], keep: good.clone() },
        Case { args: synth(&["--out", &g, "--mesh", &s(&obj)]), names: vec![s(&obj), "triangles".into()], keep: good.clone() },
        // synth records the material by its canonical path: the link's target is named.
        Case { args: synth(&["--out", &g, "--material", &s(&endless)]), names: vec!["/dev/zero".into(), "bytes".into()], keep: good.clone() },
        Case { args: synth(&["--out", &g, "--sigma=-1"]), names: vec!["--sigma -1".into(), "non-negative".into()], keep: good.clone() },
        // No exposure reaches a median for a black material.
        Case {
            args: synth(&["--out", &g, "--material", "lambert:0,0,0", "--target-median", "0.2"]),
            names: vec!["--target-median".into(), "no object pixel receives light".into()],
            keep: good.clone(),
        },
        Case { args: synth(&["--out", &s(&foreign)]), names: vec![s(&foreign), "not a data set".into()], keep: foreign.clone() },
    ];

    // Data sets whose description is wrong in one field each.
    let variant = |name: &str, edit: &dyn Fn(&Path)| {
        let dir = d.join(name);
        copy_dir(&good, &dir);
        edit(&dir);
        dir
    };
    let not_utf8 = variant("not-utf8", &|dir| {
        let p = dir.join("dataset.json");
        std::fs::write(&p, with_invalid_utf8(&std::fs::read(&p).unwrap())).unwrap();
    });
    let rotation = variant("rotation", &|dir| edit_json(&dir.join("dataset.json"), |v| v["views"][1]["R"][0][0] = 3.0.into()));
    let light = variant("light", &|dir| {
        edit_json(&dir.join("dataset.json"), |v| v["views"][1]["images"][1]["light"]["direction"] = serde_json::json!([0.0, 0.0, 0.0]))
    });
    let missing = variant("missing-exr", &|dir| std::fs::remove_file(dir.join("views/01/001.exr")).unwrap());
    let small = variant("small-exr", &|dir| {
        let img = nbrdf_scene::image::RgbImage::from_data(8, 8, vec![[0.1; 3]; 64]).unwrap();
        nbrdf_scene::image::write_exr(dir.join("views/01/000.exr"), &img).unwrap();
    });
    for (dir, names) in [
        (&not_utf8, vec!["dataset.json", "UTF-8"]),
        (&rotation, vec!["dataset.json", "views[1]", "rotation"]),
        (&light, vec!["dataset.json", "views[1].images[1].light", "direction"]),
        (&missing, vec!["views/01/001.exr"]),
        (&small, vec!["view 1 image 0", "views/01/000.exr", "8x8"]),
    ] {
        cases.push(case(&["inspect", "--dataset", &s(dir)], &names, dir));
    }
    cases.push(case(&["inspect", "--dataset", &g, "--pixel-stride", "0"], &["--pixel-stride 0", "at least 1"], &good));
    check(&cases);
}

#[test]
fn fit_names_the_file_and_the_field_and_keeps_the_previous_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let good = d.join("good");
    tiny_data_set(&good);
    let bad = d.join("bad");
    copy_dir(&good, &bad);
    edit_json(&bad.join("dataset.json"), |v| v["views"][0]["R"][1][1] = (-2.0).into());

    // A previous fit that no failed run may touch.
    let prev = d.join("prev");
    let toy = ["fit", "--toy", "500", "--model", "lambert", "--position", "uniform", "--batch", "64"];
    let ok = Command::new(env!("CARGO_BIN_EXE_trainer")).args(toy).args(["--steps", "3", "--out"]).arg(&prev).output().unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let ckpt = prev.join("lambert.ckpt.json");

    // A copy whose checkpoint holds a NaN weight, one whose checkpoint is not UTF-8.
    let nan = d.join("nan");
    copy_dir(&prev, &nan);
    edit_json(&nan.join("lambert.ckpt.json"), |v| v["weights"][3] = f32::NAN.to_bits().into());
    let utf8 = d.join("utf8");
    copy_dir(&prev, &utf8);
    let p = utf8.join("lambert.ckpt.json");
    std::fs::write(&p, with_invalid_utf8(&std::fs::read(&p).unwrap())).unwrap();
    // Checkpoints that would resume into NaN or fail deep in the tensors: Adam's β1 beyond f32 (it
    // reads as infinite), a weight too few, a moment NaN.
    let checkpoint_variant = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let dir = d.join(name);
        copy_dir(&prev, &dir);
        edit_json(&dir.join("lambert.ckpt.json"), edit);
        dir
    };
    let beta = checkpoint_variant("beta", &|v| v["adam"]["params"]["beta1"] = serde_json::from_str("1e39").unwrap());
    let short = checkpoint_variant("short", &|v| {
        v["weights"].as_array_mut().unwrap().pop();
    });
    let moment = checkpoint_variant("moment", &|v| v["adam"]["v"][1][0] = f32::NAN.to_bits().into());
    // An existing file where fit writes a folder.
    let file_out = d.join("regular.txt");
    std::fs::write(&file_out, "notes").unwrap();
    // A data set whose cameras see the mesh at half the size their masks say: most masked pixels miss.
    let wide = d.join("wide");
    copy_dir(&good, &wide);
    edit_json(&wide.join("dataset.json"), |v| {
        for view in v["views"].as_array_mut().unwrap() {
            for i in 0..2 {
                view["K"][i][i] = (view["K"][i][i].as_f64().unwrap() * 0.5).into();
            }
        }
    });
    // The same variant name (parametric names leave the position input out), another position input.
    let other_position: Vec<String> = ["fit", "--toy", "500", "--model", "lambert", "--position", "extrinsic:2", "--batch", "64", "--resume", "--steps", "9", "--out"]
        .iter()
        .map(|x| x.to_string())
        .chain([s(&prev)])
        .collect();

    let fit = |out: &Path, extra: &[&str]| {
        let mut a: Vec<String> = toy.iter().map(|x| x.to_string()).collect();
        a.extend(["--out".to_string(), s(out)]);
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let data = |dir: &Path| {
        let mut a: Vec<String> = ["fit", "--model", "lambert", "--position", "uniform", "--steps", "2", "--batch", "64"].iter().map(|x| x.to_string()).collect();
        a.extend(["--data".into(), s(dir), "--out".into(), s(&prev)]);
        a
    };
    check(&[
        Case { args: fit(&beta, &["--resume", "--steps", "9"]), names: vec![s(&beta.join("lambert.ckpt.json")), "\"beta1\"".into(), "inf".into(), "[0, 1)".into()], keep: beta.clone() },
        Case { args: fit(&short, &["--resume", "--steps", "9"]), names: vec![s(&short.join("lambert.ckpt.json")), "\"weights\"".into(), "lambert has".into()], keep: short.clone() },
        Case { args: fit(&moment, &["--resume", "--steps", "9"]), names: vec![s(&moment.join("lambert.ckpt.json")), "\"v\" value 0".into(), "NaN".into()], keep: moment.clone() },
        Case { args: other_position, names: vec![s(&ckpt), "position encoding".into(), "uniform here, extrinsic:2 asked".into()], keep: prev.clone() },
        Case { args: fit(&file_out, &[]), names: vec!["--out".into(), s(&file_out), "not a folder".into()], keep: d.to_path_buf() },
        Case { args: fit(&prev, &["--pixel-stride", "0"]), names: vec!["--pixel-stride 0".into()], keep: prev.clone() },
        Case { args: data(&wide), names: vec![s(&wide.join("dataset.json")), "miss the mesh".into(), "view 1".into(), "cameras".into()], keep: prev.clone() },
        Case { args: fit(&prev, &["--resume", "--steps", "2"]), names: vec![s(&ckpt), "step 3".into(), "--steps 2".into()], keep: prev.clone() },
        Case { args: fit(&nan, &["--resume", "--steps", "9"]), names: vec![s(&nan.join("lambert.ckpt.json")), "weight 3".into(), "NaN".into()], keep: nan.clone() },
        Case { args: fit(&utf8, &["--resume", "--steps", "9"]), names: vec![s(&p), "UTF-8".into()], keep: utf8.clone() },
        Case { args: data(&bad), names: vec![s(&bad.join("dataset.json")), "views[0]".into()], keep: prev.clone() },
        Case { args: data(&d.join("absent")), names: vec![s(&d.join("absent"))], keep: prev.clone() },
    ]);
    let message = |args: &[String]| String::from_utf8_lossy(&Command::new(env!("CARGO_BIN_EXE_trainer")).args(args).output().unwrap().stderr).into_owned();
    assert!(!message(&fit(&nan, &["--resume", "--steps", "9"])).contains("last good"), "a NaN checkpoint is not good");
}

#[test]
fn study_blames_the_config_file_and_key_and_a_shard_never_takes_over_another_study() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let default = serde_json::to_value(trainer::study::StudyConfig::default_small()).unwrap();
    let config = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = default.clone();
        edit(&mut v);
        let p = d.join(name);
        std::fs::write(&p, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
        p
    };
    let good = config("good.json", &|_| {});
    let sigma = config("sigma.json", &|v| v["sigma"] = (-1.0).into());
    let batch = config("batch.json", &|v| v["batch"] = 0.into());
    let views = config("views.json", &|v| v["views"] = 100_000_000.into());
    let pairs = config("pairs.json", &|v| v["energy_pairs"] = 1_000_000_000_000u64.into());
    let position = config("position.json", &|v| v["position"] = "intrinsic:100000".into());
    let median = config("median.json", &|v| v["target_median"] = (-1.0).into());
    let lambda = config("lambda.json", &|v| v["lambda_diffuse"] = (-1.0).into());
    let samples = config("samples.json", &|v| v["energy_samples"] = 0.into());
    let typo = config("typo.json", &|v| v["models"][0]["modle"] = "rp".into());
    let strategy = config("strategy.json", &|v| v["models"][12]["reciprocity"] = "sideways".into());
    let layers = config("layers.json", &|v| v["models"][0] = serde_json::json!({ "model": "single-mlp", "enhanced": false, "direction_layers": 255 }));
    // A device that never ends, under a config's name.
    let endless = d.join("endless.json");
    std::os::unix::fs::symlink("/dev/zero", &endless).unwrap();
    let utf8 = d.join("utf8.json");
    std::fs::write(&utf8, with_invalid_utf8(&std::fs::read(&good).unwrap())).unwrap();

    // A finished unsharded study (its files as a run leaves them; what they say does not matter here).
    let done = d.join("done");
    std::fs::create_dir_all(&done).unwrap();
    let results = serde_json::json!({ "config": default, "summary": [], "jobs": [] });
    std::fs::write(done.join("results.json"), serde_json::to_vec_pretty(&results).unwrap()).unwrap();
    std::fs::write(done.join("REPORT.md"), "# the finished study\n").unwrap();
    // Shard 0/2 of the same config.
    let shard0 = d.join("shard0");
    std::fs::create_dir_all(&shard0).unwrap();
    std::fs::write(shard0.join("study-run.json"), serde_json::to_vec(&serde_json::json!({ "shard": "0/2", "config": default })).unwrap()).unwrap();
    std::fs::write(shard0.join("REPORT.md"), "# shard 0\n").unwrap();

    let study = |cfg: &Path, out: &Path, shard: Option<&str>| {
        let mut a = vec!["study".to_string(), "--config".into(), s(cfg), "--out".into(), s(out)];
        if let Some(sh) = shard {
            a.extend(["--shard".into(), sh.into()]);
        }
        a
    };
    let fresh = d.join("fresh");
    std::fs::create_dir_all(&fresh).unwrap();
    let blame = |cfg: &Path, key: &str, value: &str| Case {
        args: study(cfg, &fresh, None),
        names: vec![s(cfg), format!("\"{key}\""), value.to_string()],
        keep: fresh.clone(),
    };
    let cases = vec![
        blame(&sigma, "sigma", "-1"),
        blame(&batch, "batch", "0"),
        blame(&views, "views", "100000000"),
        blame(&pairs, "energy_pairs", "1000000000000"),
        blame(&position, "position", "1..=4096"),
        blame(&median, "target_median", "-1"),
        blame(&lambda, "lambda_diffuse", "-1"),
        blame(&samples, "energy_samples", "0"),
        Case { args: study(&typo, &fresh, None), names: vec![s(&typo), "models[0]".into(), "unknown field `modle`".into()], keep: fresh.clone() },
        Case { args: study(&strategy, &fresh, None), names: vec![s(&strategy), "\"models[12].reciprocity\"".into(), "\"sideways\"".into(), "none, swap or exact".into()], keep: fresh.clone() },
        Case { args: study(&layers, &fresh, None), names: vec![s(&layers), "models[0]".into(), "\"direction_layers\" 255".into(), "1..=6".into()], keep: fresh.clone() },
        Case { args: study(&endless, &fresh, None), names: vec![s(&endless), "bytes".into()], keep: fresh.clone() },
        Case { args: study(&utf8, &fresh, None), names: vec![s(&utf8), "UTF-8".into()], keep: fresh.clone() },
        Case { args: study(&good, &done, Some("0/2")), names: vec!["--shard 0/2".into(), "unsharded study".into(), "study merge".into()], keep: done.clone() },
        Case { args: study(&sigma.with_file_name("batch.json"), &shard0, Some("0/2")), names: vec!["\"batch\"".into()], keep: shard0.clone() },
    ];
    check(&cases);
    for c in &cases[..5] {
        let out = Command::new(env!("CARGO_BIN_EXE_trainer")).args(&c.args).output().unwrap();
        let m = String::from_utf8_lossy(&out.stderr);
        assert!(!m.contains("--sigma") && !m.contains("--batch") && !m.contains("--views"), "a config key is no flag: {m}");
    }
    // Another config into shard 0's folder is refused as well.
    let other = config("other.json", &|v| v["steps"] = 7.into());
    check(&[Case { args: study(&other, &shard0, Some("0/2")), names: vec!["another config".into()], keep: shard0.clone() }]);
}

/// NaN and infinite radiance pixels are dropped and counted (printed and in the log), not dropped
/// silently.
#[test]
fn non_finite_pixels_are_counted() {
    let tmp = tempfile::tempdir().unwrap();
    let ds = tmp.path().join("ds");
    tiny_data_set(&ds);
    // Every pixel of view 1's first image (view 1 trains) becomes NaN, and one of its second image inf.
    let first = ds.join("views/01/000.exr");
    let mut img = nbrdf_scene::image::read_exr(&first).unwrap();
    img.data.iter_mut().for_each(|p| *p = [f32::NAN; 3]);
    nbrdf_scene::image::write_exr(&first, &img).unwrap();
    let out = tmp.path().join("fit");
    let r = Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["fit", "--model", "lambert", "--position", "uniform", "--steps", "2", "--batch", "32", "--data"])
        .arg(&ds)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let message = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{message}");
    let log: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("lambert.log.json")).unwrap()).unwrap();
    let counted = log["filtered"]["non_finite"].as_u64().unwrap();
    assert!(counted > 0, "{log}");
    assert!(message.contains(&format!("filtered out {counted} non-finite")), "{message}");
}

/// A model fitted with a per-vertex table records the mesh (vertex count and content hash); the
/// renderer's check accepts that mesh and refuses another with as many vertices.
#[test]
fn a_model_records_its_mesh_and_refuses_another() {
    let tmp = tempfile::tempdir().unwrap();
    let ds = tmp.path().join("ds");
    tiny_data_set(&ds);
    let out = tmp.path().join("fit");
    let r = Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["fit", "--model", "lambert", "--position", "intrinsic:32", "--steps", "2", "--batch", "32", "--data"])
        .arg(&ds)
        .arg("--out")
        .arg(&out)
        .arg("--cache")
        .arg(tmp.path().join("cache"))
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let buf = nbrdf::ModelBuf::load(out.join("lambert.nbrdf")).unwrap();
    let sphere = nbrdf_scene::scene::builtin::BuiltinMesh::Sphere.mesh();
    assert_eq!(buf.header().n_vertices as usize, sphere.positions.len());
    assert_eq!(buf.header().mesh_hash, Some(sphere.content_hash()));
    let material = nbrdf_scene::pathtrace::Material::model(buf).unwrap();
    material.check_mesh(&sphere).unwrap();
    let mut moved = sphere.clone();
    moved.positions[0] *= 0.9;
    let err = material.check_mesh(&moved).unwrap_err().to_string();
    assert!(err.contains("another mesh") && err.contains(&format!("{:016x}", sphere.content_hash())), "{err}");
}

/// `study merge` names every job of the config that none of the joined folders has a result for,
/// instead of dropping its rows silently.
#[test]
fn study_merge_names_the_jobs_no_folder_holds() {
    let tmp = tempfile::tempdir().unwrap();
    let shard = tmp.path().join("shard");
    std::fs::create_dir_all(&shard).unwrap();
    let config = trainer::study::StudyConfig::default_small();
    let results = serde_json::json!({ "config": config, "summary": [], "jobs": [] });
    std::fs::write(shard.join("results.json"), serde_json::to_vec(&results).unwrap()).unwrap();
    let r = Command::new(env!("CARGO_BIN_EXE_trainer"))
        .args(["study", "--out"])
        .arg(tmp.path().join("merged"))
        .arg("merge")
        .arg(&shard)
        .output()
        .unwrap();
    let message = String::from_utf8_lossy(&r.stderr);
    let jobs = trainer::study::jobs(&config);
    assert_eq!(message.matches("no folder has a result for").count(), jobs.len(), "{message}");
    let scene = config.scenes[0].id();
    assert!(message.contains(&format!("{scene} / rp;")), "{message}");
}

/// `study merge` joins shards of one config only: folders of two configs would put unlike runs in one
/// table, so the merge is refused, naming both folders and the keys that differ, and writes nothing.
#[test]
fn study_merge_refuses_folders_of_two_configs() {
    let tmp = tempfile::tempdir().unwrap();
    let config = trainer::study::StudyConfig::default_small();
    let other = trainer::study::StudyConfig { steps: config.steps + 1, ..config.clone() };
    let folder = |name: &str, c: &trainer::study::StudyConfig| {
        let dir = tmp.path().join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let results = serde_json::json!({ "config": c, "summary": [], "jobs": [] });
        std::fs::write(dir.join("results.json"), serde_json::to_vec(&results).unwrap()).unwrap();
        dir
    };
    let (a, b) = (folder("a", &config), folder("b", &other));
    let merged = tmp.path().join("merged");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    check(&[Case {
        args: vec!["study".into(), "--out".into(), s(&merged), "merge".into(), s(&a), s(&b)],
        names: vec![s(&a), s(&b), "another config".into(), "\"steps\"".into()],
        keep: tmp.path().to_path_buf(),
    }]);
    assert!(!merged.exists());
}
