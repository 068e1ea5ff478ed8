//! Images in and out: linear HDR RGB as OpenEXR (f32), 8-bit sRGB PNG for viewing, 8/16-bit PNG in
//! (DiLiGenT-MV ships 16-bit linear PNGs), and the sRGB transfer functions. Every write is atomic.

use std::path::Path;
use std::string::ToString;
use std::vec::Vec;
use std::{format, vec};

use nbrdf::{io::write_atomic_with as write_atomic, Error, Rgb};

/// A row-major linear RGB image (`data[row * width + col]`).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, row-major from the top-left corner.
    pub data: Vec<Rgb>,
}

impl RgbImage {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        RgbImage { width, height, data: vec![[0.0; 3]; width as usize * height as usize] }
    }

    /// Wraps pixels, checking their count.
    pub fn from_data(width: u32, height: u32, data: Vec<Rgb>) -> Result<Self, Error> {
        let expected = width as usize * height as usize;
        if data.len() != expected {
            return Err(Error::SizeMismatch { what: "image pixel count", expected, found: data.len() });
        }
        Ok(RgbImage { width, height, data })
    }

    /// Errors unless `data` holds `width × height` pixels. The fields are public, so the writers check
    /// this before indexing rather than panicking inside the encoder.
    fn check(&self) -> Result<(), Error> {
        let expected = self.width as usize * self.height as usize;
        if self.data.len() != expected {
            return Err(Error::SizeMismatch { what: "image pixel count", expected, found: self.data.len() });
        }
        Ok(())
    }

    /// The pixel at `(col, row)`.
    #[inline]
    pub fn get(&self, col: u32, row: u32) -> Rgb {
        self.data[row as usize * self.width as usize + col as usize]
    }
}

/// The sRGB encoding (IEC 61966-2-1) of a linear value, clamped to `[0, 1]`.
///
/// ```
/// use nbrdf_scene::image::{srgb_encode, srgb_decode};
/// assert_eq!(srgb_encode(0.0), 0.0);
/// assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
/// assert!((srgb_encode(0.0031308) - 0.04045).abs() < 1e-5); // the two branches meet
/// assert!((srgb_decode(srgb_encode(0.2)) - 0.2).abs() < 1e-6);
/// ```
#[inline]
pub fn srgb_encode(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The sRGB decoding (IEC 61966-2-1): encoded value in `[0, 1]` to linear.
#[inline]
pub fn srgb_decode(y: f32) -> f32 {
    let y = if y.is_nan() { 0.0 } else { y.clamp(0.0, 1.0) };
    if y <= 0.040_45 {
        y / 12.92
    } else {
        ((y + 0.055) / 1.055).powf(2.4)
    }
}

fn exr_err(path: &Path, e: impl ToString) -> nbrdf::Error {
    Error::Parse { what: format!("OpenEXR file {}", path.display()), message: e.to_string() }
}

/// Writes a linear RGB image as a 32-bit float OpenEXR file (lossless, atomic).
pub fn write_exr(path: impl AsRef<Path>, img: &RgbImage) -> Result<(), nbrdf::Error> {
    use exr::prelude::*;
    img.check()?;
    let path = path.as_ref();
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = img.data[y * w + x];
        (p[0], p[1], p[2])
    });
    let image = Image::from_channels((w, img.height as usize), channels);
    write_atomic(path, |out| {
        image.write().to_buffered(out).map_err(|e| match e {
            exr::error::Error::Io(io) => io,
            other => std::io::Error::other(other.to_string()),
        })
    })
}

/// Reads the first RGB(A) layer of an OpenEXR file as linear f32 RGB (alpha dropped). A missing,
/// truncated or malformed file is an error naming the path.
pub fn read_exr(path: impl AsRef<Path>) -> Result<RgbImage, nbrdf::Error> {
    use exr::prelude::*;
    let path = path.as_ref();
    if !path.exists() {
        return Err(nbrdf::Error::io(path, &std::io::Error::from(std::io::ErrorKind::NotFound)));
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |res: Vec2<usize>, _| RgbImage::new(res.0 as u32, res.1 as u32),
        |img: &mut RgbImage, pos: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.data[pos.1 * w + pos.0] = [r, g, b];
        },
    )
    .map_err(|e| exr_err(path, e))?;
    Ok(image.layer_data.channel_data.pixels)
}

/// The 8-bit sRGB code of a linear value (clamped to `[0, 1]`, NaN as 0).
///
/// ```
/// use nbrdf_scene::image::srgb8;
/// assert_eq!((srgb8(0.0), srgb8(1.0), srgb8(2.0), srgb8(f32::NAN)), (0, 255, 255, 0));
/// assert_eq!(srgb8(0.216), 128); // linear 0.216 is mid-grey in sRGB
/// ```
#[inline]
pub fn srgb8(x: f32) -> u8 {
    (srgb_encode(x) * 255.0).round() as u8
}

