// The sap backend: sweep and prune with temporal coherence (the persistent sorted endpoint
// lists of SOLID and of Bullet's AxisSweep3, written here from the idea, not their code), over
// fat boxes.
//
// State kept between cycles: each box's fat box (its box at the last rebuild or at the last
// cycle it left the fat one, grown by a margin per axis: the boxes' mean extent there / 16, at
// most a quarter of the upper quartile of their extents),
// and per axis the 2n endpoints of the fat boxes (ids 0 .. n-1, removed objects included:
// inert boxes, min +inf and max -inf, sort to the two ends) in sorted order, each one 64-bit
// word: (key, is_max, box), key = bpx__float_key of the coordinate with -0.0 read as +0.0.
// The word order is (key, min before max, box): a min and a max that tie keep the min first,
// so "min_a before max_b" in a list is exactly lo_a <= hi_b (closed intervals: touching
// counts). Beside them: the fat pairs (pairs whose fat boxes overlap), sorted by (i, j). A box
// lies in its fat box, so every overlapping pair is a fat pair: the cycle's pairs are the fat
// pairs whose boxes overlap, found by one pass over the fat pairs in order (so they come out
// sorted). Fat boxes change rarely (a box at rest never leaves its own), so the lists and the
// fat pairs mostly stay as they are; that, not mending every endpoint every cycle, is what makes
// a coherent cycle cheap: mending every list each cycle costs a mispredicted branch and a random
// read per endpoint per axis.
//
// Files: lists.c (the endpoint lists), mend.c (the warm cycle), scan.c (the scan mend),
// filter.c (the boxes checked, the exact filter), rebuild.c (the cold cycle), sap.c (memory and
// the cycle's choice).

#pragma once

#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <string.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "core/transpose.h"
#include "cpu/backends.h"
#include "cpu/sort.h"

enum {
    ROWS_PER_BLOCK = 1024, // cold sweep rows per work item, as prune
    PAD = BPX_PAD_LANES,   // sentinel boxes after the swept boxes
    // A warm cycle gives up past MOVES_PER_BOX * n + MOVES_BASE element moves (mend.c): a move
    // costs a few ns and a full rebuild 150 to 300 ns per box, so past the budget a cycle costs at
    // most about two rebuilds (`bpx bench --backend sap --scene resting --sizes 100000,1000000`).
    MOVES_PER_BOX = 32,
    // Past CACHED_BOXES the fat boxes no longer fit in cache: a move's overlap test misses, so
    // the budget is this much smaller (with UNCACHED_DIVISOR 1, a give-up at 1M boxes costs
    // 0.9 s, six rebuilds: `bpx bench --backend sap --scene resting --sizes 1000000`).
    CACHED_BOXES = 1 << 16,
    UNCACHED_DIVISOR = 4,
    MOVES_BASE = 4096,
    RETRY_EVERY = 8,     // after two give-ups in a row, try mending once in this many cycles
    FIRST_CHANGES = 256, // change lists start with room for this many (+ n / 16)
    FEW_DIVISOR = 64,    // at most n / FEW_DIVISOR + FEW_BASE boxes left their fat boxes:
    FEW_BASE = 16,       // move their endpoints one by one; more: mend every list in one pass
    MARGIN_DIVISOR = 16, // fat margin on an axis: the boxes' mean extent there / this,
    MARGIN_QUARTILE_DIVISOR = 4, // at most their extents' upper quartile / this, over a sample
    MARGIN_SAMPLE = 127,         // of this many boxes, when at least MARGIN_SAMPLE_MIN of them
    MARGIN_SAMPLE_MIN = 8,       // have an extent there (rebuild.c: set_margins)
    CHECK_EVERY = 4096,          // endpoints between the early give-up checks of the first list
    PREFETCH = 32,               // pairs ahead whose second box the exact filter prefetches
    PARALLEL_MIN = 16384, // boxes (or fat pairs) from which a warm pass splits over the workers
    // The scan mend (scan.c): up to SCAN_MAX_BOXES boxes whose fat extents on the swept
    // axis are at most SCAN_WIDTH_RATIO times their mean; a cycle gives up past SCAN_WORK_PER_BOX
    // * n + MOVES_BASE boxes scanned and shifted.
    SCAN_MAX_BOXES = 1 << 15,
    SCAN_WIDTH_RATIO = 4,
    SCAN_WORK_PER_BOX = 64,
    CHUNKS_MAX = 64, // ranges of a split pass
};

