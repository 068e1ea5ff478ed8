//! Networks on a shared trunk, on one block of rows: the trunk on the position encoding, an optional
//! diffuse head on the trunk's features `t`, and the specular (Single MLP: only) head on
//! `[t, PE(a)]`; the heads' outputs side by side, `[d, s]` (or `s`), which is what the objective
//! reads. The Additive Shared model and the Single MLP whose directions enter late (Tab. 2).
//!
//! A block of rows goes through the trunk and the heads while it is in L2, forward and backward: the
//! specular head reads `t` and the angles in place as its first layer's two inputs (a [`Net`] lead),
//! the heads write straight into `[d, s]`, and a sweep's trunk gradient lives in a buffer of a few
//! hundred rows. `∂t` continues the specular head's sums from the diffuse head's instead of adding two
//! finished sums, so the trunk's gradient differs from the composed definition's by rounding.

use candle_core::Result;

use super::dense::{Mat, Shared};
use super::network::{Dst, Grad, Net, NetShape};

/// The trunk and its heads on their blocks of a parameter vector `p` (each network's matrices then
/// its biases, in the order trunk, diffuse head, specular head), checked against an input of `n_p`
/// position and `n_a` angle columns.
pub(crate) struct Trunked<'a> {
    pub trunk: Net<'a>,
    pub d: Option<Net<'a>>,
    pub s: Net<'a>,
    /// Where each network's matrices and biases start in `p`, and how many biases it has, in `p`'s
    /// order.
    at: Vec<(usize, usize, usize)>,
}

impl<'a> Trunked<'a> {
    /// `shapes`: the trunk, the heads (the diffuse one first where there is one).
    pub fn new(shapes: &[&'a NetShape], p: &'a [f32], n_p: usize, n_a: usize, op: &str) -> Result<Self> {
        if !(2..=3).contains(&shapes.len()) {
            candle_core::bail!("{op}: a trunk and one or two heads, not {} networks", shapes.len())
        }
        let total: usize = shapes.iter().map(|s| s.sizes().0 + s.sizes().1).sum();
        if p.len() != total {
            candle_core::bail!("{op}: {} parameters for networks of {total}", p.len())
        }
        let mut at = Vec::with_capacity(shapes.len());
        let mut o = 0;
        for s in shapes {
            let (w, b) = s.sizes();
            at.push((o, o + w, b));
            o += w + b;
        }
        let net = |i: usize, n_lead: usize, n_x: usize| {
            let (w, b) = shapes[i].sizes();
            Net::new(shapes[i], &p[at[i].0..at[i].0 + w], &p[at[i].1..at[i].1 + b], n_lead, n_x, op)
        };
        let trunk = net(0, 0, n_p)?;
        let n_t = trunk.m();
        let d = if shapes.len() == 3 { Some(net(1, 0, n_t)?) } else { None };
        let s = net(shapes.len() - 1, n_t, n_a)?;
        Ok(Trunked { trunk, d, s, at })
    }

    /// Columns of the diffuse head's output (0 without one): where the specular head's start.
    pub fn m_d(&self) -> usize {
        self.d.as_ref().map_or(0, Net::m)
    }

    /// Columns of the output `[d, s]`.
    pub fn m(&self) -> usize {
        self.m_d() + self.s.m()
    }

    /// Columns of the widest matrix side of the networks, the width of a sweep's gradient buffers.
    pub fn width(&self) -> usize {
        self.nets().map(Net::width).max().unwrap_or(0)
    }

    /// The networks in `p`'s order.
    fn nets(&self) -> impl Iterator<Item = &Net<'a>> {
        std::iter::once(&self.trunk).chain(self.d.as_ref()).chain(std::iter::once(&self.s))
    }

    /// `Wᵀ` of every layer of the networks, in `p`'s order.
    pub fn transposed(&self) -> Vec<Vec<Vec<f32>>> {
        self.nets().map(Net::transposed).collect()
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
    /// side by side to `out` (`[d, s]`, row stride ≥ [`Trunked::m`]); the specular head reads `t` and
    /// the angles in place.
    ///
    /// # Safety
    /// As [`Net::forward_rows`] for each network.
    pub unsafe fn forward_rows(&self, rows: usize, x: Mat, a: Mat, (dst_t, dst_d, dst_s): (&[Dst], &[Dst], &[Dst]), out: Dst) {
        let n_t = self.trunk.m();
        // SAFETY: the caller's contract.
        unsafe {
            self.trunk.forward_rows(rows, x, x, dst_t);
            let tm = Mat { ptr: dst_t[dst_t.len() - 1].at.0, ld: n_t };
            if let Some(d) = &self.d {
                let mut at_d = dst_d.to_vec();
                at_d.push(out);
                d.forward_rows(rows, tm, tm, &at_d);
            }
            let mut at_s = dst_s.to_vec();
            at_s.push(Dst { at: Shared(out.at.add(self.m_d())), ld: out.ld });
            self.s.forward_rows(rows, a, tm, &at_s);
        }
    }

    /// The backward pass on one sweep of `rows` rows from the gradient `dy` of `[d, s]`: each network's
    /// weight and bias gradients into its blocks of `dp` (laid out as `p`; `first`: the matrices are
    /// written, not added to), the heads' `∂t` through the buffer `dt` (`rows × n_t`) to the trunk.
    /// `acts_*` are the networks' layer outputs (the trunk's last is `t`, the heads' outputs are not
    /// read), `x` and `a` the inputs, all from the sweep's first row; `wt` is [`Trunked::transposed`].
    ///
    /// # Safety
    /// As [`Net::backward_rows`] for each network; `dp` must have room for `p.len()` values and its
    /// bias blocks be initialised ([`Trunked::zero_biases`]).
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn backward_rows(
        &self,
        wt: &[Vec<Vec<f32>>],
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
        let i_s = self.at.len() - 1;
        // SAFETY: the caller's contract; each network's blocks of dp are its own.
        unsafe {
            let db = |i: usize| std::slice::from_raw_parts_mut(dp.add(self.at[i].1), self.at[i].2);
            if let Some(d) = &self.d {
                d.backward_rows(&wt[1], rows, acts_d, None, tm, tm, dy, dp.add(self.at[1].0), db(1), first, (&mut *g, &mut *below), Some(Grad { to: dt_at, add: false }), None);
            }
            let to_dt = Some(Grad { to: dt_at, add: self.d.is_some() });
            self.s.backward_rows(&wt[i_s], rows, acts_s, None, a, tm, dy.at(0, self.m_d()), dp.add(self.at[i_s].0), db(i_s), first, (&mut *g, &mut *below), None, to_dt);
            let dtm = Mat { ptr: dt, ld: n_t };
            let hidden_t = &acts_t[..acts_t.len() - 1];
            self.trunk.backward_rows(&wt[0], rows, hidden_t, Some(tm), x, x, dtm, dp.add(self.at[0].0), db(0), first, (g, below), None, None);
        }
    }
}
