//! The BRDF handle: loading files and bytes, the parametric and built-in constructors, what a handle
//! reports about itself, and freeing it.

use std::ffi::{c_char, CStr};

use nbrdf_core::any::{self, AnyBrdf, Format, Kind};
use nbrdf_core::parametric::{MAX_OBJECT, MAX_RAW};

use crate::args::{bytes_of, exactly, floats_of, out_floats, parametric_kind, path_of, span};
use crate::error::{fail, guard, NbrdfStatus, Result};

/// A loaded BRDF: a `.nbrdf` model, a MERL table, an NBRDF-json network, a parametric model or a
/// built-in material (the core's [`AnyBrdf`]). Opaque; immutable once made, so one handle may be used
/// by many threads at once. Free it with [`nbrdf_free`].
pub struct NbrdfBrdf {
    /// Borrowed model bytes live as long as the handle by `nbrdf_model_borrow`'s contract.
    pub(crate) brdf: AnyBrdf<'static>,
}

/// What kind of BRDF a handle holds.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NbrdfKind {
    /// A `.nbrdf` model file (neural or parametric network).
    Model = 0,
    /// A MERL `.binary` table (nearest-bin lookup).
    Merl = 1,
    /// An NBRDF-json network (Sztrajman et al. 2021).
    NbrdfJson = 2,
    /// An analytic model with fixed parameters.
    Parametric = 3,
    /// A built-in procedural material.
    Builtin = 4,
}

/// The parametric models (the paper's Sec. 4.1.1). Functions receive it as its `int32_t` and name
/// any other value as an error (`NBRDF_STATUS_INVALID_VALUE`).
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NbrdfParametricKind {
    /// Lambert: `kd[3]`.
    Lambert = 0,
    /// The energy-preserving modified Phong "RP": `kd[3], ks[3], n` with `kd + ks <= 1`.
    Phong = 1,
    /// Torrance-Sparrow: `kd[3], ks[3], alpha`.
    TorranceSparrow = 2,
    /// The FMBRDF: `rho[3], ks, alpha, beta, eta, norm`.
    Fmbrdf = 3,
    /// Disney (Burley 2012): `base_color[3], subsurface, metallic, specular, specular_tint,
    /// roughness, sheen, sheen_tint, clearcoat, clearcoat_gloss`.
    Disney = 4,
}

/// What C passes where the header says `NbrdfParametricKind`: its `int32_t`, any value, checked on
/// use (the header names the enum; cbindgen.toml maps this name to it).
pub type NbrdfParametricKindValue = i32;

/// What [`nbrdf_info`] reports.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct NbrdfInfo {
    /// What the handle holds.
    pub kind: NbrdfKind,
    /// Whether `f(wi, wo) = f(wo, wi)` by construction (parametric models, models on the reciprocity
    /// map Θ, MERL tables).
    pub reciprocal: bool,
    /// Floats [`nbrdf_prepare`](crate::nbrdf_prepare) expects per point: 0 for a BRDF that is the
    /// same everywhere, `k` for an intrinsic encoding, 3 (the point) for an extrinsic one.
    pub position_len: u32,
    /// Stored parameters: network weights (and per-object parameters), table entries, or the model's
    /// parameters.
    pub n_parameters: u64,
}

/// Stores a new handle in `*out`.
///
/// # Safety
/// `out` is null or writable.
unsafe fn put(out: *mut *mut NbrdfBrdf, make: impl FnOnce() -> Result<AnyBrdf<'static>>) -> Result<()> {
    if out.is_null() {
        return fail(NbrdfStatus::NullPointer, "out is null");
    }
    let h = NbrdfBrdf { brdf: make()? };
    // SAFETY: non-null and writable by the caller's contract.
    unsafe { out.write(Box::into_raw(Box::new(h))) };
    Ok(())
}

/// Loads a BRDF file, chosen by extension: `.nbrdf` (a model), `.json` (an NBRDF-json network) or
/// `.binary` (a MERL table). The file is validated (sizes, checksum, finite values) and copied; it
/// can be deleted afterwards. Thread safe.
///
/// # Safety
/// `path` is a NUL-terminated string; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_load(path: *const c_char, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    guard(|| {
        let path = path_of(path)?;
        // SAFETY: the caller's contract.
        unsafe { put(out, || Ok(AnyBrdf::load(&path)?)) }
    })
}

/// A `.nbrdf` model from `len` bytes of the caller, copied (the bytes may be freed afterwards).
/// Thread safe.
///
/// # Safety
/// `bytes` addresses `len` readable bytes; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_model_from_bytes(bytes: *const u8, len: usize, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    // SAFETY: the caller's contract.
    guard(|| unsafe { put(out, || Ok(AnyBrdf::from_bytes(bytes_of(bytes, len, Format::Model.max_bytes(), "model file")?, Format::Model)?)) })
}

