//! Dense-layer kernels of the neural evaluator, selected by the CPU at run time: the bottom layer of
//! the crate, importing nothing from the modules above it (`tests/layers.rs` holds that).
//!
//! Public: the levels, their detection and `NBRDF_KERNEL` ([`Level`], [`detected`], [`level`],
//! [`set_level`], [`requested`]) and the weight types ([`Weight`]). Crate-internal: the layer
//! description (`Dense`, `Chain`, in `layer.rs`) and its table of kernels per weight type (`Kernels`,
//! `kernels()`); `lanes.rs`, the portable and NEON kernels
//! written once over a small lane trait, and `neon.rs`, the aarch64 lanes; `x86.rs`, the AVX2 and
//! AVX-512 kernels written once over that trait extended for x86 (masked loads, f16 loads, nonzero
//! masks), with `avx2.rs` and `avx512.rs` holding each level's lanes, its entry points and what exists
//! at one level only (AVX-512: the chain kernel, the paired sparse walk); `widen.rs`, the f16-to-f32
//! conversion of weight slices (`widen_f16`). Vectorised code that is not a dense layer lives with what it computes and
//! dispatches on [`level`]: Θ for 16 pairs in `angles`, the vector sin/cos in `encoding`, the output
//! maps in `math`, the tiny NBRDF-json network kernel in `measured::nbrdf_json`.
//!
//! One kernel computes one layer `y_o = init_o + Σ_s Σ_i x_s[i] M_s[i][o]` (then ReLU for hidden layers)
//! for either one query (`Kernels::one`) or a packet of [`PACKET`] queries (`Kernels::packet`).
//! The packet kernel keeps a tile of queries × outputs in registers and reads each weight row once
//! per packet, so the weights stream from cache once per packet instead of once per query.
//! `Kernels::chain` runs one query through a whole 128-wide network in one call (AVX-512).
//!
//! Levels: [`Level::Avx512`] and [`Level::Avx2`] (x86-64, with FMA and F16C: half weights are widened
//! by `vcvtph2ps` as they are loaded), [`Level::Neon`] (aarch64) and [`Level::Portable`] (plain Rust,
//! every target). With the `std` feature the level is detected once at run time
//! (`is_x86_feature_detected!`), so a default release build uses AVX-512 where the CPU has it; without
//! `std` the level is what the compile-time target features allow (`-C target-cpu=…`).
//!
//! # Determinism
//! Every query's accumulator sees the same operations in the same order whatever the kernel shape:
//! `acc = init`, then one fused multiply-add per input row in row order (`Portable`: multiply, then add).
//! So at one level, the single and the packet path give the same bits for the same query, and a query's
//! result does not depend on its neighbours in the packet — which keeps exact reciprocity bitwise in
//! batches. The one-query kernels, and the packet kernels on layers whose inputs are mostly zeros,
//! skip rows whose input is exactly zero (half the activations after a ReLU); `fma(0, w, acc) = acc`
//! for finite weights, except that `-0 + 0 = +0`, and the sign of a zero pre-activation is erased by
//! the ReLU (`max(acc, 0)` returns `+0`) and by every output map.
//! Levels differ from each other by rounding only (FMA versus multiply-then-add).

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod lanes;
#[cfg(target_arch = "aarch64")]
mod neon;
mod widen;
#[cfg(target_arch = "x86_64")]
mod x86;

use core::sync::atomic::{AtomicU8, Ordering};

pub(crate) use widen::widen_f16;
#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::{mask16, transpose16};

/// Queries per packet of the batched kernels: 16, so that one weight vector (one f16 conversion)
/// serves 16 FMAs in the AVX-512 kernel (docs/speed.md: 8 left f16 weights behind f32 ones).
pub const PACKET: usize = 16;

/// An instruction-set level of the kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// Plain Rust, every target: multiply, then add (autovectorised for the compile-time target only).
    Portable,
    /// aarch64 Advanced SIMD (NEON, part of every aarch64 CPU): 4 lanes, fused multiply-add.
    Neon,
    /// x86-64 AVX2 + FMA + F16C, 8 lanes.
    Avx2,
    /// x86-64 AVX-512 (F, BW, VL) + FMA + F16C + POPCNT, 16 lanes.
    Avx512,
}

