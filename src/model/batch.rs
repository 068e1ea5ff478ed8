//! Many direction pairs at one point: [`Model::eval_many`] and [`Model::eval_many_soa`] gather the
//! valid pairs into packets of [`PACKET`] that run through each layer together, with the AVX-512 path
//! that maps and encodes 16 pairs at once.

use super::{Model, Prepared, Weights, MAX_ANGLE_INPUT};
#[cfg(target_arch = "x86_64")]
use crate::file::Reciprocity;
use crate::file::{ModelKind, MAX_NETS};
use crate::math::sanitize;
use crate::mlp::{Net, Weight, PACKET};
use crate::neural::{additive_separate, additive_shared, single_mlp};
use crate::{Rgb, Vec3, BLACK};

impl<'a> Model<'a> {
    /// Evaluates many direction pairs at one prepared point: `out[i] = eval(prepared, wi[i], wo[i])`
    /// for the common length of the three slices, bit for bit.
    ///
    /// The valid pairs are gathered into packets of [`crate::mlp::PACKET`] that run through each layer
    /// together (every weight row read once per packet): for the paper-size Single MLP 1.2-1.3x
    /// (Zen 4) to 1.5x (Intel Xeon) faster per pair than [`Model::eval`], where single queries are
    /// bound by streaming the weights from L2 and packets by the FMA rate (see `docs/speed.md`).
    ///
    /// f16 weights cost no more than f32 ones where a [`ModelBuf`](super::ModelBuf) holds them (widened
    /// at load); a [`Model`] over borrowed f16 bytes widens the rows each packet uses, allocating
    /// nothing. Both give the same bits.
    pub fn eval_many(&self, prepared: &Prepared, wi: &[Vec3], wo: &[Vec3], out: &mut [Rgb]) {
        let n = out.len().min(wi.len()).min(wo.len());
        self.eval_many_by(prepared, n, |i| (wi[i], wo[i]), |i, f| out[i] = f);
    }

    /// [`Model::eval_many`] over directions as structure of arrays: pair `i` is
    /// `wi = (wi[0][i], wi[1][i], wi[2][i])`, `wo` likewise, and its RGB goes to
    /// `(out[0][i], out[1][i], out[2][i])`, for the common length of all nine slices.
    pub fn eval_many_soa(&self, prepared: &Prepared, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let n = wi.iter().chain(&wo).map(|s| s.len()).chain(out.iter().map(|s| s.len())).min().unwrap_or(0);
        let [r, g, b] = out;
        self.eval_many_by(
            prepared,
            n,
            |i| (Vec3::new(wi[0][i], wi[1][i], wi[2][i]), Vec3::new(wo[0][i], wo[1][i], wo[2][i])),
            |i, f| {
                r[i] = f[0];
                g[i] = f[1];
                b[i] = f[2];
            },
        );
    }

    /// The batched evaluation behind [`Model::eval_many`]: `pair(i)` gives the directions of query `i`,
    /// `put(i, f)` takes its value; every query `i < n` is put exactly once.
    #[inline]
    fn eval_many_by(
        &self,
        prepared: &Prepared,
        n: usize,
        pair: impl Fn(usize) -> (Vec3, Vec3),
        mut put: impl FnMut(usize, Rgb),
    ) {
        if !prepared.valid || prepared.params.is_some() {
            for i in 0..n {
                let (a, b) = pair(i);
                put(i, self.eval(prepared, a, b));
            }
            return;
        }
        if self.header.albedo_bound.is_some() {
            return self.eval_many_packets(prepared, n, &pair, |i, f| {
                let (a, b) = pair(i);
                put(i, self.bounded(f, a, b))
            });
        }
        self.eval_many_packets(prepared, n, pair, put)
    }

    /// [`Model::eval_many_by`] of a valid neural point, before the albedo bound.
    #[inline]
    fn eval_many_packets(
        &self,
        prepared: &Prepared,
        n: usize,
        pair: impl Fn(usize) -> (Vec3, Vec3),
        mut put: impl FnMut(usize, Rgb),
    ) {
        #[cfg(target_arch = "x86_64")]
        if crate::kernels::level() == crate::kernels::Level::Avx512 {
            return self.eval_many_theta16(prepared, n, pair, put);
        }
        let mut enc = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut index = [0usize; PACKET];
        let mut filled = 0;
        let mut len = 0;
        for i in 0..n {
            let (a, b) = pair(i);
            let slot = &mut enc[filled * MAX_ANGLE_INPUT..(filled + 1) * MAX_ANGLE_INPUT];
            match self.encode_pair(a, b, slot) {
                Some(l) => {
                    len = l;
                    index[filled] = i;
                    filled += 1;
                }
                None => put(i, BLACK),
            }
            if filled == PACKET || (i + 1 == n && filled > 0) {
                for (&i, f) in index[..filled].iter().zip(self.run_packet(prepared, &enc, len)) {
                    put(i, sanitize(f));
                }
                filled = 0;
            }
        }
    }

