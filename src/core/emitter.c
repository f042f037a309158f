// The collision emitter: per-block hit lists (filled in parallel) merged into one ordered stream.
#include <string.h>

#include "alloc.h"
#include "backend.h"

enum {
    BLOCK_TARGET_TESTS = 8192, // a few us of work: claims stay rare, 2+ threads share n = 500
    BLOCK_MAX = 1024,
    ROW_OVERHEAD_TESTS = 16, // a row's fixed cost (broadcasts, first partial vector), in tests
};

enum { BLOCK_FIRST_PAIRS = 64 }; // every block starts with room for this many hits

bpx_status bpx__emitter_reserve_blocks(bpx_emitter *e, int wanted)
{
    if (wanted > e->block_capacity) {
        // Half again as many: backends whose block count follows the data (grid) settle.
        int capacity = wanted + wanted / 2;
        size_t old_size = sizeof(bpx_block) * (size_t)e->block_capacity;
        size_t new_size = sizeof(bpx_block) * (size_t)capacity;
        if (!bpx__grow((void **)&e->blocks, old_size, new_size))
            return BPX_ERR_OUT_OF_MEMORY;
        memset((char *)e->blocks + old_size, 0, new_size - old_size);
        e->block_capacity = capacity;
    }
    // Room up front, so that a block's first hits in a later cycle do not allocate there.
    for (int b = 0; b < wanted; b++)
        if (!bpx__list_reserve(&e->blocks[b].hits, BLOCK_FIRST_PAIRS) ||
            !bpx__list_reserve(&e->blocks[b].stage, BLOCK_FIRST_PAIRS))
            return BPX_ERR_OUT_OF_MEMORY;
    return BPX_OK;
}

bpx_status bpx__emitter_own_blocks(bpx_emitter *e, int count)
{
    bpx_status status = bpx__emitter_reserve_blocks(e, count);
    if (status != BPX_OK)
        return status;
    e->block_count = count;
    e->planned_n = UINT32_MAX; // the layout is the backend's own
    return BPX_OK;
}

bpx_status bpx__emitter_one_block(bpx_emitter *e, uint32_t n, bpx_block **out)
{
    if (e->planned_n != n) {
        bpx_status status = bpx__emitter_plan(e, n, true);
        if (status != BPX_OK)
            return status;
    }
    bpx_block *block = &e->blocks[0];
    block->hits.count = 0;
    block->stage.count = 0;
    block->tests = 0;
    block->status = BPX_OK;
    *out = block;
    return BPX_OK;
}

bpx_status bpx__emitter_plan_rows(bpx_emitter *e, uint32_t n, uint32_t rows)
{
    int wanted = (int)((n + rows - 1) / rows);
    if (wanted < 1)
        wanted = 1;
    bpx_status status = bpx__emitter_reserve_blocks(e, wanted);
    if (status != BPX_OK)
        return status;
    for (int b = 0; b < wanted; b++) {
        e->blocks[b].row_begin = (uint32_t)b * rows;
        e->blocks[b].row_end = (uint32_t)b * rows + rows < n ? (uint32_t)b * rows + rows : n;
    }
    e->block_count = wanted;
    e->planned_n = n;
    return BPX_OK;
}

bpx_status bpx__emitter_plan(bpx_emitter *e, uint32_t n, bool single)
{
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++)
        total += (uint64_t)(n - 1 - i) + ROW_OVERHEAD_TESTS;
    uint64_t target = total / BLOCK_MAX + 1;
    if (target < BLOCK_TARGET_TESTS)
        target = BLOCK_TARGET_TESTS;
    int wanted = single ? 1 : (int)(total / target) + 1;

    bpx_status status = bpx__emitter_reserve_blocks(e, wanted);
    if (status != BPX_OK)
        return status;

    // Cut rows where the running cost crosses each multiple of the per-block share.
    int b = 0;
    uint64_t share = total / (uint64_t)wanted + 1, cost = 0;
    e->blocks[0].row_begin = 0;
    for (uint32_t i = 0; i < n; i++) {
        cost += (uint64_t)(n - 1 - i) + ROW_OVERHEAD_TESTS;
        if (cost >= share * (uint64_t)(b + 1) && b + 1 < wanted && i + 1 < n) {
            e->blocks[b].row_end = i + 1;
            e->blocks[++b].row_begin = i + 1;
        }
    }
    e->blocks[b].row_end = n;
    e->block_count = b + 1;
    e->planned_n = n;
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

