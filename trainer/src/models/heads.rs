//! The two heads of the Additive Shared model (docs/models.md) on one trunk, as one candle op: the
//! diffuse head reads the trunk's features `t`, the specular head `[t, PE(a)]`, and the output is both
//! side by side, `[d, s]`, which is what the fused objective reads (issue 8).
//!
//! Why one op: as two network ops the trunk's output has two consumers, so candle's backward gives it a
//! zeroed gradient buffer and adds each head's gradient into it, after copying the specular head's
//! gradient out of its `[t, PE(a)]` input, and the forward pass concatenates `[t, PE(a)]` as a graph
//! node; about 3% of a step. Here the two heads' input gradients are added by their GEMMs into one
//! buffer, and the angle columns get none (they are an input).

use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use super::fused::{data, dims2, ROW_BLOCK};
use super::mlp::Mlp;
use super::network::{backward_pass, forward_pass, join, NetShape};

/// What a forward pass keeps: each head's hidden activations and output, and the joined input `[t, a]`.
#[derive(Default)]
struct Kept {
    d: (Vec<Vec<f32>>, Vec<f32>),
    s: (Vec<Vec<f32>>, Vec<f32>),
    joined: Vec<f32>,
}

type Shared = std::sync::Arc<std::sync::Mutex<Kept>>;

/// The two heads over `(t [N, n_t], a [N, n_a], p)`, `p` the diffuse head's weights and biases then the
/// specular head's, each as [`super::network::network`] takes them.
struct Heads {
    d: NetShape,
    s: NetShape,
    kept: Shared,
}

/// Weights and biases of a network in `p`: `(w, b)` lengths.
fn sizes(shape: &NetShape) -> (usize, usize) {
    (shape.layers.iter().map(|&(i, o)| i * o).sum(), shape.layers.iter().map(|&(_, o)| o).sum())
}

/// The contiguous f32 data of a CPU tensor.
fn cpu<'a>(s: &'a candle_core::Storage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let candle_core::Storage::Cpu(c) = s else { candle_core::bail!("{op}: CPU tensors only") };
    data(c, l, op)
}

fn poisoned(op: &str) -> candle_core::Error {
    candle_core::Error::Msg(format!("{op}: poisoned activations"))
}

impl Heads {
    /// Output widths `(m_d, m_s)`.
    fn widths(&self) -> (usize, usize) {
        let m = |s: &NetShape| s.layers.last().map_or(0, |&(_, o)| o);
        (m(&self.d), m(&self.s))
    }
}

impl CustomOp3 for Heads {
    fn name(&self) -> &'static str {
        "additive-shared-heads"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout, s3: &CpuStorage, l3: &Layout) -> Result<(CpuStorage, Shape)> {
        let op = self.name();
        let (t, a, p) = (data(s1, l1, op)?, data(s2, l2, op)?, data(s3, l3, op)?);
        let ((n, n_t), (n_a_rows, n_a)) = (dims2(l1, op)?, dims2(l2, op)?);
        let ((wd, bd), (ws, bs)) = (sizes(&self.d), sizes(&self.s));
        if n_a_rows != n || p.len() != wd + bd + ws + bs {
            candle_core::bail!("{op}: {n} trunk rows, {n_a_rows} angle rows, {} parameters for {:?} and {:?}", p.len(), self.d.layers, self.s.layers)
        }
        let (pd, ps) = p.split_at(wd + bd);
        let (y_d, saved_d) = forward_pass(&self.d, t, n, n_t, &pd[..wd], &pd[wd..], op)?;
        let joined = join(t, n_t, a, n_a, n);
        let (y_s, saved_s) = forward_pass(&self.s, &joined, n, n_t + n_a, &ps[..ws], &ps[ws..], op)?;
        let (m_d, m_s) = self.widths();
        let k = m_d + m_s;
        let mut out = vec![0.0f32; n * k];
        out.par_chunks_mut(ROW_BLOCK * k).zip(y_d.par_chunks(ROW_BLOCK * m_d).zip(y_s.par_chunks(ROW_BLOCK * m_s))).for_each(|(o, (d, s))| {
            for (row, (d, s)) in o.chunks_exact_mut(k).zip(d.chunks_exact(m_d).zip(s.chunks_exact(m_s))) {
                row[..m_d].copy_from_slice(d);
                row[m_d..].copy_from_slice(s);
            }
        });
        *self.kept.lock().map_err(|_| poisoned(op))? = Kept { d: (saved_d, y_d), s: (saved_s, y_s), joined };
        Ok((CpuStorage::F32(out), Shape::from((n, k))))
    }

    fn bwd(&self, t: &Tensor, a: &Tensor, p: &Tensor, _out: &Tensor, dout: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let op = self.name();
        let ((n, n_t), n_a) = (t.dims2()?, a.dims2()?.1);
        let (m_d, m_s) = self.widths();
        let kept = self.kept.lock().map_err(|_| poisoned(op))?;
        if kept.d.1.len() != n * m_d || kept.s.1.len() != n * m_s {
            candle_core::bail!("{op}: backward without its forward pass")
        }
        let dout = dout.contiguous()?.flatten_all()?.to_vec1::<f32>()?;
        let (dy_d, dy_s): (Vec<f32>, Vec<f32>) = {
            let k = m_d + m_s;
            let mut dd = Vec::with_capacity(n * m_d);
            let mut ds = Vec::with_capacity(n * m_s);
            for row in dout.chunks_exact(k) {
                dd.extend_from_slice(&row[..m_d]);
                ds.extend_from_slice(&row[m_d..]);
            }
            (dd, ds)
        };
        let ((wd, bd), (ws, _)) = (sizes(&self.d), sizes(&self.s));
        let (t, p) = (t.contiguous()?, p.contiguous()?);
        let (ts, tl) = t.storage_and_layout();
        let (ps_, pl) = p.storage_and_layout();
        let (t_v, p) = (cpu(&ts, tl, op)?, cpu(&ps_, pl, op)?);
        let mut dp = vec![0.0f32; p.len()];
        let mut dt = vec![0.0f32; n * n_t];
        {
            let (dpd, dps) = dp.split_at_mut(wd + bd);
            let (dwd, dbd) = dpd.split_at_mut(wd);
            let (dws, dbs) = dps.split_at_mut(ws);
            backward_pass(&self.d, &kept.d.0, t_v, n, n_t, &p[..wd], &kept.d.1, &dy_d, dwd, dbd, Some((&mut dt, n_t)));
            let ps = &p[wd + bd..];
            backward_pass(&self.s, &kept.s.0, &kept.joined, n, n_t + n_a, &ps[..ws], &kept.s.1, &dy_s, dws, dbs, Some((&mut dt, n_t)));
        }
        let dev = t.device();
        let dt = t.track_op().then(|| Tensor::from_vec(dt, (n, n_t), dev)).transpose()?;
        Ok((dt, None, Some(Tensor::from_vec(dp, p.len(), dev)?)))
    }
}

/// `[d, s]` (`[N, m_d + m_s]`): the diffuse head on the trunk features `t` and the specular head on
/// `[t, a]`, as one op.
pub fn heads(t: &Tensor, a: &Tensor, diffuse: &Mlp, specular: &Mlp) -> Result<Tensor> {
    let (wd, bd) = diffuse.flat()?;
    let (ws, bs) = specular.flat()?;
    let p = Tensor::cat(&[&wd, &bd, &ws, &bs], 0)?;
    let op = Heads { d: diffuse.net_shape(), s: specular.net_shape(), kept: Shared::default() };
    t.contiguous()?.apply_op3(&a.contiguous()?, &p, op)
}
