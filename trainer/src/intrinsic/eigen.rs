//! The smallest eigenpairs of the generalised problem L φ = λ M φ, L the cotangent stiffness and M the
//! lumped mass matrix (see [`laplacian`](super::laplacian)).
//!
//! Method (the standard one for mesh spectra, e.g. ARPACK's mode 3 as used by Koestler et al. through
//! `scipy.sparse.linalg.eigsh(L, k, M, sigma=0)`): with M diagonal, substitute ψ = M^{1/2} φ to get the
//! symmetric standard problem `M^{-1/2} L M^{-1/2} ψ = λ ψ`, then invert it with a shift:
//!
//! `B = M^{1/2} (L + s M)^{-1} M^{1/2}`, `B ψ = μ ψ` with `μ = 1 / (λ + s)`.
//!
//! L + sM is symmetric positive definite for any s > 0 even though L is singular (constants are in its
//! null space), so it has a sparse Cholesky factor (faer, AMD ordering), computed once. The smallest λ
//! become the largest, well separated μ, which faer's Krylov–Schur method (thick-restart Lanczos with
//! full reorthogonalisation) finds in few iterations. The ψ come out orthonormal, hence the φ are
//! M-orthonormal. Everything runs sequentially from a fixed start vector, so results are bitwise
//! reproducible on one machine.
//!
//! Small problems, where a Krylov space of the needed size would span the whole space, are solved
//! densely instead (faer's symmetric eigendecomposition of `M^{-1/2} L M^{-1/2}`).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::Solve;
use faer::matrix_free::eigen::{partial_self_adjoint_eigen, partial_self_adjoint_eigen_scratch, PartialEigenParams};
use faer::matrix_free::LinOp;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Col, Mat, MatMut, MatRef, Par, Side};

use super::laplacian::CotanLaplacian;
use super::Error;

/// Problems with at most this many vertices are solved densely: an O(n³) eigendecomposition of a
/// 500 × 500 matrix takes well under a second and needs no convergence control.
pub const DENSE_MAX_VERTICES: usize = 500;

/// The shift is this fraction of `8π / area`. Why: by Hersch's inequality the first nonzero eigenvalue
/// of a genus-0 surface of area A is at most 8π/A (with equality for the round sphere), so the shift sits
/// about two orders of magnitude below the spectrum we want on compact shapes. Any s > 0 keeps L + sM
/// positive definite; a smaller s would only make the constant mode dominate ‖B‖ = 1/s and so raise the
/// absolute convergence threshold for everything else.
pub const SHIFT_FRACTION: f64 = 1e-2;

/// Convergence threshold of a Ritz pair of B: residual ‖Bψ − μψ‖ ≤ `LANCZOS_TOLERANCE` · ‖B‖. Why: the
/// attainable floor is about ε·‖B‖ ≈ 2e-16·‖B‖; 1e-12 leaves room above it while giving eigenvectors
/// far more accurate than the `f32` table they end up in.
pub const LANCZOS_TOLERANCE: f64 = 1e-12;

/// Restarts before the solver gives up and reports [`Error::NotConverged`].
pub const MAX_RESTARTS: usize = 1000;

/// Seed of the start vector of the Lanczos iteration; fixed so that results are reproducible.
pub const START_SEED: u64 = 0x6e62_7264_665f_6569; // "nbrdf_ei"

