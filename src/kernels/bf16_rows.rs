//! One query through a network's hidden layers in the arithmetic [`crate::mlp::Arithmetic::Bf16`]
//! (each product of bf16 roundings, sums in f32), on f32 FMAs over rows of bf16 weights that skip
//! the inputs a ReLU zeroed.
//!
//! Why not `vdpbf16ps`, as the packets do ([`super::amx`]): one query reads every weight it uses
//! once, so it runs at the speed its weights stream from L2 (32 bytes a cycle on Zen 4, which the
//! f32 one-query kernel meets: `eval-floor` in `benches/eval.rs`). A `vdpbf16ps` vector holds two
//! input rows side by side, so an input that the ReLU zeroed (about half of them, in no pattern)
//! still costs its cache line unless its neighbour is zero too: that path streamed 180 KB a Single
//! MLP query, no fewer bytes than f32 with its zero rows skipped, and took 1.07× its time. Here each
//! weight row holds one input, so the kernel skips every zero input as the f32 kernel does
//! ([`super::x86`]'s `compress`), and a row is half the f32 row's bytes: on Zen 4 a query takes
//! 0.73–0.87× the f32 one (`docs/speed.md`).
//!
//! The bits are those of the packet path: a product of two bf16 values has at most 16 significant
//! bits, exact in f32, so `fma(x, w, acc)` adds it to the sum with one rounding, which is what
//! `vdpbf16ps` does per product, the odd input of each pair first (Intel SDM, `VDPBF16PS`; AMD Zen 4
//! gives the same bits); the inputs are visited in that order. (`vdpbf16ps` also flushes values below 2^-126 to zero, which the
//! FMAs do not: results differ only there.) Widening a bf16 to f32 is a shift or a mask: each row
//! stores outputs `o` and `o + 16` of every 32 in one 32-bit lane (low and high half), so that
//! `lane << 16` is the first 16 and `lane & 0xffff0000` the second, where `vcvtph2ps` (f16) costs
//! two cycles a vector on Zen 4.

use core::arch::x86_64::*;
use core::mem::MaybeUninit;

use crate::mlp::{Net, NetDesc, Partial, Weight, MAX_WIDTH};

use super::amx::{layer_init, layer_k, split, tail_pad, tiled_row, TAIL_MAX};
use super::x86::{append, mask16, row_offsets_of};

/// Number of bf16 values [`pack_rows`] writes for a network: one row of `width` per tiled input of
/// every hidden layer (the inputs of [`super::amx::pack`], tails padded with zero rows, which the
/// kernel never reads since their inputs are 0).
pub(crate) fn rows_len(d: &NetDesc, n_tail: usize) -> usize {
    (0..d.hidden as usize).map(|l| layer_k(d, n_tail, l) * d.width as usize).sum()
}

/// Writes the hidden layers of `net` (whose last `n_tail` inputs are the per-query tail) as bf16 rows
/// to `out` (length [`rows_len`]; the network [`super::amx::fits`]): per layer, per tiled input `i`
/// (the order of [`super::amx::pack`]), per 32 outputs `o0..`, lane `t` = output `o0 + t` (low half)
/// and `o0 + 16 + t` (high half), each the bf16 rounding (nearest, ties to even) of the weight, the
/// first part of [`super::amx::pack`]'s split.
pub(crate) fn pack_rows<W: Weight>(net: &Net<'_, W>, n_tail: usize, out: &mut [u16]) {
    let d = &net.desc;
    let width = d.width as usize;
    let mut o = 0;
    for l in 0..d.hidden as usize {
        let off = d.layer_offset(l);
        let k = layer_k(d, n_tail, l);
        for i in 0..k {
            let row = tiled_row(d, n_tail, l, i);
            for o0 in (0..width).step_by(32) {
                for t in 0..16 {
                    for half in 0..2 {
                        let w = row.map_or(0.0, |r| net.weights[off + r * width + o0 + 16 * half + t].to_f32());
                        out[o + o0 + 2 * t + half] = split(w)[0];
                    }
                }
            }
            o += width;
        }
    }
    debug_assert_eq!(o, out.len());
}

/// The byte offsets of the rows of 16 inputs from `i0` (each pair odd first: the order of
/// `vdpbf16ps`), and the step to the next 16.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
fn pair_offsets(row_bytes: u32) -> (__m512i, __m512i) {
    row_offsets_of(_mm512_setr_epi32(1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14), row_bytes)
}

