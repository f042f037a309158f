// What bpx model runs on: the paper's scene (the demo's simulation) or a trace file.
// SPDX-License-Identifier: MIT

#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>

#include "model_cmd.h"

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// The paper's scene: spheres in a box, the demo's simulation (apps/demo/demo_sim.h), so the
// model sees exactly the cycles `bpx demo` runs.

void model_spheres_free(spheres *s)
{
    free(s->minima);
    free(s->centres);
    demo_sim_destroy(s->sim);
    memset(s, 0, sizeof *s);
}

// The centres as the demo's broad phase sends them to bpx: the positions rounded to float.
static void spheres_centres(spheres *s)
{
    const double *pos = demo_sim_positions(s->sim);
    for (size_t k = 0; k < 3 * (size_t)s->n; k++)
        s->centres[k] = (float)pos[k];
}

// The demo's defaults (docs/demo.md) with n spheres and the given seed.
int model_spheres_init(spheres *s, uint32_t n, uint64_t seed)
{
    memset(s, 0, sizeof *s);
    demo_params params = demo_default_params();
    params.sphere_count = n;
    params.seed = seed;
    demo_error err;
    s->n = n;
    s->minima = malloc(sizeof(float) * 3 * n);
    s->centres = malloc(sizeof(float) * 3 * n);
    if (!s->minima || !s->centres || demo_sim_create(&params, NULL, &s->sim, &err) != 0) {
        model_spheres_free(s);
        return -1;
    }
    for (size_t k = 0; k < 3 * (size_t)n; k++)
        s->minima[k] = (float)-params.radius;
    spheres_centres(s);
    return 0;
}

// One cycle of the demo's loop; *pairs are its broad phase's, valid until the next call.
int model_spheres_advance(spheres *s, const bpx_pair **pairs, size_t *count)
{
    demo_error err;
    if (demo_sim_step(s->sim, NULL, &err) != 0)
        return -1;
    *pairs = demo_sim_pairs(s->sim, count);
    spheres_centres(s);
    return 0;
}

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// A trace file, BPXTRACE version 1: 32-byte header ("BPXTRACE", u32 version 1, u32 n,
// u64 cycles, u32 floats per box = 6, u32 reserved = 0), then the cycles' boxes, 24 bytes
// each, little-endian.

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

int model_trace_open(trace_file *t, const char *path, char *message, size_t size)
{
    memset(t, 0, sizeof *t);
    unsigned char h[32];
    t->file = fopen(path, "rb");
    if (!t->file) {
        snprintf(message, size, "cannot open %s", path);
        return -1;
    }
    if (fread(h, 1, sizeof h, t->file) != sizeof h || memcmp(h, "BPXTRACE", 8) != 0 ||
        le32(h + 8) != 1 || le32(h + 24) != 6 || le32(h + 28) != 0) {
        snprintf(message, size, "%s: not a BPXTRACE version 1 file", path);
        return -1;
    }
    t->n = le32(h + 12);
    t->cycles = (uint64_t)le32(h + 16) | (uint64_t)le32(h + 20) << 32;
    if (t->n == 0 || t->n > MAX_SCENE_BOXES || t->cycles == 0) {
        snprintf(message, size, "%s: %u boxes and %llu cycles: nothing this tool can replay", path,
                 t->n, (unsigned long long)t->cycles);
        return -1;
    }
    if (!(t->bytes = malloc((size_t)t->n * 24))) {
        snprintf(message, size, "out of memory");
        return -1;
    }
    return 0;
}

// Reads one cycle into boxes (the model validates every box).
int model_trace_read(trace_file *t, bpx_box *boxes, char *message, size_t size)
{
    if (fread(t->bytes, 24, t->n, t->file) != t->n) {
        snprintf(message, size, "the trace ends before its announced cycles");
        return -1;
    }
    for (uint32_t i = 0; i < t->n; i++)
        for (int c = 0; c < 6; c++) {
            uint32_t bits = le32(t->bytes + 24 * (size_t)i + 4 * (size_t)c);
            float v;
            memcpy(&v, &bits, sizeof v);
            if (c < 3)
                boxes[i].min[c] = v;
            else
                boxes[i].max[c - 3] = v;
        }
    return 0;
}

void model_trace_close(trace_file *t)
{
    if (t->file)
        fclose(t->file);
    free(t->bytes);
    memset(t, 0, sizeof *t);
}