#if defined(__GNUC__)
#define PREFETCH_READ(p) __builtin_prefetch((p), 0, 3)
#else
#define PREFETCH_READ(p) ((void)(p))
#endif

#define MAX_BIT (UINT64_C(1) << 31) // in an endpoint word: set on maxima
#define BOX_MASK 0x7fffffffu        // in an endpoint word: the box (BPX_MAX_BOXES = 2^30)

// The per-box arrays, allocated together (capacity boxes each, or as noted).
typedef struct bpx_sap_arrays {
    uint64_t *ends[3];                                 // 2 * capacity: sorted endpoint words
    uint32_t *where[3];                                // 2 * capacity: where[axis][end_slot(w)]
                                                       // is word w's index in ends[axis]
    bpx_box *fat;                                      // each box's fat box, as in the lists
    bpx_box *fat_prev;                                 // the same at the last cycle's end
    bpx_box *cur;                                      // this cycle's boxes
    uint32_t *changed;                                 // boxes that left their fat box
    uint64_t *words[3]; // 2 * capacity: a full rebuild's unsorted endpoints, one per axis; free
                        // in warm cycles (the scan mend's found boxes, the one-pass mend's bits)
    float *lo[3], *hi[3];                              // capacity + PAD: cold sweep SoA
    uint32_t *sorted_ids;                              // capacity + PAD
    uint32_t *counts;                                  // capacity + 1: pair counting sorts
} bpx_sap_arrays;

enum { ARRAY_COUNT = 3 + 3 + 3 + 4 + 6 + 2 };

typedef struct bpx_sap_state {
    uint32_t capacity; // boxes the arrays hold
    uint32_t n;        // boxes the lists describe (when valid)
    bool valid;        // fat and fat_pairs describe the last completed cycle (ends if listed)
    uint32_t give_ups; // warm attempts in a row that ran out of moves
    uint32_t waited;   // cycles rebuilt since the last warm attempt
    int sweep_axis;    // the axis the lists' last count chose for a sweep
    bool scan;         // warm cycles mend the scan list, not the endpoint lists
    float scan_width;  // at least every listed fat box's extent on the swept axis
    bool use_grid;     // the lists' last count chose the grid for the fat pairs
    uint32_t counted_n; // n at that count
    bool listed;        // the endpoint lists are made (see bpx__sap_make_lists; stale under scan)
    bool checked;       // cur holds this cycle's boxes (a warm attempt came first)
    bpx_sap_counters counters; // what the tests cannot see in the pairs
    bool indexed;      // where describes the lists (a rebuild leaves that to the first mend)
    void *grid;        // the grid's state, when it did
    bpx_radix_work *radix[3]; // the cold sorts' work memory: one per list sorted at once
    float margin[3];   // fat margin per axis, set by each full rebuild
    float least_moves; // fewest endpoint moves a box leaving its fat box is expected to cost
    bpx_sap_arrays a;
    bpx_pair_list fat_pairs; // pairs of overlapping fat boxes, (i, j) order
    bpx_pair_list merged;    // the merge's output, then swapped with fat_pairs
    bpx_pair_list changes;   // pairs whose fat overlap may have changed this cycle
    bpx_pair_list axis_changes[3]; // the same, noted by each list's mending
    uint32_t chunk_count[CHUNKS_MAX]; // a split pass's output per range
    bpx_pair_list spare;     // sort scratch
} bpx_sap_state;

typedef enum bpx_sap_mend_result { MEND_DONE, MEND_GAVE_UP, MEND_NO_MEMORY } bpx_sap_mend_result;

typedef struct bpx_sap_job {
    bpx_sap_state *st;
    const bpx_cycle *cycle;
    uint32_t n, chunks, changed;
    uint64_t budget;
    atomic_bool stop; // a list gave up (or ran out of memory): the others stop too
    bpx_sap_mend_result result[3];
    uint64_t overlaps[3]; // a full rebuild's pairs overlapping on each axis
    uint32_t live[3];     // and its boxes that are not inert (the same count on each)
    const bpx_box *boxes; // the grid's input, into SoA
    const uint64_t *moved; // the one-pass mend's changed boxes, a bit each (without where)
    bpx_pair *out;
} bpx_sap_job;

// ---------------------------------------------------------------------------------------------
// Keys, boxes, pairs, ranges

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

