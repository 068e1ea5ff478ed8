//! The smallest eigenpairs of the generalised problem L φ = λ M φ, L the cotangent stiffness and M the
//! lumped mass matrix (see [`laplacian`](super::laplacian)), with L's null space deflated.
//!
//! Null space: L φ = 0 exactly for the functions constant on each connected component, so a mesh with
//! c components (a scan with a few loose islands, say) has the eigenvalue 0 c times, with an arbitrary,
//! rounding-dependent basis. Both solvers therefore work on the M-orthogonal complement of those
//! functions (known in closed form from the component labels) and return the smallest *non-zero*
//! eigenvalues: no eigenfunction carries a per-component constant.
//!
//! Method: shift-invert **block Lanczos** with full reorthogonalisation in the M inner product. With
//! K = L + sM, s > 0 (the shift σ = −s of the usual "L − σM" notation), K is symmetric positive definite
//! although L is singular (constants are in its null space), so faer factors it once with a sparse
//! Cholesky (AMD ordering). The operator `A = K⁻¹M` is self-adjoint in the M inner product with
//! eigenvalues `θ = 1/(λ + s)`: the smallest λ become the largest, well separated θ. The block Krylov
//! space `span{V₀, AV₀, A²V₀, …}` is built [`BLOCK`] columns at a time, every new block M-orthogonalised
//! twice against all previous ones ("twice is enough", Giraud et al. 2005) and M-orthonormalised
//! within itself (SVQB, Stathopoulos & Wu 2002, which also drops directions the space already holds).
//! The coefficients of the first pass are exactly the projected matrix `T = Vᵀ M A V`; Rayleigh–Ritz on
//! T gives the approximations, accepted once every wanted pair has a small residual
//! `‖L x − λ M x‖_{M⁻¹}` computed with the exact sparse L.
//!
//! Why a block and not single-vector Lanczos: on a symmetric mesh (the icosphere of the tests; any mesh
//! with a non-abelian symmetry group) eigenvalues are *exactly* multiple, and a single Krylov sequence
//! sees one vector per eigenspace, finding the others only through rounding errors. faer's Krylov–Schur
//! (`partial_self_adjoint_eigen`, tried first) indeed skipped part of the 9-fold l = 4 cluster of the
//! sphere and returned a duplicated vector. A block of b columns captures multiplicities up to b.
//! Why not restarted: the basis needed here (≈ 4–5 × the wanted count, measured) fits in memory on
//! every mesh of the data set, and without restarts there is nothing to tune. (Block subspace
//! iteration with Rayleigh–Ritz, tried second, is simpler but needed ~15× more triangular solves:
//! 57 s instead of 18 s for the bunny on the shared build machine.)
//!
//! Small problems are solved densely instead (faer's symmetric eigendecomposition of `M^{-1/2} L M^{-1/2}`,
//! its null space moved to the top of the spectrum by Hotelling deflation).
//! Everything runs sequentially from a fixed pseudo-random start block, so results are bitwise
//! reproducible on one machine.

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};

use super::laplacian::CotanLaplacian;
use super::Error;

/// Problems with at most this many vertices are solved densely: an O(n³) eigendecomposition of a
/// 500 × 500 matrix takes well under a second and needs no convergence control.
pub const DENSE_MAX_VERTICES: usize = 500;

/// Memory the solver may take for its dense arrays (the dense matrix, or the Krylov basis and the
/// projected matrix) before it refuses with [`Error::TooLarge`] instead of aborting on allocation.
/// Why 4 GiB: a quarter of a small workstation; k = 64 on the 35k-vertex bunny needs about 100 MiB.
pub const MAX_SOLVER_BYTES: usize = 4 << 30;

/// The shift is this fraction of `8π / area`. Why: by Hersch's inequality the first nonzero eigenvalue
/// of a genus-0 surface of area A is at most 8π/A (with equality for the round sphere), so the shift sits
/// about two orders of magnitude below the spectrum we want on compact shapes, where it barely slows
/// convergence (the rate depends on `λ + s`). Any s > 0 keeps K = L + sM positive definite.
pub const SHIFT_FRACTION: f64 = 1e-2;