/// How the eigenpairs were computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Dense symmetric eigendecomposition (small meshes).
    Dense,
    /// Shift-invert Krylov–Schur with the shift `s` (the factorised matrix is L + sM).
    ShiftInvertLanczos {
        /// The shift s > 0.
        shift: f64,
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
    /// Dense up to [`DENSE_MAX_VERTICES`] (or when the Krylov space would fill the whole space),
    /// shift-invert Lanczos above.
    Auto,
    /// Always dense: O(n³) time and O(n²) memory, meant for tests and small meshes.
    Dense,
    /// Shift-invert Lanczos; falls back to dense when the Krylov space would fill the whole space
    /// (faer's Krylov–Schur needs it strictly smaller than n).
    ShiftInvertLanczos,
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
    let (min_dim, max_dim) = krylov_dims(count);
    let use_dense = match solver {
        Solver::Auto => n <= DENSE_MAX_VERTICES || max_dim >= n,
        Solver::Dense => true,
        Solver::ShiftInvertLanczos => max_dim >= n,
    };
    let (mut values, mut vectors, method) = if use_dense {
        let (values, vectors) = dense(lap, count)?;
        (values, vectors, Method::Dense)
    } else {
        let shift = SHIFT_FRACTION * 8.0 * std::f64::consts::PI / lap.mass().iter().sum::<f64>();
        let (values, vectors) = shift_invert_lanczos(lap, count, shift, min_dim, max_dim)?;
        (values, vectors, Method::ShiftInvertLanczos { shift })
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
    Ok(Eigenpairs { values, vectors, method })
}

/// Sizes of the Krylov space after a restart and before the next: enough beyond `count` that the
/// wanted pairs converge in a few restarts, as in ARPACK's default `ncv = max(2k + 1, 20)`.
fn krylov_dims(count: usize) -> (usize, usize) {
    (count + 16, 2 * count + 32)
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

/// `B = M^{1/2} (L + sM)^{-1} M^{1/2}` as a matrix-free operator for faer's Krylov–Schur solver.
#[derive(Debug)]
struct ShiftInvert {
    factor: Llt<usize, f64>,
    sqrt_mass: Vec<f64>,
}

impl LinOp<f64> for ShiftInvert {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }

    fn nrows(&self) -> usize {
        self.sqrt_mass.len()
    }

    fn ncols(&self) -> usize {
        self.sqrt_mass.len()
    }

    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, _stack: &mut MemStack) {
        let mut out = out;
        for j in 0..rhs.ncols() {
            for (i, &m) in self.sqrt_mass.iter().enumerate() {
                out[(i, j)] = rhs[(i, j)] * m;
            }
        }
        self.factor.solve_in_place(out.as_mut());
        for j in 0..out.ncols() {
            for (i, &m) in self.sqrt_mass.iter().enumerate() {
                out[(i, j)] *= m;
            }
        }
    }

    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, stack: &mut MemStack) {
        // Real operator: conjugation is the identity.
        self.apply(out, rhs, par, stack)
    }
}

fn shift_invert_lanczos(
    lap: &CotanLaplacian,
    count: usize,
    shift: f64,
    min_dim: usize,
    max_dim: usize,
) -> Result<(Vec<f64>, Mat<f64>), Error> {
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
    let op = ShiftInvert { factor, sqrt_mass: mass.iter().map(|m| m.sqrt()).collect() };

    let v0 = start_vector(n);
    let params = PartialEigenParams { min_dim, max_dim, max_restarts: MAX_RESTARTS, ..Default::default() };
    let mut psi = Mat::<f64>::zeros(n, count);
    let mut mu = vec![0.0f64; count];
    let par = Par::Seq;
    let mut mem = MemBuffer::new(partial_self_adjoint_eigen_scratch(&op, count, par, params));
    let info = partial_self_adjoint_eigen(
        psi.as_mut(),
        &mut mu,
        &op,
        v0.as_ref(),
        LANCZOS_TOLERANCE / shift,
        par,
        MemStack::new(&mut mem),
        params,
    );
    if info.n_converged_eigen < count {
        return Err(Error::NotConverged {
            wanted: count,
            converged: info.n_converged_eigen,
            detail: format!("shift-invert Lanczos after {MAX_RESTARTS} restarts"),
        });
    }
    // Largest μ first is smallest λ first; μ > 0 because B is positive definite.
    let values = mu.iter().map(|&m| 1.0 / m - shift).collect();
    let vectors = Mat::from_fn(n, count, |i, j| psi[(i, j)] / op.sqrt_mass[i]);
    Ok((values, vectors))
}

/// A fixed pseudo-random start vector in [-1, 1)ⁿ from SplitMix64 (Steele, Lea & Flood 2014). Written
/// out because six lines give a platform-independent sequence without a `rand` dependency whose
/// streams may change between versions. Random rather than constant so that it is not orthogonal to
/// any eigenvector by symmetry (a constant start would miss every non-constant eigenfunction).
fn start_vector(n: usize) -> Col<f64> {
    let mut state = START_SEED;
    Col::from_fn(n, |_| {
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
