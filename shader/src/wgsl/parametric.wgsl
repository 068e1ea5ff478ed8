// ---- nbrdf parametric models (src/parametric): raw network outputs -> parameters -> BRDF -------------
// The raw maps (sigmoid / softplus ranges, roughness pre-activation × 0.5) and the formulas are the
// core's term by term; see each model's file there for the citations and the raw index tables.

const NBRDF_ALPHA_MIN: f32 = 0.001;

// Cosines of a direction pair from symmetric quantities only (core `microfacet::HalfGeometry`).
struct NbrdfHalf {
    h: vec3<f32>,
    cos_i: f32,
    cos_o: f32,
    cos_h: f32,
    sin2_h: f32,
    cos_d: f32,
    ok: bool,
}

fn nbrdf_half_geometry(wi: vec3<f32>, wo: vec3<f32>) -> NbrdfHalf {
    var g = NbrdfHalf(vec3<f32>(0.0, 0.0, 1.0), 1.0, 1.0, 1.0, 0.0, 1.0, false);
    let pair = nbrdf_upper_pair(wi, wo);
    if (!pair.ok) {
        return g;
    }
    let s = pair.wi + pair.wo;
    let s_len = sqrt((s.x * s.x + s.y * s.y) + s.z * s.z);
    if (!(s_len > 0.0)) {
        return g;
    }
    let h = s / s_len;
    return NbrdfHalf(h, pair.wi.z, pair.wo.z, h.z, h.x * h.x + h.y * h.y, min(0.5 * s_len, 1.0), true);
}

fn nbrdf_clamp_alpha(alpha: f32) -> f32 {
    return clamp(alpha, NBRDF_ALPHA_MIN, 1.0);
}

fn nbrdf_beckmann_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    let c2 = cos_h * cos_h;
    let a2 = alpha * alpha;
    let c4 = c2 * c2;
    if (c4 <= 0.0) {
        return 0.0;
    }
    return nbrdf_exp(-sin2_h / (a2 * c2)) / (a2 * NBRDF_PI * c4);
}

fn nbrdf_ggx_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let t = a2 * cos_h * cos_h + sin2_h;
    return a2 * NBRDF_INV_PI / (t * t);
}

fn nbrdf_gtr1_d(cos_h: f32, sin2_h: f32, alpha: f32) -> f32 {
    if (alpha >= 1.0) {
        return NBRDF_INV_PI;
    }
    let a2 = alpha * alpha;
    let t = a2 * cos_h * cos_h + sin2_h;
    return (a2 - 1.0) * NBRDF_INV_PI / (nbrdf_log(a2) * t);
}

fn nbrdf_smith_ggx_g1_over_2cos(cos_v: f32, alpha: f32) -> f32 {
    let c2 = cos_v * cos_v;
    return 1.0 / (sqrt(max(alpha * alpha * (1.0 - c2) + c2, 0.0)) + cos_v);
}

fn nbrdf_smith_ggx_g1(cos_v: f32, alpha: f32) -> f32 {
    return 2.0 * cos_v * nbrdf_smith_ggx_g1_over_2cos(cos_v, alpha);
}

fn nbrdf_v_cavity_g_over_4cos(g: NbrdfHalf) -> f32 {
    let a = 1.0 / (4.0 * g.cos_i * g.cos_o);
    let k = g.cos_h / (2.0 * g.cos_d);
    return min(min(a, k / g.cos_i), k / g.cos_o);
}

fn nbrdf_schlick_weight(c: f32) -> f32 {
    let m = clamp(1.0 - c, 0.0, 1.0);
    let m2 = m * m;
    return m2 * m2 * m;
}

fn nbrdf_fresnel_schlick(f0: f32, cos_d: f32) -> f32 {
    return f0 + (1.0 - f0) * nbrdf_schlick_weight(cos_d);
}

fn nbrdf_fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let c = clamp(cos_i, 0.0, 1.0);
    let sin2_t = (1.0 - c * c) / (eta * eta);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(max(1.0 - sin2_t, 0.0));
    let r_par = (eta * c - cos_t) / (eta * c + cos_t);
    let r_perp = (c - eta * cos_t) / (eta * cos_t + c);
    let f = (r_par * r_par + r_perp * r_perp) * 0.5;
    return select(1.0, clamp(f, 0.0, 1.0), nbrdf_finite(f));
}

fn nbrdf_lerp(a: f32, b: f32, t: f32) -> f32 {
    return a + t * (b - a);
}

fn nbrdf_sigmoid3(r0: f32, r1: f32, r2: f32) -> vec3<f32> {
    return vec3<f32>(nbrdf_sigmoid(nbrdf_raw(r0)), nbrdf_sigmoid(nbrdf_raw(r1)), nbrdf_sigmoid(nbrdf_raw(r2)));
}

// -- Lambert: kd = σ(raw[0..3]).
struct NbrdfLambert {
    kd: vec3<f32>,
}

