//! `trainer compare`: the study's image metrics (PSNR, DSSIM, LPIPS, HDR-FLIP) for any pair of linear
//! renderings, so that images from other renderers are scored exactly as the study scores its own.
//!
//! Both images are **linear** HDR RGB in OpenEXR files; the metrics are computed by the same code the
//! study runs on every test view ([`PreparedReference`]): PSNR, DSSIM and LPIPS on the sRGB encoding
//! (values clamped to [0, 1], no exposure scaling), HDR-FLIP on the linear values with its exposure range
//! taken from the reference's object pixels. An optional mask PNG (object where any channel is non-zero)
//! restricts them to the object as in the study: the test's background is replaced by the reference's,
//! PSNR and HDR-FLIP average over object pixels, DSSIM over windows centred on them.
//!
//! Input that cannot be scored is an error naming the file and the problem: a missing or unreadable
//! file, images of different sizes, a mask of another size or without any object pixel, NaN or infinite
//! pixel values, images too small for DSSIM's 11×11 window.

use std::path::{Path, PathBuf};

use nbrdf_scene::image::{read_exr, read_mask, RgbImage};
use serde::Serialize;

use crate::metrics::{ssim, ImageMetrics, Lpips, MaybeMetric, PreparedReference};
use crate::{Error, Result};

/// Arguments of `trainer compare`.
#[derive(clap::Args, Clone, Debug)]
pub struct CompareArgs {
    /// The reference rendering (linear RGB OpenEXR)
    pub reference: PathBuf,
    /// The rendering to score (linear RGB OpenEXR, same size)
    pub test: PathBuf,
    /// Object mask PNG of the same size (object where any channel is non-zero); whole frame without it
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Print the result as one JSON object instead of a table
    #[arg(long)]
    pub json: bool,
    /// LPIPS weights (safetensors); default `$NBRDF_DATA/lpips/alexnet-lpips-v0.1.safetensors`
    #[arg(long)]
    pub lpips: Option<PathBuf>,
}

/// The scores of one pair and what they were computed on.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// The reference file.
    pub reference: PathBuf,
    /// The scored file.
    pub test: PathBuf,
    /// The mask file, if any.
    pub mask: Option<PathBuf>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixels the metrics average over (the mask's object pixels, or all).
    pub pixels: usize,
    /// The metrics, as in the study's `results.json` (`psnr` is `null` for identical images: +∞).
    #[serde(flatten)]
    pub metrics: ImageMetrics,
}

/// Reads, checks and scores the pair the arguments name.
pub fn compare(args: &CompareArgs) -> Result<Comparison> {
    let reference = read_image(&args.reference, "reference")?;
    let test = read_image(&args.test, "test image")?;
    if (reference.width, reference.height) != (test.width, test.height) {
        return Err(Error::Invalid(format!(
            "image sizes differ: reference {} is {}×{}, test image {} is {}×{}",
            args.reference.display(),
            reference.width,
            reference.height,
            args.test.display(),
            test.width,
            test.height
        )));
    }
    let side = ssim::WINDOW as u32;
    if reference.width < side || reference.height < side {
        return Err(Error::Invalid(format!(
            "{} is {}×{}: DSSIM needs at least {side}×{side} pixels",
            args.reference.display(),
            reference.width,
            reference.height
        )));
    }
    let mask = match &args.mask {
        Some(path) => Some(read_object_mask(path, reference.width, reference.height)?),
        None => None,
    };
    let lpips = Lpips::load_or_na(args.lpips.as_deref());
    let metrics = PreparedReference::new(&reference, mask.as_deref(), &lpips).evaluate(&test);
    Ok(Comparison {
        reference: args.reference.clone(),
        test: args.test.clone(),
        mask: args.mask.clone(),
        width: reference.width,
        height: reference.height,
        pixels: mask.as_ref().map_or(reference.data.len(), |m| m.iter().filter(|&&k| k).count()),
        metrics,
    })
}

/// `trainer compare`: scores the pair and prints the table or the JSON object.
pub fn run(args: &CompareArgs) -> Result<()> {
    let c = compare(args)?;
    if args.json {
        let text = serde_json::to_string_pretty(&c).map_err(|e| Error::Invalid(format!("JSON output: {e}")))?;
        println!("{text}");
    } else {
        print!("{}", table(&c));
    }
    Ok(())
}

/// The human-readable report: one metric per line, unscaled (the paper's tables scale DSSIM, LPIPS
/// and HDR-FLIP by 100).
pub fn table(c: &Comparison) -> String {
    let m = &c.metrics;
    let psnr = if m.psnr.is_infinite() { "inf dB (identical)".to_string() } else { format!("{:.4} dB", m.psnr) };
    let lpips = match &m.lpips {
        MaybeMetric::Value(v) => format!("{v:.6}"),
        MaybeMetric::NotAvailable { na } => na.clone(),
    };
    let over = match &c.mask {
        Some(p) => format!("{} object pixels of {} (mask {})", c.pixels, c.width as usize * c.height as usize, p.display()),
        None => format!("all {} pixels (no mask)", c.pixels),
    };
    format!(
        "reference  {}\ntest       {}\nsize       {}×{}, metrics over {over}\nPSNR       {psnr}\nDSSIM      {:.6}\nLPIPS      {lpips}\nHDR-FLIP   {:.6}\n",
        c.reference.display(),
        c.test.display(),
        c.width,
        c.height,
        m.dssim,
        m.flip
    )
}

/// Reads a linear EXR and refuses NaN or infinite values, which no metric can score.
fn read_image(path: &Path, what: &str) -> Result<RgbImage> {
    // The core's errors name the file already.
    let img = read_exr(path).map_err(|e| Error::Invalid(format!("{what}: {e}")))?;
    if img.data.is_empty() {
        return Err(Error::Invalid(format!("{what} {}: the image has no pixels", path.display())));
    }
    let bad = img.data.iter().filter(|p| p.iter().any(|c| !c.is_finite())).count();
    if let Some(first) = img.data.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        let (x, y) = (first % img.width as usize, first / img.width as usize);
        return Err(Error::Invalid(format!(
            "{what} {}: {bad} pixels are NaN or infinite (the first at x = {x}, y = {y}); no metric can score them",
            path.display()
        )));
    }
    Ok(img)
}

/// Reads the mask PNG and checks it against the images' size and for at least one object pixel.
fn read_object_mask(path: &Path, width: u32, height: u32) -> Result<Vec<bool>> {
    let (w, h, mask) = read_mask(path).map_err(|e| Error::Invalid(format!("mask: {e}")))?;
    if (w, h) != (width, height) {
        return Err(Error::Invalid(format!(
            "mask {} is {w}×{h}, but the images are {width}×{height}",
            path.display()
        )));
    }
    if !mask.iter().any(|&k| k) {
        return Err(Error::Invalid(format!(
            "mask {} has no object pixel (every pixel is 0): nothing to score",
            path.display()
        )));
    }
    Ok(mask)
}
