//! Validation of the raw triangle mesh before any geometry is computed on it: which triangles take part
//! in the Laplace–Beltrami operator, which vertices they touch, and what was left out and why.
//!
//! The mesh comes in as plain arrays (`positions`, `triangles`) so that this module does not depend on
//! the scene loader. Input that cannot describe a surface (no triangles, non-finite coordinates, indices
//! out of range) is an error; geometry that is merely degenerate is dropped and counted, because real
//! scanned meshes contain a few zero-area triangles and unreferenced vertices and must still work.

use super::Error;

/// A triangle whose doubled area is below this fraction of its longest squared edge is degenerate.
///
/// Why this value: positions are `f32`, whose relative rounding is about 6e-8, so a triangle flatter
/// than this has a shape (and cotangents, up to ~1e8) that is rounding noise rather than geometry.
/// Dropping it changes the total area by a negligible amount, while keeping it would put weights of
/// order 1e8 into the stiffness matrix and ruin the conditioning of the factorisation.
pub const DEGENERATE_RATIO: f64 = 1e-8;

/// A triangle whose height over its longest edge is at most this many `f32` rounding units
/// (`f32::EPSILON` times its largest coordinate magnitude) is degenerate too.
///
/// Why: [`DEGENERATE_RATIO`] compares the area with the triangle's own size, but rounding moves each
/// coordinate by up to half a unit of the *coordinate's* magnitude. A vertex placed on an edge (a
/// T-junction, a zero-area triangle in exact arithmetic) ends up a few 1e-8 off it, which on an edge a
/// tenth of the coordinates' size is a ratio of ~4e-7: kept by the ratio test, it is a needle whose
/// cotangents (~1e7) make the eigenproblem as ill-conditioned as f64 allows. Four units: the most two
/// roundings of three coordinates move a point off a line, with room.
pub const DEGENERATE_ULPS: f64 = 4.0;

/// What validation found: counts the caller may want to log or assert on.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    /// Vertices in the input.
    pub n_vertices: usize,
    /// Triangles in the input.
    pub n_triangles: usize,
    /// Triangles dropped: repeated vertex indices or (near) zero area, see [`DEGENERATE_RATIO`] and
    /// [`DEGENERATE_ULPS`].
    pub degenerate_triangles: usize,
    /// Vertices referenced by no kept triangle (unreferenced, or only in degenerate triangles). They
    /// take no part in the eigenproblem and get the value 0 in every eigenfunction.
    pub isolated_vertices: usize,
    /// Connected components of the kept triangles (triangles sharing a vertex are connected). With `c`
    /// components the operator has `c` zero eigenvalues (the piecewise constant functions), all of
    /// which the eigensolver projects out.
    pub components: usize,
    /// Total area of the kept triangles, in squared mesh units.
    pub total_area: f64,
}

/// A mesh that passed validation: kept triangles in compact ("active") vertex numbering.
#[derive(Debug, Clone)]
pub struct ValidMesh {
    /// Input index of each active vertex, ascending.
    pub active: Vec<u32>,
    /// Positions of the active vertices, in `f64` for the geometry.
    pub positions: Vec<[f64; 3]>,
    /// Kept triangles, indices into `active`.
    pub triangles: Vec<[u32; 3]>,
    /// Connected component of each active vertex, labels `0..report.components`.
    pub component: Vec<u32>,
    /// What was kept and dropped.
    pub report: MeshReport,
}

/// Checks `positions` and `triangles`, drops degenerate triangles and unreferenced vertices.
pub fn validate(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<ValidMesh, Error> {
    if positions.is_empty() || triangles.is_empty() {
        return Err(Error::EmptyMesh {
            n_vertices: positions.len(),
            n_triangles: triangles.len(),
        });
    }
    // Triangle indices are u32, so a larger vertex array could not be addressed completely anyway.
    if positions.len() > u32::MAX as usize {
        return Err(Error::TooLarge {
            what: "vertex count",
            found: positions.len(),
            max: u32::MAX as usize,
        });
    }
    if let Some(vertex) = positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(Error::NonFinitePosition { vertex });
    }
    let n = positions.len();
    let mut kept = Vec::with_capacity(triangles.len());
    let mut degenerate = 0usize;
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= n) {
            return Err(Error::IndexOutOfRange {
                triangle: t,
                vertex,
                n_vertices: n,
            });
        }
        if is_degenerate(tri.map(|v| to_f64(positions[v as usize]))) || has_repeated_index(*tri) {
            degenerate += 1;
        } else {
            kept.push(*tri);
        }
    }
    if kept.is_empty() {
        return Err(Error::NoValidTriangles { degenerate });
    }

    // Compact numbering: the eigenproblem only sees vertices that some kept triangle touches, otherwise
    // the mass matrix would have zero rows and the generalised problem would be singular.
    let mut compact = vec![u32::MAX; n];
    for tri in &kept {
        for &v in tri {
            compact[v as usize] = 0;
        }
    }
    let mut active = Vec::new();
    for (v, slot) in compact.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = active.len() as u32;
            active.push(v as u32);
        }
    }
    let triangles: Vec<[u32; 3]> = kept.iter().map(|tri| tri.map(|v| compact[v as usize])).collect();
    let positions: Vec<[f64; 3]> = active.iter().map(|&v| to_f64(positions[v as usize])).collect();
    let total_area = triangles
        .iter()
        .map(|tri| 0.5 * norm(cross_edges(tri.map(|v| positions[v as usize]))))
        .sum();
    let (component, components) = label_components(active.len(), &triangles);
    let report = MeshReport {
        n_vertices: n,
        n_triangles: kept.len() + degenerate,
        degenerate_triangles: degenerate,
        isolated_vertices: n - active.len(),
        components,
        total_area,
    };
    Ok(ValidMesh {
        active,
        positions,
        triangles,
        component,
        report,
    })
}

