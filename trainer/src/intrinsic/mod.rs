//! The intrinsic position encoding of Koestler et al. 2022, "Intrinsic Neural Fields: Learning Functions
//! on Manifolds" (ECCV), used for the spatial input of every neural BRDF in the paper (Sec. 4.2): the k
//! Laplace–Beltrami eigenfunctions of smallest eigenvalue, the constant one dropped, stored per vertex
//! and interpolated barycentrically at a surface point.
//!
//! Pipeline: [`mesh`] validates the arrays and drops degenerate triangles and isolated vertices;
//! [`laplacian`] assembles the cotangent stiffness L and mixed-Voronoi mass M; [`eigen`] solves
//! L φ = λ M φ by shift-invert block Lanczos on a sparse Cholesky factor; [`cache`] keeps the result on disk
//! per mesh and k. [`extrinsic()`] is the baseline encoding of the 3D point itself.
//!
//! Any triangle soup with at least one non-degenerate triangle has an encoding, as scanned meshes must:
//! - several connected components (one constant eigenfunction each): all the per-component constants
//!   are dropped, and the k smallest non-zero eigenvalues kept, so each eigenfunction lives on one
//!   component (or a few with equal eigenvalues) and integrates to zero on each;
//! - tiny islands: their eigenvalues grow like 1/area, so none is among the k smallest unless k is
//!   large, and their vertices then get all-zero rows, like isolated vertices;
//! - isolated vertices (in no kept triangle): all-zero rows, the value of every eigenfunction's mean;
//! - degenerate (zero-area or repeated-index) triangles: dropped before assembly;
//! - boundaries, non-manifold edges (shared by three or more triangles), inconsistent orientation: the
//!   cotangent stiffness is a sum of per-triangle positive semi-definite terms and never looks at them.
//!
//! The only meshes without an encoding are those with no usable triangle and those with fewer than
//! k + c vertices in triangles (c components): [`Error::NoValidTriangles`], [`Error::InvalidK`].
//!
//! ```
//! use trainer::intrinsic::IntrinsicEncoding;
//! // A regular tetrahedron: 4 vertices, so at most k = 3 non-constant eigenfunctions.
//! let positions = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];
//! let triangles = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
//! let enc = IntrinsicEncoding::compute(&positions, &triangles, 3).unwrap();
//! // By symmetry the three non-constant eigenfunctions share one eigenvalue.
//! let l = enc.eigenvalues();
//! assert!((l[0] - l[2]).abs() < 1e-9 * l[2]);
//! let mut at_centroid = [0.0f32; 3];
//! enc.interpolate([0, 1, 2], [1.0 / 3.0; 3], &mut at_centroid).unwrap();
//! ```

pub mod cache;
pub mod eigen;
pub mod extrinsic;
pub mod laplacian;
pub mod mesh;

use std::path::{Path, PathBuf};

pub use cache::cache_key;
pub use eigen::Method;
pub use extrinsic::{extrinsic, extrinsic_into, extrinsic_len};
pub use mesh::MeshReport;

