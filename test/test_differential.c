// Differential test: every available backend, SIMD width and worker count against
// BPX_BACKEND_REFERENCE, byte for byte, on every scene kind; the reference itself against a
// double loop over bpx_overlap; and every way of getting pairs out (world buffer, caller buffer,
// too-small buffers, one-shot, two-phase updater).
#include <fenv.h>
#include <float.h>
#include <time.h>

#include "pairs_util.h"
#include "scenes.h"

static const uint32_t sizes[] = {0, 1, 2, 3, 15, 16, 17, 31, 33, 100, 257, 1000, 1234, 4099};
enum { size_count = sizeof sizes / sizeof sizes[0], max_boxes = 4099, oracle_max_n = 300 };

typedef struct config {
    bpx_backend backend;
    bpx_simd simd;
    int workers;
    int opencl_method;
    bpx_world *world;
    char label[80];
} config;

// `--opencl`: the opencl backend alone, each comparator path forced (brute force, sort and
// sweep, the tree) besides its auto rule, so that every path meets every scene kind at every
// size; skipped (77) without an OpenCL device. Without it: every other backend.
static bool opencl_only;
// `--cuda`: the cuda backend alone (test_differential_fake_cuda runs it on the fake device,
// test/fake_cuda/); skipped (77) where cuda is unavailable.
static bool cuda_only;

enum { max_configs = 64 };

static double now_s(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static const char *name_or(const char *s)
{
    return s ? s : "?";
}

// The library must leave the caller's floating-point environment alone: no flush-to-zero or
// denormals-are-zero (which would also fool the oracle here), round to nearest.
static bool fp_environment_intact(void)
{
    volatile float tiny = FLT_TRUE_MIN;
    return tiny > 0.0f && tiny * 2.0f > tiny && fegetround() == FE_TONEAREST;
}

// Seeds per size: more for small scenes, where they are cheap.
static int seed_count(uint32_t n)
{
    if (check_quick()) {
        return 1;
    }
    return n <= 257 ? 3 : n <= 1234 ? 2 : 1;
}

// Scenes whose pair count grows as n^2 would need hundreds of MB at the largest sizes.
static bool too_big(scene_kind kind, uint32_t n)
{
    return kind == SCENE_ALL_OVERLAP && n > 1234;
}

static bpx_world *make_world(bpx_backend backend, bpx_simd simd, int workers, int opencl_method)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.simd = simd;
    def.worker_count = workers;
    def.opencl_method = opencl_method;
    bpx_world *world = NULL;
    bpx_status s = bpx_world_create(&def, &world);
    CHECK_MSG(s == BPX_OK && world, "create %s/%s/%d: %s", name_or(bpx_backend_name(backend)),
              name_or(bpx_simd_name(simd)), workers, check_status_name(s));
    if (s != BPX_OK) {
        return NULL;
    }
    CHECK(bpx_world_backend(world) != BPX_BACKEND_AUTO);
    CHECK(bpx_world_backend(world) < BPX_BACKEND_COUNT);
    if (backend != BPX_BACKEND_AUTO) {
        CHECK(bpx_world_backend(world) == backend);
    }
    if (check_backend_has_simd(backend)) {
        bpx_simd want = simd == BPX_SIMD_AUTO ? bpx_simd_best() : simd;
        CHECK_MSG(bpx_world_simd(world) == want, "world simd %s, want %s",
                  name_or(bpx_simd_name(bpx_world_simd(world))), name_or(bpx_simd_name(want)));
    }
    return world;
}

// The opencl backend's paths: auto on 1 and 3 workers (which the device ignores), then each
// path forced, the tree and the sweep at every size, far below where auto would take them.
static int build_opencl_configs(config *cfgs)
{
    static const struct {
        int method, workers;
        const char *name;
    } paths[] = {{BPX_OPENCL_AUTO, 1, "auto"},
                 {BPX_OPENCL_AUTO, 3, "auto"},
                 {BPX_OPENCL_BRUTE, 1, "brute"},
                 {BPX_OPENCL_SWEEP, 1, "sweep"},
                 {BPX_OPENCL_TREE, 1, "tree"}};
    int count = 0;
    for (size_t p = 0; p < sizeof paths / sizeof paths[0]; p++) {
        config *c = &cfgs[count];
        *c = (config){.backend = BPX_BACKEND_OPENCL,
                      .simd = BPX_SIMD_AUTO,
                      .workers = paths[p].workers,
                      .opencl_method = paths[p].method};
        snprintf(c->label, sizeof c->label, "backend=opencl method=%s workers=%d", paths[p].name,
                 c->workers);
        c->world = make_world(c->backend, c->simd, c->workers, c->opencl_method);
        count += c->world != NULL;
    }
    return count;
}

