// The grid backend: a uniform grid of columns in (y, z), each column swept along x, for
// millions of boxes; big boxes apart.
//
// Why: at constant density the candidates of one sweep over the whole scene grow like
// n^(5/3) (a box meets the whole slab of boxes whose x intervals meet its own). Cutting the
// scene into columns no wider than a box's reach in y and z leaves each sweep a near
// one-dimensional problem, so candidates grow like n. Why columns and not cells: a sweep reads
// sorted, contiguous memory (the prune kernel as is), where cell-by-cell neighbour lookups
// are random reads that miss the cache at millions of boxes.
//
// Each cycle:
//  1. Sizes. A box's size is its largest extent. Boxes up to 4 x the median size are "small";
//     the column side is just over the largest small size, so a small box spans at most 2 x 2
//     columns, and two overlapping boxes share at least one.
//  2. Every small box is entered in each column it spans: a counting sort by column (entries
//     carry the box, so the scatter is the only random access), then each column sorted by
//     min x on its own (small, cache-resident), then written out as SoA runs, each ended by a
//     sentinel (min x = +inf).
//  3. The prune kernel sweeps every run (the kernel stops at the sentinel). A pair sharing
//     several columns is found in each: duplicates are dropped after the pairs are sorted.
//  4. Big boxes (a few huge among many small) are laid out first, ahead of every small box,
//     and the brute kernel tests each of their rows against everything after it.
//  5. Hits go to (i, j) order (emitter.c), duplicates out. Every test is the exact float
//     comparison of overlap.h; the grid only decides which pairs are tested.
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/world.h"
#include "kernels.h"
#include "sort.h"

enum {
    SAMPLE = 1023,        // sizes sampled for the median
    ROWS_PER_BLOCK = 2048, // sweep rows per work item
    BIG_ROWS_PER_BLOCK = 8,
    PAD = BPX_PAD_LANES,
};

// One entry of a column: the box itself travels with its id, so sorting never gathers.
typedef struct grid_entry {
    float lo[3], hi[3];
    uint32_t key;    // bpx__float_key(lo x): the sweep order
    uint32_t id;
    uint32_t column; // y column * z columns + z column
    uint32_t unused;
} grid_entry;

typedef struct grid_state {
    // Entries grouped by column, then the runs in SoA form.
    size_t entry_capacity;
    grid_entry *entries;
    grid_entry *scratch; // radix sort ping-pong
    size_t scratch_capacity;
    uint8_t *class_of; // per box: 0 inert, 1 small, 2 big
    size_t class_capacity;
    uint32_t *column_start; // columns + 1
    size_t column_capacity;
    size_t run_capacity; // floats per SoA array: entries + one sentinel per run + PAD
    float *lo[3], *hi[3];
    uint32_t *run_ids;
    size_t run_length; // positions used this cycle

    // Big boxes first, then all small ones (positions for the brute kernel).
    uint32_t layout_capacity;
    float *blo[3], *bhi[3];
    uint32_t *layout_ids;
    uint32_t big_count, small_count;

    uint32_t *counts; // n + 1
    uint32_t counts_capacity;
    bpx_pair_list a, b;
    int sweep_blocks;
    size_t most_block_hits; // the largest block's hits last cycle
} grid_state;

static void free_entries(grid_state *st)
{
    bpx__free(st->entries, st->entry_capacity * sizeof(grid_entry));
    bpx__free(st->scratch, st->scratch_capacity * sizeof(grid_entry));
    st->scratch = NULL;
    st->scratch_capacity = 0;
    bpx__free(st->class_of, st->class_capacity);
    bpx__free(st->column_start, st->column_capacity * sizeof(uint32_t));
    st->entries = NULL;
    st->class_of = NULL;
    st->column_start = NULL;
    st->entry_capacity = st->column_capacity = 0;
    st->class_capacity = 0;
}

static void free_runs(grid_state *st)
{
    for (int a = 0; a < 3; a++) {
        bpx__free(st->lo[a], st->run_capacity * sizeof(float));
        bpx__free(st->hi[a], st->run_capacity * sizeof(float));
        st->lo[a] = st->hi[a] = NULL;
    }
    bpx__free(st->run_ids, st->run_capacity * sizeof(uint32_t));
    st->run_ids = NULL;
    st->run_capacity = 0;
}

