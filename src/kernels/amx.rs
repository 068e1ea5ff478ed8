//! A packet of queries through a network's hidden layers on AMX tiles (x86-64 AMX-BF16), each f32
//! product as three or six bf16 products: the arithmetics [`crate::mlp::Arithmetic::SplitBf16`]
//! ("bf16x3") and [`crate::mlp::Arithmetic::SplitBf16x6`] ("bf16x6").
//!
//! An AMX `tdpbf16ps` multiplies a 16×32 bf16 tile by a 32×16 one into 16×16 f32 sums: 8192
//! multiply-adds in 16 cycles, 16× what the two AVX-512 FMA ports do in f32. bf16 keeps 8 significant
//! bits, too few for a network's activations (~0.4% a product), so every value is split into two
//! bf16 parts, `x = x_hi + x_lo` (`x_hi` = `x` rounded to bf16, `x_lo` = the remainder rounded), and a
//! product taken as `x_hi·w_hi + x_hi·w_lo + x_lo·w_hi` — the "bf16x3" of Henry, Tang & Heinecke,
//! *Leveraging the bfloat16 Artificial Intelligence Datatype for Higher-Precision Computations*
//! (ARITH 2019), Sec. IV. The dropped `x_lo·w_lo` and the splits' remainders are about `2^-16` of the
//! product, so a layer's sums are f32 sums of products good to ~16 bits, not to f32's 24: on fitted
//! models the outputs move by 2–4e-6 RMS (at most ~4e-5), several hundred times less than with the
//! f16 arithmetic of [`super::half_math`] (`docs/speed.md`), at three times the tile work, which still
//! leaves the tiles ~5× the f32 FMA rate. With three parts, `x = x_0 + x_1 + x_2` (24 significant
//! bits: every f32 whose exponent leaves room for them), and the six products
//! `x_0·w_0 + x_0·w_1 + x_1·w_0 + x_0·w_2 + x_1·w_1 + x_2·w_0` (bf16x6, *ibid.*), the dropped terms are
//! ~2^-24 of the product: f32's own rounding, at twice the tile work of bf16x3. Sums are f32 (the tile
//! unit's own rounding; bf16 inputs below 2^-126 count as 0), so a query's value does not depend on
//! the other queries of its packet.
//!
//! The weights are re-laid once ([`pack`], kept by [`crate::model::ModelBuf::enable_bf16`]) in the
//! order the tiles read them: per 32 outputs and 32 inputs, the three parts of two 32×16 "B" tiles
//! (pairs of input rows interleaved per output, the layout `tdpbf16ps` expects); bf16x3 reads the
//! first two. Activations stay row-major per query (an "A" tile is 16 queries × 32 inputs), split
//! after each layer.
//!
//! The same copy serves [`crate::mlp::Arithmetic::Bf16`] on CPUs with AVX512-BF16 but no tiles (AMD
//! Zen 4, say): [`hidden_vectors`] reads part 0 only, one B-tile row (16 outputs × one pair of
//! inputs) per `vdpbf16ps`, which multiplies 32 bf16 pairs into 16 f32 sums: twice the multiply-adds
//! of an f32 FMA in the same issue slot, each product of 8-bit factors (~2^-8 relative apiece).
//!
//! Inline assembly, because Rust 1.95 has the AMX intrinsics only behind the unstable
//! `x86_amx_intrinsics` feature; the tile registers are used by nothing else the compiler emits.
//! Linux hands the 8 KB of tile state to a process only after `arch_prctl(ARCH_REQ_XCOMP_PERM)`,
//! which [`available`] asks for once.

use core::arch::asm;
use core::arch::x86_64::*;
use core::mem::MaybeUninit;

use crate::mlp::{Net, NetDesc, Partial, Weight, MAX_WIDTH};

use super::x86::mask16;
use super::PACKET;

/// Inputs and outputs per tile edge: a tile row is 64 bytes, 32 bf16 inputs or 16 f32 sums.
const K_TILE: usize = 32;
/// Outputs per step of the kernel: two accumulator tiles of 16.
const N_STEP: usize = 32;
/// bf16 values of one 16-row tile.
const TILE_VALUES: usize = 16 * K_TILE;
/// Parts each weight is split into in the tiled layout (bf16x3 reads two of them).
const PARTS: usize = 3;
/// Largest padded tail (encoded angles) the activation buffers hold.
pub(super) const TAIL_MAX: usize = round_up(crate::model::MAX_ANGLE_INPUT, K_TILE);
/// Largest activation row: a hidden layer's outputs and the padded tail.
const ROW_MAX: usize = MAX_WIDTH + TAIL_MAX;

const fn round_up(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}

/// Whether the CPU has AMX-BF16 with AVX512-BF16 and the OS lets this process use the tiles (asked
/// for once; Linux only).
pub(super) fn available() -> bool {
    use core::sync::atomic::{AtomicU8, Ordering};
    static HAS: AtomicU8 = AtomicU8::new(0);
    match HAS.load(Ordering::Relaxed) {
        0 => {
            let has = detect();
            HAS.store(if has { 2 } else { 1 }, Ordering::Relaxed);
            has
        }
        v => v == 2,
    }
}

fn detect() -> bool {
    if !vectors_available() {
        return false;
    }
    // CPUID.(EAX=7, ECX=0):EDX bit 22 AMX-BF16, bit 24 AMX-TILE (Intel SDM Vol. 2A, CPUID).
    // `is_x86_feature_detected!("amx-bf16")` is unstable in Rust 1.95.
    let leaf7 = __cpuid_count(7, 0);
    if leaf7.edx & (1 << 22) == 0 || leaf7.edx & (1 << 24) == 0 {
        return false;
    }
    // arch_prctl(ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA) (Linux Documentation/arch/x86/xstate.rst).
    const SYS_ARCH_PRCTL: i64 = 158;
    const ARCH_REQ_XCOMP_PERM: i64 = 0x1023;
    const XFEATURE_XTILEDATA: i64 = 18;
    let ret: i64;
    // SAFETY: a plain system call; it only changes this process's permission to use the tile state.
    unsafe {
        asm!("syscall", inlateout("rax") SYS_ARCH_PRCTL => ret, in("rdi") ARCH_REQ_XCOMP_PERM,
             in("rsi") XFEATURE_XTILEDATA, lateout("rcx") _, lateout("r11") _, options(nostack));
    }
    ret == 0
}