impl Level {
    /// Every level of this target architecture, slowest first.
    #[cfg(target_arch = "x86_64")]
    pub const ALL: &'static [Level] = &[Level::Portable, Level::Avx2, Level::Avx512];
    /// Every level of this target architecture, slowest first.
    #[cfg(target_arch = "aarch64")]
    pub const ALL: &'static [Level] = &[Level::Portable, Level::Neon];
    /// Every level of this target architecture, slowest first.
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    pub const ALL: &'static [Level] = &[Level::Portable];

    /// The levels this process may use, slowest first: those of [`Level::ALL`] up to [`detected`].
    /// Tests and benchmarks loop over these to cover every path the host can run.
    pub fn usable() -> impl Iterator<Item = Level> {
        let top = detected();
        Level::ALL.iter().copied().filter(move |l| *l <= top)
    }

    /// The level's name as `NBRDF_KERNEL` spells it: `portable`, `neon`, `avx2` or `avx512`.
    pub const fn name(self) -> &'static str {
        match self {
            Level::Portable => "portable",
            Level::Neon => "neon",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    /// The level named `name` (as [`Level::name`] spells it, any case), if any.
    ///
    /// ```
    /// use nbrdf::kernels::Level;
    /// assert_eq!(Level::parse("AVX2"), Some(Level::Avx2));
    /// assert_eq!(Level::parse("sse"), None);
    /// ```
    pub fn parse(name: &str) -> Option<Level> {
        [Level::Portable, Level::Neon, Level::Avx2, Level::Avx512].into_iter().find(|l| l.name().eq_ignore_ascii_case(name.trim()))
    }

    fn from_u8(v: u8) -> Level {
        match v {
            2 => Level::Neon,
            3 => Level::Avx2,
            4 => Level::Avx512,
            _ => Level::Portable,
        }
    }

    fn to_u8(self) -> u8 {
        match self {
            Level::Portable => 1,
            Level::Neon => 2,
            Level::Avx2 => 3,
            Level::Avx512 => 4,
        }
    }
}

impl core::fmt::Display for Level {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why `NBRDF_KERNEL` cannot be honoured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelError {
    /// The value names no level (the value's first bytes, lossy, and its length).
    Unknown([u8; 16], usize),
    /// The level exists but this CPU (or target) lacks it; the best it has is the second.
    Unsupported(Level, Level),
}

impl core::fmt::Display for LevelError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LevelError::Unknown(b, n) => {
                let shown = core::str::from_utf8(&b[..(*n).min(16)]).unwrap_or("?");
                write!(f, "NBRDF_KERNEL={shown:?} names no kernel level; use portable, neon (aarch64), avx2 or avx512 (x86-64)")
            }
            LevelError::Unsupported(want, have) => {
                write!(f, "NBRDF_KERNEL={want}: this CPU lacks that level (the best it runs is {have}); choose a level at or below it")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for LevelError {}

/// The level `NBRDF_KERNEL` asks for: `Ok(None)` where it is unset or empty, an error where it names
/// no level or one above what the CPU runs ([`cpu_level`]). Command-line tools call this first and
/// stop on the error; the library itself ignores a bad value (with one message on stderr) and runs
/// the CPU's level.
#[cfg(feature = "std")]
pub fn requested() -> Result<Option<Level>, LevelError> {
    let Some(v) = std::env::var_os("NBRDF_KERNEL") else {
        return Ok(None);
    };
    let v = v.to_string_lossy();
    if v.trim().is_empty() {
        return Ok(None);
    }
    let Some(l) = Level::parse(&v) else {
        let mut b = [0u8; 16];
        let n = v.len().min(16);
        b[..n].copy_from_slice(&v.as_bytes()[..n]);
        // Cut at a character boundary so the message stays valid UTF-8.
        let n = (0..=n).rev().find(|i| v.is_char_boundary(*i)).unwrap_or(0);
        return Err(LevelError::Unknown(b, n));
    };
    let cpu = cpu_level();
    if !Level::ALL.contains(&l) || l > cpu {
        return Err(LevelError::Unsupported(l, cpu));
    }
    Ok(Some(l))
}

/// The best level this CPU runs, whatever `NBRDF_KERNEL` says (detected once with `std`;
/// compile-time target features without it).
pub fn cpu_level() -> Level {
    static CPU: AtomicU8 = AtomicU8::new(0);
    cached(&CPU, detect)
}

/// The level in `cell`, or `init()`'s, stored there first where the cell is still 0 (unset). Racing
/// threads may both run `init`; they store the same level.
#[inline]
fn cached(cell: &AtomicU8, init: impl FnOnce() -> Level) -> Level {
    match cell.load(Ordering::Relaxed) {
        0 => {
            let l = init();
            cell.store(l.to_u8(), Ordering::Relaxed);
            l
        }
        v => Level::from_u8(v),
    }
}

/// The highest level this process uses: [`cpu_level`], lowered to `NBRDF_KERNEL` where that names a
/// level the CPU runs (with `std`). Nothing in the crate runs code of a level above it, so one host
/// tests every level below its own by setting the variable.
pub fn detected() -> Level {
    static DETECTED: AtomicU8 = AtomicU8::new(0);
    cached(&DETECTED, ceiling)
}

#[cfg(feature = "std")]
fn ceiling() -> Level {
    match requested() {
        Ok(Some(l)) => l,
        Ok(None) => cpu_level(),
        Err(e) => {
            std::eprintln!("nbrdf: {e}; running {}", cpu_level());
            cpu_level()
        }
    }
}

#[cfg(not(feature = "std"))]
fn ceiling() -> Level {
    cpu_level()
}

/// 0: not chosen yet; otherwise the level the evaluator uses.
static ACTIVE: AtomicU8 = AtomicU8::new(0);

/// The level the evaluator uses now: [`detected`], unless lowered by [`set_level`].
#[inline]
pub fn level() -> Level {
    cached(&ACTIVE, detected)
}

/// Makes the evaluator use `level` (clamped to [`detected`]; a level of another architecture gives
/// [`Level::Portable`]), or the detected level for `None`; returns the level now in use.
/// Process-wide: for benchmarks and tests that compare levels.
pub fn set_level(level: Option<Level>) -> Level {
    let l = match level {
        None => detected(),
        Some(l) if Level::ALL.contains(&l) => l.min(detected()),
        Some(_) => Level::Portable,
    };
    ACTIVE.store(l.to_u8(), Ordering::Relaxed);
    l
}

#[cfg(all(target_arch = "x86_64", feature = "std"))]
fn detect() -> Level {
    let base = std::is_x86_feature_detected!("avx2")
        && std::is_x86_feature_detected!("fma")
        && std::is_x86_feature_detected!("f16c");
    if base
        && std::is_x86_feature_detected!("avx512f")
        && std::is_x86_feature_detected!("avx512bw")
        && std::is_x86_feature_detected!("avx512vl")
        && std::is_x86_feature_detected!("popcnt")
    {
        Level::Avx512
    } else if base {
        Level::Avx2
    } else {
        Level::Portable
    }
}

#[cfg(all(target_arch = "x86_64", not(feature = "std")))]
fn detect() -> Level {
    if cfg!(all(
        target_feature = "avx512f",
        target_feature = "avx512bw",
        target_feature = "avx512vl",
        target_feature = "avx2",
        target_feature = "fma",
        target_feature = "f16c",
        target_feature = "popcnt"
    )) {
        Level::Avx512
    } else if cfg!(all(target_feature = "avx2", target_feature = "fma", target_feature = "f16c")) {
        Level::Avx2
    } else {
        Level::Portable
    }
}

#[cfg(target_arch = "aarch64")]
fn detect() -> Level {
    // Advanced SIMD is part of the aarch64 base architecture (and of every Rust aarch64 target).
    if cfg!(target_feature = "neon") {
        Level::Neon
    } else {
        Level::Portable
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
fn detect() -> Level {
    Level::Portable
}

// The layer descriptions and the kernel table: public items in a private module, so that the
// `Weight` trait can name them while no other crate can (the level API is the kernels' public face).
mod layer;
pub(crate) use layer::{Chain, ChainLayer, Dense, Init, Kernels, Segment, CHAIN_OUT_MAX, CHAIN_TAIL_MAX, CHAIN_WIDTH};

/// A weight element: `f32`, or `half::f16` for half-size model files (widened to f32 as it is read).
///
/// The one weight trait of the crate: how the kernels read a weight type (in place, or widened) and
/// their table of kernels for it. The networks take it as [`crate::mlp::Weight`].
pub trait Weight: Copy + Send + Sync + 'static {
    /// The value as `f32`.
    fn to_f32(self) -> f32;

    /// The slice itself where it already holds f32 values (read in place rather than widened).
    fn as_f32(s: &[Self]) -> Option<&[f32]>;

    /// `dst[i] = src[i].to_f32()` over the common length, as fast as the CPU allows.
    fn widen(src: &[Self], dst: &mut [f32]);

    /// The kernels of `level`, which must be at most [`detected`] (lower levels are always safe).
    #[doc(hidden)]
    fn table(level: Level) -> &'static Kernels<Self>;
}

/// The body of [`Weight::table`] for weight type `$w`: its kernels at each level of this target.
macro_rules! table {
    ($w:ty) => {
        #[inline]
        fn table(level: Level) -> &'static Kernels<$w> {
            static PORTABLE: Kernels<$w> =
                Kernels { one: lanes::portable::one::<$w>, packet: lanes::portable::packet::<$w>, chain: None };
            #[cfg(target_arch = "aarch64")]
            static NEON: Kernels<$w> = Kernels { one: neon::one::<$w>, packet: neon::packet::<$w>, chain: None };
            #[cfg(target_arch = "x86_64")]
            static AVX2: Kernels<$w> = Kernels { one: avx2::one::<$w>, packet: avx2::packet::<$w>, chain: None };
            #[cfg(target_arch = "x86_64")]
            static AVX512: Kernels<$w> =
                Kernels { one: avx512::one::<$w>, packet: avx512::packet::<$w>, chain: Some(avx512::chain::<$w>) };
            // Never hand out a level above the detected one, whatever the caller asked for.
            match level.min(detected()) {
                Level::Portable => &PORTABLE,
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 => &AVX2,
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 => &AVX512,
                #[cfg(target_arch = "aarch64")]
                Level::Neon => &NEON,
                _ => &PORTABLE,
            }
        }
    };
}

impl Weight for f32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }

