//! The dense products of a training step on a block of rows, with the layer's epilogue (bias, ReLU,
//! ReLU mask) applied before the block is stored.
//!
//! Every product of a step is tall and skinny: a batch of 2^15 rows against a layer matrix of at most
//! ~200 × 128 values. Layer by layer, each product would stream its `[2^15, 128]` operands (16 MiB)
//! from memory, and then an elementwise pass would stream them again for the bias and ReLU. The step
//! ([`super::step`]) therefore runs a network's layers on blocks of a few hundred rows that stay in L2
//! from one layer to the next, and needs single-threaded products on such a block whose epilogue does
//! the elementwise work while the values are still in registers, with a two-part left-hand side (the
//! skip layer's `[h, x]`). No crate offers a GEMM with a caller-defined epilogue or a two-part operand,
//! so the kernels are here: written once over a lane trait ([`kernel`]), instantiated per CPU level
//! (`avx512.rs`, `avx2.rs`, `neon.rs`, `portable.rs`) and chosen at run time by the core's
//! [`nbrdf::kernels::detected`], which honours `NBRDF_KERNEL` so that one host tests every level
//! below its own.
//!
//! Order of sums: an output element is the multiply-add chain over the inner index in order, a weight
//! gradient's element the chain over the rows in order, at every level; so a product computed whole
//! and by row blocks agree to the last bit, and a step is bitwise reproducible for any number of
//! threads. Levels differ in rounding (the portable level does not fuse the multiply-add).

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod kernel;
#[cfg(target_arch = "aarch64")]
mod neon;
mod portable;

use nbrdf::kernels::Level;

/// The matrix side of a product: `rows × cols` f32 values at `ptr`, row-major with row stride `ld`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mat {
    pub ptr: *const f32,
    pub ld: usize,
}

// SAFETY: a `Mat` is an address and a stride, read only under the contract of the unsafe function it
// is passed to; sending it to the threads of a row-block loop is what it is for.
unsafe impl Send for Mat {}
unsafe impl Sync for Mat {}

impl Mat {
    /// The row-major matrix `data` with row stride `ld`.
    #[inline]
    pub fn new(data: &[f32], ld: usize) -> Mat {
        Mat { ptr: data.as_ptr(), ld }
    }

    /// The same matrix from row `r` and column `c` on.
    ///
    /// # Safety
    /// `r · ld + c` must be within the allocation.
    #[inline]
    pub unsafe fn at(self, r: usize, c: usize) -> Mat {
        // SAFETY: forwarded from the caller.
        Mat { ptr: unsafe { self.ptr.add(r * self.ld + c) }, ld: self.ld }
    }
}

/// An output buffer that the tasks of a row-block loop write in disjoint row ranges.
#[derive(Clone, Copy)]
pub(crate) struct Shared(pub *mut f32);
// SAFETY: the loops that share one write only their own rows (their callers' SAFETY comments).
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    /// The address `i` values in. A method, so that a closure captures the whole `Shared` (which is
    /// `Sync`), not its raw pointer field.
    ///
    /// # Safety
    /// `i` must be within the buffer.
    #[inline]
    pub unsafe fn add(self, i: usize) -> *mut f32 {
        // SAFETY: forwarded from the caller.
        unsafe { self.0.add(i) }
    }
}

/// What happens to a block's product `P` before it is stored in `C`:
/// `C ← mask(act(P [+ C] [+ bias]))`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Epilogue {
    /// Add the values already in `C` (`C += P`); otherwise `C` is written without being read.
    pub accumulate: bool,
    /// Add this row vector (`cols` values) to every row.
    pub bias: Option<*const f32>,
    /// `max(·, 0)`.
    pub relu: bool,
    /// A matrix the shape of `C`: zero `C` where it is not `> 0` (a ReLU layer's backward, PyTorch's
    /// `threshold_backward` convention: gradient 0 where the activation is 0).
    pub mask: Option<Mat>,
}

// SAFETY: as for `Mat`: addresses read only under the contract of the function they are passed to.
unsafe impl Send for Epilogue {}
unsafe impl Sync for Epilogue {}

