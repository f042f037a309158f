// The read-only query path from many threads at once (include/bpx/query.h, "Threads"): after
// bpx_world_prepare_queries, 8 threads run bpx_world_query_shared and bpx_world_query_each on
// one world and must each get, byte for byte, what one thread got before. Under ThreadSanitizer
// (label threads) this also proves the path writes nothing shared.
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "scenes.h"

enum { threads = 8, boxes_n = 20000, queries_n = 1500, max_hits = 4096 };

static bpx_world *world;
static bpx_query queries[queries_n];
static bpx_hit *expected;       // queries_n * max_hits
static size_t expected_count[queries_n];

typedef struct visit_sum {
    uint64_t ids, user_data, count;
} visit_sum;

static float sum_hits(const bpx_hit *hit, uint64_t user_data, void *context)
{
    visit_sum *s = context;
    s->ids += hit->id;
    s->user_data += user_data;
    s->count++;
    return INFINITY;
}

typedef struct worker {
    int index;
    int mismatches;
} worker;

static void *run(void *arg)
{
    worker *me = arg;
    bpx_hit *hits = malloc(sizeof(bpx_hit) * max_hits);
    // Each thread walks the queries from its own starting point, so they overlap in time.
    for (int step = 0; step < 4 * queries_n; step++) {
        int k = (step + me->index * (queries_n / threads)) % queries_n;
        size_t count = 0;
        bpx_error err;
        bpx_status s = bpx_world_query_shared(world, &queries[k], hits, max_hits, &count, &err);
        if (s != BPX_OK || count != expected_count[k] ||
            memcmp(hits, expected + (size_t)k * max_hits, sizeof(bpx_hit) * count) != 0)
            me->mismatches++;
        if (queries[k].closest)
            continue;
        visit_sum sum = {0, 0, 0}, want = {0, 0, 0};
        for (size_t h = 0; h < count; h++) {
            want.ids += hits[h].id;
            want.user_data += 3u * hits[h].id + 1u;
        }
        want.count = count;
        bpx_query each = queries[k];
        each.any = false;
        if (bpx_world_query_each(world, &each, sum_hits, &sum, &err) != BPX_OK ||
            (!queries[k].any && memcmp(&sum, &want, sizeof sum) != 0))
            me->mismatches++;
    }
    free(hits);
    return NULL;
}

int main(void)
{
    bpx_box *boxes = malloc(sizeof(bpx_box) * boxes_n);
    expected = malloc(sizeof(bpx_hit) * (size_t)queries_n * max_hits);
    scene_uniform_density(boxes_n, 4.0f, 5, boxes);
    bpx_world_def def = bpx_default_world_def();
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(world, boxes, boxes_n), BPX_OK);
    uint64_t *data = malloc(sizeof(uint64_t) * boxes_n);
    for (uint32_t i = 0; i < boxes_n; i++)
        data[i] = 3u * i + 1u;
    CHECK_STATUS(bpx_world_set_user_data(world, NULL, data, boxes_n), BPX_OK);
    CHECK_STATUS(bpx_world_prepare_queries(world), BPX_OK);

    scene_rng r;
    scene_rng_seed(&r, 11);
    for (int k = 0; k < queries_n; k++) {
        const bpx_box *b = &boxes[scene_rng_below(&r, boxes_n)];
        float c[3] = {b->min[0], b->min[1], b->min[2]}, d[3];
        for (int a = 0; a < 3; a++)
            d[a] = scene_rng_range(&r, -1.0f, 1.0f);
        switch (k % 4) {
        case 0: queries[k] = bpx_query_box(*b); break;
        case 1: queries[k] = bpx_query_sphere(c, 2.0f); break;
        case 2: queries[k] = bpx_query_ray(c, d, 20.0f, k % 8 == 2); break;
        default: queries[k] = bpx_query_sweep(*b, d, 5.0f, false);
        }
        queries[k].any = k % 12 == 3;
        size_t count = 0;
        CHECK_STATUS(bpx_world_query_shared(world, &queries[k], expected + (size_t)k * max_hits,
                                            max_hits, &count, NULL),
                     BPX_OK);
        expected_count[k] = count;
    }

    pthread_t ids[threads];
    worker workers[threads];
    for (int t = 0; t < threads; t++) {
        workers[t] = (worker){t, 0};
        CHECK(pthread_create(&ids[t], NULL, run, &workers[t]) == 0);
    }
    for (int t = 0; t < threads; t++) {
        pthread_join(ids[t], NULL);
        CHECK_MSG(workers[t].mismatches == 0, "thread %d: %d mismatches", t,
                  workers[t].mismatches);
    }
    bpx_world_destroy(world);
    free(boxes);
    free(data);
    free(expected);
    return check_finish("test_query_threads", 1);
}