/// A pair has converged when `‖L x − λ M x‖_{M⁻¹} ≤ TOLERANCE · (λ_max_wanted + s)` with x M-unit
/// (or, on an ill-conditioned mesh, when it is within [`FLOOR_SAFETY`] of the rounding floor).
/// Why this value: the residual is scale-free (L does not change when the mesh is scaled by α, M and x
/// scale by α² and 1/α, λ by 1/α²), so no mass normalisation is needed; an eigenvector's error is at
/// most the residual over the relative gap to the next eigenvalue, so 1e-8 puts the error of any
/// eigenvector with a gap above 20 % at or below the 6e-8 rounding of the `f32` table it is stored in,
/// and within a near-multiple cluster only mixes members of the cluster, which span the same space.
/// (It also admits the 3.65e-9 at which a scanned mesh stopped under the former 1e-10.)
pub const TOLERANCE: f64 = 1e-8;

/// A pair has also converged when its residual is at most this multiple of the rounding floor
/// `ε (‖C‖ + s)`, C = M^{-1/2} L M^{-1/2} (‖C‖ bounded by Gershgorin,
/// [`CotanLaplacian::norm_bound`]): the backward error of the solves with the factor of L + sM, below
/// which no Krylov method can push the residual. Why it matters: a sliver of height h·len gives
/// cotangents ~1/h at vertices of mass ~h·len², so ‖C‖ grows like 1/h²; a scan with slivers of
/// h = 1e-4 (of their edge) has a floor of ~3e-7 of λ_k, and the residual stagnates at ~25 × that.
/// The pairs are nonetheless accurate: there they agree with the dense solver's to 1e-12 (eigenvalues)
/// and 1e-15 (subspaces), since the M⁻¹ norm magnifies the rounding at the slivers' tiny-mass
/// vertices rather than an error. Why 300: room above the measured 20–30 ×, while a pair that
/// Lanczos has not converged yet sits orders of magnitude higher.
pub const FLOOR_SAFETY: f64 = 300.0;

/// Block size b: the largest exact eigenvalue multiplicity found without relying on rounding. Why 8:
/// exact multiplicities come from symmetry, and the irreducible representations of the 3D point
/// groups have dimension at most 5 (icosahedral); 8 leaves room and keeps each step's solve cheap.
pub const BLOCK: usize = 8;

/// A new direction is dropped (the Krylov space already holds it) when less than this fraction of
/// its block's largest column survives the orthogonalisation: below that it is rounding noise.
pub const DEFLATION: f64 = 1e-10;

/// Largest basis before the solver gives up with [`Error::NotConverged`]; the meshes of the data set
/// need 4–5 × the wanted count for k = 64.
pub fn max_basis(count: usize) -> usize {
    6 * count + 8 * BLOCK
}

/// Seed of the start block; fixed so that results are reproducible.
pub const START_SEED: u64 = 0x6e62_7264_665f_6569; // "nbrdf_ei"

/// How the eigenpairs were computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Dense symmetric eigendecomposition (small meshes).
    Dense,
    /// Shift-invert block Lanczos; the factorised matrix is L + sM.
    ShiftInvertLanczos {
        /// The shift s > 0.
        shift: f64,
        /// Size of the final Krylov basis.
        basis: usize,
        /// Right-hand sides solved with the factor.
        solves: usize,
    },
}

/// The `count` smallest eigenpairs on the complement of the null space, ascending.
#[derive(Debug, Clone)]
pub struct Eigenpairs {
    /// Eigenvalues λ > 0, ascending; each the Rayleigh quotient φᵀLφ / φᵀMφ of its vector.
    pub values: Vec<f64>,
    /// Eigenvectors φ as columns (active vertices × count), M-orthonormal and M-orthogonal to the
    /// indicator of every connected component. Sign convention: the entry of largest magnitude (first
    /// one on ties) is positive.
    pub vectors: Mat<f64>,
    /// How they were computed.
    pub method: Method,
}

