// SPDX-License-Identifier: MIT
// The fake CUDA runtime's stream-order check. Each device access that a real GPU would still
// have in flight after its call returns (an asynchronous copy or memset, a kernel's reads and
// writes) is kept, with its stream, until the host synchronises with it (the stream, an event
// recorded after it, the device, cudaFree's implicit synchronisation, a copy that returns only
// when done). An access on another stream that is not ordered after it (the legacy default
// stream and a blocking stream are; a non-blocking stream is ordered with nothing else) and that
// writes what it wrote, or writes what it read, is a race on a GPU, and aborts here.

// Exported whatever visibility the build sets: the library calls these from its own objects.
#pragma GCC visibility push(default)

#include <stdlib.h>
#include <string.h>

#include "fake_cuda.h"
#include "stream_order.h"

// A device access still in flight on a real GPU: until the host synchronises with its stream.
typedef struct {
    uintptr_t base;
    size_t bytes;
    struct CUstream_st *stream; // NULL: the legacy default stream
    bool write;
    unsigned long seq;
    const char *what;
} access;

static struct {
    access *at;
    size_t count, capacity;
} in_flight;
static unsigned long next_seq = 1;

struct CUstream_st *fake_canonical(cudaStream_t s)
{
    return fake_special_stream(s) ? NULL : s;
}

static bool blocking(const struct CUstream_st *s)
{
    return s && !(s->flags & cudaStreamNonBlocking);
}

// Work on b after work on a runs after it: one stream, or the legacy stream and a blocking one.
static bool ordered(const struct CUstream_st *a, const struct CUstream_st *b)
{
    return a == b || (!a && blocking(b)) || (!b && blocking(a));
}

static const char *stream_name(const struct CUstream_st *s)
{
    return !s ? "the legacy stream" : blocking(s) ? "a blocking stream" : "a non-blocking stream";
}

void fake_touch(const char *call, const char *what, struct CUstream_st *stream, uintptr_t base,
                size_t bytes, bool write, bool done_on_return)
{
    if (!bytes)
        return;
    for (size_t k = 0; k < in_flight.count; k++) {
        const access *a = &in_flight.at[k];
        bool meet = a->base >= base ? a->base - base < bytes : base - a->base < a->bytes;
        if (meet && (write || a->write) && !ordered(a->stream, stream))
            fake_die(call,
                     "%s [%p, +%zu) on %s (%p) races %s [%p, +%zu) on %s (%p): no "
                     "synchronisation between the two streams",
                     what, fake_pointer(base), bytes, stream_name(stream), (void *)stream, a->what,
                     fake_pointer(a->base), a->bytes, stream_name(a->stream), (void *)a->stream);
    }
    if (done_on_return)
        return;
    if (in_flight.count == in_flight.capacity) {
        size_t capacity = in_flight.capacity ? 2 * in_flight.capacity : 256;
        access *at = realloc(in_flight.at, capacity * sizeof *at);
        if (!at)
            fake_die("stream order", "out of host memory for the fake's own bookkeeping");
        in_flight.at = at;
        in_flight.capacity = capacity;
    }
    in_flight.at[in_flight.count++] =
        (access){base, bytes, stream, write, next_seq++, what ? what : call};
}

unsigned long fake_order_now(void)
{
    return next_seq;
}

// The host has waited for `stream`'s work enqueued before sequence number `before` (and so for
// what that work waited for: the legacy stream's for a blocking stream, and the reverse).
void fake_completed(const struct CUstream_st *stream, unsigned long before)
{
    for (size_t k = 0; k < in_flight.count;) {
        const access *a = &in_flight.at[k];
        if (a->seq < before && ordered(a->stream, stream))
            in_flight.at[k] = in_flight.at[--in_flight.count];
        else
            k++;
    }
}

void fake_completed_all(void)
{
    in_flight.count = 0;
}

// A copy's place in stream order (CUDA's "API synchronization behavior"): into pageable host
// memory it returns only when done, so the host has waited for its stream; from pageable host
// memory the legacy stream's cudaMemcpy first synchronises it, and the copy itself may still be
// landing when the call returns; every other copy is in flight until the host synchronises.
void fake_order_copy(const char *call, const void *dst, const void *src, size_t count,
                     struct CUstream_st *stream)
{
    bool from_device = fake_table_holding(&fake_device_blocks, (uintptr_t)src) != NULL;
    bool to_device = fake_table_holding(&fake_device_blocks, (uintptr_t)dst) != NULL;
    bool to_pageable = !to_device && !fake_table_holding(&fake_pinned_blocks, (uintptr_t)dst);
    bool from_pageable = !from_device && !fake_table_holding(&fake_pinned_blocks, (uintptr_t)src);
    if (from_device)
        fake_touch(call, "the copy's source", stream, (uintptr_t)src, count, false, to_pageable);
    if (to_device)
        fake_touch(call, "the copy's destination", stream, (uintptr_t)dst, count, true, false);
    if (to_pageable)
        fake_completed(stream, next_seq);
    else if (from_pageable && !stream && strcmp(call, "cudaMemcpy") == 0)
        fake_completed(NULL, next_seq - 1); // before the copy, which is in flight
}

// Destroying a stream does not wait for its work: that work keeps its place in stream order
// under a handle no later stream can have, as the freed address could.
void fake_order_forget(cudaStream_t stream)
{
    static struct CUstream_st destroyed = {cudaStreamNonBlocking};
    for (size_t a = 0; a < in_flight.count; a++)
        if (in_flight.at[a].stream == stream)
            in_flight.at[a].stream = &destroyed;
}

// ---- the fake kernels' accesses (fake_cuda.h) ----

void bpx_fake_cuda_access(cudaStream_t stream, const void *p, size_t bytes, int write,
                          const char *what)
{
    if (!bytes)
        return;
    const char *call = "a fake kernel";
    fake_lock();
    fake_need_stream(call, stream);
    fake_need_device(call, what ? what : "range", (uintptr_t)p, bytes);
    fake_touch(call, what, fake_canonical(stream), (uintptr_t)p, bytes, write != 0, false);
    fake_unlock();
}

#pragma GCC visibility pop
