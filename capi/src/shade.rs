//! Shading: a BRDF prepared at a surface point into storage the caller owns, then evaluated,
//! importance-sampled and its density queried, one direction pair at a time or many as arrays.

use std::ffi::c_void;
use std::mem::{align_of, size_of};

use nbrdf_core::any::At;
use nbrdf_core::{Brdf, BsdfSample, Prepared, Vec3};

use crate::args::{exactly, floats_mut, floats_of, out_floats, overlaps, span};
use crate::error::{fail, guard, NbrdfStatus, Result};
use crate::handle::{handle, NbrdfBrdf};

/// Bytes of point storage that are always enough ([`nbrdf_point_size`] is the exact need): for
/// storage on the stack, `_Alignas(16) unsigned char point[NBRDF_POINT_MAX_SIZE];`.
pub const NBRDF_POINT_MAX_SIZE: usize = 4096;

/// Alignment that is always enough for point storage.
pub const NBRDF_POINT_MAX_ALIGN: usize = 16;

/// What `nbrdf_prepare` writes into the caller's storage.
#[repr(C)]
struct Point {
    /// [`MAGIC`]: the storage was written by `nbrdf_prepare`.
    magic: u64,
    /// The handle it was prepared for.
    owner: *const NbrdfBrdf,
    prepared: Prepared,
}

const MAGIC: u64 = u64::from_le_bytes(*b"nbrdfPt1");

const _: () = assert!(size_of::<Point>() <= NBRDF_POINT_MAX_SIZE && align_of::<Point>() <= NBRDF_POINT_MAX_ALIGN);

/// Bytes of storage [`nbrdf_prepare`] writes a point into (at most [`NBRDF_POINT_MAX_SIZE`]).
#[no_mangle]
pub extern "C" fn nbrdf_point_size() -> usize {
    size_of::<Point>()
}

/// Alignment point storage needs (at most [`NBRDF_POINT_MAX_ALIGN`]; `malloc` gives enough).
#[no_mangle]
pub extern "C" fn nbrdf_point_align() -> usize {
    align_of::<Point>()
}

/// Prepares `brdf` at a surface point: `position` holds `position_len` floats ([`crate::NbrdfInfo`]:
/// the intrinsic features, or the point for an extrinsic encoding, or nothing), and the result goes
/// into `storage` (`storage_size` >= [`nbrdf_point_size`] bytes aligned to [`nbrdf_point_align`]).
/// Everything that depends on the point only is computed here once; evaluations at the point pass
/// `storage`. A BRDF that is the same everywhere needs no point (pass null to the evaluations), but
/// preparing one with `position_len` 0 works too. The storage holds plain data: copy it freely, no
/// free needed; it is valid as long as the handle. Thread safe (distinct storage per thread).
///
/// # Safety
/// `brdf` is a live handle; `position` addresses `position_len` floats; `storage` addresses
/// `storage_size` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_prepare(
    brdf: *const NbrdfBrdf,
    position: *const f32,
    position_len: usize,
    storage: *mut c_void,
    storage_size: usize,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let h = unsafe { handle(brdf)? };
        // The length is checked against the model's before the floats are read.
        let want = h.brdf.position_len();
        exactly(position_len, want, || match want {
            0 => format!("position has {position_len} floats; this BRDF takes none"),
            _ => format!("position has {position_len} floats; this model takes {want}"),
        })?;
        // SAFETY: the caller's contract; the length is the model's.
        let p = unsafe { floats_of(position, position_len, "position")? };
        if storage.is_null() {
            return fail(NbrdfStatus::NullPointer, "storage is null");
        }
        if storage_size < size_of::<Point>() {
            return fail(NbrdfStatus::BufferSize, format!("storage has {storage_size} bytes; a point needs {} (nbrdf_point_size)", size_of::<Point>()));
        }
        if !(storage as usize).is_multiple_of(align_of::<Point>()) {
            return fail(NbrdfStatus::Misaligned, format!("storage must be {}-byte aligned (nbrdf_point_align)", align_of::<Point>()));
        }
        span(storage.cast::<u8>().cast_const(), size_of::<Point>(), "storage")?;
        let prepared = h.brdf.prepare(p)?;
        // SAFETY: non-null, large enough and aligned, checked above.
        unsafe { storage.cast::<Point>().write(Point { magic: MAGIC, owner: brdf, prepared }) };
        Ok(())
    })
}

