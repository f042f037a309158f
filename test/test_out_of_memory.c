// Allocation failure through the public API: every allocation of each entry point fails in
// turn, with no crash and no leak, and the call that fails for memory leaves the world as it was
// (a twin that never saw the call answers every later call the same).
#include <stdalign.h>
#include <stdatomic.h>

#include "error_util.h"
#include "pairs_util.h"
#include "scenes.h"

// ---------------------------------------------------------------------------------------------
// Allocation failure

static atomic_llong fa_budget; // successful allocations left; negative: unlimited
static atomic_llong fa_live;   // allocations not yet freed
static atomic_int fa_misuse;   // bad alignment, foreign pointer or wrong user pointer
static atomic_llong fa_failed;
static int fa_tag;

typedef struct fa_header {
    alignas(64) size_t magic;
} fa_header;

static void *fa_alloc(size_t size, size_t alignment, void *user)
{
    if (user != &fa_tag || alignment == 0 || (alignment & (alignment - 1)) != 0 ||
        alignment > 4096) {
        atomic_fetch_add(&fa_misuse, 1);
        return NULL;
    }
    if (atomic_load(&fa_budget) >= 0 && atomic_fetch_sub(&fa_budget, 1) <= 0) {
        atomic_fetch_add(&fa_failed, 1);
        return NULL;
    }
    // A header before the block marks our pointers, so a foreign free is caught.
    size_t align = alignment < sizeof(fa_header) ? sizeof(fa_header) : alignment;
    size_t total = (align + size + align - 1) / align * align;
    unsigned char *base = aligned_alloc(align, total);
    if (!base) {
        return NULL;
    }
    unsigned char *p = base + align;
    fa_header h = {.magic = 0xfa11ed00u ^ (size_t)align};
    memcpy(p - sizeof h, &h, sizeof h);
    atomic_fetch_add(&fa_live, 1);
    return p;
}

static void fa_free(void *memory, void *user)
{
    if (user != &fa_tag) {
        atomic_fetch_add(&fa_misuse, 1);
    }
    if (!memory) {
        return;
    }
    unsigned char *p = memory;
    fa_header h;
    memcpy(&h, p - sizeof h, sizeof h);
    size_t align = h.magic ^ 0xfa11ed00u;
    if (align < sizeof(fa_header) || align > 4096 || (align & (align - 1)) != 0) {
        atomic_fetch_add(&fa_misuse, 1);
        return;
    }
    atomic_fetch_sub(&fa_live, 1);
    free(p - align);
}

// One full run with the first `budget` allocations succeeding; returns whether every call
// succeeded (the run needed no more than `budget` allocations).
static bool alloc_run(long long budget, int workers, const bpx_box *boxes, uint32_t n,
                      const float *minima, const float *centres, const pair_list *want)
{
    atomic_store(&fa_budget, budget);
    bool all_ok = true;
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *w = (bpx_world *)&w;
    bpx_status s = bpx_world_create(&def, &w);
    CHECK_MSG(ok_or_oom(s), "create: %s", check_status_name(s));
    if (s != BPX_OK) {
        CHECK(w == NULL);
        return false;
    }
    s = bpx_world_set_boxes(w, boxes, n);
    CHECK_MSG(ok_or_oom(s), "set_boxes: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    bool have_boxes = s == BPX_OK;
    s = bpx_world_collide(w);
    CHECK_MSG(ok_or_oom(s), "collide: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK && have_boxes) {
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(w, &count);
        CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
    }
    bpx_pair small[4];
    size_t count = 0;
    s = bpx_world_collide_into(w, small, 4, &count);
    CHECK_MSG(s == BPX_ERR_CAPACITY || ok_or_oom(s), "collide_into: %s", check_status_name(s));
    all_ok &= s == BPX_ERR_CAPACITY || (s == BPX_OK && !have_boxes);
    s = bpx_world_load_extents(w, minima, n);
    CHECK_MSG(ok_or_oom(s), "load_extents: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK) {
        s = bpx_world_update_centres(w, centres);
        CHECK_MSG(ok_or_oom(s), "update_centres: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
        s = bpx_world_collide(w);
        CHECK_MSG(ok_or_oom(s), "collide after update: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
    }
    // With memory back, a world that saw failures recovers.
    atomic_store(&fa_budget, -1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t got = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &got);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, got);
    bpx_world_destroy(w);
    return all_ok;
}

static void test_allocation_failure(void)
{
    enum { n = 400 };
    const uint64_t seed = 4242;
    check_set_seed(seed);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_DENSE, n, seed, boxes) == 0);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    float *centres = check_alloc(sizeof(float) * 3 * n);
    extents_of(boxes, n, minima, centres);
    pair_list want = {0};
    pair_list_brute(&want, boxes, n);

    int64_t start = bpx_allocated_bytes();
    atomic_store(&fa_budget, -1);
    bpx_set_allocator(fa_alloc, fa_free, &fa_tag);
    static const int worker_counts[] = {1, 2, 3, 8};
    for (size_t wi = 0; wi < sizeof worker_counts / sizeof worker_counts[0]; wi++) {
        int workers = worker_counts[wi];
        long long budget = 0;
        for (; budget < 100000; budget++) {
            check_set_context("allocation failure after %lld allocations, %d workers", budget,
                              workers);
            bool done = alloc_run(budget, workers, boxes, n, minima, centres, &want);
            CHECK_MSG(bpx_allocated_bytes() == start, "allocated %lld bytes, started at %lld",
                      (long long)bpx_allocated_bytes(), (long long)start);
            CHECK_EQ_U64(atomic_load(&fa_live), 0);
            if (done) {
                break;
            }
        }
        printf("  %d workers: a full run needs %lld allocations; every shorter budget failed "
               "cleanly\n",
               workers, budget);
        CHECK(budget > 0);
    }
    check_set_context("allocator hooks");
    CHECK_EQ_U64(atomic_load(&fa_misuse), 0);
    CHECK(atomic_load(&fa_failed) > 0);
    bpx_set_allocator(NULL, NULL, NULL);

    // The default allocator is back: a world works and frees everything.
    bpx_world *w = new_world(2);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    bpx_world_destroy(w);
    CHECK(bpx_allocated_bytes() == start);
    pair_list_free(&want);
    free(boxes);
    free(minima);
    free(centres);
}