/// Appends the nonzero values of 16 inputs `v` (NaN counts as nonzero), each pair odd first, with
/// their row offsets `off` (from [`pair_offsets`]) to the list at `len`; returns the new length.
///
/// # Safety
/// `xs` and `offs` have room for 16 entries from `len`.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn append_pairs(v: __m512, off: __m512i, xs: *mut f32, offs: *mut u32, len: usize) -> usize {
    // SAFETY: the room of the contract.
    unsafe { append(_mm512_permute_ps::<0b10_11_00_01>(v), 0xffff, off, xs, offs, len) }
}

/// `v` rounded to bf16 (nearest, ties to even) and back to f32.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512bf16")]
fn round_bf16(v: __m512) -> __m512 {
    // SAFETY: `__m256bh` and `__m256i` are both 256 bits of plain data.
    let b: __m256i = unsafe { core::mem::transmute(_mm512_cvtneps_pbh(v)) };
    _mm512_castsi512_ps(_mm512_slli_epi32::<16>(_mm512_cvtepu16_epi32(b)))
}

/// A list of nonzero inputs: values and the byte offsets of their rows from `base`.
struct List {
    x: *const f32,
    off: *const u32,
    len: usize,
}

/// `acc += Σ_j x_j · row_j` over the listed inputs, in order, for `32 * G` outputs (`acc[g]`: outputs
/// `32g..32g + 16` and `32g + 16..32g + 32`).
///
/// # Safety
/// Each listed offset from `base` starts a row of `32 * G` bf16 weights (see [`pack_rows`]).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c")]
unsafe fn accumulate<const G: usize>(acc: &mut [[__m512; 2]; G], base: *const u8, list: &List) {
    let high = _mm512_set1_epi32(0xffff_0000u32 as i32);
    // SAFETY (whole body): every access within the extents of the contract.
    unsafe {
        for j in 0..list.len {
            let xb = _mm512_set1_ps(*list.x.add(j));
            let r = base.add(*list.off.add(j) as usize);
            for (g, a) in acc.iter_mut().enumerate() {
                let v = _mm512_loadu_si512(r.add(64 * g).cast());
                a[0] = _mm512_fmadd_ps(xb, _mm512_castsi512_ps(_mm512_slli_epi32::<16>(v)), a[0]);
                a[1] = _mm512_fmadd_ps(xb, _mm512_castsi512_ps(_mm512_and_si512(v, high)), a[1]);
            }
        }
    }
}

/// The hidden layers of `net` for one query in bf16 products: the tail `tail[..n_tail]`, the last
/// hidden activation (after ReLU, in f32) to `h[..width]`; the activations between layers ReLU'd
/// and rounded to bf16, as the packet path's.
///
/// # Safety
/// AVX512-BF16 and AVX-512 (`amx::vectors_available`); `net` `amx::fits` with `n_tail`, `rows`
/// [`pack_rows`]'s output for them, `partial.head_len + n_tail` the network's input count; `tail`
/// holds `n_tail` values; `h` writable for `width` floats.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,avx512bf16")]
pub(crate) unsafe fn hidden_one<W: Weight>(net: &Net<'_, W>, rows: &[u16], partial: &Partial, tail: &[f32], n_tail: usize, h: *mut f32) {
    // SAFETY: the contract, with `width / 32` groups of outputs (`fits`: 1 to 8).
    unsafe {
        match net.desc.width / 32 {
            1 => hidden_one_g::<W, 1>(net, rows, partial, tail, n_tail, h),
            2 => hidden_one_g::<W, 2>(net, rows, partial, tail, n_tail, h),
            3 => hidden_one_g::<W, 3>(net, rows, partial, tail, n_tail, h),
            4 => hidden_one_g::<W, 4>(net, rows, partial, tail, n_tail, h),
            5 => hidden_one_g::<W, 5>(net, rows, partial, tail, n_tail, h),
            6 => hidden_one_g::<W, 6>(net, rows, partial, tail, n_tail, h),
            7 => hidden_one_g::<W, 7>(net, rows, partial, tail, n_tail, h),
            _ => hidden_one_g::<W, 8>(net, rows, partial, tail, n_tail, h),
        }
    }
}