/// Resolves `point` for `h`.
///
/// # Safety
/// `point` is null or addresses storage of at least `nbrdf_point_size` bytes.
unsafe fn at<'a>(h: &'a NbrdfBrdf, point: *const c_void) -> Result<At<'a>> {
    let prepared = if point.is_null() {
        None
    } else {
        if !(point as usize).is_multiple_of(align_of::<Point>()) {
            return fail(NbrdfStatus::Misaligned, format!("point must be {}-byte aligned (nbrdf_point_align)", align_of::<Point>()));
        }
        let p = point.cast::<Point>();
        // SAFETY: aligned, and at least nbrdf_point_size bytes by the caller's contract; the header
        // is read before the state, which only storage with our magic and owner holds.
        let (magic, owner) = unsafe { ((*p).magic, (*p).owner) };
        if magic != MAGIC || !std::ptr::eq(owner, h) {
            return fail(NbrdfStatus::InvalidPoint, "point was not prepared by nbrdf_prepare for this BRDF");
        }
        // SAFETY: written by nbrdf_prepare as a Point (magic and owner match).
        Some(unsafe { (*p).prepared })
    };
    match h.brdf.at_prepared(prepared.as_ref()) {
        Some(at) => Ok(at),
        None => fail(NbrdfStatus::InvalidPoint, "this model varies over the surface: pass a point from nbrdf_prepare"),
    }
}

/// Three floats at `v`.
///
/// # Safety
/// `v` is null or addresses 3 readable floats.
unsafe fn vec3(v: *const f32, what: &str) -> Result<Vec3> {
    // SAFETY: the caller's contract.
    let s = unsafe { floats_of(v, 3, what)? };
    Ok(Vec3::new(s[0], s[1], s[2]))
}

/// `f(wi, wo)` into `rgb[3]` (1/sr, cosine not included; 0 below the horizon or for invalid
/// directions, never NaN). `point` is storage from [`nbrdf_prepare`], or null for a BRDF that is the
/// same everywhere. Thread safe.
///
/// # Safety
/// `brdf` is a live handle; `point` is null or prepared storage; `wi`, `wo` address 3 floats and `rgb`
/// 3 writable floats.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_eval(
    brdf: *const NbrdfBrdf,
    point: *const c_void,
    wi: *const f32,
    wo: *const f32,
    rgb: *mut f32,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract, for every pointer.
        let (b, wi, wo) = unsafe { (at(handle(brdf)?, point)?, vec3(wi, "wi")?, vec3(wo, "wo")?) };
        out_floats(rgb, 3, "rgb")?;
        let f = b.eval(wi, wo);
        // SAFETY: checked non-null and aligned; 3 writable floats by the caller's contract.
        unsafe { std::ptr::copy_nonoverlapping(f.as_ptr(), rgb, 3) };
        Ok(())
    })
}

/// `n` directions as three arrays (structure of arrays).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct NbrdfDirections {
    /// `n` x components.
    pub x: *const f32,
    /// `n` y components.
    pub y: *const f32,
    /// `n` z components.
    pub z: *const f32,
}

/// `n` RGB values as three arrays (structure of arrays).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct NbrdfRgbArrays {
    /// `n` red values.
    pub r: *mut f32,
    /// `n` green values.
    pub g: *mut f32,
    /// `n` blue values.
    pub b: *mut f32,
}

