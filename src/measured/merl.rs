//! MERL `.binary` BRDF tables (Matusik et al. 2003, "A data-driven reflectance model"): the file format,
//! the reference lookup of MERL's `BRDFRead.cpp`, a trilinear lookup, and tabulation of any BRDF.
//!
//! # File format (`BRDFRead.cpp`, `read_brdf`)
//! - Header: three little-endian `i32`, the bin counts `(90, 90, 180)` of `(θh, θd, φd)`.
//! - Then `3 × 90 × 90 × 180` little-endian `f64`, channel-planar (all red, then all green, then all
//!   blue). Within a channel the flat index is `iφd + 180 (iθd + 90 iθh)`.
//! - Stored values are scaled: the BRDF in 1/sr is `value × (1/1500, 1.15/1500, 1.66/1500)` for R, G, B.
//! - Negative values mark bins without a valid measurement (configurations below the horizon); they
//!   evaluate to 0.
//!
//! # Bins (`BRDFRead.cpp`, `theta_half_index`, `theta_diff_index`, `phi_diff_index`)
//! - `θh` is binned non-linearly, `iθh = ⌊sqrt(θh / (π/2)) · 90⌋`, so bins are dense near the specular
//!   peak (`θh = 0`).
//! - `θd` linearly over [0, π/2): `iθd = ⌊θd / (π/2) · 90⌋`.
//! - `φd` is folded by π (the BRDF is unchanged under `φd → φd + π` by reciprocity), then binned linearly
//!   over [0, π): `iφd = ⌊(φd mod π) / π · 180⌋`.
//! - Every index is clamped into its range. `φh` is ignored: the table is isotropic.
//!
//! Because the reference lookup truncates, bin `i` stands for the index-space interval `[i, i + 1)`; this
//! module places its sample at the **bin centre** `i + ½`. Then the reference lookup is exactly a
//! nearest-sample lookup, [`MerlTable::tabulate`] samples where the lookup is most accurate, and the
//! trilinear lookup interpolates between centres (clamped at the θ ends, periodic in `φd` with period π).
//! The reference code does not document where inside a bin MERL's samples lie; readers that assume the
//! lower bin edge differ from this one by half a bin in the trilinear lookup only.

use alloc::vec;
use alloc::vec::Vec;

use crate::angles::{from_rusinkiewicz, theta_map, upper_hemisphere_pair, Rusinkiewicz};
use crate::brdf::{Brdf, BsdfSample};
use crate::math::sanitize;
use crate::sampling::{fit_proxy, fit_view_proxy_around, Proxy, ViewProxy};
use crate::{Error, Rgb, Vec3, BLACK};

/// Number of `θh` bins (header field 0).
pub const THETA_H_BINS: usize = 90;
/// Number of `θd` bins (header field 1).
pub const THETA_D_BINS: usize = 90;
/// Number of `φd` bins over [0, π) (header field 2).
pub const PHI_D_BINS: usize = 180;
/// Samples per colour channel.
pub const SAMPLES_PER_CHANNEL: usize = THETA_H_BINS * THETA_D_BINS * PHI_D_BINS;
/// Scale from stored value to BRDF (1/sr) per channel, `BRDFRead.cpp` (`RED_SCALE`, `GREEN_SCALE`,
/// `BLUE_SCALE`).
pub const CHANNEL_SCALES: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Size of the header in bytes.
pub const HEADER_BYTES: usize = 12;
/// Size of a complete `.binary` file in bytes (34,992,012).
pub const FILE_BYTES: usize = HEADER_BYTES + 3 * SAMPLES_PER_CHANNEL * 8;
/// The value [`MerlTable::tabulate`] stores in bins below the horizon; any negative value means "invalid".
pub const INVALID: f64 = -1.0;

const HALF_PI: f64 = core::f64::consts::FRAC_PI_2;
const PI: f64 = core::f64::consts::PI;

/// How [`MerlTable::eval_angles`] reads the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Lookup {
    /// The bin the angles fall in: the reference lookup of `BRDFRead.cpp` (`lookup_brdf_val`).
    #[default]
    Nearest,
    /// Trilinear interpolation between bin centres in index space (`√θh`, `θd`, `φd mod π`), clamped at
    /// the θ ends and periodic in `φd`. Invalid (negative) corners are left out and the weights of the
    /// others renormalised, so the horizon does not darken the neighbouring valid bins.
    Trilinear,
}