fn nbrdf_lambert_from_raw(r: array<f32, 3>) -> NbrdfLambert {
    return NbrdfLambert(nbrdf_sigmoid3(r[0], r[1], r[2]));
}

fn nbrdf_lambert_eval(m: NbrdfLambert, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    if (!nbrdf_upper_pair(wi, wo).ok) {
        return vec3<f32>(0.0);
    }
    return nbrdf_sanitize(m.kd * NBRDF_INV_PI);
}

// -- RP (energy-preserving Phong): kd = σ, ks = (1 - kd) σ, n = softplus.
struct NbrdfPhong {
    kd: vec3<f32>,
    ks: vec3<f32>,
    n: f32,
}

fn nbrdf_phong_from_raw(r: array<f32, 7>) -> NbrdfPhong {
    let kd = nbrdf_sigmoid3(r[0], r[1], r[2]);
    let ks = (vec3<f32>(1.0) - kd) * nbrdf_sigmoid3(r[3], r[4], r[5]);
    return NbrdfPhong(kd, ks, nbrdf_softplus(nbrdf_raw(r[6])));
}

fn nbrdf_phong_cos_alpha(wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    return wi.z * wo.z - (wi.x * wo.x + wi.y * wo.y);
}

fn nbrdf_phong_eval(m: NbrdfPhong, wi_in: vec3<f32>, wo_in: vec3<f32>) -> vec3<f32> {
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return vec3<f32>(0.0);
    }
    let cos_a = min(nbrdf_phong_cos_alpha(pair.wi, pair.wo), 1.0);
    var lobe = 0.0;
    if (cos_a > 0.0) {
        lobe = (m.n + 2.0) * (0.5 * NBRDF_INV_PI) * nbrdf_pow(cos_a, m.n);
    }
    return nbrdf_sanitize(m.kd * NBRDF_INV_PI + m.ks * lobe);
}

// -- Torrance-Sparrow: kd, ks (Schlick F0) = σ; alpha = clamp(σ(0.5 raw[6])).
struct NbrdfTorranceSparrow {
    kd: vec3<f32>,
    ks: vec3<f32>,
    alpha: f32,
}

fn nbrdf_torrance_sparrow_from_raw(r: array<f32, 7>) -> NbrdfTorranceSparrow {
    let alpha = nbrdf_clamp_alpha(nbrdf_sigmoid(nbrdf_raw(r[6]) * 0.5));
    return NbrdfTorranceSparrow(nbrdf_sigmoid3(r[0], r[1], r[2]), nbrdf_sigmoid3(r[3], r[4], r[5]), alpha);
}

fn nbrdf_torrance_sparrow_eval(m: NbrdfTorranceSparrow, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    let g = nbrdf_half_geometry(wi, wo);
    if (!g.ok) {
        return vec3<f32>(0.0);
    }
    let alpha = nbrdf_clamp_alpha(m.alpha);
    let dg = nbrdf_beckmann_d(g.cos_h, g.sin2_h, alpha) * nbrdf_v_cavity_g_over_4cos(g);
    let f = vec3<f32>(
        nbrdf_fresnel_schlick(m.ks.x, g.cos_d),
        nbrdf_fresnel_schlick(m.ks.y, g.cos_d),
        nbrdf_fresnel_schlick(m.ks.z, g.cos_d),
    );
    return nbrdf_sanitize(m.kd * NBRDF_INV_PI + dg * f);
}

// -- FMBRDF: rho, ks = σ; alpha = clamp(σ(0.5 raw[4])); beta in [0.5, 4]; eta in [1, 3];
//    norm = exp(clamp(object, -80, 80)).
struct NbrdfFresnelMicrofacet {
    rho: vec3<f32>,
    ks: f32,
    alpha: f32,
    beta: f32,
    eta: f32,
    norm: f32,
}

fn nbrdf_fresnel_microfacet_from_raw(r: array<f32, 7>, object: f32) -> NbrdfFresnelMicrofacet {
    return NbrdfFresnelMicrofacet(
        nbrdf_sigmoid3(r[0], r[1], r[2]),
        nbrdf_sigmoid(nbrdf_raw(r[3])),
        nbrdf_clamp_alpha(nbrdf_sigmoid(nbrdf_raw(r[4]) * 0.5)),
        nbrdf_sigmoid(nbrdf_raw(r[5])) * 3.5 + 0.5,
        nbrdf_sigmoid(nbrdf_raw(r[6])) * 2.0 + 1.0,
        nbrdf_exp(clamp(nbrdf_raw(object), -80.0, 80.0)),
    );
}