/// Which solver [`smallest_eigenpairs_with`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// Dense up to [`DENSE_MAX_VERTICES`] (or when the largest basis would fill the whole space),
    /// shift-invert block Lanczos above.
    Auto,
    /// Always dense: O(n³) time and O(n²) memory, meant for tests and small meshes.
    Dense,
    /// Shift-invert block Lanczos; falls back to dense when the largest basis would fill the whole space.
    ShiftInvertLanczos,
}

/// Computes the `count` smallest non-zero eigenpairs of L φ = λ M φ with [`Solver::Auto`]. `count` must
/// be in `1..=lap.len() − lap.components()`: a component of n_c vertices has n_c − 1 of them.
pub fn smallest_eigenpairs(lap: &CotanLaplacian, count: usize) -> Result<Eigenpairs, Error> {
    smallest_eigenpairs_with(lap, count, Solver::Auto)
}

/// [`smallest_eigenpairs`] with a chosen solver.
pub fn smallest_eigenpairs_with(lap: &CotanLaplacian, count: usize, solver: Solver) -> Result<Eigenpairs, Error> {
    let n = lap.len();
    let max = n.saturating_sub(lap.components());
    if count == 0 || count > max {
        return Err(Error::InvalidK { k: count, max });
    }
    if lap.mass().iter().any(|&m| !(m > 0.0 && m.is_finite())) {
        // Cannot happen for an assembled valid mesh; guards the square roots below.
        return Err(Error::Factorization {
            reason: "mass matrix has a non-positive or non-finite entry".into(),
        });
    }
    let too_big = max_basis(count) >= max;
    let use_dense = match solver {
        Solver::Auto => n <= DENSE_MAX_VERTICES || too_big,
        Solver::Dense => true,
        Solver::ShiftInvertLanczos => too_big,
    };
    // Dense: the matrix and its eigenvectors. Lanczos: basis n × d and projected matrix d × d.
    let d = max_basis(count).min(n);
    let bytes = if use_dense { 2 * n * n * 8 } else { (n * d + d * d) * 8 };
    if bytes > MAX_SOLVER_BYTES {
        return Err(Error::TooLarge {
            what: "eigensolver memory in bytes (k too large for this mesh)",
            found: bytes,
            max: MAX_SOLVER_BYTES,
        });
    }
    let (mut values, mut vectors, method) = if use_dense {
        let (values, vectors) = dense(lap, count, max)?;
        (values, vectors, Method::Dense)
    } else {
        let shift = SHIFT_FRACTION * 8.0 * std::f64::consts::PI / lap.mass().iter().sum::<f64>();
        let (values, vectors, basis, solves) = block_lanczos(lap, count, shift)?;
        (values, vectors, Method::ShiftInvertLanczos { shift, basis, solves })
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
    Ok(Eigenpairs {
        values,
        vectors,
        method,
    })
}

/// Dense path: eigendecomposition of the symmetric `C = M^{-1/2} L M^{-1/2}` plus `τ Σ_c u_c u_cᵀ`, u_c
/// the unit null vector `M^{1/2} 1_c / √area_c` of component c (Hotelling deflation). τ exceeds every
/// eigenvalue of C, so the null space moves to the top of the spectrum and the `count ≤ wanted_max`
/// smallest pairs are the non-zero ones.
fn dense(lap: &CotanLaplacian, count: usize, wanted_max: usize) -> Result<(Vec<f64>, Mat<f64>), Error> {
    let n = lap.len();
    let mass = lap.mass();
    let inv_sqrt: Vec<f64> = mass.iter().map(|m| 1.0 / m.sqrt()).collect();
    let mut c = Mat::<f64>::zeros(n, n);
    let mut row_sum = vec![0.0f64; n]; // Gershgorin: every eigenvalue of C is ≤ max_i Σ_j |C_ij|
    for &(row, col, value) in lap.stiffness_entries() {
        let (r, k) = (row as usize, col as usize);
        c[(r, k)] = value * inv_sqrt[r] * inv_sqrt[k];
        row_sum[r] += c[(r, k)].abs();
    }
    let tau = 2.0 * row_sum.iter().fold(0.0, |a: f64, &b| a.max(b)) + 1.0;
    let (label, area) = (lap.component(), lap.component_area());
    for j in 0..n {
        for i in 0..n {
            if label[i] == label[j] {
                c[(i, j)] += tau * (mass[i] * mass[j]).sqrt() / area[label[i] as usize];
            }
        }
    }
    let evd = c.self_adjoint_eigen(Side::Lower).map_err(|e| Error::NotConverged {
        wanted: count,
        converged: 0,
        detail: format!("dense eigendecomposition: {e:?}"),
    })?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| s[a].total_cmp(&s[b]));
    debug_assert!(count <= wanted_max);
    let order = &order[..count];
    let values = order.iter().map(|&j| s[j]).collect();
    let mut vectors = Mat::from_fn(n, count, |i, j| u[(i, order[j])] * inv_sqrt[i]);
    // Exact in exact arithmetic; removes the rounding-level constants the decomposition leaves.
    for j in 0..count {
        lap.project_out_constants(vectors.col_as_slice_mut(j));
    }
    Ok((values, vectors))
}