/// A MERL BRDF table: the raw stored values exactly as in the file (so that a file read and written
/// again is bit-identical), channel-planar, unscaled.
///
/// ```
/// use nbrdf::measured::merl::{MerlTable, FILE_BYTES};
/// let table = MerlTable::tabulate(|wi, wo| [wi.z * wo.z; 3]);
/// let bytes = table.to_bytes();
/// assert_eq!(bytes.len(), FILE_BYTES);
/// assert_eq!(MerlTable::from_bytes(&bytes).unwrap(), table);
/// ```
#[derive(Clone, PartialEq)]
pub struct MerlTable {
    /// `3 × SAMPLES_PER_CHANNEL` stored values, finite; negative = invalid.
    raw: Vec<f64>,
    /// The sampling proxy fitted to the table at construction (a function of `raw`).
    proxy: Proxy,
    /// The per-view sampling table fitted around `proxy` at construction; what sampling uses.
    view: ViewProxy,
}

impl core::fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // 4.4 million numbers are no use in a debug message.
        let invalid = self.raw.iter().filter(|v| **v < 0.0).count();
        f.debug_struct("MerlTable")
            .field("samples", &self.raw.len())
            .field("invalid", &invalid)
            .finish()
    }
}

impl MerlTable {
    /// The table over `raw` with its proxy fitted (what every constructor returns).
    fn with_proxy(raw: Vec<f64>) -> Self {
        let mut table = MerlTable { raw, proxy: Proxy::COSINE, view: ViewProxy::default() };
        table.proxy = fit_proxy(|wi, wo| table.eval(wi, wo));
        table.view = fit_view_proxy_around(|wi, wo| table.eval(wi, wo), &table.proxy);
        table
    }

    /// The proxy [`Brdf::sample`] draws from: [`fit_proxy`] on the nearest-bin lookup, fitted once at
    /// construction.
    pub fn proxy(&self) -> &Proxy {
        &self.proxy
    }

    /// The per-view sampling table [`Brdf::sample`] draws from ([`fit_view_proxy_around`] the
    /// [`proxy`](Self::proxy)); exported shaders sample the single proxy.
    pub fn view_proxy(&self) -> &ViewProxy {
        &self.view
    }

