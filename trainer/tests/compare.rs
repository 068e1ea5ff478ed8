//! `trainer compare` on image pairs whose scores are known in closed form, and on every kind of input it
//! must refuse: each refusal exits non-zero and names the file and what is wrong with it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use nbrdf_scene::image::{srgb_decode, write_exr, write_png_mask, RgbImage};

const W: u32 = 48;
const H: u32 = 40;

fn trainer(args: &[&Path]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_trainer")).arg("compare").args(args).output().unwrap()
}

/// A linear image whose sRGB encoding is `srgb(x, y)`.
fn from_srgb(srgb: impl Fn(u32, u32) -> [f32; 3]) -> RgbImage {
    let data = (0..W * H).map(|i| srgb(i % W, i / W).map(srgb_decode)).collect();
    RgbImage::from_data(W, H, data).unwrap()
}

/// A textured reference: sRGB values in [0.2, 0.8], away from the clamp at 0 and 1.
fn reference_srgb(x: u32, y: u32) -> [f32; 3] {
    [0.2 + 0.6 * (x as f32 / W as f32), 0.5 + 0.3 * ((x + 2 * y) % 7) as f32 / 7.0 - 0.15, 0.2 + 0.6 * (y as f32 / H as f32)]
}

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

struct Files {
    _dir: tempfile::TempDir,
    root: PathBuf,
}

impl Files {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        Files { _dir: dir, root }
    }

    fn exr(&self, name: &str, img: &RgbImage) -> PathBuf {
        let p = self.root.join(name);
        write_exr(&p, img).unwrap();
        p
    }

    fn mask(&self, name: &str, w: u32, h: u32, keep: impl Fn(u32, u32) -> bool) -> PathBuf {
        let p = self.root.join(name);
        let m: Vec<bool> = (0..w * h).map(|i| keep(i % w, i / w)).collect();
        write_png_mask(&p, w, h, &m).unwrap();
        p
    }
}

#[test]
fn an_image_against_itself_scores_perfectly() {
    let f = Files::new();
    let a = f.exr("a.exr", &from_srgb(reference_srgb));
    let j = json(&trainer(&[&a, &a, Path::new("--json")]));
    // +∞ dB is written as JSON null (as in the study's results.json).
    assert!(j["psnr"].is_null(), "{j}");
    assert_eq!(j["dssim"].as_f64(), Some(0.0));
    assert_eq!(j["flip"].as_f64(), Some(0.0));
    assert_eq!((j["width"].as_u64(), j["height"].as_u64(), j["pixels"].as_u64()), (Some(48), Some(40), Some(48 * 40)));
    // LPIPS is 0 with the weights, otherwise n/a with the reason.
    assert!(j["lpips"].as_f64() == Some(0.0) || j["lpips"]["na"].as_str().is_some_and(|r| r.starts_with("n/a")), "{j}");
    let text = trainer(&[&a, &a]);
    assert!(text.status.success());
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("inf dB (identical)") && text.contains("HDR-FLIP") && text.contains("all 1920 pixels"), "{text}");
}

#[test]
fn psnr_of_a_known_perturbation_matches_the_closed_form() {
    // Every sRGB channel off by ±δ: MSE = δ², PSNR = −20 log10 δ = 40 dB for δ = 0.01. The background
    // (outside the mask) is off by 0.3, which the masked score must ignore.
    let f = Files::new();
    let delta = 0.01f32;
    let inside = |x: u32, y: u32| (8..40).contains(&x) && (6..34).contains(&y);
    let a = f.exr("ref.exr", &from_srgb(reference_srgb));
    let b = f.exr(
        "test.exr",
        &from_srgb(|x, y| {
            let s = if (x + y) % 2 == 0 { delta } else { -delta };
            let d = if inside(x, y) { s } else { 0.3 * s / delta.abs() };
            reference_srgb(x, y).map(|v| v + d)
        }),
    );
    let mask = f.mask("mask.png", W, H, inside);
    let j = json(&trainer(&[&a, &b, Path::new("--mask"), &mask, Path::new("--json")]));
    let psnr = j["psnr"].as_f64().unwrap();
    // f32 round trips through decode and encode move each value by ~1e-7, i.e. the PSNR by ~1e-4 dB.
    assert!((psnr - 40.0).abs() < 2e-3, "PSNR {psnr}, expected 40 dB");
    assert_eq!(j["pixels"].as_u64(), Some(32 * 28));
    assert!(j["dssim"].as_f64().unwrap() > 0.0 && j["flip"].as_f64().unwrap() > 0.0, "{j}");
    // Without the mask the background's ±0.3 counts too.
    let whole = json(&trainer(&[&a, &b, Path::new("--json")]));
    assert!(whole["psnr"].as_f64().unwrap() < 20.0, "{whole}");
}

/// Runs a refused comparison: exit status 1 and a message that contains every `needle`.
fn refused(args: &[&Path], needles: &[&str]) {
    let out = trainer(args);
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {message}");
    assert!(out.stdout.is_empty(), "{args:?} printed scores");
    for n in needles {
        assert!(message.contains(n), "{args:?}: message lacks {n:?}: {message}");
    }
}

#[test]
fn malformed_or_mismatched_inputs_are_refused_naming_the_file_and_the_problem() {
    let f = Files::new();
    let a = f.exr("a.exr", &from_srgb(reference_srgb));
    let missing = f.root.join("missing.exr");
    refused(&[&a, &missing], &["missing.exr", "test image"]);
    refused(&[&missing, &a], &["missing.exr", "reference"]);

    let not_exr = f.root.join("notes.exr");
    std::fs::write(&not_exr, "this is text, not OpenEXR").unwrap();
    refused(&[&a, &not_exr], &["notes.exr", "OpenEXR"]);

    let small = f.exr("small.exr", &RgbImage::new(32, 40));
    refused(&[&a, &small], &["a.exr", "small.exr", "48×40", "32×40", "differ"]);

    let mut nan = from_srgb(reference_srgb);
    nan.data[3 * W as usize + 5][1] = f32::NAN;
    nan.data[7][0] = f32::INFINITY;
    let nan = f.exr("nan.exr", &nan);
    refused(&[&a, &nan], &["nan.exr", "2 pixels are NaN or infinite", "x = 7, y = 0"]);

    let wrong_mask = f.mask("wrong.png", 40, 48, |_, _| true);
    refused(&[&a, &a, Path::new("--mask"), &wrong_mask], &["wrong.png", "40×48", "48×40"]);
    let empty_mask = f.mask("empty.png", W, H, |_, _| false);
    refused(&[&a, &a, Path::new("--mask"), &empty_mask], &["empty.png", "no object pixel"]);
    let not_png = f.root.join("mask.png");
    std::fs::write(&not_png, [0u8; 16]).unwrap();
    refused(&[&a, &a, Path::new("--mask"), &not_png], &["mask.png", "PNG"]);

    let tiny = f.exr("tiny.exr", &RgbImage::new(8, 8));
    refused(&[&tiny, &tiny], &["tiny.exr", "8×8", "11×11"]);
}
