// bpx_snapbench: what a snapshot and a restore cost beside one collide of the same world, on
// uniform boxes (one overlap per box) with user data on every box, medians of alternating
// rounds. SPDX-License-Identifier: MIT
//
//   bpx_snapbench [n = 1000000] [workers = 1] [rounds = 5]
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include <bpx/bpx.h>

#include "scenes.h"

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int count)
{
    qsort(v, (size_t)count, sizeof *v, by_value);
    return count % 2 ? v[count / 2] : 0.5 * (v[count / 2 - 1] + v[count / 2]);
}

int main(int argc, char **argv)
{
    uint32_t n = argc > 1 ? (uint32_t)strtoul(argv[1], NULL, 10) : 1000000;
    int workers = argc > 2 ? atoi(argv[2]) : 1;
    int rounds = argc > 3 ? atoi(argv[3]) : 5;
    if (rounds < 1 || rounds > 100 || n == 0) {
        fprintf(stderr, "usage: bpx_snapbench [n] [workers] [rounds 1..100]\n");
        return 2;
    }
    bpx_box *boxes = malloc(sizeof(bpx_box) * n);
    uint64_t *data = malloc(sizeof(uint64_t) * n);
    scene_uniform_density(n, 1.0f, 42, boxes);
    for (uint32_t i = 0; i < n; i++)
        data[i] = i * 2654435761u;
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    def.track_events = true;
    bpx_world *w;
    if (bpx_world_create(&def, &w) != BPX_OK || bpx_world_set_boxes(w, boxes, n) != BPX_OK ||
        bpx_world_set_user_data(w, NULL, data, n) != BPX_OK || bpx_world_collide(w) != BPX_OK) {
        fprintf(stderr, "bpx: cannot make the world\n");
        return 1;
    }
    size_t size = 0;
    bpx_world_snapshot(w, NULL, 0, &size);
    void *buffer = malloc(size);
    double collide[100], snap[100], restore[100];
    for (int r = 0; r < rounds; r++) {
        double t0 = now_s();
        bpx_world_collide(w);
        double t1 = now_s();
        bpx_status s = bpx_world_snapshot(w, buffer, size, &size);
        double t2 = now_s();
        s = s == BPX_OK ? bpx_world_restore(w, buffer, size) : s;
        double t3 = now_s();
        if (s != BPX_OK) {
            fprintf(stderr, "bpx: %s\n", bpx_status_string(s));
            return 1;
        }
        collide[r] = t1 - t0, snap[r] = t2 - t1, restore[r] = t3 - t2;
    }
    size_t pairs = 0;
    bpx_world_collide(w);
    bpx_world_pairs(w, &pairs);
    double c = median(collide, rounds), sn = median(snap, rounds), re = median(restore, rounds);
    printf("| boxes | pairs | snapshot bytes | collide (%s, %d workers) | snapshot | restore | "
           "(snapshot + restore) / collide |\n|---:|---:|---:|---:|---:|---:|---:|\n",
           bpx_backend_name(bpx_world_backend(w)), workers);
    printf("| %u | %zu | %zu (%.1f per box) | %.2f ms | %.2f ms | %.2f ms | %.2f |\n", n, pairs,
           size, (double)size / n, 1e3 * c, 1e3 * sn, 1e3 * re, (sn + re) / c);
    bpx_world_destroy(w);
    free(buffer);
    free(boxes);
    free(data);
    return 0;
}
