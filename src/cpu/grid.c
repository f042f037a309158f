// The grid backend: a hierarchical grid of columns in (y, z), each a run sorted along x, for
// millions of boxes; the few biggest boxes apart. Linear in n at constant density.
//
// Why: at constant density the candidates of one sweep over the whole scene grow like n^(5/3)
// (a box meets the whole slab of boxes whose x intervals meet its own). Columns no wider than a
// box leave each box a handful of short, sorted, contiguous runs to test (SIMD, no hashing).
//
// Each cycle, every pass but the small serial ones split over the workers:
//  1. Parameters (serial, from a sample and last cycle's exact bounds): the level-0 cell side s
//     is the largest box size that keeps about GRID_WINDOW_BOXES boxes per window at the scene's
//     density (all boxes when sizes are even; the bulk when they are heavy-tailed), and no more
//     columns than about one per GRID_BOXES_PER_COLUMN boxes.
//  2. Keys: each box's cells (q = floor((v - origin) / s), clamped: monotone in v, which is all
//     the tests' reasoning needs, so any float input is safe), its level (the first at which it
//     spans at most 2 cells per axis; level l has cells 4^l s), the 1 to 4 columns ((y, z)
//     cells at that level) it covers, 16 boxes at a time in vectors (grid_kernel.h); per-chunk
//     histograms of columns.
//  3. Levels: the top levels holding few boxes become "big" boxes, tested against all (the
//     rest never look for them); the others get columns: a prefix of the histograms.
//  4. Scatter: each box (coordinates, id, x cell, flags) to its columns, 32 bytes an entry;
//     two entries of a column that share a cache line go out together as one streamed line
//     (the second waits in a small per-worker stash), so no line is read before it is written.
//  5. Per column: a counting sort on the x cell, mended by insertion sort on min x (radix when
//     that gives up), written out as SoA runs.
//  6. Tests (grid_kernel.h): each box against the rest of its run, and from its home column
//     against windows of the columns it covers at each coarser level; big boxes against all.
//     A pair met in several columns is kept in one (a rule on the flags), so no dedupe pass.
//  7. Hits to (i, j) order: a scatter by i / 2048 into buckets, then in cache each bucket by
//     i (a counting pass) and each i's few pairs by j; the result goes to block 0. Every test
//     is the exact float comparison of overlap.h; the grid only decides which pairs are tested,
//     and the order is a full sort, so the bytes are the same for any worker count or schedule.
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/alloc.h"
#include "core/world.h"
#include "cpu_features.h"
#include "grid.h"
#include "kernels.h"
#include "sort.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

enum {
    SAMPLE = 1023,            // boxes sampled for sizes (and first-cycle bounds)
    GRID_SWEEP_BOXES = 8,     // boxes one sweep should meet at the scene's density
    GRID_CELL_SIZES = 3,      // cell side / box size
    GRID_BOXES_PER_COLUMN = 16,
    CHUNKS_MAX = 64,          // box ranges of the key and scatter passes
    ITEM_ENTRIES = 4096,      // positions per test item (at least)
    ITEMS_MAX = 512,
    KEY_BLOCK = 1024,         // boxes keyed in vectors, then counted, while in cache
    BIG_SPAN = 1 << 14,       // ids per big-box work item (all big boxes against them)
    BIG_STEP = 2048,          // ids in cache at a time while every big box passes over them
    EMIT_SHIFT = 11,          // at most 2^11 ids per bucket of pairs, 11-bit sort digits
    EMIT_BUCKET_PAIRS = 8192, // pairs per bucket wanted (the in-cache sort)
    EMIT_GROUPS = 64,
    EMIT_ITEMS = 256,
    PAD = BPX_PAD_LANES,
    LEVELS = BPX_GRID_LEVELS,
    WORKERS_MAX = 256, // bpx_world_def.worker_count's range
};

// A box on its way to its column.
typedef struct grid_entry {
    float lo[3], hi[3];
    uint32_t id;
    uint32_t fx; // fine x cell of min x | flags << 24
} grid_entry;

typedef struct grid_params {
    float origin[3], inv[3];
    uint32_t top[3]; // largest cell coordinate per axis (on x, of the fine cells)
    int fine_bits;   // x is cut 2^fine_bits times finer than the cells, for the column sort
    uint32_t columns;
} grid_params;

// Sorted runs in SoA form, with the sort's scratch; `capacity` positions (padding included).
typedef struct grid_soa {
    float *lo[3], *hi[3];
    uint32_t *id, *cx, *keys, *ids, *scratch_keys, *scratch_ids;
    uint8_t *flags;
    size_t capacity;
} grid_soa;

typedef struct grid_chunk {
    uint32_t begin, end;
    uint32_t level_count[LEVELS];
    float lo_min[3], lo_max[3];
    float max_extent;
} grid_chunk;

typedef struct grid_state {
    // Last cycle's exact figures, for this cycle's parameters.
    bool have_stats;
    float bounds_lo[3], bounds_hi[3];
    float max_extent;

    grid_params params;
    bpx_grid_layout layout;
    grid_chunk chunks[CHUNKS_MAX];
    int chunk_count;

    uint32_t *key; // per box id (padded to a whole group for the big kernel)
    size_t key_capacity;
    uint32_t *hist; // chunk x column: counts, then write offsets
    size_t hist_capacity;
    uint32_t *column_start;
    size_t column_capacity;
    grid_entry *entries;
    size_t entry_capacity;
    // Scatter's write-combining, per worker: a column's entry waiting for the other half of its
    // cache line, and the position it goes to.
    grid_entry *stash;
    size_t stash_capacity;
    uint32_t wcolumns; // columns of the windowed levels
    uint32_t *stash_at;
    size_t stash_at_capacity;
    // Positions of the coarser levels' runs (level 0's are sorted in the workers' scratch).
    grid_soa positions;
    grid_soa scratch[WORKERS_MAX];
    int scratch_count;
    uint32_t *big_ids;
    size_t big_capacity;
    uint32_t item_column[ITEMS_MAX + 1];
    int item_count, big_items;
    uint32_t big_parts; // work items of the big boxes, BIG_SPAN ids each

    // Emitter.
    bpx_pair_list a, b;
    uint32_t *emit_hist; // groups x buckets
    size_t emit_hist_capacity;
    uint32_t *bucket_start;
    size_t bucket_capacity;
    size_t *block_hits; // last cycle's hits per block
    size_t block_hits_capacity;
} grid_state;

