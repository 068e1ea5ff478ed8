//! The study end to end on a tiny config: one small scene, a parametric model, a neural one with the
//! exact Θ mapping, its Tab. 2 layer-count variant and its no-strategy Tab. 3 variant, very few steps.
//! Checks that the report has every table and figure, that the numbers are the ones the metrics promise
//! (reciprocity exactly 0 for RP and the Θ mapping and not for the unconstrained network, finite image
//! metrics, f16 copies of the neural models), and that a rerun reuses the finished jobs.

use trainer::study::{self, ModelSpec, SceneConfig, StudyConfig};

/// The model kind of a name, as a config names it.
fn kind(name: &str) -> trainer::models::Kind {
    trainer::names::parse_kind(name).unwrap()
}

fn tiny() -> StudyConfig {
    StudyConfig {
        scenes: vec![SceneConfig { mesh: "sphere".into(), material: "two-lobe-metal".into() }],
        models: vec![
            ModelSpec::new(kind("rp")),
            ModelSpec::new(kind("single-mlp")),
            ModelSpec { direction_layers: Some(3), ..ModelSpec::new(kind("single-mlp")) },
            ModelSpec { reciprocity: Some(trainer::models::Reciprocity::None), ..ModelSpec::new(kind("single-mlp")) },
        ],
        size: 40,
        views: 3,
        train_views: 2,
        train_lights: 3,
        test_lights: 2,
        steps: 10,
        batch: 512,
        pixel_stride: 2,
        reciprocity_pairs: 100,
        energy_pairs: 4,
        energy_samples: 100,
        // Bounding costs half a million evaluations per point: only the test of the bound pays it.
        energy_bound: false,
        ..StudyConfig::default_small()
    }
}

