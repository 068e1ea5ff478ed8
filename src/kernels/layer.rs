//! What a dense layer is to the kernels (its input segments, weights and bias, or a chain of narrow
//! layers) and the table of one weight type's kernels at one level.

use super::PACKET;

/// One input segment of a layer: `n` inputs per query read from `x` (query `q` at `x[q * stride..]`)
/// against the `n` weight rows `rows` (`[n][n_out]`, row-major).
#[derive(Clone, Copy, Debug)]
pub struct Segment<'a, W> {
    /// Inputs, query after query.
    pub x: &'a [f32],
    /// Distance between two queries' inputs in `x`.
    pub stride: usize,
    /// Number of inputs (and weight rows).
    pub n: usize,
    /// The weight rows.
    pub rows: &'a [W],
}

/// One dense layer: `out[q][o] = act(init[o] + Σ over segments Σ_i x[q][i] rows[i][o])`.
#[derive(Clone, Copy, Debug)]
pub struct Dense<'a, W> {
    /// Starting accumulators (bias, or bias plus precomputed rows), shared by every query.
    pub init: &'a [f32],
    /// Input segments, accumulated in order; only the first `n_segs` are used.
    pub segs: [Segment<'a, W>; 2],
    /// Number of segments used (1 or 2).
    pub n_segs: usize,
    /// Number of outputs.
    pub n_out: usize,
    /// Apply ReLU.
    pub relu: bool,
}

impl<W> Dense<'_, W> {
    /// Checks every slice against the extents that `queries` queries with outputs `out_stride` apart
    /// in a buffer of `out_len` values will touch: the kernels read and write through raw pointers.
    pub(super) fn check(&self, queries: usize, out_len: usize, out_stride: usize) {
        assert!((1..=2).contains(&self.n_segs), "1 or 2 segments");
        assert!(self.init.len() >= self.n_out, "init shorter than the outputs");
        for s in &self.segs[..self.n_segs] {
            assert!(s.rows.len() >= s.n * self.n_out, "fewer weight rows than inputs");
            assert!(s.n == 0 || s.x.len() >= (queries - 1) * s.stride + s.n, "inputs out of bounds");
        }
        assert!(self.n_out == 0 || out_len >= (queries - 1) * out_stride + self.n_out, "outputs out of bounds");
    }
}

/// Where a layer's starting accumulators come from: f32 values (a bias with precomputed rows
/// folded in), or the layer's own bias in the weight type.
#[derive(Clone, Copy, Debug)]
pub enum Init<'a, W> {
    /// `CHAIN_WIDTH` f32 values.
    F32(&'a [f32]),
    /// `CHAIN_WIDTH` weights, widened as they are loaded.
    Bias(&'a [W]),
}

impl<W> Init<'_, W> {
    /// Number of starting values.
    #[inline]
    pub fn len(&self) -> usize {
        match self {
            Init::F32(s) => s.len(),
            Init::Bias(s) => s.len(),
        }
    }

    /// Whether there are none.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Width of every hidden layer of a [`Chain`]: the paper's networks.
pub const CHAIN_WIDTH: usize = 128;

/// Most tail inputs of a [`Chain`] (the encoded angles: at most 132).
pub const CHAIN_TAIL_MAX: usize = 256;

/// Most outputs of a [`Chain`]'s output layer (one vector).
pub const CHAIN_OUT_MAX: usize = 16;

/// A hidden layer after the first one of a [`Chain`]: `h' = ReLU(init + h rows [+ tail tail_rows])`.
#[derive(Clone, Copy, Debug)]
pub struct ChainLayer<'a, W> {
    /// Starting accumulators.
    pub init: Init<'a, W>,
    /// `[CHAIN_WIDTH][CHAIN_WIDTH]` rows read by the previous layer's activations.
    pub rows: &'a [W],
    /// The input skip: `[n_tail][CHAIN_WIDTH]` rows read by the tail, after `rows`.
    pub tail_rows: Option<&'a [W]>,
}