    #[inline(always)]
    fn as_f32(s: &[f32]) -> Option<&[f32]> {
        Some(s)
    }

    #[inline(always)]
    fn widen(src: &[f32], dst: &mut [f32]) {
        let n = src.len().min(dst.len());
        dst[..n].copy_from_slice(&src[..n]);
    }

    table!(f32);
}

impl Weight for half::f16 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        half::f16::to_f32(self)
    }

    #[inline(always)]
    fn as_f32(_: &[half::f16]) -> Option<&[f32]> {
        None
    }

    /// Through `widen_f16`: one level check per slice and 16 values per `vcvtph2ps`, where `to_f32`
    /// in a loop is an out-of-line call with its own feature check per element.
    #[inline(always)]
    fn widen(src: &[half::f16], dst: &mut [f32]) {
        widen_f16(src, dst);
    }

    table!(half::f16);
}

/// Says, past the test harness's output capture, that a check was skipped for want of `level` on this
/// host (or under `NBRDF_KERNEL`), so a test that could not run its check does not pass silently:
/// cargo prints it with the test run, and `.ci/run` counts the lines.
#[cfg(all(test, feature = "std"))]
pub(crate) fn skipped(check: &str, level: Level) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED: {check}: needs the {level} level; this run's highest is {}", detected());
}

