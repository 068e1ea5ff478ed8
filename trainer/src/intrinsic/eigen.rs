//! The smallest eigenpairs of the generalised problem L φ = λ M φ, L the cotangent stiffness and M the
//! lumped mass matrix (see [`laplacian`](super::laplacian)).
//!
//! Method: shift-invert **block** subspace iteration with Rayleigh–Ritz projection (Bathe & Wilson 1972,
//! "Large eigenvalue problems in dynamic analysis"; Bathe, *Finite Element Procedures*, Sec. 11.6).
//! With K = L + sM, s > 0 (the shift σ = −s of the usual "L − σM" notation), K is symmetric positive
//! definite although L is singular (constants are in its null space), so faer factors it once with a
//! sparse Cholesky (AMD ordering). Each iteration
//!
//! 1. applies the inverse to the whole block: `Y = (K⁻¹ M)^m X` (p right-hand sides at once,
//!    m = [`SOLVES_PER_PROJECTION`]),
//! 2. projects the pencil onto span(Y): `K_r = Yᵀ K Y`, `M_r = Yᵀ M Y`,
//! 3. solves the small p × p problem `K_r Z = M_r Z Θ` densely and sets `X = Y Z`, M-orthonormal,
//!
//! until the residuals `‖L x_j − λ_j M x_j‖_{M⁻¹}` of the wanted pairs are small. Pair j converges like
//! `((λ_j + s) / (λ_{p+1} + s))^(m·iterations)`; with p ≈ 2·count + 16 the ratio is about 1/2.
//!
//! Why a block method and not single-vector (shift-invert) Lanczos: on a symmetric mesh (the icosphere of
//! the tests; any mirror-symmetric scan) eigenvalues are *exactly* multiple, and a single Krylov sequence
//! sees one vector per eigenspace, finding the others only through rounding errors. faer's Krylov–Schur
//! (`partial_self_adjoint_eigen`, tried first) indeed skipped part of the 9-fold l = 4 cluster of the
//! sphere and returned a duplicated vector. A block of size p finds every multiplicity below p. LOBPCG
//! would need fewer iterations but is numerically delicate; with the factor at hand this costs seconds.
//!
//! Small problems are solved densely instead (faer's symmetric eigendecomposition of `M^{-1/2} L M^{-1/2}`).
//! Everything runs sequentially from a fixed pseudo-random start block, so results are bitwise
//! reproducible on one machine.

use faer::linalg::solvers::Solve;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, MatMut, Par, Side};

use super::laplacian::CotanLaplacian;
use super::Error;

/// Problems with at most this many vertices are solved densely: an O(n³) eigendecomposition of a
/// 500 × 500 matrix takes well under a second and needs no convergence control.
pub const DENSE_MAX_VERTICES: usize = 500;

/// The shift is this fraction of `8π / area`. Why: by Hersch's inequality the first nonzero eigenvalue
/// of a genus-0 surface of area A is at most 8π/A (with equality for the round sphere), so the shift sits
/// about two orders of magnitude below the spectrum we want on compact shapes, where it barely slows
/// convergence (the rate depends on `λ + s`). Any s > 0 keeps K = L + sM positive definite.
pub const SHIFT_FRACTION: f64 = 1e-2;

/// A pair has converged when `‖L x − λ M x‖_{M⁻¹} ≤ TOLERANCE · (λ_max_wanted + s)` with x M-unit.
/// Why this value: the residual is formed with the exact sparse K, so its floor is about
/// ε·‖K‖ ≈ 2e-16·λ_max(mesh), a few 1e-13 of the wanted eigenvalues even on the finest meshes here;
/// 1e-10 stays clear of it while making the eigenvectors far more accurate than their `f32` table.
pub const TOLERANCE: f64 = 1e-10;

/// Applications of K⁻¹M between two Rayleigh–Ritz projections. Why 2: on large meshes the dense
/// n × p × p products of the projection cost several times the sparse triangular solves, so squaring
/// the convergence factor per projection (≈ 0.45 → 0.2) for one more solve halves the total time. The
/// block stays well conditioned because its columns are already Ritz vectors, which K⁻¹M maps to
/// nearly M-orthogonal vectors.
pub const SOLVES_PER_PROJECTION: usize = 2;