    /// The [`PACKET`] pairs encoded in `enc` (`MAX_ANGLE_INPUT` apart, `len` values each) through the
    /// model's networks ([`Model::eval_packet_with`] over its weights).
    #[inline]
    fn run_packet(&self, prepared: &Prepared, enc: &[f32], len: usize) -> [Rgb; PACKET] {
        match self.weights {
            Weights::F32(w) => self.eval_packet_with(&self.nets(w), prepared, enc, len),
            Weights::F16(w) => self.eval_packet_with(&self.nets(w), prepared, enc, len),
        }
    }

    /// [`Model::eval_many_by`] on AVX-512: the pairs mapped (Θ, or the Rusinkiewicz angles) and
    /// encoded 16 at a time (`angles::theta16`, the bits of [`Model::encode_pair`] in every lane; the
    /// pairs it leaves to the scalar code encoded by that), the valid ones gathered into packets as there.
    #[cfg(target_arch = "x86_64")]
    fn eval_many_theta16(
        &self,
        prepared: &Prepared,
        n: usize,
        pair: impl Fn(usize) -> (Vec3, Vec3),
        mut put: impl FnMut(usize, Rgb),
    ) {
        let frequencies = self.header.angle_frequencies as usize;
        let exact = self.header.reciprocity == Reciprocity::Exact;
        let len = self.header.angle_input_len();
        let run = |enc: &[f32]| self.run_packet(prepared, enc, len);
        // 16 encoded rows, and the packet the valid ones are gathered into where some are not.
        let mut stage = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut enc = [0.0f32; PACKET * MAX_ANGLE_INPUT];
        let mut index = [0usize; PACKET];
        let mut filled = 0;
        let mut i = 0;
        while i < n {
            let m = (n - i).min(16);
            let (mut wi, mut wo) = ([Vec3::Z; 16], [Vec3::Z; 16]);
            for q in 0..m {
                (wi[q], wo[q]) = pair(i + q);
            }
            // SAFETY: the level is AVX-512 (checked by the caller); `m ≤ 16`; at most `MAX_FREQUENCIES`
            // octaves, so a row's `len` values fit the `MAX_ANGLE_INPUT` between rows.
            let (valid, scalar) = unsafe { crate::angles::theta16::encode16(&wi, &wo, m, exact, frequencies, &mut stage, MAX_ANGLE_INPUT) };
            if filled == 0 && valid == 0xffff {
                // A whole packet of valid pairs: straight from the rows.
                for (q, f) in run(&stage).into_iter().enumerate() {
                    put(i + q, sanitize(f));
                }
                i += m;
                continue;
            }
            for q in 0..m {
                let slot = &mut enc[filled * MAX_ANGLE_INPUT..(filled + 1) * MAX_ANGLE_INPUT];
                let ok = if valid & (1 << q) != 0 {
                    slot[..len].copy_from_slice(&stage[q * MAX_ANGLE_INPUT..q * MAX_ANGLE_INPUT + len]);
                    true
                } else {
                    scalar & (1 << q) != 0 && self.encode_pair(wi[q], wo[q], slot).is_some()
                };
                if !ok {
                    put(i + q, BLACK);
                    continue;
                }
                index[filled] = i + q;
                filled += 1;
                if filled == PACKET {
                    for (&k, f) in index.iter().zip(run(&enc)) {
                        put(k, sanitize(f));
                    }
                    filled = 0;
                }
            }
            i += m;
        }
        if filled > 0 {
            for (&k, f) in index[..filled].iter().zip(run(&enc)) {
                put(k, sanitize(f));
            }
        }
    }

    /// [`Model::eval_with`] for the [`PACKET`] queries encoded in `enc` (`MAX_ANGLE_INPUT` apart,
    /// `n` values each); lanes past the filled ones hold stale inputs whose results are discarded.
    #[inline]
    fn eval_packet_with<W: Weight>(&self, nets: &[Net<'a, W>; MAX_NETS], p: &Prepared, enc: &[f32], n: usize) -> [Rgb; PACKET] {
        let enhanced = self.header.enhanced;
        let s = MAX_ANGLE_INPUT;
        match self.header.kind {
            ModelKind::Parametric(_) => [BLACK; PACKET],
            ModelKind::SingleMlp => single_mlp::eval_packet(&nets[self.header.n_nets as usize - 1], &p.partial, enc, s, n),
            ModelKind::AdditiveSeparate => {
                additive_separate::eval_packet(&nets[1], p.diffuse, &p.partial, enc, s, n, enhanced)
            }
            ModelKind::AdditiveShared => additive_shared::eval_packet(&nets[2], p.diffuse, &p.partial, enc, s, n, enhanced),
        }
    }
}
