// A soak: a world that moves, grows and shrinks for a million cycles, with objects added and
// removed, filters changed and events tracked, checked against Algorithm 1 every k cycles, its
// resident memory sampled from /proc/self/statm. SPDX-License-Identifier: MIT
//
//   test_soak [CYCLES [K [WORKERS [BACKEND]]]]     defaults 1000000, 1000, 2, auto
//
// The population follows a sine between 200 and 1800 boxes (period 50,000 cycles) and every
// box's size another (period 20,000 cycles, its own phase); boxes wander and bounce off the
// walls of a cube sized for about one overlap per box. Each cycle moves every live box, adds or
// removes a few (and swaps one out and in), and collides; every 100 cycles ten filters change.
// Every cycle checks that the events add up (began - ended = this count - last count) and each
// added box's id; every K cycles the pairs are checked against brute force over the model of
// the world (live boxes, filters: the oracle that fuzz/fuzz_api.c uses too, oracle.h) and the
// events against the previous cycle's pairs.
//
// Memory: the first 10% of the cycles (two population periods at the default) are warm-up. After
// it, the resident set must stay within 2 MB of its warm-up peak, and the bytes the library
// holds (bpx_allocated_bytes) within 1 MB of theirs; with fewer than 200,000 cycles (the short
// run in the unit tests, and under the sanitizers, whose allocators keep freed memory) the
// figures are printed, not asserted. All the test's own memory is allocated before cycle 0.
#define _POSIX_C_SOURCE 200809L // clock_gettime, sysconf
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "check.h"
#include "oracle.h"

enum {
    MAX_IDS = 4096,
    MAX_PAIRS = 1 << 20,
    POP_MIN = 200,
    POP_MAX = 1800,
    POP_PERIOD = 50000,
    SIZE_PERIOD = 20000,
    FILTER_EVERY = 100,
    ASSERT_MEMORY_FROM = 200000, // cycles: below, memory is reported only
};
static const float WALL = 24.0f; // the cube [0, WALL]^3: about one overlap per box at POP_MAX

typedef struct soak {
    bpx_world *world;
    uint64_t rng;
    oracle_model model; // what the world holds: boxes, live ids, filters
    // Each id's motion, and the live ids to pick from.
    float centre[MAX_IDS][3], velocity[MAX_IDS][3], base[MAX_IDS], phase[MAX_IDS];
    uint32_t live_ids[MAX_IDS], live_count;
    // Scratch, allocated once.
    uint32_t *ids;
    bpx_box *boxes;
    bpx_pair *want, *previous, *diff;
    size_t previous_count;
    bool have_previous;
} soak;

static uint64_t next(soak *s)
{
    s->rng ^= s->rng << 13, s->rng ^= s->rng >> 7, s->rng ^= s->rng << 17;
    return s->rng;
}

static float uniform(soak *s, float lo, float hi)
{
    return lo + (hi - lo) * (float)(next(s) >> 40) / (float)(1u << 24);
}

static long resident_kb(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    if (!f)
        return -1;
    long size = 0, resident = 0;
    int got = fscanf(f, "%ld %ld", &size, &resident);
    fclose(f);
    return got == 2 ? resident * (sysconf(_SC_PAGESIZE) / 1024) : -1;
}

// Every box grows and shrinks by half its base size, each in its own phase.
static float half_extent(float base, float phase, uint64_t cycle)
{
    return base * (1.0f + 0.5f * sinf(6.2831853f * (float)(cycle % SIZE_PERIOD) / SIZE_PERIOD +
                                      phase));
}

static bpx_box box_of(const soak *s, uint32_t id, uint64_t cycle)
{
    float h = half_extent(s->base[id], s->phase[id], cycle);
    const float *c = s->centre[id];
    return (bpx_box){{c[0] - h, c[1] - h, c[2] - h}, {c[0] + h, c[1] + h, c[2] + h}};
}

static uint32_t population(uint64_t cycle)
{
    double t = (double)(cycle % POP_PERIOD) / POP_PERIOD;
    return (uint32_t)((POP_MIN + POP_MAX) / 2 + (POP_MAX - POP_MIN) / 2 * sin(6.283185307 * t));
}

static void add_objects(soak *s, uint32_t count, uint64_t cycle)
{
    float centre[8][3], velocity[8][3], base[8], phase[8];
    bpx_box boxes[8];
    for (uint32_t k = 0; k < count; k++) {
        for (int a = 0; a < 3; a++) {
            centre[k][a] = uniform(s, 1.0f, WALL - 1.0f);
            velocity[k][a] = uniform(s, -0.02f, 0.02f);
        }
        base[k] = uniform(s, 0.3f, 1.2f);
        phase[k] = uniform(s, 0.0f, 6.2831853f);
        float h = half_extent(base[k], phase[k], cycle);
        const float *c = centre[k];
        boxes[k] = (bpx_box){{c[0] - h, c[1] - h, c[2] - h}, {c[0] + h, c[1] + h, c[2] + h}};
    }
    uint32_t ids[8];
    CHECK_STATUS(bpx_world_add_boxes(s->world, boxes, count, ids), BPX_OK);
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = oracle_add(&s->model, &boxes[k]); // live, unfiltered
        CHECK_MSG(ids[k] == id, "add_boxes gave id %u, the model %u", ids[k], id);
        memcpy(s->centre[id], centre[k], sizeof s->centre[id]);
        memcpy(s->velocity[id], velocity[k], sizeof s->velocity[id]);
        s->base[id] = base[k];
        s->phase[id] = phase[k];
        s->live_ids[s->live_count++] = id;
    }
}