/// The `count` smallest eigenpairs by shift-invert block Lanczos (see the module documentation), with
/// the final basis size and the number of right-hand sides solved.
fn block_lanczos(lap: &CotanLaplacian, count: usize, shift: f64) -> Result<(Vec<f64>, Mat<f64>, usize, usize), Error> {
    let n = lap.len();
    let mass = lap.mass();
    let mut triplets: Vec<Triplet<usize, usize, f64>> = lap
        .stiffness_entries()
        .iter()
        .map(|&(r, c, v)| Triplet::new(r as usize, c as usize, v))
        .collect();
    triplets.extend(mass.iter().enumerate().map(|(i, &m)| Triplet::new(i, i, shift * m)));
    let k = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).map_err(|e| Error::Factorization {
        reason: format!("building L + sM: {e:?}"),
    })?;
    let factor = k.sp_cholesky(Side::Lower).map_err(|e| Error::Factorization {
        reason: format!("Cholesky of L + sM (s = {shift:e}): {e:?}"),
    })?;

    let d_max = max_basis(count).min(n);
    let mut v = Mat::<f64>::zeros(n, d_max);
    let mut t = Mat::<f64>::zeros(d_max, d_max);
    let mut d = append_orthonormal(&mut v, 0, start_block(n, BLOCK.min(d_max)), lap);
    let mut applied = 0usize; // leading columns of V whose image under A is in T
    let mut solves = 0usize;
    // Shift-invert Lanczos needs a basis of about 4–5 × count here; checks before 2 × count would
    // only cost time.
    let check_every = (count / 8).max(BLOCK);
    let mut next_check = 2 * count;
    let mut worst = f64::INFINITY;
    loop {
        let exhausted = applied == d; // no new direction: the basis spans an invariant subspace
        if !exhausted {
            // W = A V_new = K⁻¹ M V_new; its M-projection on the whole basis is T's new block column.
            let mut w = scale_rows(v.as_ref().subcols(applied, d - applied), mass);
            factor.solve_in_place(w.as_mut());
            solves += d - applied;
            let mw = scale_rows(w.as_ref(), mass);
            let mut c = Mat::<f64>::zeros(d, d - applied);
            matmul(
                c.as_mut(),
                Accum::Replace,
                v.as_ref().subcols(0, d).transpose(),
                mw.as_ref(),
                1.0,
                Par::Seq,
            );
            for j in 0..d - applied {
                for i in 0..d {
                    t[(i, applied + j)] = c[(i, j)];
                    if i < applied {
                        t[(applied + j, i)] = c[(i, j)];
                    }
                }
            }
            applied = d;
            if d < d_max {
                d = append_orthonormal(&mut v, d, w, lap);
            }
        }
        if applied >= count && (applied >= next_check || exhausted || d == applied) {
            match rayleigh_ritz(lap, v.as_ref().subcols(0, applied), t.as_ref(), applied, count, shift) {
                Ok((values, x)) => return Ok((values, x, applied, solves)),
                Err(residual) => worst = residual,
            }
            next_check = applied + check_every;
        }
        if exhausted || (applied == d && d == d_max) {
            return Err(Error::NotConverged {
                wanted: count,
                converged: 0,
                detail: format!(
                    "block Lanczos: relative residual {worst:e} with a basis of {applied} vectors{}",
                    if d == d_max {
                        " (largest basis reached)"
                    } else {
                        " (Krylov space exhausted)"
                    }
                ),
            });
        }
    }
}

