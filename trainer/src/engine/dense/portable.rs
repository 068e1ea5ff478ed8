//! The portable level of the dense products: the workspace's plain-Rust lanes on 4 lanes (one SSE2
//! or NEON register), multiply then add. Tiles of 4 × 2 vectors (8 of the 16 SSE2 registers) and a
//! narrow tile of 8 rows.

use nbrdf_lanes::Scalar;

use super::kernel::{self, Tile};
use super::{Epilogue, Mat};

/// Plain Rust on 4 lanes (one SSE2 or NEON register).
type Portable = Scalar<4>;

// SAFETY: plain Rust, no instruction beyond the compile-time target's.
unsafe impl Tile for Portable {
    const MR: usize = 4;
    const NV: usize = 2;
}

/// Rows of the narrow tile.
const NARROW: usize = 8;

/// [`kernel::product`] at this level.
///
/// # Safety
/// As `super::product`.
#[allow(clippy::too_many_arguments)]
pub(super) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded.
    unsafe { kernel::product::<Portable, NARROW>(rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`kernel::weight_product`] at this level.
///
/// # Safety
/// As `super::weight_product`.
pub(super) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded.
    unsafe { kernel::weight_product::<Portable, NARROW>(rows, k, m, a, g, w, accumulate) }
}

/// [`kernel::fma_peak`] at this level.
pub(super) fn fma_peak(iters: usize) -> (f64, f32) {
    kernel::fma_peak::<Portable>(iters)
}
