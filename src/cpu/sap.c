// The sap backend: sweep and prune with temporal coherence (the persistent sorted endpoint
// lists of SOLID and of Bullet's AxisSweep3, written here from the idea, not their code).
//
// State kept between cycles: per axis, the 2n endpoints of every box (ids 0 .. n-1, removed
// objects included: their inert boxes, min +inf and max -inf, sort to the two ends) in sorted
// order, each one 64-bit word: (key, is_max, box), key = bpx__float_key of the coordinate with
// -0.0 read as +0.0. The word order is (key, min before max, box): a min and a max that tie
// keep the min first, so "min_a before max_b" in a list is exactly lo_a <= hi_b (closed
// intervals: touching counts), and the order of the lists is a pure function of the boxes.
// Beside them: last cycle's boxes (`prev`) and last cycle's pairs, sorted by (i, j).
//
// A warm cycle (O(n + moves + k log k + p), k the pairs that began or ended, p the pairs):
//  1. Every endpoint gets its new key in place, and each axis is mended by insertion sort.
//     Insertion sort swaps exactly the endpoints whose relative order changed, each such couple
//     once. The order of min_a and max_b is the truth of lo_a <= hi_b, so a pair whose overlap
//     changed has at least one of its six conditions flipped: it is met at least once as a swap
//     of a min with a max, and no other pair is.
//       - a min moving left past a max: lo_a <= hi_b just became true, so the pair did not
//         overlap last cycle; it began iff bpx_overlap(new a, new b).
//       - a max moving left past a min: lo_b <= hi_a just became false, so the pair does not
//         overlap now; it ended iff bpx_overlap(old a, old b).
//     Deciding by the boxes themselves (overlap.h, the reference's own predicate), not by the
//     state of the other two lists in mid-update, makes the order of the axes irrelevant; a pair
//     met several times gives the same verdict each time, and duplicates go when the changes
//     are sorted. (The design brief asked for a hash set for membership; "was in the set" is
//     "overlapped last cycle", which the kept boxes answer with six compares and no table to
//     grow or probe, so there is none.)
//  2. The began and ended pairs (few when the scene is coherent) are sorted and merged into
//     last cycle's sorted pairs: the new pair list, in (i, j) order, with no per-cycle sort of
//     all pairs. The world gets a copy in block 0 (its filters edit the blocks in place; the
//     kept list must stay unfiltered).
// Growth (add_boxes appending ids) stays warm: a new box enters as if it had been inert last
// cycle (max at the front, min at the back of each list) and sorts in like any other move. So
// does an id freed by remove_boxes (its box turns inert and travels to the ends). Both cost
// O(n) moves per box, like AxisSweep3's insert and remove, and fall under the budget below.
//
// A cold cycle rebuilds: on the first cycle; when n shrank, or grew by more than an eighth;
// after a failed cycle; when a warm cycle passes MOVES_PER_BOX * n + MOVES_BASE element moves
// over its three insertion sorts (abandoned part way); and, after two such give-ups in a row,
// on every cycle but one in RETRY_EVERY, so that incoherent motion does not pay a wasted
// attempt each cycle. It sorts each axis's 2n endpoints with the radix sort of sort.c (minima
// listed before maxima; the sort is stable, so ties come out in word order), then sweeps once:
// the prune kernel, on the world's workers, over the boxes in min order of the axis whose
// intervals overlap least (counted in O(n) from the sorted lists, so boxes that all share one x
// interval make the sweep quadratic only if y and z overlap as much); the emitter's
// counting sorts put the pairs in (i, j) order. bpx_cycle_stats.rebuilt tells the two kinds
// apart. There is no "boxes replaced wholesale" trigger: set_boxes is the general mode's
// per-cycle call, so a replaced scene is told from a moved one by the move budget alone, as
// prune does.
//
// Threads: the warm path is serial (insertion sorts and their swaps are inherently ordered);
// the cold sweep runs on the world's workers. The output is the same bytes either way.
// Memory: about 190 bytes per box (three endpoint lists, keys by box, two box copies, the
// cold sweep's arrays) plus a few pair lists; grown with slack, so steady cycles allocate nothing.
#include <stdio.h>
#include <string.h>

