//! The checked-in `include/nbrdf.h` is what cbindgen makes of the crate today (`NBRDF_BLESS=1`
//! rewrites it).

use std::path::Path;

#[test]
fn the_checked_in_header_is_up_to_date() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).expect("cbindgen.toml parses");
    let mut fresh = Vec::new();
    cbindgen::Builder::new()
        .with_crate(dir)
        .with_config(config)
        .generate()
        .expect("cbindgen reads the crate")
        .write(&mut fresh);
    let path = dir.join("include/nbrdf.h");
    if std::env::var_os("NBRDF_BLESS").is_some() {
        std::fs::write(&path, &fresh).unwrap();
        return;
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == fresh,
        "{} is stale: run `NBRDF_BLESS=1 cargo test -p nbrdf-capi --test header` and commit it",
        path.display()
    );
}
