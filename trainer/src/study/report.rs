//! The study's report: per-model means over the objects in the layout of the paper's tables (Tab. 1
//! image and BRDF metrics, Tab. 2 direction-layer ablation as differences to Tab. 1, Tab. 3
//! reciprocity, Tab. 4 energy, and accuracy against cost with f32 and f16 weights and its Pareto
//! plots), plus every per-job number in `results.json` and `results.csv`.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::config::is_parametric;
use crate::names::{position_name, reciprocity_name};
use super::figures::{self, Comparison, CostPoint};
use super::{Evaluation, JobResult, StudyConfig};
use crate::{Error, Result};

/// Per-model means over the objects (scenes); fields as in [`JobResult`].
#[derive(Clone, Debug, Serialize)]
pub struct ModelSummary {
    pub model: String,
    pub objects: usize,
    pub psnr: f64,
    pub dssim: f64,
    /// `None` when LPIPS was not available for some object (the reason is in `results.json`).
    pub lpips: Option<f64>,
    pub flip: f64,
    pub brdf_rmse_cbrt: f64,
    pub reciprocity_rmse: f64,
    /// Share (0–1) of point-light pairs whose albedo is significantly above 1.
    pub energy_share_above_one: f64,
    /// Mean over objects of the median violating albedo; `None` when no object violates.
    pub energy_median_above_one: Option<f64>,
    /// Smallest excess over 1 the energy test can see for a typical pair: `z` times the mean standard
    /// error of the albedo estimates, averaged over objects.
    pub energy_detectable_excess: f64,
    /// Mean worst-channel albedo over the pairs, averaged over objects.
    pub energy_mean_albedo: f64,
    pub train_wall_s: f64,
    pub eval_ns_per_query: f64,
    /// Batched evaluation ns per query (`None` unless every object has it).
    pub eval_batch_ns_per_query: Option<f64>,
    /// `prepare` and `prepare_many` ns per shading point (`None` unless every object has it).
    pub prepare_ns_per_point: Option<f64>,
    pub prepare_many_ns_per_point: Option<f64>,
    pub n_weights: usize,
    pub size_bytes: u64,
    /// The f16-weight copies (purely neural models; `None` when some object has none).
    pub f16: Option<F16Summary>,
    /// The energy-bounded copies (`None` unless every object has one).
    pub bounded: Option<BoundedSummary>,
}

/// Means over the objects of the energy-bounded copies of a model (`StudyConfig::energy_bound`).
#[derive(Clone, Debug, Serialize)]
pub struct BoundedSummary {
    pub psnr: f64,
    pub brdf_rmse_cbrt: f64,
    pub energy_share_above_one: f64,
    /// Mean over objects of the median violating albedo; `None` when no object violates.
    pub energy_median_above_one: Option<f64>,
    pub energy_mean_albedo: f64,
    /// Largest value of the albedo tables over the objects (at most 1: no value was changed).
    pub albedo_bound_max: f64,
}

/// Means over the objects of the f16-weight copies of a model.
#[derive(Clone, Debug, Serialize)]
pub struct F16Summary {
    pub psnr: f64,
    pub brdf_rmse_cbrt: f64,
    pub eval_ns_per_query: f64,
    pub eval_batch_ns_per_query: Option<f64>,
    pub prepare_ns_per_point: Option<f64>,
    pub prepare_many_ns_per_point: Option<f64>,
    pub size_bytes: u64,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Groups the results by model, in first-seen order, and averages over objects.
pub fn summarize(results: &[JobResult]) -> Vec<ModelSummary> {
    let mut order: Vec<&str> = Vec::new();
    for r in results {
        if !order.contains(&r.model.as_str()) {
            order.push(&r.model);
        }
    }
    order
        .into_iter()
        .map(|model| {
            let rs: Vec<&JobResult> = results.iter().filter(|r| r.model == model).collect();
            let lpips: Option<Vec<f64>> = rs.iter().map(|r| r.eval.image.lpips.value()).collect();
            let medians: Vec<f64> = rs.iter().filter_map(|r| r.eval.energy.median_above_one).collect();
            ModelSummary {
                model: model.to_string(),
                objects: rs.len(),
                psnr: mean(rs.iter().map(|r| r.eval.image.psnr)),
                dssim: mean(rs.iter().map(|r| r.eval.image.dssim)),
                lpips: lpips.map(|v| mean(v.into_iter())),
                flip: mean(rs.iter().map(|r| r.eval.image.flip)),
                brdf_rmse_cbrt: mean(rs.iter().map(|r| r.eval.brdf_rmse_cbrt.value)),
                reciprocity_rmse: mean(rs.iter().map(|r| r.eval.reciprocity_rmse)),
                energy_share_above_one: mean(rs.iter().map(|r| r.eval.energy.share_above_one)),
                energy_detectable_excess: mean(rs.iter().map(|r| r.eval.energy.z * r.eval.energy.mean_standard_error)),
                energy_mean_albedo: mean(rs.iter().map(|r| r.eval.energy.mean_albedo)),
                energy_median_above_one: (!medians.is_empty()).then(|| mean(medians.into_iter())),
                train_wall_s: mean(rs.iter().map(|r| r.train_wall_s)),
                eval_ns_per_query: mean(rs.iter().map(|r| r.eval.eval_ns_per_query)),
                eval_batch_ns_per_query: mean_all(rs.iter().map(|r| r.eval.eval_batch_ns_per_query)),
                prepare_ns_per_point: mean_all(rs.iter().map(|r| r.eval.prepare_ns_per_point)),
                prepare_many_ns_per_point: mean_all(rs.iter().map(|r| r.eval.prepare_many_ns_per_point)),
                n_weights: rs[0].n_weights,
                size_bytes: rs[0].size_bytes,
                f16: f16_summary(rs.iter().map(|r| r.eval_f16.as_ref().zip(r.size_bytes_f16))),
                bounded: bounded_summary(rs.iter().map(|r| r.eval_bounded.as_ref().zip(r.albedo_bound_max))),
            }
        })
        .collect()
}

/// Means over the objects of f16 evaluations, `None` unless every object has one.
fn f16_summary<'a>(v: impl Iterator<Item = Option<(&'a Evaluation, u64)>>) -> Option<F16Summary> {
    v.collect::<Option<Vec<_>>>().filter(|v| !v.is_empty()).map(|v| F16Summary {
        psnr: mean(v.iter().map(|(e, _)| e.image.psnr)),
        brdf_rmse_cbrt: mean(v.iter().map(|(e, _)| e.brdf_rmse_cbrt.value)),
        eval_ns_per_query: mean(v.iter().map(|(e, _)| e.eval_ns_per_query)),
        eval_batch_ns_per_query: mean_all(v.iter().map(|(e, _)| e.eval_batch_ns_per_query)),
        prepare_ns_per_point: mean_all(v.iter().map(|(e, _)| e.prepare_ns_per_point)),
        prepare_many_ns_per_point: mean_all(v.iter().map(|(e, _)| e.prepare_many_ns_per_point)),
        size_bytes: v[0].1,
    })
}

