//! Indexed triangle meshes: validation, OBJ and PLY loading, normalisation into the unit sphere and
//! smooth vertex normals.
//!
//! A [`Mesh`] is always valid once built: at least one triangle, every index in range, finite positions,
//! non-zero total area, one unit normal per vertex. Individual zero-area triangles are kept (so triangle
//! ids match the file) but never hit by a ray and carry no weight in the vertex normals.

use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;
use std::string::{String, ToString};
use std::vec::Vec;
use std::{format, vec};

use nbrdf::{Error, Vec3};

/// An indexed triangle mesh with one shading normal per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, interpolated barycentrically at hit points (Sec. 5.1).
    pub normals: Vec<Vec3>,
    /// Triangles as counter-clockwise (outward-facing) vertex index triples.
    pub triangles: Vec<[u32; 3]>,
}

/// The similarity `x ↦ (x - center) * scale` that [`Mesh::normalized`] applied.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Normalization {
    /// Centre of the bounding box of the original mesh.
    pub center: Vec3,
    /// Inverse of the largest distance of a vertex from `center`.
    pub scale: f32,
}

impl Normalization {
    /// Maps a point of the original mesh into the normalised frame.
    ///
    /// ```
    /// use nbrdf_scene::scene::Normalization;
    /// use nbrdf::Vec3;
    /// let n = Normalization { center: Vec3::new(1.0, 0.0, 0.0), scale: 0.5 };
    /// assert_eq!(n.apply(Vec3::new(3.0, 0.0, 0.0)), Vec3::new(1.0, 0.0, 0.0));
    /// ```
    #[inline]
    pub fn apply(&self, p: Vec3) -> Vec3 {
        (p - self.center) * self.scale
    }
}

fn parse_err(what: &str, message: impl ToString) -> Error {
    Error::Parse { what: what.to_string(), message: message.to_string() }
}

impl Mesh {
    /// Validates positions and triangles and computes angle-weighted vertex normals.
    ///
    /// Errors: no triangle, an index out of range, a non-finite position, or zero total area (every
    /// triangle degenerate).
    ///
    /// ```
    /// use nbrdf_scene::scene::Mesh;
    /// use nbrdf::Vec3;
    /// let quad = Mesh::new(
    ///     vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
    ///     vec![[0, 1, 2], [0, 2, 3]],
    /// ).unwrap();
    /// assert!(quad.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    /// assert!(Mesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 2]]).is_err()); // degenerate
    /// ```
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, Error> {
        validate(&positions, &triangles)?;
        let normals = angle_weighted_normals(&positions, &triangles);
        Ok(Mesh { positions, normals, triangles })
    }

    /// Like [`Mesh::new`] but with the caller's vertex normals (normalised here); a zero or non-finite
    /// normal is an error.
    pub fn with_normals(
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Result<Self, Error> {
        validate(&positions, &triangles)?;
        if normals.len() != positions.len() {
            return Err(Error::SizeMismatch {
                what: "mesh vertex normals",
                expected: positions.len(),
                found: normals.len(),
            });
        }
        let normals = normals
            .iter()
            .enumerate()
            .map(|(i, n)| {
                nbrdf::angles::unit(*n).ok_or(Error::NonFinite { what: "mesh vertex normals (zero or non-finite)", index: i })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Mesh { positions, normals, triangles })
    }

    /// Loads an OBJ (`.obj`) or PLY (`.ply`) file, chosen by extension.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, Error> {
        let path = path.as_ref();
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            // OBJ is read whole: through the capped reader, so that a device or a huge file is
            // refused instead of filling the memory.
            Some("obj") => {
                let bytes = nbrdf::io::read(path)?;
                Self::from_obj_reader(&mut bytes.as_slice()).map_err(|e| with_path(e, path))
            }
            Some("ply") => {
                let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
                let len = file.metadata().map_err(|e| Error::io(path, &e))?.len();
                if len > nbrdf::io::MAX_READ_BYTES {
                    let message = format!("{len} bytes, more than the {} bytes read of a mesh", nbrdf::io::MAX_READ_BYTES);
                    return Err(Error::io(path, &std::io::Error::new(std::io::ErrorKind::FileTooLarge, message)));
                }
                // The stream stops at the cap: a device that never ends is a PLY cut short.
                let capped = std::io::Read::take(file, nbrdf::io::MAX_READ_BYTES);
                Self::from_ply_reader(&mut std::io::BufReader::new(capped))
                    .map_err(|e| with_path(e, path))
            }
            _ => Err(Error::Parse {
                what: path.display().to_string(),
                message: "unknown mesh format: expected a .obj or .ply file".to_string(),
            }),
        }
    }

