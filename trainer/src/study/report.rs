//! The study's report: per-model means over the objects in the layout of the paper's tables (Tab. 1
//! image and BRDF metrics, Tab. 3 reciprocity, Tab. 4 energy, and accuracy against cost), plus every
//! per-job number in `results.json` and `results.csv`.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::{JobResult, StudyConfig};
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
    pub train_wall_s: f64,
    pub eval_ns_per_query: f64,
    pub n_weights: usize,
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
                energy_median_above_one: (!medians.is_empty()).then(|| mean(medians.into_iter())),
                train_wall_s: mean(rs.iter().map(|r| r.train_wall_s)),
                eval_ns_per_query: mean(rs.iter().map(|r| r.eval.eval_ns_per_query)),
                n_weights: rs[0].n_weights,
                size_bytes: rs[0].size_bytes,
            }
        })
        .collect()
}

fn opt(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or("n/a".into(), |x| format!("{:.*}", digits, x * scale))
}

/// The Markdown report.
pub fn markdown(config: &StudyConfig, results: &[JobResult]) -> String {
    let s = summarize(results);
    let mut md = String::new();
    let scenes: Vec<String> = config.scenes.iter().map(|sc| format!("{} / {}", sc.mesh, sc.material)).collect();
    let _ = writeln!(md, "# Neural BRDF study\n");
    let _ = writeln!(
        md,
        "Objects: {}. Images {}×{}, {} views ({} train), {} / {} lights per train / test view, σ = {}. \
         Position input `{}`, {} steps at batch {}. Reciprocity over {} test pairs; energy over {} pairs × {} \
         view samples (paper: 50k × 20k). Every number is a mean over the objects; per-job values are in \
         `results.json` / `results.csv`.\n",
        scenes.join(", "),
        config.size,
        config.size,
        config.views,
        config.train_views,
        config.train_lights,
        config.test_lights,
        config.sigma,
        config.position,
        config.steps,
        config.batch,
        config.reciprocity_pairs,
        config.energy_pairs,
        config.energy_samples
    );
    let _ = writeln!(md, "## Tab. 1 — reconstruction quality\n");
    let _ = writeln!(md, "DSSIM, LPIPS and FLIP ×100, as in the paper. ↑ higher is better, ↓ lower.\n");
    let _ = writeln!(md, "| model | PSNR ↑ | DSSIM ↓ | LPIPS ↓ | FLIP ↓ | RMSE ∛ ↓ |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|");
    for m in &s {
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.3} | {} | {:.3} | {:.4} |",
            m.model,
            m.psnr,
            m.dssim * 100.0,
            opt(m.lpips, 100.0, 3),
            m.flip * 100.0,
            m.brdf_rmse_cbrt
        );
    }
    let _ = writeln!(md, "\n## Tab. 3 — reciprocity\n");
    let _ = writeln!(md, "RMSE of f(x, l, v) − f(x, v, l) in 1/sr (0 by construction for parametric models and Θ).\n");
    let _ = writeln!(md, "| model | reciprocity RMSE ↓ |");
    let _ = writeln!(md, "|---|---:|");
    for m in &s {
        let _ = writeln!(md, "| {} | {:.3e} |", m.model, m.reciprocity_rmse);
    }
    let _ = writeln!(md, "\n## Tab. 4 — energy conservation\n");
    let _ = writeln!(md, "Share of point-light pairs whose albedo is above 1 by more than 3 standard errors, and the median albedo of those.\n");
    let _ = writeln!(md, "| model | % > 1 | μ.5 > 1 |");
    let _ = writeln!(md, "|---|---:|---:|");
    for m in &s {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {} |",
            m.model,
            m.energy_share_above_one * 100.0,
            m.energy_median_above_one.map_or("all valid".into(), |v| format!("{v:.3}"))
        );
    }
    let _ = writeln!(md, "\n## Accuracy versus cost\n");
    let _ = writeln!(md, "Training wall time on this machine (CPU), core evaluation ns per query (one thread, point prepared), model file size.\n");
    let _ = writeln!(md, "| model | train s | eval ns/query | parameters | size (KiB) | PSNR ↑ | RMSE ∛ ↓ |");
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|");
    for m in &s {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.0} | {} | {:.1} | {:.2} | {:.4} |",
            m.model,
            m.train_wall_s,
            m.eval_ns_per_query,
            m.n_weights,
            m.size_bytes as f64 / 1024.0,
            m.psnr,
            m.brdf_rmse_cbrt
        );
    }
    md
}

/// One CSV row per job.
pub fn csv(results: &[JobResult]) -> String {
    let mut out = String::from(
        "scene,model,psnr,dssim,lpips,flip,brdf_rmse_cbrt,brdf_samples,reciprocity_rmse,energy_share_above_one,\
         energy_median_above_one,energy_mean_albedo,train_wall_s,eval_ns_per_query,n_weights,size_bytes,steps,final_loss\n",
    );
    let o = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
    for r in results {
        let e = &r.eval;
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
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
            r.final_loss
        );
    }
    out
}

/// Writes `REPORT.md`, `results.json` (config, per-model summary, every job) and `results.csv`.
pub fn write(out: &Path, config: &StudyConfig, results: &[JobResult]) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let put = |name: &str, bytes: &[u8]| crate::train::write_atomic(&out.join(name), bytes);
    put("REPORT.md", markdown(config, results).as_bytes())?;
    put("results.csv", csv(results).as_bytes())?;
    let json = serde_json::json!({ "config": config, "summary": summarize(results), "jobs": results });
    put("results.json", &serde_json::to_vec_pretty(&json).map_err(|e| Error::io(out, e))?)?;
    Ok(())
}

/// Reads the `results.json` of several study outputs (e.g. one per shard) and joins their jobs; a job
/// (scene, model) found twice keeps the later folder's result. The config is the first folder's.
pub fn merge(dirs: &[std::path::PathBuf]) -> Result<(StudyConfig, Vec<JobResult>)> {
    #[derive(serde::Deserialize)]
    struct Saved {
        config: StudyConfig,
        jobs: Vec<JobResult>,
    }
    let mut config = None;
    let mut jobs: Vec<JobResult> = Vec::new();
    for d in dirs {
        let p = d.join("results.json");
        let bytes = std::fs::read(&p).map_err(|e| Error::io(&p, e))?;
        let saved: Saved =
            serde_json::from_slice(&bytes).map_err(|e| Error::Invalid(format!("{}: {e}", p.display())))?;
        config.get_or_insert(saved.config);
        for j in saved.jobs {
            match jobs.iter_mut().find(|k| k.scene == j.scene && k.model == j.model) {
                Some(k) => *k = j,
                None => jobs.push(j),
            }
        }
    }
    let config = config.ok_or_else(|| Error::Invalid("study merge: give at least one folder".into()))?;
    Ok((config, jobs))
}