// Every available backend other than the reference (and opencl, which --opencl covers), with
// each supported SIMD width for the brute comparator, on 1 and 3 workers (3 > cores here: more
// workers than cores must work too). A backend with a box limit (rtl) meets only the sizes
// within it.
static int build_configs(config *cfgs)
{
    static const int worker_counts[] = {1, 3};
    int count = 0;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        bpx_backend_info info = bpx_backend_query((bpx_backend)b);
        printf("backend %-10s available=%d detail='%s' reason='%s'\n", name_or(info.name),
               (int)info.available, info.detail, name_or(info.reason));
        if (b == BPX_BACKEND_REFERENCE || b == BPX_BACKEND_OPENCL || !info.available ||
            (cuda_only && b != BPX_BACKEND_CUDA)) {
            continue;
        }
        for (int s = 0; s < BPX_SIMD_COUNT; s++) {
            bool forced = s != BPX_SIMD_AUTO;
            if (forced && (!check_backend_has_simd((bpx_backend)b) ||
                           !bpx_simd_supported((bpx_simd)s) || check_quick())) {
                continue;
            }
            for (size_t w = 0; w < sizeof worker_counts / sizeof worker_counts[0]; w++) {
                if (check_quick() && worker_counts[w] == 1) {
                    continue;
                }
                if (count == max_configs) {
                    return count;
                }
                config *c = &cfgs[count];
                c->backend = (bpx_backend)b;
                c->simd = (bpx_simd)s;
                c->workers = worker_counts[w];
                snprintf(c->label, sizeof c->label, "backend=%s simd=%s workers=%d",
                         name_or(bpx_backend_name(c->backend)), name_or(bpx_simd_name(c->simd)),
                         c->workers);
                c->opencl_method = BPX_OPENCL_AUTO;
                c->world = make_world(c->backend, c->simd, c->workers, c->opencl_method);
                if (c->world) {
                    count++;
                }
            }
        }
    }
    return count;
}

// Runs the world's comparator and copies its pairs into out.
static bool world_pairs(bpx_world *world, const bpx_box *boxes, uint32_t n, pair_list *out)
{
    bpx_status s = bpx_world_set_boxes(world, boxes, n);
    CHECK_STATUS(s, BPX_OK);
    if (s != BPX_OK) {
        return false;
    }
    CHECK(bpx_world_box_count(world) == n);
    s = bpx_world_collide(world);
    CHECK_STATUS(s, BPX_OK);
    if (s != BPX_OK) {
        return false;
    }
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(world, &count);
    CHECK(pairs != NULL || count == 0);
    bpx_cycle_stats stats = bpx_world_stats(world);
    CHECK_EQ_U64(stats.pair_count, count);
    CHECK_EQ_U64(stats.box_count, n);
    size_t again = 12345;
    CHECK(bpx_world_pairs(world, NULL) == pairs);
    CHECK(bpx_world_pairs(world, &again) == pairs && again == count);
    pair_list_set(out, pairs, count);
    return true;
}

static void fill_sentinel(bpx_pair *p, size_t count)
{
    memset(p, 0xA5, sizeof(bpx_pair) * count);
}

static bool is_sentinel(const bpx_pair *p, size_t count)
{
    const unsigned char *b = (const unsigned char *)p;
    for (size_t k = 0; k < sizeof(bpx_pair) * count; k++) {
        if (b[k] != 0xA5) {
            return false;
        }
    }
    return true;
}

