//! The AVX2 level (x86-64 AVX2 with FMA and F16C): 8-lane vectors for the kernels of `x86.rs` and this
//! level's entry points. Without mask registers, a partial vector is a `vmaskmovps` under a lane mask,
//! a partial f16 vector a bounded copy, and a list of nonzero inputs is compressed through a table of
//! permutations.

use core::arch::x86_64::*;

use nbrdf_lanes::Avx2;

use super::x86::{self, Load, X86};
use super::{Dense, PACKET};

/// The valid lanes of a partial vector: as a `vmaskmovps` mask, and their number (for f16 loads).
#[derive(Clone, Copy)]
pub(super) struct Tail {
    lanes: __m256i,
    n: usize,
}

// SAFETY: the dispatch hands out this level only where the CPU has AVX2, FMA and F16C (`detect`); every
// entry point below enables them.
unsafe impl X86 for Avx2 {
    /// 4 queries × 2 vectors: 8 of the 16 registers hold accumulators, the packet in four quarters.
    const QT: usize = 4;
    const K: usize = 2;
    type Mask = Tail;

    #[inline(always)]
    fn mask(m: usize) -> Tail {
        // SAFETY: the level is present.
        Tail { lanes: unsafe { lane_mask(m) }, n: m.min(8) }
    }

    #[inline(always)]
    unsafe fn load_masked(p: *const f32, m: Tail) -> __m256 {
        // SAFETY: the caller's contract; lanes outside the mask are not read.
        unsafe { _mm256_maskload_ps(p, m.lanes) }
    }

    #[inline(always)]
    unsafe fn store_masked(p: *mut f32, m: Tail, v: __m256) {
        // SAFETY: the caller's contract; lanes outside the mask are not written.
        unsafe { _mm256_maskstore_ps(p, m.lanes, v) }
    }

    #[inline(always)]
    unsafe fn load_f16(p: *const half::f16) -> __m256 {
        // SAFETY: the caller's contract (8 halves, 16 bytes).
        unsafe { _mm256_cvtph_ps(_mm_loadu_si128(p.cast())) }
    }

    #[inline(always)]
    unsafe fn load_f16_masked(p: *const half::f16, m: Tail) -> __m256 {
        // No masked 16-bit load before AVX-512: the valid halves copied to a zeroed buffer.
        let mut t = [0u16; 8];
        // SAFETY: the caller's contract (`m.n` readable halves).
        unsafe {
            core::ptr::copy_nonoverlapping(p.cast::<u16>(), t.as_mut_ptr(), m.n);
            _mm256_cvtph_ps(_mm_loadu_si128(t.as_ptr().cast()))
        }
    }

    #[inline(always)]
    unsafe fn nonzero(x: *const f32, n: usize) -> u64 {
        // SAFETY: the caller's contract.
        unsafe { nonzero_mask(x, n) }
    }

    #[inline(always)]
    unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
        // SAFETY: the caller's contract.
        unsafe { compress(x, n, row_bytes, xs, offs) }
    }

    #[inline(never)]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn packet_dense<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
        // SAFETY: the caller's contract.
        unsafe { x86::packet_dense::<Self, W, { Self::QT }, { Self::K }>(l, out, os) }
    }

    #[inline(always)]
    unsafe fn transpose(x: *const f32, stride: usize, n: usize, xt: *mut f32) {
        // SAFETY: the caller's contract.
        unsafe { transpose_inputs(x, stride, n, xt) }
    }
}

/// One query through the layer ([`x86::one`]).
///
/// # Safety
/// The CPU has this level; `l` passed `check(1, ..)` for `out`.
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn one<W: Load>(l: &Dense<'_, W>, out: *mut f32) {
    // SAFETY: the contract, passed on.
    unsafe { x86::one::<Avx2, W>(l, out) }
}

/// `PACKET` queries through the layer ([`x86::packet`]).
///
/// # Safety
/// The CPU has this level; `l` passed `check(PACKET, ..)` for `out` with rows `os` apart.
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn packet<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { x86::packet::<Avx2, W>(l, out, os, false) }
}

/// [`packet`] with the sparse kernel on every 128-wide ReLU layer whose masks fit, however dense: the
/// sparse kernel on its own, for the tests.
///
/// # Safety
/// As [`packet`].
#[cfg(test)]
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn packet_sparse<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { x86::packet::<Avx2, W>(l, out, os, true) }
}

/// The dense packet kernel on its own ([`x86::packet_dense`]), for the tests.
///
/// # Safety
/// As [`packet`].
#[cfg(test)]
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn packet_dense<W: Load>(l: &Dense<'_, W>, out: *mut f32, os: usize) {
    // SAFETY: the contract, passed on.
    unsafe { Avx2::packet_dense(l, out, os) }
}

/// `dst[i] = src[i]` widened ([`x86::widen_f16`]): the f16 conversion behind `kernels::widen_f16`.
///
/// # Safety
/// The CPU has this level; `src` and `dst` have the same length.
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn widen_f16(src: &[half::f16], dst: &mut [f32]) {
    // SAFETY: the contract, passed on.
    unsafe { x86::widen_f16::<Avx2>(src, dst) }
}

/// The mask selecting lanes `0..m`.
#[inline]
#[target_feature(enable = "avx2")]
fn lane_mask(m: usize) -> __m256i {
    let idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    _mm256_cmpgt_epi32(_mm256_set1_epi32(m.min(8) as i32), idx)
}