/// Means over the objects of energy-bounded evaluations, `None` unless every object has one.
fn bounded_summary<'a>(v: impl Iterator<Item = Option<(&'a Evaluation, f32)>>) -> Option<BoundedSummary> {
    v.collect::<Option<Vec<_>>>().filter(|v| !v.is_empty()).map(|v| {
        let medians: Vec<f64> = v.iter().filter_map(|(e, _)| e.energy.median_above_one).collect();
        BoundedSummary {
            psnr: mean(v.iter().map(|(e, _)| e.image.psnr)),
            brdf_rmse_cbrt: mean(v.iter().map(|(e, _)| e.brdf_rmse_cbrt.value)),
            energy_share_above_one: mean(v.iter().map(|(e, _)| e.energy.share_above_one)),
            energy_median_above_one: (!medians.is_empty()).then(|| mean(medians.into_iter())),
            energy_mean_albedo: mean(v.iter().map(|(e, _)| e.energy.mean_albedo)),
            albedo_bound_max: v.iter().map(|(_, m)| *m as f64).fold(0.0, f64::max),
        }
    })
}

/// The mean where every value is present, else `None`.
fn mean_all(v: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    v.collect::<Option<Vec<f64>>>().filter(|v| !v.is_empty()).map(|v| mean(v.into_iter()))
}

fn opt(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or("n/a".into(), |x| format!("{:.*}", digits, x * scale))
}

/// Where a variant belongs in the paper's tables, from its name (`Config::name`): the base kind,
/// its reciprocity strategy (purely neural models) and whether it is a Tab. 2 layer-count variant.
#[derive(Clone, Debug, PartialEq)]
pub struct Role {
    pub parametric: bool,
    /// `none`, `swap` or `exact`; `None` for parametric models.
    pub reciprocity: Option<&'static str>,
    /// The Tab. 1 row a Tab. 2 variant is compared with (its name without `+nolN`).
    pub nol_base: Option<String>,
}

/// The [`Role`] of a variant name.
pub fn role(name: &str) -> Role {
    let parts: Vec<&str> = name.split('+').collect();
    let parametric = is_parametric(parts[0]);
    let reciprocity = (!parametric).then(|| {
        if parts.contains(&"swap") {
            "swap"
        } else if parts.contains(&"exact") {
            "exact"
        } else {
            "none"
        }
    });
    let nol_base = parts
        .iter()
        .any(|p| p.starts_with("nol"))
        .then(|| parts.iter().filter(|p| !p.starts_with("nol")).copied().collect::<Vec<_>>().join("+"));
    Role { parametric, reciprocity, nol_base }
}

/// Whether a variant is a Tab. 1 row: not a layer-count variant, and (purely neural) with the study's
/// reciprocity strategy.
pub fn in_tab1(name: &str, config: &StudyConfig) -> bool {
    let r = role(name);
    r.nol_base.is_none() && r.reciprocity.is_none_or(|s| s == reciprocity_name(config.reciprocity))
}

/// The Tab. 1 scores of one job, as the paper scales them (RMSE∛, DSSIM, LPIPS, FLIP ×100).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    pub rmse: f64,
    pub psnr: f64,
    pub dssim: f64,
    pub lpips: Option<f64>,
    pub flip: f64,
}

impl Scores {
    pub fn of(r: &JobResult) -> Self {
        let e = &r.eval;
        Scores {
            rmse: e.brdf_rmse_cbrt.value * 100.0,
            psnr: e.image.psnr,
            dssim: e.image.dssim * 100.0,
            lpips: e.image.lpips.value().map(|v| v * 100.0),
            flip: e.image.flip * 100.0,
        }
    }
}

/// Mean over objects of `variant − base` for each score (paper Tab. 2: "the difference to the results
/// in Tab. 1"; the mean of the per-object differences equals the difference of the per-model means when
/// both rows cover the same objects, which pairing guarantees). LPIPS is `None` if missing anywhere.
pub fn mean_delta(pairs: &[(Scores, Scores)]) -> Scores {
    let d = |f: fn(&Scores) -> f64| mean(pairs.iter().map(|(v, b)| f(v) - f(b)));
    let lpips: Option<Vec<f64>> = pairs.iter().map(|(v, b)| Some(v.lpips? - b.lpips?)).collect();
    Scores {
        rmse: d(|s| s.rmse),
        psnr: d(|s| s.psnr),
        dssim: d(|s| s.dssim),
        lpips: lpips.filter(|v| !v.is_empty()).map(|v| mean(v.into_iter())),
        flip: d(|s| s.flip),
    }
}