/// A `.nbrdf` model over `len` bytes of the caller, borrowed without a copy (embedded models,
/// memory-mapped files): `bytes` must be 4-byte aligned (`NBRDF_STATUS_MISALIGNED` otherwise) and stay
/// alive and unchanged until [`nbrdf_free`]. f16 files are evaluated row by row as they are read.
/// Thread safe.
///
/// # Safety
/// `bytes` addresses `len` readable bytes that outlive the handle; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_model_borrow(bytes: *const u8, len: usize, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller keeps the bytes alive until nbrdf_free, which drops the handle.
        let bytes: &'static [u8] = unsafe { bytes_of(bytes, len, Format::Model.max_bytes(), "model file")? };
        if !(bytes.as_ptr() as usize).is_multiple_of(4) {
            return fail(NbrdfStatus::Misaligned, "bytes must be 4-byte aligned to be borrowed (nbrdf_model_from_bytes copies instead)");
        }
        // SAFETY: the caller's contract.
        unsafe { put(out, || Ok(AnyBrdf::borrow_model(bytes)?)) }
    })
}

/// A MERL table from the `len` bytes of a `.binary` file (copied). Thread safe.
///
/// # Safety
/// `bytes` addresses `len` readable bytes; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_merl_from_bytes(bytes: *const u8, len: usize, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    // SAFETY: the caller's contract.
    guard(|| unsafe { put(out, || Ok(AnyBrdf::from_bytes(bytes_of(bytes, len, Format::Merl.max_bytes(), "MERL file")?, Format::Merl)?)) })
}

/// An NBRDF-json network from `len` bytes of JSON text (UTF-8, no NUL needed). Thread safe.
///
/// # Safety
/// `json` addresses `len` readable bytes; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_nbrdf_json_from_bytes(json: *const u8, len: usize, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    // SAFETY: the caller's contract.
    guard(|| unsafe { put(out, || Ok(AnyBrdf::from_bytes(bytes_of(json, len, Format::NbrdfJson.max_bytes(), "NBRDF-json file")?, Format::NbrdfJson)?)) })
}

/// A parametric model from its parameters in natural units, `n` floats in the order
/// [`NbrdfParametricKind`] lists (e.g. Phong: `kd[3], ks[3], n`). Errors on a wrong count, a
/// non-finite value, albedos outside [0, 1], Phong's `kd + ks > 1`, a roughness `alpha <= 0`.
/// Thread safe.
///
/// # Safety
/// `params` addresses `n` floats; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_parametric(
    kind: NbrdfParametricKindValue,
    params: *const f32,
    n: usize,
    out: *mut *mut NbrdfBrdf,
) -> NbrdfStatus {
    guard(|| {
        let kind = parametric_kind(kind)?;
        // The count is checked before the floats are read; the values by the core's one set of checks.
        let want = any::params_of(kind).len();
        exactly(n, want, || format!("{} takes {want} parameters, got {n}", kind.id()))?;
        // SAFETY: the caller's contract; n is the model's small count.
        let v = unsafe { floats_of(params, n, "params")? };
        // SAFETY: the caller's contract.
        unsafe { put(out, || Ok(AnyBrdf::from_params(kind, v)?)) }
    })
}

/// A parametric model from raw network outputs, as a parametric `.nbrdf` model's network predicts them
/// (`docs/models.md`: every raw value is mapped into its parameter's range, so any finite input is
/// valid): `n_raw` raw values and `n_object` per-object parameters (the FMBRDF's normalisation; 0 for
/// the others). Thread safe.
///
/// # Safety
/// `raw` addresses `n_raw` floats and `object` `n_object`; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_parametric_from_raw(
    kind: NbrdfParametricKindValue,
    raw: *const f32,
    n_raw: usize,
    object: *const f32,
    n_object: usize,
    out: *mut *mut NbrdfBrdf,
) -> NbrdfStatus {
    guard(|| {
        let k = parametric_kind(kind)?;
        if (n_raw, n_object) != (k.n_raw(), k.n_object()) {
            return fail(
                NbrdfStatus::BufferSize,
                format!("{} takes {} raw values and {} object parameters, got {n_raw} and {n_object}", k.id(), k.n_raw(), k.n_object()),
            );
        }
        debug_assert!(n_raw <= MAX_RAW && n_object <= MAX_OBJECT);
        // SAFETY: the caller's contract; the counts are the model's small ones.
        let (raw, object) = unsafe { (floats_of(raw, n_raw, "raw")?, floats_of(object, n_object, "object")?) };
        // SAFETY: the caller's contract.
        unsafe { put(out, || Ok(AnyBrdf::from_raw(k, raw, object)?)) }
    })
}

