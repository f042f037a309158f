// The memory floor of a cycle on this machine (bpx_memfloor, and `bpx bench --profile` beside
// each backend's stages): one random gather or scatter of every record, beside a sequential copy
// of the same bytes, on 32-byte records (a box and two words), every address known ahead.
// SPDX-License-Identifier: MIT
#pragma once

#include <stdint.h>

enum { BPX_FLOOR_RECORD = 32, BPX_FLOOR_ROUNDS = 5 };

typedef enum bpx_floor_kind {
    BPX_FLOOR_COPY = 0, // to[k] = from[k]
    BPX_FLOOR_GATHER,   // to[k] = from[perm[k]], prefetched
    BPX_FLOOR_SCATTER,  // to[perm[k]] = from[k], prefetched
    BPX_FLOOR_KINDS
} bpx_floor_kind;

// n records, their copy and a random permutation: bpx_floor_open's.
typedef struct bpx_floor {
    void *from, *to;
    uint32_t *perm;
    uint32_t n;
} bpx_floor;

// Makes the arrays (touched, so no page fault is timed). 0, or -1 out of memory.
int bpx_floor_open(bpx_floor *f, uint32_t n);
void bpx_floor_close(bpx_floor *f);
// Best of BPX_FLOOR_ROUNDS, in ms: the whole array split over `threads` (1..64).
double bpx_floor_time(const bpx_floor *f, bpx_floor_kind kind, int threads);