#include "core/alloc.h"
#include "core/world.h"
#include "kernels.h"
#include "sort.h"

enum {
    ROWS_PER_BLOCK = 1024, // cold sweep rows per work item, as prune
    PAD = BPX_PAD_LANES,   // sentinel boxes after the swept boxes
    // A warm cycle gives up past MOVES_PER_BOX * n + MOVES_BASE element moves. Measured on a
    // 2-vCPU Xeon VM (uniform_density, n = 1000): a warm cycle costs about 25 ns per
    // box plus 13 ns per move (a move of a min past a max tests a pair, on random memory); a
    // rebuild 120 ns per box at n = 1000 and 290 at 10,000 (its sweep grows like prune's). The
    // crossover is 7 to 20 moves per box; past the budget a cycle costs at most about two
    // rebuilds.
    MOVES_PER_BOX = 16,
    MOVES_BASE = 4096,
    RETRY_EVERY = 8, // after two give-ups in a row, try mending once in this many cycles
    FIRST_CHANGES = 256, // began/ended lists start with room for this many (+ n / 16)
};

#define MAX_BIT (UINT64_C(1) << 31) // in an endpoint word: set on maxima
#define BOX_MASK 0x7fffffffu        // in an endpoint word: the box (BPX_MAX_BOXES = 2^30)

// The per-box arrays, allocated together (capacity boxes each, or as noted).
typedef struct sap_arrays {
    uint64_t *ends[3];      // 2 * capacity: sorted endpoint words per axis
    uint32_t *box_keys[3];  // 2 * capacity: this cycle's keys by box, [2 i] min, [2 i + 1] max
    bpx_box *prev;          // last completed cycle's boxes
    bpx_box *cur;           // this cycle's boxes
    uint32_t *keys, *ids, *scratch_keys, *scratch_ids; // 2 * capacity: cold radix sort
    float *lo[3], *hi[3];                              // capacity + PAD: cold sweep SoA
    uint32_t *sorted_ids;                              // capacity + PAD
    uint32_t *counts;                                  // capacity + 1: pair counting sorts
} sap_arrays;

enum { ARRAY_COUNT = 3 + 3 + 2 + 4 + 6 + 2 };

typedef struct sap_state {
    uint32_t capacity; // boxes the arrays hold
    uint32_t n;        // boxes the lists describe (when valid)
    bool valid;        // ends, prev and pairs describe the last completed cycle
    uint32_t give_ups; // warm attempts in a row that ran out of moves
    uint32_t waited;   // cycles rebuilt since the last warm attempt
    sap_arrays a;
    bpx_pair_list pairs;  // last cycle's pairs, (i, j) order, unfiltered
    bpx_pair_list merged; // the merge's output, then swapped with pairs
    bpx_pair_list began, ended;
    bpx_pair_list spare; // sort scratch
} sap_state;

// ---------------------------------------------------------------------------------------------
// Memory

// Every array of a with its size in bytes for `capacity` boxes; returns the count.
static int array_table(sap_arrays *a, size_t capacity, void ***ptrs, size_t *sizes)
{
    int k = 0;
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->ends[axis];
        sizes[k++] = 2 * capacity * sizeof(uint64_t);
        ptrs[k] = (void **)&a->box_keys[axis];
        sizes[k++] = 2 * capacity * sizeof(uint32_t);
    }
    ptrs[k] = (void **)&a->prev;
    sizes[k++] = capacity * sizeof(bpx_box);
    ptrs[k] = (void **)&a->cur;
    sizes[k++] = capacity * sizeof(bpx_box);
    uint32_t **radix[] = {&a->keys, &a->ids, &a->scratch_keys, &a->scratch_ids};
    for (int r = 0; r < 4; r++) {
        ptrs[k] = (void **)radix[r];
        sizes[k++] = 2 * capacity * sizeof(uint32_t);
    }
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->lo[axis];
        sizes[k++] = (capacity + PAD) * sizeof(float);
        ptrs[k] = (void **)&a->hi[axis];
        sizes[k++] = (capacity + PAD) * sizeof(float);
    }
    ptrs[k] = (void **)&a->sorted_ids;
    sizes[k++] = (capacity + PAD) * sizeof(uint32_t);
    ptrs[k] = (void **)&a->counts;
    sizes[k++] = (capacity + 1) * sizeof(uint32_t);
    return k;
}

