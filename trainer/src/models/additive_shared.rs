//! The Additive Shared model's three networks (docs/models.md) as one candle op with its own backward
//! pass (issue 8): the trunk on the position encoding, the diffuse head on the trunk's features `t`,
//! the specular head on `[t, PE(a)]`; the output is both heads side by side, `[d, s]`, which is what
//! the fused objective reads.
//!
//! Why one op: as a trunk op and a heads op, candle gave the trunk's output gradient a zeroed buffer
//! and added the heads' gradient into it (three passes over a `[2^15, 128]` matrix), `t` went to memory
//! between the two ops and back, and the specular head read a joined copy of `[t, PE(a)]`. Here a block
//! of rows goes through the trunk and both heads while it is in L2, forward and backward: the specular
//! head reads `t` and the angles in place as its first layer's two inputs (a [`Net`] lead), the heads
//! write straight into `[d, s]`, and a sweep's trunk gradient lives in a buffer of a few hundred rows.
//! The outputs are those of the three networks run one by one, bit for bit, and so are the heads'
//! gradients; the trunk's differ by rounding, as `∂t` continues the specular head's sums from the
//! diffuse head's instead of adding two finished sums. trainer/tests/fused.rs checks both, and the
//! op against the layer-by-layer path.

use std::sync::{Arc, Mutex};

use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::dense::{Mat, Shared};
use super::fused::{add_in_order, data, dims2, storage_data};
use super::mlp::Mlp;
use super::network::{Dst, Grad, Net, NetShape, BACKWARD_ROWS, FORWARD_ROWS, SWEEP_ROWS};

/// What a forward pass keeps for the backward pass: every trunk layer's output (the last is `t`) and
/// each head's hidden activations.
#[derive(Default)]
struct Kept {
    trunk: Vec<Vec<f32>>,
    d: Vec<Vec<f32>>,
    s: Vec<Vec<f32>>,
}

/// The op over `(x [N, n_p], a [N, n_a], p)`: the position encoding, the angles' encoding, and the
/// three networks' weights, each network's matrices then its biases as [`super::network::network`]
/// takes them, in the order trunk, diffuse head, specular head.
struct AdditiveShared {
    trunk: NetShape,
    d: NetShape,
    s: NetShape,
    kept: Arc<Mutex<Kept>>,
}

fn poisoned(op: &str) -> candle_core::Error {
    candle_core::Error::Msg(format!("{op}: poisoned activations"))
}

/// `[n, m]` buffers, uninitialised, one per layer width in `widths`, and where their rows go.
fn buffers(widths: &[usize], n: usize) -> (Vec<Vec<f32>>, Vec<Dst>) {
    let mut v: Vec<Vec<f32>> = Vec::new();
    let mut d = Vec::new();
    for &m in widths {
        let mut b = Vec::with_capacity(n * m);
        d.push(Dst { at: Shared(b.as_mut_ptr()), ld: m });
        v.push(b);
    }
    (v, d)
}

/// The same destinations from row `r` on.
///
/// # Safety
/// Row `r` must be within every buffer.
unsafe fn from_row(dst: &[Dst], r: usize) -> Vec<Dst> {
    // SAFETY: forwarded from the caller.
    dst.iter().map(|d| Dst { at: Shared(unsafe { d.at.add(r * d.ld) }), ld: d.ld }).collect()
}

/// The rows of each buffer from row `r` on, to read.
///
/// # Safety
/// Row `r` must be within every buffer.
unsafe fn mats_from(v: &[Vec<f32>], widths: &[(usize, usize)], r: usize) -> Vec<Mat> {
    // SAFETY: forwarded from the caller.
    v.iter().zip(widths).map(|(b, &(_, m))| unsafe { Mat::new(b, m).at(r, 0) }).collect()
}

/// The model's three networks on their blocks of a parameter vector `p` (each network's matrices then
/// its biases, in the order trunk, diffuse head, specular head), checked against an input of `n_p`
/// position and `n_a` angle columns: the passes on a block of rows that this op and the fused
/// training step ([`super::step`]) share.
pub(super) struct Three<'a> {
    pub trunk: Net<'a>,
    pub d: Net<'a>,
    pub s: Net<'a>,
    /// Where each network's matrices and biases start in `p`, and how many biases it has.
    at: [(usize, usize, usize); 3],
}

