// ---- nbrdf parametric sampling (src/sampling/mod.rs): each model samples its own lobes --------------
// A lobe is chosen with probability proportional to an estimate of its albedo at wo; the pdf reported is
// the mixture's (one-sample MIS with the balance heuristic), as in the core.

fn nbrdf_lum(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// Lobe probabilities from non-negative estimates; all zero selects the first lobe (core `normalise`).
fn nbrdf_normalise3(w_in: vec3<f32>) -> vec3<f32> {
    let w = vec3<f32>(nbrdf_sanitize1(w_in.x), nbrdf_sanitize1(w_in.y), nbrdf_sanitize1(w_in.z));
    let s = (w.x + w.y) + w.z;
    if (s > 0.0) {
        return w / s;
    }
    return vec3<f32>(1.0, 0.0, 0.0);
}

fn nbrdf_choose(p: vec3<f32>, u: f32) -> i32 {
    var acc = p.x;
    if (u < acc) {
        return 0;
    }
    acc = acc + p.y;
    if (u < acc) {
        return 1;
    }
    acc = acc + p.z;
    if (u < acc) {
        return 2;
    }
    if (p.z > 0.0) {
        return 2;
    }
    if (p.y > 0.0) {
        return 1;
    }
    return 0;
}

fn nbrdf_orthonormal_basis_t(n: vec3<f32>) -> vec3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
}

fn nbrdf_orthonormal_basis_b(n: vec3<f32>) -> vec3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return vec3<f32>(b, sign + n.y * n.y * a, -n.y);
}

fn nbrdf_around(n: vec3<f32>, cos_t: f32, phi: f32) -> vec3<f32> {
    let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    let sc = nbrdf_sincos(phi);
    return nbrdf_orthonormal_basis_t(n) * (sin_t * sc.y) + nbrdf_orthonormal_basis_b(n) * (sin_t * sc.x) + n * cos_t;
}

fn nbrdf_sample_beckmann(alpha: f32, u: vec2<f32>) -> vec3<f32> {
    let tan2 = -alpha * alpha * nbrdf_log(1.0 - u.x);
    let cos_t = 1.0 / sqrt(1.0 + tan2);
    return nbrdf_around(vec3<f32>(0.0, 0.0, 1.0), max(cos_t, 1e-7), 2.0 * NBRDF_PI * u.y);
}

fn nbrdf_sample_gtr1(alpha: f32, u: vec2<f32>) -> vec3<f32> {
    let a2 = alpha * alpha;
    var cos2 = 1.0 - u.x;
    if (alpha < 1.0) {
        cos2 = (1.0 - nbrdf_pow(a2, 1.0 - u.x)) / (1.0 - a2);
    }
    return nbrdf_around(vec3<f32>(0.0, 0.0, 1.0), max(sqrt(max(cos2, 0.0)), 1e-7), 2.0 * NBRDF_PI * u.y);
}

fn nbrdf_sample_phong_lobe(axis: vec3<f32>, n: f32, u: vec2<f32>) -> vec3<f32> {
    return nbrdf_around(axis, nbrdf_pow(u.x, 1.0 / (n + 1.0)), 2.0 * NBRDF_PI * u.y);
}

fn nbrdf_phong_lobe_pdf(cos_a: f32, n: f32) -> f32 {
    if (cos_a > 0.0) {
        return (n + 1.0) * (0.5 * NBRDF_INV_PI) * nbrdf_pow(min(cos_a, 1.0), n);
    }
    return 0.0;
}

// D(h) cos θh / (4 wo·h) of a pair, for a distribution `kind`: 0 Beckmann, 1 GTR1.
fn nbrdf_half_vector_pdf(wo: vec3<f32>, wi: vec3<f32>, kind: i32, alpha: f32) -> f32 {
    let h = nbrdf_half_of(wo, wi);
    if (h.w <= 0.0) {
        return 0.0;
    }
    let sin2 = h.x * h.x + h.y * h.y;
    var d = nbrdf_beckmann_d(h.z, sin2, alpha);
    if (kind == 1) {
        d = nbrdf_gtr1_d(h.z, sin2, alpha);
    }
    return d * h.z / (4.0 * h.w);
}

fn nbrdf_final_pdf(p: f32) -> f32 {
    return select(0.0, p, nbrdf_finite(p) && p > 0.0);
}

// -- Lambert: the cosine lobe.
fn nbrdf_lambert_pdf(m: NbrdfLambert, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi, wo);
    if (!pair.ok) {
        return 0.0;
    }
    return nbrdf_final_pdf(nbrdf_cosine_hemisphere_pdf(pair.wi));
}