// ---------------------------------------------------------------------------------------------
// Memory

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

static void free_soa(grid_soa *r)
{
    size_t cap = r->capacity;
    for (int a = 0; a < 3; a++) {
        bpx__free(r->lo[a], cap * sizeof(float));
        bpx__free(r->hi[a], cap * sizeof(float));
    }
    uint32_t *u32s[] = {r->id, r->cx, r->keys, r->ids, r->scratch_keys, r->scratch_ids};
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++)
        bpx__free(u32s[k], cap * sizeof(uint32_t));
    bpx__free(r->flags, cap);
    *r = (grid_soa){0};
}

static bool reserve_soa(grid_soa *r, size_t need)
{
    if (need <= r->capacity && r->id)
        return true;
    free_soa(r);
    size_t cap = need + need / 2 + 64;
    bool ok = true;
    for (int a = 0; a < 3; a++) {
        ok &= (r->lo[a] = bpx__alloc(cap * sizeof(float))) != NULL;
        ok &= (r->hi[a] = bpx__alloc(cap * sizeof(float))) != NULL;
    }
    uint32_t **u32s[] = {&r->id, &r->cx, &r->keys, &r->ids, &r->scratch_keys, &r->scratch_ids};
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++)
        ok &= (*u32s[k] = bpx__alloc(cap * sizeof(uint32_t))) != NULL;
    ok &= (r->flags = bpx__alloc(cap)) != NULL;
    r->capacity = cap;
    if (!ok)
        free_soa(r);
    return ok;
}

// Sentinels after a run: never in reach (min x +inf), never overlapping.
static void pad_soa(grid_soa *r, size_t at)
{
    for (size_t k = at; k < at + PAD; k++) {
        for (int a = 0; a < 3; a++) {
            r->lo[a][k] = INFINITY;
            r->hi[a][k] = -INFINITY;
        }
        r->id[k] = 0;
        r->cx[k] = UINT32_MAX;
        r->flags[k] = 0;
    }
}

void bpx__grid_free(void **state)
{
    grid_state *st = *state;
    if (!st)
        return;
    free_soa(&st->positions);
    for (int k = 0; k < WORKERS_MAX; k++)
        free_soa(&st->scratch[k]);
    bpx__free(st->key, st->key_capacity * sizeof(uint32_t));
    bpx__free(st->hist, st->hist_capacity * sizeof(uint32_t));
    bpx__free(st->column_start, st->column_capacity * sizeof(uint32_t));
    bpx__free(st->entries, st->entry_capacity * sizeof(grid_entry));
    bpx__free(st->stash, st->stash_capacity * sizeof(grid_entry));
    bpx__free(st->stash_at, st->stash_at_capacity * sizeof(uint32_t));
    bpx__free(st->big_ids, st->big_capacity * sizeof(uint32_t));
    bpx__free(st->a.pairs, st->a.capacity * sizeof(bpx_pair));
    bpx__free(st->b.pairs, st->b.capacity * sizeof(bpx_pair));
    bpx__free(st->emit_hist, st->emit_hist_capacity * sizeof(uint32_t));
    bpx__free(st->bucket_start, st->bucket_capacity * sizeof(uint32_t));
    bpx__free(st->block_hits, st->block_hits_capacity * sizeof(size_t));
    bpx__free(st, sizeof *st);
    *state = NULL;
}

void bpx__grid_forget(void *state)
{
    if (state)
        ((grid_state *)state)->have_stats = false;
}

static void grid_destroy(bpx_world *w)
{
    bpx__grid_free(&w->backend_state);
}

// ---------------------------------------------------------------------------------------------
// Kernels per instruction set (grid_<isa>.c), chosen at run time like brute's.

#define GRID_DECLARE(isa)                                                                          \
    bpx_grid_column_fn bpx__grid_column_##isa;                                                     \
    bpx_grid_big_fn bpx__grid_big_##isa;                                                           \
    bpx_grid_keys_fn bpx__grid_keys_##isa;
GRID_DECLARE(scalar)
#if BPX_HAVE_SSE2
GRID_DECLARE(sse2)
#endif
#if BPX_HAVE_AVX2
GRID_DECLARE(avx2)
#endif
#if BPX_HAVE_AVX512
GRID_DECLARE(avx512)
#endif
#if BPX_HAVE_NEON
GRID_DECLARE(neon)
#endif

typedef struct grid_kernels {
    bpx_grid_column_fn *column;
    bpx_grid_big_fn *big;
    bpx_grid_keys_fn *keys;
} grid_kernels;

static grid_kernels kernels_for(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        simd = bpx_simd_best();
    if (!bpx_simd_supported(simd))
        simd = BPX_SIMD_SCALAR;
    switch (simd) {
#if BPX_HAVE_SSE2
    case BPX_SIMD_SSE2:
        return (grid_kernels){bpx__grid_column_sse2, bpx__grid_big_sse2, bpx__grid_keys_sse2};
#endif
#if BPX_HAVE_AVX2
    case BPX_SIMD_AVX2:
        return (grid_kernels){bpx__grid_column_avx2, bpx__grid_big_avx2, bpx__grid_keys_avx2};
#endif
#if BPX_HAVE_AVX512
    case BPX_SIMD_AVX512:
        return (grid_kernels){bpx__grid_column_avx512, bpx__grid_big_avx512, bpx__grid_keys_avx512};
#endif
#if BPX_HAVE_NEON
    case BPX_SIMD_NEON:
        return (grid_kernels){bpx__grid_column_neon, bpx__grid_big_neon, bpx__grid_keys_neon};
#endif
    default:
        return (grid_kernels){bpx__grid_column_scalar, bpx__grid_big_scalar, bpx__grid_keys_scalar};
    }
}

