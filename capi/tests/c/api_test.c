/* The C ABI from C99: reads the cases and direction pairs the Rust test wrote into DIR, writes
 * every value, batch, sample and density it gets back (the test compares them with the Rust API bit
 * for bit), runs a chi-square test of nbrdf_sample against nbrdf_pdf, and checks every error path.
 * Usage: api_test [quick] DIR (quick: no chi-square test). Exit status 0 when every check passed. */
#include "nbrdf.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static int failures = 0;

#define CHECK(cond, ...)                                                          \
    do {                                                                          \
        if (!(cond)) {                                                            \
            fprintf(stderr, "FAILED %s:%d: ", __FILE__, __LINE__);                \
            fprintf(stderr, __VA_ARGS__);                                         \
            fprintf(stderr, " (last error: %s)\n", nbrdf_last_error());           \
            failures++;                                                           \
        }                                                                         \
    } while (0)

/* The status `call` returns is `want`, and the message mentions `needle`. */
#define EXPECT(call, want, needle)                                                \
    do {                                                                          \
        NbrdfStatus s_ = (call);                                                  \
        CHECK(s_ == (want), "%s: status %d, want %d", #call, (int)s_, (int)(want)); \
        CHECK(strstr(nbrdf_last_error(), (needle)) != NULL, "%s: message lacks \"%s\"", #call, (needle)); \
    } while (0)

static float *read_floats(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long bytes = ftell(f);
    fseek(f, 0, SEEK_SET);
    float *v = malloc((size_t)bytes);
    *n = fread(v, sizeof(float), (size_t)bytes / sizeof(float), f);
    fclose(f);
    return v;
}

static NbrdfStatus make(const char *kind, const char *arg, NbrdfBrdf **out, unsigned char **keep) {
    if (strcmp(kind, "builtin") == 0) return nbrdf_builtin(arg, out);
    if (strcmp(kind, "file") == 0) return nbrdf_load(arg, out);
    if (strcmp(kind, "borrow") == 0) {
        /* Borrowed bytes must be 4-byte aligned and outlive the handle: malloc'd, freed at the end. */
        FILE *f = fopen(arg, "rb");
        if (!f) return NBRDF_STATUS_IO;
        fseek(f, 0, SEEK_END);
        long n = ftell(f);
        fseek(f, 0, SEEK_SET);
        *keep = malloc((size_t)n);
        size_t got = fread(*keep, 1, (size_t)n, f);
        fclose(f);
        return nbrdf_model_borrow(*keep, got, out);
    }
    if (strcmp(kind, "parametric") == 0 || strcmp(kind, "raw") == 0) {
        int k;
        float v[16];
        int used = 0, count = 0;
        sscanf(arg, "%d%n", &k, &used);
        const char *p = arg + used;
        while (count < 16 && sscanf(p, "%f%n", &v[count], &used) == 1) {
            p += used;
            count++;
        }
        if (kind[0] == 'p') return nbrdf_parametric((NbrdfParametricKind)k, v, (size_t)count, out);
        size_t n_object = (k == NBRDF_PARAMETRIC_KIND_FMBRDF) ? 1 : 0;
        return nbrdf_parametric_from_raw((NbrdfParametricKind)k, v, (size_t)count - n_object, v + count - n_object, n_object, out);
    }
    return NBRDF_STATUS_INVALID_VALUE;
}

/* Chi-square of nbrdf_sample against nbrdf_pdf at one wo, on 8 x 16 bins of (cos theta, phi). */
static double chi_square(const NbrdfBrdf *b, const void *point, const float wo[3], int n, double *limit) {
    enum { NT = 8, NP = 16, SUB = 12 };
    static double obs[NT * NP], expct[NT * NP];
    memset(obs, 0, sizeof obs);
    memset(expct, 0, sizeof expct);
    unsigned long long state = 12345;
    for (int i = 0; i < n; i++) {
        float u[3];
        for (int c = 0; c < 3; c++) {
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            u[c] = (float)(state >> 40) / 16777216.0f;
        }
        NbrdfSample s;
        if (nbrdf_sample(b, point, wo, u, &s) != NBRDF_STATUS_OK || s.pdf == 0.0f) continue;
        double phi = atan2(s.wi[1], s.wi[0]);
        if (phi < 0) phi += 2 * PI;
        int t = (int)(s.wi[2] * NT), q = (int)(phi / (2 * PI) * NP);
        obs[(t < NT ? t : NT - 1) * NP + (q < NP ? q : NP - 1)] += 1;
    }
    for (int i = 0; i < NT * SUB; i++) {
        double z = (i + 0.5) / (NT * SUB), r = sqrt(1 - z * z);
        for (int j = 0; j < NP * SUB; j++) {
            double phi = (j + 0.5) / (NP * SUB) * 2 * PI;
            float wi[3] = {(float)(r * cos(phi)), (float)(r * sin(phi)), (float)z}, p = 0;
            nbrdf_pdf(b, point, wi, wo, &p);
            expct[(i / SUB) * NP + j / SUB] += p * (1.0 / (NT * SUB)) * (2 * PI / (NP * SUB)) * n;
        }
    }
    double chi2 = 0, pool_o = 0, pool_e = 0;
    int dof = 0;
    for (int k = 0; k < NT * NP; k++) {
        if (expct[k] < 5) {
            pool_o += obs[k];
            pool_e += expct[k];
        } else {
            chi2 += (obs[k] - expct[k]) * (obs[k] - expct[k]) / expct[k];
            dof++;
        }
    }
    if (pool_e >= 5) {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof++;
    }
    /* Upper quantile at z = 4 by Wilson-Hilferty, as the Rust tests use. */
    double d = dof > 1 ? dof - 1 : 1, k = 2.0 / (9.0 * d);
    *limit = d * pow(1 - k + 4 * sqrt(k), 3);
    return chi2;
}

static void error_paths(const char *dir) {
    char path[4096];
    NbrdfBrdf *b = NULL;
    snprintf(path, sizeof path, "%s/missing.nbrdf", dir);
    EXPECT(nbrdf_load(path, &b), NBRDF_STATUS_IO, "missing.nbrdf");
    snprintf(path, sizeof path, "%s/truncated.nbrdf", dir);
    EXPECT(nbrdf_load(path, &b), NBRDF_STATUS_TRUNCATED, "");
    snprintf(path, sizeof path, "%s/version.nbrdf", dir);
    EXPECT(nbrdf_load(path, &b), NBRDF_STATUS_VERSION, "version");
    snprintf(path, sizeof path, "%s/model.obj", dir);
    EXPECT(nbrdf_load(path, &b), NBRDF_STATUS_INVALID_VALUE, "unknown BRDF file type");
    EXPECT(nbrdf_load(NULL, &b), NBRDF_STATUS_NULL_POINTER, "path");
    EXPECT(nbrdf_builtin("velvet", NULL), NBRDF_STATUS_NULL_POINTER, "out");
    EXPECT(nbrdf_builtin("felt", &b), NBRDF_STATUS_INVALID_VALUE, "known: two-lobe-metal");
    CHECK(b == NULL, "a failed call leaves *out untouched");
    float phong[7] = {0.6f, 0.6f, 0.6f, 0.5f, 0.5f, 0.5f, 10.0f};
    EXPECT(nbrdf_parametric(NBRDF_PARAMETRIC_KIND_PHONG, phong, 7, &b), NBRDF_STATUS_INVALID_VALUE, "kd + ks");
    EXPECT(nbrdf_parametric(NBRDF_PARAMETRIC_KIND_PHONG, phong, 6, &b), NBRDF_STATUS_BUFFER_SIZE, "7 parameters");
    unsigned char junk[64] = {0};
    EXPECT(nbrdf_model_borrow(junk + 1, 32, &b), NBRDF_STATUS_MISALIGNED, "aligned");
    EXPECT(nbrdf_model_from_bytes(junk, 64, &b), NBRDF_STATUS_CORRUPT, "");
    EXPECT(nbrdf_merl_from_bytes(junk, 4, &b), NBRDF_STATUS_TRUNCATED, "MERL");
    EXPECT(nbrdf_nbrdf_json_from_bytes((const unsigned char *)"{", 1, &b), NBRDF_STATUS_CORRUPT, "NBRDF-json");

    /* A spatially varying model: points, storage and lengths. */
    snprintf(path, sizeof path, "%s/varying.nbrdf", dir);
    CHECK(nbrdf_load(path, &b) == NBRDF_STATUS_OK, "load %s", path);
    NbrdfInfo info;
    CHECK(nbrdf_info(b, &info) == NBRDF_STATUS_OK && info.position_len == 3, "extrinsic model: 3 floats per point");
    EXPECT(nbrdf_info(NULL, &info), NBRDF_STATUS_NULL_POINTER, "brdf");
    float wi[3] = {0.3f, 0.1f, 0.9f}, wo[3] = {-0.2f, 0.3f, 0.9f}, rgb[3], x[3] = {0.1f, -0.2f, 0.3f};
    EXPECT(nbrdf_eval(b, NULL, wi, wo, rgb), NBRDF_STATUS_INVALID_POINT, "varies over the surface");
    size_t size = nbrdf_point_size();
    CHECK(size <= NBRDF_POINT_MAX_SIZE && nbrdf_point_align() <= NBRDF_POINT_MAX_ALIGN, "point storage bounds");
    unsigned char *storage = malloc(size + 16);
    EXPECT(nbrdf_prepare(b, x, 3, storage, size - 1), NBRDF_STATUS_BUFFER_SIZE, "nbrdf_point_size");
    EXPECT(nbrdf_prepare(b, x, 2, storage, size), NBRDF_STATUS_BUFFER_SIZE, "takes 3");
    EXPECT(nbrdf_prepare(b, NULL, 3, storage, size), NBRDF_STATUS_NULL_POINTER, "position");
    EXPECT(nbrdf_prepare(b, x, 3, storage + 4, size), NBRDF_STATUS_MISALIGNED, "aligned");
    memset(storage, 0, size);
    EXPECT(nbrdf_eval(b, storage, wi, wo, rgb), NBRDF_STATUS_INVALID_POINT, "not prepared");
    CHECK(nbrdf_prepare(b, x, 3, storage, size) == NBRDF_STATUS_OK, "prepare");
    EXPECT(nbrdf_eval(b, storage, NULL, wo, rgb), NBRDF_STATUS_NULL_POINTER, "wi");
    EXPECT(nbrdf_eval(b, storage, wi, wo, NULL), NBRDF_STATUS_NULL_POINTER, "rgb");
    EXPECT(nbrdf_pdf(b, storage, wi, wo, NULL), NBRDF_STATUS_NULL_POINTER, "pdf");
    EXPECT(nbrdf_sample(b, storage, wo, NULL, NULL), NBRDF_STATUS_NULL_POINTER, "u");
    float many[4] = {0.3f, 0.1f, 0.9f, 0.5f}, out[4];
    NbrdfDirections d = {many, many, many};
    NbrdfRgbArrays o = {out, out, many};
    EXPECT(nbrdf_eval_many(b, storage, 4, d, d, o), NBRDF_STATUS_INVALID_VALUE, "overlaps");
    NbrdfBrdf *other = NULL;
    CHECK(nbrdf_builtin("velvet", &other) == NBRDF_STATUS_OK, "builtin");
    EXPECT(nbrdf_eval(other, storage, wi, wo, rgb), NBRDF_STATUS_INVALID_POINT, "for this BRDF");
    nbrdf_free(other);
    free(storage);
    nbrdf_free(b);
    nbrdf_free(NULL);
}

/* Values a C caller can pass that are no enum value, and lengths no buffer can have: each call returns
 * its status without touching its outputs (the Rust side never holds an undeclared enum value nor
 * makes a slice of an impossible length). */
static void hostile_values(const char *dir) {
    static const int kinds[] = {-1, 5, 99, INT_MAX, INT_MIN};
    static const size_t lengths[] = {SIZE_MAX, SIZE_MAX / 4, (size_t)1 << 62, (size_t)PTRDIFF_MAX / 4 + 1};
    char path[4096];
    NbrdfBrdf *b = NULL;
    float p[12] = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
    for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++) {
        char needle[32];
        snprintf(needle, sizeof needle, "kind %d", kinds[i]);
        EXPECT(nbrdf_parametric((NbrdfParametricKind)kinds[i], p, 3, &b), NBRDF_STATUS_INVALID_VALUE, needle);
        EXPECT(nbrdf_parametric_from_raw((NbrdfParametricKind)kinds[i], p, 3, NULL, 0, &b), NBRDF_STATUS_INVALID_VALUE, needle);
        CHECK(b == NULL, "kind %d: *out untouched", kinds[i]);
    }

    snprintf(path, sizeof path, "%s/model.nbrdf", dir);
    NbrdfBrdf *model = NULL, *varying = NULL;
    CHECK(nbrdf_load(path, &model) == NBRDF_STATUS_OK, "load %s", path);
    snprintf(path, sizeof path, "%s/varying.nbrdf", dir);
    CHECK(nbrdf_load(path, &varying) == NBRDF_STATUS_OK, "load %s", path);
    if (!model || !varying) return;
    static float a[6][4], r[3][4];
    unsigned char *storage = malloc(NBRDF_POINT_MAX_SIZE); /* malloc aligns for any type */
    static uint32_t bytes[64]; /* 4-byte aligned, for the borrowed model */
    memset(r, 0x5a, sizeof r);
    unsigned char before[sizeof r];
    memcpy(before, r, sizeof r);
    NbrdfDirections wi = {a[0], a[1], a[2]}, wo = {a[3], a[4], a[5]};
    NbrdfRgbArrays out = {r[0], r[1], r[2]};
    uint32_t tri[3] = {0, 1, 2};
    float bary[3] = {0.2f, 0.3f, 0.5f}, features[4] = {7, 7, 7, 7};
    for (size_t i = 0; i < sizeof lengths / sizeof lengths[0]; i++) {
        size_t n = lengths[i];
        EXPECT(nbrdf_eval_many(model, NULL, n, wi, wo, out), NBRDF_STATUS_BUFFER_SIZE, "isize::MAX");
        EXPECT(nbrdf_model_from_bytes((const uint8_t *)bytes, n, &b), NBRDF_STATUS_BUFFER_SIZE, "model file");
        EXPECT(nbrdf_model_borrow((const uint8_t *)bytes, n, &b), NBRDF_STATUS_BUFFER_SIZE, "model file");
        EXPECT(nbrdf_merl_from_bytes((const uint8_t *)bytes, n, &b), NBRDF_STATUS_BUFFER_SIZE, "MERL file");
        EXPECT(nbrdf_nbrdf_json_from_bytes((const uint8_t *)bytes, n, &b), NBRDF_STATUS_BUFFER_SIZE, "NBRDF-json");
        EXPECT(nbrdf_prepare(varying, a[0], n, storage, NBRDF_POINT_MAX_SIZE), NBRDF_STATUS_BUFFER_SIZE, "takes 3");
        EXPECT(nbrdf_position_features(varying, tri, bary, features, n), NBRDF_STATUS_BUFFER_SIZE, "out has");
        EXPECT(nbrdf_parametric(NBRDF_PARAMETRIC_KIND_LAMBERT, p, n, &b), NBRDF_STATUS_BUFFER_SIZE, "3 parameters");
        EXPECT(nbrdf_parametric_from_raw(NBRDF_PARAMETRIC_KIND_LAMBERT, p, n, NULL, 0, &b), NBRDF_STATUS_BUFFER_SIZE, "raw values");
        CHECK(b == NULL, "n = %zu: *out untouched", n);
        CHECK(memcmp(r, before, sizeof r) == 0, "n = %zu: outputs untouched", n);
    }
    /* Arrays that would run past the end of the address space. */
    NbrdfRgbArrays wrapping = {r[0], r[1], (float *)(uintptr_t)(UINTPTR_MAX - 7)};
    EXPECT(nbrdf_eval_many(model, NULL, 4, wi, wo, wrapping), NBRDF_STATUS_BUFFER_SIZE, "end of the address space");
    CHECK(memcmp(r, before, sizeof r) == 0, "wrapping output: outputs untouched");
    /* Non-finite barycentric weights. */
    bary[1] = NAN;
    EXPECT(nbrdf_position_features(varying, tri, bary, features, 3), NBRDF_STATUS_INVALID_VALUE, "bary[1]");
    CHECK(features[0] == 7 && features[3] == 7, "NaN barycentrics: out untouched");
    free(storage);
    nbrdf_free(varying);
    nbrdf_free(model);
}

int main(int argc, char **argv) {
    if (argc < 2) return 2;
    /* "api_test quick DIR": no chi-square test (under valgrind). */
    const char *dir = argv[argc - 1];
    int quick = argc > 2 && strcmp(argv[1], "quick") == 0;
    CHECK(strcmp(nbrdf_version(), "") != 0, "a version");
    char path[4096];
    size_t n_pairs_f;
    snprintf(path, sizeof path, "%s/pairs.f32", dir);
    float *pairs = read_floats(path, &n_pairs_f);
    CHECK(pairs != NULL, "read %s", path);
    if (!pairs) return 1;
    size_t n = n_pairs_f / 9; /* wi[3], wo[3], u[3] */
    snprintf(path, sizeof path, "%s/cases.txt", dir);
    FILE *cases = fopen(path, "r");
    char line[1024];
    int index = 0;
    while (cases && fgets(line, sizeof line, cases)) {
        line[strcspn(line, "\n")] = 0;
        /* KIND ARG... | POINT... */
        char *bar = strchr(line, '|');
        *bar = 0;
        char *sp = strchr(line, ' ');
        *sp = 0;
        unsigned char *keep = NULL;
        NbrdfBrdf *b = NULL;
        CHECK(make(line, sp + 1, &b, &keep) == NBRDF_STATUS_OK, "case %d %s %s", index, line, sp + 1);
        if (!b) return 1;
        float point[64];
        int np = 0, used = 0;
        const char *p = bar + 1;
        while (np < 64 && sscanf(p, "%f%n", &point[np], &used) == 1) {
            p += used;
            np++;
        }
        void *storage = NULL;
        NbrdfInfo info;
        CHECK(nbrdf_info(b, &info) == NBRDF_STATUS_OK && info.position_len == (uint32_t)np, "case %d: position_len", index);
        if (np > 0) {
            storage = malloc(NBRDF_POINT_MAX_SIZE); /* malloc aligns for any type */
            CHECK(nbrdf_prepare(b, point, (size_t)np, storage, NBRDF_POINT_MAX_SIZE) == NBRDF_STATUS_OK, "case %d: prepare", index);
        }
        /* Per pair: eval (3), eval_many (3), sample (7), pdf at the sample (1), pdf at wi (1). */
        float *out = calloc(n * 15, sizeof(float));
        float *soa = malloc(n * 9 * sizeof(float));
        for (size_t i = 0; i < n; i++) {
            const float *wi = pairs + 9 * i, *wo = wi + 3, *u = wi + 6;
            float *o = out + 15 * i;
            CHECK(nbrdf_eval(b, storage, wi, wo, o) == NBRDF_STATUS_OK, "eval");
            NbrdfSample s;
            CHECK(nbrdf_sample(b, storage, wo, u, &s) == NBRDF_STATUS_OK, "sample");
            memcpy(o + 6, s.wi, 3 * sizeof(float));
            memcpy(o + 9, s.weight, 3 * sizeof(float));
            o[12] = s.pdf;
            if (s.pdf > 0) CHECK(nbrdf_pdf(b, storage, s.wi, wo, o + 13) == NBRDF_STATUS_OK, "pdf");
            CHECK(nbrdf_pdf(b, storage, wi, wo, o + 14) == NBRDF_STATUS_OK, "pdf");
            for (int c = 0; c < 3; c++) {
                soa[c * n + i] = wi[c];
                soa[(3 + c) * n + i] = wo[c];
            }
        }
        float *rgb = malloc(n * 3 * sizeof(float));
        NbrdfDirections wi = {soa, soa + n, soa + 2 * n}, wo = {soa + 3 * n, soa + 4 * n, soa + 5 * n};
        NbrdfRgbArrays o = {rgb, rgb + n, rgb + 2 * n};
        CHECK(nbrdf_eval_many(b, storage, n, wi, wo, o) == NBRDF_STATUS_OK, "eval_many");
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) out[15 * i + 3 + c] = rgb[c * n + i];
        snprintf(path, sizeof path, "%s/out-%d.f32", dir, index);
        FILE *f = fopen(path, "wb");
        fwrite(out, sizeof(float), n * 15, f);
        fclose(f);
        /* Sampling agrees with the density, for a view near the normal and a grazing one. */
        const float views[2][3] = {{0.2f, 0.1f, 0.97467943f}, {0.8f, 0.0f, 0.6f}};
        for (int v = 0; v < 2 && !quick; v++) {
            double limit, chi2 = chi_square(b, storage, views[v], 20000, &limit);
            CHECK(chi2 < limit, "case %d (%s %s), view %d: chi2 %.1f > %.1f", index, line, sp + 1, v, chi2, limit);
        }
        free(rgb);
        free(soa);
        free(out);
        free(storage);
        nbrdf_free(b);
        free(keep);
        index++;
    }
    if (cases) fclose(cases);
    CHECK(index > 0, "cases were read");
    error_paths(dir);
    hostile_values(dir);
    free(pairs);
    if (failures) fprintf(stderr, "%d checks failed\n", failures);
    return failures ? 1 : 0;
}
