// bpx_nbench: the cost of periodicity and of float64 in the general image search of
// bpx_find_neighbors (src/neighbors/neighbors.c), one thread, on uniform boxes (about one
// overlap per box, scene_uniform_density), against a plain bpx_find_pairs on the same boxes.
// SPDX-License-Identifier: MIT
//
//   bpx_nbench [--sizes 100000,1000000] [--rounds 5] [--only a|b|c|d] [--hash]
//
// Columns, each timed in CPU time of the calling thread (CLOCK_THREAD_CPUTIME_ID), the columns
// alternating within each round, medians over the rounds:
//   a  bpx_find_pairs, float32 boxes (the plain baseline; its output buffer allocated once)
//   b  bpx_find_neighbors, the same boxes, BPX_BOXES_F32, open, cutoff 0
//   c  the same, periodic on all three axes: a cell the size of the scene's domain (the range
//      of the min corners; about 3% of the boxes at 100k reach past an upper face)
//   d  bpx_find_pairs_f64 on the boxes as float64, each face moved out by 2^-30 of its
//      magnitude plus 1e-9 (values no float32 holds)
// The ratios c/b, c/a and d/a are printed as ratios of the medians and, in brackets, as the
// medians of the rounds' own ratios.
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <bpx/bpx.h>
#include <bpx/neighbors.h>

#include "scenes.h"

enum { MAX_ROUNDS = 101, COLUMNS = 4 };

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(const double *v, int count)
{
    double s[MAX_ROUNDS];
    memcpy(s, v, sizeof *v * (size_t)count);
    qsort(s, (size_t)count, sizeof *s, by_value);
    return count % 2 ? s[count / 2] : 0.5 * (s[count / 2 - 1] + s[count / 2]);
}

static void fail(const char *what, bpx_status s, const bpx_error *err)
{
    fprintf(stderr, "bpx_nbench: %s: %s (%s)\n", what, bpx_status_string(s),
            err ? err->message : "");
    exit(1);
}

typedef struct scene {
    uint32_t n;
    bpx_box *boxes;
    bpx_box64 *boxes64;
    double period[3];
    bpx_pair *out; // for a and d
    size_t capacity;
} scene;

// With --hash: an FNV-1a hash of each column's output bytes, taken after the timed rounds, to
// compare builds (the same bytes before and after a change).
static bool hashing;
static uint64_t hashes[COLUMNS];

static uint64_t fnv1a(const void *data, size_t size)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t k = 0; k < size; k++)
        h = (h ^ ((const unsigned char *)data)[k]) * 0x100000001b3ull;
    return h;
}

// One column once; returns the pairs found.
static size_t run_column(scene *sc, int column)
{
    bpx_error err;
    bpx_status s;
    size_t count = 0;
    if (column == 0 || column == 3) {
        s = column == 0 ? bpx_find_pairs(sc->boxes, sc->n, BPX_BACKEND_AUTO, sc->out, sc->capacity,
                                         &count, &err)
                        : bpx_find_pairs_f64(sc->boxes64, sc->n, BPX_BACKEND_AUTO, sc->out,
                                             sc->capacity, &count, &err);
        if (s != BPX_OK)
            fail(column == 0 ? "bpx_find_pairs" : "bpx_find_pairs_f64", s, &err);
        if (hashing)
            hashes[column] = fnv1a(sc->out, count * sizeof *sc->out);
        return count;
    }
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = BPX_BOXES_F32;
    def.worker_count = 1;
    if (column == 2)
        memcpy(def.period, sc->period, sizeof def.period);
    bpx_neighbor_list list;
    s = bpx_find_neighbors(&def, sc->boxes, sc->n, &list, &err);
    if (s != BPX_OK)
        fail("bpx_find_neighbors", s, &err);
    count = list.count;
    if (hashing)
        hashes[column] = fnv1a(list.pairs, count * sizeof *list.pairs);
    bpx_neighbor_list_free(&list);
    return count;
}