    /// Parses a `.binary` file (module docs for the format).
    ///
    /// Errors: [`Error::Truncated`] for a short header or sample block, [`Error::SizeMismatch`] for a
    /// header other than `(90, 90, 180)` or trailing bytes, [`Error::InvalidValue`] for a negative bin
    /// count, [`Error::NonFinite`] for a NaN or infinite sample.
    ///
    /// ```
    /// use nbrdf::{measured::MerlTable, Error};
    /// let err = MerlTable::from_bytes(&[90, 0, 0, 0]).unwrap_err();
    /// assert!(matches!(err, Error::Truncated { what: "MERL header", needed: 12, got: 4 }));
    /// ```
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        check_header(bytes)?;
        if bytes.len() < FILE_BYTES {
            return Err(Error::Truncated {
                what: "MERL samples",
                needed: FILE_BYTES,
                got: bytes.len(),
            });
        }
        if bytes.len() > FILE_BYTES {
            return Err(Error::SizeMismatch {
                what: "MERL file length in bytes (trailing data)",
                expected: FILE_BYTES,
                found: bytes.len(),
            });
        }
        let mut raw = Vec::with_capacity(3 * SAMPLES_PER_CHANNEL);
        for (index, chunk) in bytes[HEADER_BYTES..].chunks_exact(8).enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            let v = f64::from_le_bytes(b);
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    what: "MERL samples",
                    index,
                });
            }
            check_magnitude(v, index)?;
            raw.push(v);
        }
        Ok(Self::with_proxy(raw))
    }

    /// Builds a table from stored (unscaled) values, channel-planar as in the file.
    ///
    /// Errors: [`Error::SizeMismatch`] unless there are `3 × 90 × 90 × 180` values, [`Error::NonFinite`]
    /// for a NaN or infinite value.
    pub fn from_raw(raw: Vec<f64>) -> Result<Self, Error> {
        if raw.len() != 3 * SAMPLES_PER_CHANNEL {
            return Err(Error::SizeMismatch {
                what: "MERL sample count",
                expected: 3 * SAMPLES_PER_CHANNEL,
                found: raw.len(),
            });
        }
        if let Some(index) = raw.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "MERL samples",
                index,
            });
        }
        for (index, &v) in raw.iter().enumerate() {
            check_magnitude(v, index)?;
        }
        Ok(Self::with_proxy(raw))
    }

    /// The stored (unscaled) values, channel-planar; negative entries are invalid bins.
    pub fn raw(&self) -> &[f64] {
        &self.raw
    }

    /// The `.binary` file of this table: header `(90, 90, 180)`, then the stored values as `f64` LE.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FILE_BYTES);
        for n in [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS] {
            out.extend_from_slice(&(n as i32).to_le_bytes());
        }
        for v in &self.raw {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Tabulates a BRDF: every bin holds `brdf(wi, wo)` at its centre (module docs), with `φh = 0`.
    ///
    /// Bins whose centre puts `wi` or `wo` on or below the horizon hold [`INVALID`], like the unmeasured
    /// bins of the MERL files. NaN, infinite or negative values of `brdf` are stored as 0: a table holds
    /// only valid reflectance.
    ///
    /// ```
    /// use nbrdf::measured::MerlTable;
    /// let table = MerlTable::tabulate(|_, wo| [wo.z, 0.0, 1.0]);
    /// // Bin centre (iθh, iθd, iφd) = (0, 0, 0): both directions almost along the normal.
    /// let [th, td, pd] = MerlTable::bin_centre(0, 0, 0);
    /// let f = table.sample(MerlTable::index(th, td, pd)).unwrap();
    /// assert!((f[0] - 1.0).abs() < 1e-4 && f[1] == 0.0 && (f[2] - 1.0).abs() < 1e-6);
    /// ```
    pub fn tabulate(brdf: impl Fn(Vec3, Vec3) -> Rgb) -> Self {
        let mut raw = vec![0.0f64; 3 * SAMPLES_PER_CHANNEL];
        for ih in 0..THETA_H_BINS {
            for id in 0..THETA_D_BINS {
                for ip in 0..PHI_D_BINS {
                    let [theta_h, theta_d, phi_d] = Self::bin_centre(ih, id, ip);
                    let (wi, wo) = from_rusinkiewicz(&Rusinkiewicz {
                        theta_h,
                        phi_h: 0.0,
                        theta_d,
                        phi_d,
                    });
                    let i = flat_index(ih, id, ip);
                    if wi.z > 0.0 && wo.z > 0.0 {
                        let f = sanitize(brdf(wi, wo));
                        for c in 0..3 {
                            raw[c * SAMPLES_PER_CHANNEL + i] = f64::from(f[c]) / CHANNEL_SCALES[c];
                        }
                    } else {
                        for c in 0..3 {
                            raw[c * SAMPLES_PER_CHANNEL + i] = INVALID;
                        }
                    }
                }
            }
        }
        Self::with_proxy(raw)
    }

    /// The bins `[iθh, iθd, iφd]` of Rusinkiewicz angles, exactly as `BRDFRead.cpp` computes them
    /// (module docs), in `f64` like the reference. `φd` may be anywhere; it is folded by π. Non-finite
    /// angles give bin 0.
    ///
    /// ```
    /// use nbrdf::measured::MerlTable;
    /// use core::f32::consts::PI;
    /// // θh = π/8 is a quarter of the θh range: ⌊sqrt(1/4) · 90⌋ = 45.
    /// assert_eq!(MerlTable::bins(PI / 8.0 + 1e-6, 0.0, 0.0), [45, 0, 0]);
    /// // φd and φd + π share a bin.
    /// assert_eq!(MerlTable::bins(0.1, 0.2, 0.5), MerlTable::bins(0.1, 0.2, 0.5 + PI));
    /// ```
    pub fn bins(theta_h: f32, theta_d: f32, phi_d: f32) -> [usize; 3] {
        let (theta_h, theta_d, phi_d) = (f64::from(theta_h), f64::from(theta_d), f64::from(phi_d));
        // theta_half_index: sqrt(θh / (π/2) · 90 · 90), the square-root spacing of the θh bins.
        let ih = if theta_h > 0.0 {
            clamp_bin(
                libm::sqrt(theta_h / HALF_PI * (THETA_H_BINS * THETA_H_BINS) as f64),
                THETA_H_BINS,
            )
        } else {
            0
        };
        // theta_diff_index: linear over [0, π/2).
        let id = clamp_bin(theta_d / HALF_PI * THETA_D_BINS as f64, THETA_D_BINS);
        // phi_diff_index: reciprocity folds φd by π; linear over [0, π).
        let ip = clamp_bin(fold_pi(phi_d) / PI * PHI_D_BINS as f64, PHI_D_BINS);
        [ih, id, ip]
    }

    /// The flat index into one channel plane of the bin holding the angles: `iφd + 180 (iθd + 90 iθh)`.
    ///
    /// ```
    /// use nbrdf::measured::MerlTable;
    /// assert_eq!(MerlTable::index(0.0, 0.0, 0.0), 0);
    /// assert_eq!(MerlTable::index(0.0, 0.0, 3.1), 177); // ⌊3.1 / π · 180⌋
    /// ```
    pub fn index(theta_h: f32, theta_d: f32, phi_d: f32) -> usize {
        let [ih, id, ip] = Self::bins(theta_h, theta_d, phi_d);
        flat_index(ih, id, ip)
    }

    /// The angles `[θh, θd, φd]` at the centre of bin `(iθh, iθd, iφd)`: the inverse bin maps at `i + ½`,
    /// so `θh = ((iθh + ½) / 90)² · π/2`, `θd = (iθd + ½) / 90 · π/2`, `φd = (iφd + ½) / 180 · π`.
    /// Indices past the end are clamped to the last bin.
    pub fn bin_centre(ih: usize, id: usize, ip: usize) -> [f32; 3] {
        let uh = (ih.min(THETA_H_BINS - 1) as f64 + 0.5) / THETA_H_BINS as f64;
        let ud = (id.min(THETA_D_BINS - 1) as f64 + 0.5) / THETA_D_BINS as f64;
        let up = (ip.min(PHI_D_BINS - 1) as f64 + 0.5) / PHI_D_BINS as f64;
        [
            (uh * uh * HALF_PI) as f32,
            (ud * HALF_PI) as f32,
            (up * PI) as f32,
        ]
    }

    /// The BRDF value of one bin (flat index as [`index`](Self::index)), scaled to 1/sr; `None` when the
    /// index is out of range or any channel of the bin is invalid.
    pub fn sample(&self, index: usize) -> Option<Rgb> {
        if index >= SAMPLES_PER_CHANNEL {
            return None;
        }
        let mut rgb = BLACK;
        for c in 0..3 {
            let v = self.raw[c * SAMPLES_PER_CHANNEL + index];
            if v < 0.0 {
                return None;
            }
            rgb[c] = (v * CHANNEL_SCALES[c]) as f32;
        }
        Some(rgb)
    }

    /// The BRDF at (`wi`, `wo`) by the reference (nearest-bin) lookup; 0 below the horizon, for degenerate
    /// input and in invalid bins.
    ///
    /// The angles come from the exact reciprocity map Θ, so `eval(wi, wo)` and `eval(wo, wi)` are
    /// bitwise identical.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        self.eval_with(wi, wo, Lookup::Nearest)
    }

    /// The BRDF at (`wi`, `wo`) by trilinear interpolation ([`Lookup::Trilinear`]); exactly reciprocal
    /// like [`eval`](Self::eval).
    pub fn eval_trilinear(&self, wi: Vec3, wo: Vec3) -> Rgb {
        self.eval_with(wi, wo, Lookup::Trilinear)
    }

    /// The BRDF at (`wi`, `wo`) with the given lookup.
    pub fn eval_with(&self, wi: Vec3, wo: Vec3, lookup: Lookup) -> Rgb {
        let Some((wi, wo)) = upper_hemisphere_pair(wi, wo) else {
            return BLACK;
        };
        let Some([theta_h, theta_d, phi_d, _]) = theta_map(wi, wo) else {
            return BLACK;
        };
        self.eval_angles(theta_h, theta_d, phi_d, lookup)
    }

    /// The BRDF at Rusinkiewicz angles (`φd` folded by π); 0 for non-finite angles and invalid bins.
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32, lookup: Lookup) -> Rgb {
        if !(theta_h.is_finite() && theta_d.is_finite() && phi_d.is_finite()) {
            return BLACK;
        }
        match lookup {
            Lookup::Nearest => {
                let i = Self::index(theta_h, theta_d, phi_d);
                let mut rgb = BLACK;
                for c in 0..3 {
                    // An invalid channel reads as 0 (module docs); the others keep their value.
                    let v = self.raw[c * SAMPLES_PER_CHANNEL + i];
                    rgb[c] = (v.max(0.0) * CHANNEL_SCALES[c]) as f32;
                }
                sanitize(rgb)
            }
            Lookup::Trilinear => sanitize(self.trilinear(theta_h, theta_d, phi_d)),
        }
    }

    fn trilinear(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        let (theta_h, theta_d, phi_d) = (f64::from(theta_h), f64::from(theta_d), f64::from(phi_d));
        // Continuous index coordinates with the samples at the bin centres i + ½ (module docs).
        let uh = libm::sqrt(theta_h.max(0.0) / HALF_PI) * THETA_H_BINS as f64 - 0.5;
        let ud = theta_d / HALF_PI * THETA_D_BINS as f64 - 0.5;
        let up = fold_pi(phi_d) / PI * PHI_D_BINS as f64 - 0.5;
        let (h0, h1, th) = clamped_cell(uh, THETA_H_BINS);
        let (d0, d1, td) = clamped_cell(ud, THETA_D_BINS);
        // φd is periodic with period π: the cell below bin 0's centre pairs bin 179 with bin 0.
        let pf = libm::floor(up);
        let tp = up - pf;
        let p0 = (pf as i64).rem_euclid(PHI_D_BINS as i64) as usize;
        let p1 = (p0 + 1) % PHI_D_BINS;

        let mut sum = [0.0f64; 3];
        let mut weight = [0.0f64; 3];
        for (ih, wh) in [(h0, 1.0 - th), (h1, th)] {
            for (id, wd) in [(d0, 1.0 - td), (d1, td)] {
                for (ip, wp) in [(p0, 1.0 - tp), (p1, tp)] {
                    let w = wh * wd * wp;
                    let i = flat_index(ih, id, ip);
                    for c in 0..3 {
                        let v = self.raw[c * SAMPLES_PER_CHANNEL + i];
                        if v >= 0.0 {
                            sum[c] += w * v;
                            weight[c] += w;
                        }
                    }
                }
            }
        }
        let mut rgb = BLACK;
        for c in 0..3 {
            if weight[c] > 0.0 {
                rgb[c] = (sum[c] / weight[c] * CHANNEL_SCALES[c]) as f32;
            }
        }
        rgb
    }

    /// Reads a `.binary` file.
    ///
    /// Errors: [`Error::Io`] when the file cannot be read, and every error of
    /// [`from_bytes`](Self::from_bytes). An oversized file is rejected before it is read.
    #[cfg(feature = "std")]
    pub fn read(path: impl AsRef<std::path::Path>) -> Result<Self, Error> {
        let path = path.as_ref();
        let at = || std::format!("MERL file {}", path.display());
        let len = std::fs::metadata(path)
            .map_err(|e| Error::io(path, &e))?
            .len();
        if len > FILE_BYTES as u64 {
            return Err(Error::SizeMismatch {
                what: "MERL file length in bytes (trailing data)",
                expected: FILE_BYTES,
                found: usize::try_from(len).unwrap_or(usize::MAX),
            }
            .context(at()));
        }
        // A device or pipe has no length to check: read no more than a whole table.
        let bytes = crate::io::read_at_most(path, FILE_BYTES as u64)?;
        Self::from_bytes(&bytes).map_err(|e| e.context(at()))
    }

    /// Writes the table as a `.binary` file, atomically: into a temporary file in the same directory,
    /// flushed to disk, then renamed over `path`, so that no half-written file is ever visible.
    #[cfg(feature = "std")]
    pub fn write(&self, path: impl AsRef<std::path::Path>) -> Result<(), Error> {
        crate::io::write_atomic(path.as_ref(), &self.to_bytes())
    }
}