/// What can go wrong computing, caching or using the encoding.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No vertices or no triangles.
    #[error("empty mesh: {n_vertices} vertices, {n_triangles} triangles")]
    EmptyMesh {
        /// Vertices given.
        n_vertices: usize,
        /// Triangles given.
        n_triangles: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinitePosition {
        /// Index of the first such vertex.
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {vertex}, but the mesh has {n_vertices} vertices")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The bad vertex index.
        vertex: u32,
        /// Vertices in the mesh.
        n_vertices: usize,
    },
    /// Every triangle is degenerate (zero area or repeated vertex).
    #[error("no usable triangle: all {degenerate} triangles are degenerate")]
    NoValidTriangles {
        /// Degenerate triangles found.
        degenerate: usize,
    },
    /// k is 0 or larger than (vertices in use − connected components): the eigenproblem has only that
    /// many non-constant eigenfunctions.
    #[error(
        "k = {k} eigenfunctions requested, but this mesh has at most {max} (vertices in triangles − connected components) and k must be ≥ 1"
    )]
    InvalidK {
        /// Requested k.
        k: usize,
        /// Largest possible k.
        max: usize,
    },
    /// A size beyond what the format or index type can hold.
    #[error("{what} = {found} exceeds the maximum {max}")]
    TooLarge {
        /// The quantity.
        what: &'static str,
        /// Value found.
        found: usize,
        /// Largest accepted.
        max: usize,
    },
    /// The sparse factorisation of L + sM failed.
    #[error("factorisation failed: {reason}")]
    Factorization {
        /// What failed.
        reason: String,
    },
    /// The eigensolver stopped before all wanted pairs converged.
    #[error("eigensolver converged {converged} of {wanted} eigenpairs ({detail})")]
    NotConverged {
        /// Pairs wanted (k).
        wanted: usize,
        /// Pairs converged.
        converged: usize,
        /// Which solver and how it stopped.
        detail: String,
    },
    /// A cache file exists but cannot be used.
    #[error("corrupt eigenfunction cache {path}: {reason}; delete it to recompute")]
    CorruptCache {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// File system failure.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// An output slice has the wrong length.
    #[error("output slice has length {got}, expected {expected}")]
    OutputLength {
        /// Length needed.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// An interpolation query names a vertex the encoding does not have.
    #[error("vertex {vertex} out of range: the encoding has {n_vertices} vertices")]
    VertexOutOfRange {
        /// The bad index.
        vertex: u32,
        /// Vertices in the encoding.
        n_vertices: usize,
    },
}

/// Diagnostics of one computation, for logs and tests.
#[derive(Debug, Clone)]
pub struct Report {
    /// What mesh validation kept and dropped.
    pub mesh: MeshReport,
    /// Which solver ran.
    pub method: Method,
    /// Largest scale-free residual `‖Lφ − λMφ‖_{M⁻¹} / (λ_k ‖φ‖_M)` over the kept pairs, relative to
    /// the largest kept eigenvalue λ_k, so that one number bounds the error of every pair.
    pub max_relative_residual: f64,
    /// `ε ‖M^{-1/2} L M^{-1/2}‖ / λ_k` (the norm bounded by Gershgorin): the residual that rounding alone
    /// causes. Around 1e-13 on clean meshes; slivers raise it (it grows like 1/height²), and the solver
    /// accepts residuals up to [`eigen::FLOOR_SAFETY`] times it.
    pub rounding_floor: f64,
    /// Largest `|∫_c φ_j dA| / √area_c` over the kept eigenfunctions j and connected components c: how
    /// far the per-component constants are from removed (0 in exact arithmetic).
    pub max_component_mean: f64,
}

/// The per-vertex table of the k smallest non-constant Laplace–Beltrami eigenfunctions of a mesh.
///
/// Values are `f32`, row-major `[n_vertices × k]`: row v holds φ_1(v) … φ_k(v). The eigenfunctions are
/// M-orthonormal (∫ φ_i φ_j dA = δ_ij over the surface), so their magnitude scales like
/// 1/√area; see [`scaled_to_unit_range`](Self::scaled_to_unit_range) for the rescaling Koestler et al.
/// apply before the network. Isolated vertices (in no usable triangle) have all-zero rows. On a mesh
/// with c > 1 connected components the c constant eigenfunctions (eigenvalue 0) are all dropped: every
/// column is M-orthogonal to each component's indicator, and the eigenvalues are all positive.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicEncoding {
    key: u64,
    n_vertices: usize,
    k: usize,
    eigenvalues: Vec<f64>,
    values: Vec<f32>,
}

impl IntrinsicEncoding {
    /// Computes the k eigenfunctions of smallest non-zero eigenvalue of the mesh.
    pub fn compute(positions: &[[f32; 3]], triangles: &[[u32; 3]], k: usize) -> Result<Self, Error> {
        Self::compute_with_report(positions, triangles, k).map(|(enc, _)| enc)
    }

