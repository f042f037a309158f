// SPDX-License-Identifier: MIT
// A fake CUDA runtime, for running the cuda backend's host code (buffer sizing, copies, streams,
// error paths) on machines without a GPU: the fake-device tests link it in place of cudart, and
// host loops in place of the kernels (kernels.cu here). "Device memory" is host memory, and
// every call's work is done when it returns. Its files, one concern each:
// - runtime.c (this file): the bookkeeping the others share (the lock, the tables of live blocks
//   and handles, misuse and errors), the device, streams and events, error names;
// - memory.c: allocations (device and pinned), copies and memsets, and the checks on their
//   ranges;
// - stream_order.c: the stream-order check, and the fake kernels' accesses;
// - hooks.c: the hooks that nvcc's host code calls (registration, launches).
//
// Stream order is checked all the same (stream_order.c): an access that races one still in
// flight on a stream it is not ordered with (by the streams' kinds, or by cudaStreamWaitEvent)
// aborts, naming both.
//
// Strict: it is here to catch the host code's bugs, so every misuse (a copy in the wrong
// direction or past the end of a block, a free of what was not allocated, a dead handle, a NULL
// out-pointer, a kernel launch) prints what was wrong and aborts. What a correct program can
// meet on a real GPU (allocation failure, an unrecorded event's timing, a bad device ordinal, a
// bad pitch) is an error return that also sets the last error.
//
// Choices where the real runtime leaves room:
// - cudaMalloc of 0 bytes succeeds with NULL (as cudart does), registers nothing and is not
//   counted by bpx_fake_cuda_fail_allocations_after.
// - Blocks are registered with the size asked for, not the size rounded up to the 256-byte
//   alignment: a copy into the padding is an overrun. Fresh blocks (device and pinned) are
//   filled with 0xa5, so code that assumes zeroed memory fails deterministically.
// - The device has 8 GiB (totalGlobalMem): a cudaMalloc past that in live device blocks fails.
// - The last error is per thread, as in cudart.
// - A host-side range that overlaps a pinned block must lie inside it (staging overruns), and
//   the two ranges of a copy must not overlap (cudaMemcpy's rule).
// - cudaStreamLegacy and cudaStreamPerThread are accepted wherever NULL is.

// Exported whatever visibility the build sets: the library calls these from its own objects.
#pragma GCC visibility push(default)

#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif

#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "runtime.h"
#include "stream_order.h"

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static fake_table streams, events;
static _Thread_local cudaError_t last_error;

void fake_lock(void)
{
    pthread_mutex_lock(&lock);
}

void fake_unlock(void)
{
    pthread_mutex_unlock(&lock);
}

void fake_die(const char *call, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fprintf(stderr, "fake cuda: %s: ", call);
    vfprintf(stderr, format, args);
    fputc('\n', stderr);
    va_end(args);
    fflush(stderr);
    abort();
}

cudaError_t fake_fail(cudaError_t e)
{
    last_error = e;
    return e;
}

void *fake_pointer(uintptr_t p)
{
    return (void *)p;
}

void fake_table_add(fake_table *t, uintptr_t base, size_t size)
{
    if (t->count == t->capacity) {
        size_t capacity = t->capacity ? 2 * t->capacity : 64;
        fake_block *at = realloc(t->at, capacity * sizeof *at);
        if (!at)
            fake_die("table", "out of host memory for the fake's own bookkeeping");
        t->at = at;
        t->capacity = capacity;
    }
    t->at[t->count++] = (fake_block){base, size};
}

long fake_table_find(const fake_table *t, uintptr_t base)
{
    for (size_t k = 0; k < t->count; k++)
        if (t->at[k].base == base)
            return (long)k;
    return -1;
}

void fake_table_drop(fake_table *t, long k)
{
    t->at[k] = t->at[--t->count];
}

const fake_block *fake_table_holding(const fake_table *t, uintptr_t p)
{
    for (size_t k = 0; k < t->count; k++)
        if (p - t->at[k].base < t->at[k].size)
            return &t->at[k];
    return NULL;
}

bool fake_special_stream(cudaStream_t s)
{
    return !s || s == cudaStreamLegacy || s == cudaStreamPerThread;
}

void fake_need_stream(const char *call, cudaStream_t s)
{
    if (!fake_special_stream(s) && fake_table_find(&streams, (uintptr_t)s) < 0)
        fake_die(call, "stream %p is not a live stream (never created, or destroyed)", (void *)s);
}

static struct CUevent_st *need_event(const char *call, cudaEvent_t e)
{
    if (fake_table_find(&events, (uintptr_t)e) < 0)
        fake_die(call, "event %p is not a live event (never created, or destroyed)", (void *)e);
    return e;
}

void fake_need_out(const char *call, const void *out)
{
    if (!out)
        fake_die(call, "NULL out-pointer");
}

// ---- the device ----

cudaError_t cudaSetDevice(int device)
{
    return device == 0 ? cudaSuccess : fake_fail(cudaErrorInvalidDevice);
}