static void free_layout(grid_state *st)
{
    size_t cap = (size_t)st->layout_capacity + 2 * PAD;
    for (int a = 0; a < 3; a++) {
        bpx__free(st->blo[a], cap * sizeof(float));
        bpx__free(st->bhi[a], cap * sizeof(float));
        st->blo[a] = st->bhi[a] = NULL;
    }
    bpx__free(st->layout_ids, cap * sizeof(uint32_t));
    st->layout_ids = NULL;
    st->layout_capacity = 0;
}

static void grid_destroy(bpx_world *w)
{
    grid_state *st = w->backend_state;
    if (!st)
        return;
    free_entries(st);
    free_runs(st);
    free_layout(st);
    bpx__free(st->counts, ((size_t)st->counts_capacity + 1) * sizeof(uint32_t));
    bpx__free(st->a.pairs, st->a.capacity * sizeof(bpx_pair));
    bpx__free(st->b.pairs, st->b.capacity * sizeof(bpx_pair));
    bpx__free(st, sizeof *st);
    w->backend_state = NULL;
}

// Makes *array hold at least `need` elements of `size` bytes (contents not kept; grows by half
// again, so it settles after a few cycles). Never zero-sized, so NULL means no memory.
static bool reserve_array(void **array, size_t *capacity, size_t need, size_t size)
{
    if (need <= *capacity && *array)
        return true;
    bpx__free(*array, *capacity * size);
    *capacity = need + need / 2 + 64;
    *array = bpx__alloc(*capacity * size);
    if (!*array)
        *capacity = 0;
    return *array != NULL;
}

static bool reserve_runs(grid_state *st, size_t floats)
{
    if (floats <= st->run_capacity && st->run_ids)
        return true;
    free_runs(st);
    size_t cap = floats + floats / 2 + 64;
    bool ok = true;
    for (int a = 0; a < 3; a++) {
        ok &= (st->lo[a] = bpx__alloc(cap * sizeof(float))) != NULL;
        ok &= (st->hi[a] = bpx__alloc(cap * sizeof(float))) != NULL;
    }
    ok &= (st->run_ids = bpx__alloc(cap * sizeof(uint32_t))) != NULL;
    st->run_capacity = cap;
    if (!ok)
        free_runs(st);
    return ok;
}

static bool reserve_layout(grid_state *st, uint32_t n)
{
    if (n <= st->layout_capacity && st->layout_ids)
        return true;
    free_layout(st);
    size_t cap = (size_t)n + 2 * PAD;
    bool ok = true;
    for (int a = 0; a < 3; a++) {
        ok &= (st->blo[a] = bpx__alloc(cap * sizeof(float))) != NULL;
        ok &= (st->bhi[a] = bpx__alloc(cap * sizeof(float))) != NULL;
    }
    ok &= (st->layout_ids = bpx__alloc(cap * sizeof(uint32_t))) != NULL;
    st->layout_capacity = n;
    if (!ok)
        free_layout(st);
    return ok;
}

static int compare_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static float box_size(const bpx_soa *s, uint32_t i)
{
    float e = s->hi[0][i] - s->lo[0][i];
    for (int a = 1; a < 3; a++) {
        float d = s->hi[a][i] - s->lo[a][i];
        e = d > e ? d : e;
    }
    return e;
}

// Removed ids hold inert boxes (min +inf > max -inf): they take no part.
static bool is_inert(const bpx_soa *s, uint32_t i)
{
    return !(s->lo[0][i] <= s->hi[0][i]);
}

// One stable counting-sort pass of src into dst by digit(entry) in [0, buckets).
#define GRID_SCATTER(src, dst, count, counts, buckets, digit)                                      \
    do {                                                                                           \
        memset(counts, 0, sizeof(uint32_t) * ((buckets) + 1));                                     \
        for (size_t k_ = 0; k_ < (count); k_++) {                                                  \
            const grid_entry *e = &(src)[k_];                                                      \
            counts[(digit) + 1]++;                                                                 \
        }                                                                                          \
        for (size_t b_ = 0; b_ < (buckets); b_++)                                                  \
            counts[b_ + 1] += counts[b_];                                                          \
        for (size_t k_ = 0; k_ < (count); k_++) {                                                  \
            const grid_entry *e = &(src)[k_];                                                      \
            (dst)[counts[(digit)]++] = *e;                                                         \
        }                                                                                          \
    } while (0)