int main(int argc, char **argv)
{
    uint32_t sizes[16] = {100000, 1000000};
    int size_count = 2, rounds = 5, only = -1;
    bool want_hash = false;
    for (int a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--sizes") && a + 1 < argc) {
            size_count = 0;
            for (char *p = argv[++a]; *p && size_count < 16;) {
                sizes[size_count++] = (uint32_t)strtoul(p, &p, 10);
                if (*p == ',')
                    p++;
            }
        } else if (!strcmp(argv[a], "--only") && a + 1 < argc && argv[a + 1][0] >= 'a' &&
                   argv[a + 1][0] <= 'd') {
            only = argv[++a][0] - 'a'; // one column alone, for a profiler
        } else if (!strcmp(argv[a], "--hash")) {
            want_hash = true; // taken after the timed rounds
        } else if (!strcmp(argv[a], "--rounds") && a + 1 < argc) {
            rounds = atoi(argv[++a]);
        } else {
            fprintf(
                stderr,
                "usage: bpx_nbench [--sizes N,N,...] [--rounds 1..%d] [--only a|b|c|d] [--hash]\n",
                MAX_ROUNDS);
            return 2;
        }
    }
    if (rounds < 1 || rounds > MAX_ROUNDS) {
        fprintf(stderr, "bpx_nbench: --rounds 1..%d\n", MAX_ROUNDS);
        return 2;
    }
    printf("bpx_nbench: uniform boxes (~1 overlap per box), one thread, CPU time, medians of "
           "%d alternating rounds\n\n",
           rounds);
    printf("| boxes | pairs a | pairs c | pairs d | a find_pairs f32 (ms) | b neighbors open "
           "(ms) | c neighbors periodic (ms) | d find_pairs_f64 (ms) | c/b | c/a | d/a |\n"
           "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int z = 0; z < size_count; z++) {
        scene sc = {.n = sizes[z]};
        uint32_t n = sc.n;
        if (n == 0)
            continue;
        sc.boxes = malloc(sizeof *sc.boxes * n);
        sc.boxes64 = malloc(sizeof *sc.boxes64 * n);
        if (!sc.boxes || !sc.boxes64)
            fail("malloc", BPX_ERR_OUT_OF_MEMORY, NULL);
        scene_uniform_density(n, 1.0f, 42, sc.boxes);
        float lo[3], hi[3]; // the range of the min corners
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = sc.boxes[0].min[a];
        for (uint32_t k = 0; k < n; k++)
            for (int a = 0; a < 3; a++) {
                float x = sc.boxes[k].min[a], y = sc.boxes[k].max[a];
                lo[a] = x < lo[a] ? x : lo[a];
                hi[a] = x > hi[a] ? x : hi[a];
                sc.boxes64[k].min[a] = (double)x - (0x1p-30 * (x < 0 ? -x : x) + 1e-9);
                sc.boxes64[k].max[a] = (double)y + (0x1p-30 * (y < 0 ? -y : y) + 1e-9);
            }
        // The cell: the scene's domain (where the min corners lie), so that the density stays
        // uniform across its faces; the boxes that reach past an upper face get images.
        for (int a = 0; a < 3; a++)
            sc.period[a] = (double)hi[a] - (double)lo[a];
        size_t pairs[COLUMNS] = {0};
        bpx_error err; // the output for a and d: sized by a first call, touched before timing
        bpx_find_pairs(sc.boxes, n, BPX_BACKEND_AUTO, NULL, 0, &sc.capacity, &err);
        sc.capacity *= 2;
        sc.out = malloc(sizeof *sc.out * sc.capacity);
        if (!sc.out)
            fail("malloc", BPX_ERR_OUT_OF_MEMORY, NULL);
        memset(sc.out, 0, sizeof *sc.out * sc.capacity);
        double t[COLUMNS][MAX_ROUNDS], cb[MAX_ROUNDS], ca[MAX_ROUNDS], da[MAX_ROUNDS];
        for (int r = 0; r < rounds; r++) {
            for (int k = 0; k < COLUMNS; k++) {
                int column = (k + r) % COLUMNS; // each column in every position in turn
                if (only >= 0 && column != only) {
                    t[column][r] = 1;
                    continue;
                }
                double t0 = cpu_s();
                pairs[column] = run_column(&sc, column);
                t[column][r] = cpu_s() - t0;
            }
            cb[r] = t[2][r] / t[1][r];
            ca[r] = t[2][r] / t[0][r];
            da[r] = t[3][r] / t[0][r];
        }
        if (only < 0 && pairs[1] != pairs[0])
            fprintf(stderr, "bpx_nbench: neighbors open found %zu pairs, find_pairs %zu\n",
                    pairs[1], pairs[0]);
        double m[COLUMNS];
        for (int k = 0; k < COLUMNS; k++)
            m[k] = median(t[k], rounds);
        printf("| %u | %zu | %zu | %zu | %.1f | %.1f | %.1f | %.1f | %.2f (%.2f) | %.2f (%.2f) | "
               "%.2f (%.2f) |\n",
               n, pairs[0], pairs[2], pairs[3], 1e3 * m[0], 1e3 * m[1], 1e3 * m[2], 1e3 * m[3],
               m[2] / m[1], median(cb, rounds), m[2] / m[0], median(ca, rounds), m[3] / m[0],
               median(da, rounds));
        if (want_hash) {
            hashing = true;
            for (int k = 0; k < COLUMNS; k++)
                run_column(&sc, k);
            hashing = false;
            printf("hashes %u: a %016llx b %016llx c %016llx d %016llx\n", n,
                   (unsigned long long)hashes[0], (unsigned long long)hashes[1],
                   (unsigned long long)hashes[2], (unsigned long long)hashes[3]);
        }
        fflush(stdout);
        free(sc.out);
        free(sc.boxes64);
        free(sc.boxes);
    }
    return 0;
}