fn nbrdf_lambert_sample(m: NbrdfLambert, u: vec3<f32>, wo_in: vec3<f32>) -> NbrdfSample {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return nbrdf_no_sample();
    }
    let wi = nbrdf_square_to_cosine_hemisphere(u.xy);
    return nbrdf_finish(wi, nbrdf_cosine_hemisphere_pdf(wi), nbrdf_lambert_eval(m, wi, wo.xyz));
}

// -- RP: cosine + the Phong lobe about the mirror direction of wo.
fn nbrdf_phong_probabilities(m: NbrdfPhong) -> vec3<f32> {
    return nbrdf_normalise3(vec3<f32>(nbrdf_lum(m.kd), nbrdf_lum(m.ks), 0.0));
}

fn nbrdf_phong_pdf(m: NbrdfPhong, wo_in: vec3<f32>, wi_in: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return 0.0;
    }
    let p = nbrdf_phong_probabilities(m);
    let cos_a = nbrdf_phong_cos_alpha(pair.wi, pair.wo);
    return nbrdf_final_pdf(p.x * nbrdf_cosine_hemisphere_pdf(pair.wi) + p.y * nbrdf_phong_lobe_pdf(cos_a, m.n));
}

fn nbrdf_phong_sample(m: NbrdfPhong, u: vec3<f32>, wo_in: vec3<f32>) -> NbrdfSample {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return nbrdf_no_sample();
    }
    var wi = nbrdf_square_to_cosine_hemisphere(u.xy);
    if (nbrdf_choose(nbrdf_phong_probabilities(m), u.z) != 0) {
        let mirror = vec3<f32>(-wo.x, -wo.y, wo.z);
        wi = nbrdf_sample_phong_lobe(mirror, m.n, u.xy);
    }
    return nbrdf_finish(wi, nbrdf_phong_pdf(m, wo.xyz, wi), nbrdf_phong_eval(m, wi, wo.xyz));
}

// -- Torrance-Sparrow and FMBRDF: cosine + Beckmann half vectors.
fn nbrdf_cosine_beckmann_pdf(p: vec3<f32>, alpha: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    let a = nbrdf_clamp_alpha(alpha);
    return p.x * nbrdf_cosine_hemisphere_pdf(wi) + p.y * nbrdf_half_vector_pdf(wo, wi, 0, a);
}

fn nbrdf_cosine_beckmann_sample(p: vec3<f32>, alpha: f32, u: vec3<f32>, wo: vec3<f32>) -> vec3<f32> {
    if (nbrdf_choose(p, u.z) == 0) {
        return nbrdf_square_to_cosine_hemisphere(u.xy);
    }
    return nbrdf_reflect_about(wo, nbrdf_sample_beckmann(nbrdf_clamp_alpha(alpha), u.xy));
}

fn nbrdf_torrance_sparrow_probabilities(m: NbrdfTorranceSparrow, wo: vec3<f32>) -> vec3<f32> {
    let spec = vec3<f32>(
        nbrdf_fresnel_schlick(m.ks.x, wo.z),
        nbrdf_fresnel_schlick(m.ks.y, wo.z),
        nbrdf_fresnel_schlick(m.ks.z, wo.z),
    );
    return nbrdf_normalise3(vec3<f32>(nbrdf_lum(m.kd), nbrdf_lum(spec), 0.0));
}

fn nbrdf_torrance_sparrow_pdf(m: NbrdfTorranceSparrow, wo_in: vec3<f32>, wi_in: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return 0.0;
    }
    let p = nbrdf_torrance_sparrow_probabilities(m, pair.wo);
    return nbrdf_final_pdf(nbrdf_cosine_beckmann_pdf(p, m.alpha, pair.wo, pair.wi));
}

fn nbrdf_torrance_sparrow_sample(m: NbrdfTorranceSparrow, u: vec3<f32>, wo_in: vec3<f32>) -> NbrdfSample {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return nbrdf_no_sample();
    }
    let p = nbrdf_torrance_sparrow_probabilities(m, wo.xyz);
    let wi = nbrdf_cosine_beckmann_sample(p, m.alpha, u, wo.xyz);
    return nbrdf_finish(wi, nbrdf_torrance_sparrow_pdf(m, wo.xyz, wi), nbrdf_torrance_sparrow_eval(m, wi, wo.xyz));
}

