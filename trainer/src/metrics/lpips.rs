//! LPIPS (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual Metric"),
//! AlexNet variant v0.1, on the sRGB-encoded renderings (paper Sec. 6, Tab. 1), with candle-core's
//! conv2d and max-pool on the CPU.
//!
//! The network, exactly as the reference `lpips` package (v0.1, `net='alex'`, `spatial=False`) and the
//! shared data's README describe it:
//! 1. sRGB in [0, 1] → `2x - 1` → `(x - shift) / scale` per channel (`ScalingLayer`).
//! 2. AlexNet features: conv 11×11/4 pad 2, ReLU (tap 1), max-pool 3/2, conv 5×5 pad 2, ReLU (tap 2),
//!    max-pool 3/2, conv 3×3 pad 1, ReLU (tap 3), conv 3×3 pad 1, ReLU (tap 4), conv 3×3 pad 1, ReLU (tap 5).
//! 3. Each tap unit-normalised over channels, `f / (‖f‖₂ + 1e-10)` (`normalize_tensor`); the squared
//!    difference of the two images' taps weighted by the tap's 1×1 linear head (no bias), averaged over
//!    the tap's pixels; the five averages summed.
//!
//! The weights are read from `alexnet-lpips-v0.1.safetensors` (OIHW), by default
//! `$NBRDF_DATA/lpips/...`. They are not ours to ship, so a missing file is not an error for the study:
//! [`Lpips::load_or_na`] returns the "n/a: ..." text the report prints instead of a number.

use std::path::{Path, PathBuf};

use candle_core::{DType, Device, Tensor};
use nbrdf_scene::image::RgbImage;

use super::check_pair;

/// Location of the weights inside the shared data directory.
pub const WEIGHTS_IN_DATA: &str = "lpips/alexnet-lpips-v0.1.safetensors";

/// `ScalingLayer.shift` of the reference implementation (ImageNet mean in [-1, 1] units).
const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// `ScalingLayer.scale` of the reference implementation (ImageNet standard deviation in [-1, 1] units).
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// `normalize_tensor`'s epsilon.
const EPS: f64 = 1e-10;
/// `(padding, stride)` of AlexNet's five convolutions (torchvision `alexnet().features`).
const CONV: [(usize, usize); 5] = [(2, 4), (2, 1), (1, 1), (1, 1), (1, 1)];
/// Smallest side the network accepts: below 31 px the second max-pool has no output.
pub const MIN_SIDE: u32 = 31;

/// The shared data directory: `$NBRDF_DATA`, else `../shared/data` relative to the working directory
/// (the project root's convention), else the same path from the workspace root this crate was built in,
/// so that `cargo test -p trainer` (run from `trainer/`) finds it too.
pub fn data_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("NBRDF_DATA") {
        return PathBuf::from(dir);
    }
    let cwd = PathBuf::from("../shared/data");
    if cwd.is_dir() {
        return cwd;
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    if built.is_dir() {
        built
    } else {
        cwd
    }
}

/// The default weights file, `data_dir()/lpips/alexnet-lpips-v0.1.safetensors`.
pub fn default_weights() -> PathBuf {
    data_dir().join(WEIGHTS_IN_DATA)
}

/// The unit-normalised AlexNet taps of one image (see [`Lpips::prepare`]).
#[derive(Debug, Clone)]
pub struct LpipsFeatures {
    taps: Vec<Tensor>,
    width: u32,
    height: u32,
}

/// The loaded LPIPS network.
#[derive(Debug, Clone)]
pub struct Lpips {
    /// `(weight OIHW, bias reshaped to 1×C×1×1)` of the five convolutions.
    convs: Vec<(Tensor, Tensor)>,
    /// The five linear heads, `1×C×1×1`.
    heads: Vec<Tensor>,
    device: Device,
}

fn err(e: candle_core::Error) -> String {
    e.to_string()
}