void bpx__list_free(bpx_pair_list *list)
{
    bpx__free(list->pairs, list->capacity * sizeof(bpx_pair));
    *list = (bpx_pair_list){0};
}

bpx_status bpx__emitter_total(const bpx_emitter *e, size_t *total)
{
    size_t sum = 0;
    for (int b = 0; b < e->block_count; b++) {
        if (e->blocks[b].status != BPX_OK)
            return e->blocks[b].status;
        sum += e->blocks[b].hits.count;
    }
    *total = sum;
    return BPX_OK;
}

void bpx__emitter_merge(const bpx_emitter *e, bpx_pair *out)
{
    for (int b = 0; b < e->block_count; b++) {
        const bpx_block *block = &e->blocks[b];
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

// Insertion sort by (i, j) of pairs already in i order: only runs of equal i move. False when
// the moves pass max_moves (the pairs are then a permutation of what they were).
static bool sort_runs_by_j(bpx_pair *p, size_t count, uint64_t max_moves)
{
    uint64_t moves = 0;
    for (size_t k = 1; k < count; k++) {
        bpx_pair x = p[k];
        size_t at = k;
        while (at > 0 && p[at - 1].i == x.i && p[at - 1].j > x.j) {
            p[at] = p[at - 1];
            at--;
        }
        p[at] = x;
        moves += k - at;
        if (moves > max_moves)
            return false;
    }
    return true;
}

bpx_status bpx__emitter_sort_blocks(bpx_emitter *e, uint32_t n, bpx_pair_list *a, bpx_pair_list *b,
                                    uint32_t *counts)
{
    size_t total = 0;
    bpx_status status = bpx__emitter_total(e, &total);
    if (status != BPX_OK)
        return status;
    if (total > UINT32_MAX)
        return BPX_ERR_TOO_MANY_PAIRS; // the counting sort's offsets are 32-bit
    a->count = b->count = 0;
    // Headroom: the three lists that take turns here (a, b and block 0's) settle in a few
    // cycles even when the pair count drifts up.
    if (!bpx__list_reserve(a, total + total / 2) || !bpx__list_reserve(b, total + total / 2))
        return BPX_ERR_OUT_OF_MEMORY;
    bpx__emitter_merge(e, a->pairs);
    // (i, j) order. By i into b, then each run of equal i put in j order by insertion: runs are
    // a box's few partners, so that pass is about linear and one counting sort (a pass over n
    // counts, serial) is saved: the two were 8% of prune's cycle at n = 200 (perf, Table 2's
    // scenario). When a run is long (a big box meeting many) the moves pass a budget and the two
    // stable counting sorts (by j, then by i) run instead. Either way the result is the one
    // sorted set.
    counting_sort(a->pairs, b->pairs, total, n, counts, true);
    if (sort_runs_by_j(b->pairs, total, 4 * (uint64_t)total + 64)) {
        bpx_pair_list t = *a;
        *a = *b;
        *b = t;
    } else {
        counting_sort(a->pairs, b->pairs, total, n, counts, false);
        counting_sort(b->pairs, a->pairs, total, n, counts, true);
    }
    a->count = total;

    // Block 0 takes the ordered list (a swap, not a copy); its old list becomes scratch.
    uint64_t tests = 0;
    for (int k = 0; k < e->block_count; k++) {
        tests += e->blocks[k].tests;
        e->blocks[k].hits.count = 0;
        e->blocks[k].tests = 0;
    }
    bpx_pair_list block0 = e->blocks[0].hits;
    e->blocks[0].hits = *a;
    e->blocks[0].tests = tests;
    *a = block0;
    return BPX_OK;
}

void bpx__emitter_release(bpx_emitter *e)
{
    for (int b = 0; b < e->block_capacity; b++) {
        bpx__list_free(&e->blocks[b].hits);
        bpx__list_free(&e->blocks[b].stage);
        e->blocks[b].status = BPX_OK;
    }
}

void bpx__emitter_free(bpx_emitter *e)
{
    for (int b = 0; b < e->block_capacity; b++) {
        bpx__list_free(&e->blocks[b].hits);
        bpx__list_free(&e->blocks[b].stage);
    }
    bpx__free(e->blocks, sizeof(bpx_block) * (size_t)e->block_capacity);
    e->blocks = NULL;
    e->block_capacity = e->block_count = 0;
}