/// Padded tail length (inputs after the head of layer 0 and the skip layer).
#[inline]
pub(super) const fn tail_pad(n_tail: usize) -> usize {
    round_up(n_tail, K_TILE)
}

/// Number of tiled inputs of hidden layer `l`: the tail (layer 0), the hidden width and the tail (the
/// skip layer), the hidden width (the others).
#[inline]
pub(super) fn layer_k(d: &NetDesc, n_tail: usize, l: usize) -> usize {
    let width = d.width as usize;
    if l == 0 {
        tail_pad(n_tail)
    } else if d.skip as usize == l {
        width + tail_pad(n_tail)
    } else {
        width
    }
}

/// Whether a network can run on tiles: a hidden width of a multiple of 32 (each step fills two
/// 16-wide accumulator tiles), a tail of 1 to [`crate::model::MAX_ANGLE_INPUT`] inputs after its head.
pub(crate) fn fits(d: &NetDesc, n_tail: usize) -> bool {
    let width = d.width as usize;
    d.validate().is_ok() && width.is_multiple_of(N_STEP) && n_tail > 0 && tail_pad(n_tail) <= TAIL_MAX && n_tail <= d.n_in as usize
}

/// Number of bf16 values [`pack`] writes for a network (the three parts of every hidden weight it
/// reads per query, tails padded); 0 where it does not [`fits`].
pub(crate) fn packed_len(d: &NetDesc, n_tail: usize) -> usize {
    if !fits(d, n_tail) {
        return 0;
    }
    (0..d.hidden as usize).map(|l| PARTS * layer_k(d, n_tail, l) * d.width as usize).sum()
}

/// Number of bf16 values of a network's whole bf16 copy ([`crate::mlp::Tiled`]): the tiles of
/// [`pack`], then the rows of [`super::bf16_rows::pack_rows`] for single queries; 0 where it does
/// not [`fits`].
pub(crate) fn copy_len(d: &NetDesc, n_tail: usize) -> usize {
    match packed_len(d, n_tail) {
        0 => 0,
        tiles => tiles + super::bf16_rows::rows_len(d, n_tail),
    }
}

/// Writes the bf16 copy of `net` (see [`copy_len`], the length of `out`; non-zero).
pub(crate) fn make_copy<W: Weight>(net: &Net<'_, W>, n_tail: usize, out: &mut [u16]) {
    // The tiles' length is a multiple of 32 values: the rows start on a cache line when `out` does.
    let (tiles, rows) = out.split_at_mut(packed_len(&net.desc, n_tail));
    pack(net, n_tail, tiles);
    super::bf16_rows::pack_rows(net, n_tail, rows);
}

/// `x` as `x_0 + x_1 + x_2`, each the bf16 rounding (to nearest, ties to even) of what the parts
/// before it leave, as their bits. The remainders are exact (Sterbenz: a rounding is within a factor
/// 2 of what it rounds).
#[inline]
pub(super) fn split(x: f32) -> [u16; PARTS] {
    let p0 = half::bf16::from_f32(x);
    let r = x - p0.to_f32();
    let p1 = half::bf16::from_f32(r);
    let p2 = half::bf16::from_f32(r - p1.to_f32());
    [p0.to_bits(), p1.to_bits(), p2.to_bits()]
}

/// Writes the hidden layers of `net` (whose last `n_tail` inputs are the per-query tail) to `out` in
/// tile order; `out.len()` must be [`packed_len`] (non-zero).
///
/// Per layer, per 32 outputs, per 32 inputs `k0..`: for each half `j` of the outputs the three parts
/// (see [`split`]) of a "B" tile, whose row `r` holds, for output `n`, the weights of inputs `k0 + 2r`
/// and `k0 + 2r + 1` side by side (Intel SDM, `TDPBF16PS`). Input rows past the layer's (tail
/// padding) are 0.
pub(crate) fn pack<W: Weight>(net: &Net<'_, W>, n_tail: usize, out: &mut [u16]) {
    let d = &net.desc;
    let width = d.width as usize;
    let mut o = 0;
    for l in 0..d.hidden as usize {
        let off = d.layer_offset(l);
        let k = layer_k(d, n_tail, l);
        let row = |i: usize| tiled_row(d, n_tail, l, i);
        for n0 in (0..width).step_by(N_STEP) {
            for k0 in (0..k).step_by(K_TILE) {
                for j in 0..2 {
                    let tiles = &mut out[o..o + PARTS * TILE_VALUES];
                    for r in 0..16 {
                        for n in 0..16 {
                            for p in 0..2 {
                                let w = row(k0 + 2 * r + p).map_or(0.0, |i| net.weights[off + i * width + n0 + 16 * j + n].to_f32());
                                for (part, bits) in split(w).into_iter().enumerate() {
                                    tiles[part * TILE_VALUES + r * 32 + 2 * n + p] = bits;
                                }
                            }
                        }
                    }
                    o += PARTS * TILE_VALUES;
                }
            }
        }
    }
    debug_assert_eq!(o, out.len());
}