/// Writes an 8-bit sRGB PNG of a linear image scaled by `exposure` (values clamped to `[0, 1]`).
pub fn write_png_srgb(path: impl AsRef<Path>, img: &RgbImage, exposure: f32) -> Result<(), Error> {
    img.check()?;
    let bytes: Vec<u8> = img.data.iter().flat_map(|p| p.map(|c| srgb8(c * exposure))).collect();
    write_png(path.as_ref(), img.width, img.height, ::image::ExtendedColorType::Rgb8, &bytes)
}

/// Writes an 8-bit RGB PNG from code values (`width × height` pixels, 3 bytes each, row-major),
/// atomically: figures and colour maps that are already 8-bit.
pub fn write_png_rgb8(path: impl AsRef<Path>, width: u32, height: u32, rgb: &[u8]) -> Result<(), Error> {
    let expected = width as usize * height as usize * 3;
    if rgb.len() != expected {
        return Err(Error::SizeMismatch { what: "RGB8 byte count", expected, found: rgb.len() });
    }
    write_png(path.as_ref(), width, height, ::image::ExtendedColorType::Rgb8, rgb)
}

/// Writes an 8-bit grey PNG (masks: 255 inside, 0 outside).
pub fn write_png_mask(path: impl AsRef<Path>, width: u32, height: u32, mask: &[bool]) -> Result<(), Error> {
    let expected = width as usize * height as usize;
    if mask.len() != expected {
        return Err(Error::SizeMismatch { what: "mask pixel count", expected, found: mask.len() });
    }
    let bytes: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    write_png(path.as_ref(), width, height, ::image::ExtendedColorType::L8, &bytes)
}

/// Writes a 16-bit RGB PNG from raw code values (as DiLiGenT-MV stores its images), atomically.
pub fn write_png16(path: impl AsRef<Path>, width: u32, height: u32, rgb: &[[u16; 3]]) -> Result<(), Error> {
    let expected = width as usize * height as usize;
    if rgb.len() != expected {
        return Err(Error::SizeMismatch { what: "image pixel count", expected, found: rgb.len() });
    }
    // PNG stores 16-bit samples big-endian; `image` takes them in native order.
    let bytes: Vec<u8> = rgb.iter().flat_map(|p| p.iter().flat_map(|c| c.to_ne_bytes())).collect();
    write_png(path.as_ref(), width, height, ::image::ExtendedColorType::Rgb16, &bytes)
}

fn write_png(path: &Path, width: u32, height: u32, color: ::image::ExtendedColorType, bytes: &[u8]) -> Result<(), Error> {
    use ::image::ImageEncoder;
    write_atomic(path, |out| {
        ::image::codecs::png::PngEncoder::new(out)
            .write_image(bytes, width, height, color)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Reads an 8- or 16-bit PNG (grey, grey-alpha, RGB or RGBA) as raw code values divided by the
/// largest code (255 or 65535), with no transfer function: DiLiGenT-MV's 16-bit PNGs are linear.
pub fn read_png(path: impl AsRef<Path>) -> Result<RgbImage, Error> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
    let dynimg = ::image::ImageReader::with_format(std::io::BufReader::new(file), ::image::ImageFormat::Png)
        .decode()
        .map_err(|e| Error::Parse { what: format!("PNG file {}", path.display()), message: e.to_string() })?;
    let rgb = dynimg.to_rgb32f_raw();
    Ok(rgb)
}

trait ToRgb32fRaw {
    fn to_rgb32f_raw(&self) -> RgbImage;
}

impl ToRgb32fRaw for ::image::DynamicImage {
    /// `image`'s own float conversion would be fine for 16-bit data but applies no transfer function
    /// either; spelled out here so that the scaling (code / max code) is explicit.
    fn to_rgb32f_raw(&self) -> RgbImage {
        let (w, h) = (self.width(), self.height());
        let data: Vec<Rgb> = match self {
            ::image::DynamicImage::ImageLuma16(_)
            | ::image::DynamicImage::ImageLumaA16(_)
            | ::image::DynamicImage::ImageRgb16(_)
            | ::image::DynamicImage::ImageRgba16(_) => {
                self.to_rgb16().pixels().map(|p| p.0.map(|c| c as f32 / 65535.0)).collect()
            }
            _ => self.to_rgb8().pixels().map(|p| p.0.map(|c| c as f32 / 255.0)).collect(),
        };
        RgbImage { width: w, height: h, data }
    }
}

/// Reads a mask PNG: a pixel is inside where any channel is non-zero.
pub fn read_mask(path: impl AsRef<Path>) -> Result<(u32, u32, Vec<bool>), Error> {
    let img = read_png(path)?;
    Ok((img.width, img.height, img.data.iter().map(|p| p.iter().any(|&c| c > 0.0)).collect()))
}
