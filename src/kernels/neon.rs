//! The aarch64 Advanced SIMD (NEON) level: the workspace's 4-lane `Neon` vectors with fused
//! multiply-add, the algorithm of `lanes.rs`. NEON is part of the aarch64 base architecture, so
//! these need no run-time check.

use nbrdf_lanes::Neon;

use super::lanes;
use super::{Dense, Weight};

/// [`lanes::one`] over [`Neon`].
///
/// # Safety
/// As [`lanes::one`].
pub(super) unsafe fn one<W: Weight>(layer: &Dense<'_, W>, out: *mut f32) {
    // SAFETY: forwarded; NEON is present at this level.
    unsafe { lanes::one::<Neon, W>(layer, out) }
}

/// [`lanes::packet`] over [`Neon`].
///
/// # Safety
/// As [`lanes::packet`].
pub(super) unsafe fn packet<W: Weight>(layer: &Dense<'_, W>, out: *mut f32, out_stride: usize) {
    // SAFETY: forwarded; NEON is present at this level.
    unsafe { lanes::packet::<Neon, W>(layer, out, out_stride) }
}
