// SPDX-License-Identifier: MIT
// The fake CUDA runtime's memory (runtime.c says what the fake is): device and pinned host
// blocks, which are host memory, and the copies and memsets between them. Each range a call
// names must lie where the call says it lies (one live device block, or host memory that
// overlaps a pinned block only from inside it); a copy's two ranges must not overlap. Copies and
// memsets take their place in stream order (stream_order.c). Fresh blocks are filled with 0xa5;
// allocations can be made to fail from the k-th on (fake_cuda.h).

// Exported whatever visibility the build sets: the library calls these from its own objects.
#pragma GCC visibility push(default)

#include <stdlib.h>
#include <string.h>

#include "fake_cuda.h"
#include "runtime.h"
#include "stream_order.h"

enum {
    block_alignment = 256,
    fill_byte = 0xa5,
};

fake_table fake_device_blocks, fake_pinned_blocks;
static size_t device_bytes;        // live device blocks' sizes, against fake_device_memory
static long allocations_left = -1; // before injected failure; < 0: none

// ---- ranges: where a call's pointers must lie ----

// The first block that shares a byte with [p, p + bytes), or NULL (bytes > 0).
static const fake_block *touching(const fake_table *t, uintptr_t p, size_t bytes)
{
    for (size_t k = 0; k < t->count; k++) {
        const fake_block *b = &t->at[k];
        if (b->base >= p ? b->base - p < bytes : p - b->base < b->size)
            return b;
    }
    return NULL;
}

static bool inside(const fake_block *b, uintptr_t p, size_t bytes)
{
    return b && p >= b->base && p - b->base <= b->size && bytes <= b->size - (p - b->base);
}

void fake_need_device(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    const fake_block *b = fake_table_holding(&fake_device_blocks, p);
    if (!b) {
        const fake_block *h = fake_table_holding(&fake_pinned_blocks, p);
        fake_die(call, "%s [%p, +%zu) is not device memory%s", what, fake_pointer(p), bytes,
                 h ? " (it is in a pinned host block)" : "");
    }
    if (!inside(b, p, bytes))
        fake_die(call, "%s [%p, +%zu) runs %zu bytes past the end of device block [%p, +%zu)", what,
                 fake_pointer(p), bytes, bytes - (b->size - (p - b->base)), fake_pointer(b->base),
                 b->size);
}

static void need_host(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    if (!p)
        fake_die(call, "%s is NULL (%zu bytes)", what, bytes);
    const fake_block *b = touching(&fake_device_blocks, p, bytes);
    if (b)
        fake_die(call,
                 "%s [%p, +%zu) is host memory by the copy's kind but overlaps device block "
                 "[%p, +%zu)",
                 what, fake_pointer(p), bytes, fake_pointer(b->base), b->size);
    b = touching(&fake_pinned_blocks, p, bytes);
    if (b && !inside(b, p, bytes))
        fake_die(call, "%s [%p, +%zu) runs outside pinned block [%p, +%zu)", what, fake_pointer(p),
                 bytes, fake_pointer(b->base), b->size);
}

