//! Bad input: every input format the crate reads, its malformed variants and the specific
//! error each one gets, and every writer's behaviour when its output cannot be written.
//!
//! `docs/bad-input.md` is the table of these cases (with the rows that `tests/model_file.rs` and
//! `tests/measured.rs` already assert); keep the two in step. No case may panic: each is an `Error` value
//! that names what is wrong.

use std::io::Write;
use std::path::{Path, PathBuf};

use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
use nbrdf::{Model, ModelBuf};
use nbrdf::image::RgbImage;
use nbrdf::measured::{MerlTable, NbrdfNetwork};
use nbrdf::parametric::ParametricKind;
use nbrdf::scene::Mesh;
use nbrdf::Error;

/// Asserts that `$result` is an `Err` matching `$pat`, naming the case and what came instead.
macro_rules! assert_err {
    ($case:expr, $result:expr, $pat:pat $(if $guard:expr)?) => {
        match $result {
            Err($pat) $(if $guard)? => {}
            Err(other) => panic!("{}: expected {}, got the error {other:?}", $case, stringify!($pat)),
            Ok(_) => panic!("{}: expected {}, got Ok", $case, stringify!($pat)),
        }
    };
}

/// A scratch directory removed at the end of the test.
struct Scratch(PathBuf);

impl Scratch {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("nbrdf-bad-input-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

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
// Meshes: OBJ and PLY

fn obj(text: &str) -> Result<Mesh, Error> {
    Mesh::from_obj_reader(&mut text.as_bytes())
}

fn ply(bytes: &[u8]) -> Result<Mesh, Error> {
    Mesh::from_ply_reader(&mut &bytes[..])
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn obj_malformed_variants() {
    assert!(obj(&format!("{TRI}f 1 2 3\n")).is_ok());
    assert_err!("empty file", obj(""), Error::InvalidValue { what: "mesh", .. });
    assert_err!("vertices only", obj(TRI), Error::InvalidValue { what: "mesh", .. });
    // Polygons are triangulated as fans (the paper's suzanne.obj has quads).
    assert_eq!(obj(&format!("{TRI}v 1 1 0\nf 1 2 4 3\n")).unwrap().triangles.len(), 2);
    // tobj checks face indices itself ("face vertex index out of bounds").
    assert_err!("index past the vertices", obj(&format!("{TRI}f 1 2 4\n")), Error::Parse { what, .. } if what == "OBJ");
    assert_err!("index 0", obj(&format!("{TRI}f 0 1 2\n")), Error::Parse { what, .. } if what == "OBJ");
    // Regression (found by fuzz target mesh_parse): normal and texture indices whose bounds
    // arithmetic overflows inside tobj. 6148914691236517206 - 1 = 0x5555555555555555, times 3 wraps to
    // u64::MAX, plus 2 wraps to 1: past tobj's check and out of bounds, a panic even in release builds.
    assert_err!("wrapping normal index", obj(&format!("{TRI}vn 0 0 1\nf 1//6148914691236517206 2//1 3//1\n")),
        Error::Parse { what, .. } if what == "OBJ");
    assert_err!("overflowing normal index", obj(&format!("{TRI}vn 0 0 1\nf 1//1 2//-1537228672809129305 3//1\n")),
        Error::Parse { what, .. } if what == "OBJ");
    assert_err!("overflowing texture index", obj(&format!("{TRI}vt 0 0\nf 1/1 2/-4611686018427387904 3/1\n")),
        Error::Parse { what, .. } if what == "OBJ");
    assert_err!("relative index before the first normal", obj(&format!("{TRI}vn 0 0 1\nf 1//-2 2//1 3//1\n")),
        Error::Parse { what, .. } if what == "OBJ");
    // Relative indices that land on an element are fine.
    assert!(obj(&format!("{TRI}vn 0 0 1\nf -3//-1 -2//1 -1//1\n")).is_ok());
    assert_err!("not a number", obj("v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), Error::Parse { .. });
    assert_err!("NaN position", obj("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), Error::NonFinite { what: "mesh vertex positions", index: 0 });
    assert_err!("inf position", obj("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n"), Error::NonFinite { what: "mesh vertex positions", index: 1 });
    assert_err!("degenerate", obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), Error::InvalidValue { what: "mesh", .. });
    assert_err!("zero normal", obj(&format!("{TRI}vn 0 0 0\nf 1//1 2//1 3//1\n")), Error::NonFinite { .. });
    // tobj skips lines it does not know, so garbage is a file without triangles.
    assert_err!("binary garbage", obj("\u{0}\u{1}\u{2}\u{ff}\u{fe}"), Error::InvalidValue { what: "mesh", .. });
}

#[test]
fn ply_malformed_variants() {
    let header_n = |vertices: &str, faces: &str| {
        format!("ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n")
    };
    let header = |faces: &str| header_n("3", faces);
    let good = format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", header("1"));
    assert!(ply(good.as_bytes()).is_ok());
    assert_err!("empty file", ply(b""), Error::Parse { .. });
    assert_err!("not a ply", ply(b"solid stl\n"), Error::Parse { .. });
    assert_err!("truncated body", ply(&good.as_bytes()[..good.len() - 6]), Error::Parse { .. });
    assert_err!("no face element", ply(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"), Error::Parse { .. });
    assert_eq!(ply(format!("{}0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2\n", header_n("4", "1")).as_bytes()).unwrap().triangles.len(), 2);
    assert_err!("a two-corner face", ply(format!("{}0 0 0\n1 0 0\n0 1 0\n2 0 1\n", header("1")).as_bytes()), Error::Parse { .. });
    assert_err!("negative index", ply(format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 -2\n", header("1")).as_bytes()), Error::Parse { .. });
    assert_err!("index past the vertices", ply(format!("{}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", header("1")).as_bytes()),
        Error::SizeMismatch { found: 3, expected: 3, .. });
    // The ASCII PLY grammar has no NaN literal: a parse error, not a NaN position.
    assert_err!("NaN position", ply(format!("{}0 0 nan\n1 0 0\n0 1 0\n3 0 1 2\n", header("1")).as_bytes()),
        Error::Parse { what, .. } if what == "PLY");
    // A binary PLY can carry NaN bits: caught by the mesh validation.
    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [0.0f32, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    bin.push(3);
    for i in [0i32, 1, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    assert_err!("binary NaN position", ply(&bin), Error::NonFinite { what: "mesh vertex positions", index: 1 });
    assert_err!("no faces", ply(format!("{}0 0 0\n1 0 0\n0 1 0\n", header("0")).as_bytes()), Error::InvalidValue { what: "mesh", .. });
    // Binary, little endian, cut inside the vertex data.
    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    assert_err!("binary truncated", ply(&bin), Error::Parse { .. });
}

#[test]
fn mesh_files_missing_or_of_unknown_type() {
    let dir = Scratch::new("mesh");
    assert_err!("missing OBJ", Mesh::load(dir.path("missing.obj")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    assert_err!("missing PLY", Mesh::load(dir.path("missing.ply")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    let stl = dir.write("m.stl", b"solid x\n");
    assert_err!("unknown extension", Mesh::load(&stl), Error::Parse { .. });
    // A parse error names the file it came from.
    let bad = dir.write("bad.obj", format!("{TRI}f 1 2 4\n").as_bytes());
    assert_err!("bad index in a file", Mesh::load(&bad), Error::Parse { what, .. } if what.contains("bad.obj"));
}

// -------------------------------------------------------------------------------------------------
// Images: EXR and PNG

fn gradient(w: u32, h: u32) -> RgbImage {
    let data = (0..w * h).map(|i| [i as f32 * 0.01, 0.5, 2.0]).collect();
    RgbImage::from_data(w, h, data).unwrap()
}

#[test]
fn exr_and_png_malformed_variants() {
    let dir = Scratch::new("images");
    let img = gradient(5, 3);
    assert_err!("wrong pixel count", RgbImage::from_data(5, 3, vec![[0.0; 3]; 14]),
        Error::SizeMismatch { what: "image pixel count", expected: 15, found: 14 });

    let exr = dir.path("a.exr");
    nbrdf::image::write_exr(&exr, &img).unwrap();
    assert_eq!(nbrdf::image::read_exr(&exr).unwrap(), img);
    let bytes = std::fs::read(&exr).unwrap();
    assert_err!("missing EXR", nbrdf::image::read_exr(dir.path("missing.exr")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    for (case, content) in [
        ("empty EXR", &b""[..]),
        ("not an EXR", &b"P6\n1 1\n255\n\0\0\0"[..]),
        ("EXR magic only", &bytes[..4]),
        ("EXR header cut", &bytes[..bytes.len() / 4]),
        ("EXR pixels cut", &bytes[..bytes.len() - 8]),
    ] {
        let p = dir.write("bad.exr", content);
        assert_err!(case, nbrdf::image::read_exr(&p), Error::Parse { what, .. } if what.contains("bad.exr"));
    }

    let png = dir.path("a.png");
    nbrdf::image::write_png16(&png, 2, 1, &[[0, 1000, 65535], [7, 8, 9]]).unwrap();
    assert_eq!(nbrdf::image::read_png(&png).unwrap().data[0], [0.0, 1000.0 / 65535.0, 1.0]);
    let bytes = std::fs::read(&png).unwrap();
    assert_err!("missing PNG", nbrdf::image::read_png(dir.path("missing.png")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    assert_err!("missing mask", nbrdf::image::read_mask(dir.path("missing.png")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    for (case, content) in [
        ("empty PNG", &b""[..]),
        ("not a PNG", &b"GIF89a"[..]),
        ("PNG signature only", &bytes[..8]),
        ("PNG cut in the data", &bytes[..bytes.len() - 16]),
    ] {
        let p = dir.write("bad.png", content);
        assert_err!(case, nbrdf::image::read_png(&p), Error::Parse { what, .. } if what.contains("bad.png"));
    }
    // A PNG with a flipped byte in its image data fails its CRC.
    let mut b = bytes.clone();
    let n = b.len();
    b[n - 20] ^= 0xff;
    let p = dir.write("crc.png", &b);
    assert_err!("PNG bad chunk CRC", nbrdf::image::read_png(&p), Error::Parse { .. });

    // Writers check the pixel count against the size instead of panicking inside the encoder.
    assert_err!("mask size", nbrdf::image::write_png_mask(dir.path("m.png"), 2, 2, &[true; 3]),
        Error::SizeMismatch { what: "mask pixel count", expected: 4, found: 3 });
    assert_err!("png16 size", nbrdf::image::write_png16(dir.path("m.png"), 2, 2, &[[0; 3]; 5]),
        Error::SizeMismatch { what: "image pixel count", expected: 4, found: 5 });
    assert_err!("rgb8 size", nbrdf::image::write_png_rgb8(dir.path("m.png"), 2, 2, &[0; 11]),
        Error::SizeMismatch { what: "RGB8 byte count", expected: 12, found: 11 });
    // RgbImage's fields are public, so an inconsistent image can reach the writers.
    let broken = RgbImage { width: 4, height: 4, data: vec![[0.0; 3]; 3] };
    assert_err!("EXR of an inconsistent image", nbrdf::image::write_exr(dir.path("b.exr"), &broken),
        Error::SizeMismatch { what: "image pixel count", expected: 16, found: 3 });
    assert_err!("PNG of an inconsistent image", nbrdf::image::write_png_srgb(dir.path("b.png"), &broken, 1.0),
        Error::SizeMismatch { what: "image pixel count", expected: 16, found: 3 });
    assert!(!dir.path("b.exr").exists() && !dir.path("b.png").exists());
}

#[test]
fn hdr_content_survives_exr_unchanged() {
    // NaN, inf and huge pixels are data, not a format error: EXR stores them and reads them back as they
    // are. Whoever consumes the pixels (the trainer) decides to skip them.
    let dir = Scratch::new("hdr");
    let img = RgbImage::from_data(2, 2, vec![[f32::NAN, 0.0, 1.0], [f32::INFINITY, 1e30, -1.0], [f32::MAX, 0.5, 0.5], [1e-40, 0.0, 0.0]]).unwrap();
    let p = dir.path("hdr.exr");
    nbrdf::image::write_exr(&p, &img).unwrap();
    let back = nbrdf::image::read_exr(&p).unwrap();
    assert!(back.data[0][0].is_nan());
    assert_eq!(&back.data[1..], &img.data[1..]);
    // The 8-bit sRGB view clamps them instead.
    nbrdf::image::write_png_srgb(dir.path("hdr.png"), &img, 1.0).unwrap();
    let view = nbrdf::image::read_png(dir.path("hdr.png")).unwrap();
    assert!(view.data.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
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
    check("EXR", nbrdf::image::read_exr(&p).map(|_| ()));
    check("PNG", nbrdf::image::read_png(&p).map(|_| ()));
    check("io::read", nbrdf::io::read(&p).map(|_| ()));
    // A directory where a file is expected.
    assert_err!("model from a directory", ModelBuf::load(&dir.0), Error::Io { .. });
    assert_err!("NBRDF-json from a directory", NbrdfNetwork::load(&dir.0), Error::Io { .. });
}

// -------------------------------------------------------------------------------------------------
// Outputs: atomic, and an existing file survives a failed write

/// Makes `dir` unwritable for the duration of the guard: mode 0555, or for root (whom permissions do not
/// stop) the immutable attribute. `None` where neither works here.
struct ReadOnly {
    dir: PathBuf,
    immutable: bool,
}

impl ReadOnly {
    fn new(dir: &Path) -> Option<Self> {
        use std::os::unix::fs::PermissionsExt;
        let writable = || {
            let probe = dir.join(".probe");
            let ok = std::fs::File::create(&probe).is_ok();
            let _ = std::fs::remove_file(&probe);
            ok
        };
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o555)).unwrap();
        if !writable() {
            return Some(ReadOnly { dir: dir.to_path_buf(), immutable: false });
        }
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755)).unwrap();
        let chattr = std::process::Command::new("chattr").arg("+i").arg(dir).output();
        let guard = ReadOnly { dir: dir.to_path_buf(), immutable: true };
        if chattr.is_ok_and(|o| o.status.success()) && !writable() {
            Some(guard)
        } else {
            None
        }
    }
}

impl Drop for ReadOnly {
    fn drop(&mut self) {
        use std::os::unix::fs::PermissionsExt;
        if self.immutable {
            let _ = std::process::Command::new("chattr").arg("-i").arg(&self.dir).output();
        }
        let _ = std::fs::set_permissions(&self.dir, std::fs::Permissions::from_mode(0o755));
    }
}

/// The entries of `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn a_failed_write_leaves_the_existing_file_intact_for_every_writer() {
    let scratch = Scratch::new("unwritable");
    let dir = scratch.path("out");
    std::fs::create_dir(&dir).unwrap();
    let old = b"the previous, complete contents";
    let names = ["m.nbrdf", "t.binary", "i.exr", "i.png", "mask.png", "i16.png", "i8.png", "raw.bin", "fill.bin"];
    for n in names {
        std::fs::write(dir.join(n), old).unwrap();
    }
    let before = listing(&dir);

    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 1);
    let model = encode(&h, &small_weights(h.n_weights()), None).unwrap();
    let table = MerlTable::tabulate(|_, _| [0.1; 3]);
    let img = gradient(3, 2);
    type Write<'a> = Box<dyn Fn() -> Result<(), Error> + 'a>;
    let writes: Vec<(&str, Write)> = vec![
        ("file::save", Box::new(|| nbrdf::file::save(dir.join("m.nbrdf"), &model))),
        ("MerlTable::write", Box::new(|| table.write(dir.join("t.binary")))),
        ("write_exr", Box::new(|| nbrdf::image::write_exr(dir.join("i.exr"), &img))),
        ("write_png_srgb", Box::new(|| nbrdf::image::write_png_srgb(dir.join("i.png"), &img, 1.0))),
        ("write_png_mask", Box::new(|| nbrdf::image::write_png_mask(dir.join("mask.png"), 1, 1, &[true]))),
        ("write_png16", Box::new(|| nbrdf::image::write_png16(dir.join("i16.png"), 1, 1, &[[1, 2, 3]]))),
        ("write_png_rgb8", Box::new(|| nbrdf::image::write_png_rgb8(dir.join("i8.png"), 1, 1, &[1, 2, 3]))),
        ("io::write_atomic", Box::new(|| nbrdf::io::write_atomic(&dir.join("raw.bin"), b"new"))),
        ("io::write_atomic_with", Box::new(|| nbrdf::io::write_atomic_with(&dir.join("fill.bin"), |w| w.write_all(b"new")))),
    ];

    match ReadOnly::new(&dir) {
        Some(guard) => {
            for (case, write) in &writes {
                assert_err!(case, write(), Error::Io { .. });
            }
            drop(guard);
            for n in names {
                assert_eq!(std::fs::read(dir.join(n)).unwrap(), old, "{n} changed by a failed write");
            }
            assert_eq!(listing(&dir), before, "a failed write left a file behind");
        }
        None => eprintln!("skipping the read-only directory case: cannot make a directory unwritable here"),
    }

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
        ("EXR over a directory", nbrdf::image::write_exr(dir.join("taken"), &img)),
    ] {
        assert_err!(case, r, Error::Io { .. });
    }
    let mut expected = before.clone();
    expected.push("taken".into());
    expected.sort();
    assert_eq!(listing(&dir), expected, "a failed rename left a temporary file");

    // Writing into a directory that does not exist.
    assert_err!("missing parent", nbrdf::file::save(scratch.path("no/such/dir/m.nbrdf"), &model), Error::Io { .. });
    assert_err!("missing parent (EXR)", nbrdf::image::write_exr(scratch.path("no/such/i.exr"), &img), Error::Io { .. });
}
