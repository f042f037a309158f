// The fake CUDA runtime's own header, private to its files: runtime.c (the device, streams,
// events, errors and the bookkeeping below), memory.c (allocations, copies, memsets),
// stream_order.c (accesses in flight) and hooks.c (nvcc's registration and launch hooks).
// SPDX-License-Identifier: MIT
#pragma once

#include <cuda_runtime_api.h>

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

// The handles' objects: opaque types of the header, completed here.
struct CUstream_st {
    unsigned flags;
};
struct CUevent_st {
    unsigned flags;
    bool recorded;
    double at_ms; // the host's clock when recorded: the fake device works at once, on the host
    struct CUstream_st *stream; // where it was last recorded (NULL: the legacy stream)
    unsigned long seq;          // the accesses before it there have its sequence number below
};

/// The device's memory (totalGlobalMem): a cudaMalloc past it in live device blocks fails.
static const size_t fake_device_memory = (size_t)8 << 30;

typedef struct {
    uintptr_t base;
    size_t size;
} fake_block;

/// Live blocks or handles. Few (a world holds about a dozen), so a linear search.
typedef struct {
    fake_block *at;
    size_t count, capacity;
} fake_table;

// runtime.c: one lock over all the fake's state (the tables, the accesses in flight).
void fake_lock(void);
void fake_unlock(void);
/// Prints "fake cuda: CALL: ..." and aborts: a misuse.
__attribute__((format(printf, 2, 3), noreturn)) void fake_die(const char *call, const char *format,
                                                              ...);
/// An error return that a correct program can meet: sets the thread's last error.
cudaError_t fake_fail(cudaError_t e);
void *fake_pointer(uintptr_t p);

void fake_table_add(fake_table *t, uintptr_t base, size_t size);
/// The entry that starts at base, or -1.
long fake_table_find(const fake_table *t, uintptr_t base);
void fake_table_drop(fake_table *t, long k);
/// The block that holds byte p, or NULL.
const fake_block *fake_table_holding(const fake_table *t, uintptr_t p);

/// NULL, cudaStreamLegacy or cudaStreamPerThread: accepted wherever NULL is.
bool fake_special_stream(cudaStream_t s);
/// Aborts unless s is a live stream or a special one.
void fake_need_stream(const char *call, cudaStream_t s);
void fake_need_out(const char *call, const void *out);

// memory.c: the live device and pinned host blocks.
extern fake_table fake_device_blocks, fake_pinned_blocks;
/// Aborts unless [p, p + bytes) lies inside one live device block.
void fake_need_device(const char *call, const char *what, uintptr_t p, size_t bytes);
