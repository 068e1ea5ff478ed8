//! The OBJ and PLY mesh readers on arbitrary bytes: an error value or a mesh, never a panic. A mesh they
//! accept is valid: finite positions, unit normals (one per vertex), every index in range, and at least
//! one triangle.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nbrdf_scene::scene::Mesh;

fn check(m: &Mesh) {
    assert!(!m.triangles.is_empty());
    assert!(m.positions.iter().all(|p| p.is_finite()));
    assert_eq!(m.normals.len(), m.positions.len());
    assert!(m.normals.iter().all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-3), "normals");
    assert!(m.triangles.iter().flatten().all(|&i| (i as usize) < m.positions.len()));
}

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Mesh::from_obj_reader(&mut &data[..]) {
        check(&m);
    }
    if let Ok(m) = Mesh::from_ply_reader(&mut &data[..]) {
        check(&m);
    }
});