    /// [`compute`](Self::compute), also returning what was dropped and how well the solve converged.
    pub fn compute_with_report(
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
        k: usize,
    ) -> Result<(Self, Report), Error> {
        let mesh = mesh::validate(positions, triangles)?;
        let max = mesh.active.len() - mesh.report.components;
        if k == 0 || k > max {
            return Err(Error::InvalidK { k, max });
        }
        if k > u32::MAX as usize {
            return Err(Error::TooLarge {
                what: "k",
                found: k,
                max: u32::MAX as usize,
            });
        }
        let lap = laplacian::CotanLaplacian::assemble(&mesh);
        let pairs = eigen::smallest_eigenpairs(&lap, k)?;
        let scale = pairs.values[k - 1];
        let column = |j: usize| -> Vec<f64> { (0..lap.len()).map(|i| pairs.vectors[(i, j)]).collect() };
        let max_relative_residual = (0..k)
            .map(|j| eigen::residual(&lap, &column(j), pairs.values[j]) / scale)
            .fold(0.0, f64::max);
        let rounding_floor = f64::EPSILON * lap.norm_bound() / scale;
        let max_component_mean = (0..k)
            .map(|j| component_means(&lap, &column(j)))
            .fold(0.0, f64::max);

        let mut values = vec![0.0f32; positions.len() * k];
        for (a, &v) in mesh.active.iter().enumerate() {
            let row = &mut values[v as usize * k..(v as usize + 1) * k];
            for (j, out) in row.iter_mut().enumerate() {
                *out = pairs.vectors[(a, j)] as f32;
            }
        }
        let enc = Self {
            key: cache_key(positions, triangles, k),
            n_vertices: positions.len(),
            k,
            eigenvalues: pairs.values,
            values,
        };
        let report = Report {
            mesh: mesh.report,
            method: pairs.method,
            max_relative_residual,
            rounding_floor,
            max_component_mean,
        };
        Ok((enc, report))
    }

    /// Loads the encoding of this mesh and k from `cache_dir`, or computes and stores it there.
    ///
    /// The file name is derived from [`cache_key`]; a file that exists but is corrupt, or holds another
    /// mesh, is an error ([`Error::CorruptCache`]) rather than silently recomputed, so that a broken
    /// cache directory is noticed.
    pub fn load_or_compute(
        cache_dir: &Path,
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
        k: usize,
    ) -> Result<Self, Error> {
        let key = cache_key(positions, triangles, k);
        let path = cache_dir.join(cache::cache_file_name(key));
        if path.exists() {
            let enc = Self::load(&path)?;
            if enc.key != key || enc.n_vertices != positions.len() || enc.k != k {
                return Err(Error::CorruptCache {
                    path,
                    reason: format!(
                        "holds key {:016x} (n = {}, k = {}), expected {key:016x} (n = {}, k = {k})",
                        enc.key,
                        enc.n_vertices,
                        enc.k,
                        positions.len()
                    ),
                });
            }
            return Ok(enc);
        }
        let enc = Self::compute(positions, triangles, k)?;
        enc.save(&path)?;
        Ok(enc)
    }

    /// Reads a cache file written by [`save`](Self::save).
    pub fn load(path: &Path) -> Result<Self, Error> {
        cache::read(path)
    }