// ---------------------------------------------------------------------------------------------
// 1. Parameters

// Removed ids hold inert boxes (min +inf > max -inf): they take no part.
static inline bool is_inert(const bpx_soa *s, uint32_t i)
{
    return !(s->lo[0][i] <= s->hi[0][i]);
}

static inline float box_size(const bpx_soa *s, uint32_t i)
{
    float e = s->hi[0][i] - s->lo[0][i];
    for (int a = 1; a < 3; a++) {
        float d = s->hi[a][i] - s->lo[a][i];
        e = d > e ? d : e;
    }
    return e;
}

static void sort_floats(float *v, uint32_t count)
{
    for (uint32_t k = 1; k < count; k++) {
        float x = v[k];
        uint32_t at = k;
        for (; at > 0 && v[at - 1] > x; at--)
            v[at] = v[at - 1];
        v[at] = x;
    }
}

static void choose_params(const bpx_soa *s, grid_state *st, grid_params *p)
{
    uint32_t n = s->n;
    float sample[SAMPLE];
    float lo_min[3] = {INFINITY, INFINITY, INFINITY}, lo_max[3] = {-INFINITY, -INFINITY, -INFINITY};
    uint32_t taken = 0, stride = n / SAMPLE + 1;
    for (uint32_t i = 0; i < n && taken < SAMPLE; i += stride) {
        if (is_inert(s, i))
            continue;
        sample[taken++] = box_size(s, i);
        for (int a = 0; a < 3; a++) {
            lo_min[a] = fminf(lo_min[a], s->lo[a][i]);
            lo_max[a] = fmaxf(lo_max[a], s->lo[a][i]);
        }
    }
    if (st->have_stats)
        for (int a = 0; a < 3; a++) {
            lo_min[a] = st->bounds_lo[a];
            lo_max[a] = st->bounds_hi[a];
        }
    if (!taken || !(lo_min[0] <= lo_max[0])) { // nothing live: any grid will do
        for (int a = 0; a < 3; a++)
            lo_min[a] = lo_max[a] = 0.0f;
        sample[taken++] = 1.0f;
    }
    sort_floats(sample, taken);

    // Cells GRID_CELL_SIZES times the largest box size that keeps about GRID_SWEEP_BOXES boxes
    // in one sweep (a column's cross-section, (s + e)^2, times an x reach e, the median size)
    // at the scene's density; at least that times the median size.
    double span[3], volume = 1.0, median = (double)sample[taken / 2];
    for (int a = 0; a < 3; a++) {
        span[a] = (double)lo_max[a] - (double)lo_min[a];
        volume *= fmax(span[a], median);
    }
    double density = volume > 0.0 ? (double)(n ? n : 1) / volume : 0.0;
    double reach = fmax(median, 1e-30);
    double cap = density > 0.0 ? (sqrt(GRID_SWEEP_BOXES / (density * reach)) - reach) /
                                     GRID_CELL_SIZES
                               : INFINITY;
    double size = median;
    for (uint32_t k = taken; k-- > taken / 2;)
        if ((double)sample[k] <= cap) {
            size = (double)sample[k];
            break;
        }
    // Sizes even (the whole sample fits): last cycle's exact largest, so that no box goes up.
    if ((double)sample[taken - 1] <= cap && st->have_stats && (double)st->max_extent <= cap)
        size = fmax(size, (double)st->max_extent);
    double side = GRID_CELL_SIZES * size;
    // Cells representable (22 bits a coordinate), never zero, and not too many columns.
    for (int a = 0; a < 3; a++)
        side = fmax(side, span[a] / (double)(1u << (BPX_GRID_Q_BITS - 1)));
    side = fmax(side, 1e-30);
    double columns_max = fmin((double)(n / GRID_BOXES_PER_COLUMN) + 64.0, (double)(1u << 24));
    while ((floor(span[1] / side) + 1.0) * (floor(span[2] / side) + 1.0) > columns_max)
        side *= 1.25;

    float inv = (float)(1.0 / side);
    if (!(inv > 0.0f))
        inv = 1e-38f;
    for (int a = 0; a < 3; a++) {
        p->origin[a] = lo_min[a];
        p->inv[a] = inv;
        double top = floor(span[a] / side);
        p->top[a] = top < (double)((1u << BPX_GRID_Q_BITS) - 1)
                        ? (uint32_t)top
                        : (1u << BPX_GRID_Q_BITS) - 1;
    }
    // About 1024 fine x cells across the scene (exact power-of-two scaling, 24 bits at most).
    p->fine_bits = 0;
    while (p->fine_bits < 4 && (p->top[0] + 1) << (p->fine_bits + 1) <= 1024)
        p->fine_bits++;
    p->inv[0] = inv * (float)(1 << p->fine_bits);
    if (!(p->inv[0] < INFINITY))
        p->inv[0] = inv, p->fine_bits = 0;
    p->top[0] = ((p->top[0] + 1) << p->fine_bits) - 1;
}

// The cell of coordinate v on one axis: monotone in v (rounding is), clamped to [0, top].
static inline uint32_t cell_of(float v, float origin, float inv, uint32_t top)
{
    return bpx__grid_cell(v, origin, inv, (float)top); // exact: top < 2^24
}