// ---------------------------------------------------------------------------------------------
// A call that fails for memory leaves the world as it was: a twin world that never saw the call
// answers every later call the same (statuses, ids handed out, pairs, events).

enum { keep_n = 300, keep_small = 50 };

static struct {
    bpx_box dense[keep_n];
    bpx_box apart[keep_n]; // the same boxes far apart: no pairs
    bpx_box pile[keep_n];  // every pair overlaps
    float minima[3 * keep_n];
    float tiny[3 * keep_n];
    float centres[3 * keep_n]; // with minima, neighbours overlap on x
    bpx_pair out[keep_n * keep_n / 2];
    uint32_t ids[keep_n];
    void *snapshot[2]; // of a world of objects, and of a two-phase world (make_snapshots)
    size_t snapshot_size[2];
} keep;

static void setup_two_phase(bpx_world *w)
{
    CHECK_STATUS(bpx_world_load_extents(w, keep.minima, 2), BPX_OK);
    CHECK_STATUS(bpx_world_update_centres(w, keep.centres), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
}

static void setup_plain(bpx_world *w)
{
    CHECK_STATUS(bpx_world_set_boxes(w, keep.dense, keep_small), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
}

// Filters, removed ids free for reuse and one removed id still pending.
static void setup_objects(bpx_world *w)
{
    setup_plain(w);
    const uint32_t filtered[2] = {5, 9}, cats[2] = {2, 2}, masks[2] = {0, 1};
    CHECK_STATUS(bpx_world_set_filters(w, filtered, cats, masks, 2), BPX_OK);
    const uint32_t grouped[2] = {8, 10};
    const int32_t groups[2] = {-1, -1};
    CHECK_STATUS(bpx_world_set_groups(w, grouped, groups, 2), BPX_OK);
    const bpx_pair excluded[2] = {{0, 1}, {7, 2}}; // 7's goes with it, at the collide below
    CHECK_STATUS(bpx_world_exclude_pairs(w, excluded, 2), BPX_OK);
    const uint64_t data[2] = {11, 12};
    CHECK_STATUS(bpx_world_set_user_data(w, grouped, data, 2), BPX_OK);
    const uint32_t removed[3] = {3, 7, 11};
    CHECK_STATUS(bpx_world_remove_boxes(w, removed, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_remove_boxes(w, removed + 2, 1), BPX_OK);
}

// One pair last cycle, every pair now: the events' lists must grow, and the next events must
// still be reported against that one pair.
static void setup_events(bpx_world *w)
{
    bpx_box one_pair[keep_small];
    memcpy(one_pair, keep.apart, sizeof one_pair);
    one_pair[1] = one_pair[0];
    CHECK_STATUS(bpx_world_set_boxes(w, one_pair, keep_small), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, keep.pile, keep_small), BPX_OK);
}

static void setup_events_pending(bpx_world *w)
{
    setup_events(w);
    const uint32_t removed[2] = {3, 11};
    CHECK_STATUS(bpx_world_remove_boxes(w, removed, 2), BPX_OK);
}

static bpx_status call_load(bpx_world *w)
{
    return bpx_world_load_extents(w, keep.tiny, keep_n);
}
static bpx_status call_set(bpx_world *w)
{
    return bpx_world_set_boxes(w, keep.dense, keep_n);
}
static bpx_status call_add(bpx_world *w)
{
    return bpx_world_add_boxes(w, keep.dense, keep_n, keep.ids);
}
static const uint32_t some_ids[3] = {1, 2, 4};
static bpx_status call_remove(bpx_world *w)
{
    return bpx_world_remove_boxes(w, some_ids, 3);
}
static bpx_status call_move(bpx_world *w)
{
    return bpx_world_move_boxes(w, some_ids, keep.apart + keep_n - 3, 3);
}
static bpx_status call_filters(bpx_world *w)
{
    const uint32_t cats[3] = {2, 2, 2}, masks[3] = {0, 0, 0};
    return bpx_world_set_filters(w, some_ids, cats, masks, 3);
}
static bpx_status call_groups(bpx_world *w)
{
    const int32_t groups[3] = {-2, -2, -2};
    return bpx_world_set_groups(w, some_ids, groups, 3);
}
static bpx_status call_exclude(bpx_world *w)
{
    bpx_pair pairs[38]; // past the set's first 32 keys: it grows
    for (uint32_t k = 0; k < 38; k++)
        pairs[k] = (bpx_pair){k % 2, 12 + k}; // ids < 50, none removed by setup_objects
    return bpx_world_exclude_pairs(w, pairs, 38);
}
static bpx_status call_user_data(bpx_world *w)
{
    const uint64_t values[3] = {1, 2, 3};
    return bpx_world_set_user_data(w, some_ids, values, 3);
}
static bpx_status call_restore_objects(bpx_world *w)
{
    return bpx_world_restore(w, keep.snapshot[0], keep.snapshot_size[0]);
}
static bpx_status call_restore_two_phase(bpx_world *w)
{
    return bpx_world_restore(w, keep.snapshot[1], keep.snapshot_size[1]);
}

// Snapshots bigger than the cases' worlds (300 boxes), made before any allocation fails.
static void make_snapshots(void)
{
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    for (int k = 0; k < 2; k++) {
        bpx_world *w = NULL;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
        if (k == 0) {
            CHECK_STATUS(bpx_world_set_boxes(w, keep.dense, keep_n), BPX_OK);
            const uint32_t ids[2] = {5, 9}, cats[2] = {2, 2}, masks[2] = {0, 1};
            CHECK_STATUS(bpx_world_set_filters(w, ids, cats, masks, 2), BPX_OK);
            const bpx_pair excluded[1] = {{1, 2}};
            CHECK_STATUS(bpx_world_exclude_pairs(w, excluded, 1), BPX_OK);
            const uint32_t removed = 7;
            CHECK_STATUS(bpx_world_remove_boxes(w, &removed, 1), BPX_OK);
        } else {
            CHECK_STATUS(bpx_world_load_extents(w, keep.minima, keep_n), BPX_OK);
            CHECK_STATUS(bpx_world_update_centres(w, keep.centres), BPX_OK);
        }
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        bpx_world_snapshot(w, NULL, 0, &keep.snapshot_size[k]);
        keep.snapshot[k] = malloc(keep.snapshot_size[k]);
        CHECK_STATUS(bpx_world_snapshot(w, keep.snapshot[k], keep.snapshot_size[k],
                                        &keep.snapshot_size[k]),
                     BPX_OK);
        bpx_world_destroy(w);
    }
}

static bpx_status call_collide(bpx_world *w)
{
    return bpx_world_collide(w);
}
static bpx_status call_collide_into(bpx_world *w)
{
    size_t count = 0;
    return bpx_world_collide_into(w, keep.out, sizeof keep.out / sizeof keep.out[0], &count);
}

typedef struct keep_case {
    const char *name;
    void (*setup)(bpx_world *w);
    bpx_status (*call)(bpx_world *w);
} keep_case;

static void check_same_cycle(bpx_world *w, bpx_world *twin)
{
    CHECK_EQ_U64(bpx_world_box_count(w), bpx_world_box_count(twin));
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_collide(twin), BPX_OK);
    size_t count = 0, want_count = 0;
    const bpx_pair *got = bpx_world_pairs(w, &count);
    const bpx_pair *want = bpx_world_pairs(twin, &want_count);
    CHECK_PAIRS_EQ(want, want_count, got, count);
    bpx_pair_events ev, want_ev;
    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
    CHECK_STATUS(bpx_world_pair_events(twin, &want_ev), BPX_OK);
    CHECK_PAIRS_EQ(want_ev.began, want_ev.began_count, ev.began, ev.began_count);
    CHECK_PAIRS_EQ(want_ev.ended, want_ev.ended_count, ev.ended, ev.ended_count);
}

// Adds a box to both (before a collide: pending ids must still be held back), then cycles.
static void check_same_world(bpx_world *w, bpx_world *twin)
{
    uint32_t id = UINT32_MAX, want_id = UINT32_MAX;
    CHECK_STATUS(bpx_world_add_boxes(w, keep.dense, 1, &id),
                 bpx_world_add_boxes(twin, keep.dense, 1, &want_id));
    CHECK_EQ_U64(id, want_id);
    check_same_cycle(w, twin);
    CHECK_STATUS(bpx_world_update_centres(w, keep.centres),
                 bpx_world_update_centres(twin, keep.centres));
    check_same_cycle(w, twin);
    CHECK_STATUS(bpx_world_add_boxes(w, keep.dense, 2, keep.ids),
                 bpx_world_add_boxes(twin, keep.dense, 2, keep.ids + 2));
    CHECK(keep.ids[0] == keep.ids[2] && keep.ids[1] == keep.ids[3]);
    check_same_cycle(w, twin);
}

static void test_failure_keeps_world(void)
{
    CHECK(scene_generate(SCENE_DENSE, keep_n, 2222, keep.dense) == 0);
    for (uint32_t i = 0; i < keep_n; i++) {
        keep.apart[i] = keep.dense[i];
        keep.apart[i].min[0] += 1000.0f * (float)i;
        keep.apart[i].max[0] += 1000.0f * (float)i;
        keep.pile[i] = (bpx_box){{0, 0, 0}, {1 + 0.01f * (float)i, 1, 1}};
        for (int a = 0; a < 3; a++) {
            keep.minima[3 * i + a] = -0.5f;
            keep.tiny[3 * i + a] = -0.01f;
            keep.centres[3 * i + a] = a == 0 ? 0.75f * (float)i : 0.0f;
        }
    }
    static const keep_case cases[] = {
        {"load_extents over two-phase", setup_two_phase, call_load},
        {"load_extents over objects", setup_objects, call_load},
        {"set_boxes over two-phase", setup_two_phase, call_set},
        {"set_boxes over objects", setup_objects, call_set},
        {"add_boxes", setup_plain, call_add},
        {"add_boxes over objects", setup_objects, call_add},
        {"remove_boxes, first", setup_plain, call_remove},
        {"move_boxes, first", setup_plain, call_move},
        {"set_filters, first", setup_plain, call_filters},
        {"set_groups, first", setup_plain, call_groups},
        {"exclude_pairs, first", setup_plain, call_exclude},
        {"exclude_pairs over objects", setup_objects, call_exclude},
        {"set_user_data, first", setup_plain, call_user_data},
        {"collide with events", setup_events, call_collide},
        {"collide_into with events", setup_events, call_collide_into},
        {"collide with pending ids", setup_events_pending, call_collide},
        {"restore over objects", setup_objects, call_restore_objects},
        {"restore over two-phase", setup_two_phase, call_restore_two_phase},
        {"restore two-phase over objects", setup_objects, call_restore_two_phase},
    };
    make_snapshots();
    int64_t start = bpx_allocated_bytes();
    atomic_store(&fa_budget, -1);
    bpx_set_allocator(fa_alloc, fa_free, &fa_tag);
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        int failures = 0;
        for (long long budget = 0; budget < 1000; budget++) {
            check_set_context("%s, failing after %lld allocations", cases[c].name, budget);
            bpx_world *w = NULL, *twin = NULL;
            CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
            CHECK_STATUS(bpx_world_create(&def, &twin), BPX_OK);
            if (!w || !twin) {
                bpx_world_destroy(w);
                bpx_world_destroy(twin);
                break;
            }
            cases[c].setup(w);
            cases[c].setup(twin);
            atomic_store(&fa_budget, budget);
            bpx_status s = cases[c].call(w);
            atomic_store(&fa_budget, -1);
            bool done = s == BPX_OK;
            if (!done) {
                failures++;
                check_world_error(w, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1);
                check_same_world(w, twin);
            }
            bpx_world_destroy(w);
            bpx_world_destroy(twin);
            CHECK_EQ_U64(atomic_load(&fa_live), 0);
            if (done)
                break;
        }
        check_set_context("%s", cases[c].name);
        CHECK_MSG(failures > 0, "no allocation of the call failed: the case tests nothing");
    }
    bpx_set_allocator(NULL, NULL, NULL);
    free(keep.snapshot[0]);
    free(keep.snapshot[1]);
    CHECK(bpx_allocated_bytes() == start);
}