fn has_repeated_index([a, b, c]: [u32; 3]) -> bool {
    a == b || b == c || a == c
}

fn is_degenerate(p: [[f64; 3]; 3]) -> bool {
    let longest = [sub(p[1], p[0]), sub(p[2], p[1]), sub(p[0], p[2])]
        .iter()
        .map(|e| dot(*e, *e))
        .fold(0.0, f64::max);
    // Positions are finite (checked before) and f32-sized, so nothing here overflows f64 or is NaN.
    let double_area = norm(cross_edges(p));
    let magnitude = p.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    // height = 2·area / longest edge, compared without dividing (longest may be 0).
    double_area <= DEGENERATE_RATIO * longest
        || double_area <= DEGENERATE_ULPS * f64::from(f32::EPSILON) * magnitude * longest.sqrt()
}

/// Connected component of each vertex (union–find over the kept triangles), labelled 0, 1, … in the
/// order of each component's lowest vertex index, so that the labelling is deterministic.
fn label_components(n: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, usize) {
    fn find(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let grand = parent[parent[v as usize] as usize];
            parent[v as usize] = grand;
            v = grand;
        }
        v
    }
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for tri in triangles {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2])] {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                // The smaller index becomes the root, so every root is its component's lowest vertex.
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut count = 0u32;
    for v in 0..n as u32 {
        let root = find(&mut parent, v);
        if label[root as usize] == u32::MAX {
            label[root as usize] = count;
            count += 1;
        }
        label[v as usize] = label[root as usize];
    }
    (label, count as usize)
}

pub(crate) fn to_f64(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `(p1 - p0) × (p2 - p0)`: its length is twice the triangle's area.
pub(crate) fn cross_edges(p: [[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(p[1], p[0]), sub(p[2], p[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn a_square_of_two_triangles_has_area_one_and_one_component() {
        let mesh = validate(&SQUARE, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert_eq!(mesh.report.components, 1);
        assert!((mesh.report.total_area - 1.0).abs() < 1e-15);
        assert_eq!(mesh.report.degenerate_triangles, 0);
    }

    #[test]
    fn degenerate_triangles_and_unreferenced_vertices_are_dropped_and_counted() {
        let mut positions = SQUARE.to_vec();
        positions.push([0.5, 0.0, 0.0]); // on the edge 0-1: the triangle (0, 4, 1) has zero area
        positions.push([9.0, 9.0, 9.0]); // referenced by nothing
        let mesh = validate(&positions, &[[0, 1, 2], [0, 2, 3], [0, 4, 1], [2, 2, 3]]).unwrap();
        assert_eq!(mesh.report.degenerate_triangles, 2);
        assert_eq!(mesh.report.isolated_vertices, 2);
        assert_eq!(mesh.active, vec![0, 1, 2, 3]);
    }

    #[test]
    fn a_vertex_rounded_next_to_an_edge_makes_a_degenerate_triangle() {
        // The f32 midpoint of an edge is off the edge by rounding only: zero area in exact arithmetic.
        let (a, b) = ([0.3f32, 0.7, -0.1], [0.41f32, 0.62, 0.05]);
        let mid: [f32; 3] = std::array::from_fn(|c| 0.5 * (a[c] + b[c]));
        let mesh = validate(&[a, mid, b, [0.3, 0.9, 0.0]], &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert_eq!((mesh.report.degenerate_triangles, mesh.report.isolated_vertices), (1, 1));
        // A thin but real triangle (height 1e-5, ~100 rounding units of its coordinates) is kept.
        let apex = [mid[0], mid[1], mid[2] + 1e-5];
        let thin = validate(&[a, apex, b, [0.3, 0.9, 0.0]], &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert_eq!(thin.report.degenerate_triangles, 0);
    }

    #[test]
    fn bad_input_is_an_error_value() {
        assert!(matches!(validate(&[], &[]), Err(Error::EmptyMesh { .. })));
        assert!(matches!(
            validate(&SQUARE, &[[0, 1, 7]]),
            Err(Error::IndexOutOfRange {
                triangle: 0,
                vertex: 7,
                n_vertices: 4
            })
        ));
        let mut nan = SQUARE;
        nan[2][1] = f32::NAN;
        assert!(matches!(
            validate(&nan, &[[0, 1, 2]]),
            Err(Error::NonFinitePosition { vertex: 2 })
        ));
        assert!(matches!(
            validate(&SQUARE, &[[0, 0, 1]]),
            Err(Error::NoValidTriangles { degenerate: 1 })
        ));
    }

    #[test]
    fn two_separate_triangles_are_two_components() {
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [5.0, 1.0, 0.0],
        ];
        let mesh = validate(&positions, &[[3, 4, 5], [0, 1, 2]]).unwrap();
        assert_eq!(mesh.report.components, 2);
        assert_eq!(mesh.component, vec![0, 0, 0, 1, 1, 1]);
    }
}