static void set_levels(grid_state *st)
{
    const grid_params *p = &st->params;
    uint32_t first = 0;
    for (int l = 0; l < LEVELS; l++) {
        bpx_grid_level *lv = &st->layout.level[l];
        lv->first_column = first;
        lv->ny = (p->top[1] >> (2 * l)) + 1;
        lv->nz = (p->top[2] >> (2 * l)) + 1;
        first += lv->ny * lv->nz;
    }
    st->params.columns = first;
}

// ---------------------------------------------------------------------------------------------
// 2. Keys, 4. scatter (tasks over chunks of box ids)

typedef struct grid_job {
    bpx_world *world;
    grid_state *st;
    bpx_soa soa;
    bpx_grid_column_fn *column;
    bpx_grid_big_fn *big;
    bpx_grid_keys_fn *keys;
} grid_job;

static void key_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    grid_job *job = context;
    grid_state *st = job->st;
    const grid_params *p = &st->params;
    const bpx_grid_level *levels = st->layout.level;
    uint32_t columns = p->columns;
    bpx_grid_cells cells = {.fine_bits = p->fine_bits};
    for (int a = 0; a < 3; a++) {
        cells.origin[a] = p->origin[a];
        cells.inv[a] = p->inv[a];
        cells.top[a] = (float)p->top[a];
    }
    for (int l = 0; l < LEVELS; l++) {
        cells.first_column[l] = levels[l].first_column;
        cells.nz[l] = levels[l].nz;
    }
    for (int c = begin; c < end; c++) {
        grid_chunk *ch = &st->chunks[c];
        uint32_t *hist = st->hist + (size_t)c * columns;
        memset(hist, 0, sizeof(uint32_t) * columns);
        memset(ch->level_count, 0, sizeof ch->level_count);
        bpx_grid_seen seen = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, 0};
        // A block's keys in vectors, then its counts while the keys are in cache.
        for (uint32_t i0 = ch->begin; i0 < ch->end; i0 += KEY_BLOCK) {
            uint32_t i1 = i0 + KEY_BLOCK < ch->end ? i0 + KEY_BLOCK : ch->end;
            job->keys(&cells, &job->soa, i0, i1, st->key, &seen);
            for (uint32_t i = i0; i < i1; i++) {
                uint32_t key = st->key[i];
                if (key == BPX_GRID_INERT)
                    continue;
                uint32_t l = bpx__grid_key_level(key), column = bpx__grid_key_column(key);
                uint32_t dy = (key & BPX_GRID_SPAN_Y) != 0, dz = (key & BPX_GRID_SPAN_Z) != 0;
                uint32_t nz = levels[l].nz;
                hist[column]++;
                hist[column + dz] += dz;
                hist[column + dy * nz] += dy;
                hist[column + dy * nz + dz] += dy & dz;
                ch->level_count[l]++;
            }
        }
        for (int a = 0; a < 3; a++) {
            ch->lo_min[a] = seen.lo_min[a];
            ch->lo_max[a] = seen.lo_max[a];
        }
        ch->max_extent = seen.largest;
    }
}

// Entries are 32 bytes, positions 64-byte aligned in pairs: an entry at an even position waits
// in the stash until the odd one after it comes from the same chunk, and the two go out as one
// whole line, bypassing the cache (no read for ownership of a line about to be overwritten).
// Entries whose other half belongs to another chunk (a range's ends) are stored plainly.
static inline void put_line(grid_entry *to, const grid_entry *first, const grid_entry *second)
{
#if defined(__SSE2__)
    const __m128i *a = (const __m128i *)(const void *)first;
    const __m128i *b = (const __m128i *)(const void *)second;
    __m128i *d = (__m128i *)(void *)to;
    __m128i a0 = _mm_loadu_si128(a), a1 = _mm_loadu_si128(a + 1);
    __m128i b0 = _mm_loadu_si128(b), b1 = _mm_loadu_si128(b + 1);
    _mm_stream_si128(d, a0);
    _mm_stream_si128(d + 1, a1);
    _mm_stream_si128(d + 2, b0);
    _mm_stream_si128(d + 3, b1);
#else
    to[0] = *first;
    to[1] = *second;
#endif
}

static inline void put(grid_state *st, grid_entry *stash, uint32_t *stash_at, uint32_t column,
                       uint32_t at, const grid_entry *e)
{
    if (!(at & 1)) {
        stash[column] = *e;
        stash_at[column] = at;
    } else if (stash_at[column] == at - 1) {
        put_line(st->entries + at - 1, &stash[column], e);
    } else {
        st->entries[at] = *e;
    }
}

