//! The `.nbrdf` loader on arbitrary bytes and on structured mutations of valid files.
//!
//! First byte even: the rest is the file, as it is. First byte odd: it picks one of the small valid
//! files of `common::small_file` (every kind, both precisions, every position encoding), and the rest is
//! a list of 5-byte edits `(offset u32 LE, xor u8)` applied to it; bit 1 says whether the checksum is
//! recomputed afterwards, so that the edits reach the header and content validation behind it.
//!
//! Invariants: `ModelBuf::from_bytes` and the zero-copy `Model::from_bytes` never panic and agree; a
//! file they accept evaluates finite and non-negative, and bitwise reciprocal where it promises it.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use nbrdf::file::{ModelKind, Reciprocity};
use nbrdf::{Model, ModelBuf};
use nbrdf::Vec3;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    let bytes = if mode & 1 == 0 {
        rest.to_vec()
    } else {
        let mut b = common::small_file((mode >> 2) as usize, rest.first().copied().unwrap_or(0));
        for e in rest.get(1..).unwrap_or(&[]).chunks_exact(5) {
            let at = u32::from_le_bytes([e[0], e[1], e[2], e[3]]) as usize;
            if !b.is_empty() {
                let n = b.len();
                b[at % n] ^= e[4];
            }
        }
        if mode & 2 != 0 && b.len() >= 4 {
            let n = b.len() - 4;
            let crc = crc32(&b[..n]);
            b[n..].copy_from_slice(&crc.to_le_bytes());
        }
        b
    };

    let owned = ModelBuf::from_bytes(&bytes);
    // The zero-copy loader over 4-byte aligned storage must reach the same verdict.
    let mut words = vec![0u32; bytes.len().div_ceil(4)];
    // SAFETY: u8 has no alignment requirement; the u32 storage is initialised.
    let aligned = unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), words.len() * 4) };
    aligned[..bytes.len()].copy_from_slice(&bytes);
    let borrowed = Model::from_bytes(&aligned[..bytes.len()]);
    assert_eq!(owned.as_ref().err(), borrowed.as_ref().err(), "the two loaders disagree");

    let Ok(buf) = owned else { return };
    let model = buf.model();
    let point = [0.3f32, -0.2, 0.6];
    let Ok(prepared) = model.prepare(&point[..model.position_len().min(3)]) else {
        // Intrinsic k > 3: only the empty-point path is checked.
        let p = model.prepare(&[]).unwrap();
        assert_eq!(model.eval(&p, Vec3::Z, Vec3::Z), [0.0; 3]);
        return;
    };
    let exact = model.header().reciprocity == Reciprocity::Exact || matches!(model.header().kind, ModelKind::Parametric(_));
    for (wi, wo) in [
        (Vec3::new(0.3, 0.1, 0.9), Vec3::new(-0.5, 0.2, 0.7)),
        (Vec3::Z, Vec3::Z),
        (Vec3::new(1.0, 0.0, 1e-7), Vec3::new(-1.0, 0.0, 1e-7)),
    ] {
        let f = model.eval(&prepared, wi, wo);
        common::assert_valid_brdf(f, "accepted model");
        if exact {
            assert!(common::same_bits(f, model.eval(&prepared, wo, wi)), "not reciprocal");
        }
    }
});

/// CRC-32 (IEEE), bitwise: the fuzz crate has no dependency for it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}
