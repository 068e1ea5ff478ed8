//! The study end to end on a tiny config: one small scene, a parametric and a neural model, very few
//! steps. Checks that the report has every table, that the numbers are the ones the metrics promise
//! (reciprocity exactly 0 for RP and the Θ mapping, finite image metrics), and that a rerun reuses the
//! finished jobs instead of fitting again.

use trainer::study::{self, ModelSpec, SceneConfig, StudyConfig};

fn tiny() -> StudyConfig {
    StudyConfig {
        scenes: vec![SceneConfig { mesh: "sphere".into(), material: "two-lobe-metal".into() }],
        models: vec![
            ModelSpec { model: "rp".into(), enhanced: false, direction_layers: None },
            ModelSpec { model: "single-mlp".into(), enhanced: false, direction_layers: None },
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
        ..StudyConfig::default_small()
    }
}

#[test]
fn tiny_study_writes_every_table_and_reuses_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let config = tiny();
    let results = study::run_and_report(&config, &out, None, false).unwrap();
    assert_eq!(results.len(), 2);
    for r in &results {
        let e = &r.eval;
        assert!(e.image.psnr.is_finite() && e.image.psnr > 5.0, "{}: {:?}", r.model, e.image);
        assert!(e.image.dssim >= 0.0 && e.image.flip > 0.0 && e.image.views == 2);
        assert!(e.brdf_rmse_cbrt.value.is_finite() && e.brdf_rmse_cbrt.samples > 0);
        // RP is symmetric in its arguments, and the exact Θ mapping makes the MLP's input symmetric.
        assert_eq!(e.reciprocity_rmse, 0.0, "{}", r.model);
        assert_eq!(e.energy.pairs, 4);
        assert!(e.eval_ns_per_query > 0.0 && r.size_bytes > 0 && r.train_wall_s > 0.0);
    }
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    for heading in ["## Tab. 1", "## Tab. 3", "## Tab. 4", "## Accuracy versus cost"] {
        assert!(report.contains(heading), "missing {heading}:\n{report}");
    }
    for r in &results {
        assert!(report.matches(&format!("| {} |", r.model)).count() == 4, "{} not in every table", r.model);
    }
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["jobs"].as_array().unwrap().len(), 2);

    // A rerun finds both results and fits nothing: the model files stay untouched.
    let model_file = |name: &str| {
        std::fs::read_dir(study::job_dir(&out, &config.scenes[0], name))
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.extension().is_some_and(|x| x == "nbrdf"))
            .unwrap()
    };
    let before = std::fs::metadata(model_file(&results[1].model)).unwrap().modified().unwrap();
    let again = study::run_and_report(&config, &out, None, false).unwrap();
    // Read back from result.json (serde_json's float parsing may differ in the last bit).
    assert!((again[1].train_wall_s - results[1].train_wall_s).abs() <= 1e-9 * results[1].train_wall_s);
    assert_eq!(std::fs::metadata(model_file(&results[1].model)).unwrap().modified().unwrap(), before);

    // Shards split the jobs between processes without overlap.
    let s0 = study::run(&config, &out, Some("0/2".parse().unwrap()), false).unwrap();
    let s1 = study::run(&config, &out, Some("1/2".parse().unwrap()), false).unwrap();
    assert_eq!((s0.len(), s1.len()), (1, 1));
    assert_ne!(s0[0].model, s1[0].model);

    // Shards run into separate folders and merged give the same jobs as one run.
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    study::run_and_report(&config, &a, Some("0/2".parse().unwrap()), false).unwrap();
    study::run_and_report(&config, &b, Some("1/2".parse().unwrap()), false).unwrap();
    let (merged_config, merged) = study::report::merge(&[a, b]).unwrap();
    assert_eq!(merged_config, config);
    let names = |r: &[study::JobResult]| r.iter().map(|j| j.model.clone()).collect::<Vec<_>>();
    assert_eq!(names(&merged), names(&results));
}