static void scatter_task(int begin, int end, int worker, void *context)
{
    grid_job *job = context;
    grid_state *st = job->st;
    const bpx_soa *s = &job->soa;
    const grid_params *p = &st->params;
    uint32_t windowed = (uint32_t)st->layout.windowed, columns = p->columns;
    uint32_t wcolumns = st->wcolumns;
    grid_entry *stash = st->stash + (size_t)worker * wcolumns;
    uint32_t *stash_at = st->stash_at + (size_t)worker * wcolumns;
    for (int c = begin; c < end; c++) {
        const grid_chunk *ch = &st->chunks[c];
        uint32_t *offset = st->hist + (size_t)c * columns;
        memset(stash_at, 0xff, sizeof(uint32_t) * wcolumns);
        for (uint32_t i = ch->begin; i < ch->end; i++) {
            uint32_t key = st->key[i];
            uint32_t l = bpx__grid_key_level(key);
            if (l >= windowed) // big or inert
                continue;
            float lx = s->lo[0][i];
            uint32_t cx = cell_of(lx, p->origin[0], p->inv[0], p->top[0]);
            uint32_t spans = (key & BPX_GRID_SPAN_Y ? BPX_GRID_SPANS_Y : 0) |
                             (key & BPX_GRID_SPAN_Z ? BPX_GRID_SPANS_Z : 0);
            grid_entry e = {{lx, s->lo[1][i], s->lo[2][i]},
                            {s->hi[0][i], s->hi[1][i], s->hi[2][i]},
                            i,
                            cx | (spans | BPX_GRID_HOME) << 24};
            uint32_t column = bpx__grid_key_column(key), nz = st->layout.level[l].nz;
            put(st, stash, stash_at, column, offset[column]++, &e);
            if (key & BPX_GRID_SPAN_Z) {
                e.fx = cx | (spans | BPX_GRID_FIRST_Y) << 24;
                put(st, stash, stash_at, column + 1, offset[column + 1]++, &e);
            }
            if (key & BPX_GRID_SPAN_Y) {
                e.fx = cx | (spans | BPX_GRID_FIRST_Z) << 24;
                put(st, stash, stash_at, column + nz, offset[column + nz]++, &e);
                if (key & BPX_GRID_SPAN_Z) {
                    e.fx = cx | spans << 24;
                    put(st, stash, stash_at, column + nz + 1, offset[column + nz + 1]++, &e);
                }
            }
        }
        // Entries still waiting: the last of their column's range, at an even position.
        for (uint32_t k = 0; k < wcolumns; k++)
            if (stash_at[k] != UINT32_MAX && stash_at[k] + 1 == offset[k])
                st->entries[stash_at[k]] = stash[k];
    }
#if defined(__SSE2__)
    _mm_sfence(); // the streamed lines are visible before the tests read them
#endif
}

// ---------------------------------------------------------------------------------------------
// 5. Per column: sort by min x, write the SoA run (tasks over items of columns)

// Sorts the m entries of a column by min x into r at offset `at`; x cells >> shift.
static void sort_column(const grid_entry *ent, uint32_t m, grid_soa *r, size_t at, int shift)
{
    uint32_t *keys = r->keys + at, *ids = r->ids + at;
    for (uint32_t t = 0; t < m; t++) {
        keys[t] = bpx__float_key(ent[t].lo[0]);
        ids[t] = t;
    }
    bool sorted = m <= 16 && bpx__insertion_sort(keys, ids, m, UINT64_MAX);
    if (!sorted) {
        // Fine x cells are min x quantised: bucketing on them leaves little to insertion sort.
        uint32_t low = UINT32_MAX, high = 0;
        for (uint32_t t = 0; t < m; t++) {
            uint32_t fx = ent[t].fx & 0xffffffu;
            low = fx < low ? fx : low;
            high = fx > high ? fx : high;
        }
        uint32_t range = high - low + 1;
        uint32_t *sk = r->scratch_keys + at, *si = r->scratch_ids + at;
        if (range <= 2048 && range <= 8 * m) {
            uint32_t counts[2049];
            memset(counts, 0, sizeof(uint32_t) * (range + 1));
            for (uint32_t t = 0; t < m; t++)
                counts[(ent[t].fx & 0xffffffu) - low + 1]++;
            for (uint32_t b = 0; b < range; b++)
                counts[b + 1] += counts[b];
            for (uint32_t t = 0; t < m; t++) {
                uint32_t to = counts[(ent[t].fx & 0xffffffu) - low]++;
                sk[to] = keys[t];
                si[to] = t;
            }
            memcpy(keys, sk, sizeof(uint32_t) * m);
            memcpy(ids, si, sizeof(uint32_t) * m);
            sorted = bpx__insertion_sort(keys, ids, m, 4 * (uint64_t)m + 64);
        }
        if (!sorted)
            bpx__radix_sort(keys, ids, sk, si, m);
    }
    for (uint32_t t = 0; t < m; t++) {
        const grid_entry *x = &ent[ids[t]];
        for (int a = 0; a < 3; a++) {
            r->lo[a][at + t] = x->lo[a];
            r->hi[a][at + t] = x->hi[a];
        }
        r->id[at + t] = x->id;
        r->cx[at + t] = (x->fx & 0xffffffu) >> shift;
        r->flags[at + t] = (uint8_t)(x->fx >> 24);
    }
}