/// Tiled input `i` of hidden layer `l` (see [`layer_k`]) → the layer's weight row, where it has one:
/// the tail after the head (layer 0), the hidden inputs then the tail after the head (the skip layer),
/// none for the padding.
#[inline]
pub(super) fn tiled_row(d: &NetDesc, n_tail: usize, l: usize, i: usize) -> Option<usize> {
    let (width, head) = (d.width as usize, d.n_in as usize - n_tail);
    if l == 0 {
        (i < n_tail).then_some(head + i)
    } else if i < width {
        Some(i)
    } else {
        (i - width < n_tail).then_some(width + head + i - width)
    }
}

/// Tile configuration (the 64-byte memory operand of `LDTILECFG`, Intel SDM Vol. 2: palette 1, then the
/// bytes per row of each tile at 16, its rows at 48): all 8 tiles 16 rows of 64 bytes.
#[repr(C, align(64))]
struct Config([u8; 64]);

const CONFIG: Config = {
    let mut c = [0u8; 64];
    c[0] = 1;
    let mut t = 0;
    while t < 8 {
        c[16 + 2 * t] = 64;
        c[48 + t] = 16;
        t += 1;
    }
    Config(c)
};

/// 64-byte-aligned storage (a tile row per cache line).
#[repr(C, align(64))]
struct Aligned<T>(T);

/// Bytes of the weight tiles of one step of 32 outputs and 32 inputs: both halves, every part.
const STEP_BYTES: usize = 2 * PARTS * TILE_VALUES * 2;

/// One step of a layer, 32 outputs: the accumulators `tmm0`, `tmm1` start as 16 rows of `init`
/// (stride 0), then per 32 inputs the loop `body` multiplies in the input and weight tiles, and the sums
/// go to `out`. The operands the bodies use: `{x0}`..`{x2}` (the parts of the inputs, advanced 64 bytes
/// a loop), `{xs}` (their row stride), `{w}` (advanced one step of weights a loop), `{s64}`.
macro_rules! tile_step {
    ($w:expr, $k:expr, $x:expr, $x_stride:expr, $init:expr, $out:expr, $out_stride:expr, [$($body:literal),* $(,)?]) => {
        asm!(
            "tileloadd tmm0, [{init} + {zero}*1]",
            "tileloadd tmm1, [{init} + {zero}*1 + 64]",
            "2:",
            $($body,)*
            "add {w}, {step}",
            "add {x0}, 64",
            "add {x1}, 64",
            "add {x2}, 64",
            "sub {kb}, 1",
            "jnz 2b",
            "tilestored [{out} + {os}*1], tmm0",
            "tilestored [{out} + {os}*1 + 64], tmm1",
            init = in(reg) $init,
            out = in(reg) $out,
            os = in(reg) $out_stride,
            zero = in(reg) 0usize,
            s64 = in(reg) 64usize,
            xs = in(reg) $x_stride,
            step = const STEP_BYTES,
            x0 = inout(reg) $x[0] => _,
            x1 = inout(reg) $x[1] => _,
            x2 = inout(reg) $x[2] => _,
            w = inout(reg) $w => _,
            kb = inout(reg) $k / K_TILE => _,
            options(nostack),
        )
    };
}

/// One hidden layer on the tiles: `out[q][o] = init[o] + Σ_i x[q][i] w[i][o]` for the 16 queries, in
/// steps of 32 outputs, in bf16x6 (`SIX`; inputs `tmm2`..`tmm4` = `x_0`..`x_2`, weights `tmm5`..`tmm7`
/// = `w_0`..`w_2` of one half of the outputs at a time) or bf16x3 (inputs `tmm2`, `tmm3` = `x_0`,
/// `x_1`; weights `tmm4`..`tmm7` = `w_0`, `w_1` of both halves).
///
/// # Safety
/// Tiles configured with [`CONFIG`]; `w` holds the layer's `k / 32 * n / 32` steps of [`STEP_BYTES`];
/// `x[p]` 16 rows `x_stride` bytes apart of `k` values (part 2 read in bf16x6 only); `init` `n` floats;
/// `out` 16 rows of `n` floats, `n * 4` bytes apart; `k`, `n` positive multiples of 32.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn layer<const SIX: bool>(w: *const u16, k: usize, n: usize, x: [*const u16; PARTS], x_stride: usize, init: *const f32, out: *mut f32) {
    for n0 in (0..n).step_by(N_STEP) {
        let w = w.wrapping_byte_add(n0 / N_STEP * (k / K_TILE) * STEP_BYTES);
        let (init, out) = (init.wrapping_add(n0), out.wrapping_add(n0));
        // SAFETY: every tile read and written lies in the extents of the contract.
        unsafe {
            if SIX {
                tile_step!(w, k, x, x_stride, init, out, n * 4, [
                    "tileloadd tmm2, [{x0} + {xs}*1]",
                    "tileloadd tmm3, [{x1} + {xs}*1]",
                    "tileloadd tmm4, [{x2} + {xs}*1]",
                    "tileloadd tmm5, [{w} + {s64}*1]",
                    "tileloadd tmm6, [{w} + {s64}*1 + 1024]",
                    "tileloadd tmm7, [{w} + {s64}*1 + 2048]",
                    // Small terms first: x_2·w_0, x_1·w_1, x_0·w_2, x_1·w_0, x_0·w_1, x_0·w_0.
                    "tdpbf16ps tmm0, tmm4, tmm5",
                    "tdpbf16ps tmm0, tmm3, tmm6",
                    "tdpbf16ps tmm0, tmm2, tmm7",
                    "tdpbf16ps tmm0, tmm3, tmm5",
                    "tdpbf16ps tmm0, tmm2, tmm6",
                    "tdpbf16ps tmm0, tmm2, tmm5",
                    "tileloadd tmm5, [{w} + {s64}*1 + 3072]",
                    "tileloadd tmm6, [{w} + {s64}*1 + 4096]",
                    "tileloadd tmm7, [{w} + {s64}*1 + 5120]",
                    "tdpbf16ps tmm1, tmm4, tmm5",
                    "tdpbf16ps tmm1, tmm3, tmm6",
                    "tdpbf16ps tmm1, tmm2, tmm7",
                    "tdpbf16ps tmm1, tmm3, tmm5",
                    "tdpbf16ps tmm1, tmm2, tmm6",
                    "tdpbf16ps tmm1, tmm2, tmm5",
                ]);
            } else {
                tile_step!(w, k, x, x_stride, init, out, n * 4, [
                    "tileloadd tmm2, [{x0} + {xs}*1]",
                    "tileloadd tmm3, [{x1} + {xs}*1]",
                    "tileloadd tmm4, [{w} + {s64}*1]",
                    "tileloadd tmm5, [{w} + {s64}*1 + 1024]",
                    "tileloadd tmm6, [{w} + {s64}*1 + 3072]",
                    "tileloadd tmm7, [{w} + {s64}*1 + 4096]",
                    // Small terms first: x_1·w_0, x_0·w_1, then x_0·w_0; the two accumulators
                    // alternate so that neither waits on its own previous product.
                    "tdpbf16ps tmm0, tmm3, tmm4",
                    "tdpbf16ps tmm1, tmm3, tmm6",
                    "tdpbf16ps tmm0, tmm2, tmm5",
                    "tdpbf16ps tmm1, tmm2, tmm7",
                    "tdpbf16ps tmm0, tmm2, tmm4",
                    "tdpbf16ps tmm1, tmm2, tmm6",
                ]);
            }
        }
    }
}

