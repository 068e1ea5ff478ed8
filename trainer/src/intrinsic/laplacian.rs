//! The discrete Laplace–Beltrami operator of a triangle mesh as the pair (L, M): the cotangent
//! stiffness matrix L (symmetric positive semi-definite, L·1 = 0) and the lumped mixed-Voronoi mass
//! matrix M (diagonal, positive, summing to the surface area). The eigenfunctions of the intrinsic
//! encoding solve L φ = λ M φ (Koestler et al. 2022, Sec. 3).
//!
//! Both are assembled in `f64` on a [`ValidMesh`], i.e. in compact numbering
//! without isolated vertices and degenerate triangles. The operator also keeps the mesh's connected
//! components: L's null space is exactly the functions constant on each component, which the
//! eigensolver projects out.

use super::mesh::{cross_edges, dot, norm, sub, ValidMesh};

/// The cotangent stiffness and lumped mass matrices of a validated mesh.
#[derive(Debug, Clone)]
pub struct CotanLaplacian {
    /// Nonzeros of L as `(row, col, value)`, sorted by column then row, diagonal included, no
    /// duplicates; both triangles of the symmetric matrix are stored.
    entries: Vec<(u32, u32, f64)>,
    /// Diagonal of M, one positive value per active vertex.
    mass: Vec<f64>,
    /// Connected component of each active vertex, labels `0..component_area.len()`.
    component: Vec<u32>,
    /// Σ M_ii over each component: its area.
    component_area: Vec<f64>,
}

impl CotanLaplacian {
    /// Assembles L and M.
    ///
    /// **Stiffness** (Pinkall & Polthier 1993; the P1 finite-element stiffness matrix): for the edge
    /// (i, j) with opposite angles α and β in its one or two triangles,
    /// `L_ij = -(cot α + cot β) / 2`, and `L_ii = -Σ_j L_ij`. A boundary edge has one term only, which
    /// is the natural (Neumann) boundary condition. Obtuse angles give negative cotangents; L then is
    /// no longer an M-matrix but stays positive semi-definite, since it is the Gram matrix of the hat
    /// functions' gradients. The same argument (a sum of per-triangle positive semi-definite matrices)
    /// covers non-manifold edges and inconsistent orientation, which the formula does not look at.
    ///
    /// **Mass** (Meyer, Desbrun, Schröder & Barr 2003, "Discrete Differential-Geometry Operators for
    /// Triangulated 2-Manifolds", Sec. 3.3 and Fig. 4, the mixed area A_mixed): in a non-obtuse
    /// triangle vertex P with neighbours Q, R receives its Voronoi area
    /// `(|PR|² cot∠Q + |PQ|² cot∠R) / 8`; in an obtuse triangle, where the circumcentre lies outside
    /// and the Voronoi areas would be wrong (even negative), the obtuse vertex receives half the
    /// triangle's area and the other two a quarter each. Each triangle hands out exactly its area, so
    /// `Σ M_ii` is the surface area.
    pub fn assemble(mesh: &ValidMesh) -> Self {
        let n = mesh.positions.len();
        let mut off_diagonal: Vec<(u32, u32, f64)> = Vec::with_capacity(6 * mesh.triangles.len());
        let mut diagonal = vec![0.0f64; n];
        let mut mass = vec![0.0f64; n];
        for tri in &mesh.triangles {
            let p = tri.map(|v| mesh.positions[v as usize]);
            let double_area = norm(cross_edges(p));
            let area = 0.5 * double_area;
            // Corner c sits opposite the edge (c+1, c+2). cot θ = cos θ / sin θ = (u·v) / |u×v| with
            // the same |u×v| = 2·area for all three corners.
            let mut dots = [0.0f64; 3];
            let mut cots = [0.0f64; 3];
            for c in 0..3 {
                let (a, b) = ((c + 1) % 3, (c + 2) % 3);
                dots[c] = dot(sub(p[a], p[c]), sub(p[b], p[c]));
                cots[c] = dots[c] / double_area;
            }
            for c in 0..3 {
                let (a, b) = (tri[(c + 1) % 3], tri[(c + 2) % 3]);
                let w = 0.5 * cots[c];
                off_diagonal.push((a, b, -w));
                off_diagonal.push((b, a, -w));
                diagonal[a as usize] += w;
                diagonal[b as usize] += w;
            }
            let obtuse = dots.iter().position(|&d| d < 0.0);
            for c in 0..3 {
                let (q, r) = ((c + 1) % 3, (c + 2) % 3);
                mass[tri[c] as usize] += match obtuse {
                    None => {
                        let pr = sub(p[r], p[c]);
                        let pq = sub(p[q], p[c]);
                        (dot(pr, pr) * cots[q] + dot(pq, pq) * cots[r]) / 8.0
                    }
                    Some(o) if o == c => area / 2.0,
                    Some(_) => area / 4.0,
                };
            }
        }
        let mut entries = off_diagonal;
        entries.extend(diagonal.iter().enumerate().map(|(i, &d)| (i as u32, i as u32, d)));
        entries.sort_unstable_by_key(|&(row, col, _)| (col, row));
        // Merge the contributions of the (up to two) triangles sharing an edge. The sort is unstable
        // but the addition order of two terms does not change their sum, so the result is deterministic.
        let mut merged: Vec<(u32, u32, f64)> = Vec::with_capacity(entries.len() / 2 + n);
        for (row, col, value) in entries {
            match merged.last_mut() {
                Some(last) if last.0 == row && last.1 == col => last.2 += value,
                _ => merged.push((row, col, value)),
            }
        }
        let mut component_area = vec![0.0f64; mesh.report.components];
        for (&c, &m) in mesh.component.iter().zip(&mass) {
            component_area[c as usize] += m;
        }
        Self {
            entries: merged,
            mass,
            component: mesh.component.clone(),
            component_area,
        }
    }