static void free_arrays(sap_arrays *a, uint32_t capacity)
{
    void **ptrs[ARRAY_COUNT];
    size_t sizes[ARRAY_COUNT];
    int count = array_table(a, capacity, ptrs, sizes);
    for (int k = 0; k < count; k++) {
        bpx__free(*ptrs[k], sizes[k]);
        *ptrs[k] = NULL;
    }
}

static void list_free(bpx_pair_list *list)
{
    bpx__free(list->pairs, list->capacity * sizeof(bpx_pair));
    *list = (bpx_pair_list){0};
}

static void sap_destroy(bpx_world *w)
{
    sap_state *st = w->backend_state;
    if (!st)
        return;
    free_arrays(&st->a, st->capacity);
    bpx_pair_list *lists[] = {&st->pairs, &st->merged, &st->began, &st->ended, &st->spare};
    for (size_t k = 0; k < sizeof lists / sizeof lists[0]; k++)
        list_free(lists[k]);
    bpx__free(st, sizeof *st);
    w->backend_state = NULL;
}

// Makes the arrays hold n boxes. With `keep`, the endpoint lists (2 * st->n words each) and
// prev (st->n boxes) survive a move to bigger arrays. All or nothing: on failure st is as it was.
static bool reserve_arrays(sap_state *st, uint32_t n, bool keep)
{
    if (n <= st->capacity && st->a.ends[0])
        return true;
    // Growth by add_boxes comes in small steps: leave room for more.
    uint64_t capacity = st->capacity ? (uint64_t)st->capacity + st->capacity / 2 : 0;
    if (capacity < n)
        capacity = n;
    if (capacity > BPX_MAX_BOXES)
        capacity = BPX_MAX_BOXES;
    if (capacity == 0)
        capacity = 1;
    sap_arrays grown = {0};
    void **ptrs[ARRAY_COUNT];
    size_t sizes[ARRAY_COUNT];
    int count = array_table(&grown, capacity, ptrs, sizes);
    for (int k = 0; k < count; k++)
        if (!(*ptrs[k] = bpx__alloc(sizes[k]))) {
            free_arrays(&grown, (uint32_t)capacity);
            return false;
        }
    if (keep && st->a.ends[0]) {
        for (int axis = 0; axis < 3; axis++)
            memcpy(grown.ends[axis], st->a.ends[axis], 2 * (size_t)st->n * sizeof(uint64_t));
        memcpy(grown.prev, st->a.prev, (size_t)st->n * sizeof(bpx_box));
    }
    free_arrays(&st->a, st->capacity);
    st->a = grown;
    st->capacity = (uint32_t)capacity;
    return true;
}

// ---------------------------------------------------------------------------------------------
// Keys and endpoint words

// Sortable key of a coordinate; -0.0 and +0.0 share one key (they are equal in the contract).
static inline uint32_t coord_key(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    u &= -(uint32_t)(u != 0x80000000u); // -0.0 -> +0.0, without a branch
    memcpy(&x, &u, sizeof u);
    return bpx__float_key(x);
}

static inline uint64_t end_word(uint32_t key, uint64_t low)
{
    return (uint64_t)key << 32 | low;
}