static void remove_objects(soak *s, uint32_t count)
{
    uint32_t ids[8];
    if (count > s->live_count)
        count = s->live_count;
    for (uint32_t k = 0; k < count; k++) {
        uint32_t at = (uint32_t)(next(s) % s->live_count);
        ids[k] = s->live_ids[at];
        s->live_ids[at] = s->live_ids[--s->live_count];
        oracle_remove(&s->model, ids[k]);
    }
    CHECK_STATUS(bpx_world_remove_boxes(s->world, ids, count), BPX_OK);
}

// Every live box takes a step, bouncing off the walls, at its size of this cycle.
static void move_all(soak *s, uint64_t cycle)
{
    for (uint32_t k = 0; k < s->live_count; k++) {
        uint32_t id = s->live_ids[k];
        for (int a = 0; a < 3; a++) {
            float c = s->centre[id][a] + s->velocity[id][a];
            if (c < 0.0f || c > WALL) {
                s->velocity[id][a] = -s->velocity[id][a];
                c = s->centre[id][a] + s->velocity[id][a];
            }
            s->centre[id][a] = c;
        }
        s->ids[k] = id;
        s->boxes[k] = box_of(s, id, cycle);
        oracle_move(&s->model, id, &s->boxes[k]);
    }
    CHECK_STATUS(bpx_world_move_boxes(s->world, s->ids, s->boxes, s->live_count), BPX_OK);
}

static void change_filters(soak *s)
{
    uint32_t ids[10], categories[10], masks[10], count = 0;
    for (; count < 10 && s->live_count; count++) {
        uint32_t id = s->live_ids[next(s) % s->live_count];
        ids[count] = id;
        uint64_t r = next(s);
        categories[count] = 1u << (r % 3);
        masks[count] = (r >> 8) % 4 == 0 ? UINT32_MAX & ~(1u << ((r >> 16) % 3)) : UINT32_MAX;
        oracle_set_filter(&s->model, id, categories[count], masks[count]);
    }
    CHECK_STATUS(bpx_world_set_filters(s->world, ids, categories, masks, count), BPX_OK);
}