fn nbrdf_fresnel_microfacet_eval(m: NbrdfFresnelMicrofacet, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    let g = nbrdf_half_geometry(wi, wo);
    if (!g.ok) {
        return vec3<f32>(0.0);
    }
    let theta_h = nbrdf_atan2(sqrt(g.sin2_h), g.cos_h);
    let alpha = nbrdf_clamp_alpha(m.alpha);
    let ndf = m.norm * nbrdf_exp(-nbrdf_pow(theta_h / alpha, m.beta));
    let surface = m.ks * ndf * nbrdf_v_cavity_g_over_4cos(g) * nbrdf_fresnel_dielectric(g.cos_d, m.eta);
    let t_i = 1.0 - nbrdf_fresnel_dielectric(g.cos_i, m.eta);
    let t_o = 1.0 - nbrdf_fresnel_dielectric(g.cos_o, m.eta);
    let body = (t_i * t_o) * NBRDF_INV_PI;
    return nbrdf_sanitize(vec3<f32>(surface) + m.rho * body);
}

// -- Disney (isotropic, BRDF Explorer's disney.brdf): every parameter σ, roughness σ(0.5 raw[7]).
struct NbrdfDisney {
    base_color: vec3<f32>,
    subsurface: f32,
    metallic: f32,
    specular: f32,
    specular_tint: f32,
    roughness: f32,
    sheen: f32,
    sheen_tint: f32,
    clearcoat: f32,
    clearcoat_gloss: f32,
}

fn nbrdf_disney_from_raw(r: array<f32, 12>) -> NbrdfDisney {
    return NbrdfDisney(
        nbrdf_sigmoid3(r[0], r[1], r[2]),
        nbrdf_sigmoid(nbrdf_raw(r[3])),
        nbrdf_sigmoid(nbrdf_raw(r[4])),
        nbrdf_sigmoid(nbrdf_raw(r[5])),
        nbrdf_sigmoid(nbrdf_raw(r[6])),
        nbrdf_sigmoid(nbrdf_raw(r[7]) * 0.5),
        nbrdf_sigmoid(nbrdf_raw(r[8])),
        nbrdf_sigmoid(nbrdf_raw(r[9])),
        nbrdf_sigmoid(nbrdf_raw(r[10])),
        nbrdf_sigmoid(nbrdf_raw(r[11])),
    );
}

fn nbrdf_disney_tint(c: vec3<f32>) -> vec3<f32> {
    let lum = c.x * 0.3 + c.y * 0.6 + c.z * 0.1;
    if (lum > 0.0) {
        return c / lum;
    }
    return vec3<f32>(1.0);
}

fn nbrdf_disney_eval(m: NbrdfDisney, wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    let g = nbrdf_half_geometry(wi, wo);
    if (!g.ok) {
        return vec3<f32>(0.0);
    }
    let c = m.base_color;
    let tint = nbrdf_disney_tint(c);
    let fl = nbrdf_schlick_weight(g.cos_i);
    let fv = nbrdf_schlick_weight(g.cos_o);
    let fh = nbrdf_schlick_weight(g.cos_d);
    let r = m.roughness;
    let cd2 = g.cos_d * g.cos_d;
    // Burley diffuse and the Hanrahan-Krueger-like subsurface shape.
    let fd90 = r * (2.0 * cd2) + 0.5;
    let fd = nbrdf_lerp(1.0, fd90, fl) * nbrdf_lerp(1.0, fd90, fv);
    let fss90 = r * cd2;
    let fss = nbrdf_lerp(1.0, fss90, fl) * nbrdf_lerp(1.0, fss90, fv);
    let ss = (fss * (1.0 / (g.cos_i + g.cos_o) - 0.5) + 0.5) * 1.25;
    let diffuse = nbrdf_lerp(fd, ss, m.subsurface) * NBRDF_INV_PI;
    // Primary specular: GTR2 and separable Smith GGX.
    let alpha = max(r * r, NBRDF_ALPHA_MIN);
    let ds = nbrdf_ggx_d(g.cos_h, g.sin2_h, alpha);
    let gs = nbrdf_smith_ggx_g1_over_2cos(g.cos_i, alpha) * nbrdf_smith_ggx_g1_over_2cos(g.cos_o, alpha);
    // Clearcoat: GTR1, fixed-roughness masking, F0 = 0.04.
    let dr = nbrdf_gtr1_d(g.cos_h, g.sin2_h, nbrdf_lerp(0.1, 0.001, m.clearcoat_gloss));
    let fr = nbrdf_lerp(0.04, 1.0, fh);
    let gr = nbrdf_smith_ggx_g1_over_2cos(g.cos_i, 0.25) * nbrdf_smith_ggx_g1_over_2cos(g.cos_o, 0.25);
    let coat = m.clearcoat * 0.25 * gr * fr * dr;
    var out = vec3<f32>(0.0);
    for (var i = 0; i < 3; i++) {
        let spec0 = nbrdf_lerp(m.specular * 0.08 * nbrdf_lerp(1.0, tint[i], m.specular_tint), c[i], m.metallic);
        let fs = nbrdf_lerp(spec0, 1.0, fh);
        let sheen = m.sheen * fh * nbrdf_lerp(1.0, tint[i], m.sheen_tint);
        out[i] = (diffuse * c[i] + sheen) * (1.0 - m.metallic) + gs * fs * ds + coat;
    }
    return nbrdf_sanitize(out);
}
