// The collision emitter: per-block hit lists (filled in parallel) merged into one ordered stream.
#include <string.h>

#include "alloc.h"
#include "world.h"

enum {
    BLOCK_TARGET_TESTS = 8192, // a few us of work: claims stay rare, 2+ threads share n = 500
    BLOCK_MAX = 1024,
    ROW_OVERHEAD_TESTS = 16, // a row's fixed cost (broadcasts, first partial vector), in tests
};

enum { BLOCK_FIRST_PAIRS = 64 }; // every block starts with room for this many hits

bpx_status bpx__emitter_reserve_blocks(bpx_world *w, int wanted)
{
    if (wanted > w->block_capacity) {
        // Half again as many: backends whose block count follows the data (grid) settle.
        int capacity = wanted + wanted / 2;
        size_t old_size = sizeof(bpx_block) * (size_t)w->block_capacity;
        size_t new_size = sizeof(bpx_block) * (size_t)capacity;
        if (!bpx__grow((void **)&w->blocks, old_size, new_size))
            return BPX_ERR_OUT_OF_MEMORY;
        memset((char *)w->blocks + old_size, 0, new_size - old_size);
        w->block_capacity = capacity;
    }
    // Room up front, so that a block's first hits in a later cycle do not allocate there.
    for (int b = 0; b < wanted; b++)
        if (!bpx__list_reserve(&w->blocks[b].hits, BLOCK_FIRST_PAIRS) ||
            !bpx__list_reserve(&w->blocks[b].stage, BLOCK_FIRST_PAIRS))
            return BPX_ERR_OUT_OF_MEMORY;
    return BPX_OK;
}

bpx_status bpx__emitter_one_block(bpx_world *w, bpx_block **out)
{
    if (w->planned_n != w->n) {
        bpx_status status = bpx__emitter_plan(w, true);
        if (status != BPX_OK)
            return status;
    }
    bpx_block *block = &w->blocks[0];
    block->hits.count = 0;
    block->stage.count = 0;
    block->tests = 0;
    block->status = BPX_OK;
    *out = block;
    return BPX_OK;
}

bpx_status bpx__emitter_plan_rows(bpx_world *w, uint32_t rows)
{
    uint32_t n = w->n;
    int wanted = (int)((n + rows - 1) / rows);
    if (wanted < 1)
        wanted = 1;
    bpx_status status = bpx__emitter_reserve_blocks(w, wanted);
    if (status != BPX_OK)
        return status;
    for (int b = 0; b < wanted; b++) {
        w->blocks[b].row_begin = (uint32_t)b * rows;
        w->blocks[b].row_end = (uint32_t)b * rows + rows < n ? (uint32_t)b * rows + rows : n;
    }
    w->block_count = wanted;
    w->planned_n = n;
    return BPX_OK;
}

bpx_status bpx__emitter_plan(bpx_world *w, bool single)
{
    uint32_t n = w->n;
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++)
        total += (uint64_t)(n - 1 - i) + ROW_OVERHEAD_TESTS;
    uint64_t target = total / BLOCK_MAX + 1;
    if (target < BLOCK_TARGET_TESTS)
        target = BLOCK_TARGET_TESTS;
    int wanted = single ? 1 : (int)(total / target) + 1;

    bpx_status status = bpx__emitter_reserve_blocks(w, wanted);
    if (status != BPX_OK)
        return status;

    // Cut rows where the running cost crosses each multiple of the per-block share.
    int b = 0;
    uint64_t share = total / (uint64_t)wanted + 1, cost = 0;
    w->blocks[0].row_begin = 0;
    for (uint32_t i = 0; i < n; i++) {
        cost += (uint64_t)(n - 1 - i) + ROW_OVERHEAD_TESTS;
        if (cost >= share * (uint64_t)(b + 1) && b + 1 < wanted && i + 1 < n) {
            w->blocks[b].row_end = i + 1;
            w->blocks[++b].row_begin = i + 1;
        }
    }
    w->blocks[b].row_end = n;
    w->block_count = b + 1;
    w->planned_n = n;
    return BPX_OK;
}

bool bpx__list_reserve(bpx_pair_list *list, size_t extra)
{
    if (list->capacity - list->count >= extra)
        return true;
    size_t capacity = list->capacity ? list->capacity : 64;
    while (capacity - list->count < extra) {
        if (capacity > SIZE_MAX / 2 / sizeof(bpx_pair))
            return false;
        capacity *= 2;
    }
    if (!bpx__grow((void **)&list->pairs, list->capacity * sizeof(bpx_pair),
                   capacity * sizeof(bpx_pair)))
        return false;
    list->capacity = capacity;
    return true;
}

