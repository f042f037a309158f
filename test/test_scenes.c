// Tests of the scene generators themselves: validity, determinism, and that each kind has the
// property it promises (else the backend tests would test less than they claim).
#include <float.h>
#include <math.h>

#include "check.h"
#include "scenes.h"

static bool box_valid(const bpx_box *b)
{
    for (int a = 0; a < 3; a++) {
        if (!isfinite(b->min[a]) || !isfinite(b->max[a]) || !(b->min[a] <= b->max[a])) {
            return false;
        }
    }
    return true;
}

static uint64_t count_pairs(const bpx_box *boxes, uint32_t n)
{
    uint64_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (uint32_t j = i + 1; j < n; j++) {
            count += bpx_overlap(&boxes[i], &boxes[j]);
        }
    }
    return count;
}

// Touching on an axis: the closed intervals meet in exactly one point.
static bool touch_value(const bpx_box *p, const bpx_box *q, int a, float *at)
{
    if (p->max[a] == q->min[a] && p->min[a] < q->min[a]) {
        *at = q->min[a];
        return true;
    }
    if (q->max[a] == p->min[a] && q->min[a] < p->min[a]) {
        *at = p->min[a];
        return true;
    }
    return false;
}

static void test_rng(void)
{
    scene_rng r;
    scene_rng_seed(&r, 0);
    // splitmix64(0)'s first output: pins the seeding to the published algorithm.
    CHECK_EQ_U64(r.s[0], 0xe220a8397b1dcdafull);
    scene_rng a;
    scene_rng b;
    scene_rng_seed(&a, 42);
    scene_rng_seed(&b, 42);
    for (int k = 0; k < 1000; k++) {
        CHECK(scene_rng_u64(&a) == scene_rng_u64(&b));
    }
    scene_rng_seed(&r, 7);
    double sum = 0.0;
    for (int k = 0; k < 100000; k++) {
        float u = scene_rng_float01(&r);
        CHECK(u >= 0.0f && u < 1.0f);
        sum += u;
        float v = scene_rng_range(&r, -FLT_MAX, FLT_MAX);
        CHECK(isfinite(v));
        float w = scene_rng_range(&r, -2.0f, 3.0f);
        CHECK(w >= -2.0f && w <= 3.0f);
        CHECK(scene_rng_below(&r, 7) < 7);
    }
    CHECK_MSG(fabs(sum / 100000.0 - 0.5) < 0.01, "mean %f", sum / 100000.0);
    CHECK(scene_rng_below(&r, 0) == 0);
    CHECK(scene_rng_range(&r, 5.0f, 5.0f) == 5.0f);
}

static void test_names(void)
{
    for (int k = 0; k < SCENE_KIND_COUNT; k++) {
        const char *name = scene_kind_name((scene_kind)k);
        CHECK(name && name[0]);
        scene_kind back = SCENE_KIND_COUNT;
        CHECK(scene_kind_from_name(name, &back) == 0 && back == (scene_kind)k);
        for (int m = 0; m < k; m++) {
            CHECK(strcmp(name, scene_kind_name((scene_kind)m)) != 0);
        }
    }
    scene_kind kind;
    CHECK(scene_kind_from_name("ALL-OVERLAP", &kind) == 0 && kind == SCENE_ALL_OVERLAP);
    CHECK(scene_kind_from_name("nope", &kind) == -1);
    CHECK(scene_kind_from_name("dens", &kind) == -1);
    CHECK(scene_kind_from_name("densey", &kind) == -1);
    CHECK(scene_kind_from_name(NULL, &kind) == -1);
    CHECK(scene_kind_name(SCENE_KIND_COUNT) == NULL);
    CHECK(scene_generate(SCENE_KIND_COUNT, 4, 1, NULL) == -1);
    CHECK(scene_generate(SCENE_DENSE, 4, 1, NULL) == -1);
    CHECK(scene_generate(SCENE_DENSE, 0, 1, NULL) == 0);
    bpx_box one;
    CHECK(scene_generate(SCENE_DENSE, BPX_MAX_BOXES + 1u, 1, &one) == -1);
}

