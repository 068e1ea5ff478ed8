// ---- nbrdf math: the core's numerics (src/math) in portable f32 -------------------------------------
// Every transcendental is written here rather than taken from the target's builtins: GPU sin/cos/exp/
// atan2 are approximations whose error the APIs bound loosely (Vulkan: sin within 2^-11 absolute), and
// the positional encoding takes sin(2^k x) of arguments up to ~2^18. These follow libm/Cephes, as the
// core does, so the shader agrees with it to a few ulp. Non-finite values are detected on their bits:
// WGSL lets a compiler assume that floating-point values are finite.

const NBRDF_PI: f32 = 3.14159265358979;
const NBRDF_TAU: f32 = 6.28318530717959;
const NBRDF_INV_PI: f32 = 0.318309886183791;

// Whether `x` is neither infinite nor NaN (exponent bits not all set).
fn nbrdf_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn nbrdf_finite3(v: vec3<f32>) -> bool {
    return nbrdf_finite(v.x) && nbrdf_finite(v.y) && nbrdf_finite(v.z);
}

// The last guard of every evaluation (core `math::sanitize`): a non-finite or non-positive channel is 0.
fn nbrdf_sanitize1(x: f32) -> f32 {
    return select(0.0, x, nbrdf_finite(x) && x > 0.0);
}

fn nbrdf_sanitize(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(nbrdf_sanitize1(v.x), nbrdf_sanitize1(v.y), nbrdf_sanitize1(v.z));
}

// A raw network output as the parametric maps read it: non-finite counts as 0 (core `raw_at`).
fn nbrdf_raw(x: f32) -> f32 {
    return select(0.0, x, nbrdf_finite(x));
}

// e^x (Cephes expf): x = k ln 2 + r in two exact steps, a degree-7 polynomial for e^r, then 2^k. The
// networks' maps never overflow it (softplus and the sigmoid take e^-|x|); above 88.7 it saturates.
fn nbrdf_exp(x: f32) -> f32 {
    if (x < -103.972) {
        return 0.0;
    }
    let xc = min(x, 88.72);
    let k = round(xc * 1.44269504088896);
    var r = xc - k * 0.693359375;
    r = r - k * -2.12194440e-4;
    var p = 1.9875691500e-4;
    p = p * r + 1.3981999507e-3;
    p = p * r + 8.3334519073e-3;
    p = p * r + 4.1665795894e-2;
    p = p * r + 1.6666665459e-1;
    p = p * r + 5.0000001201e-1;
    p = p * (r * r) + r + 1.0;
    return ldexp(p, i32(k));
}

// ln x for finite x > 0 (Cephes logf): x = 2^e m, m in [sqrt(1/2), sqrt(2)), a degree-9 polynomial.
fn nbrdf_log(x: f32) -> f32 {
    let fe = frexp(x);
    var m = fe.fract;
    var e = f32(fe.exp);
    if (m < 0.707106781186548) {
        e = e - 1.0;
        m = m + m - 1.0;
    } else {
        m = m - 1.0;
    }
    let z = m * m;
    var y = 7.0376836292e-2;
    y = y * m - 1.1514610310e-1;
    y = y * m + 1.1676998740e-1;
    y = y * m - 1.2420140846e-1;
    y = y * m + 1.4249322787e-1;
    y = y * m - 1.6668057665e-1;
    y = y * m + 2.0000714765e-1;
    y = y * m - 2.4999993993e-1;
    y = y * m + 3.3333331174e-1;
    y = y * m * z;
    y = y + -2.12194440e-4 * e;
    y = y + -0.5 * z;
    return m + y + 0.693359375 * e;
}

// ln(1 + u) for u in [0, 1] as 2 atanh(s), s = u / (2 + u) ≤ 1/3, by its series to s^15 (truncation
// 1e-8 relative): no rounding compensation for a compiler to reassociate away (llvmpipe folded
// `u - ((1 + u) - 1)` to 0, an error of half an ulp of 1 on softplus of very negative x).
fn nbrdf_log1p_unit(u: f32) -> f32 {
    let s = u / (2.0 + u);
    let t = s * s;
    let p = 1.0 + t * (0.33333334 + t * (0.2 + t * (0.14285715 + t * (0.11111111 + t * (0.09090909 + t * (0.07692308 + t * 0.06666667))))));
    return 2.0 * s * p;
}

// Softplus ln(1 + e^x) as max(x, 0) + ln(1 + e^-|x|): never overflows (core `math::softplus`).
fn nbrdf_softplus(x: f32) -> f32 {
    return max(x, 0.0) + nbrdf_log1p_unit(nbrdf_exp(-abs(x)));
}

// The logistic sigmoid, stable on both sides (core `math::sigmoid`).
fn nbrdf_sigmoid(x: f32) -> f32 {
    if (x >= 0.0) {
        return 1.0 / (1.0 + nbrdf_exp(-x));
    }
    let e = nbrdf_exp(x);
    return e / (1.0 + e);
}

// e^x - 1 without cancellation near 0 (NBRDF-json outputs): k = round(x / ln 2), r = x - k ln 2 in two
// exact steps, expm1(r) by its Taylor series to degree 9, then 2^k expm1(r) + (2^k - 1). The caller
// handles x above the f32 overflow (88.72), where the core's value is infinite and so sanitised to 0.
fn nbrdf_expm1(x: f32) -> f32 {
    let k = min(round(x * 1.44269504088896), 127.0);
    var r = x - k * 0.693145751953125;
    r = r - k * 1.428606765330187e-6;
    var q = 1.0 / 362880.0;
    q = q * r + 1.0 / 40320.0;
    q = q * r + 1.0 / 5040.0;
    q = q * r + 1.0 / 720.0;
    q = q * r + 1.0 / 120.0;
    q = q * r + 1.0 / 24.0;
    q = q * r + 1.0 / 6.0;
    q = q * r + 0.5;
    let em = r + r * r * q;
    if (k == 0.0) {
        return em;
    }
    let two_k = ldexp(1.0, i32(k));
    return two_k * em + (two_k - 1.0);
}

