// The memory floor's passes (floor.h): shared by bpx_memfloor and `bpx bench --profile`.
// SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L // clock_gettime
#include "floor.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct record {
    float lo[3], hi[3];
    uint32_t id, key;
} record;

typedef struct job {
    const record *from;
    record *to;
    const uint32_t *perm;
    uint32_t begin, end;
    int kind;
} job;

enum { AHEAD = 16 };

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static void *run(void *arg)
{
    const job *j = arg;
    for (uint32_t k = j->begin; k < j->end; k++) {
        if (j->kind == BPX_FLOOR_COPY) {
            j->to[k] = j->from[k];
        } else if (j->kind == BPX_FLOOR_GATHER) {
            if (k + AHEAD < j->end) // the best case: every address known ahead
                __builtin_prefetch(&j->from[j->perm[k + AHEAD]], 0, 3);
            j->to[k] = j->from[j->perm[k]];
        } else {
            if (k + AHEAD < j->end)
                __builtin_prefetch(&j->to[j->perm[k + AHEAD]], 1, 3);
            j->to[j->perm[k]] = j->from[k];
        }
    }
    return NULL;
}

int bpx_floor_open(bpx_floor *f, uint32_t n)
{
    _Static_assert(sizeof(record) == BPX_FLOOR_RECORD, "records are 32 bytes");
    size_t count = n ? n : 1;
    *f = (bpx_floor){malloc(sizeof(record) * count), malloc(sizeof(record) * count),
                     malloc(sizeof(uint32_t) * count), n};
    if (!f->from || !f->to || !f->perm) {
        bpx_floor_close(f);
        return -1;
    }
    memset(f->from, 1, sizeof(record) * count);
    memset(f->to, 0, sizeof(record) * count);
    uint64_t s = 0x9e3779b97f4a7c15ull; // a random permutation: ids are spread in space
    for (uint32_t i = 0; i < n; i++)
        f->perm[i] = i;
    for (uint32_t i = n ? n - 1 : 0; i > 0; i--) {
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        uint32_t j = (uint32_t)(s % (i + 1)), t = f->perm[i];
        f->perm[i] = f->perm[j];
        f->perm[j] = t;
    }
    return 0;
}

void bpx_floor_close(bpx_floor *f)
{
    free(f->from);
    free(f->to);
    free(f->perm);
    *f = (bpx_floor){0};
}

double bpx_floor_time(const bpx_floor *f, bpx_floor_kind kind, int threads)
{
    threads = threads < 1 ? 1 : threads > 64 ? 64 : threads;
    double best = 1e30;
    for (int r = 0; r < BPX_FLOOR_ROUNDS; r++) {
        pthread_t tid[64];
        job jobs[64];
        bool started[64] = {false};
        double t0 = now();
        for (int t = 0; t < threads; t++) {
            jobs[t] = (job){f->from,
                            f->to,
                            f->perm,
                            (uint32_t)((uint64_t)f->n * t / threads),
                            (uint32_t)((uint64_t)f->n * (t + 1) / threads),
                            (int)kind};
            if (t > 0)
                started[t] = pthread_create(&tid[t], NULL, run, &jobs[t]) == 0;
        }
        for (int t = 0; t < threads; t++) // this thread's part, and any no thread took
            if (!started[t])
                run(&jobs[t]);
        for (int t = 1; t < threads; t++)
            if (started[t])
                pthread_join(tid[t], NULL);
        double ms = (now() - t0) * 1e3;
        best = ms < best ? ms : best;
    }
    return best;
}
