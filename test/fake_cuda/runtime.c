// SPDX-License-Identifier: MIT
// A fake CUDA runtime, for running the cuda backend's host code (buffer sizing, copies, streams,
// error paths) on machines without a GPU: the fake-device tests link it in place of cudart, and
// host loops in place of the kernels (kernels.cu here). "Device memory" is host memory, and
// every call's work is done when it returns.
//
// Stream order is checked all the same. Each device access that a real GPU would still have in
// flight after the call returns (an asynchronous copy or memset, a kernel's reads and writes) is
// kept, with its stream, until the host synchronises with it (the stream, an event recorded after
// it, the device, cudaFree's implicit synchronisation, a copy that returns only when done). An
// access on another stream that is not ordered after it (the legacy default stream and a blocking
// stream are; a non-blocking stream is ordered with nothing else) and that writes what it wrote,
// or writes what it read, is a race on a GPU, and aborts here.
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

#include <cuda_runtime_api.h>

#include <pthread.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

// The fake's own calls (declared again in fake_cuda.h for the fake kernels).
void bpx_fake_cuda_access(cudaStream_t stream, const void *p, size_t bytes, int write,
                          const char *what);
void bpx_fake_cuda_fail_allocations_after(long k);
long bpx_fake_cuda_live_blocks(void);

// The hooks that nvcc's host code calls (declared by crt/host_runtime.h and
// crt/device_functions.h, which are C++ only).
void **__cudaRegisterFatBinary(void *fatCubin);
void __cudaRegisterFatBinaryEnd(void **fatCubinHandle);
void __cudaUnregisterFatBinary(void **fatCubinHandle);
void __cudaRegisterFunction(void **fatCubinHandle, const char *hostFun, char *deviceFun,
                            const char *deviceName, int thread_limit, uint3 *tid, uint3 *bid,
                            dim3 *bDim, dim3 *gDim, int *wSize);
void __cudaRegisterVar(void **fatCubinHandle, char *hostVar, char *deviceAddress,
                       const char *deviceName, int ext, size_t size, int constant, int global);
char __cudaInitModule(void **fatCubinHandle);
unsigned __cudaPushCallConfiguration(dim3 gridDim, dim3 blockDim, size_t sharedMem,
                                     struct CUstream_st *stream);
cudaError_t __cudaPopCallConfiguration(dim3 *gridDim, dim3 *blockDim, size_t *sharedMem,
                                       void *stream);
cudaError_t __cudaGetKernel(cudaKernel_t *kernel, const void *func);
cudaError_t __cudaLaunchKernel(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                               size_t sharedMem, cudaStream_t stream);
cudaError_t __cudaLaunchKernel_ptsz(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                                    size_t sharedMem, cudaStream_t stream);

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
struct CUkern_st {
    char unused;
};

enum {
    block_alignment = 256,
    fill_byte = 0xa5,
};
static const size_t device_memory = (size_t)8 << 30;

typedef struct {
    uintptr_t base;
    size_t size;
} block;

// Live blocks or handles. Few (a world holds about a dozen), so a linear search.
typedef struct {
    block *at;
    size_t count, capacity;
} table;

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static table device_blocks, pinned_blocks, streams, events;
static size_t device_bytes;        // live device blocks' sizes, against device_memory
static long allocations_left = -1; // before injected failure; < 0: none
static _Thread_local cudaError_t last_error;
static _Thread_local struct {
    bool pushed;
    dim3 grid, block;
    size_t shared;
    cudaStream_t stream;
} launch_config;
static void *fat_binary_handle;
static struct CUkern_st kernel_handle;

__attribute__((format(printf, 2, 3), noreturn)) static void die(const char *call,
                                                                const char *format, ...)
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

static cudaError_t fail(cudaError_t e)
{
    last_error = e;
    return e;
}

static void *pointer(uintptr_t p)
{
    return (void *)p;
}

static void add(table *t, uintptr_t base, size_t size)
{
    if (t->count == t->capacity) {
        size_t capacity = t->capacity ? 2 * t->capacity : 64;
        block *at = realloc(t->at, capacity * sizeof *at);
        if (!at)
            die("table", "out of host memory for the fake's own bookkeeping");
        t->at = at;
        t->capacity = capacity;
    }
    t->at[t->count++] = (block){base, size};
}