// b^e for b > 0 (the parametric models' powers): e^(e ln b); 0^e = 0 for e > 0.
fn nbrdf_pow(b: f32, e: f32) -> f32 {
    if (b <= 0.0) {
        return select(1.0, 0.0, e > 0.0);
    }
    return nbrdf_exp(e * nbrdf_log(b));
}

// atan x (musl atanf): four reduction intervals with atan of their centres split hi + lo, an odd
// polynomial on the rest.
fn nbrdf_atan(x: f32) -> f32 {
    let ix = bitcast<u32>(x) & 0x7fffffffu;
    let negative = (bitcast<u32>(x) >> 31u) != 0u;
    if (ix >= 0x4c800000u) {
        return select(1.57079637050629, -1.57079637050629, negative);
    }
    var id = -1;
    var t = x;
    if (ix < 0x3ee00000u) {
        if (ix < 0x39800000u) {
            return x;
        }
    } else {
        t = abs(x);
        if (ix < 0x3f980000u) {
            if (ix < 0x3f300000u) {
                id = 0;
                t = (2.0 * t - 1.0) / (2.0 + t);
            } else {
                id = 1;
                t = (t - 1.0) / (t + 1.0);
            }
        } else {
            if (ix < 0x401c0000u) {
                id = 2;
                t = (t - 1.5) / (1.0 + 1.5 * t);
            } else {
                id = 3;
                t = -1.0 / t;
            }
        }
    }
    let z = t * t;
    let w = z * z;
    let s1 = z * (3.3333328366e-01 + w * (1.4253635705e-01 + w * 6.1687607318e-02));
    let s2 = w * (-1.9999158382e-01 + w * -1.0648017377e-01);
    if (id < 0) {
        return t - t * (s1 + s2);
    }
    var hi = 4.6364760399e-01;
    var lo = 5.0121582440e-09;
    if (id == 1) {
        hi = 7.8539812565e-01;
        lo = 3.7748947079e-08;
    } else if (id == 2) {
        hi = 9.8279368877e-01;
        lo = 3.4473217170e-08;
    } else if (id == 3) {
        hi = 1.5707962513e+00;
        lo = 7.5497894159e-08;
    }
    let r = hi - ((t * (s1 + s2) - lo) - t);
    return select(r, -r, negative);
}

// atan2(y, x) for finite arguments (musl atan2f), signed zeros by their bits: atan2(+0, -0) = π.
fn nbrdf_atan2(y: f32, x: f32) -> f32 {
    let ix = bitcast<u32>(x);
    let iy = bitcast<u32>(y);
    if (ix == 0x3f800000u) {
        return nbrdf_atan(y);
    }
    let m = ((iy >> 31u) & 1u) | ((ix >> 30u) & 2u);
    let ax = ix & 0x7fffffffu;
    let ay = iy & 0x7fffffffu;
    let pi_lo = -8.7422776573e-08;
    if (ay == 0u) {
        if (m <= 1u) {
            return y;
        }
        return select(-3.14159274101257, 3.14159274101257, m == 2u);
    }
    if (ax == 0u) {
        return select(1.57079637050629, -1.57079637050629, (m & 1u) != 0u);
    }
    if (ax + (26u << 23u) < ay) {
        return select(1.57079637050629, -1.57079637050629, (m & 1u) != 0u);
    }
    var z = 0.0;
    if (!((m & 2u) != 0u && ay + (26u << 23u) < ax)) {
        z = nbrdf_atan(abs(y / x));
    }
    if (m == 0u) {
        return z;
    }
    if (m == 1u) {
        return -z;
    }
    if (m == 2u) {
        return 3.14159274101257 - (z - pi_lo);
    }
    return (z - pi_lo) - 3.14159274101257;
}

// (sin x, cos x): x - j π/2 with π/2 in six 6-bit pieces and a rest (Cody-Waite: every product j·piece
// is exact for |j| < 2^18, so the reduction is exact to the f32 remainder up to |x| ≈ 4e5: the
// encoding's 2^15 · 2π), then the Cephes polynomials on |r| ≤ π/4 and the quadrant. Beyond that
// range (never in a valid model) the target's builtins.
fn nbrdf_sincos(x: f32) -> vec2<f32> {
    if (!(abs(x) < 262144.0)) {
        return vec2<f32>(sin(x), cos(x));
    }
    let j = round(x * 0.636619746685028);
    var r = x - j * 1.5625;
    r = r - j * 0.008056640625;
    r = r - j * 0.00023651123046875;
    r = r - j * 3.159046173095703e-06;
    r = r - j * 1.5832483768463135e-08;
    r = r - j * 6.002665031701326e-11;
    r = r - j * 7.443547731314504e-13;
    let z = r * r;
    let s = ((-1.9515295891e-4 * z + 8.3321608736e-3) * z - 1.6666654611e-1) * z * r + r;
    let c = ((2.443315711809948e-5 * z - 1.388731625493765e-3) * z + 4.166664568298827e-2) * z * z - 0.5 * z + 1.0;
    let q = i32(j) & 3;
    if (q == 0) {
        return vec2<f32>(s, c);
    }
    if (q == 1) {
        return vec2<f32>(c, -s);
    }
    if (q == 2) {
        return vec2<f32>(-s, -c);
    }
    return vec2<f32>(-c, s);
}
