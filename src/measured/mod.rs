//! Measured materials: the ground-truth BRDFs the semi-synthetic dataset is rendered with (Sec. 5.1).
//!
//! - [`MerlTable`]: the tabulated isotropic BRDFs of the MERL database (Matusik et al. 2003, "A
//!   data-driven reflectance model"), read from and written to their `.binary` files, looked up nearest
//!   (the reference `BRDFRead.cpp`) or trilinearly. Tables can also be made from any function, which is
//!   how the dataset tooling turns an analytic material into a MERL file.
//! - [`NbrdfNetwork`]: the compact neural fits of the MERL materials published by Sztrajman et al. 2021
//!   ("Neural BRDF representation and importance sampling") in the NBRDF-json format of
//!   `../shared/data/README.md`; the stand-in for the 33 MB MERL tables.
//!
//! Both need the `alloc` feature (they own their data); reading and writing files needs `std`. Evaluation
//! itself never allocates and, like every BRDF of the crate, returns 0 for directions below the horizon and
//! for degenerate or non-finite input.
//!
//! ```
//! use nbrdf::measured::MerlTable;
//! use nbrdf::Vec3;
//! // A Lambertian material with albedo 0.5, tabulated and looked up again.
//! let table = MerlTable::tabulate(|_, _| [0.5 / core::f32::consts::PI; 3]);
//! let f = table.eval(Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::Z);
//! assert!((f[1] - 0.5 / core::f32::consts::PI).abs() < 1e-6);
//! assert_eq!(table.eval(Vec3::new(0.0, 0.0, -1.0), Vec3::Z), [0.0; 3]); // below the horizon
//! ```

pub mod merl;
pub mod nbrdf_json;

pub use merl::{Lookup, MerlTable};
pub use nbrdf_json::{Activation, NbrdfNetwork};

/// Writes `bytes` to `path` atomically: a temporary file in the same directory (so the rename cannot
/// cross file systems), flushed to disk, then renamed over `path`. On any failure the temporary file is
/// removed and `path` is left as it was.
#[cfg(feature = "std")]
pub(crate) fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> Result<(), crate::Error> {
    use std::io::Write;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    let io = |e: std::io::Error| crate::Error::io(path, &e);
    let mut builder = tempfile::Builder::new();
    builder.prefix(".nbrdf-tmp-");
    // tempfile's default mode is 0600; a data file gets the usual 0666 minus the umask instead.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut tmp = builder.tempfile_in(dir).map_err(io)?;
    tmp.write_all(bytes).map_err(io)?;
    tmp.as_file().sync_all().map_err(io)?;
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}
