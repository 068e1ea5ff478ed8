// ---- NBRDF-json input (src/measured/nbrdf_json): the half vector with φh = 0 and the difference vector,
// [hx, hy, hz, dx, dy, dz], from the pair without trigonometry (core `nbrdf_json::input`).
struct NbrdfJsonInput {
    x: array<f32, 6>,
    ok: bool,
}

fn nbrdf_json_input(wi_in: vec3<f32>, wo_in: vec3<f32>) -> NbrdfJsonInput {
    var r = NbrdfJsonInput(array<f32, 6>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), false);
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return r;
    }
    let wi = pair.wi;
    let wo = pair.wo;
    let hx = wi.x + wo.x;
    let hy = wi.y + wo.y;
    let hz = wi.z + wo.z;
    let q = hx * hx + hy * hy;
    let inv_len = 1.0 / sqrt(q + hz * hz);
    let cos_h = hz * inv_len;
    if (q > 0.0) {
        let rr = sqrt(q);
        let inv_r = 1.0 / rr;
        let a = hx * wi.x + hy * wi.y;
        let b = hx * wi.y - hy * wi.x;
        r.x = array<f32, 6>(rr * inv_len, 0.0, cos_h, (inv_len * inv_r) * (hz * a - q * wi.z), b * inv_r, inv_len * (a + hz * wi.z));
    } else {
        r.x = array<f32, 6>(0.0, 0.0, cos_h, cos_h * wi.x, wi.y, cos_h * wi.z);
    }
    r.ok = true;
    for (var i = 0; i < 6; i++) {
        r.ok = r.ok && nbrdf_finite(r.x[i]);
    }
    return r;
}

// expm1 of a network output, clamped as the core does: an overflow (infinite there) sanitises to 0.
fn nbrdf_expm1_clamped(y: f32) -> f32 {
    if (!(y <= 88.7216796875)) {
        return 0.0;
    }
    return nbrdf_sanitize1(nbrdf_expm1(y));
}