    /// Writes the cache file atomically (temporary file + rename).
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        if self.n_vertices > u32::MAX as usize {
            return Err(Error::TooLarge {
                what: "vertex count",
                found: self.n_vertices,
                max: u32::MAX as usize,
            });
        }
        cache::write_atomic(path, &cache::encode(self))
    }

    pub(crate) fn from_parts(key: u64, n_vertices: usize, k: usize, eigenvalues: Vec<f64>, values: Vec<f32>) -> Self {
        Self {
            key,
            n_vertices,
            k,
            eigenvalues,
            values,
        }
    }

    /// [`cache_key`] of the mesh and k this encoding was computed for.
    pub fn key(&self) -> u64 {
        self.key
    }

    /// Number of mesh vertices (rows of the table), isolated ones included.
    pub fn n_vertices(&self) -> usize {
        self.n_vertices
    }

    /// Number of eigenfunctions (columns of the table).
    pub fn k(&self) -> usize {
        self.k
    }

    /// The k eigenvalues λ_1 ≤ … ≤ λ_k, in 1 / (mesh unit)².
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// The table, row-major `[n_vertices × k]`.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Row `vertex` of the table, or `None` if out of range.
    pub fn vertex(&self, vertex: u32) -> Option<&[f32]> {
        let v = vertex as usize;
        (v < self.n_vertices).then(|| &self.values[v * self.k..(v + 1) * self.k])
    }

    /// The encoding at the surface point with barycentric coordinates `bary` in triangle `tri`:
    /// `out = b0 φ(v0) + b1 φ(v1) + b2 φ(v2)` (Koestler et al. 2022, Sec. 3: the eigenfunctions are
    /// piecewise linear on the mesh). `out.len()` must be k. At a vertex (`bary` a unit vector) this is
    /// that vertex's row exactly.
    pub fn interpolate(&self, tri: [u32; 3], bary: [f32; 3], out: &mut [f32]) -> Result<(), Error> {
        if out.len() != self.k {
            return Err(Error::OutputLength {
                expected: self.k,
                got: out.len(),
            });
        }
        let row = |v: u32| {
            self.vertex(v).ok_or(Error::VertexOutOfRange {
                vertex: v,
                n_vertices: self.n_vertices,
            })
        };
        let (r0, r1, r2) = (row(tri[0])?, row(tri[1])?, row(tri[2])?);
        for (j, o) in out.iter_mut().enumerate() {
            *o = bary[0] * r0[j] + bary[1] * r1[j] + bary[2] * r2[j];
        }
        Ok(())
    }

    /// [`interpolate`](Self::interpolate) for many points: `out` is row-major `[tris.len() × k]`.
    pub fn interpolate_many(&self, tris: &[[u32; 3]], barys: &[[f32; 3]], out: &mut [f32]) -> Result<(), Error> {
        if barys.len() != tris.len() {
            return Err(Error::OutputLength {
                expected: tris.len(),
                got: barys.len(),
            });
        }
        if out.len() != tris.len() * self.k {
            return Err(Error::OutputLength {
                expected: tris.len() * self.k,
                got: out.len(),
            });
        }
        for ((tri, bary), o) in tris.iter().zip(barys).zip(out.chunks_exact_mut(self.k.max(1))) {
            self.interpolate(*tri, *bary, o)?;
        }
        Ok(())
    }

    /// The table with every eigenfunction divided by its range (max − min over the vertices), so each
    /// column spans an interval of length 1: the default ("standard") rescaling in Koestler et al.'s
    /// reference implementation, which makes the input scale independent of the mesh's area. A constant
    /// column (only possible for isolated-vertex-only data) is left unchanged.
    pub fn scaled_to_unit_range(&self) -> Vec<f32> {
        let k = self.k;
        let mut lo = vec![f32::INFINITY; k];
        let mut hi = vec![f32::NEG_INFINITY; k];
        for row in self.values.chunks_exact(k.max(1)) {
            for j in 0..k {
                lo[j] = lo[j].min(row[j]);
                hi[j] = hi[j].max(row[j]);
            }
        }
        let scale: Vec<f32> = lo
            .iter()
            .zip(&hi)
            .map(|(l, h)| if h > l { 1.0 / (h - l) } else { 1.0 })
            .collect();
        let mut out = self.values.clone();
        for row in out.chunks_exact_mut(k.max(1)) {
            for j in 0..k {
                row[j] *= scale[j];
            }
        }
        out
    }
}

/// `max_c |∫_c φ dA| / √area_c`: the M-inner product of φ with each component's unit indicator.
fn component_means(lap: &laplacian::CotanLaplacian, phi: &[f64]) -> f64 {
    let mut integral = vec![0.0f64; lap.components()];
    for ((&c, &m), &v) in lap.component().iter().zip(lap.mass()).zip(phi) {
        integral[c as usize] += m * v;
    }
    integral
        .iter()
        .zip(lap.component_area())
        .map(|(i, a)| i.abs() / a.sqrt())
        .fold(0.0, f64::max)
}