// The entry that starts at base, or -1.
static long find(const table *t, uintptr_t base)
{
    for (size_t k = 0; k < t->count; k++)
        if (t->at[k].base == base)
            return (long)k;
    return -1;
}

static void drop(table *t, long k)
{
    t->at[k] = t->at[--t->count];
}

// The block that holds byte p, or NULL.
static const block *holding(const table *t, uintptr_t p)
{
    for (size_t k = 0; k < t->count; k++)
        if (p - t->at[k].base < t->at[k].size)
            return &t->at[k];
    return NULL;
}

// The first block that shares a byte with [p, p + bytes), or NULL (bytes > 0).
static const block *touching(const table *t, uintptr_t p, size_t bytes)
{
    for (size_t k = 0; k < t->count; k++) {
        const block *b = &t->at[k];
        if (b->base >= p ? b->base - p < bytes : p - b->base < b->size)
            return b;
    }
    return NULL;
}

static bool inside(const block *b, uintptr_t p, size_t bytes)
{
    return b && p >= b->base && p - b->base <= b->size && bytes <= b->size - (p - b->base);
}

static void need_device(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    const block *b = holding(&device_blocks, p);
    if (!b) {
        const block *h = holding(&pinned_blocks, p);
        die(call, "%s [%p, +%zu) is not device memory%s", what, pointer(p), bytes,
            h ? " (it is in a pinned host block)" : "");
    }
    if (!inside(b, p, bytes))
        die(call, "%s [%p, +%zu) runs %zu bytes past the end of device block [%p, +%zu)", what,
            pointer(p), bytes, bytes - (b->size - (p - b->base)), pointer(b->base), b->size);
}

static void need_host(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    if (!p)
        die(call, "%s is NULL (%zu bytes)", what, bytes);
    const block *b = touching(&device_blocks, p, bytes);
    if (b)
        die(call,
            "%s [%p, +%zu) is host memory by the copy's kind but overlaps device block "
            "[%p, +%zu)",
            what, pointer(p), bytes, pointer(b->base), b->size);
    b = touching(&pinned_blocks, p, bytes);
    if (b && !inside(b, p, bytes))
        die(call, "%s [%p, +%zu) runs outside pinned block [%p, +%zu)", what, pointer(p), bytes,
            pointer(b->base), b->size);
}

// cudaMemcpyDefault: the pointer says which side it is on.
static void need_either(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    if (holding(&device_blocks, p))
        need_device(call, what, p, bytes);
    else
        need_host(call, what, p, bytes);
}

static void need_kind(const char *call, enum cudaMemcpyKind kind)
{
    switch (kind) {
    case cudaMemcpyHostToHost:
    case cudaMemcpyHostToDevice:
    case cudaMemcpyDeviceToHost:
    case cudaMemcpyDeviceToDevice:
    case cudaMemcpyDefault:
        return;
    }
    die(call, "unknown cudaMemcpyKind %d", (int)kind);
}

static void need_sides(const char *call, enum cudaMemcpyKind kind, uintptr_t dst, uintptr_t src,
                       size_t bytes)
{
    switch (kind) {
    case cudaMemcpyHostToHost:
        need_host(call, "destination", dst, bytes);
        need_host(call, "source", src, bytes);
        return;
    case cudaMemcpyHostToDevice:
        need_device(call, "destination", dst, bytes);
        need_host(call, "source", src, bytes);
        return;
    case cudaMemcpyDeviceToHost:
        need_host(call, "destination", dst, bytes);
        need_device(call, "source", src, bytes);
        return;
    case cudaMemcpyDeviceToDevice:
        need_device(call, "destination", dst, bytes);
        need_device(call, "source", src, bytes);
        return;
    case cudaMemcpyDefault:
        need_either(call, "destination", dst, bytes);
        need_either(call, "source", src, bytes);
        return;
    }
    need_kind(call, kind);
}

static bool overlap(uintptr_t a, uintptr_t b, size_t bytes)
{
    return a < b ? b - a < bytes : a - b < bytes;
}

static bool special_stream(cudaStream_t s)
{
    return !s || s == cudaStreamLegacy || s == cudaStreamPerThread;
}

static void need_stream(const char *call, cudaStream_t s)
{
    if (!special_stream(s) && find(&streams, (uintptr_t)s) < 0)
        die(call, "stream %p is not a live stream (never created, or destroyed)", (void *)s);
}