/// Iterations before the solver gives up and reports [`Error::NotConverged`]; typical runs need 20–40.
pub const MAX_ITERATIONS: usize = 500;

/// Seed of the start block; fixed so that results are reproducible.
pub const START_SEED: u64 = 0x6e62_7264_665f_6569; // "nbrdf_ei"

/// How the eigenpairs were computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Dense symmetric eigendecomposition (small meshes).
    Dense,
    /// Shift-invert block subspace iteration; the factorised matrix is L + sM.
    ShiftInvertSubspace {
        /// The shift s > 0.
        shift: f64,
        /// Block size p.
        block: usize,
        /// Iterations until convergence.
        iterations: usize,
    },
}

/// The `count` smallest eigenpairs, ascending.
#[derive(Debug, Clone)]
pub struct Eigenpairs {
    /// Eigenvalues λ, ascending; each the Rayleigh quotient φᵀLφ / φᵀMφ of its vector.
    pub values: Vec<f64>,
    /// Eigenvectors φ as columns (active vertices × count), M-orthonormal. Sign convention: the entry of
    /// largest magnitude (first one on ties) is positive.
    pub vectors: Mat<f64>,
    /// How they were computed.
    pub method: Method,
}

/// Which solver [`smallest_eigenpairs_with`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// Dense up to [`DENSE_MAX_VERTICES`] (or when the block would fill the whole space), shift-invert
    /// subspace iteration above.
    Auto,
    /// Always dense: O(n³) time and O(n²) memory, meant for tests and small meshes.
    Dense,
    /// Shift-invert subspace iteration; falls back to dense when the block would fill the whole space.
    ShiftInvertSubspace,
}

/// Computes the `count` smallest eigenpairs of L φ = λ M φ with [`Solver::Auto`]. `count` must be in
/// `1..=lap.len()`.
pub fn smallest_eigenpairs(lap: &CotanLaplacian, count: usize) -> Result<Eigenpairs, Error> {
    smallest_eigenpairs_with(lap, count, Solver::Auto)
}

/// [`smallest_eigenpairs`] with a chosen solver.
pub fn smallest_eigenpairs_with(lap: &CotanLaplacian, count: usize, solver: Solver) -> Result<Eigenpairs, Error> {
    let n = lap.len();
    if count == 0 || count > n {
        return Err(Error::InvalidK { k: count.saturating_sub(1), max: n.saturating_sub(1) });
    }
    if lap.mass().iter().any(|&m| !(m > 0.0 && m.is_finite())) {
        // Cannot happen for an assembled valid mesh; guards the square roots below.
        return Err(Error::Factorization { reason: "mass matrix has a non-positive or non-finite entry".into() });
    }
    let block = block_size(count);
    let use_dense = match solver {
        Solver::Auto => n <= DENSE_MAX_VERTICES || block >= n,
        Solver::Dense => true,
        Solver::ShiftInvertSubspace => block >= n,
    };
    let (mut values, mut vectors, method) = if use_dense {
        let (values, vectors) = dense(lap, count)?;
        (values, vectors, Method::Dense)
    } else {
        let shift = SHIFT_FRACTION * 8.0 * std::f64::consts::PI / lap.mass().iter().sum::<f64>();
        let (values, vectors, iterations) = subspace_iteration(lap, count, shift, block)?;
        (values, vectors, Method::ShiftInvertSubspace { shift, block, iterations })
    };
    normalize_signs(vectors.as_mut());
    // Rayleigh quotients: more accurate than 1/μ − s, and the same formula for both methods.
    let mut lx = vec![0.0; n];
    for (j, value) in values.iter_mut().enumerate() {
        let x: Vec<f64> = (0..n).map(|i| vectors[(i, j)]).collect();
        lap.apply_stiffness(&x, &mut lx);
        let num: f64 = x.iter().zip(&lx).map(|(a, b)| a * b).sum();
        let den: f64 = x.iter().zip(lap.mass()).map(|(a, m)| a * a * m).sum();
        *value = num / den;
    }
    // The Rayleigh quotients may reorder members of a (numerically) multiple eigenvalue by an ulp;
    // re-sort so that `values` is ascending as promised.
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let values = order.iter().map(|&j| values[j]).collect();
    let vectors = Mat::from_fn(n, count, |i, j| vectors[(i, order[j])]);
    Ok(Eigenpairs { values, vectors, method })
}