/// One row of Tab. 2: a layer-count variant, its Tab. 1 base, the objects both ran on, the deltas.
#[derive(Clone, Debug)]
pub struct Tab2Row {
    pub model: String,
    pub base: String,
    pub objects: Vec<String>,
    pub delta: Scores,
}

/// Tab. 2: every `+nolN` variant against its base row, paired per object.
pub fn tab2(results: &[JobResult]) -> Vec<Tab2Row> {
    let mut rows: Vec<Tab2Row> = Vec::new();
    for r in results {
        let Some(base) = role(&r.model).nol_base else { continue };
        if rows.iter().any(|t| t.model == r.model) {
            continue;
        }
        let mut objects = Vec::new();
        let mut pairs = Vec::new();
        for v in results.iter().filter(|v| v.model == r.model) {
            if let Some(b) = results.iter().find(|b| b.model == base && b.scene == v.scene) {
                objects.push(v.scene.clone());
                pairs.push((Scores::of(v), Scores::of(b)));
            }
        }
        if !pairs.is_empty() {
            rows.push(Tab2Row { model: r.model.clone(), base, objects, delta: mean_delta(&pairs) });
        }
    }
    rows
}

/// Objects (scenes) a summary row averages over.
fn objects_of(results: &[JobResult], model: &str) -> Vec<String> {
    results.iter().filter(|r| r.model == model).map(|r| r.scene.clone()).collect()
}

fn signed(v: f64, digits: usize) -> String {
    format!("{v:+.digits$}")
}

/// A plot label short enough not to run into its neighbours: the architecture names abbreviated and
/// the study's own reciprocity strategy (every Tab. 1 row has it) left out.
fn short_label(name: &str, config: &StudyConfig) -> String {
    name.split('+')
        .filter(|p| *p != reciprocity_name(config.reciprocity))
        .map(|p| match p {
            "additive-separate" => "add-sep",
            "additive-shared" => "add-shared",
            "enhanced" => "enh",
            other => other,
        })
        .collect::<Vec<_>>()
        .join("+")
}

/// The two Pareto plots (PSNR against training wall time and against evaluation ns per query, the
/// latter with the f16 copies) over the rows that ran on every object of the study, so that all means
/// cover the same objects. Returns their paths relative to `out`.
pub fn pareto_plots(out: &Path, config: &StudyConfig, results: &[JobResult]) -> Result<Vec<(String, std::path::PathBuf)>> {
    let s = summarize(results);
    let all = config.scenes.len();
    let full: Vec<&ModelSummary> = s.iter().filter(|m| m.objects == all).collect();
    let train: Vec<CostPoint> =
        full.iter().map(|m| CostPoint { label: short_label(&m.model, config), cost: m.train_wall_s, accuracy: m.psnr }).collect();
    // Each model's point, then those of the f16 copies that have the cost.
    let points = |cost: fn(&ModelSummary) -> Option<f64>, f16_cost: fn(&F16Summary) -> Option<f64>| {
        let mut pts: Vec<CostPoint> = full
            .iter()
            .filter_map(|m| Some(CostPoint { label: short_label(&m.model, config), cost: cost(m)?, accuracy: m.psnr }))
            .collect();
        pts.extend(full.iter().filter_map(|m| {
            let f = m.f16.as_ref()?;
            Some(CostPoint { label: format!("{} f16", short_label(&m.model, config)), cost: f16_cost(f)?, accuracy: f.psnr })
        }));
        pts
    };
    let eval = points(|m| Some(m.eval_ns_per_query), |f| Some(f.eval_ns_per_query));
    let batch = points(|m| m.eval_batch_ns_per_query, |f| f.eval_batch_ns_per_query);
    let mut plots = vec![
        ("PSNR against training wall time", "figures/pareto-train.png", "training wall time (s, log)", train),
        ("PSNR against evaluation cost", "figures/pareto-eval.png", "core eval ns per query (log)", eval),
    ];
    if !batch.is_empty() {
        plots.push(("PSNR against batched evaluation cost", "figures/pareto-eval-batch.png", "core eval ns per query, batches of 256 (log)", batch));
    }
    let mut written = Vec::new();
    for (title, rel, xlabel, pts) in plots {
        figures::pareto_plot(&out.join(rel), title, xlabel, "PSNR (dB), mean over objects", &pts)?;
        written.push((title.to_string(), std::path::PathBuf::from(rel)));
    }
    Ok(written)
}

/// What the image metrics were scored against, per object, and each object's ceiling: its clean
/// reference scored against the noisy capture, the best a perfect model would read there.
fn references(config: &StudyConfig, results: &[JobResult]) -> String {
    let mut md = String::from("## References and ceilings\n\n");
    md += "Image metrics score each model's rendering against the **clean** reference where the object has a ground \
           truth (the noise-free Eq. 9 render of its material: same camera, lights and shadows; a perfect model scores \
           PSNR +inf), and against the **captured** images otherwise (real captures). The ceiling is the clean reference \
           scored against the noisy capture: a model scored against the capture cannot read better, so differences \
           there below the gap to the ceiling measure the noise, not the models. `results.json` keeps each model's PSNR \
           against the capture too (`eval.captured_psnr`).\n\n";
    md += "| object | reference | ceiling PSNR | DSSIM | LPIPS | FLIP | models' PSNR vs. capture |\n|---|---|---|---|---|---|---|\n";
    for sc in &config.scenes {
        let jobs: Vec<&JobResult> = results.iter().filter(|r| r.scene == sc.id()).collect();
        let Some(first) = jobs.first() else { continue };
        let kinds: Vec<&str> = {
            let mut k: Vec<&str> = jobs.iter().map(|r| r.eval.reference.name()).collect();
            k.dedup();
            k
        };
        let captured: Vec<f64> = jobs.iter().filter_map(|r| r.eval.captured_psnr).collect();
        let range = match (captured.iter().cloned().reduce(f64::min), captured.iter().cloned().reduce(f64::max)) {
            (Some(lo), Some(hi)) => format!("{lo:.2}–{hi:.2} dB"),
            _ => "—".into(),
        };
        let (p, d, l, f) = match &first.ceiling {
            Some(c) => (
                format!("{:.2} dB", c.psnr),
                format!("{:.2}", 100.0 * c.dssim),
                c.lpips.value().map_or("n/a".into(), |v| format!("{:.2}", 100.0 * v)),
                format!("{:.2}", 100.0 * c.flip),
            ),
            None => ("—".into(), "—".into(), "—".into(), "—".into()),
        };
        md += &format!("| {} | {} | {p} | {d} | {l} | {f} | {range} |\n", sc.label(), kinds.join(", "));
    }
    md
}