// collide_into with ample and too-small buffers, then copy_pairs, against want.
static void check_caller_buffers(bpx_world *world, const pair_list *want)
{
    const size_t slack = 4;
    bpx_pair *buf = check_alloc(sizeof(bpx_pair) * (want->count + slack));

    fill_sentinel(buf, want->count + slack);
    size_t count = 999;
    CHECK_STATUS(bpx_world_collide_into(world, buf, want->count + slack, &count), BPX_OK);
    CHECK_PAIRS_EQ(want->pairs, want->count, buf, count);
    CHECK(count > want->count || is_sentinel(buf + want->count, slack));

    // Exactly enough is enough.
    fill_sentinel(buf, want->count + slack);
    count = 999;
    CHECK_STATUS(bpx_world_collide_into(world, buf, want->count, &count), BPX_OK);
    CHECK_PAIRS_EQ(want->pairs, want->count, buf, count);

    if (want->count > 0) {
        size_t small[2] = {want->count - 1, 0};
        for (int k = 0; k < 2; k++) {
            fill_sentinel(buf, want->count + slack);
            count = 999;
            CHECK_STATUS(bpx_world_collide_into(world, buf, small[k], &count), BPX_ERR_CAPACITY);
            CHECK_EQ_U64(count, want->count);
            CHECK_MSG(is_sentinel(buf, want->count + slack), "out written on CAPACITY");
            // Nothing lost: the full set is in the world.
            size_t full = 0;
            const bpx_pair *pairs = bpx_world_pairs(world, &full);
            CHECK_PAIRS_EQ(want->pairs, want->count, pairs, full);
            CHECK_EQ_U64(bpx_world_stats(world).pair_count, want->count);
        }
    }

    fill_sentinel(buf, want->count + slack);
    size_t count_copy = 999;
    CHECK_STATUS(bpx_world_copy_pairs(world, buf, want->count + slack, &count_copy), BPX_OK);
    CHECK_PAIRS_EQ(want->pairs, want->count, buf, count_copy);
    if (want->count > 0) {
        fill_sentinel(buf, want->count + slack);
        count_copy = 999;
        CHECK_STATUS(bpx_world_copy_pairs(world, buf, want->count - 1, &count_copy),
                     BPX_ERR_CAPACITY);
        CHECK_EQ_U64(count_copy, want->count);
        CHECK(is_sentinel(buf, want->count + slack));
    }
    free(buf);
}

// bpx_find_pairs on every available backend (reference included; opencl alone with --opencl),
// ample and too small.
static void check_one_shot(const bpx_box *boxes, uint32_t n, const pair_list *want)
{
    const size_t slack = 4;
    bpx_pair *buf = check_alloc(sizeof(bpx_pair) * (want->count + slack));
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        if (!bpx_backend_query((bpx_backend)b).available ||
            (b == BPX_BACKEND_OPENCL) != opencl_only || (cuda_only && b != BPX_BACKEND_CUDA) ||
            n > check_backend_max_boxes((bpx_backend)b)) {
            continue;
        }
        fill_sentinel(buf, want->count + slack);
        size_t count = 999;
        bpx_error err;
        memset(&err, 0, sizeof err);
        CHECK_STATUS(
            bpx_find_pairs(boxes, n, (bpx_backend)b, buf, want->count + slack, &count, &err),
            BPX_OK);
        CHECK_PAIRS_EQ(want->pairs, want->count, buf, count);
        count = 999;
        CHECK_STATUS(bpx_find_pairs(boxes, n, (bpx_backend)b, buf, want->count, &count, NULL),
                     BPX_OK);
        CHECK_PAIRS_EQ(want->pairs, want->count, buf, count);
        if (want->count > 0) {
            fill_sentinel(buf, want->count + slack);
            count = 999;
            CHECK_STATUS(
                bpx_find_pairs(boxes, n, (bpx_backend)b, buf, want->count - 1, &count, &err),
                BPX_ERR_CAPACITY);
            CHECK_EQ_U64(count, want->count);
            CHECK(is_sentinel(buf, want->count + slack));
        }
    }
    free(buf);
}

