// bpx scenes: deterministic box sets. SPDX-License-Identifier: MIT
#include "scenes.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

// ---------------------------------------------------------------------------------------------
// PRNG

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static uint64_t rotl64(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

void scene_rng_seed(scene_rng *r, uint64_t seed)
{
    // splitmix64 never yields four zero words, the one state xoshiro cannot leave.
    for (int k = 0; k < 4; k++) {
        r->s[k] = splitmix64(&seed);
    }
}

uint64_t scene_rng_u64(scene_rng *r)
{
    uint64_t *s = r->s;
    uint64_t result = rotl64(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl64(s[3], 45);
    return result;
}

uint32_t scene_rng_u32(scene_rng *r)
{
    return (uint32_t)(scene_rng_u64(r) >> 32);
}

uint32_t scene_rng_below(scene_rng *r, uint32_t bound)
{
    // Multiply-shift: a bias below 2^-32 is fine for scenes and needs no loop.
    return (uint32_t)(((uint64_t)scene_rng_u32(r) * bound) >> 32);
}

float scene_rng_float01(scene_rng *r)
{
    return (float)(scene_rng_u32(r) >> 8) * (1.0f / 16777216.0f);
}

float scene_rng_range(scene_rng *r, float lo, float hi)
{
    double u = (double)(scene_rng_u32(r) >> 8) * (1.0 / 16777216.0);
    double v = (double)lo + ((double)hi - (double)lo) * u;
    float f = (float)v;
    // Rounding to float may step just outside [lo, hi].
    if (f < lo) {
        f = lo;
    }
    if (f > hi) {
        f = hi;
    }
    return f;
}

// ---------------------------------------------------------------------------------------------
// Helpers

// Roots by Newton from above: libm's cbrt may differ by an ulp between platforms, this does not.
static double det_cbrt(double x)
{
    if (!(x > 0.0)) {
        return 0.0;
    }
    double y = x > 1.0 ? x : 1.0;
    for (int it = 0; it < 2000; it++) {
        double ny = (2.0 * y + x / (y * y)) / 3.0;
        if (!(ny < y)) {
            break;
        }
        y = ny;
    }
    return y;
}

static double det_sqrt(double x)
{
    if (!(x > 0.0)) {
        return 0.0;
    }
    double y = x > 1.0 ? x : 1.0;
    for (int it = 0; it < 2000; it++) {
        double ny = 0.5 * (y + x / y);
        if (!(ny < y)) {
            break;
        }
        y = ny;
    }
    return y;
}

static uint32_t cube_side_for(uint32_t n)
{
    uint32_t g = (uint32_t)det_cbrt((double)n);
    while ((uint64_t)g * g * g < n) {
        g++;
    }
    return g < 1 ? 1 : g;
}

static void set_axis(bpx_box *b, int axis, float lo, float hi)
{
    b->min[axis] = lo;
    b->max[axis] = hi;
}

static bool coin(scene_rng *r, float p)
{
    return scene_rng_float01(r) < p;
}

static void shuffle_boxes(bpx_box *boxes, uint32_t n, scene_rng *r)
{
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = scene_rng_below(r, i);
        bpx_box t = boxes[i - 1];
        boxes[i - 1] = boxes[j];
        boxes[j] = t;
    }
}

// A random choice of n distinct cells of a g^3 grid, in random order. NULL on allocation failure.
static uint32_t *pick_cells(uint32_t n, uint32_t g, scene_rng *r)
{
    uint32_t cells = g * g * g;
    uint32_t *perm = malloc(sizeof(uint32_t) * (cells ? cells : 1));
    if (!perm) {
        return NULL;
    }
    for (uint32_t c = 0; c < cells; c++) {
        perm[c] = c;
    }
    // Partial Fisher-Yates: the first n entries are a uniform random selection.
    for (uint32_t i = 0; i < n && i < cells; i++) {
        uint32_t j = i + scene_rng_below(r, cells - i);
        uint32_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    return perm;
}

// Random boxes with side 0.5..1.5 in [-side/2, side/2]^3 (min corner), centred on `at`.
static void random_boxes(bpx_box *out, uint32_t n, double side, const float at[3], scene_rng *r)
{
    float half = (float)(side * 0.5);
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float lo = at[a] + scene_rng_range(r, -half, half);
            float size = scene_rng_range(r, 0.5f, 1.5f);
            set_axis(&out[i], a, lo, lo + size);
        }
    }
}

