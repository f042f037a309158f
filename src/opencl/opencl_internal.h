// The opencl backend's internals that the tests look at (test/test_opencl.c). Not public API.
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "bpx/bpx.h"

/// What the backend did since the world was made: the paths a test wants to see taken.
typedef struct bpx__opencl_counters {
    uint64_t brute_cycles;    ///< cycles on the brute-force comparator (whole or streamed)
    uint64_t sweep_cycles;    ///< cycles on sort and sweep
    uint64_t sweep_fallbacks; ///< sweeps given up for brute force (pairs beyond the limit)
    uint64_t tree_cycles;     ///< cycles on the linear BVH
    uint64_t tree_fallbacks;  ///< trees given up for brute force (beyond the memory limit)
    uint64_t streamed_blocks; ///< box blocks uploaded while streaming
    uint64_t emit_reruns;     ///< emits repeated after growing the pair buffer
    uint64_t pair_windows;    ///< extra emits to read pairs out in windows
} bpx__opencl_counters;

/// The counters of an opencl world whose device state exists; false otherwise.
bool bpx__opencl_get_counters(const bpx_world *world, bpx__opencl_counters *out);

/// The device's sort and sweep run on the host through the same code (kernels/twin.h): keys,
/// stable sort by min-x key, bpx_sweep_position per position, then (i, j) order. For debugging
/// kernels on the host, and a test of the shared code against the reference.
/// Errors: CAPACITY (*count is the need), OUT_OF_MEMORY.
bpx_status bpx__opencl_twin_pairs(const bpx_box *boxes, uint32_t n, bpx_pair *out, size_t capacity,
                                  size_t *count);

/// The device's tree run on the host through the same code (kernels/lbvh.h): bounds, Morton
/// codes, a stable sort by code, every node built, every leaf refitted, every position walked,
/// the keys sorted. The pair keys' buffer holds `key_capacity` keys, as on the device: with
/// fewer than the pairs, the walks drop the rest and the count still tells the need, and the
/// twin walks again with room (*rewalks counts it; may be NULL). *tests (may be NULL) gets the
/// walks' bounds tests. Errors: CAPACITY (*count is the need), OUT_OF_MEMORY.
bpx_status bpx__opencl_twin_tree_pairs(const bpx_box *boxes, uint32_t n, size_t key_capacity,
                                       bpx_pair *out, size_t capacity, size_t *count,
                                       uint64_t *tests, int *rewalks);