// This cycle's boxes as an array of boxes (for the overlap tests, by id) and their keys by box
// (for the endpoint words): two sequential passes over the world's SoA arrays.
static void load_boxes(const bpx_world *w, sap_arrays *a)
{
    const bpx_box_arrays *b = &w->boxes;
    uint32_t n = w->n;
    for (uint32_t i = 0; i < n; i++)
        a->cur[i] = (bpx_box){{b->lo[0][i], b->lo[1][i], b->lo[2][i]},
                              {b->hi[0][i], b->hi[1][i], b->hi[2][i]}};
    for (int axis = 0; axis < 3; axis++) {
        const float *lo = b->lo[axis], *hi = b->hi[axis];
        uint32_t *keys = a->box_keys[axis];
        for (uint32_t i = 0; i < n; i++) {
            keys[2 * (size_t)i] = coord_key(lo[i]);
            keys[2 * (size_t)i + 1] = coord_key(hi[i]);
        }
    }
}

// The key of an endpoint word's coordinate: its low half, (is_max << 31) | box, rotated left
// by one is 2 box + is_max, the endpoint's place in box_keys.
static inline uint32_t word_key(const uint32_t *box_keys, uint64_t e)
{
    uint32_t low = (uint32_t)e;
    return box_keys[(low << 1) | (low >> 31)];
}

static inline bpx_pair ordered(uint32_t a, uint32_t b)
{
    return a < b ? (bpx_pair){a, b} : (bpx_pair){b, a};
}

static inline uint64_t pair_word(bpx_pair p)
{
    return (uint64_t)p.i << 32 | p.j;
}

static inline bool push(bpx_pair_list *list, bpx_pair p)
{
    if (list->count == list->capacity && !bpx__list_reserve(list, 1))
        return false;
    list->pairs[list->count++] = p;
    return true;
}

// ---------------------------------------------------------------------------------------------
// Warm cycle

typedef enum mend_result { MEND_DONE, MEND_GAVE_UP, MEND_NO_MEMORY } mend_result;

typedef struct mend {
    sap_state *st;
    uint64_t moves;
    uint64_t budget;
    uint64_t tests;
} mend;

// Insertion sort of one axis's endpoint words, each min/max swap deciding one pair (see the
// top of the file).
static mend_result mend_axis(mend *m, uint64_t *ends, uint32_t count)
{
    sap_state *st = m->st;
    const bpx_box *cur = st->a.cur, *prev = st->a.prev;
    for (uint32_t k = 1; k < count; k++) {
        uint64_t x = ends[k];
        if (ends[k - 1] < x)
            continue;
        uint32_t box = (uint32_t)x & BOX_MASK;
        uint32_t at = k;
        do {
            uint64_t past = ends[at - 1];
            uint32_t other = (uint32_t)past & BOX_MASK;
            if (((past ^ x) & MAX_BIT) && other != box) {
                m->tests++;
                bool ok = true;
                if (!(x & MAX_BIT)) { // a min past a max: maybe began
                    if (bpx_overlap(&cur[box], &cur[other]))
                        ok = push(&st->began, ordered(box, other));
                } else if (bpx_overlap(&prev[box], &prev[other])) { // a max past a min
                    ok = push(&st->ended, ordered(box, other));
                }
                if (!ok)
                    return MEND_NO_MEMORY;
            }
            ends[at] = past;
            at--;
        } while (at > 0 && ends[at - 1] > x);
        ends[at] = x;
        m->moves += k - at;
        if (m->moves > m->budget)
            return MEND_GAVE_UP;
    }
    return MEND_DONE;
}

// Sorts a change list by (i, j) (bottom-up merge sort through st->spare: O(k log k), no
// allocation past the spare's high-water mark) and drops repeats (a pair met on several axes).
static bool sort_unique(sap_state *st, bpx_pair_list *list)
{
    size_t count = list->count;
    if (count < 2)
        return true;
    st->spare.count = 0;
    if (!bpx__list_reserve(&st->spare, count))
        return false;
    bpx_pair *src = list->pairs, *dst = st->spare.pairs;
    for (size_t width = 1; width < count; width *= 2) {
        for (size_t lo = 0; lo < count; lo += 2 * width) {
            size_t mid = lo + width < count ? lo + width : count;
            size_t hi = mid + width < count ? mid + width : count;
            size_t a = lo, b = mid, out = lo;
            while (a < mid && b < hi)
                dst[out++] = pair_word(src[b]) < pair_word(src[a]) ? src[b++] : src[a++];
            while (a < mid)
                dst[out++] = src[a++];
            while (b < hi)
                dst[out++] = src[b++];
        }
        bpx_pair *t = src;
        src = dst;
        dst = t;
    }
    if (src != list->pairs) { // an odd number of passes left it in the spare: swap the lists
        bpx_pair_list t = *list;
        *list = st->spare;
        list->count = count;
        st->spare = t;
    }
    size_t kept = 1;
    for (size_t k = 1; k < count; k++)
        if (pair_word(list->pairs[k]) != pair_word(list->pairs[kept - 1]))
            list->pairs[kept++] = list->pairs[k];
    list->count = kept;
    return true;
}