impl Epilogue {
    /// `C ← P`.
    pub const STORE: Epilogue = Epilogue { accumulate: false, bias: None, relu: false, mask: None };
    /// `C ← C + P`.
    pub const ADD: Epilogue = Epilogue { accumulate: true, bias: None, relu: false, mask: None };
}

/// `C [rows × cols] ← epilogue(A1 [rows × p1] · B[0..p1] + A2 [rows × p2] · B[p1..p1 + p2])`, with `B`
/// row-major `[(p1 + p2) × cols]`: one thread, one block of rows, at the level in use. `A2` (`p2 > 0`)
/// is the second part of a left-hand side stored as two matrices, the skip layer's `[h, x]`; its sums
/// continue the chain of `A1`'s, as if the two were one matrix.
///
/// # Safety
/// `a1`, `a2`, `b`, `c` and a mask must address the rows and columns named, `c` writable and, when the
/// epilogue accumulates, initialised; a bias must hold `cols` values. `c` must not overlap the inputs.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product(rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    // SAFETY: forwarded from the caller.
    unsafe { product_at(nbrdf::kernels::detected(), rows, cols, a1, p1, a2, p2, b, c, ldc, epi) }
}

/// [`product`] at `level`.
///
/// # Safety
/// As [`product`]; `level` is at most [`nbrdf::kernels::detected`].
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn product_at(level: Level, rows: usize, cols: usize, a1: Mat, p1: usize, a2: Mat, p2: usize, b: Mat, c: *mut f32, ldc: usize, epi: Epilogue) {
    if rows == 0 || cols == 0 {
        return;
    }
    // SAFETY: the level is one the CPU has (the caller's contract); the memory contract is the caller's.
    unsafe {
        match level {
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => avx512::product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi),
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => avx2::product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi),
            #[cfg(target_arch = "aarch64")]
            Level::Neon => neon::product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi),
            _ => portable::product(rows, cols, a1, p1, a2, p2, b, c, ldc, epi),
        }
    }
}

/// `W [k × m] += Aᵀ G` (`accumulate`) or `W = Aᵀ G` over one block of rows (`A [rows × k]`,
/// `G [rows × m]`), `W` row-major with row stride `m`: a layer's weight gradient, one thread. Without
/// `accumulate` the sums start from the first row's product, as they would from a zeroed `W`, and `W`
/// need not be initialised.
///
/// # Safety
/// `a` and `g` must address `rows` rows of `k` and `m` values, `w` `k × m` values (initialised when
/// `accumulate`) that overlap neither.
pub(crate) unsafe fn weight_product(rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    // SAFETY: forwarded from the caller.
    unsafe { weight_product_at(nbrdf::kernels::detected(), rows, k, m, a, g, w, accumulate) }
}

/// [`weight_product`] at `level`.
///
/// # Safety
/// As [`weight_product`]; `level` is at most [`nbrdf::kernels::detected`].
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn weight_product_at(level: Level, rows: usize, k: usize, m: usize, a: Mat, g: Mat, w: *mut f32, accumulate: bool) {
    if k == 0 || m == 0 {
        return;
    }
    if rows == 0 {
        if !accumulate {
            // SAFETY: w holds k × m values (the caller's contract).
            unsafe { std::ptr::write_bytes(w, 0, k * m) };
        }
        return;
    }
    // SAFETY: as in `product_at`.
    unsafe {
        match level {
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => avx512::weight_product(rows, k, m, a, g, w, accumulate),
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => avx2::weight_product(rows, k, m, a, g, w, accumulate),
            #[cfg(target_arch = "aarch64")]
            Level::Neon => neon::weight_product(rows, k, m, a, g, w, accumulate),
            _ => portable::weight_product(rows, k, m, a, g, w, accumulate),
        }
    }
}

