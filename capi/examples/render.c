/* Renders a sphere lit by one directional light with any BRDF nbrdf loads (.nbrdf, NBRDF-json
 * .json, MERL .binary), through the C ABI only. Orthographic view along -z, white light from
 * (1, 1, 1), output as PFM (linear, .pfm) or PPM (sRGB, anything else).
 *
 *   cc -std=c99 -O2 -I capi/include capi/examples/render.c target/release/libnbrdf.a \
 *      -lpthread -ldl -lm -o render && ./render model.nbrdf sphere.ppm 256
 *
 * A spatially varying model is prepared at each point: the point itself for an extrinsic encoding
 * (the sphere is the unit sphere, as training normalises meshes); an intrinsic encoding needs its
 * mesh's eigenfunctions, which a sphere drawn here does not have (the program says so). */
#include "nbrdf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* An orthonormal frame around the unit normal n (Duff et al. 2017). */
static void frame(const float n[3], float t[3], float b[3]) {
    float sign = n[2] >= 0 ? 1.0f : -1.0f, a = -1.0f / (sign + n[2]), c = n[0] * n[1] * a;
    t[0] = 1 + sign * n[0] * n[0] * a, t[1] = sign * c, t[2] = -sign * n[0];
    b[0] = c, b[1] = sign + n[1] * n[1] * a, b[2] = -n[1];
}

static float dot(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static int fail(const char *what) {
    fprintf(stderr, "render: %s: %s\n", what, nbrdf_last_error());
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: render BRDF_FILE OUT.(pfm|ppm) [SIZE]\n");
        return 2;
    }
    int size = argc > 3 ? atoi(argv[3]) : 256;
    if (size < 1 || size > 8192) {
        fprintf(stderr, "render: SIZE must be in 1..8192\n");
        return 2;
    }
    NbrdfBrdf *brdf = NULL;
    if (nbrdf_load(argv[1], &brdf) != NBRDF_STATUS_OK) return fail(argv[1]);
    NbrdfInfo info;
    if (nbrdf_info(brdf, &info) != NBRDF_STATUS_OK) return fail("info");
    if (info.position_len != 0 && info.position_len != 3) {
        fprintf(stderr, "render: %s has an intrinsic position encoding; render it on its own mesh\n", argv[1]);
        nbrdf_free(brdf);
        return 1;
    }
    fprintf(stderr, "render: %s (kernel level %s, %s, %llu parameters)\n", argv[1], nbrdf_kernel_level(),
            info.reciprocal ? "reciprocal" : "not reciprocal", (unsigned long long)info.n_parameters);
    void *point = malloc(nbrdf_point_size());
    float *img = calloc((size_t)size * size * 3, sizeof(float));
    const float view[3] = {0, 0, 1}, irradiance = 3.0f;
    const float light[3] = {0.57735027f, 0.57735027f, 0.57735027f};
    for (int y = 0; y < size; y++) {
        for (int x = 0; x < size; x++) {
            float px = (2.0f * x + 1) / size - 1, py = 1 - (2.0f * y + 1) / size, r2 = px * px + py * py;
            if (r2 >= 1) continue;
            float n[3] = {px, py, sqrtf(1 - r2)}, t[3], b[3];
            frame(n, t, b);
            float wo[3] = {dot(view, t), dot(view, b), dot(view, n)};
            float wi[3] = {dot(light, t), dot(light, b), dot(light, n)};
            if (wi[2] <= 0) continue;
            const void *at = NULL;
            if (info.position_len == 3) {
                if (nbrdf_prepare(brdf, n, 3, point, nbrdf_point_size()) != NBRDF_STATUS_OK) return fail("prepare");
                at = point;
            }
            float f[3];
            if (nbrdf_eval(brdf, at, wi, wo, f) != NBRDF_STATUS_OK) return fail("eval");
            for (int c = 0; c < 3; c++) img[3 * ((size_t)y * size + x) + c] = f[c] * wi[2] * irradiance;
        }
    }
    FILE *out = fopen(argv[2], "wb");
    if (!out) {
        perror(argv[2]);
        return 1;
    }
    size_t len = strlen(argv[2]);
    if (len > 4 && strcmp(argv[2] + len - 4, ".pfm") == 0) {
        /* PFM: rows bottom to top; a negative scale means little-endian floats. */
        fprintf(out, "PF\n%d %d\n-1.0\n", size, size);
        for (int y = size - 1; y >= 0; y--) fwrite(img + 3 * (size_t)y * size, sizeof(float), 3 * (size_t)size, out);
    } else {
        fprintf(out, "P6\n%d %d\n255\n", size, size);
        for (size_t i = 0; i < (size_t)size * size * 3; i++) {
            float v = img[i] <= 0.0031308f ? 12.92f * img[i] : 1.055f * powf(img[i], 1 / 2.4f) - 0.055f;
            fputc((int)(fminf(fmaxf(v, 0), 1) * 255 + 0.5f), out);
        }
    }
    fclose(out);
    free(img);
    free(point);
    nbrdf_free(brdf);
    return 0;
}
