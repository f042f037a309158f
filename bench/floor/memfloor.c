// bpx_memfloor: what this machine's memory allows a cycle at a million boxes, whatever the
// algorithm. Any spatial broad phase must bring each box from id order (the caller's array) to
// spatial order (or look each one up from there): at least one random access per box per cycle.
// This times that step alone on 32-byte records (a box and two words), with 1 and 2 threads,
// beside a sequential copy of the same bytes, so a backend's figure can be read against it.
//
//   bpx_memfloor [records] [threads]     (default 1000000 2)
#define _POSIX_C_SOURCE 200809L // clock_gettime
#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
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
    int kind; // 0 copy, 1 gather (to[k] = from[perm[k]]), 2 scatter (to[perm[k]] = from[k])
} job;

enum { AHEAD = 16, ROUNDS = 5 };

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
        if (j->kind == 0) {
            j->to[k] = j->from[k];
        } else if (j->kind == 1) {
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

// Best of ROUNDS, in ms: the whole array split over `threads`.
static double time_kind(int kind, int threads, const record *from, record *to,
                        const uint32_t *perm, uint32_t n)
{
    double best = 1e30;
    for (int r = 0; r < ROUNDS; r++) {
        pthread_t tid[64];
        job jobs[64];
        bool started[64] = {false};
        double t0 = now();
        for (int t = 0; t < threads; t++) {
            jobs[t] = (job){from, to, perm, (uint32_t)((uint64_t)n * t / threads),
                            (uint32_t)((uint64_t)n * (t + 1) / threads), kind};
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

int main(int argc, char **argv)
{
    long n_arg = argc > 1 ? atol(argv[1]) : 1000000;
    int threads = argc > 2 ? atoi(argv[2]) : 2;
    if (n_arg < 1 || n_arg > (1L << 28) || threads < 1 || threads > 64) {
        fprintf(stderr, "bpx_memfloor: usage: bpx_memfloor [records 1..2^28] [threads 1..64]\n");
        return 2;
    }
    uint32_t n = (uint32_t)n_arg;
    record *from = malloc(sizeof(record) * n), *to = malloc(sizeof(record) * n);
    uint32_t *perm = malloc(sizeof(uint32_t) * n);
    if (!from || !to || !perm) {
        fprintf(stderr, "bpx_memfloor: out of memory for %u records\n", n);
        return 1;
    }
    memset(from, 1, sizeof(record) * n);
    memset(to, 0, sizeof(record) * n);
    uint64_t s = 0x9e3779b97f4a7c15ull; // a random permutation: ids are spread in space
    for (uint32_t i = 0; i < n; i++)
        perm[i] = i;
    for (uint32_t i = n - 1; i > 0; i--) {
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        uint32_t j = (uint32_t)(s % (i + 1)), t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    printf("%u records of %zu bytes (%.1f MB), best of %d\n\n", n, sizeof(record),
           (double)n * sizeof(record) / 1e6, ROUNDS);
    printf("| pass | 1 thread ms | %d threads ms | ns per record (%d threads) |\n", threads,
           threads);
    printf("|---|---|---|---|\n");
    const char *names[] = {"sequential copy", "random gather (prefetched)",
                           "random scatter (prefetched)"};
    for (int kind = 0; kind < 3; kind++) {
        double one = time_kind(kind, 1, from, to, perm, n);
        double many = time_kind(kind, threads, from, to, perm, n);
        printf("| %s | %.2f | %.2f | %.1f |\n", names[kind], one, many, many * 1e6 / n);
    }
    free(from);
    free(to);
    free(perm);
    return 0;
}