// cudaMemcpyDefault: the pointer says which side it is on.
static void need_either(const char *call, const char *what, uintptr_t p, size_t bytes)
{
    if (fake_table_holding(&fake_device_blocks, p))
        fake_need_device(call, what, p, bytes);
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
    fake_die(call, "unknown cudaMemcpyKind %d", (int)kind);
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
        fake_need_device(call, "destination", dst, bytes);
        need_host(call, "source", src, bytes);
        return;
    case cudaMemcpyDeviceToHost:
        need_host(call, "destination", dst, bytes);
        fake_need_device(call, "source", src, bytes);
        return;
    case cudaMemcpyDeviceToDevice:
        fake_need_device(call, "destination", dst, bytes);
        fake_need_device(call, "source", src, bytes);
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

// ---- allocations ----

void bpx_fake_cuda_fail_allocations_after(long k)
{
    fake_lock();
    allocations_left = k < 0 ? -1 : k;
    fake_unlock();
}

long bpx_fake_cuda_live_blocks(void)
{
    fake_lock();
    long n = (long)(fake_device_blocks.count + fake_pinned_blocks.count);
    fake_unlock();
    return n;
}

static cudaError_t allocate(const char *call, fake_table *t, void **out, size_t size)
{
    fake_need_out(call, out);
    *out = NULL;
    if (!size)
        return cudaSuccess;
    fake_lock();
    bool device = t == &fake_device_blocks;
    void *p = NULL;
    if (allocations_left != 0 && size <= SIZE_MAX - (block_alignment - 1) &&
        (!device || size <= fake_device_memory - device_bytes))
        p = aligned_alloc(block_alignment,
                          (size + block_alignment - 1) / block_alignment * block_alignment);
    if (!p) {
        fake_unlock();
        return fake_fail(cudaErrorMemoryAllocation);
    }
    memset(p, fill_byte, size);
    fake_table_add(t, (uintptr_t)p, size);
    if (device)
        device_bytes += size;
    if (allocations_left > 0)
        allocations_left--;
    fake_unlock();
    *out = p;
    return cudaSuccess;
}

static cudaError_t release(const char *call, fake_table *t, void *p)
{
    if (!p)
        return cudaSuccess;
    fake_lock();
    long k = fake_table_find(t, (uintptr_t)p);
    if (k < 0) {
        bool device = t == &fake_device_blocks;
        fake_table *other = device ? &fake_pinned_blocks : &fake_device_blocks;
        const fake_block *b = fake_table_holding(t, (uintptr_t)p);
        if (b)
            fake_die(call, "%p is inside the live block [%p, +%zu), not its start", p,
                     fake_pointer(b->base), b->size);
        if (fake_table_find(other, (uintptr_t)p) >= 0)
            fake_die(call, "%p is a %s block: free it with %s", p,
                     device ? "pinned host" : "device", device ? "cudaFreeHost" : "cudaFree");
        fake_die(call, "%p is not a live %s block (never allocated, or freed already)", p,
                 device ? "device" : "pinned host");
    }
    if (t == &fake_device_blocks)
        device_bytes -= t->at[k].size;
    fake_table_drop(t, k);
    fake_completed_all(); // cudaFree and cudaFreeHost synchronise the device
    fake_unlock();
    free(p);
    return cudaSuccess;
}

cudaError_t cudaMalloc(void **devPtr, size_t size)
{
    return allocate("cudaMalloc", &fake_device_blocks, devPtr, size);
}

cudaError_t cudaFree(void *devPtr)
{
    return release("cudaFree", &fake_device_blocks, devPtr);
}

cudaError_t cudaMallocHost(void **ptr, size_t size)
{
    return allocate("cudaMallocHost", &fake_pinned_blocks, ptr, size);
}

// C++'s typed cudaMallocHost(T **, size_t, flags = 0) comes here.
cudaError_t cudaHostAlloc(void **pHost, size_t size, unsigned int flags)
{
    if (flags &
        ~(unsigned)(cudaHostAllocPortable | cudaHostAllocMapped | cudaHostAllocWriteCombined))
        fake_die("cudaHostAlloc", "unknown flags %#x", flags);
    return allocate("cudaHostAlloc", &fake_pinned_blocks, pHost, size);
}

cudaError_t cudaFreeHost(void *ptr)
{
    return release("cudaFreeHost", &fake_pinned_blocks, ptr);
}

// ---- copies and memsets ----

static cudaError_t copy(const char *call, void *dst, const void *src, size_t count,
                        enum cudaMemcpyKind kind, const cudaStream_t *stream)
{
    fake_lock();
    if (stream)
        fake_need_stream(call, *stream);
    need_kind(call, kind);
    if (count) {
        need_sides(call, kind, (uintptr_t)dst, (uintptr_t)src, count);
        if (overlap((uintptr_t)dst, (uintptr_t)src, count))
            fake_die(call, "destination %p and source %p overlap (%zu bytes)", dst, src, count);
        fake_order_copy(call, dst, src, count, stream ? fake_canonical(*stream) : NULL);
        memcpy(dst, src, count);
    }
    fake_unlock();
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
    fake_lock();
    fake_need_stream(call, stream);
    need_kind(call, kind);
    if (width > dpitch || width > spitch) {
        fake_unlock();
        return fake_fail(cudaErrorInvalidPitchValue);
    }
    if (width && height) {
        uintptr_t d = (uintptr_t)dst, s = (uintptr_t)src;
        size_t last = height - 1;
        if (width > UINTPTR_MAX - d || width > UINTPTR_MAX - s ||
            (dpitch && last > (UINTPTR_MAX - d - width) / dpitch) ||
            (spitch && last > (UINTPTR_MAX - s - width) / spitch))
            fake_die(call, "%zu rows of pitch %zu / %zu wrap around the address space", height,
                     dpitch, spitch);
        for (size_t r = 0; r < height; r++)
            need_sides(call, kind, d + r * dpitch, s + r * spitch, width);
        // Spans first: rows are compared only where the spans meet.
        uintptr_t d_end = d + last * dpitch + width, s_end = s + last * spitch + width;
        if (d < s_end && s < d_end)
            for (size_t r = 0; r < height; r++)
                for (size_t q = 0; q < height; q++)
                    if (overlap(d + r * dpitch, s + q * spitch, width))
                        fake_die(call, "destination row %zu %p and source row %zu %p overlap", r,
                                 fake_pointer(d + r * dpitch), q, fake_pointer(s + q * spitch));
        for (size_t r = 0; r < height; r++) {
            fake_order_copy(call, fake_pointer(d + r * dpitch), (const void *)(s + r * spitch),
                            width, fake_canonical(stream));
            memcpy(fake_pointer(d + r * dpitch), (const void *)(s + r * spitch), width);
        }
    }
    fake_unlock();
    return cudaSuccess;
}

static cudaError_t set(const char *call, void *devPtr, int value, size_t count,
                       const cudaStream_t *stream)
{
    fake_lock();
    if (stream)
        fake_need_stream(call, *stream);
    if (count) {
        fake_need_device(call, "destination", (uintptr_t)devPtr, count);
        fake_touch(call, "the memset's destination", stream ? fake_canonical(*stream) : NULL,
                   (uintptr_t)devPtr, count, true, false); // in flight even from cudaMemset
        memset(devPtr, value, count);
    }
    fake_unlock();
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

#pragma GCC visibility pop