/// The paper's Tab. 1, MERL columns (RMSE ∛ ×100, PSNR, DSSIM ×100, LPIPS ×100, FLIP ×100), for a
/// Tab. 1 row of ours by its name (any reciprocity suffix).
pub fn paper_tab1(model: &str) -> Option<&'static [f64; 5]> {
    const ROWS: [(&str, [f64; 5]); 9] = [
        ("rp", [1.632, 44.05, 0.779, 1.656, 6.025]),
        ("ts", [1.216, 46.06, 0.620, 1.174, 5.717]),
        ("fmbrdf", [1.167, 46.40, 0.654, 1.310, 5.876]),
        ("disney", [1.218, 46.46, 0.616, 1.158, 5.735]),
        ("single-mlp", [0.554, 52.35, 0.411, 0.565, 4.795]),
        ("additive-separate", [0.562, 52.28, 0.413, 0.571, 4.802]),
        ("additive-shared", [0.665, 51.40, 0.428, 0.621, 5.075]),
        ("additive-separate+enhanced", [0.547, 52.39, 0.412, 0.565, 4.794]),
        ("additive-shared+enhanced", [0.579, 51.95, 0.419, 0.580, 4.836]),
    ];
    let base: Vec<&str> = model.split('+').filter(|p| !matches!(*p, "none" | "swap" | "exact")).collect();
    let base = base.join("+");
    ROWS.iter().find(|(name, _)| *name == base).map(|(_, row)| row)
}

/// One learning-curve figure per object over its Tab. 1 variants that recorded a curve
/// (`figures/curves-<scene>.png`). Returns their titles and paths relative to `out`.
pub fn curve_plots(out: &Path, config: &StudyConfig, results: &[JobResult]) -> Result<Vec<(String, std::path::PathBuf)>> {
    let mut written = Vec::new();
    for scene in &config.scenes {
        let id = scene.id();
        let curves: Vec<figures::Curve> = results
            .iter()
            .filter(|r| r.scene == id && in_tab1(&r.model, config) && r.curve.iter().any(|p| p.test_psnr.is_some()))
            .map(|r| figures::Curve {
                label: short_label(&r.model, config),
                points: r.curve.iter().filter_map(|p| Some((p.step as f64, p.wall_s, p.test_psnr?))).collect(),
            })
            .collect();
        if curves.is_empty() {
            continue;
        }
        let rel = std::path::PathBuf::from(format!("figures/curves-{id}.png"));
        let title = format!("Learning curves, {}", scene.label());
        figures::curve_plot(&out.join(&rel), &title, &curves)?;
        written.push((title, rel));
    }
    Ok(written)
}

