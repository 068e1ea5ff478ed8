// nbrdf for C++17: RAII handles and exceptions over the C ABI in nbrdf.h, and a pbrt-v4-style BxDF
// adapter. Header-only; link with libnbrdf.a (plus -lpthread -ldl -lm on Linux) or libnbrdf.so.
//
//   nbrdf::Brdf brdf = nbrdf::Brdf::load("fitted.nbrdf");     // throws nbrdf::Error on failure
//   nbrdf::Point at = brdf.prepare({x, y, z});                 // once per shading point
//   nbrdf::Rgb f = brdf.eval(at, wi, wo);                      // 1/sr, cosine not included
//   if (auto s = brdf.sample(at, wo, {u0, u1, u2})) { /* s->wi, s->weight, s->pdf */ }
//
// Conventions (nbrdf.h has the full table): local shading frame with the normal on +z; wi toward the
// light, wo toward the viewer, both pointing away from the surface. pbrt-v4 uses the same names (its
// f(wo, wi) is eval(wi, wo)); Mitsuba 3 calls the viewer direction si.wi.
//
// Threads: a Brdf is immutable after loading; its const methods may run on many threads at once.
#ifndef NBRDF_HPP
#define NBRDF_HPP

#include "nbrdf.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace nbrdf {

using Vec3 = std::array<float, 3>;
using Rgb = std::array<float, 3>;

// A failed call: the C status and this thread's message.
class Error : public std::runtime_error {
  public:
    Error(NbrdfStatus status, const char *message) : std::runtime_error(message), status_(status) {}
    NbrdfStatus status() const noexcept { return status_; }

  private:
    NbrdfStatus status_;
};

namespace detail {
inline void check(NbrdfStatus s) {
    if (s != NBRDF_STATUS_OK) throw Error(s, nbrdf_last_error());
}
}  // namespace detail

// A BRDF prepared at one surface point: plain data, copyable, valid as long as its Brdf.
class Point {
  public:
    Point() = default;
    const void *data() const noexcept { return storage_.data(); }
    void *data() noexcept { return storage_.data(); }

  private:
    alignas(NBRDF_POINT_MAX_ALIGN) std::array<unsigned char, NBRDF_POINT_MAX_SIZE> storage_{};
};

// A sampled direction: wi toward the light, weight = f cos(theta_i) / pdf, pdf per solid angle.
struct Sample {
    Vec3 wi;
    Rgb weight;
    float pdf;
};

// One loaded BRDF (a .nbrdf model, MERL table, NBRDF-json network, parametric model or built-in).
// Move-only; frees itself.
class Brdf {
  public:
    // A .nbrdf, .json (NBRDF-json) or .binary (MERL) file, by extension.
    static Brdf load(const std::string &path) { return make([&](NbrdfBrdf **o) { return nbrdf_load(path.c_str(), o); }); }
    // A .nbrdf model from bytes (copied).
    static Brdf model_from_bytes(const std::uint8_t *bytes, std::size_t len) {
        return make([&](NbrdfBrdf **o) { return nbrdf_model_from_bytes(bytes, len, o); });
    }
    // A .nbrdf model over bytes that stay alive and 4-byte aligned until this Brdf is destroyed.
    static Brdf model_borrow(const std::uint8_t *bytes, std::size_t len) {
        return make([&](NbrdfBrdf **o) { return nbrdf_model_borrow(bytes, len, o); });
    }
    // A parametric model from natural parameters (order in nbrdf.h, NbrdfParametricKind).
    static Brdf parametric(NbrdfParametricKind kind, const std::vector<float> &params) {
        return make([&](NbrdfBrdf **o) { return nbrdf_parametric(kind, params.data(), params.size(), o); });
    }
    // A parametric model from raw network outputs (and per-object parameters: the FMBRDF's one).
    static Brdf parametric_from_raw(NbrdfParametricKind kind, const std::vector<float> &raw, const std::vector<float> &object = {}) {
        return make([&](NbrdfBrdf **o) {
            return nbrdf_parametric_from_raw(kind, raw.data(), raw.size(), object.data(), object.size(), o);
        });
    }
    // "two-lobe-metal", "clear-coat" or "velvet".
    static Brdf builtin(const std::string &id) { return make([&](NbrdfBrdf **o) { return nbrdf_builtin(id.c_str(), o); }); }

    Brdf(Brdf &&other) noexcept : h_(std::exchange(other.h_, nullptr)) {}
    Brdf &operator=(Brdf &&other) noexcept {
        if (this != &other) {
            nbrdf_free(h_);
            h_ = std::exchange(other.h_, nullptr);
        }
        return *this;
    }
    Brdf(const Brdf &) = delete;
    Brdf &operator=(const Brdf &) = delete;
    ~Brdf() { nbrdf_free(h_); }

    NbrdfInfo info() const {
        NbrdfInfo i;
        detail::check(nbrdf_info(h_, &i));
        return i;
    }
    bool is_reciprocal() const { return info().reciprocal; }

    // The BRDF at a point: `position` holds info().position_len floats.
    Point prepare(const std::vector<float> &position = {}) const {
        Point p;
        detail::check(nbrdf_prepare(h_, position.data(), position.size(), p.data(), NBRDF_POINT_MAX_SIZE));
        return p;
    }