static void test_scenes_all_backends(config *cfgs, int cfg_count)
{
    bpx_world *ref_world = make_world(BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, 0);
    if (!ref_world) {
        return;
    }
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * max_boxes);
    pair_list ref = {0};
    pair_list oracle = {0};
    pair_list got = {0};
    for (int k = 0; k < SCENE_KIND_COUNT; k++) {
        scene_kind kind = (scene_kind)k;
        double t0 = now_s();
        uint64_t pairs_seen = 0;
        for (int si = 0; si < size_count; si++) {
            uint32_t n = sizes[si];
            if (too_big(kind, n)) {
                continue;
            }
            for (int seed_i = 0; seed_i < seed_count(n); seed_i++) {
                uint64_t seed = (uint64_t)seed_i + 1;
                check_set_seed(seed);
                check_set_context("scene=%s n=%u reference", scene_kind_name(kind), n);
                CHECK(scene_generate(kind, n, seed, boxes) == 0);
                if (!world_pairs(ref_world, boxes, n, &ref)) {
                    continue;
                }
                pairs_seen += ref.count;
                CHECK_MSG(pairs_well_formed(ref.pairs, ref.count, n), "reference pairs unsorted");
                if (n <= oracle_max_n) {
                    check_set_context("scene=%s n=%u oracle vs reference", scene_kind_name(kind),
                                      n);
                    pair_list_brute(&oracle, boxes, n);
                    CHECK_PAIRS_EQ(oracle.pairs, oracle.count, ref.pairs, ref.count);
                }
                // The other entry points on the first seed only: they cost a cycle each.
                bool api_paths = seed_i == 0 && n <= 1234;
                if (api_paths) {
                    check_set_context("scene=%s n=%u one-shot", scene_kind_name(kind), n);
                    check_one_shot(boxes, n, &ref);
                }
                for (int c = 0; c < cfg_count; c++) {
                    if (n > check_backend_max_boxes(cfgs[c].backend)) {
                        continue;
                    }
                    check_set_context("scene=%s n=%u %s", scene_kind_name(kind), n, cfgs[c].label);
                    if (!world_pairs(cfgs[c].world, boxes, n, &got)) {
                        continue;
                    }
                    CHECK_PAIRS_EQ(ref.pairs, ref.count, got.pairs, got.count);
                    if (api_paths) {
                        check_caller_buffers(cfgs[c].world, &ref);
                    }
                }
                CHECK(fp_environment_intact());
            }
        }
        printf("  %-16s %6.2f s  (%" PRIu64 " reference pairs over all sizes and seeds)\n",
               scene_kind_name(kind), now_s() - t0, pairs_seen);
        fflush(stdout);
    }
    pair_list_free(&ref);
    pair_list_free(&oracle);
    pair_list_free(&got);
    free(boxes);
    bpx_world_destroy(ref_world);
}

// Two-phase updater (load_extents + update_centres) against set_boxes of the same boxes,
// computed here in float exactly as documented: min = c + m, max = c - m.
static void test_updater(config *cfgs, int cfg_count)
{
    static const scene_kind kinds[] = {SCENE_UNIFORM_DENSITY, SCENE_MIXED_SIZES, SCENE_TOUCHING,
                                       SCENE_ZERO_EXTENT,     SCENE_SIGNED_ZERO, SCENE_CLUSTERED,
                                       SCENE_DENSE,           SCENE_DENORMAL};
    static const uint32_t counts[] = {0, 1, 17, 257, 1234};
    enum { cycles = 4, max_n = 1234 };
    bpx_world *truth = make_world(BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, 0);
    if (!truth) {
        return;
    }
    // The reference backend's own updater is tested as well.
    bpx_world *worlds[max_configs + 1];
    char labels[max_configs + 1][80];
    int world_count = 0;
    worlds[world_count] = make_world(BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, 0);
    snprintf(labels[world_count], sizeof labels[0], "backend=reference");
    world_count += worlds[world_count] != NULL;
    for (int c = 0; c < cfg_count; c++) {
        worlds[world_count] =
            make_world(cfgs[c].backend, cfgs[c].simd, cfgs[c].workers, cfgs[c].opencl_method);
        snprintf(labels[world_count], sizeof labels[0], "%s", cfgs[c].label);
        world_count += worlds[world_count] != NULL;
    }
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * max_n);
    bpx_box *equivalent = check_alloc(sizeof(bpx_box) * max_n);
    float *minima = check_alloc(sizeof(float) * 3 * max_n);
    float *centres = check_alloc(sizeof(float) * 3 * max_n);
    pair_list want = {0};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        for (size_t ci = 0; ci < sizeof counts / sizeof counts[0]; ci++) {
            uint32_t n = counts[ci];
            uint64_t seed = 100 + ci;
            check_set_seed(seed);
            CHECK(scene_generate(kinds[k], n, seed, boxes) == 0);
            for (uint32_t i = 0; i < n; i++) {
                for (int a = 0; a < 3; a++) {
                    float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
                    minima[3 * i + a] = -half;
                    centres[3 * i + a] = boxes[i].min[a] + half;
                }
            }
            for (int w = 0; w < world_count; w++) {
                check_set_context("updater scene=%s n=%u %s", scene_kind_name(kinds[k]), n,
                                  labels[w]);
                CHECK_STATUS(bpx_world_load_extents(worlds[w], minima, n), BPX_OK);
                CHECK(bpx_world_box_count(worlds[w]) == n);
            }
            scene_rng motion;
            scene_rng_seed(&motion, seed);
            for (int cycle = 0; cycle < cycles; cycle++) {
                if (cycle > 0) {
                    for (uint32_t i = 0; i < 3 * n; i++) {
                        centres[i] += scene_rng_range(&motion, -0.05f, 0.05f);
                    }
                }
                for (uint32_t i = 0; i < n; i++) {
                    for (int a = 0; a < 3; a++) {
                        equivalent[i].min[a] = centres[3 * i + a] + minima[3 * i + a];
                        equivalent[i].max[a] = centres[3 * i + a] - minima[3 * i + a];
                    }
                }
                check_set_context("updater scene=%s n=%u cycle=%d truth", scene_kind_name(kinds[k]),
                                  n, cycle);
                if (!world_pairs(truth, equivalent, n, &want)) {
                    continue;
                }
                for (int w = 0; w < world_count; w++) {
                    if (n > check_backend_max_boxes(bpx_world_backend(worlds[w]))) {
                        continue;
                    }
                    check_set_context("updater scene=%s n=%u cycle=%d %s",
                                      scene_kind_name(kinds[k]), n, cycle, labels[w]);
                    CHECK_STATUS(bpx_world_update_centres(worlds[w], centres), BPX_OK);
                    CHECK_STATUS(bpx_world_collide(worlds[w]), BPX_OK);
                    size_t count = 0;
                    const bpx_pair *pairs = bpx_world_pairs(worlds[w], &count);
                    CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
                    CHECK_EQ_U64(bpx_world_stats(worlds[w]).box_count, n);
                }
            }
        }
    }
    pair_list_free(&want);
    free(boxes);
    free(equivalent);
    free(minima);
    free(centres);
    for (int w = 0; w < world_count; w++) {
        bpx_world_destroy(worlds[w]);
    }
    bpx_world_destroy(truth);
}