/// `f(wi[i], wo[i])` for `i < n` at one point, into `out` (as [`nbrdf_eval`], bit for bit; models run
/// in packets, faster than one call per pair). The outputs must not overlap the inputs or each other
/// (`NBRDF_STATUS_INVALID_VALUE`). Thread safe.
///
/// # Safety
/// `brdf` is a live handle; `point` is null or prepared storage; each array addresses `n` floats
/// (readable for `wi`, `wo`, writable for `out`).
#[no_mangle]
pub unsafe extern "C" fn nbrdf_eval_many(
    brdf: *const NbrdfBrdf,
    point: *const c_void,
    n: usize,
    wi: NbrdfDirections,
    wo: NbrdfDirections,
    out: NbrdfRgbArrays,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let b = unsafe { at(handle(brdf)?, point)? };
        if n == 0 {
            return Ok(());
        }
        // Every array is checked (null, alignment, length, address wrap) before any slice is made.
        let ins = [(wi.x, "wi.x"), (wi.y, "wi.y"), (wi.z, "wi.z"), (wo.x, "wo.x"), (wo.y, "wo.y"), (wo.z, "wo.z")];
        for (p, what) in ins {
            if p.is_null() {
                return fail(NbrdfStatus::NullPointer, format!("{what} is null"));
            }
            span(p, n, what)?;
        }
        let outs = [out.r, out.g, out.b];
        for (o, what) in outs.iter().zip(["out.r", "out.g", "out.b"]) {
            out_floats(*o, n, what)?;
        }
        for (i, o) in outs.iter().enumerate() {
            let inputs = ins.iter().map(|(p, _)| *p);
            if inputs.chain(outs[..i].iter().map(|p| p.cast_const())).any(|p| overlaps(p, o.cast_const(), n)) {
                return fail(NbrdfStatus::InvalidValue, "an output array overlaps an input or another output");
            }
        }
        // SAFETY: each array addresses n floats by the caller's contract; checked non-null, aligned
        // and a range a slice may describe.
        let (wi, wo) = unsafe {
            (
                [floats_of(wi.x, n, "wi.x")?, floats_of(wi.y, n, "wi.y")?, floats_of(wi.z, n, "wi.z")?],
                [floats_of(wo.x, n, "wo.x")?, floats_of(wo.y, n, "wo.y")?, floats_of(wo.z, n, "wo.z")?],
            )
        };
        // SAFETY: n writable floats each by the caller's contract, disjoint from each other and the
        // inputs (checked above).
        let (r, g, bl) = unsafe { (floats_mut(out.r, n, "out.r")?, floats_mut(out.g, n, "out.g")?, floats_mut(out.b, n, "out.b")?) };
        match &b {
            At::Model(m) => m.model.eval_many_soa(&m.prepared, wi, wo, [r, g, bl]),
            At::Fixed(f) => {
                for i in 0..n {
                    let v = f.eval(Vec3::new(wi[0][i], wi[1][i], wi[2][i]), Vec3::new(wo[0][i], wo[1][i], wo[2][i]));
                    (r[i], g[i], bl[i]) = (v[0], v[1], v[2]);
                }
            }
        }
        Ok(())
    })
}

/// A direction sampled by [`nbrdf_sample`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct NbrdfSample {
    /// The sampled direction toward the light, unit, upper hemisphere.
    pub wi: [f32; 3],
    /// `f(wi, wo) cos θi / pdf`: what the path's throughput is multiplied by.
    pub weight: [f32; 3],
    /// Density of `wi` per unit solid angle; 0 when no direction was produced (then `wi` and `weight`
    /// are 0 too).
    pub pdf: f32,
}

/// Samples `wi` for the view `wo` from three uniform numbers `u` in [0, 1): the BRDF's own lobes
/// (parametric models), or the proxy stored in the model file or fitted at load (neural models, MERL
/// tables, NBRDF-json networks). `out->pdf` is 0 when no direction was produced (`wo` below the
/// horizon, or a lobe reflected below it); otherwise `out->pdf` equals `nbrdf_pdf(out->wi, wo)` (to rounding when `wo` is not exactly unit).
/// Thread safe.
///
/// # Safety
/// `brdf` is a live handle; `point` is null or prepared storage; `wo`, `u` address 3 floats; `out` is
/// writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_sample(
    brdf: *const NbrdfBrdf,
    point: *const c_void,
    wo: *const f32,
    u: *const f32,
    out: *mut NbrdfSample,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let (b, wo, u) = unsafe { (at(handle(brdf)?, point)?, vec3(wo, "wo")?, vec3(u, "u")?) };
        if out.is_null() {
            return fail(NbrdfStatus::NullPointer, "out is null");
        }
        let s = match b.sample(wo, u.to_array()) {
            Some(BsdfSample { wi, weight, pdf }) => NbrdfSample { wi: wi.to_array(), weight, pdf },
            None => NbrdfSample::default(),
        };
        // SAFETY: non-null and writable by the caller's contract.
        unsafe { out.write(s) };
        Ok(())
    })
}

/// Density of [`nbrdf_sample`] at `wi` for the view `wo`, per unit solid angle, into `*pdf`. Thread
/// safe.
///
/// # Safety
/// `brdf` is a live handle; `point` is null or prepared storage; `wi`, `wo` address 3 floats; `pdf` is
/// writable.
#[no_mangle]
pub unsafe extern "C" fn nbrdf_pdf(
    brdf: *const NbrdfBrdf,
    point: *const c_void,
    wi: *const f32,
    wo: *const f32,
    pdf: *mut f32,
) -> NbrdfStatus {
    guard(|| {
        // SAFETY: the caller's contract.
        let (b, wi, wo) = unsafe { (at(handle(brdf)?, point)?, vec3(wi, "wi")?, vec3(wo, "wo")?) };
        out_floats(pdf, 1, "pdf")?;
        let p: f32 = b.pdf(wi, wo);
        // SAFETY: checked non-null and aligned; writable by the caller's contract.
        unsafe { pdf.write(p) };
        Ok(())
    })
}