/// The Markdown report; `plots` and `comparisons` are the figures to link (paths relative to the
/// report).
pub fn markdown(
    config: &StudyConfig,
    results: &[JobResult],
    plots: &[(String, std::path::PathBuf)],
    curves: &[(String, std::path::PathBuf)],
    comparisons: &[Comparison],
) -> String {
    let s = summarize(results);
    let mut md = String::new();
    let scenes: Vec<String> = config.scenes.iter().map(|sc| sc.label()).collect();
    let paper_scale = config.steps >= 20_000 && config.size >= 256;
    let _ = writeln!(md, "# Neural BRDF study\n");
    if paper_scale {
        let _ = writeln!(md, "**Scale:** the paper's training budget (≥ 20k steps, 256² images); numbers comparable in kind to the paper's Tabs. 1–4 (semi-synthetic objects rendered by `synth`, not the paper's renders).\n");
    } else {
        let _ = writeln!(
            md,
            "**Reduced scale, not the paper's numbers.** {} steps at batch {} on {}² images (paper: 20k steps at 2^15 values on 256² \
             renders of 25 MERL materials on 9 meshes): no model is converged and {} objects are a small sample, so compare \
             rankings and differences, not values; the tables show that every measurement of Sec. 6 runs end to end and how the \
             variants compare at this budget.\n",
            config.steps,
            config.batch,
            config.size,
            config.scenes.len()
        );
    }
    let _ = writeln!(
        md,
        "Objects: {}. Images {}×{}, {} views ({} train), {} / {} lights per train / test view, σ = {}. \
         Position input `{}`, {} steps at batch {}. Reciprocity over {} test pairs; energy over {} pairs × {} \
         view samples (paper: 50k × 20k). Every number is a mean over the objects a row ran on (each table says which); \
         per-job values are in `results.json` / `results.csv`.\n",
        scenes.join(", "),
        config.size,
        config.size,
        config.views,
        config.train_views,
        config.train_lights,
        config.test_lights,
        config.sigma,
        position_name(config.position),
        config.steps,
        config.batch,
        config.reciprocity_pairs,
        config.energy_pairs,
        config.energy_samples
    );
    let missing = results.iter().find_map(|r| match &r.eval.image.lpips {
        crate::metrics::MaybeMetric::NotAvailable { na } => Some(na.clone()),
        crate::metrics::MaybeMetric::Value(_) => None,
    });
    if let Some(why) = missing {
        let _ = writeln!(
            md,
            "**LPIPS is n/a** ({why}). To enable it, point `NBRDF_DATA` at a folder holding \
             `lpips/alexnet-lpips-v0.1.safetensors` (the AlexNet-LPIPS v0.1 weights; `../shared/data` in this \
             repository's layout, see its README) and run the study again into a fresh `--out` folder (a finished job \
             keeps the scores it was evaluated with).\n"
        );
    }
    let _ = writeln!(md, "{}", references(config, results));
    let tab1: Vec<&ModelSummary> = s.iter().filter(|m| in_tab1(&m.model, config)).collect();
    let _ = writeln!(md, "## Tab. 1 — reconstruction quality\n");
    let _ = writeln!(
        md,
        "Purely neural models with the `{}` reciprocity strategy. RMSE ∛, DSSIM, LPIPS and FLIP ×100, as in the paper. \
         ↑ higher is better, ↓ lower.\n",
        reciprocity_name(config.reciprocity)
    );
    let _ = writeln!(md, "| model | objects | RMSE ∛ ↓ | PSNR ↑ | DSSIM ↓ | LPIPS ↓ | FLIP ↓ |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|");
    for m in &tab1 {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {} | {:.2} |",
            m.model,
            m.objects,
            m.brdf_rmse_cbrt * 100.0,
            m.psnr,
            m.dssim * 100.0,
            opt(m.lpips, 100.0, 2),
            m.flip * 100.0
        );
    }
    let paper: Vec<(&ModelSummary, &[f64; 5])> = tab1.iter().filter_map(|m| Some((*m, paper_tab1(&m.model)?))).collect();
    if !paper.is_empty() {
        let _ = writeln!(
            md,
            "\nThe paper's Tab. 1 (MERL columns: 25 materials × 9 meshes, 20k steps) for the same rows, beside ours \
             (each cell ours / paper; RMSE ∛, DSSIM, LPIPS, FLIP ×100):\n"
        );
        let _ = writeln!(md, "| model | RMSE ∛ | PSNR | DSSIM | LPIPS | FLIP |");
        let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|");
        for (m, p) in paper {
            let _ = writeln!(
                md,
                "| {} | {:.2} / {:.3} | {:.2} / {:.2} | {:.2} / {:.3} | {} / {:.3} | {:.2} / {:.3} |",
                m.model,
                m.brdf_rmse_cbrt * 100.0,
                p[0],
                m.psnr,
                p[1],
                m.dssim * 100.0,
                p[2],
                opt(m.lpips, 100.0, 2),
                p[3],
                m.flip * 100.0,
                p[4]
            );
        }
    }

    let exposures: Vec<String> = config
        .scenes
        .iter()
        .filter_map(|sc| {
            let e = results.iter().find(|r| r.scene == sc.id())?.exposure?;
            Some(format!(
                "{}: light intensity {:.3}, median luminance of the lit object pixels {:.3}, {:.1} % of them saturated",
                sc.label(),
                e.light_intensity,
                e.median_luminance,
                100.0 * e.saturated_share
            ))
        })
        .collect();
    if !exposures.is_empty() {
        let _ = writeln!(
            md,
            "\nExposure of the renders (a channel at or above {} counts as saturated; saturated pixels are left out of RMSE∛, \
             as in the paper):\n",
            crate::dataset::spec::SATURATED
        );
        for e in exposures {
            let _ = writeln!(md, "- {e}");
        }
    }

    let _ = writeln!(md, "\n## Learning curves\n");
    if curves.is_empty() {
        let _ = writeln!(md, "None recorded (results written before the fits recorded their curves).");
    } else {
        let _ = writeln!(
            md,
            "Mean test-view PSNR of every Tab. 1 variant at {} points of its run, against training steps (left) and \
             training wall time (right; the probes' own time excluded). A curve still rising at its last point would gain \
             from more steps. The points, with the training loss, are in `results.json` (`jobs[].curve`).\n",
            crate::commands::fit::CURVE_POINTS + 1
        );
        for (title, path) in curves {
            let _ = writeln!(md, "![{title}]({})", path.display());
        }
    }

    let _ = writeln!(md, "\n## Tab. 2 — number of layers the directions pass through (NOL)\n");
    let rows2 = tab2(results);
    if rows2.is_empty() {
        let _ = writeln!(md, "No `direction_layers` variants in this config.");
    } else {
        let _ = writeln!(
            md,
            "Difference to the Tab. 1 row of the same architecture (variant − Tab. 1), paired per object and averaged over \
             the objects listed; RMSE ∛, DSSIM, LPIPS and FLIP ×100, as in the paper.\n"
        );
        let _ = writeln!(md, "| model | vs. | objects | Δ RMSE ∛ | Δ PSNR | Δ DSSIM | Δ LPIPS | Δ FLIP |");
        let _ = writeln!(md, "|---|---|---|---:|---:|---:|---:|---:|");
        for t in &rows2 {
            let d = &t.delta;
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                t.model,
                t.base,
                t.objects.join(", "),
                signed(d.rmse, 2),
                signed(d.psnr, 2),
                signed(d.dssim, 2),
                d.lpips.map_or("n/a".into(), |v| signed(v, 2)),
                signed(d.flip, 2)
            );
        }
    }

    let _ = writeln!(md, "\n## Tab. 3 — reciprocity\n");
    let _ = writeln!(
        md,
        "RMSE of f(x, l, v) − f(x, v, l) in 1/sr, not scaled (as the paper). The exact Θ mapping (Sec. 4.3) and the \
         parametric models are reciprocal by construction, so their RMSE is 0 (the paper leaves them out; the exact rows \
         below are measured and confirm it). PSNR for the influence on quality.\n"
    );
    let _ = writeln!(md, "| model | strategy | objects | reciprocity RMSE ↓ | PSNR ↑ |");
    let _ = writeln!(md, "|---|---|---|---:|---:|");
    let mut neural: Vec<&ModelSummary> =
        s.iter().filter(|m| role(&m.model).reciprocity.is_some() && role(&m.model).nol_base.is_none()).collect();
    // Grouped as the paper: no strategy, random input swap, then the exact mapping.
    let rank = |m: &ModelSummary| match role(&m.model).reciprocity {
        Some("none") => 0,
        Some("swap") => 1,
        _ => 2,
    };
    neural.sort_by_key(|m| rank(m));
    for m in &neural {
        let strategy = match role(&m.model).reciprocity {
            Some("none") => "none",
            Some("swap") => "random input swap",
            _ => "exact Θ (0 by construction)",
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3e} | {:.2} |",
            m.model,
            strategy,
            objects_of(results, &m.model).join(", "),
            m.reciprocity_rmse,
            m.psnr
        );
    }

    let _ = writeln!(md, "\n## Tab. 4 — energy conservation\n");
    let _ = writeln!(
        md,
        "Tab. 1 rows. Share of point-light pairs whose albedo is above 1 by more than 3 standard errors, and the median \
         albedo of those. What the test can see: with {} pairs per object a share below {:.2} % is one pair or none, and \
         with {} view samples per pair an excess over 1 is detected once it exceeds 3 standard errors of the estimate, \
         the column \"detectable\" (mean over pairs and objects). A 0 means no violation of that size, not none at all.\n",
        config.energy_pairs,
        100.0 / config.energy_pairs.max(1) as f64,
        config.energy_samples
    );
    let _ = writeln!(md, "| model | % > 1 | μ.5 > 1 | mean albedo | detectable excess |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|");
    for m in &tab1 {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {} | {:.3} | {:.3} |",
            m.model,
            m.energy_share_above_one * 100.0,
            m.energy_median_above_one.map_or("all valid".into(), |v| format!("{v:.3}")),
            m.energy_mean_albedo,
            m.energy_detectable_excess
        );
    }

    if s.iter().any(|m| m.bounded.is_some()) {
        let _ = writeln!(md, "\n## Energy bound — what conservation by construction costs\n");
        let _ = writeln!(
            md,
            "Every variant, fitted once and scored twice: as fitted, and energy-bounded as `trainer fit --energy-bound` \
             writes it (`f / max(1, Â(θi), Â(θo))` per channel, `Â` an upper bound of the albedo over the view angle \
             fitted over {} training points; docs/models.md, \"Energy bound\"). Largest Â: the table's largest value over \
             the objects; at most 1 means the bound changed no value and both rows are the same model. Tab. 4's columns \
             for both, at the same detection threshold as above; reciprocity is unchanged (the divisor is symmetric).\n",
            crate::models::export::BOUND_POINTS
        );
        let _ = writeln!(
            md,
            "| model | largest Â | PSNR | bounded | RMSE ∛ ×100 | bounded | % > 1 | bounded | μ.5 > 1 | bounded | mean albedo | bounded |"
        );
        let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        let median = |v: Option<f64>| v.map_or("all valid".into(), |v| format!("{v:.3}"));
        for m in &s {
            let Some(b) = &m.bounded else { continue };
            let _ = writeln!(
                md,
                "| {} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {:.1} | {} | {} | {:.3} | {:.3} |",
                m.model,
                b.albedo_bound_max,
                m.psnr,
                b.psnr,
                m.brdf_rmse_cbrt * 100.0,
                b.brdf_rmse_cbrt * 100.0,
                m.energy_share_above_one * 100.0,
                b.energy_share_above_one * 100.0,
                median(m.energy_median_above_one),
                median(b.energy_median_above_one),
                m.energy_mean_albedo,
                b.energy_mean_albedo
            );
        }
    }

    let _ = writeln!(md, "\n## Accuracy versus cost\n");
    let _ = writeln!(
        md,
        "Every variant. Training wall time on this machine (CPU, shared), core evaluation ns per query (one thread, point \
         prepared), model file size; `f16` rows are the same fit re-encoded with f16 network weights (no retraining), \
         evaluated the same way over the f16 file borrowed in place (`Model::from_bytes`, whose kernels widen the f16 rows \
         as they read them; a `ModelBuf` widens an f16 file to f32 at load and runs at the f32 rows' speed, with the same \
         values). Batched: ns per pair of `eval_many` over batches of {} \
         directions at one point. Prepare: ns per shading point of `Model::prepare` one point at a time and of \
         `Model::prepare_many` over the evaluation's sample points at once (the per-point work every evaluation at a point \
         adds to: for the parametric models their whole network). Means over the objects column.\n",
        super::evaluate::BATCH
    );
    let _ = writeln!(md, "| model | weights | objects | train s | eval ns/query | batched ns/query | prepare ns/point: single, many | parameters | size (KiB) | PSNR ↑ | RMSE ∛ ×100 ↓ |");
    let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let prepare = |single: Option<f64>, many: Option<f64>| format!("{}, {}", opt(single, 1.0, 0), opt(many, 1.0, 0));
    for m in &s {
        let _ = writeln!(
            md,
            "| {} | f32 | {} | {:.1} | {:.0} | {} | {} | {} | {:.1} | {:.2} | {:.2} |",
            m.model,
            m.objects,
            m.train_wall_s,
            m.eval_ns_per_query,
            opt(m.eval_batch_ns_per_query, 1.0, 0),
            prepare(m.prepare_ns_per_point, m.prepare_many_ns_per_point),
            m.n_weights,
            m.size_bytes as f64 / 1024.0,
            m.psnr,
            m.brdf_rmse_cbrt * 100.0
        );
        if let Some(f) = &m.f16 {
            let _ = writeln!(
                md,
                "| {} | f16 | {} | {:.1} | {:.0} | {} | {} | {} | {:.1} | {:.2} | {:.2} |",
                m.model,
                m.objects,
                m.train_wall_s,
                f.eval_ns_per_query,
                opt(f.eval_batch_ns_per_query, 1.0, 0),
                prepare(f.prepare_ns_per_point, f.prepare_many_ns_per_point),
                m.n_weights,
                f.size_bytes as f64 / 1024.0,
                f.psnr,
                f.brdf_rmse_cbrt * 100.0
            );
        }
    }
    if !plots.is_empty() {
        let _ = writeln!(
            md,
            "\nPareto plots over the variants that ran on every object (red: the Pareto front — no other variant is both \
             cheaper and more accurate):\n"
        );
        for (title, path) in plots {
            let _ = writeln!(md, "![{title}]({})", path.display());
        }
    }

    let _ = writeln!(md, "\n## Renderings\n");
    if comparisons.is_empty() {
        let _ = writeln!(
            md,
            "None here: no data set or fitted model of a Tab. 1 variant was found (a merge renders them from the shard \
             folders it joins, so those must still hold their `data/` and `jobs/`)."
        );
    } else {
        let _ = writeln!(
            md,
            "First test image of each object: reference (left) and the rendering of the best parametric and the best purely \
             neural Tab. 1 variant by PSNR on that object (right), sRGB at exposure 1 as the metrics see them, enlarged \
             4× (nearest pixel); and the HDR-FLIP error map (magma: black = no error, bright = large).\n"
        );
        let _ = writeln!(md, "| object | model | reference · rendering | HDR-FLIP | mean FLIP ×100 |");
        let _ = writeln!(md, "|---|---|---|---|---:|");
        for c in comparisons {
            let _ = writeln!(
                md,
                "| {} | {} | ![{} {}]({}) | ![FLIP]({}) | {:.2} |",
                c.scene,
                c.model,
                c.scene,
                c.model,
                c.images.display(),
                c.flip_map.display(),
                c.flip_mean * 100.0
            );
        }
    }
    md
}