/// Block size p: about twice the wanted count, as ARPACK's default `ncv = max(2k + 1, 20)`, so that
/// `λ_count / λ_{p+1} ≈ 1/2` by Weyl's law (λ_j grows linearly with j on a surface); the extra 16
/// covers a multiplet that straddles `count` on small k.
fn block_size(count: usize) -> usize {
    2 * count + 16
}

/// Dense path: eigendecomposition of the symmetric `M^{-1/2} L M^{-1/2}`.
fn dense(lap: &CotanLaplacian, count: usize) -> Result<(Vec<f64>, Mat<f64>), Error> {
    let n = lap.len();
    let inv_sqrt: Vec<f64> = lap.mass().iter().map(|m| 1.0 / m.sqrt()).collect();
    let mut c = Mat::<f64>::zeros(n, n);
    for &(row, col, value) in lap.stiffness_entries() {
        let (r, k) = (row as usize, col as usize);
        c[(r, k)] = value * inv_sqrt[r] * inv_sqrt[k];
    }
    let evd = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| Error::NotConverged { wanted: count, converged: 0, detail: format!("dense eigendecomposition: {e:?}") })?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| s[a].total_cmp(&s[b]));
    let order = &order[..count];
    let values = order.iter().map(|&j| s[j]).collect();
    let vectors = Mat::from_fn(n, count, |i, j| u[(i, order[j])] * inv_sqrt[i]);
    Ok((values, vectors))
}

fn subspace_iteration(
    lap: &CotanLaplacian,
    count: usize,
    shift: f64,
    p: usize,
) -> Result<(Vec<f64>, Mat<f64>, usize), Error> {
    let n = lap.len();
    let mass = lap.mass();
    let mut triplets: Vec<Triplet<usize, usize, f64>> = lap
        .stiffness_entries()
        .iter()
        .map(|&(r, c, v)| Triplet::new(r as usize, c as usize, v))
        .collect();
    triplets.extend(mass.iter().enumerate().map(|(i, &m)| Triplet::new(i, i, shift * m)));
    let k = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets)
        .map_err(|e| Error::Factorization { reason: format!("building L + sM: {e:?}") })?;
    let factor = k
        .sp_cholesky(Side::Lower)
        .map_err(|e| Error::Factorization { reason: format!("Cholesky of L + sM (s = {shift:e}): {e:?}") })?;
    // K y for the first `cols` columns of a block, from the stored entries: exact, unlike the identity
    // K K⁻¹ = I through the factor.
    let apply_k = |y: &Mat<f64>, cols: usize| {
        let mut out = Mat::<f64>::zeros(n, cols);
        for j in 0..cols {
            let (src, dst) = (y.col_as_slice(j), out.col_as_slice_mut(j));
            for i in 0..n {
                dst[i] = shift * mass[i] * src[i];
            }
            for &(row, col, value) in lap.stiffness_entries() {
                dst[row as usize] += value * src[col as usize];
            }
        }
        out
    };
    let scale_rows = |y: &Mat<f64>, cols: usize| {
        let mut out = Mat::<f64>::zeros(n, cols);
        for j in 0..cols {
            for ((d, s), m) in out.col_as_slice_mut(j).iter_mut().zip(y.col_as_slice(j)).zip(mass) {
                *d = m * s;
            }
        }
        out
    };

    let mut x = start_block(n, p);
    let mut worst = f64::INFINITY;
    for iteration in 1..=MAX_ITERATIONS {
        let mut y = scale_rows(&x, p);
        factor.solve_in_place(y.as_mut());
        for _ in 1..SOLVES_PER_PROJECTION {
            y = scale_rows(&y, p);
            factor.solve_in_place(y.as_mut());
        }
        // Unit M-norm columns keep M_r close to the identity: the raw columns differ in size by the
        // ratio of their eigenvalues (up to 1/s for the constant), which would cost digits in its
        // Cholesky factor.
        for j in 0..p {
            let col = y.col_as_slice_mut(j);
            let norm = col.iter().zip(mass).map(|(v, m)| m * v * v).sum::<f64>().sqrt();
            if !(norm > 0.0 && norm.is_finite()) {
                return Err(Error::NotConverged {
                    wanted: count,
                    converged: 0,
                    detail: format!("subspace iteration: block column {j} vanished or overflowed"),
                });
            }
            col.iter_mut().for_each(|v| *v /= norm);
        }
        let ky = apply_k(&y, p);
        let my = scale_rows(&y, p);
        let kr = symmetric_part(y.transpose() * &ky);
        let mr = symmetric_part(y.transpose() * &my);
        let (theta, z) = projected_pencil(kr, mr).map_err(|detail| Error::NotConverged { wanted: count, converged: 0, detail })?;
        x = &y * &z;
        // Residuals K x − θ M x = L x − λ M x of the wanted Ritz pairs. The sparse products cost
        // O(nnz · count), less than reusing K Y through another dense n × p × p product.
        let kx = apply_k(&x, count);
        let scale = theta[count - 1];
        worst = (0..count)
            .map(|j| {
                let (kx, x) = (kx.col_as_slice(j), x.col_as_slice(j));
                let r2: f64 = (0..n).map(|i| (kx[i] - theta[j] * mass[i] * x[i]).powi(2) / mass[i]).sum();
                r2.sqrt() / scale
            })
            .fold(0.0, f64::max);
        if worst <= TOLERANCE {
            let values = theta[..count].iter().map(|t| t - shift).collect();
            let vectors = Mat::from_fn(n, count, |i, j| x[(i, j)]);
            return Ok((values, vectors, iteration));
        }
        if !worst.is_finite() {
            break;
        }
    }
    Err(Error::NotConverged {
        wanted: count,
        converged: 0,
        detail: format!("subspace iteration: relative residual {worst:e} after {MAX_ITERATIONS} iterations"),
    })
}