    /// Reads a Wavefront OBJ with `tobj`: every object of the file, polygons triangulated as fans, file
    /// normals where every face has them, else computed ones. Materials and texture coordinates are
    /// ignored.
    pub fn from_obj_reader(reader: &mut impl BufRead) -> Result<Self, Error> {
        // `..Default::default()` stays: tobj's `merging`/`reordering` features, which another crate
        // of a build may enable, add fields.
        #[allow(clippy::needless_update)]
        let options = tobj::LoadOptions {
            single_index: false,
            // Polygons (suzanne.obj has quads) become triangle fans.
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
            ..Default::default()
        };
        let mut text = String::new();
        reader.read_to_string(&mut text).map_err(|e| parse_err("OBJ", e))?;
        check_obj_face_indices(&text)?;
        // Second line of defence: should tobj still panic on some input, it is a parse error here.
        let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
                Err(tobj::LoadError::OpenFileFailed) // materials are not needed
            })
        }))
        .map_err(|_| parse_err("OBJ", "face index out of range (the OBJ parser failed on it)"))?;
        let (models, _) = loaded.map_err(|e| parse_err("OBJ", e))?;
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut triangles = Vec::new();
        // File normals are used only if every object has one per face corner; otherwise all are computed.
        let all_have_normals = !models.is_empty()
            && models.iter().all(|m| {
                !m.mesh.normals.is_empty() && m.mesh.normal_indices.len() == m.mesh.indices.len()
            });
        for model in &models {
            let m = &model.mesh;
            if m.indices.len() % 3 != 0 {
                return Err(parse_err("OBJ", format!("object '{}' is not a triangle mesh", model.name)));
            }
            let p = |i: u32| {
                let i = i as usize * 3;
                Vec3::new(m.positions[i], m.positions[i + 1], m.positions[i + 2])
            };
            if all_have_normals {
                // A position with several file normals (a crease) becomes several vertices.
                let mut remap: HashMap<(u32, u32), u32> = HashMap::new();
                let nrm = |i: u32| {
                    let i = i as usize * 3;
                    Vec3::new(m.normals[i], m.normals[i + 1], m.normals[i + 2])
                };
                let mut corners = Vec::with_capacity(m.indices.len());
                for (&pi, &ni) in m.indices.iter().zip(&m.normal_indices) {
                    let id = *remap.entry((pi, ni)).or_insert_with(|| {
                        positions.push(p(pi));
                        normals.push(nrm(ni));
                        (positions.len() - 1) as u32
                    });
                    corners.push(id);
                }
                triangles.extend(corners.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            } else {
                let base = positions.len() as u32;
                positions.extend((0..m.positions.len() as u32 / 3).map(p));
                triangles
                    .extend(m.indices.chunks_exact(3).map(|c| [base + c[0], base + c[1], base + c[2]]));
            }
        }
        if all_have_normals {
            Self::with_normals(positions, normals, triangles)
        } else {
            Self::new(positions, triangles)
        }
    }

    /// Reads an ASCII or binary PLY with `ply-rs-bw`: element `vertex` with `x, y, z` (and optional
    /// `nx, ny, nz`), and element `face` with a `vertex_indices` (or `vertex_index`) list of three or
    /// more entries (polygons become triangle fans) or element `tristrips` with one such list of
    /// strips separated by -1 (or both).
    ///
    /// ```
    /// use nbrdf_scene::scene::Mesh;
    /// let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
    ///            property float z\nelement tristrips 1\nproperty list int int vertex_indices\n\
    ///            end_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n";
    /// let mesh = Mesh::from_ply_reader(&mut ply.as_bytes()).unwrap();
    /// assert_eq!(mesh.triangles, vec![[0, 1, 2], [2, 1, 3]]); // the second one flipped: same winding
    /// ```
    pub fn from_ply_reader(reader: &mut impl std::io::Read) -> Result<Self, Error> {
        use ply_rs_bw::parser::Parser;
        use ply_rs_bw::ply::{DefaultElement, Property};
        let ply = Parser::<DefaultElement>::new().read_ply(reader).map_err(|e| parse_err("PLY", e))?;
        let scalar = |p: &Property| -> Option<f32> {
            Some(match *p {
                Property::Float(v) => v,
                Property::Double(v) => v as f32,
                Property::Char(v) => v as f32,
                Property::UChar(v) => v as f32,
                Property::Short(v) => v as f32,
                Property::UShort(v) => v as f32,
                Property::Int(v) => v as f32,
                Property::UInt(v) => v as f32,
                _ => return None,
            })
        };
        let vertices = ply
            .payload
            .get("vertex")
            .ok_or_else(|| parse_err("PLY", "no 'vertex' element"))?;
        let get3 = |e: &DefaultElement, keys: [&str; 3]| -> Option<Vec3> {
            let c = |k: &str| e.get(k).and_then(scalar);
            Some(Vec3::new(c(keys[0])?, c(keys[1])?, c(keys[2])?))
        };
        let mut positions = Vec::with_capacity(vertices.len());
        let mut normals = Vec::with_capacity(vertices.len());
        for (i, v) in vertices.iter().enumerate() {
            positions.push(get3(v, ["x", "y", "z"]).ok_or_else(|| {
                parse_err("PLY", format!("vertex {i} lacks a numeric x, y or z"))
            })?);
            if let Some(n) = get3(v, ["nx", "ny", "nz"]) {
                normals.push(n);
            }
        }
        // The integer list of element `what`'s entry `i`, widened.
        let indices = |what: &str, i: usize, e: &DefaultElement| -> Result<Vec<i64>, Error> {
            Ok(match e.get("vertex_indices").or_else(|| e.get("vertex_index")) {
                Some(Property::ListChar(l)) => l.iter().map(|&x| x as i64).collect(),
                Some(Property::ListUChar(l)) => l.iter().map(|&x| x as i64).collect(),
                Some(Property::ListShort(l)) => l.iter().map(|&x| x as i64).collect(),
                Some(Property::ListUShort(l)) => l.iter().map(|&x| x as i64).collect(),
                Some(Property::ListInt(l)) => l.iter().map(|&x| x as i64).collect(),
                Some(Property::ListUInt(l)) => l.iter().map(|&x| x as i64).collect(),
                _ => return Err(parse_err("PLY", format!("{what} {i} lacks an integer vertex_indices list"))),
            })
        };
        let vertex = |what: &str, i: usize, x: i64| {
            u32::try_from(x).map_err(|_| parse_err("PLY", format!("{what} {i} has the negative vertex index {x}")))
        };
        let (faces, strips) = (ply.payload.get("face"), ply.payload.get("tristrips"));
        if faces.is_none() && strips.is_none() {
            return Err(parse_err("PLY", "no 'face' or 'tristrips' element"));
        }
        let mut triangles = Vec::new();
        for (i, f) in faces.into_iter().flatten().enumerate() {
            let idx = indices("face", i, f)?;
            if idx.len() < 3 {
                return Err(parse_err(
                    "PLY",
                    format!("face {i} has {} corners; a face needs at least three", idx.len()),
                ));
            }
            let idx: Vec<u32> = idx.iter().map(|&x| vertex("face", i, x)).collect::<Result<_, _>>()?;
            // Polygons become triangle fans, as tobj does for OBJ files.
            triangles.extend((1..idx.len() - 1).map(|j| [idx[0], idx[j], idx[j + 1]]));
        }
        // Triangle strips (as Stanford's scanner tools write them): -1 ends a strip; every other
        // triangle is flipped so that all keep the strip's winding; repeated vertices give
        // degenerate triangles, which are dropped.
        for (i, s) in strips.into_iter().flatten().enumerate() {
            for strip in indices("tristrips", i, s)?.split(|&x| x == -1) {
                let strip: Vec<u32> = strip.iter().map(|&x| vertex("tristrips", i, x)).collect::<Result<_, _>>()?;
                for (j, w) in strip.windows(3).enumerate() {
                    let t = if j % 2 == 0 { [w[0], w[1], w[2]] } else { [w[1], w[0], w[2]] };
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        triangles.push(t);
                    }
                }
            }
        }
        if !normals.is_empty() && normals.len() == positions.len() {
            Self::with_normals(positions, normals, triangles)
        } else {
            Self::new(positions, triangles)
        }
    }

    /// The mesh moved and scaled into the unit sphere (bounding-box centre at the origin, farthest vertex
    /// at distance 1), with the similarity applied. Normals are unchanged by a uniform scaling.
    ///
    /// ```
    /// use nbrdf_scene::scene::Mesh;
    /// use nbrdf::Vec3;
    /// let m = Mesh::new(vec![Vec3::new(10.0, 0.0, 0.0), Vec3::new(14.0, 0.0, 0.0), Vec3::new(10.0, 2.0, 0.0)],
    ///                   vec![[0, 1, 2]]).unwrap();
    /// let (n, t) = m.normalized();
    /// let r = n.positions.iter().map(|p| p.length()).fold(0.0, f32::max);
    /// assert!((r - 1.0).abs() < 1e-6);
    /// assert_eq!(t.apply(m.positions[1]), n.positions[1]);
    /// ```
    pub fn normalized(&self) -> (Mesh, Normalization) {
        let (lo, hi) = self.bounds();
        let center = (lo + hi) * 0.5;
        let radius = self.positions.iter().map(|p| (*p - center).length()).fold(0.0f32, f32::max);
        // Validation guarantees a non-zero area, hence a non-zero radius.
        let t = Normalization { center, scale: 1.0 / radius };
        let positions = self.positions.iter().map(|p| t.apply(*p)).collect();
        (Mesh { positions, normals: self.normals.clone(), triangles: self.triangles.clone() }, t)
    }

    /// A hash of the vertex positions (their bits) and the triangles: the identity of the mesh a
    /// model's per-vertex table was fitted on ([`ModelHeader::mesh_hash`](nbrdf::file::ModelHeader::mesh_hash)).
    /// The CRC-32 of the positions in the high half, of the triangles in the low half. The trainer and
    /// the path tracer hash the mesh as they hold it: built-in meshes as built, files after
    /// [`normalized`](Self::normalized).
    ///
    /// ```
    /// use nbrdf_scene::scene::builtin::BuiltinMesh;
    /// let (a, b) = (BuiltinMesh::Sphere.mesh(), BuiltinMesh::Torus.mesh());
    /// assert_eq!(a.content_hash(), BuiltinMesh::Sphere.mesh().content_hash());
    /// assert_ne!(a.content_hash(), b.content_hash());
    /// ```
    pub fn content_hash(&self) -> u64 {
        let mut p = crc32fast::Hasher::new();
        for v in &self.positions {
            for c in v.to_array() {
                p.update(&c.to_bits().to_le_bytes());
            }
        }
        let mut t = crc32fast::Hasher::new();
        for tri in &self.triangles {
            for i in tri {
                t.update(&i.to_le_bytes());
            }
        }
        (u64::from(p.finalize()) << 32) | u64::from(t.finalize())
    }

    /// Axis-aligned bounding box `(min, max)` of the vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        })
    }

    /// Radius of the bounding sphere around the bounding-box centre: the length scale for ray offsets.
    pub fn radius(&self) -> f32 {
        let (lo, hi) = self.bounds();
        let c = (lo + hi) * 0.5;
        self.positions.iter().map(|p| (*p - c).length()).fold(0.0f32, f32::max)
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn corners(&self, t: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t as usize];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Shading normal at barycentrics `(b1, b2)` of triangle `t` (weights `1 - b1 - b2`, `b1`, `b2` on its
    /// corners): the normalised barycentric interpolation of the vertex normals (Sec. 5.1).
    #[inline]
    pub fn shading_normal(&self, t: u32, b1: f32, b2: f32) -> Vec3 {
        let [a, b, c] = self.triangles[t as usize];
        let n = self.normals[a as usize] * (1.0 - b1 - b2)
            + self.normals[b as usize] * b1
            + self.normals[c as usize] * b2;
        // Opposite corner normals can cancel (a knife edge); the face normal is the honest fallback.
        nbrdf::angles::unit(n).unwrap_or_else(|| self.face_normal(t))
    }

    /// Unit geometric normal of triangle `t` (right-handed winding); `+z` for a degenerate triangle.
    #[inline]
    pub fn face_normal(&self, t: u32) -> Vec3 {
        let [a, b, c] = self.corners(t);
        nbrdf::angles::unit((b - a).cross(c - a)).unwrap_or(Vec3::Z)
    }

    /// Surface point at barycentrics `(b1, b2)` of triangle `t`.
    #[inline]
    pub fn point(&self, t: u32, b1: f32, b2: f32) -> Vec3 {
        let [a, b, c] = self.corners(t);
        a * (1.0 - b1 - b2) + b * b1 + c * b2
    }
}

/// tobj 4.0.5 bounds-checks texture and normal indices with unchecked arithmetic (`vt * 2 + 1`,
/// `vn * 3 + 2`): a huge index, or a relative one reaching before the first element, overflows it — a
/// panic with overflow checks, and for normals an index that wraps past the check out of bounds, a panic
/// in release too (found by the `mesh_parse` fuzz target). So faces are checked here first, the
/// way tobj reads them (line by line, whitespace-separated `v/vt/vn` triples, relative indices counted
/// from the elements declared so far): an absolute index must fit `u32`, a relative one must not reach
/// before the first element. Tokens that are not integers are left to tobj, which rejects them.
fn check_obj_face_indices(text: &str) -> Result<(), Error> {
    let mut declared = [0u64; 3]; // v, vt, vn lines so far
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => declared[0] += 1,
            Some("vt") => declared[1] += 1,
            Some("vn") => declared[2] += 1,
            Some("f") | Some("l") => {
                for word in words {
                    for (k, part) in word.split('/').enumerate().take(3) {
                        let Ok(x) = part.parse::<i64>() else { continue };
                        let ok = if x < 0 { x.unsigned_abs() <= declared[k] } else { x <= i64::from(u32::MAX) };
                        if !ok {
                            return Err(parse_err("OBJ", format!("line {}: face index {x} is out of range", n + 1)));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn with_path(e: Error, path: &Path) -> Error {
    match e {
        Error::Parse { what, message } => Error::Parse { what: format!("{what} file {}", path.display()), message },
        other => other,
    }
}

fn validate(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(), Error> {
    if triangles.is_empty() {
        return Err(Error::InvalidValue { what: "mesh", reason: "it has no triangles" });
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::NonFinite { what: "mesh vertex positions", index: i });
    }
    for t in triangles {
        for &i in t {
            if i as usize >= positions.len() {
                return Err(Error::SizeMismatch {
                    what: "mesh vertex index (index found, vertex count expected above it)",
                    expected: positions.len(),
                    found: i as usize,
                });
            }
        }
    }
    let area: f64 = triangles
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (positions[a as usize], positions[b as usize], positions[c as usize]);
            (b - a).cross(c - a).length() as f64
        })
        .sum();
    if area.is_nan() || area <= 0.0 {
        return Err(Error::InvalidValue {
            what: "mesh",
            reason: "it is degenerate: every triangle has zero area",
        });
    }
    Ok(())
}

/// Vertex normals as the sum of incident face normals weighted by the corner angle, the "mean weighted
/// by angle" normal of Thürmer & Wüthrich 1998, "Computing vertex normals from polygonal facets": it does
/// not depend on how a surface is tessellated. A vertex whose weighted sum vanishes (no incident
/// non-degenerate face) gets `+z`; such a vertex belongs only to triangles no ray can hit.
pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for &t in triangles {
        let p = t.map(|i| positions[i as usize]);
        let Some(n) = nbrdf::angles::unit((p[1] - p[0]).cross(p[2] - p[0])) else { continue };
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            let (Some(e1), Some(e2)) = (nbrdf::angles::unit(e1), nbrdf::angles::unit(e2)) else { continue };
            let angle = nbrdf::math::safe_acos(e1.dot(e2));
            acc[t[k] as usize] += n * angle;
        }
    }
    acc.into_iter().map(|n| nbrdf::angles::unit(n).unwrap_or(Vec3::Z)).collect()
}