/// A built-in material by id: `"two-lobe-metal"`, `"clear-coat"` or `"velvet"`. Thread safe.
///
/// # Safety
/// `id` is a NUL-terminated string; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_builtin(id: *const c_char, out: *mut *mut NbrdfBrdf) -> NbrdfStatus {
    guard(|| {
        if id.is_null() {
            return fail(NbrdfStatus::NullPointer, "id is null");
        }
        // SAFETY: non-null and NUL-terminated by the caller's contract.
        let id = unsafe { CStr::from_ptr(id) }.to_string_lossy();
        // SAFETY: the caller's contract.
        unsafe { put(out, || Ok(AnyBrdf::builtin_id(&id)?)) }
    })
}

/// Frees a handle (null is allowed and does nothing). No other thread may be using it.
///
/// # Safety
/// `brdf` is null or a handle from this library not freed before.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_free(brdf: *mut NbrdfBrdf) {
    if !brdf.is_null() {
        // SAFETY: made by Box::into_raw in `put` and not freed before (the caller's contract). A
        // panic in a destructor cannot happen (plain data), but stays inside the library anyway.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| drop(unsafe { Box::from_raw(brdf) })));
    }
}

/// Returns the handle, or the null-pointer failure.
///
/// # Safety
/// `brdf` is null or a live handle.
pub(crate) unsafe fn handle<'a>(brdf: *const NbrdfBrdf) -> Result<&'a NbrdfBrdf> {
    // SAFETY: the caller's contract.
    match unsafe { brdf.as_ref() } {
        Some(h) => Ok(h),
        None => fail(NbrdfStatus::NullPointer, "brdf is null"),
    }
}

/// What the handle holds (see [`NbrdfInfo`]). Thread safe.
///
/// # Safety
/// `brdf` is a live handle; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_info(brdf: *const NbrdfBrdf, out: *mut NbrdfInfo) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let h = unsafe { handle(brdf)? };
        if out.is_null() {
            return fail(NbrdfStatus::NullPointer, "out is null");
        }
        let i = h.brdf.info();
        let kind = match i.kind {
            Kind::Model => NbrdfKind::Model,
            Kind::Merl => NbrdfKind::Merl,
            Kind::NbrdfJson => NbrdfKind::NbrdfJson,
            Kind::Parametric => NbrdfKind::Parametric,
            Kind::Builtin => NbrdfKind::Builtin,
        };
        let info = NbrdfInfo { kind, reciprocal: i.reciprocal, position_len: i.position_len as u32, n_parameters: i.n_parameters as u64 };
        // SAFETY: non-null and writable by the caller's contract.
        unsafe { out.write(info) };
        Ok(())
    })
}

/// The per-point position input of an intrinsically encoded model at triangle `tri` (vertex indices)
/// with barycentric weights `bary`, interpolated from the per-vertex table the file carries; `out`
/// receives `out_len` = `position_len` floats to pass to [`nbrdf_prepare`](crate::nbrdf_prepare).
/// Errors for a handle that is not such a model or an index beyond the table. Thread safe.
///
/// # Safety
/// `brdf` is a live handle; `tri` addresses 3 values, `bary` 3 and `out` `out_len`.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_position_features(
    brdf: *const NbrdfBrdf,
    tri: *const u32,
    bary: *const f32,
    out: *mut f32,
    out_len: usize,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let h = unsafe { handle(brdf)? };
        let Some(m) = h.brdf.as_model() else {
            return fail(NbrdfStatus::InvalidValue, "not a model: only intrinsically encoded models have position features");
        };
        // The output length is checked against the model's before anything is read or written.
        exactly(out_len, m.position_len(), || format!("out has {out_len} floats; this model's position input has {}", m.position_len()))?;
        if tri.is_null() {
            return fail(NbrdfStatus::NullPointer, "tri is null");
        }
        if !(tri as usize).is_multiple_of(4) {
            return fail(NbrdfStatus::Misaligned, "tri is not 4-byte aligned");
        }
        span(tri, 3, "tri")?;
        // SAFETY: non-null, aligned, 3 values by the caller's contract.
        let tri = unsafe { [*tri, *tri.add(1), *tri.add(2)] };
        // SAFETY: the caller's contract.
        let bary = unsafe { floats_of(bary, 3, "bary")? };
        out_floats(out, out_len, "out")?;
        let mut feat = vec![0.0f32; out_len];
        h.brdf.position_features(tri, [bary[0], bary[1], bary[2]], &mut feat)?;
        // SAFETY: out addresses out_len writable floats (caller's contract), aligned, checked non-null.
        unsafe { std::ptr::copy_nonoverlapping(feat.as_ptr(), out, out_len) };
        Ok(())
    })
}
