// ---- nbrdf sampling (src/sampling): warps and the GGX visible-normal lobes of the sampling proxy -----
// A sample draws wi for the view wo from three uniforms; its pdf is always the whole mixture's density
// per unit solid angle of wi, so weight = f cos θi / pdf is unbiased (core `sampling`).

// The result of nbrdf_sample: ok = false where the core returns None (wo below the horizon, a lobe's
// direction below it, a zero pdf); then the other fields are 0.
struct NbrdfSample {
    wi: vec3<f32>,
    pdf: f32,
    weight: vec3<f32>,
    ok: bool,
}

fn nbrdf_no_sample() -> NbrdfSample {
    return NbrdfSample(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), false);
}

// wo normalised and above the horizon in .xyz, .w = 1; .w = 0 otherwise (core `valid_wo`).
fn nbrdf_valid_wo(wo: vec3<f32>) -> vec4<f32> {
    let u = nbrdf_unit(wo);
    if (u.w > 0.0 && u.z > 0.0) {
        return u;
    }
    return vec4<f32>(0.0);
}

fn nbrdf_square_to_disk_concentric(u: vec2<f32>) -> vec2<f32> {
    let a = 2.0 * u.x - 1.0;
    let b = 2.0 * u.y - 1.0;
    if (a == 0.0 && b == 0.0) {
        return vec2<f32>(0.0);
    }
    var r = b;
    var phi = 0.5 * NBRDF_PI - 0.25 * NBRDF_PI * (a / b);
    if (abs(a) > abs(b)) {
        r = a;
        phi = 0.25 * NBRDF_PI * (b / a);
    }
    let sc = nbrdf_sincos(phi);
    return vec2<f32>(r * sc.y, r * sc.x);
}

fn nbrdf_square_to_cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let d = nbrdf_square_to_disk_concentric(u);
    let z = max(sqrt(max(1.0 - d.x * d.x - d.y * d.y, 0.0)), 1e-7);
    return vec3<f32>(d.x, d.y, z);
}

fn nbrdf_cosine_hemisphere_pdf(w: vec3<f32>) -> f32 {
    return select(0.0, w.z * NBRDF_INV_PI, w.z > 0.0);
}

fn nbrdf_normalize(v: vec3<f32>) -> vec3<f32> {
    return v / sqrt((v.x * v.x + v.y * v.y) + v.z * v.z);
}

fn nbrdf_reflect_about(wo: vec3<f32>, h: vec3<f32>) -> vec3<f32> {
    return h * (2.0 * dot(wo, h)) - wo;
}

// Visible normals of GGX (Heitz 2018, "Sampling the GGX Distribution of Visible Normals").
fn nbrdf_sample_ggx_vndf(wo: vec3<f32>, alpha: f32, u: vec2<f32>) -> vec3<f32> {
    let vh = nbrdf_normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3<f32>(1.0, 0.0, 0.0);
    if (lensq > 0.0) {
        t1 = vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(lensq);
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let sc = nbrdf_sincos(2.0 * NBRDF_PI * u.y);
    let p1 = r * sc.y;
    let sh = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - sh) * sqrt(max(1.0 - p1 * p1, 0.0)) + sh * (r * sc.x);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return nbrdf_normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-7)));
}

fn nbrdf_ggx_vndf_pdf(wo: vec3<f32>, h: vec3<f32>, alpha: f32) -> f32 {
    let oh = dot(wo, h);
    if (!(oh > 0.0 && wo.z > 0.0 && h.z > 0.0)) {
        return 0.0;
    }
    let sin2_h = h.x * h.x + h.y * h.y;
    let c2 = wo.z * wo.z;
    let g1 = 2.0 * wo.z / (sqrt(max(alpha * alpha * (1.0 - c2) + c2, 0.0)) + wo.z);
    let a2 = alpha * alpha;
    let t = a2 * h.z * h.z + sin2_h;
    return g1 * oh * (a2 * NBRDF_INV_PI / (t * t)) / wo.z;
}

// The half vector of a valid pair with wo·h in .w, or .w = 0 (core `half_of`).
fn nbrdf_half_of(wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    let pair = nbrdf_upper_pair(wi, wo);
    if (!pair.ok) {
        return vec4<f32>(0.0);
    }
    let h = nbrdf_unit(pair.wi + pair.wo);
    if (h.w <= 0.0) {
        return vec4<f32>(0.0);
    }
    let oh = dot(pair.wo, h.xyz);
    if (!(oh > 0.0)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(h.xyz, oh);
}

fn nbrdf_finish(wi: vec3<f32>, pdf: f32, f: vec3<f32>) -> NbrdfSample {
    if (!(wi.z > 0.0 && nbrdf_finite3(wi) && pdf > 0.0 && nbrdf_finite(pdf))) {
        return nbrdf_no_sample();
    }
    return NbrdfSample(wi, pdf, nbrdf_sanitize(f * (wi.z / pdf)), true);
}

// The sampling proxy (core `sampling::Proxy`): a cosine lobe of probability .x and GGX visible-normal
// lobes of probabilities .y, .z with roughness NBRDF_PROXY_ALPHA.
fn nbrdf_proxy_choose(p: vec3<f32>, u: f32) -> i32 {
    var acc = p.x;
    if (u < acc) {
        return 0;
    }
    acc = acc + p.y;
    if (u < acc && p.y > 0.0) {
        return 1;
    }
    acc = acc + p.z;
    if (u < acc && p.z > 0.0) {
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

fn nbrdf_proxy_pdf(p: vec3<f32>, alpha: vec2<f32>, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    let pair = nbrdf_upper_pair(wi, wo);
    if (!pair.ok) {
        return 0.0;
    }
    var pdf = p.x * nbrdf_cosine_hemisphere_pdf(pair.wi);
    let h = nbrdf_half_of(pair.wo, pair.wi);
    if (h.w > 0.0) {
        if (p.y > 0.0) {
            pdf = pdf + p.y * nbrdf_ggx_vndf_pdf(pair.wo, h.xyz, alpha.x) / (4.0 * h.w);
        }
        if (p.z > 0.0) {
            pdf = pdf + p.z * nbrdf_ggx_vndf_pdf(pair.wo, h.xyz, alpha.y) / (4.0 * h.w);
        }
    }
    return select(0.0, pdf, nbrdf_finite(pdf) && pdf > 0.0);
}

// wi drawn from the proxy for the view wo, .w = 0 where the core's `sample_wi` gives None.
fn nbrdf_proxy_sample_wi(p: vec3<f32>, alpha: vec2<f32>, u: vec3<f32>, wo_in: vec3<f32>) -> vec4<f32> {
    let wo = nbrdf_valid_wo(wo_in);
    if (wo.w <= 0.0) {
        return vec4<f32>(0.0);
    }
    var wi = vec3<f32>(0.0);
    let k = nbrdf_proxy_choose(p, u.z);
    if (k == 0) {
        wi = nbrdf_square_to_cosine_hemisphere(u.xy);
    } else {
        let a = select(alpha.y, alpha.x, k == 1);
        wi = nbrdf_reflect_about(wo.xyz, nbrdf_sample_ggx_vndf(wo.xyz, a, u.xy));
    }
    if (wi.z > 0.0 && nbrdf_finite3(wi)) {
        return vec4<f32>(wi, 1.0);
    }
    return vec4<f32>(0.0);
}