#[test]
fn tiny_study_writes_every_table_and_reuses_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let config = StudyConfig { energy_bound: true, ..tiny() };
    let results = study::run_and_report(&config, &out, None, false).unwrap();
    let names: Vec<&str> = results.iter().map(|r| r.model.as_str()).collect();
    assert_eq!(names, ["rp", "single-mlp+exact", "single-mlp+exact+nol3", "single-mlp"]);
    for r in &results {
        let e = &r.eval;
        assert!(e.image.psnr.is_finite() && e.image.psnr > 5.0, "{}: {:?}", r.model, e.image);
        assert!(e.image.dssim >= 0.0 && e.image.flip > 0.0 && e.image.views == 2);
        assert!(e.brdf_rmse_cbrt.value.is_finite() && e.brdf_rmse_cbrt.samples > 0);
        if r.model == "single-mlp" {
            // Nothing constrains an unmapped network to be reciprocal.
            assert!(e.reciprocity_rmse > 0.0, "{}", r.model);
        } else {
            // RP is symmetric in its arguments, and the exact Θ mapping makes the MLP's input symmetric.
            assert_eq!(e.reciprocity_rmse, 0.0, "{}", r.model);
        }
        assert_eq!(e.energy.pairs, 4);
        // The learning curve: step 0 and 20 points after it (10 steps: each step once), each with the
        // held-out PSNR, the training loss after step 0, and wall time that never goes back.
        let steps: Vec<usize> = r.curve.iter().map(|p| p.step).collect();
        assert_eq!(steps, (0..=10).collect::<Vec<_>>(), "{}", r.model);
        assert!(r.curve.iter().all(|p| p.test_psnr.is_some_and(f64::is_finite)), "{}", r.model);
        assert!(r.curve[0].train_loss.is_none() && r.curve[1..].iter().all(|p| p.train_loss.is_some()));
        assert!(r.curve.windows(2).all(|w| w[0].wall_s <= w[1].wall_s));
        // The curve's last PSNR is the evaluation's: the same renderings, scored the same way.
        let last = r.curve.last().unwrap().test_psnr.unwrap();
        assert!((last - e.image.psnr).abs() < 1e-6, "{}: curve {last} vs evaluation {}", r.model, e.image.psnr);
        // The data set was exposed like a capture: the lit pixels' median at the configured value
        // unless that would clip more than 10 % of them (both measured on a probe of four views, so the
        // whole data set lands near, not on, the bound).
        let x = r.exposure.expect("synth records the exposure");
        assert!(x.median_luminance > 0.01 && x.median_luminance < 0.3, "{}: {x:?}", r.model);
        assert!(x.saturated_share < 0.15, "{x:?}");
        assert!(e.eval_ns_per_query > 0.0 && r.size_bytes > 0 && r.train_wall_s > 0.0);
        assert!(e.eval_batch_ns_per_query.is_some_and(|ns| ns > 0.0), "{}: batched timing", r.model);
        // Neural models also get an f16 copy: smaller, and close to the f32 one in quality.
        match (&r.eval_f16, r.size_bytes_f16) {
            (Some(e16), Some(b16)) => {
                assert_ne!(r.model, "rp");
                assert!(b16 < r.size_bytes, "{}: f16 file {b16} B not smaller than {} B", r.model, r.size_bytes);
                assert!((e16.image.psnr - e.image.psnr).abs() < 1.0, "{}: {} vs {}", r.model, e16.image.psnr, e.image.psnr);
            }
            (None, None) => assert_eq!(r.model, "rp"),
            other => panic!("{}: f16 evaluation and size must come together, got {other:?}", r.model),
        }
        // Every fit is also scored energy-bounded: no pair above 1, reciprocity as it was (the divisor
        // is symmetric), and where the table stays under 1 the very same values.
        let b = r.eval_bounded.as_ref().expect("the default config scores the bounded copy");
        let max = r.albedo_bound_max.unwrap();
        assert!(max > 0.0 && max.is_finite(), "{}: largest Â {max}", r.model);
        assert_eq!(b.energy.share_above_one, 0.0, "{}: bounded {:?}", r.model, b.energy);
        assert_eq!(b.reciprocity_rmse == 0.0, e.reciprocity_rmse == 0.0, "{}", r.model);
        if max <= 1.0 {
            assert_eq!(b.image.psnr, e.image.psnr, "{}: a bound under 1 changes nothing", r.model);
        }
        let bounded_file = std::fs::read_dir(out.join("jobs")).unwrap().flatten().any(|scene| {
            scene.path().join(r.model.replace('+', "_")).join(format!("{}.bounded.nbrdf", r.model.replace('+', "_"))).exists()
        });
        assert!(bounded_file, "{}: the bounded model is kept beside the fit", r.model);
    }
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    for heading in ["## Tab. 1", "## Learning curves", "Exposure of the renders", "## Tab. 2", "## Tab. 3", "## Tab. 4", "## Energy bound", "## Accuracy versus cost", "## Renderings", "Reduced scale"] {
        assert!(report.contains(heading), "missing {heading}:\n{report}");
    }
    let section = |h: &str| {
        let start = report.find(h).unwrap();
        let rest = &report[start + h.len()..];
        rest[..rest.find("\n## ").unwrap_or(rest.len())].to_string()
    };
    let (t1, t2, t3, t4) = (section("## Tab. 1"), section("## Tab. 2"), section("## Tab. 3"), section("## Tab. 4"));
    // Tab. 1 and 4: the base rows only; Tab. 2: the layer-count variant against its base; Tab. 3: the
    // neural rows, the unconstrained one first.
    for m in ["rp", "single-mlp+exact"] {
        assert!(t1.contains(&format!("| {m} |")) && t4.contains(&format!("| {m} |")), "{m}:\n{t1}\n{t4}");
    }
    assert!(!t1.contains("| single-mlp |") && !t1.contains("nol3"));
    // The paper's numbers beside ours: the Single MLP's 52.35 dB PSNR, RP's 6.025 FLIP.
    assert!(t1.contains(" / 52.35 |") && t1.contains(" / 6.025 |"), "{t1}");
    assert!(t2.contains("| single-mlp+exact+nol3 | single-mlp+exact | sphere__two-lobe-metal |"), "{t2}");
    assert!(t3.find("| single-mlp |").unwrap() < t3.find("| single-mlp+exact |").unwrap(), "{t3}");
    assert!(!t3.contains("| rp |"));
    // Every variant in the accuracy-versus-cost table, the neural ones with an f16 row too.
    let cost = section("## Accuracy versus cost");
    for r in &results {
        let rows = cost.matches(&format!("| {} |", r.model)).count();
        assert_eq!(rows, if r.model == "rp" { 1 } else { 2 }, "{}:\n{cost}", r.model);
    }
    // A result.json written before the batched timing still loads (without it), and one written with
    // the deleted arithmetics' fields loads without them; a truncated one is a parse error (the study
    // then runs the job again).
    let mut old = serde_json::to_value(&results[1]).unwrap();
    let eval = old["eval"].clone();
    for field in ["eval_f16_half", "eval_split_bf16", "eval_split_bf16x6", "eval_bf16"] {
        old.as_object_mut().unwrap().insert(field.into(), eval.clone());
    }
    old["eval"].as_object_mut().unwrap().remove("eval_batch_ns_per_query");
    old["eval"].as_object_mut().unwrap().insert("single_in_arithmetic".into(), true.into());
    let loaded: study::JobResult = serde_json::from_value(old).unwrap();
    assert!(loaded.eval_f16.is_some());
    assert!(loaded.eval.eval_batch_ns_per_query.is_none());
    let json = serde_json::to_string(&results[1]).unwrap();
    assert!(serde_json::from_str::<study::JobResult>(&json[..json.len() / 2]).is_err());
    // One learning-curve figure per object, with a line per Tab. 1 variant.
    assert!(report.contains("figures/curves-sphere__two-lobe-metal.png"));
    let curves = image::open(out.join("figures/curves-sphere__two-lobe-metal.png")).unwrap().to_rgb8();
    assert_eq!(curves.dimensions(), (1400, 560));
    // The figures: Pareto plots and, per object, best parametric and best neural comparisons.
    for plot in ["figures/pareto-train.png", "figures/pareto-eval.png", "figures/pareto-eval-batch.png"] {
        assert!(report.contains(plot), "{plot} not linked");
        let img = image::open(out.join(plot)).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (900, 600));
        // Not blank: the front is drawn in red.
        assert!(img.pixels().any(|p| p.0 == [200, 40, 40]), "{plot} has no Pareto front");
    }
    let pngs: Vec<_> = std::fs::read_dir(out.join("figures")).unwrap().map(|e| e.unwrap().path()).collect();
    let flips: Vec<_> = pngs.iter().filter(|p| p.to_string_lossy().ends_with("-flip.png")).collect();
    assert_eq!(flips.len(), 2, "one parametric and one neural comparison: {pngs:?}");
    for f in flips {
        let map = image::open(f).unwrap().to_rgb8();
        let z = study::figures::ZOOM;
        assert_eq!(map.dimensions(), (40 * z, 40 * z));
        let pair = std::path::PathBuf::from(f.to_string_lossy().replace("-flip.png", ".png"));
        assert_eq!(image::open(&pair).unwrap().to_rgb8().dimensions(), (2 * 40 * z + 4, 40 * z), "{}", pair.display());
        let rel = pair.strip_prefix(&out).unwrap().to_string_lossy().into_owned();
        assert!(report.contains(&rel), "{rel} not linked");
    }
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    assert_eq!(csv.lines().count(), 5);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["jobs"].as_array().unwrap().len(), 4);

    // A rerun finds both results and fits nothing: the model files stay untouched.
    let model_file = |name: &str| study::job_dir(&out, &config.scenes[0], name).join(format!("{}.nbrdf", name.replace('+', "_")));
    let before = std::fs::metadata(model_file(&results[1].model)).unwrap().modified().unwrap();
    let again = study::run_and_report(&config, &out, None, false).unwrap();
    // Read back from result.json (serde_json's float parsing may differ in the last bit).
    assert!((again[1].train_wall_s - results[1].train_wall_s).abs() <= 1e-9 * results[1].train_wall_s);
    assert_eq!(std::fs::metadata(model_file(&results[1].model)).unwrap().modified().unwrap(), before);

    // A finished job whose model file was cut short is not reused: it runs again and its file loads.
    let cut = model_file(&results[0].model);
    let whole = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &whole[..100]).unwrap();
    let rerun = study::run(&config, &out, None, false).unwrap();
    nbrdf::ModelBuf::load(&cut).unwrap();
    assert_eq!(rerun.len(), results.len());

    // Shards split the jobs between processes without overlap.
    let s0 = study::run(&config, &out, Some("0/2".parse().unwrap()), false).unwrap();
    let s1 = study::run(&config, &out, Some("1/2".parse().unwrap()), false).unwrap();
    assert_eq!((s0.len(), s1.len()), (2, 2));
    assert!(s0.iter().all(|a| s1.iter().all(|b| a.model != b.model)));

    // Shards run into separate folders and merged give the same jobs as one run.
    let config = tiny();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    study::run_and_report(&config, &a, Some("0/2".parse().unwrap()), false).unwrap();
    study::run_and_report(&config, &b, Some("1/2".parse().unwrap()), false).unwrap();
    let shards = [a, b];
    let (merged_config, merged) = study::report::merge(&shards).unwrap();
    assert_eq!(merged_config, config);
    // The merged report renders its comparisons from the shard folders, as the single run did.
    let joined = dir.path().join("joined");
    let figs = study::comparisons(&config, &shards, &joined, &merged).unwrap();
    assert_eq!(figs.len(), 2, "one parametric and one neural comparison from the shards");
    assert!(figs.iter().all(|f| joined.join(&f.images).is_file() && joined.join(&f.flip_map).is_file()));
    let names = |r: &[study::JobResult]| {
        let mut n = r.iter().map(|j| j.model.clone()).collect::<Vec<_>>();
        n.sort();
        n
    };
    assert_eq!(names(&merged), names(&results));

    // Studies of one protocol on other scenes (one mesh per machine) merge into one report over every
    // scene; here a copy of shard `b` relabelled as another object stands for the second machine's run.
    let other = dir.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    let mut saved: serde_json::Value = serde_json::from_slice(&std::fs::read(shards[1].join("results.json")).unwrap()).unwrap();
    let scene = study::SceneConfig { mesh: "torus".into(), material: "clear-coat".into() };
    saved["config"]["scenes"] = serde_json::to_value([&scene]).unwrap();
    for job in saved["jobs"].as_array_mut().unwrap() {
        job["scene"] = scene.id().into();
    }
    std::fs::write(other.join("results.json"), serde_json::to_vec(&saved).unwrap()).unwrap();
    let (both, jobs) = study::report::merge(&[shards[0].clone(), shards[1].clone(), other]).unwrap();
    assert_eq!(both.scenes, [config.scenes[0].clone(), scene.clone()]);
    assert_eq!(jobs.len(), merged.len() + s1.len());
    assert!(jobs[..merged.len()].iter().all(|j| j.scene == config.scenes[0].id()), "config order: scene-major");
    assert!(jobs[merged.len()..].iter().all(|j| j.scene == scene.id()));
}