cudaError_t cudaGetDevice(int *device)
{
    fake_need_out("cudaGetDevice", device);
    *device = 0;
    return cudaSuccess;
}

cudaError_t cudaGetDeviceCount(int *count)
{
    fake_need_out("cudaGetDeviceCount", count);
    *count = 1;
    return cudaSuccess;
}

cudaError_t cudaGetDeviceProperties(struct cudaDeviceProp *prop, int device)
{
    fake_need_out("cudaGetDeviceProperties", prop);
    if (device != 0)
        return fake_fail(cudaErrorInvalidDevice);
    memset(prop, 0, sizeof *prop);
    snprintf(prop->name, sizeof prop->name, "%s", "bpx fake device (host memory)");
    prop->major = 9;
    prop->minor = 0;
    prop->totalGlobalMem = fake_device_memory;
    prop->multiProcessorCount = 1;
    prop->warpSize = 32;
    return cudaSuccess;
}

cudaError_t cudaDriverGetVersion(int *driverVersion)
{
    fake_need_out("cudaDriverGetVersion", driverVersion);
    *driverVersion = CUDART_VERSION;
    return cudaSuccess;
}

cudaError_t cudaRuntimeGetVersion(int *runtimeVersion)
{
    fake_need_out("cudaRuntimeGetVersion", runtimeVersion);
    *runtimeVersion = CUDART_VERSION;
    return cudaSuccess;
}

cudaError_t cudaDeviceSynchronize(void)
{
    fake_lock();
    fake_completed_all();
    fake_unlock();
    return cudaSuccess;
}

// ---- streams and events ----

cudaError_t cudaStreamCreateWithFlags(cudaStream_t *pStream, unsigned int flags)
{
    const char *call = "cudaStreamCreateWithFlags";
    fake_need_out(call, pStream);
    if (flags & ~(unsigned)cudaStreamNonBlocking)
        fake_die(call, "unknown flags %#x", flags);
    struct CUstream_st *s = malloc(sizeof *s);
    if (!s)
        return fake_fail(cudaErrorMemoryAllocation);
    s->flags = flags;
    fake_lock();
    fake_table_add(&streams, (uintptr_t)s, sizeof *s);
    fake_unlock();
    *pStream = s;
    return cudaSuccess;
}

cudaError_t cudaStreamCreate(cudaStream_t *pStream)
{
    fake_need_out("cudaStreamCreate", pStream);
    return cudaStreamCreateWithFlags(pStream, cudaStreamDefault);
}

cudaError_t cudaStreamDestroy(cudaStream_t stream)
{
    const char *call = "cudaStreamDestroy";
    if (fake_special_stream(stream))
        fake_die(call, "stream %p is a default stream, not one to destroy", (void *)stream);
    fake_lock();
    long k = fake_table_find(&streams, (uintptr_t)stream);
    if (k < 0)
        fake_die(call, "stream %p is not a live stream (never created, or destroyed)",
                 (void *)stream);
    fake_table_drop(&streams, k);
    fake_order_forget(stream); // its work may still be in flight: destroying does not wait
    fake_unlock();
    free(stream);
    return cudaSuccess;
}

cudaError_t cudaStreamSynchronize(cudaStream_t stream)
{
    fake_lock();
    fake_need_stream("cudaStreamSynchronize", stream);
    fake_completed(fake_canonical(stream), fake_order_now());
    fake_unlock();
    return cudaSuccess;
}

cudaError_t cudaEventCreateWithFlags(cudaEvent_t *event, unsigned int flags)
{
    const char *call = "cudaEventCreateWithFlags";
    fake_need_out(call, event);
    if (flags & ~(unsigned)(cudaEventBlockingSync | cudaEventDisableTiming | cudaEventInterprocess))
        fake_die(call, "unknown flags %#x", flags);
    if ((flags & cudaEventInterprocess) && !(flags & cudaEventDisableTiming))
        fake_die(call, "cudaEventInterprocess needs cudaEventDisableTiming");
    struct CUevent_st *e = malloc(sizeof *e);
    if (!e)
        return fake_fail(cudaErrorMemoryAllocation);
    *e = (struct CUevent_st){
        .flags = flags, .recorded = false, .at_ms = 0.0, .stream = NULL, .seq = 0};
    fake_lock();
    fake_table_add(&events, (uintptr_t)e, sizeof *e);
    fake_unlock();
    *event = e;
    return cudaSuccess;
}

cudaError_t cudaEventCreate(cudaEvent_t *event)
{
    fake_need_out("cudaEventCreate", event);
    return cudaEventCreateWithFlags(event, cudaEventDefault);
}

cudaError_t cudaEventDestroy(cudaEvent_t event)
{
    fake_lock();
    need_event("cudaEventDestroy", event);
    fake_table_drop(&events, fake_table_find(&events, (uintptr_t)event));
    fake_unlock();
    free(event);
    return cudaSuccess;
}