/// Largest stored value accepted: 1e12 × (1/1500) ≈ 7e8 1/sr, far beyond any measured reflectance,
/// and finite in f32 after scaling (1e300 became infinite there and rendered black).
pub const MAX_SAMPLE: f64 = 1e12;

fn check_magnitude(v: f64, index: usize) -> Result<(), Error> {
    if v > MAX_SAMPLE {
        return Err(Error::Context {
            what: alloc::format!("MERL samples, index {index}"),
            message: alloc::format!("value {v:e} is beyond {MAX_SAMPLE:e}; no measured BRDF comes near it"),
        });
    }
    Ok(())
}

/// Checks the 12-byte header: `(90, 90, 180)` as little-endian `i32`.
fn check_header(bytes: &[u8]) -> Result<(), Error> {
    if bytes.len() < HEADER_BYTES {
        return Err(Error::Truncated {
            what: "MERL header",
            needed: HEADER_BYTES,
            got: bytes.len(),
        });
    }
    let fields = [
        ("MERL header theta_h bin count", THETA_H_BINS),
        ("MERL header theta_d bin count", THETA_D_BINS),
        ("MERL header phi_d bin count", PHI_D_BINS),
    ];
    for (k, (what, expected)) in fields.into_iter().enumerate() {
        let mut b = [0u8; 4];
        b.copy_from_slice(&bytes[4 * k..4 * k + 4]);
        let n = i32::from_le_bytes(b);
        let Ok(found) = usize::try_from(n) else {
            return Err(Error::InvalidValue {
                what,
                reason: "negative bin count",
            });
        };
        if found != expected {
            return Err(Error::SizeMismatch {
                what,
                expected,
                found,
            });
        }
    }
    Ok(())
}

