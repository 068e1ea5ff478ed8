//! The AVX-512 level of the dense products: 16 lanes, tiles of 6 × 4 vectors (24 of the 32
//! registers) and a narrow tile of 24 rows.

use nbrdf_lanes::Avx512;

use super::kernel::{self, Tile};
use super::{Epilogue, Mat};

// SAFETY: the entry points below enable the level's features and are only called where the CPU has them.
unsafe impl Tile for Avx512 {
    const MR: usize = 6;
    const NV: usize = 4;
}

/// Rows of the narrow tile.
const NARROW: usize = 24;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`; the CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Avx512, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`; the CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Avx512, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
///
/// # Safety
/// The CPU has AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Avx512>(iters)
}