    /// Number of (active) vertices, the size of L and M.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether the operator is empty (never for an assembled valid mesh).
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Nonzeros of L as `(row, col, value)`, column-major, both triangles stored.
    pub fn stiffness_entries(&self) -> &[(u32, u32, f64)] {
        &self.entries
    }

    /// Diagonal of the lumped mass matrix M.
    pub fn mass(&self) -> &[f64] {
        &self.mass
    }

    /// Connected component of each vertex, labels `0..components()`.
    pub fn component(&self) -> &[u32] {
        &self.component
    }

    /// Number of connected components: the dimension of L's null space.
    pub fn components(&self) -> usize {
        self.component_area.len()
    }

    /// Area of each connected component (Σ M_ii over its vertices).
    pub fn component_area(&self) -> &[f64] {
        &self.component_area
    }

    /// Subtracts from `x` its M-weighted mean on each component: the M-orthogonal projection onto the
    /// complement of L's null space (the locally constant functions).
    pub fn project_out_constants(&self, x: &mut [f64]) {
        let mut mean = vec![0.0f64; self.component_area.len()];
        for ((&c, &m), &v) in self.component.iter().zip(&self.mass).zip(x.iter()) {
            mean[c as usize] += m * v;
        }
        mean.iter_mut().zip(&self.component_area).for_each(|(s, a)| *s /= a);
        for (v, &c) in x.iter_mut().zip(&self.component) {
            *v -= mean[c as usize];
        }
    }

    /// An upper bound on the largest eigenvalue of L φ = λ M φ, i.e. on ‖M^{-1/2} L M^{-1/2}‖₂
    /// (Gershgorin: the largest absolute row sum of that matrix). Sets the rounding floor of the
    /// eigensolver's residuals; huge on meshes with slivers.
    pub fn norm_bound(&self) -> f64 {
        let mut row = vec![0.0f64; self.mass.len()];
        for &(r, c, value) in &self.entries {
            row[r as usize] += value.abs() / (self.mass[r as usize] * self.mass[c as usize]).sqrt();
        }
        row.into_iter().fold(0.0, f64::max)
    }