/// Splits 16 values into bf16 parts (round to nearest even, AVX512-BF16), as [`split`]: part 0 at
/// `x[0]`, part 1 at `x[1]`, and part 2 at `x[2]` unless it is null (bf16x3 needs two).
///
/// # Safety
/// Each non-null `x[p]` has room for 16 values; `x[0]` and `x[1]` are not null.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16,avx512vl")]
unsafe fn split16(v: __m512, x: [*mut u16; PARTS]) {
    // SAFETY: `__m256bh` and `__m256i` are both 256 bits of plain data; the stores are in the room.
    unsafe {
        let p0: __m256i = core::mem::transmute(_mm512_cvtneps_pbh(v));
        let r = _mm512_sub_ps(v, widen(p0));
        let p1: __m256i = core::mem::transmute(_mm512_cvtneps_pbh(r));
        _mm256_storeu_si256(x[0].cast(), p0);
        _mm256_storeu_si256(x[1].cast(), p1);
        if !x[2].is_null() {
            let p2: __m256i = core::mem::transmute(_mm512_cvtneps_pbh(_mm512_sub_ps(r, widen(p1))));
            _mm256_storeu_si256(x[2].cast(), p2);
        }
    }
}

/// 16 bf16 values as f32 (their bits in the high half of each lane).
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
fn widen(p: __m256i) -> __m512 {
    _mm512_castsi512_ps(_mm512_slli_epi32::<16>(_mm512_cvtepu16_epi32(p)))
}

/// `x[p] + offset` for the parts in use (null stays null).
#[inline(always)]
fn offset(x: [*mut u16; PARTS], by: usize) -> [*mut u16; PARTS] {
    x.map(|p| if p.is_null() { p } else { p.wrapping_add(by) })
}

/// ReLU of the 16 rows of `n` sums at `y`: back to `y` (`x` `None`: the last layer), or split into
/// bf16 parts at `x` (rows `x_row` values apart, see [`split16`]) as the next layer's input.
///
/// # Safety
/// `y` holds `16 * n` floats, each non-null `x[p]` 16 rows of `x_row ≥ n` values; `n` a multiple of 16.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512bf16,avx512vl")]
unsafe fn relu_split(y: *mut f32, n: usize, x: Option<[*mut u16; PARTS]>, x_row: usize) {
    // SAFETY: every access within the extents of the contract.
    unsafe {
        let zero = _mm512_setzero_ps();
        for q in 0..PACKET {
            for i in (0..n).step_by(16) {
                let p = y.add(q * n + i);
                let v = _mm512_max_ps(_mm512_loadu_ps(p), zero);
                match x {
                    None => _mm512_storeu_ps(p, v),
                    Some(x) => split16(v, offset(x, q * x_row + i)),
                }
            }
        }
    }
}

/// What hidden layer `l`'s sums start from: the folded head of layer 0 and of the skip layer
/// (`partial`), the bias (widened into `bias`) of the others.
#[inline]
pub(super) fn layer_init<'a, W: Weight>(net: &Net<'_, W>, partial: &'a Partial, l: usize, bias: &'a mut [f32; MAX_WIDTH]) -> &'a [f32] {
    let d = &net.desc;
    let width = d.width as usize;
    if l == 0 {
        &partial.layer0[..width]
    } else if d.skip as usize == l {
        &partial.skip[..width]
    } else {
        let off = d.layer_offset(l) + width * width;
        W::widen(&net.weights[off..off + width], &mut bias[..width]);
        &bias[..width]
    }
}

