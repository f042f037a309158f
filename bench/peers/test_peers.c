// bpx bench peers: every peer compiled in, on scenes from scenes.h, checked after every cycle
// against bpx's reference. SPDX-License-Identifier: MIT
//
// After creation and after each cycle: the peer's pairs whose exact boxes overlap equal
// bpx_find_pairs(REFERENCE) as a set (sorted, same bytes), and the peer's raw pair count (fat /
// quantised boxes) is at least that. The raw and exact counts are printed, so the README's
// table comes from here. No case is exempt: every peer here enlarges boxes conservatively
// (see README.md); if one ever did not, the difference must be reported, not hidden.
// Exit 77 when no peer is compiled in.
#include <float.h>
#include <stdbool.h>

#include "check.h"
#include "pairs_util.h"
#include "peers.h"
#include "scenes.h"

static const uint64_t kSeed = 0x5eed0001u;

/// The reference pairs of boxes into l (grown as needed).
static void reference_pairs(pair_list *l, const bpx_box *boxes, uint32_t n)
{
    size_t count = 0;
    bpx_error err;
    bpx_status s =
        bpx_find_pairs(boxes, n, BPX_BACKEND_REFERENCE, l->pairs, l->capacity, &count, &err);
    if (s == BPX_ERR_CAPACITY) {
        pair_list_reserve(l, count);
        s = bpx_find_pairs(boxes, n, BPX_BACKEND_REFERENCE, l->pairs, l->capacity, &count, &err);
    }
    CHECK_MSG(s == BPX_OK, "reference: %s", err.message);
    l->count = s == BPX_OK ? count : 0;
}

/// Checks the peer's pair set against the reference for the boxes of its last cycle.
static void check_frame(const bench_peer *peer, const char *peer_name, const char *scene,
                        uint32_t n, int frame, const bpx_box *boxes, pair_list *want,
                        pair_list *got, bool print)
{
    reference_pairs(want, boxes, n);
    uint64_t raw = bench_peer_pair_count(peer);
    uint64_t exact = bench_peer_exact_pairs(peer, boxes, NULL, 0);
    pair_list_reserve(got, (size_t)exact);
    uint64_t again = bench_peer_exact_pairs(peer, boxes, got->pairs, got->capacity);
    got->count = (size_t)(again < got->capacity ? again : got->capacity);
    CHECK_EQ_U64(again, exact);
    CHECK_MSG(pairs_well_formed(got->pairs, got->count, n),
              "%s %s frame %d: pairs not sorted, "
              "unique and in range",
              peer_name, scene, frame);
    CHECK_PAIRS_EQ(want->pairs, want->count, got->pairs, got->count);
    CHECK_MSG(raw >= exact, "%s %s frame %d: raw pair count %" PRIu64 " < exact %" PRIu64,
              peer_name, scene, frame, raw, exact);
    if (exact != want->count) {
        // Not expected for any peer here; if it happens the numbers go in the log and README.
        printf("  DIFFERENCE %s %s n=%u frame %d: peer exact %" PRIu64 ", reference %zu\n",
               peer_name, scene, n, frame, exact, want->count);
    }
    // A short buffer gets the smallest pairs, the same prefix, and the full count.
    if (want->count >= 2) {
        uint64_t half = want->count / 2;
        bpx_pair *part = check_alloc(sizeof(bpx_pair) * (size_t)half);
        uint64_t full = bench_peer_exact_pairs(peer, boxes, part, half);
        CHECK_EQ_U64(full, exact);
        CHECK_PAIRS_EQ(want->pairs, (size_t)half, part, (size_t)half);
        free(part);
    }
    if (print) {
        printf("  %-13s %-22s n=%-5u frame %d: raw %8" PRIu64 "  exact %8" PRIu64
               "  reference %8zu  (raw/exact %.2f)\n",
               peer_name, scene, n, frame, raw, exact, want->count,
               exact ? (double)raw / (double)exact : 0.0);
    }
}

/// Creates the peer on frames[0] and cycles it through every frame, checking each.
static void run_case(int index, const char *scene, const bpx_box *frames, uint32_t n,
                     int frame_count, bool print)
{
    const bench_peer_info *info = bench_peer_get(index);
    check_set_context("peer=%s scene=%s n=%u", info->name, scene, n);
    if (n > info->max_n) {
        printf("  %-13s %-22s n=%-5u skipped (max_n %u, slow_n %u)\n", info->name, scene, n,
               info->max_n, info->slow_n);
        return;
    }
    float lo[3] = {0.0f, 0.0f, 0.0f}, hi[3] = {0.0f, 0.0f, 0.0f};
    if (n > 0) {
        for (int a = 0; a < 3; a++) {
            lo[a] = FLT_MAX;
            hi[a] = -FLT_MAX;
        }
    }
    for (size_t k = 0; k < (size_t)n * (size_t)frame_count; k++) {
        for (int a = 0; a < 3; a++) {
            lo[a] = frames[k].min[a] < lo[a] ? frames[k].min[a] : lo[a];
            hi[a] = frames[k].max[a] > hi[a] ? frames[k].max[a] : hi[a];
        }
    }
    char err[160];
    bench_peer *peer = bench_peer_create(index, frames, n, lo, hi, err, sizeof err);
    CHECK_MSG(peer != NULL, "create: %s", err);
    if (!peer) {
        return;
    }
    pair_list want = {0}, got = {0};
    check_frame(peer, info->name, scene, n, -1, frames, &want, &got, false);
    for (int f = 0; f < frame_count; f++) {
        const bpx_box *boxes = frames + (size_t)f * n;
        CHECK_MSG(bench_peer_cycle(peer, boxes) == 0, "cycle %d failed", f);
        check_frame(peer, info->name, scene, n, f, boxes, &want, &got, print);
    }
    pair_list_free(&want);
    pair_list_free(&got);
    bench_peer_destroy(peer);
}