fn symmetric_part(a: Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| 0.5 * (a[(i, j)] + a[(j, i)]))
}

/// Solves the small pencil `K_r Z = M_r Z Θ` through `M_r = C Cᵀ`: the eigenvectors W of the symmetric
/// `C⁻¹ K_r C⁻ᵀ` give `Z = C⁻ᵀ W`, hence `Zᵀ M_r Z = I` (M-orthonormal Ritz vectors). Θ ascending.
fn projected_pencil(kr: Mat<f64>, mr: Mat<f64>) -> Result<(Vec<f64>, Mat<f64>), String> {
    let llt = mr.llt(Side::Lower).map_err(|e| format!("projected mass matrix not positive definite: {e:?}"))?;
    let c = llt.L();
    let mut t = kr;
    solve_lower_triangular_in_place(c, t.as_mut(), Par::Seq);
    let mut a = t.transpose().to_owned();
    solve_lower_triangular_in_place(c, a.as_mut(), Par::Seq);
    let a = symmetric_part(a);
    let evd = a.self_adjoint_eigen(Side::Lower).map_err(|e| format!("projected eigenproblem: {e:?}"))?;
    let s = evd.S().column_vector();
    let mut order: Vec<usize> = (0..s.nrows()).collect();
    order.sort_by(|&i, &j| s[i].total_cmp(&s[j]));
    let theta = order.iter().map(|&j| s[j]).collect();
    let mut z = Mat::from_fn(a.nrows(), a.ncols(), |i, j| evd.U()[(i, order[j])]);
    solve_upper_triangular_in_place(c.transpose(), z.as_mut(), Par::Seq);
    Ok((theta, z))
}

/// A fixed pseudo-random start block in [-1, 1)^{n×p} from SplitMix64 (Steele, Lea & Flood 2014).
/// Written out because six lines give a platform-independent sequence without a `rand` dependency whose
/// streams may change between versions. Random rather than structured so that no column is orthogonal
/// to a wanted eigenvector by symmetry.
fn start_block(n: usize, p: usize) -> Mat<f64> {
    let mut state = START_SEED;
    Mat::from_fn(n, p, |_, _| {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    })
}

/// Eigenvectors are defined up to sign; fix it so that equal inputs give equal tables everywhere.
fn normalize_signs(mut vectors: MatMut<'_, f64>) {
    for j in 0..vectors.ncols() {
        let mut best = 0usize;
        for i in 0..vectors.nrows() {
            if vectors[(i, j)].abs() > vectors[(best, j)].abs() {
                best = i;
            }
        }
        if vectors[(best, j)] < 0.0 {
            for i in 0..vectors.nrows() {
                vectors[(i, j)] = -vectors[(i, j)];
            }
        }
    }
}