/// One CSV row per job.
pub fn csv(results: &[JobResult]) -> String {
    let mut out = String::from(
        "scene,model,psnr,dssim,lpips,flip,brdf_rmse_cbrt,brdf_samples,reciprocity_rmse,energy_share_above_one,\
         energy_median_above_one,energy_mean_albedo,train_wall_s,eval_ns_per_query,n_weights,size_bytes,steps,final_loss,\
         psnr_f16,brdf_rmse_cbrt_f16,eval_ns_per_query_f16,size_bytes_f16,eval_batch_ns_per_query,\
         eval_batch_ns_per_query_f16,prepare_ns_per_point,prepare_many_ns_per_point,psnr_bounded,brdf_rmse_cbrt_bounded,\
         energy_share_above_one_bounded,albedo_bound_max\n",
    );
    let o = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
    for r in results {
        let e = &r.eval;
        let f16 = r.eval_f16.as_ref();
        let bounded = r.eval_bounded.as_ref();
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.scene,
            r.model,
            e.image.psnr,
            e.image.dssim,
            o(e.image.lpips.value()),
            e.image.flip,
            e.brdf_rmse_cbrt.value,
            e.brdf_rmse_cbrt.samples,
            e.reciprocity_rmse,
            e.energy.share_above_one,
            o(e.energy.median_above_one),
            e.energy.mean_albedo,
            r.train_wall_s,
            e.eval_ns_per_query,
            r.n_weights,
            r.size_bytes,
            r.steps,
            r.final_loss,
            o(f16.map(|e| e.image.psnr)),
            o(f16.map(|e| e.brdf_rmse_cbrt.value)),
            o(f16.map(|e| e.eval_ns_per_query)),
            r.size_bytes_f16.map_or(String::new(), |b| b.to_string()),
            o(e.eval_batch_ns_per_query),
            o(f16.and_then(|e| e.eval_batch_ns_per_query)),
            o(e.prepare_ns_per_point),
            o(e.prepare_many_ns_per_point),
            o(bounded.map(|e| e.image.psnr)),
            o(bounded.map(|e| e.brdf_rmse_cbrt.value)),
            o(bounded.map(|e| e.energy.share_above_one)),
            o(r.albedo_bound_max.map(f64::from)),
        );
    }
    out
}

