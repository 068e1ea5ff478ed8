// The C++17 header nbrdf.hpp: reads the cases and pairs the Rust test wrote into DIR and writes every
// value, batch, sample and density through the RAII classes (the test compares them with the Rust
// API bit for bit); checks that errors throw nbrdf::Error with their status, and that the pbrt-style
// BxDF adapter is the BRDF in pbrt's argument order. Usage: api_test_cpp DIR.
#include "nbrdf.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

static int failures = 0;
#define CHECK(cond, what)                                                                     \
    do {                                                                                      \
        if (!(cond)) {                                                                        \
            std::cerr << "FAILED " << __FILE__ << ":" << __LINE__ << ": " << what << "\n";    \
            failures++;                                                                       \
        }                                                                                     \
    } while (0)

static std::vector<unsigned char> read_bytes(const std::string &path) {
    std::ifstream f(path, std::ios::binary);
    return std::vector<unsigned char>(std::istreambuf_iterator<char>(f), {});
}

static nbrdf::Brdf make(const std::string &kind, const std::string &arg, std::vector<std::uint32_t> &keep) {
    if (kind == "builtin") return nbrdf::Brdf::builtin(arg);
    if (kind == "file") return nbrdf::Brdf::load(arg);
    if (kind == "borrow") {
        auto bytes = read_bytes(arg);
        keep.assign((bytes.size() + 3) / 4, 0);  // u32 storage: 4-byte aligned
        std::memcpy(keep.data(), bytes.data(), bytes.size());
        return nbrdf::Brdf::model_borrow(reinterpret_cast<const std::uint8_t *>(keep.data()), bytes.size());
    }
    std::istringstream in(arg);
    int k;
    in >> k;
    std::vector<float> v;
    for (float x; in >> x;) v.push_back(x);
    auto kind_ = static_cast<NbrdfParametricKind>(k);
    if (kind == "parametric") return nbrdf::Brdf::parametric(kind_, v);
    std::size_t n_object = kind_ == NBRDF_PARAMETRIC_KIND_FMBRDF ? 1 : 0;
    return nbrdf::Brdf::parametric_from_raw(kind_, std::vector<float>(v.begin(), v.end() - n_object),
                                            std::vector<float>(v.end() - n_object, v.end()));
}

int main(int argc, char **argv) {
    if (argc < 2) return 2;
    std::string dir = argv[argc - 1];  // [quick] DIR: nothing here is slow
    auto raw = read_bytes(dir + "/pairs.f32");
    std::vector<float> pairs(raw.size() / 4);
    std::memcpy(pairs.data(), raw.data(), raw.size());
    std::size_t n = pairs.size() / 9;
    std::ifstream cases(dir + "/cases.txt");
    std::string line;
    int index = 0;
    while (std::getline(cases, line)) {
        auto bar = line.find('|'), sp = line.find(' ');
        std::vector<std::uint32_t> keep;
        nbrdf::Brdf b = make(line.substr(0, sp), line.substr(sp + 1, bar - sp - 1), keep);
        std::istringstream pin(line.substr(bar + 1));
        std::vector<float> position;
        for (float x; pin >> x;) position.push_back(x);
        CHECK(b.info().position_len == position.size(), "case " << index << ": position_len");
        std::optional<nbrdf::Point> at;
        if (!position.empty()) at = b.prepare(position);
        const nbrdf::Point *p = at ? &*at : nullptr;
        std::vector<float> out(n * 15, 0.0f), soa(n * 9), rgb(n * 3);
        for (std::size_t i = 0; i < n; i++) {
            nbrdf::Vec3 wi{pairs[9 * i], pairs[9 * i + 1], pairs[9 * i + 2]};
            nbrdf::Vec3 wo{pairs[9 * i + 3], pairs[9 * i + 4], pairs[9 * i + 5]};
            nbrdf::Vec3 u{pairs[9 * i + 6], pairs[9 * i + 7], pairs[9 * i + 8]};
            float *o = &out[15 * i];
            auto f = b.eval(p, wi, wo);
            std::copy(f.begin(), f.end(), o);
            if (auto s = b.sample(p, wo, u)) {
                std::copy(s->wi.begin(), s->wi.end(), o + 6);
                std::copy(s->weight.begin(), s->weight.end(), o + 9);
                o[12] = s->pdf;
                o[13] = b.pdf(p, s->wi, wo);
            }
            o[14] = b.pdf(p, wi, wo);
            // The pbrt-style adapter: pbrt's argument order, the same numbers.
            nbrdf::BxDF bxdf(b, p);
            CHECK(bxdf.f(wo, wi) == f && bxdf.PDF(wo, wi) == o[14], "BxDF adapter at pair " << i);
            auto bs = bxdf.Sample_f(wo, u[2], {u[0], u[1]});
            CHECK(bool(bs) == (o[12] > 0) && (!bs || (bs->pdf == o[12] && bs->f == b.eval(p, bs->wi, wo))),
                  "BxDF Sample_f at pair " << i);
            for (int c = 0; c < 3; c++) {
                soa[c * n + i] = wi[c];
                soa[(3 + c) * n + i] = wo[c];
            }
        }
        b.eval_many(p, n, {&soa[0], &soa[n], &soa[2 * n]}, {&soa[3 * n], &soa[4 * n], &soa[5 * n]}, {&rgb[0], &rgb[n], &rgb[2 * n]});
        for (std::size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) out[15 * i + 3 + c] = rgb[c * n + i];
        std::ofstream(dir + "/out-" + std::to_string(index) + ".f32", std::ios::binary)
            .write(reinterpret_cast<const char *>(out.data()), std::streamsize(out.size() * sizeof(float)));
        index++;
    }
    CHECK(index > 0, "cases were read");
    // Errors throw nbrdf::Error carrying the status and the message.
    auto throws = [](auto f, NbrdfStatus want, const char *needle) {
        try {
            f();
        } catch (const nbrdf::Error &e) {
            return e.status() == want && std::strstr(e.what(), needle) != nullptr;
        }
        return false;
    };
    CHECK(throws([&] { nbrdf::Brdf::load(dir + "/missing.nbrdf"); }, NBRDF_STATUS_IO, "missing.nbrdf"), "missing file");
    CHECK(throws([&] { nbrdf::Brdf::load(dir + "/version.nbrdf"); }, NBRDF_STATUS_VERSION, "version"), "wrong version");
    CHECK(throws([] { nbrdf::Brdf::parametric(NBRDF_PARAMETRIC_KIND_PHONG, {0.6f, 0.6f, 0.6f, 0.5f, 0.5f, 0.5f, 1.0f}); },
                 NBRDF_STATUS_INVALID_VALUE, "kd + ks"),
          "Phong energy");
    auto varying = nbrdf::Brdf::load(dir + "/varying.nbrdf");
    CHECK(throws([&] { varying.prepare({1.0f}); }, NBRDF_STATUS_BUFFER_SIZE, "takes 3"), "point length");
    CHECK(throws([&] { varying.eval({0, 0, 1}, {0, 0, 1}); }, NBRDF_STATUS_INVALID_POINT, "varies"), "no point");
    nbrdf::Brdf moved = std::move(varying);
    CHECK(moved.get() != nullptr && varying.get() == nullptr, "move leaves the source empty");
    if (failures) std::cerr << failures << " checks failed\n";
    return failures ? 1 : 0;
}
