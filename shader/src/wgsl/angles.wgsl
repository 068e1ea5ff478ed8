// ---- nbrdf angles: the core's direction maps (src/angles) with its hard-case handling ----------------

// v / |v| in .xyz and 1 in .w, or .w = 0 when v is zero or not finite (core `angles::unit`): the Taylor
// step 1.5 - |v|²/2 near unit length, one square root in the usual range, a rescale by the largest
// component outside it.
fn nbrdf_unit(v: vec3<f32>) -> vec4<f32> {
    if (!nbrdf_finite3(v)) {
        return vec4<f32>(0.0);
    }
    let l2 = (v.x * v.x + v.y * v.y) + v.z * v.z;
    if (abs(l2 - 1.0) <= 0.000244140625) {
        return vec4<f32>(v * (1.5 - 0.5 * l2), 1.0);
    }
    if (l2 >= 1e-30 && l2 <= 1e30) {
        return vec4<f32>(v * (1.0 / sqrt(l2)), 1.0);
    }
    let m = max(max(abs(v.x), abs(v.y)), abs(v.z));
    if (!(m > 0.0)) {
        return vec4<f32>(0.0);
    }
    let s = v / m;
    return vec4<f32>(s / sqrt((s.x * s.x + s.y * s.y) + s.z * s.z), 1.0);
}

// Both directions normalised and strictly above the horizon, or ok = false: the gate every BRDF passes
// its input through (core `angles::upper_hemisphere_pair`); what it rejects evaluates to 0.
struct NbrdfPair {
    wi: vec3<f32>,
    wo: vec3<f32>,
    ok: bool,
}

fn nbrdf_upper_pair(wi: vec3<f32>, wo: vec3<f32>) -> NbrdfPair {
    let a = nbrdf_unit(wi);
    let b = nbrdf_unit(wo);
    let ok = a.w > 0.0 && b.w > 0.0 && a.z > 0.0 && b.z > 0.0;
    return NbrdfPair(a.xyz, b.xyz, ok);
}

// The half-vector frame (core `angles::half_frame`): everything from s = wi + wo (symmetric) and
// u = wi - wo (negated exactly by the swap), φd brought to the canonical half plane before atan2, so Θ
// of (wi, wo) and (wo, wi) are the same bits.
struct NbrdfFrame {
    theta_h: f32,
    theta_d: f32,
    phi_d_mod_pi: f32,
    flipped: bool,
    ok: bool,
}

fn nbrdf_half_frame(wi_in: vec3<f32>, wo_in: vec3<f32>) -> NbrdfFrame {
    var f = NbrdfFrame(0.0, 0.0, 0.0, false, false);
    let a = nbrdf_unit(wi_in);
    let b = nbrdf_unit(wo_in);
    if (!(a.w > 0.0 && b.w > 0.0)) {
        return f;
    }
    let s = a.xyz + b.xyz;
    let u = a.xyz - b.xyz;
    let s_len = sqrt((s.x * s.x + s.y * s.y) + s.z * s.z);
    if (!(s_len > 0.0)) {
        return f;
    }
    let h = s / s_len;
    let rho = sqrt(h.x * h.x + h.y * h.y);
    f.theta_h = nbrdf_atan2(rho, h.z);
    f.theta_d = nbrdf_atan2(sqrt((u.x * u.x + u.y * u.y) + u.z * u.z), s_len);
    var cos_phi_h = 1.0;
    var sin_phi_h = 0.0;
    if (rho > 0.0) {
        cos_phi_h = h.x / rho;
        sin_phi_h = h.y / rho;
    }
    let x_axis = vec3<f32>(h.z * cos_phi_h, h.z * sin_phi_h, -rho);
    let y_axis = vec3<f32>(-sin_phi_h, cos_phi_h, 0.0);
    var pa = (u.x * x_axis.x + u.y * x_axis.y) + u.z * x_axis.z;
    var pb = (u.x * y_axis.x + u.y * y_axis.y) + u.z * y_axis.z;
    var flipped = pb < 0.0 || (pb == 0.0 && pa < 0.0);
    if (flipped) {
        pa = -pa;
        pb = -pb;
    }
    // Signed zeros dropped on their bits, so that atan2 sees the same bits for both orders.
    if ((bitcast<u32>(pa) & 0x7fffffffu) == 0u) {
        pa = 0.0;
    }
    if ((bitcast<u32>(pb) & 0x7fffffffu) == 0u) {
        pb = 0.0;
    }
    var phi = nbrdf_atan2(pb, pa);
    // atan2 of (tiny b > 0, a < 0) can round up to π: fold it to 0 of the other half plane.
    if (phi >= NBRDF_PI) {
        phi = 0.0;
        flipped = !flipped;
    }
    f.phi_d_mod_pi = phi;
    f.flipped = flipped;
    f.ok = true;
    return f;
}

// Θ of Sec. 4.3, Eq. 6: [θh, θd, φd mod π, φd mod π + π]; .ok false for degenerate pairs.
fn nbrdf_theta(f: NbrdfFrame) -> vec4<f32> {
    return vec4<f32>(f.theta_h, f.theta_d, f.phi_d_mod_pi, f.phi_d_mod_pi + NBRDF_PI);
}

// Isotropic Rusinkiewicz angles [θh, θd, φd], φd in [0, 2π).
fn nbrdf_rusinkiewicz(f: NbrdfFrame) -> vec3<f32> {
    var phi_d = f.phi_d_mod_pi;
    if (f.flipped) {
        phi_d = phi_d + NBRDF_PI;
    }
    if (phi_d >= NBRDF_TAU) {
        phi_d = 0.0;
    }
    return vec3<f32>(f.theta_h, f.theta_d, phi_d);
}