/// Writes the Pareto plots, `REPORT.md` (linking them and `comparisons`), `results.json` (config,
/// per-model summary, every job) and `results.csv`.
pub fn write(out: &Path, config: &StudyConfig, results: &[JobResult], comparisons: &[Comparison]) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let plots = pareto_plots(out, config, results)?;
    let curves = curve_plots(out, config, results)?;
    let put = |name: &str, bytes: &[u8]| crate::train::write_atomic(&out.join(name), bytes);
    put("REPORT.md", markdown(config, results, &plots, &curves, comparisons).as_bytes())?;
    put("results.csv", csv(results).as_bytes())?;
    let json = serde_json::json!({ "config": config, "summary": summarize(results), "jobs": results });
    put("results.json", &serde_json::to_vec_pretty(&json).map_err(|e| Error::io(out, e))?)?;
    Ok(())
}

/// Reads the `results.json` of several study outputs (e.g. one per shard, or one per mesh run on
/// different machines) and joins their jobs; a job (scene, model) found twice keeps the later folder's
/// result. The folders must hold one config, or configs that differ only in their scenes (the joined
/// config lists every scene, in the order the folders first name them): jobs of two protocols in one
/// table would compare unlike runs, so a folder whose config differs in anything else is refused,
/// naming both folders and the keys that differ.
pub fn merge(dirs: &[std::path::PathBuf]) -> Result<(StudyConfig, Vec<JobResult>)> {
    #[derive(serde::Deserialize)]
    struct Saved {
        config: StudyConfig,
        jobs: Vec<JobResult>,
    }
    let mut config: Option<(StudyConfig, &std::path::Path)> = None;
    let mut jobs: Vec<JobResult> = Vec::new();
    for d in dirs {
        let p = d.join("results.json");
        let saved: Saved = crate::json::read(&p, "study results file")?;
        match &mut config {
            None => config = Some((saved.config, d)),
            Some((first, first_dir)) => {
                let keys = differing_keys(first, &saved.config);
                if keys == "\"scenes\"" {
                    // A model limited to some scenes names them by index, which a longer list would shift.
                    if let Some(m) = first.models.iter().find(|m| m.scenes.is_some()) {
                        return Err(Error::Invalid(format!(
                            "study merge: {} and {} hold studies of different scenes, and model {:?} runs on scenes \
                             chosen by index, which joining the lists would change; merge only shards of one config",
                            d.display(),
                            first_dir.display(),
                            m.model
                        )));
                    }
                    for scene in saved.config.scenes {
                        if !first.scenes.contains(&scene) {
                            first.scenes.push(scene);
                        }
                    }
                } else if !keys.is_empty() {
                    return Err(Error::Invalid(format!(
                        "study merge: {} holds a study of another config than {} (they differ in {keys}); merge only \
                         shards of one config, or studies that differ only in their scenes",
                        d.display(),
                        first_dir.display(),
                    )));
                }
            }
        }
        for j in saved.jobs {
            match jobs.iter_mut().find(|k| k.scene == j.scene && k.model == j.model) {
                Some(k) => *k = j,
                None => jobs.push(j),
            }
        }
    }
    let (config, _) = config.ok_or_else(|| Error::Invalid("study merge: give at least one folder".into()))?;
    // Config order (scene-major, as one unsharded run lists them), whatever the order of the folders.
    let order: Vec<(String, String)> = super::jobs(&config)
        .into_iter()
        .filter_map(|(s, m)| Some((config.scenes[s].id(), config.model_config(&config.models[m]).ok()?.name())))
        .collect();
    jobs.sort_by_key(|j| order.iter().position(|(s, m)| *s == j.scene && *m == j.model).unwrap_or(usize::MAX));
    Ok((config, jobs))
}