/// [`hidden_one`] for a width of `32 * G`: the activations stay in registers from one layer to the
/// next, and the list of the next layer's nonzero inputs is made from them (as the f32 chain kernel
/// does, [`super::x86`]); the tail's list is made once for layer 0 and the skip layer.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,fma,f16c,avx512bf16")]
unsafe fn hidden_one_g<W: Weight, const G: usize>(net: &Net<'_, W>, rows: &[u16], partial: &Partial, tail: &[f32], n_tail: usize, h: *mut f32) {
    let d = &net.desc;
    let width = 32 * G;
    let row_bytes = (width * 2) as u32;
    let tp = tail_pad(n_tail);
    let mut lists = MaybeUninit::<[[f32; TAIL_MAX]; 2]>::uninit();
    let mut offs = MaybeUninit::<[[u32; TAIL_MAX]; 2]>::uninit();
    let (tx, to) = (lists.as_mut_ptr().cast::<f32>(), offs.as_mut_ptr().cast::<u32>());
    let mut hidden_x = MaybeUninit::<[f32; MAX_WIDTH]>::uninit();
    let mut hidden_o = MaybeUninit::<[u32; MAX_WIDTH]>::uninit();
    let (hx, ho) = (hidden_x.as_mut_ptr().cast::<f32>(), hidden_o.as_mut_ptr().cast::<u32>());
    let mut bias = [0.0f32; MAX_WIDTH];
    let mut w = rows.as_ptr().cast::<u8>();
    let zero = _mm512_setzero_ps();
    // SAFETY: the tail list holds `tp ≤ TAIL_MAX` entries, the hidden one `width ≤ MAX_WIDTH`; the
    // masked loads read only the `n_tail` values of the tail; each layer's rows are the next
    // `k * width` values of `rows` (its length is `rows_len`), the skip layer's tail rows after its
    // `width` hidden ones; `h` is writable for `width` floats.
    unsafe {
        let (mut off, step) = pair_offsets(row_bytes);
        let mut tlen = 0;
        for i in (0..tp).step_by(16) {
            // `wrapping_add`: past the tail the pointer may leave the slice; the mask reads nothing there.
            let t = _mm512_maskz_loadu_ps(mask16(n_tail.saturating_sub(i)), tail.as_ptr().wrapping_add(i));
            tlen = append_pairs(round_bf16(t), off, tx, to, tlen);
            off = _mm512_add_epi32(off, step);
        }
        let tail_list = List { x: tx, off: to, len: tlen };
        let mut act = [[zero; 2]; G];
        for l in 0..d.hidden as usize {
            let init = layer_init(net, partial, l, &mut bias);
            let mut acc: [[__m512; 2]; G] = core::array::from_fn(|g| core::array::from_fn(|k| _mm512_loadu_ps(init.as_ptr().add(32 * g + 16 * k))));
            if l == 0 {
                accumulate(&mut acc, w, &tail_list);
            } else {
                let (mut off, step) = pair_offsets(row_bytes);
                let mut len = 0;
                for a in act.iter().flatten() {
                    len = append_pairs(*a, off, hx, ho, len);
                    off = _mm512_add_epi32(off, step);
                }
                accumulate(&mut acc, w, &List { x: hx, off: ho, len });
                if d.skip as usize == l {
                    accumulate(&mut acc, w.add(width * row_bytes as usize), &tail_list);
                }
            }
            w = w.add(layer_k(d, n_tail, l) * row_bytes as usize);
            let last = l + 1 == d.hidden as usize;
            for (g, a) in acc.iter().enumerate() {
                for (k, v) in a.iter().enumerate() {
                    let r = _mm512_max_ps(*v, zero);
                    if last {
                        _mm512_storeu_ps(h.add(32 * g + 16 * k), r);
                    } else {
                        act[g][k] = round_bf16(r);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::tests::random;
    use crate::mlp::{forward_with, partial, Arithmetic, Tiled};

    fn bf16(x: f32) -> f32 {
        half::bf16::from_f32(x).to_f32()
    }

    /// One query's hidden layers in bf16 against a scalar reference written from the definition of
    /// the arithmetic: inputs and weights rounded to bf16, each product added to its f32 sum with one
    /// rounding (`mul_add`: the product is exact), pairs of inputs in order and the odd one of each
    /// first (`vdpbf16ps`, Intel SDM), every input read, ReLU in f32 and the activations rounded again.
    /// The same bits (a zero's sign aside), for every width the kernel is built for (1, 3, 4 and 8
    /// groups of 32 outputs) and networks with and without a skip layer.
    #[test]
    fn one_query_has_the_bits_of_the_bf16_definition() {
        if !super::super::amx::vectors_available() {
            std::eprintln!("bf16_rows: this CPU has no AVX512-BF16; skipping");
            return;
        }
        let (head_len, n_tail) = (5usize, 27usize);
        for (width, hidden, skip) in [(32usize, 2u8, 1u8), (96, 3, 2), (128, 6, 2), (256, 2, 0)] {
            let d = NetDesc { n_in: (head_len + n_tail) as u16, width: width as u16, hidden, n_out: 0, skip };
            let w = random(d.n_weights(), width as u32 + hidden as u32, 2.0 / (width as f32).sqrt());
            let net = Net { desc: d, weights: &w[..] };
            let mut copy = alloc::vec![0u16; super::super::amx::copy_len(&d, n_tail)];
            super::super::amx::make_copy(&net, n_tail, &mut copy);
            let tiled = Tiled { values: &copy, n_tail };
            for q in 0..8u32 {
                let head = random(head_len, 100 + q, 1.0);
                let tail = random(n_tail, 200 + q, 1.0);
                let p = partial(&net, &head);
                let mut got = [f32::NAN; MAX_WIDTH];
                forward_with(Arithmetic::Bf16, Some(tiled), &net, &p, &tail, &mut got);

                let x_tail: alloc::vec::Vec<f32> = tail.iter().map(|&t| bf16(t)).collect();
                let mut h = alloc::vec::Vec::new();
                for l in 0..hidden as usize {
                    let off = d.layer_offset(l);
                    // (input value, weight row) in the order of the tiled inputs, one per input.
                    let inputs: alloc::vec::Vec<(f32, usize)> = if l == 0 {
                        x_tail.iter().enumerate().map(|(i, &x)| (x, head_len + i)).collect()
                    } else {
                        let hid = h.iter().enumerate().map(|(i, &x)| (x, i));
                        let tail_rows = x_tail.iter().enumerate().map(|(i, &x)| (x, width + head_len + i));
                        if skip as usize == l { hid.chain(tail_rows).collect() } else { hid.collect() }
                    };
                    let init: alloc::vec::Vec<f32> = if l == 0 {
                        p.layer0[..width].to_vec()
                    } else if skip as usize == l {
                        p.skip[..width].to_vec()
                    } else {
                        w[off + width * width..off + width * width + width].to_vec()
                    };
                    let mut next = init;
                    for pair in inputs.chunks(2) {
                        for &(x, row) in pair.iter().rev() {
                            for (o, acc) in next.iter_mut().enumerate() {
                                *acc = x.mul_add(bf16(w[off + row * width + o]), *acc);
                            }
                        }
                    }
                    let last = l + 1 == hidden as usize;
                    h = next.iter().map(|&v| if last { v.max(0.0) } else { bf16(v.max(0.0)) }).collect();
                }
                for o in 0..width {
                    // `+ 0.0` makes -0 (a skipped zero input leaves it) +0.
                    assert_eq!((got[o] + 0.0).to_bits(), (h[o] + 0.0).to_bits(), "width {width} skip {skip} query {q} output {o}: {} vs {}", got[o], h[o]);
                }
            }
        }
    }

    /// `pack_rows` against the weights: row `i` of each layer holds, per 32 outputs, output `o0 + t`
    /// in the low half of lane `t` and `o0 + 16 + t` in the high half, each the bf16 rounding of its
    /// weight; the padding rows after the tail are 0. Runs on any x86-64 CPU.
    #[test]
    fn pack_rows_lays_out_one_input_per_row() {
        let (head_len, n_tail, width) = (3usize, 11usize, 64usize);
        let d = NetDesc { n_in: (head_len + n_tail) as u16, width: width as u16, hidden: 3, n_out: 3, skip: 2 };
        let w = random(d.n_weights(), 9, 1.0);
        let mut rows = alloc::vec![0xffffu16; rows_len(&d, n_tail)];
        pack_rows(&Net { desc: d, weights: &w[..] }, n_tail, &mut rows);
        assert_eq!(rows.len(), (32 + 64 + 96) * width);
        let mut r = 0;
        for l in 0..3 {
            let off = d.layer_offset(l);
            for i in 0..layer_k(&d, n_tail, l) {
                let weight_row = match (l, i) {
                    (0, i) => (i < n_tail).then_some(head_len + i),
                    (_, i) if i < width => Some(i),
                    (_, i) => (i - width < n_tail).then_some(width + head_len + i - width),
                };
                for o in 0..width {
                    let at = r * width + (o / 32) * 32 + 2 * (o % 16) + (o % 32) / 16;
                    let want = weight_row.map_or(0.0, |k| bf16(w[off + k * width + o]));
                    assert_eq!(half::bf16::from_bits(rows[at]).to_f32(), want, "layer {l} input {i} output {o}");
                }
                r += 1;
            }
        }
    }
}