/// The hidden layers of `net` for [`PACKET`] queries at one prepared point, on tiles, in bf16x6 (`six`)
/// or bf16x3: query `q`'s tail at `tails[q * tail_stride..][..n_tail]`, its last hidden activation
/// (after ReLU) to `h[q * width..][..width]` (every one of those `PACKET * width` values written).
/// `tiles` is [`pack`]'s output for `net` and `n_tail`.
///
/// # Safety
/// [`available`]; `net` [`fits`] with `n_tail`, `tiles` as above, `partial.head_len + n_tail` the
/// network's input count; `tails` readable as described; `h` writable for `PACKET * width` floats.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16,avx512vl")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn hidden<W: Weight>(
    six: bool,
    net: &Net<'_, W>,
    tiles: &[u16],
    partial: &Partial,
    tails: &[f32],
    tail_stride: usize,
    n_tail: usize,
    h: *mut f32,
) {
    let d = &net.desc;
    let width = d.width as usize;
    let tp = tail_pad(n_tail);
    let row = width + tp;
    // Activation rows `[hidden outputs | tail, zero padded]`, one buffer per part (the third for
    // bf16x6 only). Not zeroed (13 KB a part a packet): the tail part is written in full below, the
    // hidden part by each layer before the next reads it, and the tiles read nothing else.
    let mut buf = MaybeUninit::<[Aligned<[u16; PACKET * ROW_MAX]>; PARTS]>::uninit();
    let base = buf.as_mut_ptr().cast::<u16>();
    let x: [*mut u16; PARTS] = core::array::from_fn(|p| if p < 2 || six { base.wrapping_add(p * PACKET * ROW_MAX) } else { core::ptr::null_mut() });
    let mut bias = [0.0f32; MAX_WIDTH];
    let mut w = tiles.as_ptr();
    // SAFETY: the buffers hold the extents `split16`, the layers and `relu_split` are given (rows of
    // `row ≤ ROW_MAX` values); the masked loads read only the `n_tail` values of each tail; tiles are
    // configured before the first tile instruction and released after the last.
    unsafe {
        for q in 0..PACKET {
            // `wrapping_add`: past the tail the pointer may leave the slice; the mask reads nothing there.
            let t = tails.as_ptr().wrapping_add(q * tail_stride);
            for i in (0..tp).step_by(16) {
                let m = mask16(n_tail.saturating_sub(i));
                split16(_mm512_maskz_loadu_ps(m, t.wrapping_add(i)), offset(x, q * row + width + i));
            }
        }
        asm!("ldtilecfg [{}]", in(reg) CONFIG.0.as_ptr(), options(nostack, readonly));
        for l in 0..d.hidden as usize {
            let k = layer_k(d, n_tail, l);
            let init = layer_init(net, partial, l, &mut bias);
            // Layer 0 reads the tail (after the hidden part of the rows); the others from the start.
            let input = offset(x, if l == 0 { width } else { 0 }).map(|p| p.cast_const());
            if six {
                layer::<true>(w, k, width, input, 2 * row, init.as_ptr(), h);
            } else {
                layer::<false>(w, k, width, input, 2 * row, init.as_ptr(), h);
            }
            w = w.add(PARTS * k * width);
            let next = (l + 1 < d.hidden as usize).then_some(x);
            relu_split(h, width, next, row);
        }
        asm!("tilerelease", options(nostack, nomem));
    }
}

/// Pairs of activations, pair-major: `xp[p * PACKET + q]` holds query `q`'s inputs `2p` (low half)
/// and `2p + 1` as bf16 bits, so that one pair of all 16 queries is one cache line and each
/// `vdpbf16ps` broadcasts its pair from a fixed offset of a moving pointer.
type Pairs = Aligned<[u32; PACKET * ROW_MAX / 2]>;

/// Writes 16 rows of 32 values (`row(q)` gives query `q`'s two vectors, low 16 first) to the pairs
/// `xp[p0..p0 + 16]`, each value rounded to bf16 (nearest, ties to even).
///
/// # Safety
/// `xp` has room for pairs `p0..p0 + 16` of [`PACKET`] queries.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,avx512bf16")]
unsafe fn to_pairs(mut row: impl FnMut(usize) -> (__m512, __m512), xp: *mut u32, p0: usize) {
    // `vcvtne2ps2bf16 dst, hi, lo` puts `lo` in the low 16 bf16: 32-bit lane `i` is the pair
    // (`2i`, `2i + 1`) of the 32 values; the transpose turns query rows into pair rows.
    let rows: [__m512; PACKET] = core::array::from_fn(|q| {
        let (lo, hi) = row(q);
        _mm512_castsi512_ps(unsafe { core::mem::transmute::<__m512bh, __m512i>(_mm512_cvtne2ps_pbh(hi, lo)) })
    });
    for (c, v) in super::x86::transpose16(rows).into_iter().enumerate() {
        // SAFETY: pair `p0 + c < p0 + 16` lies in the room of the contract.
        unsafe { _mm512_store_ps(xp.add((p0 + c) * PACKET).cast(), v) };
    }
}

