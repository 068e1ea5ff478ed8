//! Bad input for the scene crate: the mesh (OBJ, PLY) and image (EXR, PNG) readers, their malformed
//! variants and the specific error each one gets, and the image writers' behaviour when their output
//! cannot be written. The core's formats (model files, MERL, NBRDF-json) and its atomic writes are
//! checked in the core's `tests/bad_input.rs`, where these cases came from.
//!
//! `docs/bad-input.md` is the table of these cases; keep the two in step. No case may panic: each is an
//! `Error` value that names what is wrong.


use nbrdf::Error;
use nbrdf_scene::image::RgbImage;
use nbrdf_scene::scene::Mesh;

#[path = "../../tests/support/bad_input.rs"]
#[macro_use]
mod support;
use support::{failed_writes_keep_the_old_files, listing, Scratch, WriteCase};

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
    nbrdf_scene::image::write_exr(&exr, &img).unwrap();
    assert_eq!(nbrdf_scene::image::read_exr(&exr).unwrap(), img);
    let bytes = std::fs::read(&exr).unwrap();
    assert_err!("missing EXR", nbrdf_scene::image::read_exr(dir.path("missing.exr")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    for (case, content) in [
        ("empty EXR", &b""[..]),
        ("not an EXR", &b"P6\n1 1\n255\n\0\0\0"[..]),
        ("EXR magic only", &bytes[..4]),
        ("EXR header cut", &bytes[..bytes.len() / 4]),
        ("EXR pixels cut", &bytes[..bytes.len() - 8]),
    ] {
        let p = dir.write("bad.exr", content);
        assert_err!(case, nbrdf_scene::image::read_exr(&p), Error::Parse { what, .. } if what.contains("bad.exr"));
    }

    let png = dir.path("a.png");
    nbrdf_scene::image::write_png16(&png, 2, 1, &[[0, 1000, 65535], [7, 8, 9]]).unwrap();
    assert_eq!(nbrdf_scene::image::read_png(&png).unwrap().data[0], [0.0, 1000.0 / 65535.0, 1.0]);
    let bytes = std::fs::read(&png).unwrap();
    assert_err!("missing PNG", nbrdf_scene::image::read_png(dir.path("missing.png")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    assert_err!("missing mask", nbrdf_scene::image::read_mask(dir.path("missing.png")),
        Error::Io { kind: std::io::ErrorKind::NotFound, .. });
    for (case, content) in [
        ("empty PNG", &b""[..]),
        ("not a PNG", &b"GIF89a"[..]),
        ("PNG signature only", &bytes[..8]),
        ("PNG cut in the data", &bytes[..bytes.len() - 16]),
    ] {
        let p = dir.write("bad.png", content);
        assert_err!(case, nbrdf_scene::image::read_png(&p), Error::Parse { what, .. } if what.contains("bad.png"));
    }
    // A PNG with a flipped byte in its image data fails its CRC.
    let mut b = bytes.clone();
    let n = b.len();
    b[n - 20] ^= 0xff;
    let p = dir.write("crc.png", &b);
    assert_err!("PNG bad chunk CRC", nbrdf_scene::image::read_png(&p), Error::Parse { .. });

    // Writers check the pixel count against the size instead of panicking inside the encoder.
    assert_err!("mask size", nbrdf_scene::image::write_png_mask(dir.path("m.png"), 2, 2, &[true; 3]),
        Error::SizeMismatch { what: "mask pixel count", expected: 4, found: 3 });
    assert_err!("png16 size", nbrdf_scene::image::write_png16(dir.path("m.png"), 2, 2, &[[0; 3]; 5]),
        Error::SizeMismatch { what: "image pixel count", expected: 4, found: 5 });
    assert_err!("rgb8 size", nbrdf_scene::image::write_png_rgb8(dir.path("m.png"), 2, 2, &[0; 11]),
        Error::SizeMismatch { what: "RGB8 byte count", expected: 12, found: 11 });
    // RgbImage's fields are public, so an inconsistent image can reach the writers.
    let broken = RgbImage { width: 4, height: 4, data: vec![[0.0; 3]; 3] };
    assert_err!("EXR of an inconsistent image", nbrdf_scene::image::write_exr(dir.path("b.exr"), &broken),
        Error::SizeMismatch { what: "image pixel count", expected: 16, found: 3 });
    assert_err!("PNG of an inconsistent image", nbrdf_scene::image::write_png_srgb(dir.path("b.png"), &broken, 1.0),
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
    nbrdf_scene::image::write_exr(&p, &img).unwrap();
    let back = nbrdf_scene::image::read_exr(&p).unwrap();
    assert!(back.data[0][0].is_nan());
    assert_eq!(&back.data[1..], &img.data[1..]);
    // The 8-bit sRGB view clamps them instead.
    nbrdf_scene::image::write_png_srgb(dir.path("hdr.png"), &img, 1.0).unwrap();
    let view = nbrdf_scene::image::read_png(dir.path("hdr.png")).unwrap();
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
    check("EXR", nbrdf_scene::image::read_exr(&p).map(|_| ()));
    check("PNG", nbrdf_scene::image::read_png(&p).map(|_| ()));
}

// -------------------------------------------------------------------------------------------------
// Outputs: atomic, and an existing file survives a failed write

#[test]
fn a_failed_write_leaves_the_existing_file_intact_for_every_writer() {
    let scratch = Scratch::new("unwritable");
    let dir = scratch.path("out");
    std::fs::create_dir(&dir).unwrap();
    let old = b"the previous, complete contents";
    let names = ["i.exr", "i.png", "mask.png", "i16.png", "i8.png"];
    for n in names {
        std::fs::write(dir.join(n), old).unwrap();
    }
    let before = listing(&dir);

    let img = gradient(3, 2);
    let writes: Vec<(&str, WriteCase)> = vec![
        ("write_exr", Box::new(|| nbrdf_scene::image::write_exr(dir.join("i.exr"), &img))),
        ("write_png_srgb", Box::new(|| nbrdf_scene::image::write_png_srgb(dir.join("i.png"), &img, 1.0))),
        ("write_png_mask", Box::new(|| nbrdf_scene::image::write_png_mask(dir.join("mask.png"), 1, 1, &[true]))),
        ("write_png16", Box::new(|| nbrdf_scene::image::write_png16(dir.join("i16.png"), 1, 1, &[[1, 2, 3]]))),
        ("write_png_rgb8", Box::new(|| nbrdf_scene::image::write_png_rgb8(dir.join("i8.png"), 1, 1, &[1, 2, 3]))),
    ];

    failed_writes_keep_the_old_files(&dir, &names, old, &writes);

    // The destination is a directory: the final rename fails, and the temporary file goes with it.
    std::fs::create_dir(dir.join("taken")).unwrap();
    std::fs::write(dir.join("taken").join("x"), b"x").unwrap();
    assert_err!("EXR over a directory", nbrdf_scene::image::write_exr(dir.join("taken"), &img), Error::Io { .. });
    let mut expected = before.clone();
    expected.push("taken".into());
    expected.sort();
    assert_eq!(listing(&dir), expected, "a failed rename left a temporary file");

    // Writing into a directory that does not exist.
    assert_err!("missing parent (EXR)", nbrdf_scene::image::write_exr(scratch.path("no/such/i.exr"), &img), Error::Io { .. });
}