// merged = pairs - ended + began, all sorted; ended must be a subset of pairs and began
// disjoint from it. Returns false if ended was not (never, unless this file has a bug: the
// caller then rebuilds rather than report a wrong set).
static bool merge_changes(sap_state *st)
{
    const bpx_pair *old = st->pairs.pairs, *gone = st->ended.pairs, *added = st->began.pairs;
    size_t old_count = st->pairs.count, gone_count = st->ended.count;
    size_t added_count = st->began.count;
    bpx_pair *out = st->merged.pairs;
    size_t o = 0, g = 0, a = 0, count = 0;
    while (o < old_count) {
        uint64_t p = pair_word(old[o]);
        if (g < gone_count && pair_word(gone[g]) == p) {
            o++, g++;
            continue;
        }
        while (a < added_count && pair_word(added[a]) < p)
            out[count++] = added[a++];
        out[count++] = old[o++];
    }
    while (a < added_count)
        out[count++] = added[a++];
    st->merged.count = count;
    return g == gone_count;
}

// Puts new boxes n_old .. n-1 into the lists as if they had been inert last cycle: maxima at
// the front, minima at the back (their keys are set by the refresh that follows).
static void append_boxes(sap_state *st, uint32_t n_old, uint32_t n)
{
    uint32_t added = n - n_old;
    for (int axis = 0; axis < 3; axis++) {
        uint64_t *ends = st->a.ends[axis];
        memmove(ends + added, ends, 2 * (size_t)n_old * sizeof(uint64_t));
        for (uint32_t k = 0; k < added; k++) {
            ends[k] = MAX_BIT | (n_old + k);
            ends[added + 2 * (size_t)n_old + k] = n_old + k;
        }
    }
    const float inf = 1.0f / 0.0f;
    for (uint32_t i = n_old; i < n; i++)
        st->a.prev[i] = (bpx_box){{inf, inf, inf}, {-inf, -inf, -inf}};
}

// The warm cycle into st->pairs. MEND_GAVE_UP: too many moves (or an inconsistency); the
// caller rebuilds. On MEND_NO_MEMORY the state is invalid (the caller marks it so).
static mend_result warm_cycle(bpx_world *w, sap_state *st, uint64_t *tests)
{
    uint32_t n = w->n;
    if (n > st->n)
        append_boxes(st, st->n, n);
    load_boxes(w, &st->a);
    st->began.count = st->ended.count = 0;
    mend m = {st, 0, (uint64_t)MOVES_PER_BOX * n + MOVES_BASE, 0};
    for (int axis = 0; axis < 3; axis++) {
        uint64_t *ends = st->a.ends[axis];
        const uint32_t *keys = st->a.box_keys[axis];
        for (size_t k = 0; k < 2 * (size_t)n; k++)
            ends[k] = end_word(word_key(keys, ends[k]), ends[k] & 0xffffffffu);
        mend_result r = mend_axis(&m, ends, 2 * n);
        if (r != MEND_DONE)
            return r;
    }
    *tests = m.tests;
    if (!sort_unique(st, &st->began) || !sort_unique(st, &st->ended))
        return MEND_NO_MEMORY;
    st->merged.count = 0;
    if (!bpx__list_reserve(&st->merged, st->pairs.count + st->began.count))
        return MEND_NO_MEMORY;
    if (!merge_changes(st))
        return MEND_GAVE_UP;
    bpx_pair_list t = st->pairs;
    st->pairs = st->merged;
    st->merged = t;
    return MEND_DONE;
}