/// One hidden layer in bf16 products on AVX512-BF16 vectors: `out[q][o] = init[o] + Σ_i x[q][i] w[i][o]`
/// for the 16 queries, each product of the bf16 roundings of `x` and `w` (exact in f32) added in f32
/// pairs by `vdpbf16ps`. The weights are part 0 of the tiled layout (a B tile's row is one vector:
/// 16 outputs × one pair of inputs), so the same copy serves the tiles and the vectors.
///
/// # Safety
/// `w` holds the layer's `k / 32 * n / 32` steps of [`STEP_BYTES`]; `xp` the `k / 2` pairs of the
/// layer's inputs (see [`Pairs`]), 64-byte aligned; `init` `n` floats; `out` 16 rows of `n` floats;
/// `k`, `n` positive multiples of 32.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512bf16")]
unsafe fn layer_vectors(w: *const u16, k: usize, n: usize, xp: *const u32, init: *const f32, out: *mut f32) {
    // SAFETY (whole body): every access within the extents of the contract.
    unsafe {
        for n0 in (0..n).step_by(N_STEP) {
            let step = w.byte_add(n0 / N_STEP * (k / K_TILE) * STEP_BYTES);
            for j in 0..2 {
                let mut acc = [_mm512_loadu_ps(init.add(n0 + 16 * j)); PACKET];
                // Part 0 of half `j`'s B tile, then the same tile of each further 32 inputs.
                let mut wt = step.byte_add(j * PARTS * TILE_VALUES * 2);
                let mut x = xp;
                for _ in 0..k / K_TILE {
                    for r in 0..16 {
                        let wv = _mm512_loadu_ps(wt.add(r * 32).cast());
                        // Inline asm for the embedded broadcast (`{1to16}`), which LLVM does not fold
                        // into `vdpbf16ps`: a separate `vbroadcastss` per product took 1.26× the time on Zen 4.
                        let xr = x.add(r * PACKET);
                        asm!(
                            "vdpbf16ps {a0}, {w}, dword ptr [{x}]{{1to16}}",
                            "vdpbf16ps {a1}, {w}, dword ptr [{x} + 4]{{1to16}}",
                            "vdpbf16ps {a2}, {w}, dword ptr [{x} + 8]{{1to16}}",
                            "vdpbf16ps {a3}, {w}, dword ptr [{x} + 12]{{1to16}}",
                            "vdpbf16ps {a4}, {w}, dword ptr [{x} + 16]{{1to16}}",
                            "vdpbf16ps {a5}, {w}, dword ptr [{x} + 20]{{1to16}}",
                            "vdpbf16ps {a6}, {w}, dword ptr [{x} + 24]{{1to16}}",
                            "vdpbf16ps {a7}, {w}, dword ptr [{x} + 28]{{1to16}}",
                            "vdpbf16ps {a8}, {w}, dword ptr [{x} + 32]{{1to16}}",
                            "vdpbf16ps {a9}, {w}, dword ptr [{x} + 36]{{1to16}}",
                            "vdpbf16ps {a10}, {w}, dword ptr [{x} + 40]{{1to16}}",
                            "vdpbf16ps {a11}, {w}, dword ptr [{x} + 44]{{1to16}}",
                            "vdpbf16ps {a12}, {w}, dword ptr [{x} + 48]{{1to16}}",
                            "vdpbf16ps {a13}, {w}, dword ptr [{x} + 52]{{1to16}}",
                            "vdpbf16ps {a14}, {w}, dword ptr [{x} + 56]{{1to16}}",
                            "vdpbf16ps {a15}, {w}, dword ptr [{x} + 60]{{1to16}}",
                            w = in(zmm_reg) wv,
                            x = in(reg) xr,
                            a0 = inout(zmm_reg) acc[0], a1 = inout(zmm_reg) acc[1],
                            a2 = inout(zmm_reg) acc[2], a3 = inout(zmm_reg) acc[3],
                            a4 = inout(zmm_reg) acc[4], a5 = inout(zmm_reg) acc[5],
                            a6 = inout(zmm_reg) acc[6], a7 = inout(zmm_reg) acc[7],
                            a8 = inout(zmm_reg) acc[8], a9 = inout(zmm_reg) acc[9],
                            a10 = inout(zmm_reg) acc[10], a11 = inout(zmm_reg) acc[11],
                            a12 = inout(zmm_reg) acc[12], a13 = inout(zmm_reg) acc[13],
                            a14 = inout(zmm_reg) acc[14], a15 = inout(zmm_reg) acc[15],
                            options(nostack, pure, readonly),
                        );
                    }
                    wt = wt.byte_add(STEP_BYTES);
                    x = x.add(16 * PACKET);
                }
                for (q, a) in acc.iter().enumerate() {
                    _mm512_storeu_ps(out.add(q * n + n0 + 16 * j), *a);
                }
            }
        }
    }
}

/// [`hidden`] in the arithmetic [`crate::mlp::Arithmetic::Bf16`]: every product of the hidden layers
/// one bf16 product (activations and weights rounded to bf16), sums in f32, on AVX512-BF16 vectors
/// ([`layer_vectors`]); the activations between layers ReLU'd in f32 and rounded once.
///
/// # Safety
/// AVX512-BF16 and AVX-512 ([`vectors_available`]); the rest as [`hidden`].
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,avx512bf16")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn hidden_vectors<W: Weight>(
    net: &Net<'_, W>,
    tiles: &[u16],
    partial: &Partial,
    tails: &[f32],
    tail_stride: usize,
    n_tail: usize,
    h: *mut f32,
) {
    let d = &net.desc;
    let width = d.width as usize;
    let tp = tail_pad(n_tail);
    // Pairs `[hidden outputs | tail, zero padded]`; not zeroed: the tail pairs are written in full
    // below, the hidden ones by each layer before the next reads them.
    let mut xp = MaybeUninit::<Pairs>::uninit();
    let xp = xp.as_mut_ptr().cast::<u32>();
    let mut bias = [0.0f32; MAX_WIDTH];
    let mut w = tiles.as_ptr();
    let zero = _mm512_setzero_ps();
    // SAFETY: the pairs buffer holds `(width + tp) / 2 ≤ ROW_MAX / 2` pairs of every query; the
    // masked loads read only the `n_tail` values of each tail; `h` is writable for `PACKET * width`.
    unsafe {
        for i in (0..tp).step_by(K_TILE) {
            let load = |q: usize, i: usize| {
                // `wrapping_add`: past the tail the pointer may leave the slice; the mask reads nothing there.
                let t = tails.as_ptr().wrapping_add(q * tail_stride);
                _mm512_maskz_loadu_ps(mask16(n_tail.saturating_sub(i)), t.wrapping_add(i))
            };
            to_pairs(|q| (load(q, i), load(q, i + 16)), xp, (width + i) / 2);
        }
        for l in 0..d.hidden as usize {
            let k = layer_k(d, n_tail, l);
            let init = layer_init(net, partial, l, &mut bias);
            // Layer 0 reads the tail (after the hidden pairs); the others from the start.
            let input = xp.add(if l == 0 { width / 2 * PACKET } else { 0 });
            layer_vectors(w, k, width, input, init.as_ptr(), h);
            w = w.add(PARTS * k * width);
            if l + 1 < d.hidden as usize {
                for i in (0..width).step_by(K_TILE) {
                    let relu = |q: usize, i: usize| _mm512_max_ps(_mm512_loadu_ps(h.add(q * width + i)), zero);
                    to_pairs(|q| (relu(q, i), relu(q, i + 16)), xp, i / 2);
                }
            } else {
                relu_split(h, width, None, width);
            }
        }
    }
}