// The coarser levels' columns, into the shared positions (level 0 sorts as it tests).
static void sort_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    grid_state *st = ((grid_job *)context)->st;
    const bpx_grid_layout *g = &st->layout;
    for (int item = begin; item < end; item++) {
        int l = 0;
        for (uint32_t c = st->item_column[item]; c < st->item_column[item + 1]; c++) {
            while (l + 1 < g->windowed && c >= g->level[l + 1].first_column)
                l++;
            uint32_t s = st->column_start[c], e = st->column_start[c + 1];
            if (l > 0 && e > s)
                sort_column(st->entries + s, e - s, &st->positions, s,
                            st->params.fine_bits + 2 * l);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 6. Tests

static void test_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    grid_job *job = context;
    grid_state *st = job->st;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->world->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        if (b < st->item_count) {
            const bpx_grid_layout *g = &st->layout;
            grid_soa *own = &st->scratch[worker], *shared = &st->positions;
            int l = 0;
            for (uint32_t c = st->item_column[b]; c < st->item_column[b + 1]; c++) {
                while (l + 1 < g->windowed && c >= g->level[l + 1].first_column)
                    l++;
                uint32_t s = st->column_start[c], e = st->column_start[c + 1];
                if (s == e)
                    continue;
                size_t at = s;
                grid_soa *r = shared;
                if (l == 0) { // sorted here, while the entries are in cache
                    at = 0;
                    r = own;
                    sort_column(st->entries + s, e - s, own, 0, st->params.fine_bits);
                    pad_soa(own, e - s);
                }
                const bpx_grid_run run = {{r->lo[0] + at, r->lo[1] + at, r->lo[2] + at},
                                          {r->hi[0] + at, r->hi[1] + at, r->hi[2] + at},
                                          r->id + at,
                                          r->cx + at,
                                          r->flags + at,
                                          e - s};
                job->column(g, l, c, &run, block);
                if (block->status != BPX_OK)
                    break;
            }
            continue;
        }
        uint32_t k = (uint32_t)(b - st->item_count);
        uint32_t stop = (job->soa.n + PAD - 1) / PAD * PAD;
        uint32_t j0 = k * BIG_SPAN, j1 = j0 + BIG_SPAN < stop ? j0 + BIG_SPAN : stop;
        // Every big box over a few thousand ids at a time: the boxes are read from memory
        // once per cycle, not once per big box.
        for (uint32_t js = j0; js < j1 && block->status == BPX_OK; js += BIG_STEP) {
            uint32_t je = js + BIG_STEP < j1 ? js + BIG_STEP : j1;
            for (uint32_t box = 0; box < st->layout.big_count && block->status == BPX_OK; box++)
                job->big(&st->layout, box, js, je, block);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 7. Hits to (i, j) order

typedef struct emit_job {
    bpx_world *world;
    grid_state *st;
    int groups, buckets, items, j_passes, shift;
    bpx_pair *to;    // the bucketed pairs
    bpx_pair *other; // scratch of the same length
} emit_job;

static void emit_range(const emit_job *job, int g, int *b0, int *b1)
{
    int blocks = job->world->block_count;
    *b0 = (int)((int64_t)blocks * g / job->groups);
    *b1 = (int)((int64_t)blocks * (g + 1) / job->groups);
}

static void emit_count_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    for (int g = begin; g < end; g++) {
        uint32_t *hist = job->st->emit_hist + (size_t)g * job->buckets;
        memset(hist, 0, sizeof(uint32_t) * (size_t)job->buckets);
        int b0, b1;
        emit_range(job, g, &b0, &b1);
        for (int b = b0; b < b1; b++) {
            const bpx_pair_list *hits = &job->world->blocks[b].hits;
            for (size_t k = 0; k < hits->count; k++)
                hist[hits->pairs[k].i >> job->shift]++;
        }
    }
}

static void emit_scatter_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    for (int g = begin; g < end; g++) {
        uint32_t *offset = job->st->emit_hist + (size_t)g * job->buckets;
        int b0, b1;
        emit_range(job, g, &b0, &b1);
        for (int b = b0; b < b1; b++) {
            const bpx_pair_list *hits = &job->world->blocks[b].hits;
            for (size_t k = 0; k < hits->count; k++)
                job->to[offset[hits->pairs[k].i >> job->shift]++] = hits->pairs[k];
        }
    }
}

// Pairs of one i sorted by j, in place: insertion for the usual few, LSD counting passes
// (through scratch) for a box that meets many.
static void sort_run(bpx_pair *run, bpx_pair *scratch, uint32_t count, int j_passes)
{
    if (count <= 32) {
        for (uint32_t k = 1; k < count; k++) {
            bpx_pair x = run[k];
            uint32_t at = k;
            for (; at > 0 && x.j < run[at - 1].j; at--)
                run[at] = run[at - 1];
            run[at] = x;
        }
        return;
    }
    enum { DIGITS = 1 << EMIT_SHIFT };
    uint32_t counts[DIGITS + 1];
    bpx_pair *src = run, *dst = scratch;
    for (int pass = 0; pass < j_passes; pass++) {
        int at = pass * EMIT_SHIFT;
        memset(counts, 0, sizeof counts);
        for (uint32_t k = 0; k < count; k++)
            counts[((src[k].j >> at) & (DIGITS - 1)) + 1]++;
        for (uint32_t d = 0; d < DIGITS; d++)
            counts[d + 1] += counts[d];
        for (uint32_t k = 0; k < count; k++)
            dst[counts[(src[k].j >> at) & (DIGITS - 1)]++] = src[k];
        bpx_pair *t = src;
        src = dst;
        dst = t;
    }
    if (src != run)
        memcpy(run, src, sizeof(bpx_pair) * count);
}

// Sorts one bucket of src (2^shift ids) by (i, j) into dst: a counting pass on i's low bits,
// then each i's pairs by j (src is the scratch).
static void sort_bucket(bpx_pair *src, bpx_pair *dst, uint32_t count, int j_passes, int shift)
{
    enum { IDS = 1 << EMIT_SHIFT };
    uint32_t counts[IDS + 1];
    uint32_t mask = (1u << shift) - 1;
    memset(counts, 0, sizeof(uint32_t) * (mask + 2));
    for (uint32_t k = 0; k < count; k++)
        counts[(src[k].i & mask) + 1]++;
    for (uint32_t d = 0; d <= mask; d++)
        counts[d + 1] += counts[d];
    uint32_t start[IDS + 1];
    memcpy(start, counts, sizeof(uint32_t) * (mask + 2));
    for (uint32_t k = 0; k < count; k++)
        dst[counts[src[k].i & mask]++] = src[k];
    for (uint32_t d = 0; d <= mask; d++)
        if (start[d + 1] - start[d] > 1)
            sort_run(dst + start[d], src + start[d], start[d + 1] - start[d], j_passes);
}

static void emit_sort_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    const uint32_t *start = job->st->bucket_start;
    for (int item = begin; item < end; item++) {
        int b0 = (int)((int64_t)job->buckets * item / job->items);
        int b1 = (int)((int64_t)job->buckets * (item + 1) / job->items);
        for (int b = b0; b < b1; b++)
            sort_bucket(job->to + start[b], job->other + start[b], start[b + 1] - start[b],
                        job->j_passes, job->shift);
    }
}

