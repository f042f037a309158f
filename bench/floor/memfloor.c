// bpx_memfloor: what this machine's memory allows a cycle at a million boxes, whatever the
// algorithm. Any spatial broad phase must bring each box from id order (the caller's array) to
// spatial order (or look each one up from there): at least one random access per box per cycle.
// This times that step alone on 32-byte records (a box and two words), with 1 and 2 threads,
// beside a sequential copy of the same bytes, so a backend's figure can be read against it
// (floor.c; `bpx bench --profile` times the same passes beside each backend's stages).
//
//   bpx_memfloor [records] [threads]     (default 1000000 2)
#include <stdio.h>
#include <stdlib.h>

#include "floor.h"

int main(int argc, char **argv)
{
    long n_arg = argc > 1 ? atol(argv[1]) : 1000000;
    int threads = argc > 2 ? atoi(argv[2]) : 2;
    if (n_arg < 1 || n_arg > (1L << 28) || threads < 1 || threads > 64) {
        fprintf(stderr, "bpx_memfloor: usage: bpx_memfloor [records 1..2^28] [threads 1..64]\n");
        return 2;
    }
    uint32_t n = (uint32_t)n_arg;
    bpx_floor f;
    if (bpx_floor_open(&f, n) != 0) {
        fprintf(stderr, "bpx_memfloor: out of memory for %u records\n", n);
        return 1;
    }
    printf("%u records of %d bytes (%.1f MB), best of %d\n\n", n, BPX_FLOOR_RECORD,
           (double)n * BPX_FLOOR_RECORD / 1e6, BPX_FLOOR_ROUNDS);
    printf("| pass | 1 thread ms | %d threads ms | ns per record (%d threads) |\n", threads,
           threads);
    printf("|---|---|---|---|\n");
    const char *names[] = {"sequential copy", "random gather (prefetched)",
                           "random scatter (prefetched)"};
    for (int kind = 0; kind < BPX_FLOOR_KINDS; kind++) {
        double one = bpx_floor_time(&f, (bpx_floor_kind)kind, 1);
        double many = bpx_floor_time(&f, (bpx_floor_kind)kind, threads);
        printf("| %s | %.2f | %.2f | %.1f |\n", names[kind], one, many, many * 1e6 / n);
    }
    bpx_floor_close(&f);
    return 0;
}