/// The top-level keys in which two configs differ, quoted and comma-separated.
fn differing_keys(a: &StudyConfig, b: &StudyConfig) -> String {
    let (a, b) = (serde_json::to_value(a).unwrap_or_default(), serde_json::to_value(b).unwrap_or_default());
    let empty = serde_json::Map::new();
    let (a, b) = (a.as_object().unwrap_or(&empty), b.as_object().unwrap_or(&empty));
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).filter(|k| a.get(*k) != b.get(*k)).collect();
    keys.sort();
    keys.dedup();
    keys.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_from_names() {
        assert_eq!(role("rp"), Role { parametric: true, reciprocity: None, nol_base: None });
        assert_eq!(role("single-mlp"), Role { parametric: false, reciprocity: Some("none"), nol_base: None });
        assert_eq!(role("additive-shared+enhanced+swap").reciprocity, Some("swap"));
        let r = role("additive-separate+exact+nol2");
        assert_eq!((r.reciprocity, r.nol_base.as_deref()), (Some("exact"), Some("additive-separate+exact")));
        let c = StudyConfig::default_small();
        assert!(in_tab1("disney", &c) && in_tab1("single-mlp+exact", &c));
        assert!(!in_tab1("single-mlp+swap", &c) && !in_tab1("single-mlp", &c) && !in_tab1("single-mlp+exact+nol3", &c));
        assert_eq!(short_label("additive-shared+enhanced+exact", &c), "add-shared+enh");
        assert_eq!(short_label("single-mlp+swap", &c), "single-mlp+swap");
        // The paper's row of a variant, whatever its reciprocity strategy; none for an ablation.
        assert_eq!(paper_tab1("additive-shared+enhanced+exact").unwrap()[1], 51.95);
        assert_eq!(paper_tab1("rp").unwrap()[4], 6.025);
        assert!(paper_tab1("single-mlp+exact+nol3").is_none());
    }

    /// Tab. 2 deltas by hand: two objects, variant − base per object, averaged.
    #[test]
    fn tab2_delta_by_hand() {
        let sc = |rmse, psnr, dssim, lpips, flip| Scores { rmse, psnr, dssim, lpips, flip };
        let pairs = [
            (sc(5.0, 30.0, 2.0, Some(4.0), 10.0), sc(4.0, 31.0, 1.5, Some(3.0), 9.0)),
            (sc(3.0, 25.0, 1.0, Some(2.0), 6.0), sc(3.5, 24.0, 1.5, Some(2.5), 7.0)),
        ];
        let d = mean_delta(&pairs);
        // ((5-4) + (3-3.5)) / 2 = 0.25; ((30-31) + (25-24)) / 2 = 0; ((2-1.5) + (1-1.5)) / 2 = 0;
        // ((4-3) + (2-2.5)) / 2 = 0.25; ((10-9) + (6-7)) / 2 = 0.
        assert_eq!(d, sc(0.25, 0.0, 0.0, Some(0.25), 0.0));
        // LPIPS missing for one object: no LPIPS delta rather than a partial mean.
        let mut p2 = pairs;
        p2[1].1.lpips = None;
        assert_eq!(mean_delta(&p2).lpips, None);
        assert_eq!(signed(0.25, 2), "+0.25");
        assert_eq!(signed(-0.094, 2), "-0.09");
    }
}