cudaError_t cudaEventRecord(cudaEvent_t event, cudaStream_t stream)
{
    const char *call = "cudaEventRecord";
    fake_lock();
    fake_need_stream(call, stream);
    struct CUevent_st *e = need_event(call, event);
    e->stream = fake_canonical(stream);
    e->seq = fake_order_now();
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    e->recorded = true;
    e->at_ms = 1e3 * (double)now.tv_sec + 1e-6 * (double)now.tv_nsec;
    fake_unlock();
    return cudaSuccess;
}

cudaError_t cudaEventSynchronize(cudaEvent_t event)
{
    fake_lock();
    const struct CUevent_st *e = need_event("cudaEventSynchronize", event);
    if (e->recorded)
        fake_completed(e->stream, e->seq);
    fake_unlock();
    return cudaSuccess;
}

// Work enqueued on `stream` from now on runs after the work `event` covers (its last record); an
// event never recorded is waited for at once, as cudart does.
cudaError_t cudaStreamWaitEvent(cudaStream_t stream, cudaEvent_t event, unsigned int flags)
{
    const char *call = "cudaStreamWaitEvent";
    fake_lock();
    fake_need_stream(call, stream);
    const struct CUevent_st *e = need_event(call, event);
    if (flags)
        fake_die(call, "unknown flags %#x", flags);
    if (e->recorded)
        fake_wait(fake_canonical(stream), e->stream, e->seq);
    fake_unlock();
    return cudaSuccess;
}

// The host time between the two records: the fake device's work is done between them, at once.
// An event never recorded, or one without timing, is the real runtime's
// cudaErrorInvalidResourceHandle.
cudaError_t cudaEventElapsedTime(float *ms, cudaEvent_t start, cudaEvent_t end)
{
    const char *call = "cudaEventElapsedTime";
    fake_need_out(call, ms);
    fake_lock();
    const struct CUevent_st *a = need_event(call, start), *b = need_event(call, end);
    bool timed =
        a->recorded && b->recorded && !((a->flags | b->flags) & (unsigned)cudaEventDisableTiming);
    double between = b->at_ms - a->at_ms;
    fake_unlock();
    if (!timed)
        return fake_fail(cudaErrorInvalidResourceHandle);
    *ms = (float)between;
    return cudaSuccess;
}

// ---- errors ----

cudaError_t cudaGetLastError(void)
{
    cudaError_t e = last_error;
    last_error = cudaSuccess;
    return e;
}

cudaError_t cudaPeekAtLastError(void)
{
    return last_error;
}

#define FAKE_CUDA_ERRORS(X)                                                                        \
    X(cudaSuccess, "no error")                                                                     \
    X(cudaErrorInvalidValue, "invalid argument")                                                   \
    X(cudaErrorMemoryAllocation, "out of memory")                                                  \
    X(cudaErrorInitializationError, "initialization error")                                        \
    X(cudaErrorCudartUnloading, "driver shutting down")                                            \
    X(cudaErrorInvalidConfiguration, "invalid configuration argument")                             \
    X(cudaErrorInvalidPitchValue, "invalid pitch argument")                                        \
    X(cudaErrorInvalidSymbol, "invalid device symbol")                                             \
    X(cudaErrorInvalidHostPointer, "invalid host pointer")                                         \
    X(cudaErrorInvalidDevicePointer, "invalid device pointer")                                     \
    X(cudaErrorInvalidMemcpyDirection, "invalid copy direction for memcpy")                        \
    X(cudaErrorInsufficientDriver, "CUDA driver version is insufficient for CUDA runtime version") \
    X(cudaErrorNoDevice, "no CUDA-capable device is detected")                                     \
    X(cudaErrorInvalidDevice, "invalid device ordinal")                                            \
    X(cudaErrorNoKernelImageForDevice, "no kernel image is available for execution on the device") \
    X(cudaErrorInvalidDeviceFunction, "invalid device function")                                   \
    X(cudaErrorInvalidResourceHandle, "invalid resource handle")                                   \
    X(cudaErrorNotReady, "device not ready")                                                       \
    X(cudaErrorIllegalAddress, "an illegal memory access was encountered")                         \
    X(cudaErrorLaunchOutOfResources, "too many resources requested for launch")                    \
    X(cudaErrorLaunchFailure, "unspecified launch failure")                                        \
    X(cudaErrorNotSupported, "operation not supported")                                            \
    X(cudaErrorUnknown, "unknown error")

const char *cudaGetErrorName(cudaError_t error)
{
#define FAKE_CUDA_NAME(e, text)                                                                    \
    case e:                                                                                        \
        return #e;
    switch (error) {
        FAKE_CUDA_ERRORS(FAKE_CUDA_NAME)
    default:
        return "unrecognized error code";
    }
#undef FAKE_CUDA_NAME
}

const char *cudaGetErrorString(cudaError_t error)
{
#define FAKE_CUDA_TEXT(e, text)                                                                    \
    case e:                                                                                        \
        return text;
    switch (error) {
        FAKE_CUDA_ERRORS(FAKE_CUDA_TEXT)
    default:
        return "unrecognized error code";
    }
#undef FAKE_CUDA_TEXT
}

#pragma GCC visibility pop