/// frames[0] = a scene, frames[1] = the same (a cycle where nothing moves), frames[2] = moved.
static bpx_box *static_scene_frames(scene_kind kind, uint32_t n, float step)
{
    bpx_box *frames = check_alloc(sizeof(bpx_box) * 3 * (n ? n : 1));
    CHECK(scene_generate(kind, n, kSeed, frames) == 0);
    memcpy(frames + n, frames, sizeof(bpx_box) * n);
    memcpy(frames + 2 * (size_t)n, frames, sizeof(bpx_box) * n);
    scene_rng r;
    scene_rng_seed(&r, kSeed + 1);
    scene_move(frames + 2 * (size_t)n, n, step, &r);
    return frames;
}

static void check_registry(void)
{
    int count = bench_peer_count();
    CHECK(bench_peer_get(-1) == NULL);
    CHECK(bench_peer_get(count) == NULL);
    CHECK(bench_peer_find("no-such-peer") == -1);
    CHECK(bench_peer_find(NULL) == -1);
    char err[160];
    CHECK(bench_peer_create(count, NULL, 0, NULL, NULL, err, sizeof err) == NULL);
    for (int k = 0; k < count; k++) {
        const bench_peer_info *info = bench_peer_get(k);
        CHECK(info && info->name && info->detail && info->detail[0]);
        CHECK(bench_peer_find(info->name) == k);
        printf("peer %-13s max_n %10u slow_n %10u  %s\n", info->name, info->max_n, info->slow_n,
               info->detail);
        if (info->max_n < UINT32_MAX) { // refused above max_n, with a message, before any box
            err[0] = 0;
            CHECK(bench_peer_create(k, NULL, info->max_n + 1, NULL, NULL, err, sizeof err) == NULL);
            CHECK(err[0] != 0);
        }
        // A bad box is refused with the message of bpx_validate_boxes.
        bpx_box bad = {{0, 0, 0}, {-1, 1, 1}};
        float lo[3] = {-2, -2, -2}, hi[3] = {2, 2, 2};
        err[0] = 0;
        CHECK(bench_peer_create(k, &bad, 1, lo, hi, err, sizeof err) == NULL);
        CHECK(err[0] != 0);
        bench_peer_destroy(NULL);
    }
}

int main(void)
{
    check_set_seed(kSeed);
    int count = bench_peer_count();
    printf("test_peers: %d peers compiled in, seed %" PRIu64 "\n", count, kSeed);
    check_registry();
    if (count == 0) {
        return check_finish("test_peers", 0);
    }

    // uniform_density, n = 2000, moved over 5 frames (the README's raw-vs-exact table).
    enum { kFrames = 5 };
    const uint32_t un = 2000;
    bpx_box *uniform = check_alloc(sizeof(bpx_box) * un * kFrames);
    scene_uniform_density(un, 1.0f, kSeed, uniform);
    scene_rng r;
    scene_rng_seed(&r, kSeed);
    for (int f = 1; f < kFrames; f++) {
        memcpy(uniform + (size_t)f * un, uniform + (size_t)(f - 1) * un, sizeof(bpx_box) * un);
        scene_move(uniform + (size_t)f * un, un, 0.2f, &r);
    }

    static const struct {
        scene_kind kind;
        uint32_t n;
    } kinds[] = {
        {SCENE_MIXED_SIZES, 1500},
        {SCENE_TOUCHING, 1500},
        {SCENE_SHARED_COORD, 1500},
        {SCENE_IDENTICAL, 1000},
    };
    bpx_box *scenes[sizeof kinds / sizeof kinds[0]];
    for (size_t s = 0; s < sizeof kinds / sizeof kinds[0]; s++) {
        scenes[s] = static_scene_frames(kinds[s].kind, kinds[s].n, 0.05f);
    }
    bpx_box one[2];
    scene_uniform_density(1, 1.0f, kSeed, one);
    one[1] = one[0];
    one[1].min[0] += 0.5f;
    one[1].max[0] += 0.5f;

    for (int k = 0; k < count; k++) {
        printf("%s:\n", bench_peer_get(k)->name);
        run_case(k, "uniform_density", uniform, un, kFrames, true);
        for (size_t s = 0; s < sizeof kinds / sizeof kinds[0]; s++) {
            run_case(k, scene_kind_name(kinds[s].kind), scenes[s], kinds[s].n, 3, true);
        }
        run_case(k, "empty", NULL, 0, 2, true);
        run_case(k, "one box", one, 1, 2, true);
    }

    free(uniform);
    for (size_t s = 0; s < sizeof kinds / sizeof kinds[0]; s++) {
        free(scenes[s]);
    }
    return check_finish("test_peers", 1);
}