// The word of box b's endpoint (max or min) on an axis, for fat box f.
static inline uint64_t fat_word(const bpx_box *f, int axis, bool max, uint32_t b)
{
    return end_word(coord_key(max ? f->max[axis] : f->min[axis]), (max ? MAX_BIT : 0) | b);
}

// An endpoint word's slot in where[axis]: 2 * box + is_max.
static inline uint32_t end_slot(uint64_t x)
{
    return 2 * ((uint32_t)x & BOX_MASK) + (((uint32_t)x & MAX_BIT) != 0);
}

// Whether two boxes overlap, without branches (inert boxes never do: +inf <= x fails).
static inline bool overlap(const bpx_box *a, const bpx_box *b)
{
    return (a->min[0] <= b->max[0]) & (b->min[0] <= a->max[0]) & (a->min[1] <= b->max[1]) &
           (b->min[1] <= a->max[1]) & (a->min[2] <= b->max[2]) & (b->min[2] <= a->max[2]);
}

// Box b grown by the margins, kept within +-FLT_MAX: the lists take infinite keys for inert
// boxes only, and the grid wants finite input (margins are capped at 1e30, under half an ulp of
// FLT_MAX, so no sum rounds to infinity today; the clamp keeps that true here). Rounding is
// monotone and boxes are finite, so the fat box holds the box. An inert box (min +inf, max -inf)
// stays inert.
static inline bpx_box fatten(const bpx_box *b, const float margin[3])
{
    bpx_box f;
    for (int axis = 0; axis < 3; axis++) {
        float lo = b->min[axis] - margin[axis], hi = b->max[axis] + margin[axis];
        f.min[axis] = lo < -FLT_MAX ? -FLT_MAX : lo;
        f.max[axis] = hi > FLT_MAX ? FLT_MAX : hi;
    }
    return f;
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

static inline uint32_t chunk_begin(uint64_t total, uint32_t chunks, uint32_t c)
{
    return (uint32_t)(total * c / chunks);
}

static inline void scan_order(int axis, int order[3])
{
    order[0] = axis;
    order[1] = axis == 0 ? 1 : 0;
    order[2] = axis == 2 ? 1 : 2;
}

static inline void scan_put(bpx_sap_arrays *a, uint32_t k, const bpx_box *f, const int order[3],
                            uint32_t b)
{
    for (int s = 0; s < 3; s++) {
        a->lo[s][k] = f->min[order[s]];
        a->hi[s][k] = f->max[order[s]];
    }
    a->sorted_ids[k] = b;
}

// Floats just past a double, down and up: a reach rounded the safe way (more boxes scanned).
static inline float float_below(double x)
{
    return nextafterf((float)x, -INFINITY);
}

static inline float float_above(double x)
{
    return nextafterf((float)x, INFINITY);
}

// ---------------------------------------------------------------------------------------------
// Across the files of this folder

// lists.c: the endpoint lists.
void bpx__sap_index_lists(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n);
void bpx__sap_append_boxes(bpx_sap_state *st, uint32_t n_old, uint32_t n);
bool bpx__sap_reserve_radix(bpx_sap_state *st, int sorts, size_t words);
bool bpx__sap_make_lists(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n, uint32_t *live);
// mend.c: the warm cycle.
bpx_sap_mend_result bpx__sap_warm_cycle(const bpx_cycle *cycle, bpx_sap_state *st);
// scan.c: the scan mend.
void bpx__sap_scan_pad(bpx_sap_arrays *a, uint32_t n, const int order[3]);
void bpx__sap_scan_list(bpx_sap_state *st, uint32_t n, uint32_t live);
bpx_sap_mend_result bpx__sap_mend_scan(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n,
                                       uint32_t changed);
// filter.c: the boxes against their fat boxes, and the exact filter.
uint32_t bpx__sap_chunks_for(const bpx_cycle *cycle, size_t count);
uint32_t bpx__sap_check_boxes(const bpx_cycle *cycle, bpx_sap_state *st);
size_t bpx__sap_filter_pairs(const bpx_cycle *cycle, bpx_sap_state *st, bpx_pair *out);
// rebuild.c: the cold cycle.
bpx_status bpx__sap_full_rebuild(const bpx_cycle *cycle, bpx_sap_state *st);
bpx_status bpx__sap_rebuild_without_lists(const bpx_cycle *cycle, bpx_sap_state *st);
