//! Bad input: every input format the crate reads, its malformed variants and the specific
//! error each one gets, and every writer's behaviour when its output cannot be written. Meshes and
//! images are the `nbrdf-scene` crate's, checked in `scene/tests/bad_input.rs`.
//!
//! `docs/bad-input.md` is the table of these cases (with the rows that `tests/model_file.rs` and
//! `tests/measured.rs` already assert); keep the two in step. No case may panic: each is an `Error` value
//! that names what is wrong.

use std::io::Write;

use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf};
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::parametric::ParametricKind;
use nbrdf::Error;

#[path = "support/bad_input.rs"]
#[macro_use]
mod support;
use support::{failed_writes_keep_the_old_files, listing, Scratch, WriteCase};

fn crc_fix(bytes: &mut [u8]) {
    let n = bytes.len() - 4;
    let crc = crc32fast::hash(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}

fn small_weights(n: usize) -> Vec<f32> {
    (0..n).map(|i| ((i * 7919) % 200) as f32 * 1e-3 - 0.1).collect()
}

// -------------------------------------------------------------------------------------------------
// The `.nbrdf` model file: what tests/model_file.rs does not already assert.

/// A Single MLP on no position input with Θ angles: its postcard header starts with the fields in
/// declaration order, one byte each: kind 1 (SingleMlp), enhanced 0, reciprocity 2 (Exact), angle
/// frequencies, position 0 (Uniform), precision 0 (F32); it ends with n_nets 1, n_vertices 0 and no proxy (0).
fn single_mlp_file() -> (Vec<u8>, usize) {
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 3);
    let bytes = encode(&h, &small_weights(h.n_weights()), None).unwrap();
    let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..22], &[1, 0, 2, 3, 0, 0], "the header layout this test edits");
    assert_eq!(&bytes[16 + header_len - 3..16 + header_len], &[1, 0, 0], "n_nets, n_vertices, proxy None");
    (bytes, header_len)
}

#[test]
fn model_file_header_fields_out_of_their_domain() {
    let (good, hl) = single_mlp_file();
    let edit = |at: usize, v: u8| {
        let mut b = good.clone();
        b[16 + at] = v;
        b
    };
    // The header is validated before the sizes and the checksum, so the error names the field.
    assert_err!("angle frequencies 17", ModelBuf::from_bytes(&edit(3, 17)),
        Error::TooLarge { what: "angle encoding frequencies", found: 17, max: 16 });
    assert_err!("enhanced on a single MLP", ModelBuf::from_bytes(&edit(1, 1)),
        Error::InvalidValue { what: "enhanced flag", .. });
    assert_err!("bool byte 2", ModelBuf::from_bytes(&edit(1, 2)), Error::InvalidValue { what: "model header", .. });
    assert_err!("unknown model kind 9", ModelBuf::from_bytes(&edit(0, 9)), Error::InvalidValue { what: "model header", .. });
    assert_err!("unknown reciprocity 3", ModelBuf::from_bytes(&edit(2, 3)), Error::InvalidValue { what: "model header", .. });
    assert_err!("unknown precision 2", ModelBuf::from_bytes(&edit(5, 2)), Error::InvalidValue { what: "model header", .. });
    assert_err!("4 networks", ModelBuf::from_bytes(&edit(hl - 3, 4)), Error::InvalidValue { what: "network count", .. });
    assert_err!("0 networks", ModelBuf::from_bytes(&edit(hl - 3, 0)), Error::InvalidValue { what: "network count", .. });
    assert_err!("a position table without an intrinsic encoding", ModelBuf::from_bytes(&edit(hl - 2, 1)),
        Error::InvalidValue { what: "position table", .. });
    // Extrinsic position with 17 octaves: position variant 2, then the octave count.
    let mut b = good.clone();
    b.splice(20..21, [2u8, 17]);
    b[12..16].copy_from_slice(&(hl as u32 + 1).to_le_bytes());
    assert_err!("position frequencies 17", ModelBuf::from_bytes(&b),
        Error::TooLarge { what: "position encoding frequencies", found: 17, max: 16 });
    // Intrinsic k = 0 (variant 1, k as a varint).
    b[20..22].copy_from_slice(&[1, 0]);
    assert_err!("intrinsic k = 0", ModelBuf::from_bytes(&b), Error::InvalidValue { what: "intrinsic encoding size k", .. });
}