// Orders entries by (column, min x), ties by id: LSD passes over min x (3 x 11 bits), then the
// z column, then the y column; entries come in id order and every pass is stable. Few buckets
// per pass keep the scatter cache-friendly (one pass over all columns would not be).
static void sort_entries(grid_state *st, size_t count, uint32_t zdim, uint32_t ydim,
                         uint32_t *counts)
{
    grid_entry *a = st->entries, *b = st->scratch;
    for (int shift = 0; shift < 32; shift += 11) {
        GRID_SCATTER(a, b, count, counts, 2048u, (e->key >> shift) & 2047u);
        grid_entry *t = a;
        a = b;
        b = t;
    }
    GRID_SCATTER(a, b, count, counts, zdim, e->column % zdim);
    GRID_SCATTER(b, a, count, counts, ydim, e->column / zdim);
    st->entries = a; // five passes: the result is in the other array than it started
    st->scratch = b;
    size_t t = st->entry_capacity;
    st->entry_capacity = st->scratch_capacity;
    st->scratch_capacity = t;
}

static void put_sentinels(float *lo[3], float *hi[3], uint32_t *ids, size_t at, size_t count)
{
    for (size_t k = at; k < at + count; k++) {
        for (int a = 0; a < 3; a++) {
            lo[a][k] = INFINITY;
            hi[a][k] = -INFINITY;
        }
        ids[k] = 0;
    }
}

// The column range of a box on one axis (clamped to the grid, so monotone in the input).
static inline void column_range(float lo, float hi, double origin, double inv, uint32_t top,
                                uint32_t *from, uint32_t *to)
{
    double a = floor(((double)lo - origin) * inv), b = floor(((double)hi - origin) * inv);
    *from = (uint32_t)fmin(fmax(a, 0.0), (double)top);
    *to = (uint32_t)fmin(fmax(b, 0.0), (double)top);
}