int main(int argc, char **argv)
{
    uint64_t cycles = argc > 1 ? strtoull(argv[1], NULL, 10) : 1000000;
    uint64_t k = argc > 2 ? strtoull(argv[2], NULL, 10) : 1000;
    int workers = argc > 3 ? atoi(argv[3]) : 2;
    bpx_backend backend = BPX_BACKEND_AUTO;
    if (argc > 4 && bpx_backend_from_name(argv[4], &backend) != BPX_OK) {
        fprintf(stderr, "test_soak: no backend named %s\n", argv[4]);
        return 2;
    }
    if (k == 0)
        k = 1;
    static soak s;
    s.rng = 0x50A4C0FFEEull;
    oracle_init(&s.model, MAX_IDS);
    check_set_seed(s.rng);
    s.ids = malloc(MAX_IDS * sizeof *s.ids);
    s.boxes = malloc(MAX_IDS * sizeof *s.boxes);
    s.want = malloc(MAX_PAIRS * sizeof *s.want);
    s.previous = malloc(MAX_PAIRS * sizeof *s.previous);
    s.diff = malloc(MAX_PAIRS * sizeof *s.diff);
    if (!s.ids || !s.boxes || !s.want || !s.previous || !s.diff) {
        fprintf(stderr, "test_soak: no memory\n");
        return 1;
    }
    // Touch the test's own memory now, so that its first use is no growth after warm-up.
    memset(s.want, 0, MAX_PAIRS * sizeof *s.want);
    memset(s.previous, 0, MAX_PAIRS * sizeof *s.previous);
    memset(s.diff, 0, MAX_PAIRS * sizeof *s.diff);

    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    def.track_events = true;
    def.backend = backend;
    CHECK_STATUS(bpx_world_create(&def, &s.world), BPX_OK);
    if (!s.world)
        return check_finish("test_soak", 1);

    uint64_t warm_up = cycles / 10;
    long rss_first = resident_kb(), rss_warm = 0, rss_after = 0, rss_last = 0;
    int64_t lib_warm = 0, lib_after = 0;
    size_t last_count = 0, max_pairs = 0;
    uint32_t max_n = 0;
    uint64_t checks = 0, backend_cycles[BPX_BACKEND_COUNT] = {0};
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (uint64_t c = 0; c < cycles && check_failures == 0; c++) {
        uint32_t target = population(c);
        if (s.live_count < target)
            add_objects(&s, target - s.live_count < 5 ? target - s.live_count : 5, c);
        else if (s.live_count > target)
            remove_objects(&s, s.live_count - target < 5 ? s.live_count - target : 5);
        if (c % 3 == 0 && s.live_count > 1) { // one out, one in
            remove_objects(&s, 1);
            add_objects(&s, 1, c);
        }
        move_all(&s, c);
        if (c % FILTER_EVERY == 0)
            change_filters(&s);
        CHECK_STATUS(bpx_world_collide(s.world), BPX_OK);
        oracle_collided(&s.model);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(s.world, &count);
        bpx_pair_events ev;
        CHECK_STATUS(bpx_world_pair_events(s.world, &ev), BPX_OK);
        CHECK_MSG(ev.began_count + last_count == count + ev.ended_count,
                  "cycle %llu: %zu began, %zu ended, %zu -> %zu pairs", (unsigned long long)c,
                  ev.began_count, ev.ended_count, last_count, count);
        uint32_t n = bpx_world_box_count(s.world);
        CHECK_MSG(n == s.model.n, "cycle %llu: %u boxes, the model %u", (unsigned long long)c, n,
                  s.model.n);
        backend_cycles[bpx_world_backend(s.world)]++;
        max_n = n > max_n ? n : max_n;
        max_pairs = count > max_pairs ? count : max_pairs;
        if ((c + 1) % k == 0 || c + 1 == cycles) { // the full check
            checks++;
            size_t want = oracle_pairs(&s.model, s.want, MAX_PAIRS);
            CHECK_MSG(want <= MAX_PAIRS, "%zu pairs: more than the test holds", want);
            CHECK_MSG(oracle_same_pairs(pairs, count, s.want, want),
                      "cycle %llu: %zu pairs, the reference %zu", (unsigned long long)c, count,
                      want);
            if (s.have_previous) {
                size_t began = oracle_difference(s.want, want, s.previous, s.previous_count, s.diff);
                CHECK_MSG(oracle_same_pairs(ev.began, ev.began_count, s.diff, began),
                          "cycle %llu: began differs", (unsigned long long)c);
                size_t ended = oracle_difference(s.previous, s.previous_count, s.want, want, s.diff);
                CHECK_MSG(oracle_same_pairs(ev.ended, ev.ended_count, s.diff, ended),
                          "cycle %llu: ended differs", (unsigned long long)c);
            }
            long rss = resident_kb();
            int64_t lib = bpx_allocated_bytes();
            if (c < warm_up) {
                rss_warm = rss > rss_warm ? rss : rss_warm;
                lib_warm = lib > lib_warm ? lib : lib_warm;
            } else {
                rss_after = rss > rss_after ? rss : rss_after;
                lib_after = lib > lib_after ? lib : lib_after;
            }
            rss_last = rss;
        }
        // The pairs of the cycle before a check, for its events.
        s.have_previous = (c + 2) % k == 0;
        if (s.have_previous) {
            s.previous_count = count <= MAX_PAIRS ? count : MAX_PAIRS;
            if (count)
                memcpy(s.previous, pairs, s.previous_count * sizeof *pairs);
        }
        last_count = count;
        if ((c + 1) % (cycles / 10 ? cycles / 10 : 1) == 0) {
            clock_gettime(CLOCK_MONOTONIC, &t1);
            printf("cycle %8llu  %6.1f s  n %4u  live %4u  pairs %5zu  rss %6ld kB  library "
                   "%8lld B\n",
                   (unsigned long long)c + 1,
                   (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec),
                   n, s.live_count, count, resident_kb(), (long long)bpx_allocated_bytes());
            fflush(stdout);
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    printf("%llu cycles in %.1f s (%.1f us per cycle), %llu full checks, n up to %u, pairs up "
           "to %zu\n",
           (unsigned long long)cycles, seconds, 1e6 * seconds / (double)(cycles ? cycles : 1),
           (unsigned long long)checks, max_n, max_pairs);
    printf("cycles per backend the world ran:");
    for (int b = 0; b < BPX_BACKEND_COUNT; b++)
        if (backend_cycles[b])
            printf(" %s %llu", bpx_backend_name((bpx_backend)b),
                   (unsigned long long)backend_cycles[b]);
    printf("\nresident: %ld kB at start, peak %ld kB in warm-up (first %llu cycles), peak %ld kB "
           "after, %ld kB at the end\nlibrary: peak %lld B in warm-up, peak %lld B after\n",
           rss_first, rss_warm, (unsigned long long)warm_up, rss_after, rss_last,
           (long long)lib_warm, (long long)lib_after);
    if (cycles >= ASSERT_MEMORY_FROM) {
        CHECK_MSG(rss_after <= rss_warm + 2048, "resident set grew after warm-up: %ld -> %ld kB",
                  rss_warm, rss_after);
        CHECK_MSG(lib_after <= lib_warm + (1 << 20),
                  "library memory grew after warm-up: %lld -> %lld B", (long long)lib_warm,
                  (long long)lib_after);
    }
    bpx_world_destroy(s.world);
    free(s.ids);
    free(s.boxes);
    free(s.want);
    free(s.previous);
    free(s.diff);
    oracle_free(&s.model);
    return check_finish("test_soak", 1);
}
