// SPDX-License-Identifier: MIT
// The fake CUDA runtime's stream-order check. Each device access that a real GPU would still
// have in flight after its call returns (an asynchronous copy or memset, a kernel's reads and
// writes) is kept, with its stream, until the host synchronises with it (the stream, an event
// recorded after it, the device, cudaFree's implicit synchronisation, a copy that returns only
// when done). An access on another stream that is not ordered after it (the legacy default
// stream and a blocking stream are; a non-blocking stream is ordered with nothing else) and that
// writes what it wrote, or writes what it read, is a race on a GPU, and aborts here.
// cudaStreamWaitEvent orders a stream after what its event covers: each access the event follows
// keeps the waiting stream (and when it waited), so that later work there, and the host's waits
// on it, see the access as done; through chains of waits too.

// Exported whatever visibility the build sets: the library calls these from its own objects.
#pragma GCC visibility push(default)

#include <stdlib.h>
#include <string.h>

#include "fake_cuda.h"
#include "stream_order.h"

// A stream that waited (cudaStreamWaitEvent) for an access: its work from `seq` on follows it.
typedef struct {
    struct CUstream_st *stream;
    unsigned long seq;
} waiter;

enum { max_waiters = 8 };

// A device access still in flight on a real GPU: until the host synchronises with its stream
// (or with a stream that waited for it).
typedef struct {
    uintptr_t base;
    size_t bytes;
    struct CUstream_st *stream; // NULL: the legacy default stream
    bool write;
    unsigned long seq;
    const char *what;
    waiter waited[max_waiters];
    int waiters;
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

// Work on `s` from sequence number `before` on runs after access a: a's own stream (or one ordered
// with it) from after a, or a stream that waited for a.
static bool follows(const access *a, const struct CUstream_st *s, unsigned long before)
{
    if (a->seq < before && ordered(a->stream, s))
        return true;
    for (int w = 0; w < a->waiters; w++)
        if (a->waited[w].seq < before && ordered(a->waited[w].stream, s))
            return true;
    return false;
}

// A destroyed stream's work, under a handle no later stream can have.
static struct CUstream_st destroyed = {cudaStreamNonBlocking};

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
        if (meet && (write || a->write) && !follows(a, stream, next_seq))
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
        (access){base, bytes, stream, write, next_seq++, what ? what : call, {{0}}, 0};
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
        if (follows(a, stream, before))
            in_flight.at[k] = in_flight.at[--in_flight.count];
        else
            k++;
    }
}

// `stream` waits for the work before sequence number `before` on `on` (an event recorded there):
// every access that work follows is followed by `stream`'s work from now on.
void fake_wait(struct CUstream_st *stream, const struct CUstream_st *on, unsigned long before)
{
    unsigned long now = next_seq++; // an event recorded on `stream` from now on covers the wait
    for (size_t k = 0; k < in_flight.count; k++) {
        access *a = &in_flight.at[k];
        if (!follows(a, on, before) || follows(a, stream, now + 1))
            continue; // not covered by the event, or `stream` follows it already
        int w = 0;
        while (w < a->waiters && a->waited[w].stream != stream)
            w++;
        if (w == max_waiters)
            fake_die("cudaStreamWaitEvent",
                     "more than %d streams wait for one access in flight "
                     "(the fake's own limit)",
                     max_waiters);
        if (w == a->waiters)
            a->waiters++;
        a->waited[w] = (waiter){stream, now};
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
    for (size_t a = 0; a < in_flight.count; a++) {
        access *at = &in_flight.at[a];
        if (at->stream == stream)
            at->stream = &destroyed;
        for (int w = 0; w < at->waiters; w++)
            if (at->waited[w].stream == stream)
                at->waited[w].stream = &destroyed;
    }
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