int main(int argc, char **argv)
{
    double t0 = now_s();
    opencl_only = argc > 1 && strcmp(argv[1], "--opencl") == 0;
    cuda_only = argc > 1 && strcmp(argv[1], "--cuda") == 0;
    const char *title = opencl_only ? "test_differential --opencl"
                        : cuda_only ? "test_differential --cuda"
                                    : "test_differential";
    printf("%s: scene seeds 1..3 (n <= 257), 1..2 (n <= 1234), 1 (n = 4099); "
           "updater seeds 100..104; simd best=%s\n",
           title, name_or(bpx_simd_name(bpx_simd_best())));
    if (cuda_only && !bpx_backend_query(BPX_BACKEND_CUDA).available) {
        printf("cuda unavailable: %s\n", name_or(bpx_backend_query(BPX_BACKEND_CUDA).reason));
        return check_finish(title, 0);
    }
    config cfgs[max_configs];
    int cfg_count = 0;
    if (opencl_only) {
        bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
        if (!info.available) {
            // Skipped only without OpenCL at all (as test_opencl); a device that fails to build
            // the kernels, say, is a failure.
            const char *reason = name_or(info.reason);
            printf("opencl unavailable: %s\n", reason);
            bool absent = strcmp(reason, "not in this build") == 0 ||
                          strcmp(reason, "no OpenCL platform") == 0;
            CHECK_MSG(absent, "opencl unavailable: %s", reason);
            return check_finish("test_differential --opencl", 0);
        }
        cfg_count = build_opencl_configs(cfgs);
    } else {
        cfg_count = build_configs(cfgs);
    }
    printf("%d configurations:\n", cfg_count);
    for (int c = 0; c < cfg_count; c++) {
        printf("  %s\n", cfgs[c].label);
    }
    fflush(stdout);
    // Even with no other backend the reference is still checked against the oracle.
    test_scenes_all_backends(cfgs, cfg_count);
    double t1 = now_s();
    test_updater(cfgs, cfg_count);
    printf("scenes %.2f s, updater %.2f s\n", t1 - t0, now_s() - t1);
    for (int c = 0; c < cfg_count; c++) {
        bpx_world_destroy(cfgs[c].world);
    }
    return check_finish(title, 1);
}