static double density_side(uint32_t n, double overlaps_per_box)
{
    if (overlaps_per_box < 1e-3) {
        overlaps_per_box = 1e-3;
    }
    // Two boxes of mean side 1 overlap on one axis with probability ~2 / side.
    double others = n > 1 ? (double)(n - 1) : 1.0;
    return 2.0 * det_cbrt(others / overlaps_per_box);
}

static void uniform_density(uint32_t n, double overlaps_per_box, scene_rng *r, bpx_box *out)
{
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    random_boxes(out, n, density_side(n, overlaps_per_box), origin, r);
}

// ---------------------------------------------------------------------------------------------
// Generators

static void gen_clustered(uint32_t n, scene_rng *r, bpx_box *out)
{
    uint32_t clusters = 2 + n / 500;
    if (clusters > 8) {
        clusters = 8;
    }
    float centres[8][3];
    for (uint32_t c = 0; c < clusters; c++) {
        for (int a = 0; a < 3; a++) {
            centres[c][a] = scene_rng_range(r, -1000.0f, 1000.0f);
        }
    }
    // About 4 overlaps per box inside its cluster; a sum of uniforms makes a dense core.
    float spread = (float)density_side(n / clusters + 1, 4.0);
    for (uint32_t i = 0; i < n; i++) {
        const float *c = centres[scene_rng_below(r, clusters)];
        for (int a = 0; a < 3; a++) {
            float u = scene_rng_float01(r) + scene_rng_float01(r) + scene_rng_float01(r) - 1.5f;
            float lo = c[a] + u * spread * 0.5f;
            set_axis(&out[i], a, lo, lo + scene_rng_range(r, 0.5f, 1.5f));
        }
    }
}

static void gen_all_overlap(uint32_t n, scene_rng *r, bpx_box *out)
{
    float p[3];
    for (int a = 0; a < 3; a++) {
        p[a] = scene_rng_range(r, -10.0f, 10.0f);
    }
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            // p - e <= p <= p + e holds after rounding too (rounding is monotonic).
            float lo = coin(r, 0.1f) ? p[a] : p[a] - scene_rng_range(r, 0.0f, 5.0f);
            float hi = coin(r, 0.1f) ? p[a] : p[a] + scene_rng_range(r, 0.0f, 5.0f);
            set_axis(&out[i], a, lo, hi);
        }
    }
}

static int gen_none_overlap(uint32_t n, scene_rng *r, bpx_box *out)
{
    uint32_t g = cube_side_for(n);
    uint32_t *cells = pick_cells(n, g, r);
    if (!cells) {
        return -1;
    }
    int offset = (int)(g / 2);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t c = cells[i];
        int idx[3] = {(int)(c % g), (int)(c / g % g), (int)(c / g / g)};
        for (int a = 0; a < 3; a++) {
            // Cell pitch 2, box inside [2k, 2k + 1.45]: a gap of at least 0.55 to the next cell.
            float base = 2.0f * (float)(idx[a] - offset);
            set_axis(&out[i], a, base + scene_rng_range(r, 0.0f, 0.45f),
                     base + 1.0f + scene_rng_range(r, 0.0f, 0.45f));
        }
    }
    free(cells);
    return 0;
}

static void gen_mixed_sizes(uint32_t n, scene_rng *r, bpx_box *out)
{
    float world = (float)(4.0 * det_cbrt((double)n + 1.0));
    for (uint32_t i = 0; i < n; i++) {
        float u = scene_rng_float01(r);
        bool huge = u < 0.01f || i == n / 3;
        for (int a = 0; a < 3; a++) {
            float size;
            if (huge) {
                size = scene_rng_range(r, world * 0.25f, world);
            } else if (u < 0.11f) {
                size = scene_rng_range(r, 1.0f, 4.0f);
            } else {
                size = scene_rng_range(r, 0.1f, 0.5f);
            }
            float lo = scene_rng_range(r, -world * 0.5f, world * 0.5f) - size * 0.5f;
            set_axis(&out[i], a, lo, lo + size);
        }
    }
}

