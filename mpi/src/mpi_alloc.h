// libbpx_mpi's memory: the core's (src/core/alloc.h, exported from libbpx for the project's own
// libraries), so bpx_set_allocator's hooks and bpx_allocated_bytes see it: 64-byte aligned, freed
// with the size it was allocated with. Every allocation of libbpx_mpi goes through these.
#pragma once

#include <stddef.h>

/// Memory of at least size bytes, 64-byte aligned, or NULL (also for size 0).
void *bpx_mpi__alloc(size_t size);

/// Frees memory from bpx_mpi__alloc; size is the size it was allocated with. NULL is allowed.
void bpx_mpi__free(void *memory, size_t size);

/// Room for need elements in each of count arrays that share the capacity *cap (array k holds
/// elements of sizes[k] bytes); what they held is not kept. All of them grow or none: 0, or -1
/// with every array and *cap as they were.
int bpx_mpi__reserve(void **const arrays[], const size_t sizes[], int count, size_t *cap,
                     size_t need);

/// bpx_mpi__reserve for one array of elements of size bytes.
int bpx_mpi__grow(void **memory, size_t *cap, size_t need, size_t size);