    /// `y = L x`.
    pub fn apply_stiffness(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for &(row, col, value) in &self.entries {
            y[row as usize] += value * x[col as usize];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::mesh::validate;
    use super::*;

    /// A (2m+1)² grid on [-1, 1]², split into right triangles with alternating diagonals.
    fn grid(m: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let side = 2 * m + 1;
        let mut positions = Vec::new();
        for j in 0..side {
            for i in 0..side {
                positions.push([i as f32 / m as f32 - 1.0, j as f32 / m as f32 - 1.0, 0.0]);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                let v = |di: usize, dj: usize| ((j + dj) * side + i + di) as u32;
                if (i + j) % 2 == 0 {
                    triangles.push([v(0, 0), v(1, 0), v(1, 1)]);
                    triangles.push([v(0, 0), v(1, 1), v(0, 1)]);
                } else {
                    triangles.push([v(0, 0), v(1, 0), v(0, 1)]);
                    triangles.push([v(1, 0), v(1, 1), v(0, 1)]);
                }
            }
        }
        (positions, triangles)
    }

    fn laplacian(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> (ValidMesh, CotanLaplacian) {
        let mesh = validate(positions, triangles).unwrap();
        let lap = CotanLaplacian::assemble(&mesh);
        (mesh, lap)
    }

    #[test]
    fn stiffness_is_symmetric_and_annihilates_constants_and_mass_sums_to_area() {
        let (positions, triangles) = grid(4);
        let (mesh, lap) = laplacian(&positions, &triangles);
        let mut y = vec![0.0; lap.len()];
        lap.apply_stiffness(&vec![1.0; lap.len()], &mut y);
        assert!(y.iter().all(|v| v.abs() < 1e-12), "L·1 = {y:?}");
        let lookup = |r: u32, c: u32| lap.entries.iter().find(|e| e.0 == r && e.1 == c).map(|e| e.2);
        for &(r, c, v) in lap.stiffness_entries() {
            assert_eq!(lookup(c, r), Some(v));
        }
        // The grid covers [-1, 1]²: area 4, computed independently of the triangles.
        assert!((lap.mass().iter().sum::<f64>() - 4.0).abs() < 1e-12);
        assert!((mesh.report.total_area - 4.0).abs() < 1e-12);
    }

    #[test]
    fn a_linear_function_is_harmonic_at_interior_vertices() {
        // Linear precision of the cotangent formula: (L f)_i = 0 at every interior vertex for f linear.
        let (positions, triangles) = grid(3);
        let (mesh, lap) = laplacian(&positions, &triangles);
        let f: Vec<f64> = mesh.positions.iter().map(|p| 2.0 * p[0] - 3.0 * p[1] + 0.5).collect();
        let mut y = vec![0.0; lap.len()];
        lap.apply_stiffness(&f, &mut y);
        for (i, p) in mesh.positions.iter().enumerate() {
            if p[0].abs() < 1.0 - 1e-9 && p[1].abs() < 1.0 - 1e-9 {
                assert!(y[i].abs() < 1e-12, "vertex {i} at {p:?}: (Lf)_i = {}", y[i]);
            }
        }
    }

    #[test]
    fn equilateral_triangle_has_cot_60_weights_and_thirds_of_the_area() {
        let h = 3f32.sqrt() / 2.0;
        let (_, lap) = laplacian(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, h, 0.0]], &[[0, 1, 2]]);
        let cot60 = 1.0 / 3f64.sqrt();
        for &(r, c, v) in lap.stiffness_entries() {
            let expected = if r == c { cot60 } else { -cot60 / 2.0 };
            assert!((v - expected).abs() < 1e-7, "L[{r},{c}] = {v}, expected {expected}");
        }
        let area = 3f64.sqrt() / 4.0;
        for &m in lap.mass() {
            assert!((m - area / 3.0).abs() < 1e-7);
        }
    }

    #[test]
    fn obtuse_triangle_gives_half_its_area_to_the_obtuse_vertex() {
        // Angle at vertex 2 is 2·atan(2) ≈ 127°; area = 1 · 0.25 / 2 = 0.125.
        let (_, lap) = laplacian(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.25, 0.0]], &[[0, 1, 2]]);
        let m = lap.mass();
        assert!(
            (m[2] - 0.0625).abs() < 1e-12 && (m[0] - 0.03125).abs() < 1e-12 && (m[1] - 0.03125).abs() < 1e-12,
            "{m:?}"
        );
        // The edge 0-1 faces the obtuse angle: its cotangent weight is negative.
        let w01 = lap.stiffness_entries().iter().find(|e| e.0 == 0 && e.1 == 1).unwrap().2;
        assert!(w01 > 0.0, "L_01 = -cot(127°)/2 must be positive, got {w01}");
    }
}