static bpx_status emit_sorted(bpx_world *w, grid_state *st, uint32_t n)
{
    size_t total = 0;
    bpx_status status = bpx__emitter_total(w, &total);
    if (status != BPX_OK)
        return status;
    uint64_t tests = 0;
    for (int k = 0; k < w->block_count; k++)
        tests += w->blocks[k].tests;
    if (total > UINT32_MAX)
        return BPX_ERR_OUT_OF_MEMORY; // bucket offsets are 32-bit
    // Buckets of 2^shift ids holding about EMIT_BUCKET_PAIRS pairs (dense pair sets: fewer ids).
    int shift = EMIT_SHIFT;
    while (shift > 0 && (double)total * (double)(1u << shift) > (double)EMIT_BUCKET_PAIRS * n)
        shift--;
    int buckets = n ? (int)(((n - 1) >> shift) + 1) : 1;
    int groups = w->block_count < EMIT_GROUPS ? w->block_count : EMIT_GROUPS;
    int j_passes = 1; // 11-bit digits of the largest j
    for (uint32_t top = n ? n - 1 : 0;
         EMIT_SHIFT * j_passes < 32 && top >> (EMIT_SHIFT * j_passes);)
        j_passes++;
    if (!bpx__list_reserve(&st->a, total + total / 4) ||
        !bpx__list_reserve(&st->b, total + total / 4) ||
        !reserve_array((void **)&st->emit_hist, &st->emit_hist_capacity,
                       (size_t)groups * (size_t)buckets, sizeof(uint32_t)) ||
        !reserve_array((void **)&st->bucket_start, &st->bucket_capacity, (size_t)buckets + 1,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    emit_job job = {
        w,        st,    groups,      buckets,    buckets < EMIT_ITEMS ? buckets : EMIT_ITEMS,
        j_passes, shift, st->a.pairs, st->b.pairs};
    if (total) {
        bpx__parallel_for(&w->executor, emit_count_task, groups, &job);
        uint32_t at = 0;
        for (int b = 0; b < buckets; b++) {
            st->bucket_start[b] = at;
            for (int g = 0; g < groups; g++) {
                uint32_t *slot = &st->emit_hist[(size_t)g * buckets + b];
                uint32_t c = *slot;
                *slot = at;
                at += c;
            }
        }
        st->bucket_start[buckets] = at;
        bpx__parallel_for(&w->executor, emit_scatter_task, groups, &job);
        bpx__parallel_for(&w->executor, emit_sort_task, job.items, &job);
    }
    // Block 0 takes the ordered list (a swap, not a copy); its old list becomes scratch.
    bpx_pair_list *result = &st->b;
    result->count = total;
    for (int k = 0; k < w->block_count; k++) {
        w->blocks[k].hits.count = 0;
        w->blocks[k].tests = 0;
    }
    bpx_pair_list block0 = w->blocks[0].hits;
    w->blocks[0].hits = *result;
    w->blocks[0].tests = tests;
    *result = block0;
    result->count = 0;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// The cycle

// Work items: column ranges of about equal positions (empty columns count a little).
static void plan_items(grid_state *st, uint32_t columns, uint32_t positions)
{
    uint64_t cost_total = (uint64_t)positions + columns / 8;
    uint64_t target = cost_total / ITEMS_MAX + 1;
    if (target < ITEM_ENTRIES)
        target = ITEM_ENTRIES;
    int items = 0;
    uint64_t cost = 0;
    st->item_column[0] = 0;
    for (uint32_t c = 0; c < columns; c++) {
        cost += (st->column_start[c + 1] - st->column_start[c]) + ((c & 7) == 0);
        if (cost >= target && items + 1 < ITEMS_MAX) {
            st->item_column[++items] = c + 1;
            cost = 0;
        }
    }
    if (st->item_column[items] != columns || items == 0)
        st->item_column[++items] = columns;
    st->item_count = items;
}

bpx_status bpx__grid_find(bpx_world *w, void **state, bpx_soa boxes)
{
    grid_state *st = *state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (grid_state){0};
        *state = st;
    }
    uint32_t n = boxes.n;
    grid_kernels kernels = kernels_for(w->simd);
    grid_job job = {w, st, boxes, kernels.column, kernels.big, kernels.keys};

    // 1. Parameters, levels, chunks.
    choose_params(&job.soa, st, &st->params);
    set_levels(st);
    uint32_t columns = st->params.columns;
    int workers = w->executor.worker_count > 1 ? w->executor.worker_count : 1;
    int chunks = 2 * workers;
    chunks = chunks < CHUNKS_MAX ? chunks : CHUNKS_MAX;
    if ((uint32_t)chunks > n / 4096 + 1)
        chunks = (int)(n / 4096 + 1);
    st->chunk_count = chunks;
    for (int c = 0; c < chunks; c++) {
        st->chunks[c].begin = (uint32_t)((uint64_t)n * c / chunks);
        st->chunks[c].end = (uint32_t)((uint64_t)n * (c + 1) / chunks);
    }
    size_t padded = ((size_t)n + PAD - 1) / PAD * PAD + PAD;
    if (!reserve_array((void **)&st->key, &st->key_capacity, padded, sizeof(uint32_t)) ||
        !reserve_array((void **)&st->hist, &st->hist_capacity, (size_t)chunks * columns,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;

    // 2. Keys.
    bpx__parallel_for(&w->executor, key_task, chunks, &job);

    // 3. Levels: big from the top while few boxes; the rest in columns.
    uint32_t level_count[LEVELS] = {0};
    float lo_min[3] = {INFINITY, INFINITY, INFINITY}, lo_max[3] = {-INFINITY, -INFINITY, -INFINITY};
    float largest = 0.0f;
    for (int c = 0; c < chunks; c++) {
        const grid_chunk *ch = &st->chunks[c];
        for (int l = 0; l < LEVELS; l++)
            level_count[l] += ch->level_count[l];
        for (int a = 0; a < 3; a++) {
            lo_min[a] = fminf(lo_min[a], ch->lo_min[a]);
            lo_max[a] = fmaxf(lo_max[a], ch->lo_max[a]);
        }
        largest = fmaxf(largest, ch->max_extent);
    }
    st->have_stats = lo_min[0] <= lo_max[0];
    for (int a = 0; a < 3; a++) {
        st->bounds_lo[a] = lo_min[a];
        st->bounds_hi[a] = lo_max[a];
    }
    st->max_extent = largest;
    uint32_t big_limit = n / 16384 > 16 ? n / 16384 : 16, big = 0;
    int windowed = LEVELS;
    while (windowed > 0 && big + level_count[windowed - 1] <= big_limit)
        big += level_count[--windowed];
    bpx_grid_layout *g = &st->layout;
    g->windowed = windowed;
    for (int l = 0; l < LEVELS; l++)
        g->level[l].count = level_count[l];
    uint32_t wcolumns = windowed < LEVELS ? g->level[windowed].first_column : columns;
    if (!reserve_array((void **)&st->column_start, &st->column_capacity, (size_t)wcolumns + 1,
                       sizeof(uint32_t)) ||
        !reserve_array((void **)&st->big_ids, &st->big_capacity, big, sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    size_t at = 0;
    uint32_t level1 = windowed > 1 ? g->level[1].first_column : wcolumns, longest = 0;
    for (uint32_t c = 0; c < wcolumns; c++) {
        st->column_start[c] = (uint32_t)at;
        for (int ch = 0; ch < chunks; ch++) {
            uint32_t *slot = &st->hist[(size_t)ch * columns + c];
            uint32_t count = *slot;
            *slot = (uint32_t)at;
            at += count;
        }
        if (at > UINT32_MAX - 2 * PAD)
            return BPX_ERR_OUT_OF_MEMORY; // positions are 32-bit
        if (c < level1 && at - st->column_start[c] > longest)
            longest = (uint32_t)(at - st->column_start[c]);
    }
    st->column_start[wcolumns] = (uint32_t)at;
    uint32_t positions = (uint32_t)at;
    // Coarser runs in shared positions (indexed like the entries; level 0's part untouched),
    // level 0's in each worker's scratch, one column at a time.
    bool coarse = positions > st->column_start[level1];
    if (!reserve_array((void **)&st->entries, &st->entry_capacity, positions, sizeof(grid_entry)) ||
        (coarse && !reserve_soa(&st->positions, (size_t)positions + PAD)))
        return BPX_ERR_OUT_OF_MEMORY;
    for (int k = 0; k < workers && k < WORKERS_MAX; k++)
        if (!reserve_soa(&st->scratch[k], (size_t)longest + PAD))
            return BPX_ERR_OUT_OF_MEMORY;
    st->wcolumns = wcolumns;
    if (!reserve_array((void **)&st->stash, &st->stash_capacity, (size_t)workers * wcolumns,
                       sizeof(grid_entry)) ||
        !reserve_array((void **)&st->stash_at, &st->stash_at_capacity, (size_t)workers * wcolumns,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    if (big) {
        uint32_t k = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t key = st->key[i];
            if (key != BPX_GRID_INERT && bpx__grid_key_level(key) >= (uint32_t)windowed)
                st->big_ids[k++] = i;
        }
    }
    for (size_t k = n; k < padded; k++)
        st->key[k] = BPX_GRID_INERT;

    // 4. Scatter; 5. sort the columns.
    bpx__parallel_for(&w->executor, scatter_task, chunks, &job);
    plan_items(st, wcolumns, positions);
    if (coarse) {
        pad_soa(&st->positions, positions);
        bpx__parallel_for(&w->executor, sort_task, st->item_count, &job);
    }

    // 6. Tests (level 0's columns sorted on the way).
    const grid_soa *r = &st->positions;
    for (int a = 0; a < 3; a++) {
        g->lo[a] = r->lo[a];
        g->hi[a] = r->hi[a];
    }
    g->id = r->id;
    g->cx = r->cx;
    g->flags = r->flags;
    g->column_start = st->column_start;
    g->boxes = job.soa;
    g->big_ids = st->big_ids;
    g->big_count = big;
    g->key = st->key;
    st->big_parts = (uint32_t)((((size_t)n + PAD - 1) / PAD * PAD + BIG_SPAN - 1) / BIG_SPAN);
    st->big_items = big ? (int)st->big_parts : 0;
    int blocks = st->item_count + st->big_items;
    bpx_status status = bpx__emitter_reserve_blocks(w, blocks);
    if (status != BPX_OK)
        return status;
    w->block_count = blocks;
    w->planned_n = UINT32_MAX; // the layout is this backend's own
    // Room for about last cycle's hits per block, so coherent cycles do not grow lists.
    if ((size_t)blocks > st->block_hits_capacity) {
        size_t old = st->block_hits_capacity, cap = (size_t)blocks + (size_t)blocks / 2;
        if (!bpx__grow((void **)&st->block_hits, old * sizeof(size_t), cap * sizeof(size_t)))
            return BPX_ERR_OUT_OF_MEMORY;
        memset(st->block_hits + old, 0, (cap - old) * sizeof(size_t));
        st->block_hits_capacity = cap;
    }
    for (int b = 0; b < blocks; b++) {
        size_t want = st->block_hits[b];
        if (!bpx__list_reserve(&w->blocks[b].hits, want + want / 4 + 64))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    bpx__parallel_for(&w->executor, test_task, blocks, &job);
    for (int b = 0; b < blocks; b++)
        st->block_hits[b] = w->blocks[b].hits.count;

    // 7. Hits to (i, j) order.
    return emit_sorted(w, st, n);
}

static bpx_status grid_compare(bpx_world *w)
{
    return bpx__grid_find(w, &w->backend_state, bpx__world_soa(w));
}

static bool grid_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size,
             "hierarchical columns in y, z swept along x, big boxes apart, %s, "
             "threads",
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
