//! The AVX2 level of the dense products: 8 lanes, tiles of 6 × 2 vectors (12 of the 16
//! registers) and a narrow tile of 12 rows.

use nbrdf_lanes::Avx2;

use super::kernel::{self, Tile};
use super::{Epilogue, Mat};

// SAFETY: the entry points below enable the level's features and are only called where the CPU has them.
unsafe impl Tile for Avx2 {
    const MR: usize = 6;
    const NV: usize = 2;
}

/// Rows of the narrow tile.
const NARROW: usize = 12;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`; the CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Avx2, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`; the CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Avx2, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
///
/// # Safety
/// The CPU has AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Avx2>(iters)
}