/// The FMA peak of one core at the level in use, in GFLOP/s: register-only multiply-add chains, the
/// best of a few runs of ~20 ms. The yardstick for the products' throughput (`trainer bench-step`).
pub fn fma_peak_gflops() -> f64 {
    let level = nbrdf::kernels::detected();
    let iters = 4_000_000;
    let mut best = 0.0f64;
    for _ in 0..5 {
        let t = std::time::Instant::now();
        // SAFETY: the level is the detected one, which the CPU has. (On aarch64 no arm needs it.)
        #[cfg_attr(target_arch = "aarch64", allow(unused_unsafe))]
        let (flops, sink) = unsafe {
            match level {
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 => avx512::fma_peak(iters),
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 => avx2::fma_peak(iters),
                #[cfg(target_arch = "aarch64")]
                Level::Neon => neon::fma_peak(iters),
                _ => portable::fma_peak(iters),
            }
        };
        std::hint::black_box(sink);
        best = best.max(flops / t.elapsed().as_secs_f64() / 1e9);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible spread of values in [-1, 1), a quarter of them exactly 0 (ReLU kinks).
    fn values(n: usize, seed: u32) -> Vec<f32> {
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                if s.is_multiple_of(4) {
                    0.0
                } else {
                    (s >> 8) as f32 / (1u32 << 23) as f32 - 1.0
                }
            })
            .collect()
    }

    /// `epilogue([a1, a2] · b)` in f64, the definition the kernels must meet, and each element's sum
    /// of the magnitudes of its terms.
    #[allow(clippy::too_many_arguments)]
    fn reference(rows: usize, cols: usize, a1: &[f32], p1: usize, a2: &[f32], p2: usize, b: &[f32], c0: &[f32], bias: &[f32], mask: &[f32], epi: Epilogue) -> Vec<(f64, f64)> {
        let mut out = vec![(0.0f64, 0.0f64); rows * cols];
        for r in 0..rows {
            for j in 0..cols {
                let mut terms: Vec<f64> = (0..p1).map(|q| a1[r * p1 + q] as f64 * b[q * cols + j] as f64).collect();
                terms.extend((0..p2).map(|q| a2[r * p2 + q] as f64 * b[(p1 + q) * cols + j] as f64));
                if epi.accumulate {
                    terms.push(c0[r * cols + j] as f64);
                }
                if epi.bias.is_some() {
                    terms.push(bias[j] as f64);
                }
                let mut v: f64 = terms.iter().sum();
                if epi.relu {
                    v = v.max(0.0);
                }
                if epi.mask.is_some() && mask[r * cols + j] <= 0.0 {
                    v = 0.0;
                }
                out[r * cols + j] = (v, terms.iter().map(|t| t.abs()).sum());
            }
        }
        out
    }

    /// The error a chain of `n` multiply-adds may make, relative to the sum of its terms' magnitudes:
    /// γ_{n+1} ≤ (n + 2)·u with u = ε/2 (Higham, Accuracy and Stability, Thm. 3.1; one more rounding
    /// per term where the level does not fuse the multiply and the add).
    fn chain_bound(n: usize) -> f64 {
        (n + 2) as f64 * f32::EPSILON as f64
    }

    /// The levels this host runs; a SKIPPED line, past the output capture, for each it lacks.
    fn levels(check: &str) -> Vec<Level> {
        use std::io::Write;
        for l in Level::ALL.iter().filter(|l| **l > nbrdf::kernels::detected()) {
            let _ = writeln!(std::io::stderr(), "SKIPPED: {check}: needs the {l} level; this run's highest is {}", nbrdf::kernels::detected());
        }
        Level::usable().collect()
    }

    #[test]
    fn product_meets_its_definition_on_every_tile_shape_at_every_level() {
        // Rows and columns that leave partial tiles (1..5 rows, 1..3 vectors, partial vectors), the
        // narrow tiles of an output layer, a skip layer's two-part input, and each epilogue.
        for level in levels("dense product at every level") {
            for &(rows, cols, p1, p2) in &[(1, 1, 1, 0), (7, 3, 5, 0), (13, 17, 9, 4), (6, 64, 128, 0), (25, 130, 40, 27), (12, 128, 128, 68), (53, 3, 128, 0), (50, 16, 20, 7), (30, 6, 33, 0)] {
                let (a1, a2, b) = (values(rows * p1, 1), values(rows * p2, 2), values((p1 + p2) * cols, 3));
                let (c0, bias, mask) = (values(rows * cols, 4), values(cols, 5), values(rows * cols, 6));
                let epilogues = [
                    Epilogue::STORE,
                    Epilogue::ADD,
                    Epilogue { bias: Some(bias.as_ptr()), relu: true, ..Epilogue::STORE },
                    Epilogue { mask: Some(Mat::new(&mask, cols)), ..Epilogue::STORE },
                ];
                for epi in epilogues {
                    let want = reference(rows, cols, &a1, p1, &a2, p2, &b, &c0, &bias, &mask, epi);
                    let mut c = c0.clone();
                    let (m1, m2, mb) = (Mat::new(&a1, p1), Mat::new(&a2, p2), Mat::new(&b, cols));
                    // SAFETY: the matrices hold the rows and columns named; c is rows × cols; the level
                    // is one the host runs.
                    unsafe { product_at(level, rows, cols, m1, p1, m2, p2, mb, c.as_mut_ptr(), cols, epi) };
                    for (i, (&got, &(w, mag))) in c.iter().zip(&want).enumerate() {
                        assert!((got as f64 - w).abs() <= chain_bound(p1 + p2 + 2) * mag, "{level} {rows}x{cols} p {p1}+{p2} {epi:?}: [{i}] {got} vs {w}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_product_by_row_blocks_is_the_whole_product_bit_for_bit_at_every_level() {
        // The step computes a layer block by block; the order of each element's sum does not depend
        // on the blocks, at any level. Columns 70: full panels and a partial vector.
        for level in levels("dense product by row blocks at every level") {
            let (rows, cols, p) = (50, 70, 33);
            let (a, b) = (values(rows * p, 7), values(p * cols, 8));
            let mut whole = vec![0.0f32; rows * cols];
            let mut blocks = vec![0.0f32; rows * cols];
            let (ma, mb) = (Mat::new(&a, p), Mat::new(&b, cols));
            // SAFETY: a is rows × p, b p × cols, the outputs rows × cols; each block's rows are in range.
            unsafe {
                product_at(level, rows, cols, ma, p, ma, 0, mb, whole.as_mut_ptr(), cols, Epilogue::STORE);
                for r0 in (0..rows).step_by(11) {
                    product_at(level, 11.min(rows - r0), cols, ma.at(r0, 0), p, ma, 0, mb, blocks.as_mut_ptr().add(r0 * cols), cols, Epilogue::STORE);
                }
            }
            assert!(whole.iter().zip(&blocks).all(|(x, y)| x.to_bits() == y.to_bits()), "{level}");
        }
    }

    #[test]
    fn weight_product_adds_the_transposed_product_at_every_level() {
        // 300 rows: more than one sweep of the kernel's row blocks; 70 columns and 13 weight rows
        // leave partial tiles; an output layer's 3 and 16 columns take the narrow tiles, 53 and 48
        // weight rows with and without a remainder.
        for level in levels("weight product at every level") {
            for (rows, k, m) in [(300, 13, 70), (300, 53, 3), (290, 48, 16), (40, 7, 6)] {
                let (a, g, w0) = (values(rows * k, 9), values(rows * m, 10), values(k * m, 11));
                for accumulate in [true, false] {
                    // Without `accumulate` the old values must not matter: start from NaN.
                    let mut w = if accumulate { w0.clone() } else { vec![f32::NAN; k * m] };
                    // SAFETY: a is rows × k, g rows × m, w k × m; the level is one the host runs.
                    unsafe { weight_product_at(level, rows, k, m, Mat::new(&a, k), Mat::new(&g, m), w.as_mut_ptr(), accumulate) };
                    for i in 0..k {
                        for j in 0..m {
                            let start = if accumulate { w0[i * m + j] as f64 } else { 0.0 };
                            let terms = (0..rows).map(|r| a[r * k + i] as f64 * g[r * m + j] as f64);
                            let (want, mag) = terms.fold((start, start.abs()), |(s, m), t| (s + t, m + t.abs()));
                            let got = w[i * m + j] as f64;
                            assert!((got - want).abs() <= chain_bound(rows + 1) * mag, "{level} {k}x{m} accumulate {accumulate} [{i}, {j}] {got} vs {want}");
                        }
                    }
                }
            }
        }
    }
}