/// The kernels of the active [`level`] for weights `W`.
#[inline]
pub(crate) fn kernels<W: Weight>() -> &'static Kernels<W> {
    W::table(level())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    const N: usize = 16384;

    /// `n` values uniform in `[-scale, scale)` from a linear congruential generator: the kernel tests'
    /// made-up weights and inputs.
    pub(crate) fn random(n: usize, seed: u32, scale: f32) -> alloc::vec::Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(1664525).wrapping_add(1013904223);
                ((s >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 2.0 * scale
            })
            .collect()
    }

    fn values(n: usize, seed: u32, zero_every: usize) -> [f32; N] {
        let mut v = [0.0f32; N];
        let mut s = seed;
        for (i, x) in v.iter_mut().take(n).enumerate() {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            *x = if zero_every > 0 && i % zero_every == 0 { 0.0 } else { ((s >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 0.8 };
        }
        v
    }

    /// f64 reference of one query of a layer.
    fn reference<W: Weight>(l: &Dense<'_, W>, q: usize) -> [f64; 256] {
        let mut y = [0.0f64; 256];
        for (o, y) in y.iter_mut().enumerate().take(l.n_out) {
            let mut a = l.init[o] as f64;
            for s in &l.segs[..l.n_segs] {
                for i in 0..s.n {
                    a += s.x[q * s.stride + i] as f64 * s.rows[i * l.n_out + o].to_f32() as f64;
                }
            }
            *y = if l.relu { a.max(0.0) } else { a };
        }
        y
    }

    /// Distance between two queries' inputs in the test layers.
    const LAYER_STRIDE: usize = 330;

    /// The inputs of a test layer: two segments' worth for `PACKET` queries, and `init`.
    fn layer_inputs(n_out: usize, n1: usize) -> ([f32; N], [f32; N], [f32; N]) {
        (values(PACKET * LAYER_STRIDE, n_out as u32, 3), values(PACKET * LAYER_STRIDE, 99 + n1 as u32, 4), values(n_out, 5, 0))
    }

    /// A test layer of shape `(n_out, n1, n2, relu)` over `w`: segments of `n1` and `n2` inputs.
    fn test_layer<'a, W>(
        w: &'a [W],
        (n_out, n1, n2, relu): (usize, usize, usize, bool),
        x1: &'a [f32],
        x2: &'a [f32],
        init: &'a [f32],
    ) -> Dense<'a, W> {
        let stride = LAYER_STRIDE;
        let seg1 = Segment { x: x1, stride, n: n1, rows: &w[..n1 * n_out] };
        let seg2 = Segment { x: x2, stride, n: n2, rows: &w[n1 * n_out..(n1 + n2) * n_out] };
        Dense { init: &init[..n_out], segs: [seg1, seg2], n_segs: if n2 > 0 { 2 } else { 1 }, n_out, relu }
    }

    /// Query `q` of a packet's test layer as a one-query layer.
    fn alone<'a, W: Copy>(layer: &Dense<'a, W>, q: usize) -> Dense<'a, W> {
        let mut l = *layer;
        for s in &mut l.segs[..l.n_segs] {
            s.x = &s.x[q * s.stride..];
        }
        l
    }

    fn check_shapes<W: Weight>(w: &[W]) {
        for &(n_out, n1, n2, relu) in
            &[(3, 20, 0, false), (6, 31, 0, false), (17, 9, 5, true), (21, 21, 0, true), (32, 6, 0, true), (64, 20, 0, false), (128, 40, 0, true), (128, 64, 7, true), (130, 12, 3, true), (200, 3, 0, true), (48, 5, 5, false), (17, 300, 20, true), (40, 250, 9, false)]
        {
            let (x1, x2, init) = layer_inputs(n_out, n1);
            let layer = test_layer(w, (n_out, n1, n2, relu), &x1, &x2, &init);
            let os = n_out + 3;
            let mut portable = [0.0f32; PACKET * 260];
            W::table(Level::Portable).packet(&layer, &mut portable, os);
            for level in Level::usable() {
                let k = W::table(level);
                let mut packed = [f32::NAN; PACKET * 260];
                k.packet(&layer, &mut packed, os);
                for q in 0..PACKET {
                    let want = reference(&layer, q);
                    // One query through the one-query kernel: the same bits as its lane of the packet.
                    let mut single = [f32::NAN; 260];
                    k.one(&alone(&layer, q), &mut single);
                    for o in 0..n_out {
                        let got = packed[q * os + o];
                        assert_eq!(got.to_bits(), single[o].to_bits(), "{level:?} n_out {n_out} q {q} o {o}");
                        assert!((got as f64 - want[o]).abs() < 1e-5, "{level:?}: {got} vs {}", want[o]);
                        assert!((got - portable[q * os + o]).abs() < 1e-5, "{level:?} vs portable");
                    }
                    // Nothing written past the outputs.
                    assert!(single[n_out].is_nan() && packed[q * os + n_out].is_nan());
                }
            }
        }
    }

    #[test]
    fn every_level_matches_the_reference_and_packets_match_single_queries_bitwise() {
        let w = values(N, 17, 0);
        check_shapes::<f32>(&w[..]);
        let h: [half::f16; N] = core::array::from_fn(|i| half::f16::from_f32(w[i]));
        check_shapes::<half::f16>(&h[..]);
    }

    /// Overlapping windows of test weights, a different one per matrix.
    struct Windows<'a, W> {
        w: &'a [W],
        at: usize,
    }

    impl<'a, W> Windows<'a, W> {
        fn take(&mut self, n: usize) -> &'a [W] {
            let start = self.at % (self.w.len() - n + 1);
            self.at += 977;
            &self.w[start..start + n]
        }
    }

    /// Layer 0's rows and 5 hidden layers of a test chain (the skip layer, if any, starting from
    /// `skip_init` and reading the tail again).
    fn chain_layers<'a, W>(
        win: &mut Windows<'a, W>,
        n_tail: usize,
        skip: Option<usize>,
        skip_init: &'a [f32],
    ) -> (&'a [W], [ChainLayer<'a, W>; 5]) {
        const C: usize = CHAIN_WIDTH;
        let first_rows = win.take(n_tail * C);
        let layers = core::array::from_fn(|l| ChainLayer {
            init: if skip == Some(l) { Init::F32(&skip_init[..C]) } else { Init::Bias(win.take(C)) },
            rows: win.take(C * C),
            tail_rows: (skip == Some(l)).then(|| win.take(n_tail * C)),
        });
        (first_rows, layers)
    }

    /// The hidden layers of a chain run one by one through `one` (a one-query kernel); the last
    /// layer's activations.
    fn layer_by_layer<W: Weight>(
        one: impl Fn(&Dense<'_, W>, &mut [f32]),
        tail: &[f32],
        first_init: &[f32],
        first_rows: &[W],
        hidden: &[ChainLayer<'_, W>],
    ) -> [f32; CHAIN_WIDTH] {
        const C: usize = CHAIN_WIDTH;
        let none = Segment { x: &[], stride: 0, n: 0, rows: &[] };
        let ts = |rows| Segment { x: tail, stride: 0, n: tail.len(), rows };
        let (mut h, mut t) = ([0.0f32; C], [0.0f32; C]);
        one(&Dense { init: &first_init[..C], segs: [ts(first_rows), none], n_segs: 1, n_out: C, relu: true }, &mut h);
        for l in hidden {
            let mut bias = [0.0f32; C];
            let init = match l.init {
                Init::F32(s) => s,
                Init::Bias(b) => {
                    W::widen(b, &mut bias);
                    &bias[..]
                }
            };
            let hs = Segment { x: &h[..], stride: 0, n: C, rows: l.rows };
            let segs = [hs, l.tail_rows.map_or(none, ts)];
            one(&Dense { init, segs, n_segs: 1 + l.tail_rows.is_some() as usize, n_out: C, relu: true }, &mut t);
            core::mem::swap(&mut h, &mut t);
        }
        h
    }

    /// The shapes of the chain tests: tail length, hidden layers, skip layer.
    const CHAIN_SHAPES: [(usize, usize, Option<usize>); 6] =
        [(0, 1, None), (5, 2, Some(0)), (36, 5, Some(1)), (40, 3, None), (120, 4, Some(3)), (17, 1, Some(0))];

    /// A chain against the same layers run one by one through `Kernels::one`: every tail length
    /// (none, below and above the dense-layer threshold, near the longest encoding), with and without a
    /// skip layer, every output-layer shape.
    fn check_chain<W: Weight>(w: &[W]) {
        let k = W::table(detected());
        if !k.has_chain() {
            return;
        }
        const C: usize = CHAIN_WIDTH;
        let f32_init = values(C, 3, 0);
        let skip_init = values(C, 4, 0);
        for (&(n_tail, n_hidden, skip), n_out) in CHAIN_SHAPES.iter().zip([3, 0, 3, 6, 16, 1]) {
            let tail = values(n_tail, 7 + n_tail as u32, 3);
            let mut win = Windows { w, at: 0 };
            let (first_rows, layers) = chain_layers(&mut win, n_tail, skip, &skip_init);
            let hidden = &layers[..n_hidden];
            let out_layer = (n_out > 0).then(|| (win.take(n_out), win.take(C * n_out), n_out));
            let chain = Chain { tail: &tail[..n_tail], first_init: &f32_init[..C], first_rows, hidden, out: out_layer };
            let mut got = [f32::NAN; C + 1];
            assert!(k.chain(&chain, &mut got));

            // The same network layer by layer.
            let h = layer_by_layer(|l, out| k.one(l, out), &tail[..n_tail], &f32_init, first_rows, hidden);
            let mut want = [f32::NAN; C + 1];
            match out_layer {
                None => want[..C].copy_from_slice(&h),
                Some((b, rows, n)) => {
                    let mut bias = [0.0f32; CHAIN_OUT_MAX];
                    W::widen(b, &mut bias[..n]);
                    let hs = Segment { x: &h[..], stride: 0, n: C, rows };
                    let none = Segment { x: &[], stride: 0, n: 0, rows: &[] };
                    k.one(&Dense { init: &bias[..n], segs: [hs, none], n_segs: 1, n_out: n, relu: false }, &mut want);
                }
            }
            let n = chain.n_out();
            for o in 0..=n {
                assert_eq!(got[o].to_bits(), want[o].to_bits(), "tail {n_tail} hidden {n_hidden} skip {skip:?} out {n_out}: output {o}");
            }
            assert!(got[n].is_nan(), "nothing written past the outputs");
        }
    }

    /// A sparse packet kernel (each query's nonzero inputs, blocks of rows) against the dense one of
    /// its level and the f64 reference: the same bits for every query, over one, two and three blocks of rows,
    /// a second segment (empty or not), inputs with no zeros, all zeros, NaN and -0, rows that one
    /// query alone uses, pairs of queries walked together with rows only one of them uses, f32 and
    /// f16 weights.
    #[cfg(target_arch = "x86_64")]
    fn check_sparse<W: Weight>(w: &[W], sparse: unsafe fn(&Dense<'_, W>, *mut f32, usize), dense: unsafe fn(&Dense<'_, W>, *mut f32, usize)) {
        for (case, &(n1, n2, zero_every)) in [(128, 0, 2), (128, 36, 2), (40, 0, 3), (150, 70, 2), (64, 1, 5), (0, 36, 2), (0, 0, 2), (100, 12, 1), (128, 0, 1), (128, 0, 2)].iter().enumerate() {
            let (mut x1, mut x2, init) = layer_inputs(128, n1);
            // Fewer zeros than `values` leaves where `zero_every` is 1 (then every input is zero).
            for (i, v) in x1.iter_mut().take(PACKET * LAYER_STRIDE).enumerate() {
                if i % zero_every == 0 {
                    *v = 0.0;
                }
            }
            if case == 3 {
                (x1[5], x1[LAYER_STRIDE + 7], x2[2 * LAYER_STRIDE + 3]) = (f32::NAN, -0.0, -0.0);
            }
            if case == 9 {
                // Neighbours that share 7/8 of their rows (walked as a pair, `sparse_pair`), each
                // with rows the other does not use: odd queries lose every sixteenth nonzero input.
                for q in (1..PACKET).step_by(2) {
                    for j in (1..128).step_by(16) {
                        x1[q * LAYER_STRIDE + j] = 0.0;
                    }
                }
            }
            if case == 8 {
                // Rows that one query alone uses, in either block (f16 weights widen only the rows
                // some query uses).
                (x1[5 * LAYER_STRIDE + 3], x1[9 * LAYER_STRIDE + 100], x1[9 * LAYER_STRIDE + 127]) = (1.5, -2.0, 0.25);
            }
            let mut layer = test_layer(w, (128, n1, n2, true), &x1, &x2, &init);
            if case == 0 {
                // A second segment without inputs (a skip layer's empty tail): the ReLU still follows
                // the first one's last block.
                layer.n_segs = 2;
            }
            let os = 133;
            let (mut got, mut want) = ([f32::NAN; PACKET * 133], [f32::NAN; PACKET * 133]);
            layer.check(PACKET, got.len(), os);
            // SAFETY: the CPU has the kernels' level (checked by the caller); the layer passed `check`.
            unsafe {
                sparse(&layer, got.as_mut_ptr(), os);
                dense(&layer, want.as_mut_ptr(), os);
            }
            for q in 0..PACKET {
                let exact = reference(&layer, q);
                for o in 0..133 {
                    let (g, d) = (got[q * os + o], want[q * os + o]);
                    assert_eq!(g.to_bits(), d.to_bits(), "case {case} q {q} o {o}: {g} vs {d}");
                    if o < 128 && !g.is_nan() {
                        assert!((g as f64 - exact[o]).abs() < 1e-5, "case {case}: {g} vs {}", exact[o]);
                    }
                }
            }
            // The NaN input makes every sum of its query NaN, which the ReLU maps to +0; no other
            // query sees it.
            if case == 3 {
                assert!(got[..128].iter().all(|v| v.to_bits() == 0) && got[os..os + 128].iter().any(|v| *v > 0.0));
            }
        }
    }

    /// `NBRDF_KERNEL`'s errors name the value and what the CPU has; every level's name parses back.
    #[test]
    fn level_names_round_trip_and_errors_say_what_to_do() {
        for l in [Level::Portable, Level::Neon, Level::Avx2, Level::Avx512] {
            assert_eq!(Level::parse(l.name()), Some(l));
        }
        assert_eq!(Level::parse(" Avx512 "), Some(Level::Avx512));
        use alloc::string::ToString;
        let e = LevelError::Unsupported(Level::Avx512, Level::Avx2).to_string();
        assert!(e.contains("NBRDF_KERNEL=avx512") && e.contains("best it runs is avx2"), "{e}");
        let mut b = [0u8; 16];
        b[..4].copy_from_slice(b"sse9");
        let e = LevelError::Unknown(b, 4).to_string();
        assert!(e.contains("\"sse9\"") && e.contains("portable") && e.contains("avx512"), "{e}");
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_sparse_packet_kernels_give_the_bits_of_the_dense_ones() {
        let w = random(128 * 220, 29, 0.4);
        let h: alloc::vec::Vec<half::f16> = w.iter().map(|&v| half::f16::from_f32(v)).collect();
        if detected() >= Level::Avx2 {
            check_sparse::<f32>(&w[..], avx2::packet_sparse, avx2::packet_dense);
            check_sparse::<half::f16>(&h[..], avx2::packet_sparse, avx2::packet_dense);
        } else {
            skipped("sparse packets at avx2", Level::Avx2);
        }
        if detected() >= Level::Avx512 {
            check_sparse::<f32>(&w[..], avx512::packet_sparse, avx512::packet_dense);
            check_sparse::<half::f16>(&h[..], avx512::packet_sparse, avx512::packet_dense);
        } else {
            skipped("sparse packets at avx512", Level::Avx512);
        }
    }

    #[test]
    fn a_chain_gives_the_bits_of_its_layers_run_one_by_one() {
        let w = values(N, 23, 0);
        check_chain::<f32>(&w[..]);
        let h: [half::f16; N] = core::array::from_fn(|i| half::f16::from_f32(w[i]));
        check_chain::<half::f16>(&h[..]);
    }

    #[test]
    fn a_chain_with_a_tail_beyond_its_capacity_is_rejected() {
        let k = <f32 as Weight>::table(detected());
        if !k.has_chain() {
            return;
        }
        let w = [0.0f32; (CHAIN_TAIL_MAX + 1) * CHAIN_WIDTH];
        let tail = [1.0f32; CHAIN_TAIL_MAX + 1];
        let chain = Chain { tail: &tail, first_init: &w[..CHAIN_WIDTH], first_rows: &w, hidden: &[], out: None };
        let r = std::panic::catch_unwind(|| k.chain(&chain, &mut [0.0; CHAIN_WIDTH]));
        assert!(r.is_err(), "a tail longer than CHAIN_TAIL_MAX must not reach the kernel");
    }

    #[test]
    fn set_level_is_clamped_to_the_detected_level() {
        assert!(level() <= detected());
        assert_eq!(Level::Portable.min(detected()), Level::Portable);
    }
}