#[test]
fn model_file_non_finite_content_in_every_section() {
    // f16 weights: +inf (0x7c00) with a correct checksum.
    let h = ModelHeader { precision: Precision::F16, ..ModelHeader::paper(ModelKind::AdditiveShared, true, Reciprocity::Exact, PositionEncoding::Extrinsic { frequencies: 2 }, 2) };
    let mut b = encode(&h, &small_weights(h.n_weights()), None).unwrap();
    let hl = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    let w0 = (16 + hl).div_ceil(4) * 4;
    b[w0 + 2 * 5..w0 + 2 * 6].copy_from_slice(&0x7c00u16.to_le_bytes());
    crc_fix(&mut b);
    assert_err!("f16 inf weight", ModelBuf::from_bytes(&b), Error::NonFinite { what: "network weights", index: 5 });

    // FMBRDF's per-object NDF normalisation (the value just before the position table) as NaN.
    let h = ModelHeader::paper(ModelKind::Parametric(ParametricKind::FresnelMicrofacet), false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 2 }, 0);
    let w = small_weights(h.n_weights());
    let mut nan_object = w.clone();
    *nan_object.last_mut().unwrap() = f32::NAN;
    assert_err!("NaN object parameter at export", encode(&h, &nan_object, None), Error::NonFinite { what: "exported weights", .. });
    let table = [0.5f32, -0.5, 0.25, 0.75, 1.0, 0.0];
    let good = encode(&h, &w, Some(&table)).unwrap();
    let table_at = good.len() - 4 - 4 * table.len();
    let mut b = good.clone();
    b[table_at - 4..table_at].copy_from_slice(&f32::NAN.to_le_bytes());
    crc_fix(&mut b);
    assert_err!("NaN object parameter", ModelBuf::from_bytes(&b), Error::NonFinite { what: "object parameters", index: 0 });

    // The per-vertex position table: an infinity in row 1, column 1 (value index 3).
    let mut b = good.clone();
    b[table_at + 4 * 3..table_at + 4 * 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    crc_fix(&mut b);
    assert_err!("inf in the position table", ModelBuf::from_bytes(&b), Error::NonFinite { what: "position table", index: 3 });
    assert_err!("NaN table at export", encode(&h, &w, Some(&[0.0, f32::NAN])), Error::NonFinite { what: "position table", index: 1 });
    assert_err!("table not a multiple of k", encode(&h, &w, Some(&[0.0; 3])), Error::SizeMismatch { .. });
}

#[test]
fn inputs_larger_than_any_valid_one_are_refused_unread() {
    // An NBRDF-json text past the cap: refused before a byte of it is parsed.
    let big = vec![b' '; nbrdf::measured::nbrdf_json::MAX_JSON_BYTES + 1];
    let err = nbrdf::measured::NbrdfNetwork::from_json_bytes(&big).unwrap_err();
    assert!(matches!(err, Error::TooLarge { what: "NBRDF-json bytes", .. }), "{err}");
}

#[test]
fn model_file_every_prefix_is_truncated_and_every_bit_flip_is_caught() {
    let h = ModelHeader::paper(ModelKind::AdditiveSeparate, true, Reciprocity::Swap, PositionEncoding::Intrinsic { k: 3 }, 1);
    let good = encode(&h, &small_weights(h.n_weights()), None).unwrap();
    // u32 storage for the zero-copy loader, which needs 4-byte alignment.
    let mut words = vec![0u32; good.len().div_ceil(4)];
    // SAFETY: u8 has no alignment requirement and every byte of the u32 slice is initialised.
    let aligned = unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), words.len() * 4) };
    aligned[..good.len()].copy_from_slice(&good);
    for cut in 0..good.len() {
        assert_err!(format!("prefix of {cut} bytes"), ModelBuf::from_bytes(&good[..cut]), Error::Truncated { .. });
        assert_err!(format!("prefix of {cut} bytes, held as is"), ModelBuf::from_bytes_as_is(&good[..cut]), Error::Truncated { .. });
        assert_err!(format!("prefix of {cut} bytes, zero-copy"), Model::from_bytes(&aligned[..cut]), Error::Truncated { .. });
    }
    // A flipped bit anywhere is an error, never a silently different model: in the magic, the version,
    // the header (a field error or the checksum), the weights and the checksum itself (the checksum).
    let hl = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let mut positions: Vec<usize> = (0..16 + hl).collect();
    positions.extend((16 + hl..good.len()).step_by(97));
    positions.extend(good.len() - 4..good.len());
    for at in positions {
        for bit in 0..8 {
            let mut b = good.clone();
            b[at] ^= 1 << bit;
            let r = ModelBuf::from_bytes(&b);
            assert!(r.is_err(), "bit {bit} of byte {at} flipped: accepted");
            assert!(ModelBuf::from_bytes_as_is(&b).is_err(), "bit {bit} of byte {at} flipped: accepted as is");
            if at >= 16 + hl.div_ceil(4) * 4 {
                assert_err!(format!("bit {bit} of byte {at}"), r, Error::ChecksumMismatch { .. });
            }
        }
    }
}