impl<'a> Three<'a> {
    pub fn new(shapes: [&'a NetShape; 3], p: &'a [f32], n_p: usize, n_a: usize, op: &str) -> Result<Self> {
        let total: usize = shapes.iter().map(|s| s.sizes().0 + s.sizes().1).sum();
        if p.len() != total {
            candle_core::bail!("{op}: {} parameters for networks of {total}", p.len())
        }
        let mut at = [(0, 0, 0); 3];
        let mut o = 0;
        for (a, s) in at.iter_mut().zip(shapes) {
            let (w, b) = s.sizes();
            *a = (o, o + w, b);
            o += w + b;
        }
        let block = |i: usize| {
            let (w, b) = shapes[i].sizes();
            (&p[at[i].0..at[i].0 + w], &p[at[i].1..at[i].1 + b])
        };
        let trunk = Net::new(shapes[0], block(0).0, block(0).1, 0, n_p, op)?;
        let n_t = trunk.m();
        let d = Net::new(shapes[1], block(1).0, block(1).1, 0, n_t, op)?;
        let s = Net::new(shapes[2], block(2).0, block(2).1, n_t, n_a, op)?;
        Ok(Three { trunk, d, s, at })
    }

    /// Columns of the output `[d, s]`: `(m_d, m_d + m_s)`.
    pub fn widths(&self) -> (usize, usize) {
        (self.d.m(), self.d.m() + self.s.m())
    }

    /// Columns of the widest matrix side of the three, the width of a sweep's gradient buffers.
    pub fn width(&self) -> usize {
        [&self.trunk, &self.d, &self.s].iter().map(|net| net.width()).max().unwrap_or(0)
    }

    /// `Wᵀ` of every layer of the three networks.
    pub fn transposed(&self) -> [Vec<Vec<f32>>; 3] {
        [self.trunk.transposed(), self.d.transposed(), self.s.transposed()]
    }

    /// Zeroes the bias blocks of a gradient laid out as `p`, the blocks that the sweeps add to.
    ///
    /// # Safety
    /// `dp` must have room for `p.len()` values.
    pub unsafe fn zero_biases(&self, dp: *mut f32) {
        for &(_, ob, nb) in &self.at {
            // SAFETY: the bias blocks lie within p's length (checked in `new`).
            unsafe { std::ptr::write_bytes(dp.add(ob), 0, nb) };
        }
    }

    /// The forward pass on `rows` rows, `x` and `a` from the block's first row: the trunk's layers to
    /// `dst_t` (the last is `t`), the heads' hidden layers to `dst_d` and `dst_s`, and their outputs
    /// side by side to `out` (`[d, s]`, row stride ≥ `m_d + m_s`); the specular head reads `t` and the
    /// angles in place.
    ///
    /// # Safety
    /// As [`Net::forward_rows`] for each network.
    pub unsafe fn forward_rows(&self, rows: usize, x: Mat, a: Mat, (dst_t, dst_d, dst_s): (&[Dst], &[Dst], &[Dst]), out: Dst) {
        let n_t = self.trunk.m();
        // SAFETY: the caller's contract.
        unsafe {
            self.trunk.forward_rows(rows, x, x, dst_t);
            let tm = Mat { ptr: dst_t[dst_t.len() - 1].at.0, ld: n_t };
            let mut at_d = dst_d.to_vec();
            at_d.push(out);
            self.d.forward_rows(rows, tm, tm, &at_d);
            let mut at_s = dst_s.to_vec();
            at_s.push(Dst { at: Shared(out.at.add(self.d.m())), ld: out.ld });
            self.s.forward_rows(rows, a, tm, &at_s);
        }
    }

    /// The backward pass on one sweep of `rows` rows from the gradient `dy` of `[d, s]`: each network's
    /// weight and bias gradients into its blocks of `dp` (laid out as `p`; `first`: the matrices are
    /// written, not added to), the heads' `∂t` through the buffer `dt` (`rows × n_t`) to the trunk.
    /// `acts_*` are the networks' layer outputs (the trunk's last is `t`, the heads' outputs are not
    /// read), `x` and `a` the inputs, all from the sweep's first row; `wt` is [`Three::transposed`].
    ///
    /// # Safety
    /// As [`Net::backward_rows`] for each network; `dp` must have room for `p.len()` values and its
    /// bias blocks be initialised ([`Three::zero_biases`]).
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn backward_rows(
        &self,
        wt: &[Vec<Vec<f32>>; 3],
        rows: usize,
        (acts_t, acts_d, acts_s): (&[Mat], &[Mat], &[Mat]),
        x: Mat,
        a: Mat,
        dy: Mat,
        dp: *mut f32,
        first: bool,
        scratch: (&mut Vec<f32>, &mut Vec<f32>),
        dt: *mut f32,
    ) {
        let n_t = self.trunk.m();
        let (g, below) = scratch;
        let tm = acts_t[acts_t.len() - 1];
        let dt_at = Dst { at: Shared(dt), ld: n_t };
        // SAFETY: the caller's contract; each network's blocks of dp are its own.
        unsafe {
            let db = |i: usize| std::slice::from_raw_parts_mut(dp.add(self.at[i].1), self.at[i].2);
            let to_dt = |add| Some(Grad { to: dt_at, add });
            self.d.backward_rows(&wt[1], rows, acts_d, None, tm, tm, dy, dp.add(self.at[1].0), db(1), first, (&mut *g, &mut *below), to_dt(false), None);
            self.s.backward_rows(&wt[2], rows, acts_s, None, a, tm, dy.at(0, self.d.m()), dp.add(self.at[2].0), db(2), first, (&mut *g, &mut *below), None, to_dt(true));
            let dtm = Mat { ptr: dt, ld: n_t };
            let hidden_t = &acts_t[..acts_t.len() - 1];
            self.trunk.backward_rows(&wt[0], rows, hidden_t, Some(tm), x, x, dtm, dp.add(self.at[0].0), db(0), first, (g, below), None, None);
        }
    }
}

impl AdditiveShared {
    /// The three networks on `p`.
    fn nets<'a>(&'a self, p: &'a [f32], n_p: usize, n_a: usize, op: &str) -> Result<Three<'a>> {
        Three::new([&self.trunk, &self.d, &self.s], p, n_p, n_a, op)
    }
}

impl CustomOp3 for AdditiveShared {
    fn name(&self) -> &'static str {
        "additive-shared"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (x, a, p) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let ((n, n_p), (n_a_rows, n_a)) = (dims2(l1, op)?, dims2(l2, op)?);
        if n_a_rows != n {
            candle_core::bail!("{op}: {n} position rows, {n_a_rows} angle rows")
        }
        let three = self.nets(p, n_p, n_a, op)?;
        let k = three.widths().1;
        let widths = [self.trunk.widths(), self.d.inner_widths(), self.s.inner_widths()];
        let (mut kt, dt) = buffers(&widths[0], n);
        let (mut kd, dd) = buffers(&widths[1], n);
        let (mut ks, ds) = buffers(&widths[2], n);
        let mut out: Vec<f32> = Vec::with_capacity(n * k);
        let o = Shared(out.as_mut_ptr());
        (0..n.div_ceil(FORWARD_ROWS)).into_par_iter().for_each(|blk| {
            let (r0, rows) = (blk * FORWARD_ROWS, FORWARD_ROWS.min(n - blk * FORWARD_ROWS));
            // SAFETY: x and a hold n rows (checked), read from row r0; every buffer has room for n rows
            // of its width, of which this task alone writes rows r0..r0 + rows.
            unsafe {
                let (xm, am) = (Mat::new(x, n_p).at(r0, 0), Mat::new(a, n_a).at(r0, 0));
                let out = Dst { at: Shared(o.add(r0 * k)), ld: k };
                three.forward_rows(rows, xm, am, (&from_row(&dt, r0), &from_row(&dd, r0), &from_row(&ds, r0)), out);
            }
        });
        for (v, &m) in kt.iter_mut().chain(&mut kd).chain(&mut ks).zip(widths.iter().flatten()) {
            // SAFETY: the tasks above wrote all n rows of every buffer.
            unsafe { v.set_len(n * m) };
        }
        // SAFETY: the heads' output layers wrote all n rows of their m_d and k - m_d columns.
        unsafe { out.set_len(n * k) };
        *self.kept.lock().map_err(|_| poisoned(op))? = Kept { trunk: kt, d: kd, s: ks };
        Ok((CpuStorage::F32(out), Shape::from((n, k))))
    }

