//! The C ABI of nbrdf (`libnbrdf.a`, `libnbrdf.so`, header `include/nbrdf.h`): load a BRDF, prepare
//! it at a surface point, evaluate and importance-sample it, from C, C++ or anything with a C FFI.
//!
//! Every function returns an [`NbrdfStatus`]; on failure [`nbrdf_last_error`] gives the message of this
//! thread's last error. Null or misaligned pointers, short buffers and wrong lengths are errors, never
//! undefined behaviour, and no panic crosses the boundary (a panic would be a bug in nbrdf; it becomes
//! `NBRDF_STATUS_PANIC`). A loaded BRDF is immutable: one handle may be used from many threads at
//! once. The conventions (frame, `wi`/`wo`, units) are in the header's preamble (`cbindgen.toml`).

mod args;
mod error;
mod handle;
mod shade;
#[cfg(test)]
mod tests;

pub use error::{nbrdf_last_error, NbrdfStatus};
pub use handle::*;
pub use shade::*;

use std::ffi::c_char;

/// The library version, `"MAJOR.MINOR.PATCH"`: a static string, never freed. Thread safe.
#[no_mangle]
pub extern "C" fn nbrdf_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// The kernel level the dense layers run at on this CPU (`"avx512"`, `"avx2"`, `"neon"` or
/// `"portable"`; `NBRDF_KERNEL` lowers it): a static string. Thread safe.
#[no_mangle]
pub extern "C" fn nbrdf_kernel_level() -> *const c_char {
    match nbrdf_core::kernels::level() {
        nbrdf_core::kernels::Level::Portable => c"portable".as_ptr(),
        nbrdf_core::kernels::Level::Neon => c"neon".as_ptr(),
        nbrdf_core::kernels::Level::Avx2 => c"avx2".as_ptr(),
        nbrdf_core::kernels::Level::Avx512 => c"avx512".as_ptr(),
    }
}
