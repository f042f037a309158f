// bpx_wbench: what a periodic world's collide costs against the same boxes in an open world
// (issue 32's target: within 1.2x). Boxes from scene_uniform_density (about one overlap per
// box); the cell is the scene's domain (the range of the min corners), so the density stays
// uniform across its faces. Two worlds, one open and one periodic, on the same backend and
// worker count, each given the boxes once; then rounds of one collide each, alternating which
// goes first, timed in wall-clock ns; medians over the rounds.
//
//   bpx_wbench [--sizes 100000,1000000] [--rounds 7] [--backend auto] [--workers 1]
//              [--frame]   (time set_boxes + collide, as a frame would, instead of collide)
//              [--move S]  (before each round, every box moves by up to S on each axis, as in
//                          a simulation; implies --frame)
//              [--cpu]     (time in the calling thread's CPU time, not wall-clock: with one worker
//                          all the work runs on it, and time lost to other processes on a shared,
//                          loaded machine is left out; memory contention is not)
#define _POSIX_C_SOURCE 199309L // clock_gettime
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <bpx/bpx.h>

#include "scenes.h"

static clockid_t clock_id = CLOCK_MONOTONIC;

static double now_s(void)
{
    struct timespec t;
    clock_gettime(clock_id, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int count)
{
    qsort(v, (size_t)count, sizeof *v, by_value);
    return count % 2 ? v[count / 2] : 0.5 * (v[count / 2 - 1] + v[count / 2]);
}

static void must(bpx_status s, bpx_world *w, const char *what)
{
    if (s != BPX_OK) {
        fprintf(stderr, "%s: %s: %s\n", what, bpx_status_name(s),
                w ? bpx_world_error(w)->message : "");
        exit(1);
    }
}

int main(int argc, char **argv)
{
    uint32_t sizes[16] = {100000, 1000000};
    int size_count = 2, rounds = 7, workers = 1;
    bool frame = false;
    float step = 0;
    bpx_backend backend = BPX_BACKEND_AUTO;
    for (int a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--sizes") && a + 1 < argc) {
            size_count = 0;
            for (char *p = argv[++a]; *p && size_count < 16;) {
                sizes[size_count++] = (uint32_t)strtoul(p, &p, 10);
                if (*p == ',')
                    p++;
            }
        } else if (!strcmp(argv[a], "--rounds") && a + 1 < argc) {
            rounds = atoi(argv[++a]);
        } else if (!strcmp(argv[a], "--workers") && a + 1 < argc) {
            workers = atoi(argv[++a]);
        } else if (!strcmp(argv[a], "--backend") && a + 1 < argc) {
            must(bpx_backend_from_name(argv[++a], &backend), NULL, "--backend");
        } else if (!strcmp(argv[a], "--move") && a + 1 < argc) {
            step = strtof(argv[++a], NULL);
            frame = true;
        } else if (!strcmp(argv[a], "--frame")) {
            frame = true;
        } else if (!strcmp(argv[a], "--cpu")) {
            clock_id = CLOCK_THREAD_CPUTIME_ID;
        } else {
            fprintf(stderr, "usage: %s [--sizes N,N] [--rounds R] [--backend B] [--workers W] "
                            "[--frame] [--move S] [--cpu]\n", argv[0]);
            return 2;
        }
    }
    if (rounds < 1 || rounds > 1000)
        rounds = 7;
    printf("| boxes | pairs open | pairs periodic | images | open (ms) | periodic (ms) | "
           "periodic/open |\n|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int z = 0; z < size_count; z++) {
        uint32_t n = sizes[z];
        bpx_box *boxes = malloc(sizeof *boxes * (n ? n : 1));
        if (!boxes)
            return 1;
        scene_uniform_density(n, 1.0f, 42, boxes);
        bpx_world_def def = bpx_default_world_def();
        def.backend = backend;
        def.worker_count = workers;
        bpx_world *w[2];
        must(bpx_world_create(&def, &w[0]), NULL, "create open");
        float lo[3], hi[3];
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = boxes[0].min[a];
        for (uint32_t k = 0; k < n; k++)
            for (int a = 0; a < 3; a++) {
                float x = boxes[k].min[a];
                lo[a] = x < lo[a] ? x : lo[a];
                hi[a] = x > hi[a] ? x : hi[a];
            }
        for (int a = 0; a < 3; a++)
            def.period[a] = (double)hi[a] - (double)lo[a];
        must(bpx_world_create(&def, &w[1]), NULL, "create periodic");
        double *t[2] = {malloc(sizeof(double) * rounds), malloc(sizeof(double) * rounds)};
        for (int k = 0; k < 2; k++) { // warm-up: states made, buffers grown
            must(bpx_world_set_boxes(w[k], boxes, n), w[k], "set_boxes");
            must(bpx_world_collide(w[k]), w[k], "collide");
        }
        scene_rng rng;
        scene_rng_seed(&rng, 7);
        for (int r = 0; r < rounds; r++)
            for (int q = 0; q < 2; q++) {
                if (q == 0 && step > 0)
                    scene_move(boxes, n, step, &rng);
                int k = (q + r) % 2;
                double t0 = now_s();
                if (frame)
                    must(bpx_world_set_boxes(w[k], boxes, n), w[k], "set_boxes");
                must(bpx_world_collide(w[k]), w[k], "collide");
                t[k][r] = now_s() - t0;
            }
        size_t pairs[2], images = 0;
        bpx_world_pairs(w[0], &pairs[0]);
        bpx_world_pairs(w[1], &pairs[1]);
        bpx_world_image_pairs(w[1], &images);
        double m0 = median(t[0], rounds), m1 = median(t[1], rounds);
        printf("| %u | %zu | %zu | %zu | %.1f | %.1f | %.2f | %s %s |\n", n, pairs[0], pairs[1],
               images, 1e3 * m0, 1e3 * m1, m1 / m0, bpx_backend_name(bpx_world_backend(w[0])),
               bpx_world_stats(w[1]).rebuilt ? "rebuilt" : "kept");
        fflush(stdout);
        free(t[0]);
        free(t[1]);
        bpx_world_destroy(w[0]);
        bpx_world_destroy(w[1]);
        free(boxes);
    }
    return 0;
}