bool bpx__list_append(bpx_pair_list *dst, const bpx_pair_list *src)
{
    if (!src->count)
        return true;
    if (!bpx__list_reserve(dst, src->count))
        return false;
    memcpy(dst->pairs + dst->count, src->pairs, src->count * sizeof(bpx_pair));
    dst->count += src->count;
    return true;
}

static void list_free(bpx_pair_list *list)
{
    bpx__free(list->pairs, list->capacity * sizeof(bpx_pair));
    *list = (bpx_pair_list){0};
}

bpx_status bpx__emitter_total(const bpx_world *w, size_t *total)
{
    size_t sum = 0;
    for (int b = 0; b < w->block_count; b++) {
        if (w->blocks[b].status != BPX_OK)
            return w->blocks[b].status;
        sum += w->blocks[b].hits.count;
    }
    *total = sum;
    return BPX_OK;
}

void bpx__emitter_merge(const bpx_world *w, bpx_pair *out)
{
    for (int b = 0; b < w->block_count; b++) {
        const bpx_block *block = &w->blocks[b];
        // out is NULL when no pair was found (an empty list owns no memory), and even + 0 on
        // a null pointer is undefined: only a block with hits moves it.
        if (block->hits.count) {
            memcpy(out, block->hits.pairs, block->hits.count * sizeof(bpx_pair));
            out += block->hits.count;
        }
    }
}

// Stable counting sort of src into dst by the i (by_i) or j field; counts has n + 1 words.
static void counting_sort(const bpx_pair *src, bpx_pair *dst, size_t count, uint32_t n,
                          uint32_t *counts, bool by_i)
{
    memset(counts, 0, sizeof(uint32_t) * ((size_t)n + 1));
    for (size_t k = 0; k < count; k++)
        counts[(by_i ? src[k].i : src[k].j) + 1]++;
    for (uint32_t v = 0; v < n; v++)
        counts[v + 1] += counts[v];
    for (size_t k = 0; k < count; k++)
        dst[counts[by_i ? src[k].i : src[k].j]++] = src[k];
}

bpx_status bpx__emitter_sort_blocks(bpx_world *w, bpx_pair_list *a, bpx_pair_list *b,
                                    uint32_t *counts)
{
    size_t total = 0;
    bpx_status status = bpx__emitter_total(w, &total);
    if (status != BPX_OK)
        return status;
    if (total > UINT32_MAX)
        return BPX_ERR_TOO_MANY_PAIRS; // the counting sort's offsets are 32-bit
    a->count = b->count = 0;
    // Headroom: the three lists that take turns here (a, b and block 0's) settle in a few
    // cycles even when the pair count drifts up.
    if (!bpx__list_reserve(a, total + total / 2) || !bpx__list_reserve(b, total + total / 2))
        return BPX_ERR_OUT_OF_MEMORY;
    bpx__emitter_merge(w, a->pairs);
    // By j, then (stably) by i: (i, j) order.
    counting_sort(a->pairs, b->pairs, total, w->n, counts, false);
    counting_sort(b->pairs, a->pairs, total, w->n, counts, true);
    a->count = total;

    // Block 0 takes the ordered list (a swap, not a copy); its old list becomes scratch.
    uint64_t tests = 0;
    for (int k = 0; k < w->block_count; k++) {
        tests += w->blocks[k].tests;
        w->blocks[k].hits.count = 0;
        w->blocks[k].tests = 0;
    }
    bpx_pair_list block0 = w->blocks[0].hits;
    w->blocks[0].hits = *a;
    w->blocks[0].tests = tests;
    *a = block0;
    return BPX_OK;
}

void bpx__emitter_release(bpx_world *w)
{
    for (int b = 0; b < w->block_capacity; b++) {
        list_free(&w->blocks[b].hits);
        list_free(&w->blocks[b].stage);
        w->blocks[b].status = BPX_OK;
    }
    list_free(&w->pairs);
}

void bpx__emitter_free(bpx_world *w)
{
    for (int b = 0; b < w->block_capacity; b++) {
        list_free(&w->blocks[b].hits);
        list_free(&w->blocks[b].stage);
    }
    bpx__free(w->blocks, sizeof(bpx_block) * (size_t)w->block_capacity);
    list_free(&w->pairs);
    w->blocks = NULL;
    w->block_capacity = w->block_count = 0;
}