    // f(wi, wo) at a point (nullptr: a BRDF that is the same everywhere).
    Rgb eval(const Point *at, const Vec3 &wi, const Vec3 &wo) const {
        Rgb f;
        detail::check(nbrdf_eval(h_, at ? at->data() : nullptr, wi.data(), wo.data(), f.data()));
        return f;
    }
    Rgb eval(const Point &at, const Vec3 &wi, const Vec3 &wo) const { return eval(&at, wi, wo); }
    Rgb eval(const Vec3 &wi, const Vec3 &wo) const { return eval(nullptr, wi, wo); }

    // Many pairs at one point, structure of arrays (n values behind every pointer).
    void eval_many(const Point *at, std::size_t n, NbrdfDirections wi, NbrdfDirections wo, NbrdfRgbArrays out) const {
        detail::check(nbrdf_eval_many(h_, at ? at->data() : nullptr, n, wi, wo, out));
    }

    // A direction toward the light for the view wo, or nothing (wo below the horizon, or a lobe
    // reflected below it).
    std::optional<Sample> sample(const Point *at, const Vec3 &wo, const Vec3 &u) const {
        NbrdfSample s;
        detail::check(nbrdf_sample(h_, at ? at->data() : nullptr, wo.data(), u.data(), &s));
        if (s.pdf == 0.0f) return std::nullopt;
        return Sample{{s.wi[0], s.wi[1], s.wi[2]}, {s.weight[0], s.weight[1], s.weight[2]}, s.pdf};
    }
    std::optional<Sample> sample(const Point &at, const Vec3 &wo, const Vec3 &u) const { return sample(&at, wo, u); }

    // Density of sample() at wi for the view wo, per unit solid angle.
    float pdf(const Point *at, const Vec3 &wi, const Vec3 &wo) const {
        float p;
        detail::check(nbrdf_pdf(h_, at ? at->data() : nullptr, wi.data(), wo.data(), &p));
        return p;
    }
    float pdf(const Point &at, const Vec3 &wi, const Vec3 &wo) const { return pdf(&at, wi, wo); }

    const NbrdfBrdf *get() const noexcept { return h_; }

  private:
    explicit Brdf(NbrdfBrdf *h) : h_(h) {}
    template <class F>
    static Brdf make(F &&f) {
        NbrdfBrdf *h = nullptr;
        detail::check(f(&h));
        return Brdf(h);
    }
    NbrdfBrdf *h_ = nullptr;
};

// The flags a pbrt-v4 BxDF reports; an nbrdf BRDF is reflective and glossy (never specular: every
// value is finite, and sampling always has a density).
enum class BxDFFlags : unsigned { Unset = 0, Reflection = 1, Transmission = 2, Diffuse = 4, Glossy = 8, Specular = 16 };

// What pbrt-v4's BxDF::Sample_f returns: the BRDF value, the direction, its density and its flags.
struct BSDFSample {
    Rgb f;
    Vec3 wi;
    float pdf;
    BxDFFlags flags;
};

// A pbrt-v4-style BxDF over an nbrdf BRDF at one point, in pbrt's argument order. pbrt-v4's
// MeasuredBxDF swapped wi and wo between Sample_f and f/PDF (pbrt-v4 #207, #215); here the order is
// pbrt's everywhere: `wo` is the viewer, `wi` the light, and f(wo, wi) = nbrdf eval(wi, wo).
//
//   pbrt::SampledSpectrum f(Vector3f wo, Vector3f wi, TransportMode) -> BxDF::f(wo, wi)
//   pstd::optional<BSDFSample> Sample_f(wo, uc, u2, mode, flags)  -> BxDF::Sample_f(wo, uc, {u2.x, u2.y})
//   Float PDF(wo, wi, mode, flags)                                -> BxDF::PDF(wo, wi)
//   BxDFFlags Flags()                                             -> BxDF::Flags()
// Convert RGB to pbrt's SampledSpectrum with RGBUnboundedSpectrum at the wavelengths of the path.
class BxDF {
  public:
    // `brdf` must outlive the adapter; `at` is its point (nullptr for a BRDF the same everywhere).
    BxDF(const Brdf &brdf, const Point *at) : brdf_(&brdf), at_(at) {}
    Rgb f(const Vec3 &wo, const Vec3 &wi) const { return brdf_->eval(at_, wi, wo); }
    std::optional<BSDFSample> Sample_f(const Vec3 &wo, float uc, const std::array<float, 2> &u2) const {
        // nbrdf's third uniform picks the lobe, as pbrt's uc does.
        auto s = brdf_->sample(at_, wo, {u2[0], u2[1], uc});
        if (!s) return std::nullopt;
        return BSDFSample{f(wo, s->wi), s->wi, s->pdf, Flags()};
    }
    float PDF(const Vec3 &wo, const Vec3 &wi) const { return brdf_->pdf(at_, wi, wo); }
    BxDFFlags Flags() const { return BxDFFlags(unsigned(BxDFFlags::Reflection) | unsigned(BxDFFlags::Glossy)); }

  private:
    const Brdf *brdf_;
    const Point *at_;
};

}  // namespace nbrdf

#endif  // NBRDF_HPP