static void test_all_valid_and_deterministic(void)
{
    static const uint32_t sizes[] = {1, 2, 3, 17, 100, 1000, 4099};
    enum { max_n = 4099 };
    bpx_box *a = check_alloc(sizeof(bpx_box) * max_n);
    bpx_box *b = check_alloc(sizeof(bpx_box) * max_n);
    for (int k = 0; k < SCENE_KIND_COUNT; k++) {
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
            uint32_t n = sizes[s];
            uint64_t seed = 1000 + s;
            check_set_seed(seed);
            check_set_context("%s n=%u", scene_kind_name((scene_kind)k), n);
            CHECK(scene_generate((scene_kind)k, n, seed, a) == 0);
            CHECK(scene_generate((scene_kind)k, n, seed, b) == 0);
            CHECK(memcmp(a, b, sizeof(bpx_box) * n) == 0);
            uint32_t bad = n;
            for (uint32_t i = 0; i < n && bad == n; i++) {
                if (!box_valid(&a[i])) {
                    bad = i;
                }
            }
            CHECK_MSG(bad == n, "box %u invalid", bad);
            CHECK_STATUS(bpx_validate_boxes(a, n, NULL), BPX_OK);
            if (n >= 100) {
                CHECK(scene_generate((scene_kind)k, n, seed + 1, b) == 0);
                CHECK(memcmp(a, b, sizeof(bpx_box) * n) != 0);
            }
            if (n == 1000) {
                scene_rng r;
                scene_rng_seed(&r, seed);
                for (int step = 0; step < 3; step++) {
                    scene_move(a, n, 0.1f, &r);
                }
                bad = n;
                for (uint32_t i = 0; i < n && bad == n; i++) {
                    if (!box_valid(&a[i])) {
                        bad = i;
                    }
                }
                CHECK_MSG(bad == n, "box %u invalid after scene_move", bad);
            }
        }
    }
    free(a);
    free(b);
}