// -------------------------------------------------------------------------------------------------
// Missing files for every reader

#[test]
fn every_reader_names_a_missing_file() {
    let dir = Scratch::new("missing");
    let p = dir.path("nothing-here");
    let check = |case: &str, r: Result<(), Error>| match r {
        Err(Error::Io { path, kind: std::io::ErrorKind::NotFound, .. }) => assert_eq!(path, p, "{case}"),
        other => panic!("{case}: expected Io NotFound naming the path, got {other:?}"),
    };
    check("model", ModelBuf::load(&p).map(|_| ()));
    check("MERL", MerlTable::read(&p).map(|_| ()));
    check("NBRDF-json", NbrdfNetwork::load(&p).map(|_| ()));
    check("io::read", nbrdf::io::read(&p).map(|_| ()));
    // A directory where a file is expected.
    assert_err!("model from a directory", ModelBuf::load(&dir.0), Error::Io { .. });
    assert_err!("NBRDF-json from a directory", NbrdfNetwork::load(&dir.0), Error::Io { .. });
}

// -------------------------------------------------------------------------------------------------
// Outputs: atomic, and an existing file survives a failed write

#[test]
fn a_failed_write_leaves_the_existing_file_intact_for_every_writer() {
    let scratch = Scratch::new("unwritable");
    let dir = scratch.path("out");
    std::fs::create_dir(&dir).unwrap();
    let old = b"the previous, complete contents";
    let names = ["m.nbrdf", "t.binary", "raw.bin", "fill.bin"];
    for n in names {
        std::fs::write(dir.join(n), old).unwrap();
    }
    let before = listing(&dir);

    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 1);
    let model = encode(&h, &small_weights(h.n_weights()), None).unwrap();
    let table = MerlTable::tabulate(|_, _| [0.1; 3]);
    let writes: Vec<(&str, WriteCase)> = vec![
        ("file::save", Box::new(|| nbrdf::file::save(dir.join("m.nbrdf"), &model))),
        ("MerlTable::write", Box::new(|| table.write(dir.join("t.binary")))),
        ("io::write_atomic", Box::new(|| nbrdf::io::write_atomic(&dir.join("raw.bin"), b"new"))),
        ("io::write_atomic_with", Box::new(|| nbrdf::io::write_atomic_with(&dir.join("fill.bin"), |w| w.write_all(b"new")))),
    ];

    failed_writes_keep_the_old_files(&dir, &names, old, &writes);

    // Interrupted while writing: the writer's output fails half way. The old file stays, and no
    // temporary file is left.
    let r = nbrdf::io::write_atomic_with(&dir.join("fill.bin"), |w| {
        w.write_all(&[7u8; 100_000])?;
        Err(std::io::Error::other("interrupted"))
    });
    assert_err!("interrupted fill", r, Error::Io { .. });
    assert_eq!(std::fs::read(dir.join("fill.bin")).unwrap(), old);
    assert_eq!(listing(&dir), before);

    // The destination is a directory: the final rename fails, and the temporary file goes with it.
    std::fs::create_dir(dir.join("taken")).unwrap();
    std::fs::write(dir.join("taken").join("x"), b"x").unwrap();
    for (case, r) in [
        ("save over a directory", nbrdf::file::save(dir.join("taken"), &model)),
        ("MERL over a directory", table.write(dir.join("taken"))),
    ] {
        assert_err!(case, r, Error::Io { .. });
    }
    let mut expected = before.clone();
    expected.push("taken".into());
    expected.sort();
    assert_eq!(listing(&dir), expected, "a failed rename left a temporary file");

    // Writing into a directory that does not exist.
    assert_err!("missing parent", nbrdf::file::save(scratch.path("no/such/dir/m.nbrdf"), &model), Error::Io { .. });
}