// ---------------------------------------------------------------------------------------------
// Cold cycle

typedef struct sweep_job {
    bpx_world *world;
    bpx_sorted sorted;
    bpx_prune_rows_fn *rows;
} sweep_job;

static void sweep_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sweep_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->world->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        job->rows(&job->sorted, block->row_begin, block->row_end, block);
    }
}

// Rebuilds the lists by radix sort and the pairs by one sweep, into block 0 and st->pairs.
static bpx_status cold_cycle(bpx_world *w, sap_state *st)
{
    uint32_t n = w->n;
    sap_arrays *a = &st->a;
    load_boxes(w, a);
    const bpx_box *cur = a->cur;
    const uint32_t inf_key = coord_key(1.0f / 0.0f), minus_inf_key = coord_key(-1.0f / 0.0f);

    // Sorted endpoint lists; on each, the pairs whose intervals overlap on that axis (inert
    // boxes, the only ones with infinite keys, left out).
    uint64_t overlaps[3];
    for (int axis = 0; axis < 3; axis++) {
        const uint32_t *box_keys = a->box_keys[axis];
        for (uint32_t i = 0; i < n; i++) {
            a->keys[i] = box_keys[2 * (size_t)i];
            a->ids[i] = i;
            a->keys[n + i] = box_keys[2 * (size_t)i + 1];
            a->ids[n + i] = (uint32_t)MAX_BIT | i;
        }
        bpx__radix_sort(a->keys, a->ids, a->scratch_keys, a->scratch_ids, 2 * n);
        uint64_t *ends = a->ends[axis];
        uint64_t sum = 0, open = 0;
        for (size_t k = 0; k < 2 * (size_t)n; k++) {
            uint32_t key = a->keys[k];
            ends[k] = end_word(key, a->ids[k]);
            if (key == inf_key || key == minus_inf_key)
                continue;
            if (a->ids[k] & MAX_BIT) {
                open--;
            } else {
                sum += open;
                open++;
            }
        }
        overlaps[axis] = sum;
    }

    // Sweep the axis with the fewest overlaps; the kernel's slot 0 is the swept axis.
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (overlaps[k] < overlaps[axis])
            axis = k;
    const int order[3] = {axis, axis == 0 ? 1 : 0, axis == 2 ? 1 : 2};
    uint32_t live = 0;
    const uint64_t *ends = a->ends[axis];
    for (size_t k = 0; k < 2 * (size_t)n; k++) {
        uint64_t e = ends[k];
        if ((e & MAX_BIT) || (uint32_t)(e >> 32) == inf_key)
            continue; // maxima, and the minima of inert boxes (min +inf)
        uint32_t box = (uint32_t)e & BOX_MASK;
        for (int s = 0; s < 3; s++) {
            a->lo[s][live] = cur[box].min[order[s]];
            a->hi[s][live] = cur[box].max[order[s]];
        }
        a->sorted_ids[live++] = box;
    }
    for (uint32_t k = live; k < live + PAD; k++) {
        for (int s = 0; s < 3; s++) {
            a->lo[s][k] = 1.0f / 0.0f;
            a->hi[s][k] = -1.0f / 0.0f;
        }
        a->sorted_ids[k] = 0;
    }

    int blocks = (int)((live + ROWS_PER_BLOCK - 1) / ROWS_PER_BLOCK);
    if (blocks < 1)
        blocks = 1;
    bpx_status status = bpx__emitter_reserve_blocks(w, blocks);
    if (status != BPX_OK)
        return status;
    for (int b = 0; b < blocks; b++) {
        uint32_t begin = (uint32_t)b * ROWS_PER_BLOCK;
        w->blocks[b].row_begin = begin;
        w->blocks[b].row_end = live - begin < ROWS_PER_BLOCK ? live : begin + ROWS_PER_BLOCK;
    }
    w->block_count = blocks;
    w->planned_n = UINT32_MAX; // the layout is this backend's own
    sweep_job job = {w,
                     {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]},
                      a->sorted_ids, live},
                     bpx__prune_rows_for(w->simd)};
    bpx__parallel_for(&w->executor, sweep_task, blocks, &job);
    status = bpx__emitter_sort_blocks(w, &st->merged, &st->spare, a->counts);
    if (status != BPX_OK)
        return status;

    // Keep the pairs, and room for the warm cycles to come.
    const bpx_pair_list *found = &w->blocks[0].hits;
    size_t room = found->count + found->count / 2 + FIRST_CHANGES;
    size_t changes = FIRST_CHANGES + n / 16;
    st->pairs.count = st->began.count = st->ended.count = 0;
    if (!bpx__list_reserve(&st->pairs, room) || !bpx__list_reserve(&st->merged, room) ||
        !bpx__list_reserve(&st->began, changes) || !bpx__list_reserve(&st->ended, changes) ||
        !bpx__list_reserve(&st->spare, changes))
        return BPX_ERR_OUT_OF_MEMORY;
    if (found->count)
        memcpy(st->pairs.pairs, found->pairs, found->count * sizeof(bpx_pair));
    st->pairs.count = found->count;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// The backend