impl Lpips {
    /// Loads the weights from a safetensors file (keys `features.conv{0..4}.{weight,bias}`,
    /// `lin{0..4}.weight`), checking every shape.
    pub fn load(path: &Path) -> Result<Self, String> {
        let device = Device::Cpu;
        let tensors = candle_core::safetensors::load(path, &device)
            .map_err(|e| format!("cannot read LPIPS weights {}: {e}", path.display()))?;
        let get = |name: &str| -> Result<Tensor, String> {
            let t = tensors.get(name).ok_or_else(|| format!("LPIPS weights {} lack {name}", path.display()))?;
            t.to_dtype(DType::F32).map_err(err)
        };
        // (out, in, k) of each convolution, torchvision AlexNet.
        let shapes = [(64, 3, 11), (192, 64, 5), (384, 192, 3), (256, 384, 3), (256, 256, 3)];
        let mut convs = Vec::new();
        let mut heads = Vec::new();
        for (i, &(o, c, k)) in shapes.iter().enumerate() {
            let w = get(&format!("features.conv{i}.weight"))?;
            let b = get(&format!("features.conv{i}.bias"))?;
            let l = get(&format!("lin{i}.weight"))?;
            if w.dims() != [o, c, k, k] || b.dims() != [o] || l.dims() != [1, o, 1, 1] {
                return Err(format!(
                    "LPIPS weights {}: layer {i} has shapes {:?}, {:?}, {:?}, expected [{o}, {c}, {k}, {k}], [{o}], [1, {o}, 1, 1]",
                    path.display(),
                    w.dims(),
                    b.dims(),
                    l.dims()
                ));
            }
            convs.push((w, b.reshape((1, o, 1, 1)).map_err(err)?));
            heads.push(l);
        }
        Ok(Self { convs, heads, device })
    }

    /// Loads `path` (or [`default_weights`]); where that fails, the reason as the study's table cell
    /// text, e.g. `"n/a: weights not found at ../shared/data/lpips/alexnet-lpips-v0.1.safetensors"`.
    pub fn load_or_na(path: Option<&Path>) -> Result<Self, String> {
        let path = path.map(Path::to_path_buf).unwrap_or_else(default_weights);
        if !path.is_file() {
            return Err(format!("n/a: weights not found at {}", path.display()));
        }
        Self::load(&path).map_err(|e| format!("n/a: {e}"))
    }

    /// The LPIPS distance between two **sRGB-encoded** images (values in [0, 1]) of equal size, at least
    /// [`MIN_SIDE`] pixels on each side: 0 for identical images, symmetric, about 0.1-0.7 for clearly
    /// different ones. Masking, if any, is the caller's (make the backgrounds equal first).
    pub fn distance(&self, a: &RgbImage, b: &RgbImage) -> Result<f64, String> {
        check_pair(a, b, None);
        self.distance_to(&self.prepare(a)?, b)
    }

    /// The network's features of a reference image, to compare several test images (one per model)
    /// against it without running the reference through AlexNet each time (half the cost).
    pub fn prepare(&self, reference: &RgbImage) -> Result<LpipsFeatures, String> {
        if reference.width < MIN_SIDE || reference.height < MIN_SIDE {
            return Err(format!(
                "LPIPS needs at least {MIN_SIDE}×{MIN_SIDE} pixels, got {}×{}",
                reference.width, reference.height
            ));
        }
        Ok(LpipsFeatures {
            taps: self.features(reference).map_err(err)?,
            width: reference.width,
            height: reference.height,
        })
    }

    /// [`Lpips::distance`] against a [`Lpips::prepare`]d reference.
    pub fn distance_to(&self, reference: &LpipsFeatures, test: &RgbImage) -> Result<f64, String> {
        if (reference.width, reference.height) != (test.width, test.height) {
            return Err(format!(
                "LPIPS image sizes differ: {}×{} vs {}×{}",
                reference.width, reference.height, test.width, test.height
            ));
        }
        let fb = self.prepare(test)?.taps;
        let mut total = 0.0f64;
        for ((x, y), head) in reference.taps.iter().zip(&fb).zip(&self.heads) {
            // Zhang et al. 2018, Eq. 1: Σ_l mean_hw ‖w_l ⊙ (ŷ_l - ŷ'_l)‖² with unit-normalised features.
            let d = (x - y).and_then(|d| d.sqr()).map_err(err)?;
            let weighted = d.broadcast_mul(head).and_then(|t| t.sum_keepdim(1)).map_err(err)?;
            total += f64::from(weighted.mean_all().and_then(|m| m.to_scalar::<f32>()).map_err(err)?);
        }
        Ok(total)
    }