// Steps 1 to 3's layout. Returns false when memory ran out.
static bool build(const bpx_soa *s, grid_state *st)
{
    uint32_t n = s->n;
    float sample[SAMPLE];
    uint32_t taken = 0, stride = n / SAMPLE + 1;
    for (uint32_t i = 0; i < n && taken < SAMPLE; i += stride)
        if (!is_inert(s, i))
            sample[taken++] = box_size(s, i);
    qsort(sample, taken, sizeof(float), compare_float);
    float limit = taken ? 4.0f * sample[taken / 2] : 0.0f;

    if (!reserve_array((void **)&st->class_of, &st->class_capacity, n, 1))
        return false;
    float largest = 0.0f, lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    st->small_count = st->big_count = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (is_inert(s, i)) {
            st->class_of[i] = 0;
            continue;
        }
        float e = box_size(s, i);
        st->class_of[i] = e > limit ? 2 : 1;
        if (e > limit) {
            st->big_count++;
            continue;
        }
        st->small_count++;
        largest = e > largest ? e : largest;
        for (int a = 0; a < 2; a++) {
            lo[a] = fminf(lo[a], s->lo[a + 1][i]);
            hi[a] = fmaxf(hi[a], s->hi[a + 1][i]);
        }
    }
    // Columns just over the largest small box (so rounding cannot put a box across 3), and no
    // more of them than 4 per small box (so the column table stays O(n)).
    double origin[2], span[2];
    for (int a = 0; a < 2; a++) {
        origin[a] = st->small_count ? (double)lo[a] : 0.0;
        span[a] = st->small_count ? (double)hi[a] - (double)lo[a] : 0.0;
    }
    double budget = fmin(4.0 * st->small_count + 64.0, 65536.0); // also columns per axis
    double side = fmax((double)largest * 1.001, sqrt(span[0] * span[1] / budget));
    side = fmax(fmax(side, span[0] / budget), fmax(span[1] / budget, 1e-300));
    double inv = 1.0 / side;
    uint32_t dim[2];
    for (int a = 0; a < 2; a++)
        dim[a] = (uint32_t)fmin(floor(span[a] * inv) + 1.0, budget);

    // Entries in id order, each with its column; then sorted by (column, min x).
    size_t entries = 0;
    for (uint32_t i = 0; i < n; i++)
        if (st->class_of[i] == 1) {
            uint32_t y0, y1, z0, z1;
            column_range(s->lo[1][i], s->hi[1][i], origin[0], inv, dim[0] - 1, &y0, &y1);
            column_range(s->lo[2][i], s->hi[2][i], origin[1], inv, dim[1] - 1, &z0, &z1);
            entries += (size_t)(y1 - y0 + 1) * (z1 - z0 + 1);
        }
    uint32_t most_buckets = dim[0] > dim[1] ? dim[0] : dim[1];
    most_buckets = most_buckets > 2048 ? most_buckets : 2048;
    if (!reserve_array((void **)&st->entries, &st->entry_capacity, entries, sizeof(grid_entry)) ||
        !reserve_array((void **)&st->scratch, &st->scratch_capacity, entries,
                       sizeof(grid_entry)) ||
        !reserve_array((void **)&st->column_start, &st->column_capacity, most_buckets + 1,
                       sizeof(uint32_t)))
        return false;
    size_t at = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (st->class_of[i] != 1)
            continue;
        grid_entry e = {{s->lo[0][i], s->lo[1][i], s->lo[2][i]},
                        {s->hi[0][i], s->hi[1][i], s->hi[2][i]},
                        bpx__float_key(s->lo[0][i]),
                        i,
                        0,
                        0};
        uint32_t y0, y1, z0, z1;
        column_range(e.lo[1], e.hi[1], origin[0], inv, dim[0] - 1, &y0, &y1);
        column_range(e.lo[2], e.hi[2], origin[1], inv, dim[1] - 1, &z0, &z1);
        for (uint32_t y = y0; y <= y1; y++)
            for (uint32_t z = z0; z <= z1; z++) {
                e.column = y * dim[1] + z;
                st->entries[at++] = e;
            }
    }
    sort_entries(st, entries, dim[1], dim[0], st->column_start);

    // The runs, a sentinel after each column.
    size_t runs = 0;
    for (size_t k = 0; k < entries; k++)
        runs += k == 0 || st->entries[k].column != st->entries[k - 1].column;
    if (!reserve_runs(st, entries + runs + PAD))
        return false;
    at = 0;
    for (size_t k = 0; k < entries; k++) {
        if (k > 0 && st->entries[k].column != st->entries[k - 1].column)
            put_sentinels(st->lo, st->hi, st->run_ids, at++, 1);
        for (int a = 0; a < 3; a++) {
            st->lo[a][at] = st->entries[k].lo[a];
            st->hi[a][at] = st->entries[k].hi[a];
        }
        st->run_ids[at++] = st->entries[k].id;
    }
    if (entries)
        put_sentinels(st->lo, st->hi, st->run_ids, at++, 1);
    put_sentinels(st->lo, st->hi, st->run_ids, at, PAD);
    st->run_length = at;

    // Big boxes first, then every small box, for the brute kernel.
    if (st->big_count) {
        if (!reserve_layout(st, n))
            return false;
        uint32_t big_at = 0, small_at = st->big_count;
        for (uint32_t i = 0; i < n; i++) {
            if (st->class_of[i] == 0)
                continue;
            uint32_t p = st->class_of[i] == 2 ? big_at++ : small_at++;
            for (int a = 0; a < 3; a++) {
                st->blo[a][p] = s->lo[a][i];
                st->bhi[a][p] = s->hi[a][i];
            }
            st->layout_ids[p] = i;
        }
        put_sentinels(st->blo, st->bhi, st->layout_ids, small_at, 2 * PAD);
    }
    return true;
}

typedef struct grid_job {
    bpx_world *world;
    grid_state *st;
    bpx_sorted runs;
    bpx_soa layout;
    bpx_prune_rows_fn *sweep;
    bpx_brute_rows_fn *brute;
} grid_job;

static void grid_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    grid_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->world->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        if (b < job->st->sweep_blocks) {
            job->sweep(&job->runs, block->row_begin, block->row_end, block);
            continue;
        }
        // Brute rows give layout positions: map them to ids.
        job->brute(&job->layout, block->row_begin, block->row_end, block);
        const uint32_t *ids = job->st->layout_ids;
        for (size_t k = 0; k < block->hits.count; k++) {
            uint32_t i = ids[block->hits.pairs[k].i], j = ids[block->hits.pairs[k].j];
            block->hits.pairs[k] = i < j ? (bpx_pair){i, j} : (bpx_pair){j, i};
        }
    }
}