/// The `count` Ritz pairs of largest θ from the projected `T = Vᵀ M A V` (its leading `dim` block),
/// as eigenpairs of the original problem (λ = 1/θ − s), if all have a relative residual within
/// [`TOLERANCE`] or [`FLOOR_SAFETY`] times the rounding floor; otherwise `Err` with the relative
/// residual that failed.
///
/// The wanted pair of largest λ converges last (Lanczos converges from the ends of the spectrum
/// inwards), so its residual alone is checked first: that costs one basis combination instead of
/// `count`, which matters because checks run every few blocks.
fn rayleigh_ritz(
    lap: &CotanLaplacian,
    v: MatRef<'_, f64>,
    t: MatRef<'_, f64>,
    dim: usize,
    count: usize,
    shift: f64,
) -> Result<(Vec<f64>, Mat<f64>), f64> {
    let n = lap.len();
    let tt = Mat::from_fn(dim, dim, |i, j| 0.5 * (t[(i, j)] + t[(j, i)]));
    let evd = tt.self_adjoint_eigen(Side::Lower).map_err(|_| f64::INFINITY)?;
    let theta = evd.S().column_vector();
    let mut order: Vec<usize> = (0..dim).collect();
    order.sort_by(|&a, &b| theta[b].total_cmp(&theta[a]));
    // θ ≤ 0 would be a Ritz value outside the spectrum of the positive definite A: not converged.
    let values: Vec<f64> = order[..count]
        .iter()
        .map(|&j| {
            if theta[j] > 0.0 {
                1.0 / theta[j] - shift
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let scale = values[count - 1] + shift;
    let floor = f64::EPSILON * (lap.norm_bound() + shift);
    let tolerance = TOLERANCE.max(FLOOR_SAFETY * floor / scale);
    // Relative to the largest wanted λ + s; NaN maps to infinity so the comparisons are total.
    let relative = |x: &[f64], lambda: f64| {
        let r = residual(lap, x, lambda) / scale;
        if r.is_finite() {
            r
        } else {
            f64::INFINITY
        }
    };
    let combine = |cols: &[usize]| {
        let z = Mat::from_fn(dim, cols.len(), |i, j| evd.U()[(i, cols[j])]);
        let mut x = Mat::<f64>::zeros(n, cols.len());
        matmul(x.as_mut(), Accum::Replace, v, z.as_ref(), 1.0, Par::Seq);
        x
    };
    let last = combine(&order[count - 1..count]);
    let r = relative(last.col_as_slice(0), values[count - 1]);
    if r > tolerance {
        return Err(r);
    }
    let x = combine(&order[..count]);
    let worst = (0..count)
        .map(|j| relative(x.col_as_slice(j), values[j]))
        .fold(0.0, f64::max);
    if worst <= tolerance {
        Ok((values, x))
    } else {
        Err(worst)
    }
}

/// `‖L x − λ M x‖_{M⁻¹}`: the M⁻¹ norm because the residual is a load (an integrated quantity), which
/// makes `residual / (λ ‖x‖_M)` independent of the mesh's resolution and scale.
pub fn residual(lap: &CotanLaplacian, x: &[f64], lambda: f64) -> f64 {
    let mass = lap.mass();
    let mut lx = vec![0.0; x.len()];
    lap.apply_stiffness(x, &mut lx);
    (0..x.len())
        .map(|i| (lx[i] - lambda * mass[i] * x[i]).powi(2) / mass[i])
        .sum::<f64>()
        .sqrt()
}

/// M-orthogonalises the columns of `w` against L's null space, against `v[:, ..d]` and among themselves,
/// twice, drops the directions that do not survive ([`DEFLATION`]), stores the rest in `v[:, d..]` (as
/// many as fit) and returns the new column count.
fn append_orthonormal(v: &mut Mat<f64>, d: usize, w: Mat<f64>, lap: &CotanLaplacian) -> usize {
    let mass = lap.mass();
    let mut w = w;
    let mut floor = (0..w.ncols())
        .map(|j| w.col_as_slice(j).iter().zip(mass).map(|(x, m)| m * x * x).sum::<f64>())
        .fold(0.0, f64::max)
        * DEFLATION
        * DEFLATION;
    for _pass in 0..2 {
        // The null space is A's dominant eigenspace (θ = 1/s), so rounding would let it grow back.
        for j in 0..w.ncols() {
            lap.project_out_constants(w.col_as_slice_mut(j));
        }
        if d > 0 {
            let mw = scale_rows(w.as_ref(), mass);
            let mut c = Mat::<f64>::zeros(d, w.ncols());
            matmul(
                c.as_mut(),
                Accum::Replace,
                v.as_ref().subcols(0, d).transpose(),
                mw.as_ref(),
                1.0,
                Par::Seq,
            );
            matmul(
                w.as_mut(),
                Accum::Add,
                v.as_ref().subcols(0, d),
                c.as_ref(),
                -1.0,
                Par::Seq,
            );
        }
        // SVQB: with the Gram matrix G = Wᵀ M W = U D Uᵀ, the columns of W U D^{-1/2} are M-orthonormal;
        // eigenvalues of G below the floor are directions already in the basis.
        let mw = scale_rows(w.as_ref(), mass);
        let mut g = Mat::<f64>::zeros(w.ncols(), w.ncols());
        matmul(g.as_mut(), Accum::Replace, w.transpose(), mw.as_ref(), 1.0, Par::Seq);
        let g = Mat::from_fn(g.nrows(), g.ncols(), |i, j| 0.5 * (g[(i, j)] + g[(j, i)]));
        let Ok(evd) = g.self_adjoint_eigen(Side::Lower) else {
            return d;
        };
        let s = evd.S().column_vector();
        let keep: Vec<usize> = (0..s.nrows()).filter(|&j| s[j] > floor && s[j].is_finite()).collect();
        if keep.is_empty() {
            return d;
        }
        let q = Mat::from_fn(g.nrows(), keep.len(), |i, j| evd.U()[(i, keep[j])] / s[keep[j]].sqrt());
        let mut next = Mat::<f64>::zeros(w.nrows(), keep.len());
        matmul(next.as_mut(), Accum::Replace, w.as_ref(), q.as_ref(), 1.0, Par::Seq);
        w = next;
        // After the first pass the columns are M-unit: the second pass drops only what is now noise.
        floor = DEFLATION * DEFLATION;
    }
    let cols = w.ncols().min(v.ncols() - d);
    for j in 0..cols {
        v.col_as_slice_mut(d + j).copy_from_slice(w.col_as_slice(j));
    }
    d + cols
}

/// `M y` for a block (M diagonal).
fn scale_rows(y: MatRef<'_, f64>, mass: &[f64]) -> Mat<f64> {
    Mat::from_fn(y.nrows(), y.ncols(), |i, j| mass[i] * y[(i, j)])
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