/// One query through a whole network of `CHAIN_WIDTH`-wide layers in one kernel call: layer 0
/// `h = ReLU(first_init + tail first_rows)`, then each of `hidden`, then the output layer
/// `bias + h rows` (no activation), or the last `h` where `out` is `None`.
///
/// The same operations in the same order as the layer-by-layer [`Kernels::one`] (so the same bits as
/// [`Kernels::packet`]); what it saves is between the layers: the activations stay in registers, their
/// nonzero entries are compressed straight from there, the tail's nonzero entries are compressed once
/// for layer 0 and the skip layer, and there is one call and one bounds check per query instead of one
/// per layer.
#[derive(Clone, Copy, Debug)]
pub struct Chain<'a, W> {
    /// The tail inputs (at most [`CHAIN_TAIL_MAX`]).
    pub tail: &'a [f32],
    /// Layer 0's starting accumulators (`CHAIN_WIDTH` values).
    pub first_init: &'a [f32],
    /// Layer 0's `[tail.len()][CHAIN_WIDTH]` rows.
    pub first_rows: &'a [W],
    /// The hidden layers after layer 0.
    pub hidden: &'a [ChainLayer<'a, W>],
    /// The output layer: bias (`n_out` weights), rows `[CHAIN_WIDTH][n_out]`, `n_out ≤ CHAIN_OUT_MAX`.
    pub out: Option<(&'a [W], &'a [W], usize)>,
}

impl<W> Chain<'_, W> {
    /// The number of outputs written.
    #[inline]
    pub fn n_out(&self) -> usize {
        self.out.map_or(CHAIN_WIDTH, |o| o.2)
    }

    /// Checks every extent the kernel reads through raw pointers.
    pub(super) fn check(&self, out_len: usize) {
        let (w, t) = (CHAIN_WIDTH, self.tail.len());
        assert!(t <= CHAIN_TAIL_MAX, "tail longer than CHAIN_TAIL_MAX");
        assert!(self.first_init.len() >= w && self.first_rows.len() >= t * w, "layer 0 out of bounds");
        for l in self.hidden {
            assert!(l.init.len() >= w && l.rows.len() >= w * w, "hidden layer out of bounds");
            assert!(l.tail_rows.is_none_or(|r| r.len() >= t * w), "skip rows out of bounds");
        }
        if let Some((bias, rows, n)) = self.out {
            assert!(n <= CHAIN_OUT_MAX && bias.len() >= n && rows.len() >= w * n, "output layer out of bounds");
        }
        assert!(out_len >= self.n_out(), "outputs out of bounds");
    }
}

/// The kernels of one weight type at one level.
pub struct Kernels<W: 'static> {
    /// One query. # Safety: callers pass a [`Dense`] that passed `check(1, ..)` and a supported level.
    pub(super) one: unsafe fn(&Dense<'_, W>, *mut f32),
    /// [`PACKET`] queries. # Safety: as `one`, `check(PACKET, ..)`.
    pub(super) packet: unsafe fn(&Dense<'_, W>, *mut f32, usize),
    /// One query through a [`Chain`], where the level has the kernel. # Safety: as `one`, the chain
    /// passed `Chain::check`.
    pub(super) chain: Option<unsafe fn(&Chain<'_, W>, *mut f32)>,
}

impl<W: 'static> Kernels<W> {
    /// Runs the layer for one query, writing `layer.n_out` values to the front of `out`.
    #[inline]
    pub fn one(&self, layer: &Dense<'_, W>, out: &mut [f32]) {
        layer.check(1, out.len(), 0);
        // SAFETY: the table holds kernels of a level the CPU supports (`table` only hands out detected
        // levels), and `check` verified every extent the kernel touches.
        unsafe { (self.one)(layer, out.as_mut_ptr()) }
    }

    /// Whether [`chain`](Self::chain) runs a whole network in one call at this level (AVX-512);
    /// elsewhere callers run the layers one by one, which gives the same bits.
    #[inline]
    pub fn has_chain(&self) -> bool {
        self.chain.is_some()
    }

    /// Runs one query through `chain`, writing `chain.n_out()` values to the front of `out`; returns
    /// `false` (and writes nothing) where the level has no chain kernel.
    #[inline]
    pub fn chain(&self, chain: &Chain<'_, W>, out: &mut [f32]) -> bool {
        let Some(f) = self.chain else {
            return false;
        };
        chain.check(out.len());
        // SAFETY: as in `one`; `check` verified every extent the kernel touches.
        unsafe { f(chain, out.as_mut_ptr()) };
        true
    }

    /// Runs the layer for [`PACKET`] queries, query `q`'s outputs at `out[q * out_stride..]`.
    #[inline]
    pub fn packet(&self, layer: &Dense<'_, W>, out: &mut [f32], out_stride: usize) {
        layer.check(PACKET, out.len(), out_stride);
        // SAFETY: as in `one`.
        unsafe { (self.packet)(layer, out.as_mut_ptr(), out_stride) }
    }
}