static int gen_touching(uint32_t n, scene_rng *r, bpx_box *out)
{
    uint32_t g = cube_side_for(n);
    uint32_t *cells = pick_cells(n, g, r);
    if (!cells) {
        return -1;
    }
    int offset = (int)(g / 2);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t c = cells[i];
        int idx[3] = {(int)(c % g), (int)(c / g % g), (int)(c / g / g)};
        for (int a = 0; a < 3; a++) {
            // Lattice pitch 0.5 (exact in float). Mostly unit cells; some span two cells, some
            // are flat faces on a lattice plane.
            float lo = 0.5f * (float)(idx[a] - offset);
            uint32_t shape = scene_rng_below(r, 8);
            float cells_spanned = shape == 0 ? 0.0f : shape <= 2 ? 2.0f : 1.0f;
            set_axis(&out[i], a, lo, lo + 0.5f * cells_spanned);
        }
    }
    free(cells);
    return 0;
}

static void gen_identical(uint32_t n, scene_rng *r, bpx_box *out)
{
    uint32_t protos = 1 + n / 128;
    uniform_density(protos, 1.0, r, out);
    for (uint32_t i = protos; i < n; i++) {
        out[i] = out[scene_rng_below(r, protos)];
    }
    shuffle_boxes(out, n, r);
}

static void gen_zero_extent(uint32_t n, scene_rng *r, bpx_box *out)
{
    uint32_t range = (uint32_t)(det_cbrt((double)n) * 0.5) + 1;
    for (uint32_t i = 0; i < n; i++) {
        bool point = coin(r, 0.25f);
        for (int a = 0; a < 3; a++) {
            // Half-integer lattice: coinciding points and planes are common.
            float v = 0.5f * ((float)scene_rng_below(r, 2 * range + 1) - (float)range);
            if (point || coin(r, 0.5f)) {
                set_axis(&out[i], a, v, v);
            } else {
                set_axis(&out[i], a, v, v + 0.5f * (float)(1 + scene_rng_below(r, 2)));
            }
        }
    }
}

static float signed_zero(scene_rng *r)
{
    return (scene_rng_u32(r) & 1u) ? -0.0f : 0.0f;
}

static void gen_signed_zero(uint32_t n, scene_rng *r, bpx_box *out)
{
    // Intervals away from zero are spread so they rarely meet; the ones at zero always meet.
    float far = (float)(4.0 * det_cbrt((double)n + 1.0));
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            uint32_t shape = scene_rng_below(r, 20);
            float size = scene_rng_range(r, 0.25f, 4.0f);
            float away = scene_rng_range(r, 1.0f, 1.0f + far);
            if (shape < 3) { // [-size, +-0]
                set_axis(&out[i], a, -size, signed_zero(r));
            } else if (shape < 6) { // [+-0, size]
                set_axis(&out[i], a, signed_zero(r), size);
            } else if (shape < 8) { // [+-0, +-0], including min +0 with max -0
                set_axis(&out[i], a, signed_zero(r), signed_zero(r));
            } else if (shape < 14) {
                set_axis(&out[i], a, away, away + size);
            } else {
                set_axis(&out[i], a, -away - size, -away);
            }
        }
    }
}

static void gen_huge_tiny(uint32_t n, scene_rng *r, bpx_box *out)
{
    double root = det_cbrt((double)n + 1.0);
    double huge_half = 4e38 / root;
    double tiny_side = 2e-30 * root;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t shape = scene_rng_below(r, 100);
        for (int a = 0; a < 3; a++) {
            double lo;
            double hi;
            if (shape < 2) { // spans the origin, up to the largest finite float
                lo = -(double)FLT_MAX * scene_rng_float01(r);
                hi = (double)FLT_MAX * (coin(r, 0.3f) ? 1.0 : scene_rng_float01(r));
            } else if (shape < 35) { // huge scale
                double c = 2.5e38 * (2.0 * scene_rng_float01(r) - 1.0);
                double h = huge_half * scene_rng_float01(r);
                lo = c - h;
                hi = c + h;
            } else { // tiny scale, near 1e-30
                double c = tiny_side * (scene_rng_float01(r) - 0.5);
                double h = 1e-30 * scene_rng_float01(r);
                lo = c - h;
                hi = c + h;
            }
            // Clamp in double so that the float conversion stays finite.
            if (lo < -(double)FLT_MAX) {
                lo = -(double)FLT_MAX;
            }
            if (hi > (double)FLT_MAX) {
                hi = (double)FLT_MAX;
            }
            float flo = (float)lo;
            float fhi = (float)hi;
            if (fhi < flo) {
                fhi = flo;
            }
            set_axis(&out[i], a, flo, fhi);
        }
    }
}