fn nbrdf_fresnel_microfacet_probabilities(m: NbrdfFresnelMicrofacet, wo: vec3<f32>) -> vec3<f32> {
    let f = nbrdf_fresnel_dielectric(wo.z, m.eta);
    return nbrdf_normalise3(vec3<f32>(nbrdf_lum(m.rho) * (1.0 - f), m.ks * f, 0.0));
}

fn nbrdf_fresnel_microfacet_pdf(m: NbrdfFresnelMicrofacet, wo_in: vec3<f32>, wi_in: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return 0.0;
    }
    let p = nbrdf_fresnel_microfacet_probabilities(m, pair.wo);
    return nbrdf_final_pdf(nbrdf_cosine_beckmann_pdf(p, m.alpha, pair.wo, pair.wi));
}

fn nbrdf_fresnel_microfacet_sample(m: NbrdfFresnelMicrofacet, u: vec3<f32>, wo_in: vec3<f32>) -> NbrdfSample {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return nbrdf_no_sample();
    }
    let p = nbrdf_fresnel_microfacet_probabilities(m, wo.xyz);
    let wi = nbrdf_cosine_beckmann_sample(p, m.alpha, u, wo.xyz);
    return nbrdf_finish(wi, nbrdf_fresnel_microfacet_pdf(m, wo.xyz, wi), nbrdf_fresnel_microfacet_eval(m, wi, wo.xyz));
}

// -- Disney: cosine (diffuse, subsurface, sheen) + GGX visible normals + GTR1 clearcoat.
fn nbrdf_disney_alpha(m: NbrdfDisney) -> f32 {
    return max(m.roughness * m.roughness, NBRDF_ALPHA_MIN);
}

fn nbrdf_disney_probabilities(m: NbrdfDisney, wo: vec3<f32>) -> vec3<f32> {
    let c = m.base_color;
    let tint = nbrdf_disney_tint(c);
    let fw = nbrdf_schlick_weight(wo.z);
    var spec = vec3<f32>(0.0);
    for (var k = 0; k < 3; k++) {
        let s0 = nbrdf_lerp(m.specular * 0.08 * nbrdf_lerp(1.0, tint[k], m.specular_tint), c[k], m.metallic);
        spec[k] = nbrdf_lerp(s0, 1.0, fw);
    }
    return nbrdf_normalise3(vec3<f32>(
        (1.0 - m.metallic) * (nbrdf_lum(c) + m.sheen),
        nbrdf_lum(spec),
        0.25 * m.clearcoat * nbrdf_lerp(0.04, 1.0, fw),
    ));
}

fn nbrdf_disney_pdf(m: NbrdfDisney, wo_in: vec3<f32>, wi_in: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi_in, wo_in);
    if (!pair.ok) {
        return 0.0;
    }
    let p = nbrdf_disney_probabilities(m, pair.wo);
    let h = nbrdf_half_of(pair.wo, pair.wi);
    if (h.w <= 0.0) {
        return nbrdf_final_pdf(p.x * nbrdf_cosine_hemisphere_pdf(pair.wi));
    }
    let spec = nbrdf_ggx_vndf_pdf(pair.wo, h.xyz, nbrdf_disney_alpha(m)) / (4.0 * h.w);
    let coat = nbrdf_half_vector_pdf(pair.wo, pair.wi, 1, nbrdf_lerp(0.1, 0.001, m.clearcoat_gloss));
    return nbrdf_final_pdf(p.x * nbrdf_cosine_hemisphere_pdf(pair.wi) + p.y * spec + p.z * coat);
}

fn nbrdf_disney_sample(m: NbrdfDisney, u: vec3<f32>, wo_in: vec3<f32>) -> NbrdfSample {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return nbrdf_no_sample();
    }
    let k = nbrdf_choose(nbrdf_disney_probabilities(m, wo.xyz), u.z);
    var wi = nbrdf_square_to_cosine_hemisphere(u.xy);
    if (k == 1) {
        wi = nbrdf_reflect_about(wo.xyz, nbrdf_sample_ggx_vndf(wo.xyz, nbrdf_disney_alpha(m), u.xy));
    } else if (k == 2) {
        wi = nbrdf_reflect_about(wo.xyz, nbrdf_sample_gtr1(nbrdf_lerp(0.1, 0.001, m.clearcoat_gloss), u.xy));
    }
    return nbrdf_finish(wi, nbrdf_disney_pdf(m, wo.xyz, wi), nbrdf_disney_eval(m, wi, wo.xyz));
}