static void test_properties(void)
{
    enum { n = 1500 };
    const uint64_t seed = 77;
    check_set_seed(seed);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);

    // Pair counts per kind, printed so a scene change that alters the workload shows.
    for (int k = 0; k < SCENE_KIND_COUNT; k++) {
        CHECK(scene_generate((scene_kind)k, n, seed, boxes) == 0);
        printf("  %-16s n=%d pairs=%" PRIu64 "\n", scene_kind_name((scene_kind)k), n,
               count_pairs(boxes, n));
    }

    check_set_context("none_overlap");
    CHECK(scene_generate(SCENE_NONE_OVERLAP, n, seed, boxes) == 0);
    CHECK_EQ_U64(count_pairs(boxes, n), 0);

    check_set_context("all_overlap");
    CHECK(scene_generate(SCENE_ALL_OVERLAP, n, seed, boxes) == 0);
    CHECK_EQ_U64(count_pairs(boxes, n), (uint64_t)n * (n - 1) / 2);

    check_set_context("sparse / dense / uniform_density");
    CHECK(scene_generate(SCENE_SPARSE, n, seed, boxes) == 0);
    CHECK(count_pairs(boxes, n) < n / 4);
    CHECK(scene_generate(SCENE_DENSE, n, seed, boxes) == 0);
    CHECK(count_pairs(boxes, n) > (uint64_t)n * n / 50);
    CHECK(scene_generate(SCENE_UNIFORM_DENSITY, n, seed, boxes) == 0);
    uint64_t uniform = count_pairs(boxes, n);
    CHECK_MSG(uniform > n / 4 && uniform < n, "%" PRIu64, uniform);
    scene_uniform_density(n, 4.0f, seed, boxes);
    uniform = count_pairs(boxes, n);
    CHECK_MSG(uniform > n && uniform < 3 * n, "%" PRIu64, uniform);

    check_set_context("heavy_tailed_density");
    scene_heavy_tailed_density(n, seed, boxes);
    uint64_t heavy = count_pairs(boxes, n);
    float widest = 0.0f;
    for (uint32_t i = 0; i < n; i++) {
        widest = fmaxf(widest, boxes[i].max[0] - boxes[i].min[0]);
    }
    CHECK_MSG(heavy > n / 4 && heavy < 4 * n, "%" PRIu64, heavy);
    CHECK_MSG(widest >= 16.0f, "widest side %g", (double)widest);

    check_set_context("touching");
    CHECK(scene_generate(SCENE_TOUCHING, n, seed, boxes) == 0);
    uint64_t touching = 0;
    bool on_lattice = true;
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            on_lattice &= boxes[i].min[a] * 2.0f == (float)(int)(boxes[i].min[a] * 2.0f);
            on_lattice &= boxes[i].max[a] * 2.0f == (float)(int)(boxes[i].max[a] * 2.0f);
        }
        for (uint32_t j = i + 1; j < n; j++) {
            float at;
            if (bpx_overlap(&boxes[i], &boxes[j]) &&
                (touch_value(&boxes[i], &boxes[j], 0, &at) ||
                 touch_value(&boxes[i], &boxes[j], 1, &at) ||
                 touch_value(&boxes[i], &boxes[j], 2, &at))) {
                touching++;
            }
        }
    }
    CHECK(on_lattice);
    CHECK_MSG(touching > n, "%" PRIu64 " touching pairs", touching);

    check_set_context("signed_zero");
    CHECK(scene_generate(SCENE_SIGNED_ZERO, n, seed, boxes) == 0);
    int neg_zero = 0;
    int pos_zero = 0;
    uint64_t zero_touch = 0;
    uint64_t other_touch = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float v[2] = {boxes[i].min[a], boxes[i].max[a]};
            for (int e = 0; e < 2; e++) {
                neg_zero += v[e] == 0.0f && signbit(v[e]);
                pos_zero += v[e] == 0.0f && !signbit(v[e]);
            }
        }
        for (uint32_t j = i + 1; j < n; j++) {
            for (int a = 0; a < 3; a++) {
                float at;
                if (touch_value(&boxes[i], &boxes[j], a, &at)) {
                    if (at == 0.0f) {
                        zero_touch++;
                    } else {
                        other_touch++;
                    }
                }
            }
        }
    }
    CHECK(neg_zero > 100 && pos_zero > 100);
    CHECK(zero_touch > 1000);
    CHECK_EQ_U64(other_touch, 0);

    check_set_context("huge_tiny");
    CHECK(scene_generate(SCENE_HUGE_TINY, n, seed, boxes) == 0);
    int huge = 0;
    int tiny = 0;
    int at_max = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float v[2] = {boxes[i].min[a], boxes[i].max[a]};
            for (int e = 0; e < 2; e++) {
                huge += fabsf(v[e]) > 1e38f;
                tiny += v[e] != 0.0f && fabsf(v[e]) < 1e-29f;
                at_max += fabsf(v[e]) == FLT_MAX;
            }
        }
    }
    CHECK(huge > 100 && tiny > 100 && at_max > 0);

    check_set_context("denormal");
    CHECK(scene_generate(SCENE_DENORMAL, n, seed, boxes) == 0);
    int subnormal = 0;
    int normal = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float v[2] = {boxes[i].min[a], boxes[i].max[a]};
            for (int e = 0; e < 2; e++) {
                subnormal += fpclassify(v[e]) == FP_SUBNORMAL;
                normal += fpclassify(v[e]) == FP_NORMAL && fabsf(v[e]) != FLT_MIN;
            }
        }
    }
    CHECK(subnormal > n);
    CHECK_EQ_U64(normal, 0);
    uint64_t denormal_pairs = count_pairs(boxes, n);
    CHECK(denormal_pairs > n / 2 && denormal_pairs < (uint64_t)n * n / 8);

    check_set_context("shared_coord");
    CHECK(scene_generate(SCENE_SHARED_COORD, n, seed, boxes) == 0);
    int shared = 0;
    for (uint32_t i = 0; i < n; i++) {
        shared += boxes[i].min[0] == 1.0f || boxes[i].max[0] == 1.0f;
    }
    CHECK(shared > n * 8 / 10);

    check_set_context("identical");
    CHECK(scene_generate(SCENE_IDENTICAL, n, seed, boxes) == 0);
    uint32_t distinct = 0;
    for (uint32_t i = 0; i < n; i++) {
        bool seen = false;
        for (uint32_t j = 0; j < i && !seen; j++) {
            seen = memcmp(&boxes[i], &boxes[j], sizeof(bpx_box)) == 0;
        }
        distinct += !seen;
    }
    CHECK(distinct >= 1 && distinct <= 1 + n / 128);

    check_set_context("zero_extent");
    CHECK(scene_generate(SCENE_ZERO_EXTENT, n, seed, boxes) == 0);
    int points = 0;
    int planes = 0;
    int same_points = 0;
    for (uint32_t i = 0; i < n; i++) {
        int flat = 0;
        for (int a = 0; a < 3; a++) {
            flat += boxes[i].min[a] == boxes[i].max[a];
        }
        points += flat == 3;
        planes += flat == 1 || flat == 2;
        if (flat == 3) {
            for (uint32_t j = 0; j < i; j++) {
                same_points += memcmp(&boxes[i], &boxes[j], sizeof(bpx_box)) == 0;
            }
        }
    }
    CHECK(points > n / 8 && planes > n / 4 && same_points > 0);

    check_set_context("mixed_sizes");
    CHECK(scene_generate(SCENE_MIXED_SIZES, n, seed, boxes) == 0);
    float smallest = FLT_MAX;
    float largest = 0.0f;
    for (uint32_t i = 0; i < n; i++) {
        float side = boxes[i].max[0] - boxes[i].min[0];
        smallest = side < smallest ? side : smallest;
        largest = side > largest ? side : largest;
    }
    CHECK(largest > 50.0f * smallest);

    check_set_context("clustered");
    CHECK(scene_generate(SCENE_CLUSTERED, n, seed, boxes) == 0);
    uint64_t clustered = count_pairs(boxes, n);
    CHECK(clustered > n / 2 && clustered < (uint64_t)n * n / 20);
    free(boxes);
}

int main(void)
{
    printf("test_scenes: seeds 0, 7, 42 (rng), 1000..1006 (validity), 77 (properties)\n");
    test_rng();
    test_names();
    test_all_valid_and_deterministic();
    test_properties();
    return check_finish("test_scenes", 1);
}