// A float from its bit pattern: subnormals built without arithmetic, immune to FTZ/DAZ here.
static float float_from_bits(uint32_t bits)
{
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

// v * 8 * 2^-149 (a subnormal, or zero) for |v| < 2^20.
static float subnormal_lattice(int32_t v)
{
    uint32_t mag = (uint32_t)(v < 0 ? -v : v) * 8u;
    return float_from_bits((v < 0 ? 0x80000000u : 0u) | mag);
}

static void gen_denormal(uint32_t n, scene_rng *r, bpx_box *out)
{
    int32_t range = (int32_t)det_cbrt((double)n) + 1;
    for (uint32_t i = 0; i < n; i++) {
        bool straddle = coin(r, 0.03f);
        int straddle_axis = (int)scene_rng_below(r, 3);
        for (int a = 0; a < 3; a++) {
            if (straddle && a == straddle_axis) {
                // The smallest normal floats around the whole subnormal lattice.
                float m = float_from_bits(0x00800000u); // FLT_MIN
                set_axis(&out[i], a, coin(r, 0.5f) ? -m : -0.0f, m);
                continue;
            }
            int32_t v = (int32_t)scene_rng_below(r, (uint32_t)(2 * range + 1)) - range;
            int32_t extent = (int32_t)scene_rng_below(r, 4); // 0: a point on this axis
            set_axis(&out[i], a, subnormal_lattice(v), subnormal_lattice(v + extent));
        }
    }
}

static void gen_shared_coord(uint32_t n, scene_rng *r, bpx_box *out)
{
    const float shared = 1.0f;
    // 90% of the boxes contain x = shared, so y/z decide: ~2 overlaps per box.
    float side = (float)(2.0 * det_sqrt(0.45 * (double)n + 1.0));
    for (uint32_t i = 0; i < n; i++) {
        uint32_t shape = scene_rng_below(r, 10);
        float size = scene_rng_range(r, 0.5f, 1.5f);
        if (shape < 4) {
            set_axis(&out[i], 0, shared, shared + size);
        } else if (shape < 8) {
            set_axis(&out[i], 0, shared - size, shared);
        } else if (shape < 9) {
            set_axis(&out[i], 0, shared, shared);
        } else {
            float lo = scene_rng_range(r, -side * 0.5f, side * 0.5f);
            set_axis(&out[i], 0, lo, lo + size);
        }
        for (int a = 1; a < 3; a++) {
            float lo = scene_rng_range(r, -side * 0.5f, side * 0.5f);
            set_axis(&out[i], a, lo, lo + scene_rng_range(r, 0.5f, 1.5f));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Public

static const char *const kind_names[SCENE_KIND_COUNT] = {
    "sparse",      "dense",       "clustered", "all_overlap", "none_overlap",
    "mixed_sizes", "touching",    "identical", "zero_extent", "signed_zero",
    "huge_tiny",   "denormal",    "shared_coord", "uniform_density",
};

const char *scene_kind_name(scene_kind kind)
{
    if ((int)kind < 0 || kind >= SCENE_KIND_COUNT) {
        return NULL;
    }
    return kind_names[kind];
}

static int name_char(char c)
{
    if (c >= 'A' && c <= 'Z') {
        return c - 'A' + 'a';
    }
    return c == '-' ? '_' : c;
}

int scene_kind_from_name(const char *name, scene_kind *out)
{
    if (!name || !out) {
        return -1;
    }
    for (int k = 0; k < SCENE_KIND_COUNT; k++) {
        const char *a = name;
        const char *b = kind_names[k];
        while (*a && *b && name_char(*a) == *b) {
            a++;
            b++;
        }
        if (*a == '\0' && *b == '\0') {
            *out = (scene_kind)k;
            return 0;
        }
    }
    return -1;
}

int scene_generate(scene_kind kind, uint32_t n, uint64_t seed, bpx_box *out)
{
    if ((int)kind < 0 || kind >= SCENE_KIND_COUNT || (!out && n > 0) || n > BPX_MAX_BOXES) {
        return -1;
    }
    if (n == 0) {
        return 0;
    }
    // Each kind gets its own stream for the same seed.
    scene_rng r;
    scene_rng_seed(&r, seed ^ (0xd1b54a32d192ed03ull * (uint64_t)(kind + 1)));
    switch (kind) {
    case SCENE_SPARSE:
        uniform_density(n, 0.05, &r, out);
        return 0;
    case SCENE_DENSE: {
        double overlaps = 0.1 * (double)(n - 1);
        uniform_density(n, overlaps < 8.0 ? 8.0 : overlaps, &r, out);
        return 0;
    }
    case SCENE_CLUSTERED:
        gen_clustered(n, &r, out);
        return 0;
    case SCENE_ALL_OVERLAP:
        gen_all_overlap(n, &r, out);
        return 0;
    case SCENE_NONE_OVERLAP:
        return gen_none_overlap(n, &r, out);
    case SCENE_MIXED_SIZES:
        gen_mixed_sizes(n, &r, out);
        return 0;
    case SCENE_TOUCHING:
        return gen_touching(n, &r, out);
    case SCENE_IDENTICAL:
        gen_identical(n, &r, out);
        return 0;
    case SCENE_ZERO_EXTENT:
        gen_zero_extent(n, &r, out);
        return 0;
    case SCENE_SIGNED_ZERO:
        gen_signed_zero(n, &r, out);
        return 0;
    case SCENE_HUGE_TINY:
        gen_huge_tiny(n, &r, out);
        return 0;
    case SCENE_DENORMAL:
        gen_denormal(n, &r, out);
        return 0;
    case SCENE_SHARED_COORD:
        gen_shared_coord(n, &r, out);
        return 0;
    case SCENE_UNIFORM_DENSITY:
        uniform_density(n, 1.0, &r, out);
        return 0;
    case SCENE_KIND_COUNT:
        break;
    }
    return -1;
}

void scene_uniform_density(uint32_t n, float overlaps_per_box, uint64_t seed, bpx_box *out)
{
    if (!out || n == 0) {
        return;
    }
    scene_rng r;
    scene_rng_seed(&r, seed);
    uniform_density(n, (double)overlaps_per_box, &r, out);
}

void scene_heavy_tailed_density(uint32_t n, uint64_t seed, bpx_box *out)
{
    if (!out || n == 0) {
        return;
    }
    scene_rng r;
    scene_rng_seed(&r, seed);
    float half = (float)(density_side(n, 1.0) * 0.5);
    for (uint32_t i = 0; i < n; i++) {
        float u = scene_rng_float01(&r);
        float lo_side = 0.5f, hi_side = 1.5f;
        if (u < 0.0001f || i == n / 2) {
            lo_side = 16.0f, hi_side = 32.0f;
        } else if (u < 0.01f) {
            lo_side = 4.0f, hi_side = 8.0f;
        }
        for (int a = 0; a < 3; a++) {
            float size = scene_rng_range(&r, lo_side, hi_side);
            float lo = scene_rng_range(&r, -half, half) - size * 0.5f;
            set_axis(&out[i], a, lo, lo + size);
        }
    }
}

void scene_elongated_density(uint32_t n, float aspect, bool random_axis, uint64_t seed,
                             bpx_box *out)
{
    if (!out || n == 0) {
        return;
    }
    scene_rng r;
    scene_rng_seed(&r, seed);
    // Two boxes of mean sides (1, 1, a) meet with probability ~8a / side^3 when parallel,
    // ~2(1 + a)^2 / side^3 when not (two of three pairs on random axes).
    double a = aspect > 1.0f ? (double)aspect : 1.0;
    double meet = random_axis ? (8.0 * a + 4.0 * (1.0 + a) * (1.0 + a)) / 3.0 : 8.0 * a;
    double side = density_side(n, 1.0) * det_cbrt(meet / 8.0);
    float half = (float)(side * 0.5);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t long_axis = random_axis ? scene_rng_below(&r, 3) : 0;
        for (uint32_t k = 0; k < 3; k++) {
            float size = scene_rng_range(&r, 0.5f, 1.5f);
            if (k == long_axis) {
                size *= (float)a;
            }
            float lo = scene_rng_range(&r, -half, half) - size * 0.5f;
            set_axis(&out[i], (int)k, lo, lo + size);
        }
    }
}

void scene_move(bpx_box *boxes, uint32_t n, float step, scene_rng *r)
{
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float d = scene_rng_range(r, -step, step);
            boxes[i].min[a] += d;
            boxes[i].max[a] += d;
        }
    }
}
