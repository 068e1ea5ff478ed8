//! Passes the target triple to the tests, which compile C and C++ programs against the library.

fn main() {
    for var in ["TARGET", "HOST"] {
        println!("cargo:rustc-env=NBRDF_CAPI_{var}={}", std::env::var(var).unwrap_or_default());
    }
}