static bpx_status sap_compare(bpx_world *w)
{
    sap_state *st = w->backend_state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (sap_state){0};
        w->backend_state = st;
    }
    uint32_t n = w->n;
    // Two give-ups in a row mean the motion is not coherent: rebuild without trying, and try
    // mending again every RETRY_EVERY cycles (a single jump costs one wasted attempt, a run of
    // incoherent cycles one in RETRY_EVERY).
    bool warm = st->valid && n >= st->n && n - st->n <= st->n / 8 &&
                (st->give_ups < 2 || st->waited + 1 >= RETRY_EVERY);
    if (!reserve_arrays(st, n, warm)) {
        st->valid = false;
        return BPX_ERR_OUT_OF_MEMORY;
    }
    st->valid = false; // until this cycle completes
    bpx_status status = BPX_OK;
    uint64_t tests = 0;
    if (warm) {
        mend_result r = warm_cycle(w, st, &tests);
        if (r == MEND_NO_MEMORY)
            return BPX_ERR_OUT_OF_MEMORY;
        st->give_ups = r == MEND_DONE ? 0 : st->give_ups + 1;
        st->waited = 0;
        warm = r == MEND_DONE;
    } else {
        st->waited++;
    }
    if (warm) {
        // Block 0 gets a copy of the pairs; the other blocks, left by the last rebuild, are
        // dropped.
        status = bpx__emitter_reserve_blocks(w, 1);
        if (status != BPX_OK)
            return status;
        bpx_block *out = &w->blocks[0];
        out->hits.count = 0;
        if (!bpx__list_reserve(&out->hits, st->pairs.count))
            return BPX_ERR_OUT_OF_MEMORY;
        if (st->pairs.count)
            memcpy(out->hits.pairs, st->pairs.pairs, st->pairs.count * sizeof(bpx_pair));
        out->hits.count = st->pairs.count;
        out->tests = tests;
        out->status = BPX_OK;
        w->block_count = 1;
        w->planned_n = UINT32_MAX;
    } else if ((status = cold_cycle(w, st)) != BPX_OK) {
        return status;
    }
    w->stats.rebuilt = !warm;
    bpx_box *t = st->a.prev; // this cycle's boxes are the next one's "last"
    st->a.prev = st->a.cur;
    st->a.cur = t;
    st->n = n;
    st->valid = true;
    return BPX_OK;
}

static bool sap_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size, "3-axis endpoint lists mended by insertion sort; rebuild sweep %s",
             bpx_simd_name(simd));
    return true;
}

const bpx_backend_impl bpx__sap_backend = {
    .id = BPX_BACKEND_SAP,
    .name = "sap",
    .query = sap_query,
    .compare = sap_compare,
    .destroy = sap_destroy,
};
