#include "alloc.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "bpx/base.h"

static bpx_alloc_fn *user_alloc;
static bpx_free_fn *user_free;
static void *user_data;
static _Atomic int64_t allocated_bytes;
static _Atomic int64_t allocated_peak;

void bpx_set_allocator(bpx_alloc_fn *alloc, bpx_free_fn *free_fn, void *user)
{
    user_alloc = alloc;
    user_free = free_fn;
    user_data = user;
}

int64_t bpx_allocated_bytes(void)
{
    return atomic_load(&allocated_bytes);
}

int64_t bpx_allocated_peak(void)
{
    return atomic_load(&allocated_peak);
}

void bpx_reset_allocated_peak(void)
{
    atomic_store(&allocated_peak, atomic_load(&allocated_bytes));
}

void *bpx__alloc(size_t size)
{
    if (size == 0)
        return NULL;
    // aligned_alloc wants a multiple of the alignment; the rounding also makes SIMD tails safe.
    size_t rounded = (size + BPX_ALIGN - 1) & ~(size_t)(BPX_ALIGN - 1);
    if (rounded < size)
        return NULL;
    void *memory = user_alloc ? user_alloc(rounded, BPX_ALIGN, user_data)
                              : aligned_alloc(BPX_ALIGN, rounded);
    if (memory) {
        int64_t now = atomic_fetch_add(&allocated_bytes, (int64_t)size) + (int64_t)size;
        int64_t peak = atomic_load(&allocated_peak);
        while (now > peak && !atomic_compare_exchange_weak(&allocated_peak, &peak, now))
            ; // another thread raised it: peak now holds its value, compare again
    }
    return memory;
}

void bpx__free(void *memory, size_t size)
{
    if (!memory)
        return;
    atomic_fetch_sub(&allocated_bytes, (int64_t)size);
    if (user_free)
        user_free(memory, user_data);
    else
        free(memory);
}

int bpx__grow(void **memory, size_t old_size, size_t new_size)
{
    void *grown = bpx__alloc(new_size);
    if (!grown)
        return 0;
    if (*memory && old_size)
        memcpy(grown, *memory, old_size < new_size ? old_size : new_size);
    bpx__free(*memory, old_size);
    *memory = grown;
    return 1;
}