/// Whether the CPU has AVX512-BF16 (with AVX-512 F, BW, VL) for [`hidden_vectors`].
pub(super) fn vectors_available() -> bool {
    std::is_x86_feature_detected!("avx512bf16")
        && std::is_x86_feature_detected!("avx512f")
        && std::is_x86_feature_detected!("avx512bw")
        && std::is_x86_feature_detected!("avx512vl")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::tests::random;
    use crate::mlp::{forward_packet, forward_with, partial, Arithmetic, Tiled};

    /// Reads `pack`'s output back with the B-tile layout of Intel's SDM (`TDPBF16PS`: element `(k, n)`
    /// of a 32×16 tile at row `k / 2`, column `2n + k % 2`): every weight of the tiled rows is its
    /// first two parts to 2^-16 of itself and its three parts to 2^-24, the padding rows are 0. Runs
    /// on any x86-64 CPU.
    #[test]
    fn pack_lays_out_the_weights_the_tiles_read() {
        let n_tail = 11;
        let d = NetDesc { n_in: 5 + n_tail as u16, width: 64, hidden: 3, n_out: 3, skip: 2 };
        let w = random(d.n_weights(), 3, 1.0);
        let net = Net { desc: d, weights: &w[..] };
        let mut tiles = alloc::vec![0u16; packed_len(&d, n_tail)];
        pack(&net, n_tail, &mut tiles);
        let (width, head) = (64, 5);
        let bf = |b: u16| half::bf16::from_bits(b).to_f32();
        let mut o = 0;
        for l in 0..3 {
            let k = layer_k(&d, n_tail, l);
            assert_eq!(k, [32, 64, 64 + 32][l]);
            let off = d.layer_offset(l);
            for n0 in (0..width).step_by(32) {
                for k0 in (0..k).step_by(32) {
                    for j in 0..2 {
                        let part = |p: usize| &tiles[o + 512 * p..o + 512 * (p + 1)];
                        for kk in 0..32 {
                            for n in 0..16 {
                                let at = (kk / 2) * 32 + 2 * n + kk % 2;
                                let i = k0 + kk;
                                let row = match l {
                                    0 => (i < n_tail).then_some(head + i),
                                    1 => Some(i),
                                    _ => if i < width { Some(i) } else { (i - width < n_tail).then_some(width + head + i - width) },
                                };
                                let want = row.map_or(0.0, |r| w[off + r * width + n0 + 16 * j + n]) as f64;
                                let two = bf(part(0)[at]) as f64 + bf(part(1)[at]) as f64;
                                let three = two + bf(part(2)[at]) as f64;
                                let at_out = n0 + 16 * j + n;
                                assert!((two - want).abs() <= want.abs() * 2f64.powi(-16), "layer {l} input {i} output {at_out}: {two} vs {want}");
                                assert!((three - want).abs() <= want.abs() * 2f64.powi(-24), "layer {l} input {i} output {at_out}: {three} vs {want}");
                            }
                        }
                        o += 3 * 512;
                    }
                }
            }
        }
        assert_eq!(o, tiles.len());
    }

    /// One tiled layer against exact sums: with inputs and weights split into bf16 pairs and f32
    /// sums, `|y - exact| ≤ (2^-15 + K·2^-23) Σ|x_i w_i|` (each product to ~3·2^-18, Henry et al.
    /// Sec. IV; the f32 sums' γ_K); in three parts (bf16x6), `≤ (2^-21 + K·2^-23) Σ|x_i w_i|`, each
    /// product to ~3·2^-24 and then f32's own sums; in one (bf16 on vectors), `≤ (2^-7 + K·2^-23)
    /// Σ|x_i w_i|`, each factor rounded to 8 significant bits (2^-8 each). Layer 0 (the tail, padded to
    /// a tile) with a head folded into `partial`; then the skip layer and a plain hidden layer, fed
    /// exact activations by a layer 0 that copies bf16-exact tail values (0/1 weights).
    #[test]
    fn tiled_layers_stay_within_the_split_bf16_error_bound() {
        let n_tail = 36;
        let maths = [(Arithmetic::SplitBf16, -15, available()), (Arithmetic::SplitBf16x6, -21, available()), (Arithmetic::Bf16, -7, vectors_available())];
        for &(math, _, here) in &maths {
            if !here {
                std::eprintln!("amx: {math:?} does not run on this CPU (no AMX-BF16 tiles, or no AVX512-BF16); skipping it");
            }
        }
        let cases = maths.into_iter().filter(|m| m.2).flat_map(|(math, e, _)| [(1u8, 0u8, false), (2, 1, true), (2, 0, true)].map(|c| (math, e, c)));
        for (math, exponent, (hidden, skip, copy_layer0)) in cases {
            let d = NetDesc { n_in: 7 + n_tail as u16, width: 128, hidden, n_out: 0, skip };
            let (width, head_len) = (128usize, 7usize);
            let mut w = random(d.n_weights(), 11 + hidden as u32 + skip as u32, 0.3);
            let mut tails = random(PACKET * n_tail, 5, 1.0);
            if copy_layer0 {
                // Layer 0: h0[o] = relu(tail[o % n_tail]), exactly (bf16-exact tails, 0/1 weights, no bias).
                for t in tails.iter_mut() {
                    *t = half::bf16::from_f32(*t).to_f32();
                }
                for i in 0..d.n_in as usize + 1 {
                    for o in 0..width {
                        w[i * width + o] = if i >= head_len && i < d.n_in as usize && (o % n_tail) == i - head_len { 1.0 } else { 0.0 };
                    }
                }
            }
            let net = Net { desc: d, weights: &w[..] };
            let head = random(head_len, 7, 1.0);
            let p = partial(&net, &head);
            let mut copy = alloc::vec![0u16; copy_len(&d, n_tail)];
            make_copy(&net, n_tail, &mut copy);
            let tiled = Tiled { values: &copy, n_tail };
            let mut out = alloc::vec![f32::NAN; PACKET * width];
            forward_packet(math, Some(tiled), &net, &p, &tails, n_tail, n_tail, &mut out, width);
            if math == Arithmetic::Bf16 {
                // One query in bf16 (`bf16_rows`: FMAs over rows) has the packet's bits (`vdpbf16ps`).
                for q in 0..PACKET {
                    let mut one = [f32::NAN; MAX_WIDTH];
                    forward_with(math, Some(tiled), &net, &p, &tails[q * n_tail..(q + 1) * n_tail], &mut one);
                    assert_eq!(one[..width], out[q * width..(q + 1) * width], "hidden {hidden} skip {skip} query {q} alone");
                }
            }
            for q in 0..PACKET {
                let x: alloc::vec::Vec<f64> = head.iter().chain(&tails[q * n_tail..(q + 1) * n_tail]).map(|&v| v as f64).collect();
                // Exact activations of the layers before the last, then the last layer's sums.
                let mut h: alloc::vec::Vec<f64> = alloc::vec::Vec::new();
                for l in 0..hidden as usize {
                    let off = d.layer_offset(l);
                    let input: alloc::vec::Vec<f64> = if l == 0 { x.clone() } else if skip as usize == l { h.iter().chain(&x).copied().collect() } else { h.clone() };
                    let k = input.len();
                    let mut next = alloc::vec![0.0f64; width];
                    for o in 0..width {
                        let (mut sum, mut mag) = (w[off + k * width + o] as f64, (w[off + k * width + o] as f64).abs());
                        for (i, &xi) in input.iter().enumerate() {
                            let t = xi * w[off + i * width + o] as f64;
                            sum += t;
                            mag += t.abs();
                        }
                        next[o] = sum.max(0.0);
                        if l + 1 == hidden as usize {
                            let got = out[q * width + o] as f64;
                            let bound = (2f64.powi(exponent) + k as f64 * 2f64.powi(-23)) * mag;
                            assert!((got - next[o]).abs() <= bound, "{math:?} hidden {hidden} skip {skip} query {q} output {o}: {got} vs {} (bound {bound:e})", next[o]);
                        }
                    }
                    h = next;
                }
            }
        }
    }

    /// Each part and product counts: layers whose outputs each read one input (so the f32 sums add
    /// nothing), with full 24-bit inputs and weights, against exact products. bf16x6 must give every
    /// output to 2^-20 of `x·w`, which dropping any of its six products or any third part would miss
    /// by ~2^-17; bf16x3 to 2^-15. Layer 0 (the tail) alone; then the skip layer and a plain layer,
    /// fed by a layer 0 that copies the tail (exact in bf16x6: `x_0 + x_1 + x_2 = x`).
    #[test]
    fn every_part_of_the_split_counts() {
        if !available() {
            std::eprintln!("amx: this CPU has no AMX-BF16 (or the OS denies the tiles); skipping");
            return;
        }
        let (n_tail, head_len, width) = (36usize, 3usize, 128usize);
        for six in [false, true] {
            for (hidden, skip) in [(1u8, 0u8), (2, 1), (2, 0)] {
                let d = NetDesc { n_in: (head_len + n_tail) as u16, width: width as u16, hidden, n_out: 0, skip };
                let last = hidden as usize - 1;
                let k_last = d.layer_inputs(last);
                // The one input row each output of the last layer reads: a tail row for layer 0, else
                // spread over the hidden rows and (skip layer) the tail rows after them.
                let pick = |o: usize| if last == 0 { head_len + o % n_tail } else { (o * 5) % k_last };
                let mut w = alloc::vec![0.0f32; d.n_weights()];
                let values = random(width, 19 + six as u32, 0.9);
                for o in 0..width {
                    if last == 1 {
                        w[(head_len + o % n_tail) * width + o] = 1.0;
                    }
                    let w_last = d.layer_offset(last) + pick(o) * width + o;
                    w[w_last] = values[o] + 0.05f32.copysign(values[o]);
                }
                let net = Net { desc: d, weights: &w[..] };
                let tails = random(PACKET * n_tail, 23, 1.0);
                let p = partial(&net, &[0.0; 3]);
                let mut copy = alloc::vec![0u16; copy_len(&d, n_tail)];
                make_copy(&net, n_tail, &mut copy);
                let mut out = alloc::vec![f32::NAN; PACKET * width];
                let math = if six { Arithmetic::SplitBf16x6 } else { Arithmetic::SplitBf16 };
                forward_packet(math, Some(Tiled { values: &copy, n_tail }), &net, &p, &tails, n_tail, n_tail, &mut out, width);
                for q in 0..PACKET {
                    let tail = &tails[q * n_tail..(q + 1) * n_tail];
                    // The input the last layer's output `o` reads, exactly.
                    let input = |o: usize| -> f64 {
                        let i = pick(o);
                        let x = if last == 0 {
                            tail[i - head_len]
                        } else if i < width {
                            tail[i % n_tail].max(0.0)
                        } else if i < width + head_len {
                            0.0 // a head row: the head (all 0) is in `partial`
                        } else {
                            tail[i - width - head_len]
                        };
                        x as f64
                    };
                    for o in 0..width {
                        let wo = w[d.layer_offset(last) + pick(o) * width + o] as f64;
                        let exact = (input(o) * wo).max(0.0);
                        let got = out[q * width + o] as f64;
                        let bound = 2f64.powi(if six { -20 } else { -15 }) * (input(o) * wo).abs();
                        assert!((got - exact).abs() <= bound, "six {six} hidden {hidden} skip {skip} query {q} output {o}: {got} vs {exact}");
                    }
                }
            }
        }
    }
}