#[inline]
fn flat_index(ih: usize, id: usize, ip: usize) -> usize {
    ip + PHI_D_BINS * (id + THETA_D_BINS * ih)
}

/// `⌊x⌋` clamped into `[0, n - 1]`; NaN gives 0 (the saturating float-to-int cast).
#[inline]
fn clamp_bin(x: f64, n: usize) -> usize {
    if x > 0.0 {
        (x as usize).min(n - 1)
    } else {
        0
    }
}

/// `φ mod π` in [0, π); rounding that lands on π folds to 0.
#[inline]
fn fold_pi(phi: f64) -> f64 {
    let mut p = libm::fmod(phi, PI);
    if p < 0.0 {
        p += PI;
    }
    if p >= PI {
        0.0
    } else {
        p
    }
}

/// The two neighbouring sample indices and the weight of the second, for a coordinate clamped into
/// `[0, n - 1]` (constant extrapolation at the ends).
#[inline]
fn clamped_cell(u: f64, n: usize) -> (usize, usize, f64) {
    let u = if u > 0.0 { u.min((n - 1) as f64) } else { 0.0 };
    let i0 = (u as usize).min(n - 1);
    let i1 = (i0 + 1).min(n - 1);
    (i0, i1, u - i0 as f64)
}


/// The nearest-bin lookup, sampled through the table's proxy. Reciprocal: `φd` and `φd + π` share a
/// bin and `θh`, `θd` are symmetric in `wi` and `wo`.
impl Brdf for MerlTable {
    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Rgb {
        MerlTable::eval(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        self.view.sample(wo, u, |wi, wo| MerlTable::eval(self, wi, wo))
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.view.pdf(wi, wo)
    }

    #[inline]
    fn is_reciprocal(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_checks_each_field() {
        let mut h = [0u8; 12];
        for (k, n) in [90i32, 90, 180].into_iter().enumerate() {
            h[4 * k..4 * k + 4].copy_from_slice(&n.to_le_bytes());
        }
        assert!(check_header(&h).is_ok());
        h[8..12].copy_from_slice(&360i32.to_le_bytes());
        assert_eq!(
            check_header(&h),
            Err(Error::SizeMismatch {
                what: "MERL header phi_d bin count",
                expected: 180,
                found: 360
            })
        );
        h[0..4].copy_from_slice(&(-90i32).to_le_bytes());
        assert!(matches!(
            check_header(&h),
            Err(Error::InvalidValue {
                reason: "negative bin count",
                ..
            })
        ));
    }

    #[test]
    fn clamped_cell_interpolates_inside_and_clamps_outside() {
        assert_eq!(clamped_cell(3.25, 90), (3, 4, 0.25));
        assert_eq!(clamped_cell(-0.5, 90), (0, 1, 0.0));
        assert_eq!(clamped_cell(89.4, 90), (89, 89, 0.0));
        assert_eq!(clamped_cell(f64::NAN, 90), (0, 1, 0.0));
    }

    #[test]
    fn fold_pi_maps_into_half_open_range() {
        assert_eq!(fold_pi(0.0), 0.0);
        assert!((fold_pi(PI + 0.25) - 0.25).abs() < 1e-12);
        assert!((fold_pi(-0.25) - (PI - 0.25)).abs() < 1e-12);
        assert!(fold_pi(-1e-300) < PI);
    }
}