static bpx_status grid_compare(bpx_world *w)
{
    grid_state *st = w->backend_state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (grid_state){0};
        w->backend_state = st;
    }

    if (w->n > st->counts_capacity || !st->counts) {
        bpx__free(st->counts, ((size_t)st->counts_capacity + 1) * sizeof(uint32_t));
        st->counts_capacity = w->n;
        if (!(st->counts = bpx__alloc(((size_t)w->n + 1) * sizeof(uint32_t))))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    bpx_soa soa = bpx__world_soa(w);
    if (!build(&soa, st))
        return BPX_ERR_OUT_OF_MEMORY;

    // Work items: runs of sweep rows, then runs of big-box rows; laid out anew each cycle
    // (the output order never depends on it).
    uint32_t sweep_rows = (uint32_t)st->run_length;
    st->sweep_blocks = (int)((sweep_rows + ROWS_PER_BLOCK - 1) / ROWS_PER_BLOCK);
    int big_blocks = (int)((st->big_count + BIG_ROWS_PER_BLOCK - 1) / BIG_ROWS_PER_BLOCK);
    int blocks = st->sweep_blocks + big_blocks;
    if (blocks == 0)
        blocks = 1; // an empty block 0 carries the (empty) result
    bpx_status status = bpx__emitter_reserve_blocks(w, blocks);
    if (status != BPX_OK)
        return status;
    for (int b = 0; b < blocks; b++) {
        bool sweep = b < st->sweep_blocks;
        uint32_t per = sweep ? ROWS_PER_BLOCK : BIG_ROWS_PER_BLOCK;
        uint32_t limit = sweep ? sweep_rows : st->big_count;
        uint32_t first = (uint32_t)(sweep ? b : b - st->sweep_blocks) * per;
        w->blocks[b].row_begin = first < limit ? first : limit;
        w->blocks[b].row_end = first + per < limit ? first + per : limit;
    }
    w->block_count = blocks;
    w->planned_n = UINT32_MAX; // the layout is this backend's own

    // Blocks cover different rows each cycle; give every one room for twice the largest
    // block's hits of the last cycle, so the sweep does not grow lists as the scene drifts.
    for (int b = 0; b < blocks; b++)
        if (!bpx__list_reserve(&w->blocks[b].hits, 2 * st->most_block_hits))
            return BPX_ERR_OUT_OF_MEMORY;

    grid_job job = {
        w,
        st,
        {{st->lo[0], st->lo[1], st->lo[2]},
         {st->hi[0], st->hi[1], st->hi[2]},
         st->run_ids,
         (uint32_t)st->run_length},
        {{st->blo[0], st->blo[1], st->blo[2]},
         {st->bhi[0], st->bhi[1], st->bhi[2]},
         st->big_count + st->small_count},
        bpx__prune_rows_for(w->simd),
        bpx__brute_rows_for(w->simd),
    };
    bpx__parallel_for(&w->executor, grid_task, blocks, &job);
    st->most_block_hits = 0;
    for (int b = 0; b < blocks; b++)
        if (w->blocks[b].hits.count > st->most_block_hits)
            st->most_block_hits = w->blocks[b].hits.count;
    status = bpx__emitter_sort_blocks(w, &st->a, &st->b, st->counts);
    if (status != BPX_OK)
        return status;

    // A pair sharing several columns was found in each: keep one of each.
    bpx_pair_list *out = &w->blocks[0].hits;
    size_t kept = 0;
    for (size_t k = 0; k < out->count; k++)
        if (kept == 0 || out->pairs[k].i != out->pairs[kept - 1].i ||
            out->pairs[k].j != out->pairs[kept - 1].j)
            out->pairs[kept++] = out->pairs[k];
    out->count = kept;
    return BPX_OK;
}

static bool grid_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size, "columns in y, z swept along x, big boxes apart, %s, threads",
             bpx_simd_name(simd));
    return true;
}

const bpx_backend_impl bpx__grid_backend = {
    .id = BPX_BACKEND_GRID,
    .name = "grid",
    .query = grid_query,
    .compare = grid_compare,
    .destroy = grid_destroy,
};
