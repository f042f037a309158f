// The fake CUDA runtime's stream-order check (stream_order.c), for its other files; every call
// with the runtime's lock held (runtime.h). SPDX-License-Identifier: MIT
#pragma once

#include "runtime.h"

/// A stream as stream order knows it: the special streams are the legacy stream, NULL.
struct CUstream_st *fake_canonical(cudaStream_t s);

/// An access on `stream` to [base, base + bytes): checked against those in flight on streams not
/// ordered with it (aborts on a race), then kept until the host synchronises with it, unless it
/// is done when its call returns.
void fake_touch(const char *call, const char *what, struct CUstream_st *stream, uintptr_t base,
                size_t bytes, bool write, bool done_on_return);

/// The sequence number the next access will have: an event recorded now comes before it.
unsigned long fake_order_now(void);

/// The host has waited for `stream`'s work enqueued before sequence number `before` (and so for
/// what that work waited for).
void fake_completed(const struct CUstream_st *stream, unsigned long before);

/// `stream` waits (cudaStreamWaitEvent) for the work before sequence number `before` on `on`.
void fake_wait(struct CUstream_st *stream, const struct CUstream_st *on, unsigned long before);

/// The host has waited for the whole device.
void fake_completed_all(void);

/// A copy's accesses and its synchronisation with the host, on `stream` (canonical).
void fake_order_copy(const char *call, const void *dst, const void *src, size_t count,
                     struct CUstream_st *stream);

/// `stream` is destroyed: its work in flight keeps its place in stream order under a handle no
/// later stream can have.
void fake_order_forget(cudaStream_t stream);