/// `results.json` without what depends on the machine's load: every field whose name says it is a
/// wall time or a timing (`train_wall_s`, `eval_ns_per_query`, `prepare_ns_per_point`, …).
fn without_timings(mut v: serde_json::Value) -> serde_json::Value {
    match &mut v {
        serde_json::Value::Object(map) => {
            map.retain(|k, _| !(k.contains("wall") || k.contains("_ns_per_")));
            for x in map.values_mut() {
                *x = without_timings(x.take());
            }
        }
        serde_json::Value::Array(items) => {
            for x in items.iter_mut() {
                *x = without_timings(x.take());
            }
        }
        _ => {}
    }
    v
}

/// `a == b` but for numbers, which may differ by serde_json's parsing (not correctly rounded without
/// its `float_roundtrip` feature: a merged mean of values read back can move in the last bits).
fn assert_close(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
    use serde_json::Value::*;
    match (a, b) {
        (Number(x), Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!((x - y).abs() <= 1e-12 * x.abs().max(y.abs()), "{at}: {x} vs {y}");
        }
        (Object(x), Object(y)) => {
            assert_eq!(x.keys().collect::<Vec<_>>(), y.keys().collect::<Vec<_>>(), "{at}");
            for (k, v) in x {
                assert_close(v, &y[k], &format!("{at}.{k}"));
            }
        }
        (Array(x), Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (v, w)) in x.iter().zip(y).enumerate() {
                assert_close(v, w, &format!("{at}[{i}]"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

/// Scale-out as `scripts/study-slurm.sh` does it, with a stand-in `sbatch` that runs each array task in
/// turn (with its `SLURM_ARRAY_TASK_ID`) and then the merge job: the shards synthesize their own copies
/// of the data set and fit their jobs in separate processes, and the merged `results.json` must equal
/// that of one unsharded run in everything but timings. Synthesis, training and evaluation are
/// deterministic (fixed seeds), so the metrics agree to the last bits a JSON round trip can move.
#[cfg(unix)]
#[test]
fn sharded_by_the_slurm_script_and_merged_equals_one_unsharded_run() {
    use std::os::unix::fs::PermissionsExt;
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let config = StudyConfig { models: vec![ModelSpec::new(kind("rp")), ModelSpec::new(kind("single-mlp"))], ..tiny() };
    let config_path = dir.path().join("config.json");
    std::fs::write(&config_path, serde_json::to_vec_pretty(&config).unwrap()).unwrap();
    let trainer = env!("CARGO_BIN_EXE_trainer");

    let one = dir.path().join("one");
    let status = Command::new(trainer).args(["study", "--config"]).arg(&config_path).arg("--out").arg(&one).status().unwrap();
    assert!(status.success(), "unsharded run: {status}");

    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(
        &sbatch,
        r#"#!/usr/bin/env bash
# Stand-in for Slurm's sbatch: runs the job now (every array task in turn), prints a job id.
array=
while [ "${1#--}" != "$1" ]; do
    case $1 in --array=*) array=${1#--array=} ;; esac
    shift
done
if [ -n "$array" ]; then
    for i in $(seq "${array%-*}" "${array#*-}"); do SLURM_ARRAY_TASK_ID=$i bash "$@" >&2 || exit 1; done
else
    bash "$@" >&2 || exit 1
fi
echo 4242
"#,
    )
    .unwrap();
    std::fs::set_permissions(&sbatch, std::fs::Permissions::from_mode(0o755)).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/study-slurm.sh");
    let sharded = dir.path().join("sharded");
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let out = Command::new("bash")
        .arg(script)
        .arg(&config_path)
        .arg(&sharded)
        .arg("2")
        .arg("--time=00:10:00")
        .env("PATH", path)
        .env("TRAINER", trainer)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "script: {said}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(said.contains("array job 4242") && said.contains("merge job 4242"), "{said}");

    let read = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(d.join("results.json")).unwrap()).unwrap()
    };
    // Each shard ran one of the two jobs, each into its own folder.
    for (i, model) in ["rp", "single-mlp+exact"].iter().enumerate() {
        let shard = read(&sharded.join(format!("shard-{i}")));
        let jobs = shard["jobs"].as_array().unwrap();
        assert_eq!(jobs.len(), 1, "shard {i}");
        assert_eq!(jobs[0]["model"], *model, "shard {i}");
    }
    let (single, merged) = (read(&one), read(&sharded));
    assert_eq!(merged["jobs"].as_array().unwrap().len(), 2);
    assert!(merged["jobs"][1]["eval"]["image"]["psnr"].as_f64().unwrap() > 5.0, "a real fit, not a blank");
    assert_close(&without_timings(merged), &without_timings(single), "results.json");
    assert!(sharded.join("REPORT.md").is_file());
    // Joined in any folder order, the jobs come out in the config's order, as one run lists them.
    let (_, reversed) = study::report::merge(&[sharded.join("shard-1"), sharded.join("shard-0")]).unwrap();
    assert_eq!(reversed.iter().map(|r| r.model.as_str()).collect::<Vec<_>>(), ["rp", "single-mlp+exact"]);
}

/// A semi-synthetic data set of a Lambertian sphere (albedo 0.5) with noise, and a model file that
/// is that material exactly: a parametric Lambert network whose weights are all zero predicts
/// `sigmoid(0) = 0.5` everywhere.
fn lambert_scene_and_its_perfect_model(dir: &std::path::Path) -> (trainer::dataset::Dataset, std::path::PathBuf) {
    use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
    use nbrdf::parametric::ParametricKind;
    use trainer::dataset::synth::{synthesize, SynthArgs};
    let data = dir.join("data");
    let args = SynthArgs {
        material: "lambert:0.5".into(),
        size: 24,
        views: 3,
        train_views: 1,
        train_lights: 2,
        test_lights: 2,
        sigma: 0.01,
        quiet: true,
        ..SynthArgs::new(&data)
    };
    synthesize(&args).unwrap();
    let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::Lambert), false, Reciprocity::None, PositionEncoding::Uniform, 2);
    let path = dir.join("perfect.nbrdf");
    std::fs::write(&path, encode(&h, &vec![0.0; h.n_weights()], None).unwrap()).unwrap();
    (trainer::dataset::Dataset::open(&data).unwrap(), path)
}

#[test]
fn a_perfect_model_scores_infinity_against_the_clean_reference_and_the_ceiling_against_the_capture() {
    let dir = std::env::temp_dir().join(format!("nbrdf-clean-ref-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (ds, perfect) = lambert_scene_and_its_perfect_model(&dir);
    let lpips: Result<trainer::metrics::Lpips, String> = Err("n/a: not needed here".into());
    let eval = study::evaluate::evaluate(&ds, &perfect, &lpips, &tiny()).unwrap();
    assert_eq!(eval.reference, study::evaluate::Reference::Clean);
    assert_eq!(eval.image.psnr, f64::INFINITY, "the clean reference is the ground truth's own render");
    assert_eq!(eval.image.flip, 0.0);
    // Against the noisy capture the perfect model reads exactly the ceiling: clean vs. captured.
    let ceiling = study::evaluate::ceiling(&ds, &lpips).unwrap().expect("a ground truth");
    let captured = eval.captured_psnr.expect("scored against the capture too");
    assert!(captured.is_finite() && captured > 20.0, "σ = 0.01 leaves a finite ceiling: {captured}");
    assert!((captured - ceiling.psnr).abs() < 1e-9, "{captured} vs ceiling {}", ceiling.psnr);
    // The learning curve's probe scores against the clean reference as well.
    let views = study::evaluate::TestViews::load(&ds).unwrap();
    assert_eq!(views.psnr(&std::fs::read(&perfect).unwrap()).unwrap(), f64::INFINITY);
    std::fs::remove_dir_all(&dir).unwrap();
}