    fn bwd(&self, x: &Tensor, a: &Tensor, p: &Tensor, _out: &Tensor, dout: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let op = self.name();
        if x.track_op() || a.track_op() {
            candle_core::bail!("{op}: the position and angle encodings are inputs of the batch; no gradient flows into them")
        }
        let ((n, n_p), n_a) = (x.dims2()?, a.dims2()?.1);
        let (x, a, p, dout) = (x.contiguous()?, a.contiguous()?, p.contiguous()?, dout.contiguous()?);
        let (xs, xl) = x.storage_and_layout();
        let (as_, al) = a.storage_and_layout();
        let (ps, pl) = p.storage_and_layout();
        let (gs, gl) = dout.storage_and_layout();
        let (x, a, p, dout) = (storage_data(&xs, xl, op)?, storage_data(&as_, al, op)?, storage_data(&ps, pl, op)?, storage_data(&gs, gl, op)?);
        let three = self.nets(p, n_p, n_a, op)?;
        let (n_t, k) = (three.trunk.m(), three.widths().1);
        let kept = self.kept.lock().map_err(|_| poisoned(op))?;
        let fits = |v: &[Vec<f32>], shape: &NetShape, all: bool| {
            v.len() + usize::from(!all) == shape.layers.len() && v.iter().zip(&shape.layers).all(|(b, &(_, m))| b.len() == n * m)
        };
        if !(fits(&kept.trunk, &self.trunk, true) && fits(&kept.d, &self.d, false) && fits(&kept.s, &self.s, false)) || dout.len() != n * k || x.len() != n * n_p || a.len() != n * n_a {
            candle_core::bail!("{op}: backward without its forward pass")
        }
        let wt = three.transposed();
        let width = three.width();
        let partial: Vec<Vec<f32>> = (0..n.div_ceil(BACKWARD_ROWS))
            .into_par_iter()
            .map(|task| {
                // The matrices' blocks are written by the first sweep's products, the biases' blocks
                // are added to from zero: no zero fill of a copy of every weight.
                let mut part: Vec<f32> = Vec::with_capacity(p.len());
                let base = part.as_mut_ptr();
                let mut g = vec![0.0f32; SWEEP_ROWS * width];
                let mut below = vec![0.0f32; SWEEP_ROWS * width];
                let mut dt = vec![0.0f32; SWEEP_ROWS * n_t];
                let (start, end) = (task * BACKWARD_ROWS, ((task + 1) * BACKWARD_ROWS).min(n));
                // SAFETY: every kept buffer, x, a and dout hold n rows of their widths (checked), read
                // from row s0 for `rows` rows; `part` has room for p.len() values, its bias blocks
                // zeroed here and its matrix blocks written by the first sweep; dt holds SWEEP_ROWS
                // rows of n_t values.
                unsafe {
                    three.zero_biases(base);
                    for s0 in (start..end).step_by(SWEEP_ROWS) {
                        let acts = (mats_from(&kept.trunk, &self.trunk.layers, s0), mats_from(&kept.d, &self.d.layers, s0), mats_from(&kept.s, &self.s.layers, s0));
                        let (xm, am, gm) = (Mat::new(x, n_p).at(s0, 0), Mat::new(a, n_a).at(s0, 0), Mat::new(dout, k).at(s0, 0));
                        let rows = SWEEP_ROWS.min(end - s0);
                        three.backward_rows(&wt, rows, (&acts.0, &acts.1, &acts.2), xm, am, gm, base, s0 == start, (&mut g, &mut below), dt.as_mut_ptr());
                    }
                    part.set_len(p.len());
                }
                part
            })
            .collect();
        let mut dp = vec![0.0f32; p.len()];
        add_in_order(&mut dp, &partial);
        Ok((None, None, Some(Tensor::from_vec(dp, p.len(), &candle_core::Device::Cpu)?)))
    }
}

/// `[d, s]` (`[N, m_d + m_s]`): the trunk on the position encoding `x`, the diffuse head on its
/// features `t` and the specular head on `[t, a]`, as one op.
pub fn additive_shared(x: &Tensor, a: &Tensor, trunk: &Mlp, diffuse: &Mlp, specular: &Mlp) -> Result<Tensor> {
    let mut parts = Vec::with_capacity(6);
    for net in [trunk, diffuse, specular] {
        let (w, b) = net.flat()?;
        parts.extend([w, b]);
    }
    let p = Tensor::cat(&parts, 0)?;
    let op = AdditiveShared { trunk: trunk.net_shape(), d: diffuse.net_shape(), s: specular.net_shape(), kept: Arc::default() };
    x.contiguous()?.apply_op3(&a.contiguous()?, &p, op)
}