    /// The five unit-normalised ReLU taps of one image.
    fn features(&self, img: &RgbImage) -> candle_core::Result<Vec<Tensor>> {
        let (w, h) = (img.width as usize, img.height as usize);
        // Planar NCHW, scaled to [-1, 1] then by the ScalingLayer.
        let mut planar = vec![0.0f32; 3 * w * h];
        for (i, p) in img.data.iter().enumerate() {
            for c in 0..3 {
                planar[c * w * h + i] = ((2.0 * p[c] - 1.0) - SHIFT[c]) / SCALE[c];
            }
        }
        let mut x = Tensor::from_vec(planar, (1, 3, h, w), &self.device)?;
        let mut taps = Vec::with_capacity(5);
        for (i, ((weight, bias), &(pad, stride))) in self.convs.iter().zip(&CONV).enumerate() {
            if i == 1 || i == 2 {
                x = x.max_pool2d_with_stride(3, 2)?;
            }
            x = x.conv2d(weight, pad, stride, 1, 1)?.broadcast_add(bias)?.relu()?;
            let norm = (x.sqr()?.sum_keepdim(1)?.sqrt()? + EPS)?;
            taps.push(x.broadcast_div(&norm)?);
        }
        Ok(taps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // The integer test patterns of the SSIM test, in [0, 1].
    use crate::metrics::ssim::tests::pair;

    fn weights() -> Option<Lpips> {
        match Lpips::load_or_na(None) {
            Ok(l) => Some(l),
            Err(reason) => {
                eprintln!("skipping LPIPS test: {reason} (set NBRDF_DATA to the shared data directory)");
                None
            }
        }
    }

    #[test]
    fn missing_weights_give_a_reason_not_an_error() {
        let reason = Lpips::load_or_na(Some(Path::new("/nonexistent/lpips.safetensors"))).unwrap_err();
        assert_eq!(reason, "n/a: weights not found at /nonexistent/lpips.safetensors");
    }

    #[test]
    fn identical_is_zero_perturbed_is_positive_and_symmetric() {
        let Some(lpips) = weights() else { return };
        let (x, y) = pair(64, 48);
        assert_eq!(lpips.distance(&x, &x).unwrap(), 0.0);
        let d = lpips.distance(&x, &y).unwrap();
        let e = lpips.distance(&y, &x).unwrap();
        assert!(d > 0.0 && (d - e).abs() < 1e-6 * d.max(1e-3), "{d} vs {e}");
        // An independent float64 numpy implementation of the same network (explicit shifted-window
        // convolutions, written from the reference `lpips` package's code) gives 0.3370828362882349.
        assert!((d - 0.337_082_836_288_234_9).abs() < 1e-4, "LPIPS {d}");
        // A slight brightening is much closer than the structural change.
        let brighter = RgbImage { data: x.data.iter().map(|p| p.map(|v| (v * 1.02).min(1.0))).collect(), ..x.clone() };
        let s = lpips.distance(&x, &brighter).unwrap();
        assert!(0.0 < s && s < d, "{s} vs {d}");
        assert!(lpips.distance(&pair(30, 64).0, &pair(30, 64).1).is_err());
        // A prepared reference gives the same value.
        let prepared = lpips.prepare(&x).unwrap();
        assert_eq!(lpips.distance_to(&prepared, &y).unwrap(), d);
        assert!(lpips.distance_to(&prepared, &pair(64, 64).1).is_err());
    }
}