// bpx_find_neighbors with every allocation failing in turn: OUT_OF_MEMORY, an empty list, nothing
// held; the run that succeeds gives the pairs of an unhindered run (periodic points in a small
// cell, so that images, pairs with images and distances are all allocated). Then the same in a
// triclinic cell (the cutoff past half its thinnest face: several images of a pair, a point's
// hits growing past their first room).
static void test_neighbors_allocation_failure(bool triclinic)
{
    enum { n = 300 };
    static double points[3 * n];
    uint64_t x = 77;
    for (int k = 0; k < 3 * n; k++) {
        x = x * 6364136223846793005ull + 1442695040888963407ull;
        points[k] = (double)(x >> 40) / (double)(1u << 24) * 6.0;
    }
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = BPX_POINTS_F64;
    def.period[0] = def.period[1] = def.period[2] = 6.0;
    def.cutoff = 1.5;
    def.metric = BPX_METRIC_EUCLIDEAN;
    def.want_distances = true;
    if (triclinic) {
        const double cell[3][3] = {{6.0, 0.0, 0.0}, {2.5, 5.0, 0.0}, {-1.5, 2.0, 2.0}};
        memset(def.period, 0, sizeof def.period);
        memcpy(def.cell, cell, sizeof def.cell);
        def.cutoff = 2.5;
    }
    bpx_neighbor_list want;
    CHECK_STATUS(bpx_find_neighbors(&def, points, n, &want, NULL), BPX_OK);
    int64_t start = bpx_allocated_bytes();
    atomic_store(&fa_budget, -1);
    bpx_set_allocator(fa_alloc, fa_free, &fa_tag);
    for (def.worker_count = 1; def.worker_count <= 3; def.worker_count += 2) {
        long long budget = 0;
        for (; budget < 100000; budget++) {
            check_set_context("neighbors%s: allocation failure after %lld allocations, %d "
                              "workers",
                              triclinic ? " (triclinic)" : "", budget, def.worker_count);
            atomic_store(&fa_budget, budget);
            bpx_neighbor_list list;
            bpx_error err;
            bpx_status status = bpx_find_neighbors(&def, points, n, &list, &err);
            atomic_store(&fa_budget, -1);
            if (status == BPX_OK) {
                CHECK(list.count == want.count &&
                      memcmp(list.pairs, want.pairs, want.count * sizeof *want.pairs) == 0 &&
                      memcmp(list.distances, want.distances, want.count * sizeof(double)) == 0);
                bpx_neighbor_list_free(&list);
                break;
            }
            CHECK_STATUS(status, BPX_ERR_OUT_OF_MEMORY);
            CHECK(list.count == 0 && list.pairs == NULL && list.distances == NULL);
            CHECK_EQ_U64(atomic_load(&fa_live), 0);
            CHECK(bpx_allocated_bytes() == start);
        }
        printf("  neighbors%s, %d workers: a full run needs %lld allocations; every shorter "
               "budget failed cleanly\n",
               triclinic ? " (triclinic)" : "", def.worker_count, budget);
        CHECK(budget > 3);
    }
    bpx_set_allocator(NULL, NULL, NULL);
    bpx_neighbor_list_free(&want);
}

int main(void)
{
    printf("test_out_of_memory: allocation scene dense n=400 seed 4242, twin scenes dense n=%d "
           "seed 2222\n",
           keep_n);
    test_allocation_failure();
    test_failure_keeps_world();
    test_neighbors_allocation_failure(false);
    test_neighbors_allocation_failure(true);
    return check_finish("test_out_of_memory", 1);
}