/// [`X86::nonzero`]: 8 lanes per compare.
///
/// # Safety
/// `n ≤ 64` inputs are readable from `x` (read under `lane_mask`, which leaves the lanes past them
/// unread).
#[inline]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn nonzero_mask(x: *const f32, n: usize) -> u64 {
    let mut nz = 0u64;
    for v in 0..n.div_ceil(8) {
        // SAFETY: see the contract.
        let xv = unsafe { _mm256_maskload_ps(x.add(8 * v), lane_mask(n - 8 * v)) };
        let c = _mm256_cmp_ps::<_CMP_NEQ_UQ>(xv, _mm256_setzero_ps());
        nz |= (_mm256_movemask_ps(c) as u32 as u64) << (8 * v);
    }
    nz
}

/// For each 8-bit mask of nonzero lanes: the indices of its set bits in order (the permutation that
/// packs them to the front), then their number.
static PACK: [[u8; 9]; 256] = {
    let mut t = [[0u8; 9]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut j, mut k) = (0, 0);
        while j < 8 {
            if (m >> j) & 1 == 1 {
                t[m][k] = j as u8;
                k += 1;
            }
            j += 1;
        }
        t[m][8] = k as u8;
        m += 1;
    }
    t
};

/// [`X86::compress`]: 8 inputs per step, packed by a permutation from [`PACK`] (`vpermps`).
///
/// # Safety
/// As [`X86::compress`].
#[inline]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn compress(x: *const f32, n: usize, row_bytes: u32, xs: *mut f32, offs: *mut u32) -> usize {
    let mut len = 0;
    let mut off = _mm256_mullo_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(row_bytes as i32));
    let step = _mm256_set1_epi32((8 * row_bytes) as i32);
    let mut i = 0;
    while i < n {
        // SAFETY: lanes `i + j < n` only are read (mask; the others load as zero, which is not kept);
        // whole vectors are stored at `len <= i`, within the rounded-up room; `PACK` rows hold 9 bytes.
        unsafe {
            let v = _mm256_maskload_ps(x.add(i), lane_mask(n - i));
            let nz = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NEQ_UQ>(v, _mm256_setzero_ps())) as usize;
            let p = PACK[nz].as_ptr();
            let idx = _mm256_cvtepu8_epi32(_mm_loadl_epi64(p.cast()));
            _mm256_storeu_ps(xs.add(len), _mm256_permutevar8x32_ps(v, idx));
            _mm256_storeu_si256(offs.add(len).cast(), _mm256_permutevar8x32_epi32(off, idx));
            len += *p.add(8) as usize;
        }
        off = _mm256_add_epi32(off, step);
        i += 8;
    }
    len
}

/// [`X86::transpose`] by 8 × 8 blocks: 8 queries' rows loaded (masked past `n`), transposed in
/// registers ([`transpose8`]), each column stored as 8 lanes of the packet's row.
///
/// # Safety
/// As [`X86::transpose`].
#[inline]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn transpose_inputs(x: *const f32, stride: usize, n: usize, xt: *mut f32) {
    const { assert!(PACKET.is_multiple_of(8)) };
    for q0 in (0..PACKET).step_by(8) {
        let mut i = 0;
        while i < n {
            let m = lane_mask(n - i);
            // SAFETY: lanes `i + j < n` only are read; column `i + j < n` goes to `xt[(i + j) * PACKET..]`,
            // within the room (contract).
            unsafe {
                let rows: [__m256; 8] = core::array::from_fn(|q| _mm256_maskload_ps(x.add((q0 + q) * stride + i), m));
                let cols = transpose8(rows);
                for (j, c) in cols.iter().enumerate().take(n - i) {
                    _mm256_storeu_ps(xt.add((i + j) * PACKET + q0), *c);
                }
            }
            i += 8;
        }
    }
}

/// The transpose of an 8 × 8 block: lane `q` of result `j` is lane `j` of `r[q]`. 32-bit interleaves,
/// 64-bit shuffles within 128-bit lanes, then 128-bit lane swaps.
#[inline]
#[target_feature(enable = "avx2")]
fn transpose8(r: [__m256; 8]) -> [__m256; 8] {
    // t[2k] = a0 b0 a1 b1 | a4 b4 a5 b5, t[2k + 1] = a2 b2 a3 b3 | a6 b6 a7 b7 for rows a, b = 2k, 2k + 1.
    let t: [__m256; 8] = core::array::from_fn(|j| {
        let (a, b) = (r[j & !1], r[j | 1]);
        if j % 2 == 0 { _mm256_unpacklo_ps(a, b) } else { _mm256_unpackhi_ps(a, b) }
    });
    // s[4h + c] holds, in 128-bit lane L, column 4L + c of rows 4h .. 4h + 3.
    let s: [__m256; 8] = core::array::from_fn(|j| {
        let (h, c) = (j / 4, j % 4);
        let (a, b) = (t[4 * h + c / 2], t[4 * h + 2 + c / 2]);
        if c % 2 == 0 { _mm256_shuffle_ps::<0b01_00_01_00>(a, b) } else { _mm256_shuffle_ps::<0b11_10_11_10>(a, b) }
    });
    core::array::from_fn(|j| {
        let c = j % 4;
        if j < 4 { _mm256_permute2f128_ps::<0x20>(s[c], s[4 + c]) } else { _mm256_permute2f128_ps::<0x31>(s[c], s[4 + c]) }
    })
}