static struct CUevent_st *need_event(const char *call, cudaEvent_t e)
{
    if (find(&events, (uintptr_t)e) < 0)
        die(call, "event %p is not a live event (never created, or destroyed)", (void *)e);
    return e;
}

static void need_out(const char *call, const void *out)
{
    if (!out)
        die(call, "NULL out-pointer");
}

// ---- stream order ----

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

static struct CUstream_st *canonical(cudaStream_t s)
{
    return special_stream(s) ? NULL : s;
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

// An access on `stream`: checked against those in flight on streams not ordered with it, then
// kept until the host synchronises with it (unless it is done when its call returns).
static void touch(const char *call, const char *what, struct CUstream_st *stream, uintptr_t base,
                  size_t bytes, bool write, bool done_on_return)
{
    if (!bytes)
        return;
    for (size_t k = 0; k < in_flight.count; k++) {
        const access *a = &in_flight.at[k];
        bool meet = a->base >= base ? a->base - base < bytes : base - a->base < a->bytes;
        if (meet && (write || a->write) && !ordered(a->stream, stream))
            die(call,
                "%s [%p, +%zu) on %s (%p) races %s [%p, +%zu) on %s (%p): no synchronisation "
                "between the two streams",
                what, pointer(base), bytes, stream_name(stream), (void *)stream, a->what,
                pointer(a->base), a->bytes, stream_name(a->stream), (void *)a->stream);
    }
    if (done_on_return)
        return;
    if (in_flight.count == in_flight.capacity) {
        size_t capacity = in_flight.capacity ? 2 * in_flight.capacity : 256;
        access *at = realloc(in_flight.at, capacity * sizeof *at);
        if (!at)
            die("stream order", "out of host memory for the fake's own bookkeeping");
        in_flight.at = at;
        in_flight.capacity = capacity;
    }
    in_flight.at[in_flight.count++] =
        (access){base, bytes, stream, write, next_seq++, what ? what : call};
}

// The host has waited for `stream`'s work enqueued before sequence number `before` (and so for
// what that work waited for: the legacy stream's for a blocking stream, and the reverse).
static void completed(const struct CUstream_st *stream, unsigned long before)
{
    for (size_t k = 0; k < in_flight.count;) {
        const access *a = &in_flight.at[k];
        if (a->seq < before && ordered(a->stream, stream))
            in_flight.at[k] = in_flight.at[--in_flight.count];
        else
            k++;
    }
}

static void completed_all(void)
{
    in_flight.count = 0;
}

static void unlock(void)
{
    pthread_mutex_unlock(&lock);
}

static void relock(void)
{
    pthread_mutex_lock(&lock);
}

// ---- the fake's own calls ----

void bpx_fake_cuda_access(cudaStream_t stream, const void *p, size_t bytes, int write,
                          const char *what)
{
    if (!bytes)
        return;
    const char *call = "a fake kernel";
    relock();
    need_stream(call, stream);
    need_device(call, what ? what : "range", (uintptr_t)p, bytes);
    touch(call, what, canonical(stream), (uintptr_t)p, bytes, write != 0, false);
    unlock();
}

void bpx_fake_cuda_fail_allocations_after(long k)
{
    relock();
    allocations_left = k < 0 ? -1 : k;
    unlock();
}

long bpx_fake_cuda_live_blocks(void)
{
    relock();
    long n = (long)(device_blocks.count + pinned_blocks.count);
    unlock();
    return n;
}

// ---- memory ----

static cudaError_t allocate(const char *call, table *t, void **out, size_t size)
{
    need_out(call, out);
    *out = NULL;
    if (!size)
        return cudaSuccess;
    relock();
    bool device = t == &device_blocks;
    void *p = NULL;
    if (allocations_left != 0 && size <= SIZE_MAX - (block_alignment - 1) &&
        (!device || size <= device_memory - device_bytes))
        p = aligned_alloc(block_alignment,
                          (size + block_alignment - 1) / block_alignment * block_alignment);
    if (!p) {
        unlock();
        return fail(cudaErrorMemoryAllocation);
    }
    memset(p, fill_byte, size);
    add(t, (uintptr_t)p, size);
    if (device)
        device_bytes += size;
    if (allocations_left > 0)
        allocations_left--;
    unlock();
    *out = p;
    return cudaSuccess;
}

static cudaError_t release(const char *call, table *t, void *p)
{
    if (!p)
        return cudaSuccess;
    relock();
    long k = find(t, (uintptr_t)p);
    if (k < 0) {
        bool device = t == &device_blocks;
        table *other = device ? &pinned_blocks : &device_blocks;
        const block *b = holding(t, (uintptr_t)p);
        if (b)
            die(call, "%p is inside the live block [%p, +%zu), not its start", p, pointer(b->base),
                b->size);
        if (find(other, (uintptr_t)p) >= 0)
            die(call, "%p is a %s block: free it with %s", p, device ? "pinned host" : "device",
                device ? "cudaFreeHost" : "cudaFree");
        die(call, "%p is not a live %s block (never allocated, or freed already)", p,
            device ? "device" : "pinned host");
    }
    if (t == &device_blocks)
        device_bytes -= t->at[k].size;
    drop(t, k);
    completed_all(); // cudaFree and cudaFreeHost synchronise the device
    unlock();
    free(p);
    return cudaSuccess;
}

cudaError_t cudaMalloc(void **devPtr, size_t size)
{
    return allocate("cudaMalloc", &device_blocks, devPtr, size);
}

cudaError_t cudaFree(void *devPtr)
{
    return release("cudaFree", &device_blocks, devPtr);
}

cudaError_t cudaMallocHost(void **ptr, size_t size)
{
    return allocate("cudaMallocHost", &pinned_blocks, ptr, size);
}

// C++'s typed cudaMallocHost(T **, size_t, flags = 0) comes here.
cudaError_t cudaHostAlloc(void **pHost, size_t size, unsigned int flags)
{
    if (flags &
        ~(unsigned)(cudaHostAllocPortable | cudaHostAllocMapped | cudaHostAllocWriteCombined))
        die("cudaHostAlloc", "unknown flags %#x", flags);
    return allocate("cudaHostAlloc", &pinned_blocks, pHost, size);
}

cudaError_t cudaFreeHost(void *ptr)
{
    return release("cudaFreeHost", &pinned_blocks, ptr);
}

// A copy's place in stream order (CUDA's "API synchronization behavior"): into pageable host
// memory it returns only when done, so the host has waited for its stream; from pageable host
// memory the legacy stream's cudaMemcpy first synchronises it, and the copy itself may still be
// landing when the call returns; every other copy is in flight until the host synchronises.
static void order_copy(const char *call, const void *dst, const void *src, size_t count,
                       struct CUstream_st *stream)
{
    bool from_device = holding(&device_blocks, (uintptr_t)src) != NULL;
    bool to_device = holding(&device_blocks, (uintptr_t)dst) != NULL;
    bool to_pageable = !to_device && !holding(&pinned_blocks, (uintptr_t)dst);
    bool from_pageable = !from_device && !holding(&pinned_blocks, (uintptr_t)src);
    if (from_device)
        touch(call, "the copy's source", stream, (uintptr_t)src, count, false, to_pageable);
    if (to_device)
        touch(call, "the copy's destination", stream, (uintptr_t)dst, count, true, false);
    if (to_pageable)
        completed(stream, next_seq);
    else if (from_pageable && !stream && strcmp(call, "cudaMemcpy") == 0)
        completed(NULL, next_seq - 1); // before the copy, which is in flight
}

static cudaError_t copy(const char *call, void *dst, const void *src, size_t count,
                        enum cudaMemcpyKind kind, const cudaStream_t *stream)
{
    relock();
    if (stream)
        need_stream(call, *stream);
    need_kind(call, kind);
    if (count) {
        need_sides(call, kind, (uintptr_t)dst, (uintptr_t)src, count);
        if (overlap((uintptr_t)dst, (uintptr_t)src, count))
            die(call, "destination %p and source %p overlap (%zu bytes)", dst, src, count);
        order_copy(call, dst, src, count, stream ? canonical(*stream) : NULL);
        memcpy(dst, src, count);
    }
    unlock();
    return cudaSuccess;
}

cudaError_t cudaMemcpy(void *dst, const void *src, size_t count, enum cudaMemcpyKind kind)
{
    return copy("cudaMemcpy", dst, src, count, kind, NULL);
}

cudaError_t cudaMemcpyAsync(void *dst, const void *src, size_t count, enum cudaMemcpyKind kind,
                            cudaStream_t stream)
{
    return copy("cudaMemcpyAsync", dst, src, count, kind, &stream);
}

// Rows of width bytes, pitch apart on each side.
cudaError_t cudaMemcpy2DAsync(void *dst, size_t dpitch, const void *src, size_t spitch,
                              size_t width, size_t height, enum cudaMemcpyKind kind,
                              cudaStream_t stream)
{
    const char *call = "cudaMemcpy2DAsync";
    relock();
    need_stream(call, stream);
    need_kind(call, kind);
    if (width > dpitch || width > spitch) {
        unlock();
        return fail(cudaErrorInvalidPitchValue);
    }
    if (width && height) {
        uintptr_t d = (uintptr_t)dst, s = (uintptr_t)src;
        size_t last = height - 1;
        if (width > UINTPTR_MAX - d || width > UINTPTR_MAX - s ||
            (dpitch && last > (UINTPTR_MAX - d - width) / dpitch) ||
            (spitch && last > (UINTPTR_MAX - s - width) / spitch))
            die(call, "%zu rows of pitch %zu / %zu wrap around the address space", height, dpitch,
                spitch);
        for (size_t r = 0; r < height; r++)
            need_sides(call, kind, d + r * dpitch, s + r * spitch, width);
        // Spans first: rows are compared only where the spans meet.
        uintptr_t d_end = d + last * dpitch + width, s_end = s + last * spitch + width;
        if (d < s_end && s < d_end)
            for (size_t r = 0; r < height; r++)
                for (size_t q = 0; q < height; q++)
                    if (overlap(d + r * dpitch, s + q * spitch, width))
                        die(call, "destination row %zu %p and source row %zu %p overlap", r,
                            pointer(d + r * dpitch), q, pointer(s + q * spitch));
        for (size_t r = 0; r < height; r++) {
            order_copy(call, pointer(d + r * dpitch), (const void *)(s + r * spitch), width,
                       canonical(stream));
            memcpy(pointer(d + r * dpitch), (const void *)(s + r * spitch), width);
        }
    }
    unlock();
    return cudaSuccess;
}

static cudaError_t set(const char *call, void *devPtr, int value, size_t count,
                       const cudaStream_t *stream)
{
    relock();
    if (stream)
        need_stream(call, *stream);
    if (count) {
        need_device(call, "destination", (uintptr_t)devPtr, count);
        touch(call, "the memset's destination", stream ? canonical(*stream) : NULL,
              (uintptr_t)devPtr, count, true, false); // in flight even from cudaMemset
        memset(devPtr, value, count);
    }
    unlock();
    return cudaSuccess;
}

cudaError_t cudaMemset(void *devPtr, int value, size_t count)
{
    return set("cudaMemset", devPtr, value, count, NULL);
}

cudaError_t cudaMemsetAsync(void *devPtr, int value, size_t count, cudaStream_t stream)
{
    return set("cudaMemsetAsync", devPtr, value, count, &stream);
}

// ---- the device ----

cudaError_t cudaSetDevice(int device)
{
    return device == 0 ? cudaSuccess : fail(cudaErrorInvalidDevice);
}

cudaError_t cudaGetDevice(int *device)
{
    need_out("cudaGetDevice", device);
    *device = 0;
    return cudaSuccess;
}

cudaError_t cudaGetDeviceCount(int *count)
{
    need_out("cudaGetDeviceCount", count);
    *count = 1;
    return cudaSuccess;
}

cudaError_t cudaGetDeviceProperties(struct cudaDeviceProp *prop, int device)
{
    need_out("cudaGetDeviceProperties", prop);
    if (device != 0)
        return fail(cudaErrorInvalidDevice);
    memset(prop, 0, sizeof *prop);
    snprintf(prop->name, sizeof prop->name, "%s", "bpx fake device (host memory)");
    prop->major = 9;
    prop->minor = 0;
    prop->totalGlobalMem = device_memory;
    prop->multiProcessorCount = 1;
    prop->warpSize = 32;
    return cudaSuccess;
}

cudaError_t cudaDriverGetVersion(int *driverVersion)
{
    need_out("cudaDriverGetVersion", driverVersion);
    *driverVersion = CUDART_VERSION;
    return cudaSuccess;
}

cudaError_t cudaRuntimeGetVersion(int *runtimeVersion)
{
    need_out("cudaRuntimeGetVersion", runtimeVersion);
    *runtimeVersion = CUDART_VERSION;
    return cudaSuccess;
}

cudaError_t cudaDeviceSynchronize(void)
{
    relock();
    completed_all();
    unlock();
    return cudaSuccess;
}

// ---- streams and events ----

cudaError_t cudaStreamCreateWithFlags(cudaStream_t *pStream, unsigned int flags)
{
    const char *call = "cudaStreamCreateWithFlags";
    need_out(call, pStream);
    if (flags & ~(unsigned)cudaStreamNonBlocking)
        die(call, "unknown flags %#x", flags);
    struct CUstream_st *s = malloc(sizeof *s);
    if (!s)
        return fail(cudaErrorMemoryAllocation);
    s->flags = flags;
    relock();
    add(&streams, (uintptr_t)s, sizeof *s);
    unlock();
    *pStream = s;
    return cudaSuccess;
}

cudaError_t cudaStreamCreate(cudaStream_t *pStream)
{
    need_out("cudaStreamCreate", pStream);
    return cudaStreamCreateWithFlags(pStream, cudaStreamDefault);
}

cudaError_t cudaStreamDestroy(cudaStream_t stream)
{
    const char *call = "cudaStreamDestroy";
    if (special_stream(stream))
        die(call, "stream %p is a default stream, not one to destroy", (void *)stream);
    relock();
    long k = find(&streams, (uintptr_t)stream);
    if (k < 0)
        die(call, "stream %p is not a live stream (never created, or destroyed)", (void *)stream);
    drop(&streams, k);
    // Its work may still be in flight (destroying does not wait): it keeps its place in stream
    // order under a handle no later stream can have, as the freed address could.
    static struct CUstream_st destroyed = {cudaStreamNonBlocking};
    for (size_t a = 0; a < in_flight.count; a++)
        if (in_flight.at[a].stream == stream)
            in_flight.at[a].stream = &destroyed;
    unlock();
    free(stream);
    return cudaSuccess;
}

cudaError_t cudaStreamSynchronize(cudaStream_t stream)
{
    relock();
    need_stream("cudaStreamSynchronize", stream);
    completed(canonical(stream), next_seq);
    unlock();
    return cudaSuccess;
}

cudaError_t cudaEventCreateWithFlags(cudaEvent_t *event, unsigned int flags)
{
    const char *call = "cudaEventCreateWithFlags";
    need_out(call, event);
    if (flags & ~(unsigned)(cudaEventBlockingSync | cudaEventDisableTiming | cudaEventInterprocess))
        die(call, "unknown flags %#x", flags);
    if ((flags & cudaEventInterprocess) && !(flags & cudaEventDisableTiming))
        die(call, "cudaEventInterprocess needs cudaEventDisableTiming");
    struct CUevent_st *e = malloc(sizeof *e);
    if (!e)
        return fail(cudaErrorMemoryAllocation);
    *e = (struct CUevent_st){
        .flags = flags, .recorded = false, .at_ms = 0.0, .stream = NULL, .seq = 0};
    relock();
    add(&events, (uintptr_t)e, sizeof *e);
    unlock();
    *event = e;
    return cudaSuccess;
}

cudaError_t cudaEventCreate(cudaEvent_t *event)
{
    need_out("cudaEventCreate", event);
    return cudaEventCreateWithFlags(event, cudaEventDefault);
}

cudaError_t cudaEventDestroy(cudaEvent_t event)
{
    relock();
    need_event("cudaEventDestroy", event);
    drop(&events, find(&events, (uintptr_t)event));
    unlock();
    free(event);
    return cudaSuccess;
}

cudaError_t cudaEventRecord(cudaEvent_t event, cudaStream_t stream)
{
    const char *call = "cudaEventRecord";
    relock();
    need_stream(call, stream);
    struct CUevent_st *e = need_event(call, event);
    e->stream = canonical(stream);
    e->seq = next_seq;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    e->recorded = true;
    e->at_ms = 1e3 * (double)now.tv_sec + 1e-6 * (double)now.tv_nsec;
    unlock();
    return cudaSuccess;
}

cudaError_t cudaEventSynchronize(cudaEvent_t event)
{
    relock();
    const struct CUevent_st *e = need_event("cudaEventSynchronize", event);
    if (e->recorded)
        completed(e->stream, e->seq);
    unlock();
    return cudaSuccess;
}

// The host time between the two records: the fake device's work is done between them, at once.
// An event never recorded, or one without timing, is the real runtime's
// cudaErrorInvalidResourceHandle.
cudaError_t cudaEventElapsedTime(float *ms, cudaEvent_t start, cudaEvent_t end)
{
    const char *call = "cudaEventElapsedTime";
    need_out(call, ms);
    relock();
    const struct CUevent_st *a = need_event(call, start), *b = need_event(call, end);
    bool timed =
        a->recorded && b->recorded && !((a->flags | b->flags) & (unsigned)cudaEventDisableTiming);
    double between = b->at_ms - a->at_ms;
    unlock();
    if (!timed)
        return fail(cudaErrorInvalidResourceHandle);
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

// ---- nvcc's hooks ----
// Every .cu object registers its fat binary at load time: accepted and ignored. A <<<>>> launch
// pushes its configuration, the stub pops it and launches: the launch aborts, since every kernel
// the fake-device tests run is host code.

void **__cudaRegisterFatBinary(void *fatCubin)
{
    (void)fatCubin;
    return &fat_binary_handle;
}

void __cudaRegisterFatBinaryEnd(void **fatCubinHandle)
{
    (void)fatCubinHandle;
}

void __cudaUnregisterFatBinary(void **fatCubinHandle)
{
    (void)fatCubinHandle;
}

void __cudaRegisterFunction(void **fatCubinHandle, const char *hostFun, char *deviceFun,
                            const char *deviceName, int thread_limit, uint3 *tid, uint3 *bid,
                            dim3 *bDim, dim3 *gDim, int *wSize)
{
    (void)fatCubinHandle, (void)hostFun, (void)deviceFun, (void)deviceName, (void)thread_limit;
    (void)tid, (void)bid, (void)bDim, (void)gDim, (void)wSize;
}

void __cudaRegisterVar(void **fatCubinHandle, char *hostVar, char *deviceAddress,
                       const char *deviceName, int ext, size_t size, int constant, int global)
{
    (void)fatCubinHandle, (void)hostVar, (void)deviceAddress, (void)deviceName, (void)ext;
    (void)size, (void)constant, (void)global;
}

// Nonzero: the module is initialised (the managed runtime's flag).
char __cudaInitModule(void **fatCubinHandle)
{
    (void)fatCubinHandle;
    return 1;
}

// 0: go on to the kernel's stub.
unsigned __cudaPushCallConfiguration(dim3 gridDim, dim3 blockDim, size_t sharedMem,
                                     struct CUstream_st *stream)
{
    launch_config.pushed = true;
    launch_config.grid = gridDim;
    launch_config.block = blockDim;
    launch_config.shared = sharedMem;
    launch_config.stream = stream;
    return 0;
}

cudaError_t __cudaPopCallConfiguration(dim3 *gridDim, dim3 *blockDim, size_t *sharedMem,
                                       void *stream)
{
    if (!launch_config.pushed)
        die("__cudaPopCallConfiguration", "no launch configuration was pushed");
    launch_config.pushed = false;
    *gridDim = launch_config.grid;
    *blockDim = launch_config.block;
    *sharedMem = launch_config.shared;
    *(cudaStream_t *)stream = launch_config.stream;
    return cudaSuccess;
}

cudaError_t __cudaGetKernel(cudaKernel_t *kernel, const void *func)
{
    (void)func;
    *kernel = &kernel_handle;
    return cudaSuccess;
}

__attribute__((noreturn)) static void launched(void)
{
    fputs("fake cuda: a kernel launch reached the fake runtime\n", stderr);
    fflush(stderr);
    abort();
}

cudaError_t __cudaLaunchKernel(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                               size_t sharedMem, cudaStream_t stream)
{
    (void)kernel, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t __cudaLaunchKernel_ptsz(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                                    size_t sharedMem, cudaStream_t stream)
{
    (void)kernel, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t cudaLaunchKernel(const void *func, dim3 gridDim, dim3 blockDim, void **args,
                             size_t sharedMem, cudaStream_t stream)
{
    (void)func, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t cudaLaunchKernelExC(const cudaLaunchConfig_t *config, const void *func, void **args)
{
    (void)config, (void)func, (void)args;
    launched();
}

#pragma GCC visibility pop
