// The sap backend: sweep and prune with temporal coherence (the persistent sorted endpoint
// lists of SOLID and of Bullet's AxisSweep3, written here from the idea, not their code), over
// fat boxes.
//
// State kept between cycles: each box's fat box (its box at the last rebuild or at the last
// cycle it left the fat one, grown by a margin per axis: the boxes' mean extent there / 16),
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
// a coherent cycle cheap (measured: a first version that mended every list each cycle spent
// most of its time on mispredicted branches and random reads, one per endpoint per axis).
//
// A warm cycle (O(n + p_fat) plus the mending, k the fat pairs that may have changed):
//  1. One pass (ranges on the workers) copies the boxes (AoS, for the exact filter) and lists
//     the boxes that left their fat boxes.
//  2. None: nothing to mend. A few (at most n / 64 + 16): each in turn gets a new fat box, and its
//     six endpoints are found by where (each word's index in its list, kept by every move: a
//     binary search per endpoint was 60% of this mend at 1k boxes; made after a rebuild by the
//     first such mend) and moved to their places, the lists sorted at every step. More (or boxes
//     were added): the moved boxes' endpoints take their new words in place and each list is
//     mended by one pass of insertion sort (the three at once on the workers). Insertion swaps
//     exactly the endpoints whose relative order changed, and the order of min_a and max_b is the
//     truth of lo_a <= hi_b, so a pair whose fat overlap changed has at least one of its six
//     conditions flipped: it is met at least once as a swap of a min with a max, and noted when
//     the fat boxes' overlap before and after the step differ (box by box: b's old and new fat box
//     against the other's current one; all at once: old against old, new against new).
//  3. The noted pairs (few when the scene is coherent) are sorted and merged into the fat
//     pairs: each is kept iff the fat boxes overlap now, whether or not it was there before. So
//     a pair noted twice, or noted and then turned back, costs nothing but a test.
//  4. The fat pairs are filtered by the exact overlap (the second box prefetched: it is
//     anywhere in memory) into block 0, already in (i, j) order.
// The scan mend, instead of step 2, for up to SCAN_MAX_BOXES boxes of even extents on the swept
// axis: the last rebuild's sweep order is kept as a list of fat boxes in SoA, sorted by min on
// that axis, and each changed box moves its one entry there (a shift of the entries between)
// and tests, a vector at a time (scan_kernel.h), the boxes whose min lies within reach of its
// old or new fat box against both: one pass over a few hundred contiguous boxes instead of ~110
// endpoint moves across three lists, each a likely cache miss (resting scene, 10k boxes: 180-230
// us a cycle against 350-440 for the lists). The endpoint lists are then left as they are; the
// next full rebuild makes them again. Uneven extents (a few wide boxes widen every box's reach)
// and larger scenes keep the lists.
// Growth (add_boxes appending ids) stays warm: a new box enters as if it had been inert last
// cycle (max at the front, min at the back of each list) and the one-pass mend sorts it in. An
// id freed by remove_boxes keeps its fat box (its inert box lies in any box) until it is reused;
// its stale fat pairs never pass the exact filter. Both cost O(n) moves per box, like
// AxisSweep3's insert and remove, and fall under the budget below (without lists, see below,
// growth past what the budget allows rebuilds untried).
//
// A cold cycle rebuilds: on the first cycle; when n shrank, or grew by more than an eighth;
// after a failed cycle; when a warm cycle passes MOVES_PER_BOX * n + MOVES_BASE element moves (a
// quarter of that past CACHED_BOXES; in the one-pass mend, a third of it per list, each abandoned
// part way, or early when its first part projects far past it, and the other lists stop too); and,
// after two such give-ups in a row, on every cycle but one in RETRY_EVERY, so that incoherent
// motion does not pay a wasted attempt each cycle. A full rebuild makes new fat boxes and margins,
// sorts each axis's 2n fat endpoint words with the radix sort of sort.c (minima listed before
// maxima; the sort is stable, so ties come out in word order), then sweeps the fat boxes once: the
// prune kernel, on the world's workers, in min order of the axis whose intervals overlap least
// (counted in O(n) from the sorted lists, so boxes that all share one x interval make the sweep
// quadratic only if y and z overlap as much); the emitter's counting sorts put the fat pairs in
// (i, j) order, and the exact filter gives the cycle's pairs. When even that axis meets more than
// BPX_SWEEP_MAX_CANDIDATES boxes per box (hundreds of thousands of boxes at constant density: the
// sweep's cost grows like n^(5/3)), the grid finds the fat pairs instead, so a rebuild at a
// million boxes costs a grid cycle, not seconds. The rebuilds after one that chose the grid keep
// the choice (while n stays within an eighth) and make no lists: the first warm cycle that must
// mend makes them, unless even the fewest moves expected put its mend past the budget (then it
// rebuilds untried, as does growth without lists). While the motion is incoherent (two give-ups in
// a row), a cycle not followed by an attempt only sorts the n minima of that axis and sweeps the
// boxes themselves (prune's work, no lists). bpx_cycle_stats.rebuilt tells warm and cold apart.
// There is no "boxes replaced wholesale" trigger: set_boxes is the general mode's per-cycle call,
// so a replaced scene is told from a moved one by the move budget alone, as prune does.
//
// Threads: from PARALLEL_MIN boxes, the warm cycle's check of the boxes and its exact filter split
// into ranges on the world's workers (each range's output packed after, in order), and the
// one-pass mend and a full rebuild's sorts run the three lists at once (each list has its own sort
// memory: at a million boxes the three sorts in a row were half of a rebuild, and a rebuild is
// what sets p99 there); the few-boxes mend is serial; the cold sweep (or grid) runs on the
// workers. The output is the same bytes either way. Memory: about 230 bytes per box (three
// endpoint lists, their indexes and their unsorted copies, three box copies, the cold sweep's
// arrays) plus a few pair lists, 24 KiB of sort memory (72 KiB when the lists sort at once, and
// 128 KiB more per list past 65,536 boxes), and the grid's own state once a rebuild has used it
// (kept for the next); grown with slack, so steady cycles allocate nothing.
#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "core/alloc.h"
#include "core/transpose.h"
#include "core/world.h"
#include "kernels.h"
#include "sort.h"

enum {
    ROWS_PER_BLOCK = 1024, // cold sweep rows per work item, as prune
    PAD = BPX_PAD_LANES,   // sentinel boxes after the swept boxes
    // A warm cycle gives up past MOVES_PER_BOX * n + MOVES_BASE element moves (see the top):
    // a move costs a few ns, a full rebuild 150 to 300 ns per box (2-vCPU Xeon VM), so past
    // the budget a cycle costs at most about two rebuilds.
    MOVES_PER_BOX = 32,
    // Past CACHED_BOXES the fat boxes no longer fit in cache: a move's overlap test misses, so
    // the budget is this much smaller (measured at 1M boxes: a give-up at 32 moves per box
    // cost 0.9 s, six rebuilds).
    CACHED_BOXES = 1 << 16,
    UNCACHED_DIVISOR = 4,
    MOVES_BASE = 4096,
    RETRY_EVERY = 8,     // after two give-ups in a row, try mending once in this many cycles
    FIRST_CHANGES = 256, // change lists start with room for this many (+ n / 16)
    FEW_DIVISOR = 64,    // at most n / FEW_DIVISOR + FEW_BASE boxes left their fat boxes:
    FEW_BASE = 16,       // move their endpoints one by one; more: mend every list in one pass
    MARGIN_DIVISOR = 16, // fat margin on an axis: the boxes' mean extent there / this
    CHECK_EVERY = 4096,  // endpoints between the early give-up checks of the first list
    PREFETCH = 32,       // pairs ahead whose second box the exact filter prefetches
    PARALLEL_MIN = 16384, // boxes (or fat pairs) from which a warm pass splits over the workers
    // The scan mend (see the top): up to SCAN_MAX_BOXES boxes whose fat extents on the swept
    // axis are at most SCAN_WIDTH_RATIO times their mean; a cycle gives up past SCAN_WORK_PER_BOX
    // * n + MOVES_BASE boxes scanned and shifted.
    SCAN_MAX_BOXES = 1 << 15,
    SCAN_WIDTH_RATIO = 4,
    SCAN_WORK_PER_BOX = 64,
    CHUNKS_MAX = 64,      // ranges of a split pass
};

#if defined(__GNUC__)
#define PREFETCH_READ(p) __builtin_prefetch((p), 0, 3)
#else
#define PREFETCH_READ(p) ((void)(p))
#endif

#define MAX_BIT (UINT64_C(1) << 31) // in an endpoint word: set on maxima
#define BOX_MASK 0x7fffffffu        // in an endpoint word: the box (BPX_MAX_BOXES = 2^30)

// The per-box arrays, allocated together (capacity boxes each, or as noted).
typedef struct sap_arrays {
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
} sap_arrays;

enum { ARRAY_COUNT = 3 + 3 + 3 + 4 + 6 + 2 };

typedef struct sap_state {
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
    bool listed;        // the endpoint lists are made (see make_lists; stale under scan)
    bool checked;       // cur holds this cycle's boxes (a warm attempt came first)
    bpx_sap_counters counters; // what the tests cannot see in the pairs
    bool indexed;      // where describes the lists (a rebuild leaves that to the first mend)
    void *grid;        // the grid's state, when it did
    bpx_radix_work *radix[3]; // the cold sorts' work memory: one per list sorted at once
    float margin[3];   // fat margin per axis, set by each full rebuild
    float least_moves; // fewest endpoint moves a box leaving its fat box is expected to cost
    sap_arrays a;
    bpx_pair_list fat_pairs; // pairs of overlapping fat boxes, (i, j) order
    bpx_pair_list merged;    // the merge's output, then swapped with fat_pairs
    bpx_pair_list changes;   // pairs whose fat overlap may have changed this cycle
    bpx_pair_list axis_changes[3]; // the same, noted by each list's mending
    uint32_t chunk_count[CHUNKS_MAX]; // a split pass's output per range
    bpx_pair_list spare;     // sort scratch
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
        ptrs[k] = (void **)&a->where[axis];
        sizes[k++] = 2 * capacity * sizeof(uint32_t);
    }
    bpx_box **boxes[] = {&a->fat, &a->fat_prev, &a->cur};
    for (int b = 0; b < 3; b++) {
        ptrs[k] = (void **)boxes[b];
        sizes[k++] = capacity * sizeof(bpx_box);
    }
    ptrs[k] = (void **)&a->changed;
    sizes[k++] = capacity * sizeof(uint32_t);
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->words[axis];
        sizes[k++] = 2 * capacity * sizeof(uint64_t);
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
    for (int k = 0; k < 3; k++)
        if (st->radix[k]) {
            bpx__free(st->radix[k]->lines, sizeof(bpx_radix_lines));
            bpx__free(st->radix[k], sizeof(bpx_radix_work));
        }
    bpx__grid_free(&st->grid);
    bpx_pair_list *lists[] = {&st->fat_pairs,      &st->merged,         &st->changes,
                              &st->spare,          &st->axis_changes[0], &st->axis_changes[1],
                              &st->axis_changes[2]};
    for (size_t k = 0; k < sizeof lists / sizeof lists[0]; k++)
        list_free(lists[k]);
    bpx__free(st, sizeof *st);
    w->backend_state = NULL;
}

// Makes the arrays hold n boxes. With `keep`, the endpoint lists (2 * st->n each) and the fat
// boxes (st->n) survive a move to bigger arrays. All or nothing: on failure st is as it was.
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
        for (int axis = 0; axis < 3; axis++) {
            memcpy(grown.ends[axis], st->a.ends[axis], 2 * (size_t)st->n * sizeof(uint64_t));
            memcpy(grown.where[axis], st->a.where[axis], 2 * (size_t)st->n * sizeof(uint32_t));
        }
        memcpy(grown.fat, st->a.fat, (size_t)st->n * sizeof(bpx_box));
        memcpy(grown.fat_prev, st->a.fat_prev, (size_t)st->n * sizeof(bpx_box));
        for (int s = 0; s < 3; s++) { // the scan list
            memcpy(grown.lo[s], st->a.lo[s], (size_t)st->n * sizeof(float));
            memcpy(grown.hi[s], st->a.hi[s], (size_t)st->n * sizeof(float));
        }
        memcpy(grown.sorted_ids, st->a.sorted_ids, (size_t)st->n * sizeof(uint32_t));
    }
    free_arrays(&st->a, st->capacity);
    st->a = grown;
    st->capacity = (uint32_t)capacity;
    return true;
}

// ---------------------------------------------------------------------------------------------
// Keys, boxes, pairs

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

// where[axis] for a whole list (after a sort or a shift of every word).
static void index_list(sap_arrays *a, int axis, uint32_t count)
{
    const uint64_t *ends = a->ends[axis];
    uint32_t *where = a->where[axis];
    for (uint32_t k = 0; k < count; k++)
        where[end_slot(ends[k])] = k;
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

// ---------------------------------------------------------------------------------------------
// Warm cycle

typedef enum mend_result { MEND_DONE, MEND_GAVE_UP, MEND_NO_MEMORY } mend_result;

// Moves the endpoint at `at` of box b to its place for word x (the list sorted but for it),
// noting in st->changes every box whose fat overlap with b changes when b's fat box goes from
// `before` to st->a.fat[b] (the other boxes as they are now). Returns the moves, or
// UINT64_MAX when memory ran out.
static uint64_t move_end(sap_state *st, int axis, uint32_t count, uint32_t at, uint64_t x,
                         const bpx_box *before)
{
    uint64_t *ends = st->a.ends[axis];
    uint32_t *where = st->a.where[axis];
    const bpx_box *fat = st->a.fat;
    uint32_t b = (uint32_t)x & BOX_MASK, from = at;
    if (x > ends[at]) {
        while (at + 1 < count && ends[at + 1] < x) {
            uint64_t next = ends[at + 1];
            uint32_t other = (uint32_t)next & BOX_MASK;
            if (((next ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(before, &fat[other]) &&
                !push(&st->changes, ordered(b, other)))
                return UINT64_MAX;
            ends[at] = next;
            where[end_slot(next)] = at;
            at++;
        }
    } else {
        while (at > 0 && ends[at - 1] > x) {
            uint64_t past = ends[at - 1];
            uint32_t other = (uint32_t)past & BOX_MASK;
            if (((past ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(before, &fat[other]) &&
                !push(&st->changes, ordered(b, other)))
                return UINT64_MAX;
            ends[at] = past;
            where[end_slot(past)] = at;
            at--;
        }
    }
    ends[at] = x;
    where[end_slot(x)] = at;
    return at > from ? at - from : from - at;
}

// Few boxes left their fat boxes: each in turn gets its new fat box, and its six endpoints
// are found (where) and moved to their places, the lists sorted at every step.
static mend_result mend_few(sap_state *st, uint32_t n, uint32_t changed, uint64_t budget)
{
    uint64_t moves = 0;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        bpx_box before = st->a.fat[b];
        st->a.fat[b] = fatten(&st->a.cur[b], st->margin);
        for (int axis = 0; axis < 3; axis++)
            for (int max = 0; max < 2; max++) {
                uint64_t old = fat_word(&before, axis, max, b);
                uint64_t x = fat_word(&st->a.fat[b], axis, max, b);
                if (old == x)
                    continue;
                uint32_t at = st->a.where[axis][end_slot(old)];
                if (at >= 2 * n || st->a.ends[axis][at] != old)
                    return MEND_GAVE_UP; // never, unless this file has a bug: rebuild
                uint64_t m = move_end(st, axis, 2 * n, at, x, &before);
                if (m == UINT64_MAX)
                    return MEND_NO_MEMORY;
                moves += m;
                if (moves > budget)
                    return MEND_GAVE_UP;
            }
    }
    return MEND_DONE;
}

// Word w as its box's fat box has it now, if `moved` flags the box.
static inline uint64_t fresh_word(uint64_t w, const bpx_box *fat, int axis, const uint64_t *moved)
{
    uint32_t b = (uint32_t)w & BOX_MASK;
    return moved[b / 64] >> (b % 64) & 1 ? fat_word(&fat[b], axis, (w & MAX_BIT) != 0, b) : w;
}

// Many boxes left their fat boxes (or boxes were added): every changed box gets its new fat
// box at once, its endpoints take their new words where they are (found by where), and each
// list is mended by one pass of insertion sort. The pass skips the words already in order
// (one compare each for the words in order); a min and a max that swap may change their
// boxes' fat overlap: the pair is noted when overlap(new, new) differs from overlap(old, old).
//
// mend_list mends one axis's list: its budget is a third of the cycle's, and it gives up early
// when its first part projects far past that. The lists are independent: the three run on the
// workers at once (mend_all). While where is not made yet (since the last rebuild), the changed
// boxes' words are renewed as the pass reaches them (`moved` flags them), and where stays
// unmade: a million boxes at rest after a rebuild leave their fat boxes together ~60 cycles
// later, too many to mend, and indexing the lists first cost that give-up 45 ms on 2 threads.
static inline mend_result mend_list_as(sap_state *st, uint32_t n, uint32_t changed,
                                       uint64_t budget, int axis, atomic_bool *stop,
                                       const uint64_t *moved, bool keep_where)
{
    const bpx_box *fat = st->a.fat, *prev = st->a.fat_prev;
    bpx_pair_list *changes = &st->axis_changes[axis];
    uint64_t *ends = st->a.ends[axis];
    uint32_t *where = st->a.where[axis];
    uint64_t moves = 0;
    budget /= 3;
    changes->count = 0;
    if (keep_where) {
        for (uint32_t c = 0; c < changed; c++) {
            uint32_t b = st->a.changed[c];
            ends[where[2 * b]] = fat_word(&fat[b], axis, false, b);
            ends[where[2 * b + 1]] = fat_word(&fat[b], axis, true, b);
        }
    } else if (n > 0) {
        ends[0] = fresh_word(ends[0], fat, axis, moved);
    }
    uint32_t check = CHECK_EVERY;
    for (uint32_t k = 1; k < 2 * n; k++) {
        if (!keep_where) // each word as the pass reaches it, so that a give-up comes early
            ends[k] = fresh_word(ends[k], fat, axis, moved);
        if (ends[k - 1] < ends[k])
            continue;
        uint64_t x = ends[k];
        uint32_t b = (uint32_t)x & BOX_MASK, at = k;
        do {
            uint64_t past = ends[at - 1];
            uint32_t other = (uint32_t)past & BOX_MASK;
            if (((past ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(&prev[b], &prev[other]) &&
                !push(changes, ordered(b, other)))
                return MEND_NO_MEMORY;
            ends[at] = past;
            if (keep_where)
                where[end_slot(past)] = at;
            at--;
        } while (at > 0 && ends[at - 1] > x);
        ends[at] = x;
        if (keep_where)
            where[end_slot(x)] = at;
        moves += k - at;
        if (moves > budget)
            return MEND_GAVE_UP;
        if (k >= check) { // projected over the list: far past its budget
            if (atomic_load_explicit(stop, memory_order_relaxed) ||
                moves * (uint64_t)n * 2 / k > 2 * budget)
                return MEND_GAVE_UP;
            check = k + CHECK_EVERY;
        }
    }
    return MEND_DONE;
}

static mend_result mend_list(sap_state *st, uint32_t n, uint32_t changed, uint64_t budget,
                             int axis, atomic_bool *stop, const uint64_t *moved)
{
    return st->indexed ? mend_list_as(st, n, changed, budget, axis, stop, moved, true)
                       : mend_list_as(st, n, changed, budget, axis, stop, moved, false);
}

typedef struct sap_job {
    sap_state *st;
    const bpx_world *w;
    uint32_t n, chunks, changed;
    uint64_t budget;
    atomic_bool stop; // a list gave up (or ran out of memory): the others stop too
    mend_result result[3];
    uint64_t overlaps[3]; // a full rebuild's pairs overlapping on each axis
    uint32_t live[3];     // and its boxes that are not inert (the same count on each)
    const bpx_box *boxes; // the grid's input, into SoA
    const uint64_t *moved; // the one-pass mend's changed boxes, a bit each (without where)
    bpx_pair *out;
} sap_job;

static void mend_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    for (int axis = begin; axis < end; axis++) {
        mend_result r = MEND_GAVE_UP;
        if (!atomic_load_explicit(&job->stop, memory_order_relaxed))
            r = mend_list(job->st, job->n, job->changed, job->budget, axis, &job->stop,
                          job->moved);
        if (r != MEND_DONE)
            atomic_store_explicit(&job->stop, true, memory_order_relaxed);
        job->result[axis] = r;
    }
}

static void index_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    for (int axis = begin; axis < end; axis++)
        index_list(&job->st->a, axis, 2 * job->n);
}

// where for the three lists at once (on the workers from PARALLEL_MIN boxes).
static void index_lists(const bpx_world *w, sap_state *st, uint32_t n)
{
    sap_job job = {.st = st, .n = n};
    if (n >= PARALLEL_MIN && w->executor.worker_count > 1)
        bpx__parallel_for(&w->executor, index_task, 3, &job);
    else
        index_task(0, 3, 0, &job);
}

static mend_result mend_all(bpx_world *w, sap_state *st, uint32_t n, uint32_t changed,
                            uint64_t budget)
{
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        st->a.fat[b] = fatten(&st->a.cur[b], st->margin);
    }
    uint64_t *moved = NULL; // without where: the changed boxes as bits (in a rebuild's array)
    if (!st->indexed) {
        moved = st->a.words[1];
        memset(moved, 0, ((size_t)n + 63) / 64 * sizeof *moved);
        for (uint32_t c = 0; c < changed; c++)
            moved[st->a.changed[c] / 64] |= UINT64_C(1) << (st->a.changed[c] % 64);
    }
    sap_job job = {.st = st, .n = n, .changed = changed, .budget = budget, .moved = moved};
    atomic_init(&job.stop, false);
    if (n >= PARALLEL_MIN && w->executor.worker_count > 1)
        bpx__parallel_for(&w->executor, mend_task, 3, &job);
    else
        mend_task(0, 3, 0, &job);
    mend_result r = MEND_DONE; // running out of memory outranks giving up
    size_t noted = 0;
    for (int axis = 0; axis < 3; axis++) {
        if (job.result[axis] == MEND_NO_MEMORY || (job.result[axis] == MEND_GAVE_UP && r == MEND_DONE))
            r = job.result[axis];
        noted += st->axis_changes[axis].count;
    }
    if (r != MEND_DONE)
        return r;
    if (!bpx__list_reserve(&st->changes, noted))
        return MEND_NO_MEMORY;
    for (int axis = 0; axis < 3; axis++) {
        const bpx_pair_list *from = &st->axis_changes[axis];
        if (from->count)
            memcpy(st->changes.pairs + st->changes.count, from->pairs,
                   from->count * sizeof(bpx_pair));
        st->changes.count += from->count;
    }
    return MEND_DONE;
}

// The scan mend: the fat boxes in SoA (a->lo, a->hi, slot 0 the swept axis; a->sorted_ids),
// sorted by min on the swept axis, inert ones last, padded. Each changed box in turn takes its
// new fat box: its entry moves to its new place (binary searches, one shift of the entries
// between), and the entries whose min lies within reach of its old or its new fat box (reach:
// the widest extent listed) are tested against both, a vector of them at a time; a box whose
// overlap differs is noted. Sequentially correct: each box's change is judged against the
// others as they are at its turn, as the few-boxes mend of the lists does.

static inline void scan_order(int axis, int order[3])
{
    order[0] = axis;
    order[1] = axis == 0 ? 1 : 0;
    order[2] = axis == 2 ? 1 : 2;
}

// First index in [k0, k1) whose min (slot 0) is >= v (or, with `after`, > v).
static inline uint32_t scan_bound(const float *lo, uint32_t k0, uint32_t k1, float v, bool after)
{
    while (k0 < k1) {
        uint32_t mid = k0 + (k1 - k0) / 2;
        if (after ? lo[mid] <= v : lo[mid] < v)
            k0 = mid + 1;
        else
            k1 = mid;
    }
    return k0;
}

static inline void scan_put(sap_arrays *a, uint32_t k, const bpx_box *f, const int order[3],
                            uint32_t b)
{
    for (int s = 0; s < 3; s++) {
        a->lo[s][k] = f->min[order[s]];
        a->hi[s][k] = f->max[order[s]];
    }
    a->sorted_ids[k] = b;
}

// Moves the entries [from, to) to [from + by, to + by) (by is -1 or +1).
static inline void scan_shift(sap_arrays *a, uint32_t from, uint32_t to, int by)
{
    size_t count = to - from;
    for (int s = 0; s < 3; s++) {
        memmove(a->lo[s] + from + by, a->lo[s] + from, count * sizeof(float));
        memmove(a->hi[s] + from + by, a->hi[s] + from, count * sizeof(float));
    }
    memmove(a->sorted_ids + from + by, a->sorted_ids + from, count * sizeof(uint32_t));
}

// Inert boxes after the n entries of the scan list: a scan reads up to a vector past its end.
static void scan_pad(sap_arrays *a, uint32_t n, const int order[3])
{
    const float inf = 1.0f / 0.0f;
    const bpx_box inert = {{inf, inf, inf}, {-inf, -inf, -inf}};
    for (uint32_t k = n; k < n + PAD; k++)
        scan_put(a, k, &inert, order, 0);
}

// The scan list after a full rebuild's sweep (its first `live` entries): the inert boxes after
// them, and the padding.
static void scan_list(sap_state *st, uint32_t n, uint32_t live)
{
    sap_arrays *a = &st->a;
    int order[3];
    scan_order(st->sweep_axis, order);
    uint32_t k = live;
    for (uint32_t i = 0; i < n && k < n; i++)
        if (!(a->fat[i].min[order[0]] <= a->fat[i].max[order[0]]))
            scan_put(a, k++, &a->fat[i], order, i);
    scan_pad(a, n, order);
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

static mend_result mend_scan(const bpx_world *w, sap_state *st, uint32_t n, uint32_t changed)
{
    sap_arrays *a = &st->a;
    int order[3];
    scan_order(st->sweep_axis, order);
    const float *lo0 = a->lo[0];
    const bpx_sorted list = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]},
                             a->sorted_ids, n};
    bpx_scan_differs_fn *differs = bpx__scan_differs_for(w->simd);
    uint32_t *found = (uint32_t *)a->words[0]; // free in a warm cycle
    uint64_t work = 0, budget = (uint64_t)SCAN_WORK_PER_BOX * n + MOVES_BASE;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = a->changed[c];
        const bpx_box old = a->fat[b];
        const bpx_box now = fatten(&a->cur[b], st->margin);
        a->fat[b] = now;
        // b's entry (by its old min, then its id), and its new place.
        float was = old.min[order[0]], v = now.min[order[0]];
        uint32_t at = scan_bound(lo0, 0, n, was, false);
        while (at < n && lo0[at] == was && a->sorted_ids[at] != b)
            at++;
        if (at >= n || lo0[at] != was)
            return MEND_GAVE_UP; // never, unless this file has a bug: rebuild
        uint32_t to = at;
        if (v > was) {
            to = scan_bound(lo0, at + 1, n, v, false) - 1;
            scan_shift(a, at + 1, to + 1, -1);
        } else if (v < was) {
            to = scan_bound(lo0, 0, at, v, false);
            scan_shift(a, to, at, +1);
        }
        scan_put(a, to, &now, order, b);
        if (now.min[order[0]] <= now.max[order[0]]) {
            float extent = float_above((double)now.max[order[0]] - (double)now.min[order[0]]);
            st->scan_width = extent > st->scan_width ? extent : st->scan_width;
        }
        // Every box whose overlap with b may differ between its old and new fat box.
        float reach_lo = float_below((double)(was < v ? was : v) - (double)st->scan_width);
        float reach_hi = old.max[order[0]] > now.max[order[0]] ? old.max[order[0]]
                                                               : now.max[order[0]];
        uint32_t k0 = scan_bound(lo0, 0, n, reach_lo, false);
        uint32_t k1 = scan_bound(lo0, k0, n, reach_hi, true);
        work += (to > at ? to - at : at - to) + (k1 - k0);
        if (work > budget)
            return MEND_GAVE_UP;
        float was_box[6], now_box[6];
        for (int k = 0; k < 3; k++) {
            was_box[k] = old.min[order[k]];
            was_box[3 + k] = old.max[order[k]];
            now_box[k] = now.min[order[k]];
            now_box[3 + k] = now.max[order[k]];
        }
        uint32_t count = differs(&list, k0, k1, was_box, now_box, found);
        for (uint32_t k = 0; k < count; k++) {
            uint32_t other = a->sorted_ids[found[k]];
            if (other != b && !push(&st->changes, ordered(b, other)))
                return MEND_NO_MEMORY;
        }
    }
    return MEND_DONE;
}

// fat_pairs after the changes: each pair noted is in the new list iff the fat boxes overlap now,
// whether or not it was in the old one.
static void merge_changes(sap_state *st)
{
    const bpx_pair *old = st->fat_pairs.pairs, *maybe = st->changes.pairs;
    size_t old_count = st->fat_pairs.count, maybe_count = st->changes.count;
    const bpx_box *fat = st->a.fat;
    bpx_pair *out = st->merged.pairs;
    size_t o = 0, m = 0, count = 0;
    while (m < maybe_count) {
        uint64_t p = pair_word(maybe[m]);
        while (o < old_count && pair_word(old[o]) < p)
            out[count++] = old[o++];
        if (o < old_count && pair_word(old[o]) == p)
            o++;
        if (overlap(&fat[maybe[m].i], &fat[maybe[m].j]))
            out[count++] = maybe[m];
        m++;
    }
    if (o < old_count)
        memcpy(out + count, old + o, (old_count - o) * sizeof(bpx_pair));
    st->merged.count = count + (old_count - o);
}

// Puts new boxes n_old .. n-1 into the lists as if they had been inert last cycle (maxima at
// the front, minima at the back; the next full pass puts them in order).
static void append_boxes(sap_state *st, uint32_t n_old, uint32_t n)
{
    uint32_t added = n - n_old;
    const float inf = 1.0f / 0.0f;
    const bpx_box inert = {{inf, inf, inf}, {-inf, -inf, -inf}};
    for (int axis = 0; axis < 3; axis++) {
        uint64_t *ends = st->a.ends[axis];
        memmove(ends + added, ends, 2 * (size_t)n_old * sizeof(uint64_t));
        for (uint32_t k = 0; k < added; k++) {
            ends[k] = fat_word(&inert, axis, true, n_old + k);
            ends[added + 2 * (size_t)n_old + k] = fat_word(&inert, axis, false, n_old + k);
        }
        index_list(&st->a, axis, 2 * n);
    }
    for (uint32_t i = n_old; i < n; i++)
        st->a.fat[i] = st->a.fat_prev[i] = inert;
}

// Boxes [i0, i1) into cur, and those that left their fat boxes into changed from i0 on;
// returns their count.
static uint32_t check_range(const bpx_world *w, sap_state *st, uint32_t i0, uint32_t i1)
{
    const bpx_box_arrays *b = &w->boxes;
    const bpx_box *fat = st->a.fat;
    bpx_box *cur = st->a.cur;
    uint32_t *changed = st->a.changed + i0, count = 0;
    uint32_t i = i0;
#ifdef BPX_HAVE_TRANSPOSE4
    // Four boxes at a time: loaded as vectors, stored to cur by one transpose, checked against
    // their fat boxes transposed the other way.
    for (; i + 4 <= i1; i += 4) {
        __m128 v[6], f[6];
        for (int a = 0; a < 3; a++) {
            v[a] = _mm_loadu_ps(b->lo[a] + i);
            v[3 + a] = _mm_loadu_ps(b->hi[a] + i);
        }
        bpx__soa4_to_boxes(v, &cur[i]);
        bpx__boxes4_to_soa(&fat[i], f);
        __m128 inside = _mm_and_ps(_mm_cmpge_ps(v[0], f[0]), _mm_cmple_ps(v[3], f[3]));
        for (int a = 1; a < 3; a++)
            inside = _mm_and_ps(inside, _mm_and_ps(_mm_cmpge_ps(v[a], f[a]),
                                                   _mm_cmple_ps(v[3 + a], f[3 + a])));
        int left = ~_mm_movemask_ps(inside) & 0xf;
        for (uint32_t k = 0; k < 4; k++) {
            changed[count] = i + k;
            count += (uint32_t)(left >> k) & 1;
        }
    }
#endif
    for (; i < i1; i++) {
        bpx_box box = {{b->lo[0][i], b->lo[1][i], b->lo[2][i]},
                       {b->hi[0][i], b->hi[1][i], b->hi[2][i]}};
        cur[i] = box;
        bool inside = (box.min[0] >= fat[i].min[0]) & (box.min[1] >= fat[i].min[1]) &
                      (box.min[2] >= fat[i].min[2]) & (box.max[0] <= fat[i].max[0]) &
                      (box.max[1] <= fat[i].max[1]) & (box.max[2] <= fat[i].max[2]);
        changed[count] = i;
        count += !inside;
    }
    return count;
}

static inline uint32_t chunk_begin(uint64_t total, uint32_t chunks, uint32_t c)
{
    return (uint32_t)(total * c / chunks);
}

static void check_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    for (int c = begin; c < end; c++)
        job->st->chunk_count[c] =
            check_range(job->w, job->st, chunk_begin(job->n, job->chunks, (uint32_t)c),
                        chunk_begin(job->n, job->chunks, (uint32_t)c + 1));
}

// How many ranges a pass over `count` items splits into (1: serial).
static uint32_t chunks_for(const bpx_world *w, size_t count)
{
    int workers = w->executor.worker_count;
    if (count < PARALLEL_MIN || workers < 2)
        return 1;
    return 4 * (uint32_t)workers < CHUNKS_MAX ? 4 * (uint32_t)workers : CHUNKS_MAX;
}

// This cycle's boxes into cur, and the boxes that left their fat boxes into changed, in id
// order (ranges on the workers, then packed); returns their count.
static uint32_t check_boxes(const bpx_world *w, sap_state *st)
{
    uint32_t chunks = chunks_for(w, w->n);
    if (chunks == 1)
        return check_range(w, st, 0, w->n);
    sap_job job = {.st = st, .w = w, .n = w->n, .chunks = chunks};
    bpx__parallel_for(&w->executor, check_task, (int)chunks, &job);
    uint32_t count = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        uint32_t at = chunk_begin(w->n, chunks, c);
        if (at != count)
            memmove(st->a.changed + count, st->a.changed + at,
                    st->chunk_count[c] * sizeof(uint32_t));
        count += st->chunk_count[c];
    }
    return count;
}

// The fat pairs [k0, k1) whose boxes overlap, into out from k0 on; returns their count.
static size_t filter_range(const sap_state *st, bpx_pair *out, size_t k0, size_t k1)
{
    const bpx_box *cur = st->a.cur;
    const bpx_pair *fat = st->fat_pairs.pairs;
    size_t count = 0;
    out += k0;
    for (size_t k = k0; k < k1; k++) {
        if (k + PREFETCH < k1) { // j is anywhere: fetch it early (i comes in order), both
                                 // lines when its 24 bytes straddle two
            const bpx_box *next = &cur[fat[k + PREFETCH].j];
            PREFETCH_READ(next);
            PREFETCH_READ((const char *)next + sizeof *next - 1);
        }
        out[count] = fat[k];
        count += overlap(&cur[fat[k].i], &cur[fat[k].j]);
    }
    return count;
}

static void filter_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    size_t total = job->st->fat_pairs.count;
    for (int c = begin; c < end; c++)
        job->st->chunk_count[c] = (uint32_t)filter_range(job->st, job->out, (size_t)((uint64_t)total * c / job->chunks),
                         (size_t)((uint64_t)total * (c + 1) / job->chunks));
}

// The exact pairs, fat pairs whose boxes overlap, into out (which holds fat_pairs.count), in
// the fat pairs' order (ranges on the workers, then packed).
static size_t filter_pairs(const bpx_world *w, sap_state *st, bpx_pair *out)
{
    size_t total = st->fat_pairs.count;
    uint32_t chunks = total <= UINT32_MAX ? chunks_for(w, total) : 1;
    if (chunks == 1)
        return filter_range(st, out, 0, total);
    sap_job job = {.st = st, .chunks = chunks, .out = out};
    bpx__parallel_for(&w->executor, filter_task, (int)chunks, &job);
    size_t count = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        size_t at = (size_t)((uint64_t)total * c / chunks);
        if (at != count)
            memmove(out + count, out + at, st->chunk_count[c] * sizeof(bpx_pair));
        count += st->chunk_count[c];
    }
    return count;
}

static bool make_lists(bpx_world *w, sap_state *st, uint32_t n, uint32_t *live); // cold cycle

// The warm cycle into st->fat_pairs. MEND_GAVE_UP: too many moves (or an inconsistency); the
// caller rebuilds. On MEND_NO_MEMORY the state is invalid (the caller marks it so).
static mend_result warm_cycle(bpx_world *w, sap_state *st)
{
    uint32_t n = w->n;
    bool grown = n > st->n;
    uint64_t budget =
        (uint64_t)MOVES_PER_BOX * n / (n > CACHED_BOXES ? UNCACHED_DIVISOR : 1) + MOVES_BASE;
    uint32_t live;
    if (grown && !st->listed) {
        // A new box enters a list at its two ends and its words travel about 2n places: past
        // the one-pass mend's third of the budget, a rebuild untried. Else the lists first.
        if ((double)(n - st->n) * 2.0 * st->n > (double)budget / 3) {
            st->counters.untried++;
            return MEND_GAVE_UP;
        }
        if (!make_lists(w, st, st->n, &live))
            return MEND_NO_MEMORY;
    }
    if (grown) {
        append_boxes(st, st->n, n);
        st->indexed = true;
    }
    uint32_t changed = check_boxes(w, st);
    st->checked = true;
    if (st->scan && grown) { // the new boxes enter the scan list as inert, at its end
        int order[3];
        scan_order(st->sweep_axis, order);
        for (uint32_t i = st->n; i < n; i++)
            scan_put(&st->a, i, &st->a.fat[i], order, i);
        scan_pad(&st->a, n, order);
    }
    if (changed > 0 && !st->listed) {
        // The lists for this mend (see make_lists), unless even the fewest moves expected put
        // it past the budget (the three lists' moves together are at least that, so one of
        // them would pass its third in the one-pass mend): then a rebuild untried.
        if ((double)changed * st->least_moves > (double)budget) {
            st->counters.untried++;
            return MEND_GAVE_UP;
        }
        if (!make_lists(w, st, n, &live))
            return MEND_NO_MEMORY;
    }
    st->changes.count = 0;
    mend_result r = MEND_DONE;
    if (st->scan) {
        if (changed > 0)
            r = mend_scan(w, st, n, changed);
    } else if (grown || changed > n / FEW_DIVISOR + FEW_BASE) {
        r = mend_all(w, st, n, changed, budget);
    } else if (changed > 0) {
        if (!st->indexed) {
            index_lists(w, st, n);
            st->indexed = true;
        }
        r = mend_few(st, n, changed, budget);
    }
    if (r != MEND_DONE)
        return r;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        st->a.fat_prev[b] = st->a.fat[b];
    }
    if (st->changes.count > 0) {
        if (!sort_unique(st, &st->changes))
            return MEND_NO_MEMORY;
        st->merged.count = 0;
        if (!bpx__list_reserve(&st->merged, st->fat_pairs.count + st->changes.count))
            return MEND_NO_MEMORY;
        merge_changes(st);
        bpx_pair_list t = st->fat_pairs;
        st->fat_pairs = st->merged;
        st->merged = t;
    }
    return MEND_DONE;
}

// ---------------------------------------------------------------------------------------------
// Cold cycle

// Sweeps the `live` boxes of sorted_ids (ids in min order of `axis`), each as `boxes` has it,
// into block 0, in (i, j) order.
static bpx_status sweep(bpx_world *w, sap_state *st, const bpx_box *boxes, int axis,
                        uint32_t live)
{
    sap_arrays *a = &st->a;
    const int order[3] = {axis, axis == 0 ? 1 : 0, axis == 2 ? 1 : 2}; // slot 0: swept axis
    for (int s = 0; s < 3; s++) {
        float *slo = a->lo[s], *shi = a->hi[s];
        for (uint32_t k = 0; k < live; k++) {
            const bpx_box *box = &boxes[a->sorted_ids[k]];
            slo[k] = box->min[order[s]];
            shi[k] = box->max[order[s]];
        }
        for (uint32_t k = live; k < live + PAD; k++) {
            slo[k] = 1.0f / 0.0f;
            shi[k] = -1.0f / 0.0f;
        }
    }
    for (uint32_t k = live; k < live + PAD; k++)
        a->sorted_ids[k] = 0;

    int blocks = (int)((live + ROWS_PER_BLOCK - 1) / ROWS_PER_BLOCK);
    if (blocks < 1)
        blocks = 1;
    bpx_status status = bpx__emitter_reserve_blocks(w, blocks);
    if (status != BPX_OK)
        return status;
    for (int k = 0; k < blocks; k++) {
        uint32_t begin = (uint32_t)k * ROWS_PER_BLOCK;
        w->blocks[k].row_begin = begin;
        w->blocks[k].row_end = live - begin < ROWS_PER_BLOCK ? live : begin + ROWS_PER_BLOCK;
    }
    w->block_count = blocks;
    w->planned_n = UINT32_MAX; // the layout is this backend's own
    bpx_sorted sorted = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]},
                         a->sorted_ids, live};
    bpx__prune_sweep_blocks(w, &sorted, blocks);
    return bpx__emitter_sort_blocks(w, &st->merged, &st->spare, a->counts);
}

static void soa_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    sap_arrays *a = &job->st->a;
    for (int c = begin; c < end; c++)
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            for (int axis = 0; axis < 3; axis++) {
                a->lo[axis][i] = job->boxes[i].min[axis];
                a->hi[axis][i] = job->boxes[i].max[axis];
            }
}

// The pairs of `boxes` (all n, by id) by the grid, into block 0 in (i, j) order: for rebuilds
// where one axis's sweep would meet too many boxes per box (millions at constant density).
static bpx_status grid_pairs(bpx_world *w, sap_state *st, const bpx_box *boxes)
{
    sap_arrays *a = &st->a;
    uint32_t n = w->n, padded = (n + PAD - 1) / PAD * PAD;
    sap_job job = {.st = st, .n = n, .chunks = chunks_for(w, n), .boxes = boxes};
    if (job.chunks == 1)
        soa_task(0, 1, 0, &job);
    else
        bpx__parallel_for(&w->executor, soa_task, (int)job.chunks, &job);
    for (int axis = 0; axis < 3; axis++)
        for (uint32_t i = n; i < padded; i++) {
            a->lo[axis][i] = 1.0f / 0.0f;
            a->hi[axis][i] = -1.0f / 0.0f;
        }
    bpx_soa soa = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]}, n};
    bpx__grid_forget(st->grid); // its last call may be long ago, on other boxes
    return bpx__grid_find(w, &st->grid, soa);
}

// What the margins need of a range of boxes: per axis, the live (non-inert) boxes, the sum of
// their extents and the bounds of their coordinates.
typedef struct margin_part {
    double sum[3];
    float low[3], high[3];
    uint32_t live[3];
} margin_part;

typedef struct margin_job {
    const bpx_box *cur;
    uint32_t n, chunks;
    margin_part part[CHUNKS_MAX];
} margin_job;

static void margin_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    margin_job *job = context;
    for (int c = begin; c < end; c++) {
        margin_part p = {{0.0, 0.0, 0.0},
                         {INFINITY, INFINITY, INFINITY},
                         {-INFINITY, -INFINITY, -INFINITY},
                         {0, 0, 0}};
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            for (int axis = 0; axis < 3; axis++) {
                const bpx_box *b = &job->cur[i];
                bool in = b->min[axis] <= b->max[axis]; // inert boxes are min > max
                p.sum[axis] += in ? (double)b->max[axis] - (double)b->min[axis] : 0.0;
                p.live[axis] += in;
                p.low[axis] = in && b->min[axis] < p.low[axis] ? b->min[axis] : p.low[axis];
                p.high[axis] = in && b->max[axis] > p.high[axis] ? b->max[axis] : p.high[axis];
            }
        job->part[c] = p;
    }
}

// The fat margins: on each axis, the (non-inert) boxes' mean extent / MARGIN_DIVISOR. One pass
// for the three axes (three passes, one per axis, took 12 ms at a million boxes), in ranges on
// the workers that depend on n only, summed in order, so the margins are the same for any worker
// count. With them, the fewest endpoint moves a box that leaves its fat box is expected to cost:
// its two endpoints on the axis it left by, each past a margin's worth of the list at the list's
// mean density (denser clusters cost more, so this errs low), on the axis where that is least.
static void set_margins(const bpx_world *w, sap_state *st)
{
    margin_job job = {.cur = st->a.cur, .n = w->n, .chunks = w->n / PARALLEL_MIN + 1};
    job.chunks = job.chunks < CHUNKS_MAX ? job.chunks : CHUNKS_MAX;
    if (job.chunks > 1 && w->executor.worker_count > 1)
        bpx__parallel_for(&w->executor, margin_task, (int)job.chunks, &job);
    else
        margin_task(0, (int)job.chunks, 0, &job);
    margin_part all = job.part[0];
    for (uint32_t c = 1; c < job.chunks; c++)
        for (int axis = 0; axis < 3; axis++) {
            const margin_part *p = &job.part[c];
            all.sum[axis] += p->sum[axis];
            all.live[axis] += p->live[axis];
            all.low[axis] = p->low[axis] < all.low[axis] ? p->low[axis] : all.low[axis];
            all.high[axis] = p->high[axis] > all.high[axis] ? p->high[axis] : all.high[axis];
        }
    double least = INFINITY;
    for (int axis = 0; axis < 3; axis++) {
        uint32_t live = all.live[axis];
        double margin = live ? all.sum[axis] / live / MARGIN_DIVISOR : 0.0;
        st->margin[axis] = margin < 1e30 ? (float)margin : 0.0f;
        double ends = 2.0 * live, span = (double)all.high[axis] - (double)all.low[axis];
        double passed = span > 0.0 ? fmin(ends, (double)st->margin[axis] * ends / span) : ends;
        least = fmin(least, 2.0 * passed);
    }
    st->least_moves = (float)least; // finite: boxes are, and at most 4n
}

// One axis's list for a full rebuild: the 2n fat endpoint words sorted into ends[axis] (minima
// listed before maxima, and the sort is stable, so ties come out in word order); and the count
// of pairs whose intervals overlap on the axis (inert boxes, the only ones with infinite keys,
// left out). where[axis] waits for the first few-boxes mend (the one-pass mend does without):
// a million boxes at rest may need none before their next rebuild, and its 2n scattered stores
// took a third of the list's time.
static void rebuild_list(sap_state *st, uint32_t n, int axis, bpx_radix_work *work,
                         uint64_t *overlaps, uint32_t *live)
{
    sap_arrays *a = &st->a;
    uint64_t *words = a->words[axis], *ends = a->ends[axis];
    for (uint32_t i = 0; i < n; i++) {
        words[i] = end_word(coord_key(a->fat[i].min[axis]), i);
        words[n + i] = end_word(coord_key(a->fat[i].max[axis]), MAX_BIT | i);
    }
    bpx__radix_sort_words(words, ends, 2 * n, work);
    const uint32_t inf_key = coord_key(1.0f / 0.0f), minus_inf_key = coord_key(-1.0f / 0.0f);
    uint64_t sum = 0, open = 0, minima = 0;
    for (uint32_t k = 0; k < 2 * n; k++) {
        uint64_t e = ends[k];
        uint32_t key = (uint32_t)(e >> 32);
        if (key == inf_key || key == minus_inf_key)
            continue;
        if (e & MAX_BIT) {
            open--;
        } else {
            sum += open;
            open++;
            minima++;
        }
    }
    *overlaps = sum;
    *live = (uint32_t)minima;
}

static void list_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    for (int axis = begin; axis < end; axis++)
        rebuild_list(job->st, job->n, axis, job->st->radix[job->chunks > 1 ? axis : 0],
                     &job->overlaps[axis], &job->live[axis]);
}

// The cold sorts' work memory for `sorts` lists at once, of `words` words each: made by the
// first rebuild that needs it (the lines only for lists long enough to stream), then kept.
static bool reserve_radix(sap_state *st, int sorts, size_t words)
{
    for (int k = 0; k < sorts; k++) {
        if (!st->radix[k]) {
            if (!(st->radix[k] = bpx__alloc(sizeof(bpx_radix_work))))
                return false;
            st->radix[k]->lines = NULL;
        }
        if (words >= BPX_RADIX_STREAM_WORDS && !st->radix[k]->lines &&
            !(st->radix[k]->lines = bpx__alloc(sizeof(bpx_radix_lines))))
            return false;
    }
    return true;
}

static void fatten_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sap_job *job = context;
    sap_arrays *a = &job->st->a;
    for (int c = begin; c < end; c++)
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            a->fat[i] = a->fat_prev[i] = fatten(&a->cur[i], job->st->margin);
}

// Every box's new fat box (ranges on the workers).
static void fatten_all(const bpx_world *w, sap_state *st)
{
    sap_job job = {.st = st, .n = w->n, .chunks = chunks_for(w, w->n)};
    if (job.chunks == 1)
        fatten_task(0, 1, 0, &job);
    else
        bpx__parallel_for(&w->executor, fatten_task, (int)job.chunks, &job);
}

// The endpoint lists of the fat boxes by radix sort, and from the count of pairs overlapping on
// each axis the rebuild's choice: sweep along the axis with the fewest, unless even that one
// meets too many boxes per box: then the grid. *live: the boxes that are not inert. False when
// memory ran out.
//
// Where the grid is chosen (hundreds of thousands of boxes, dense), the next rebuilds keep the
// choice and leave the lists unmade while the n it was made at is within an eighth of theirs:
// there the lists cost more than the grid (1M boxes, 2 threads: 80-100 ms against 66-82), and
// a million boxes at rest may need no mend before the next rebuild (all fat boxes are made
// together, so the fastest boxes leave together: too many to mend). The first warm cycle that
// must mend (or grow) makes them, so such a cycle is warm but may cost a sort of three lists;
// the choice is counted again each time they are made.
static bool make_lists(bpx_world *w, sap_state *st, uint32_t n, uint32_t *live)
{
    bool parallel = n >= PARALLEL_MIN && w->executor.worker_count > 1;
    if (!reserve_radix(st, parallel ? 3 : 1, 2 * (size_t)n))
        return false;
    sap_job job = {.st = st, .n = n, .chunks = parallel ? 3 : 1}; // chunks: the sorts' memory
    if (parallel)
        bpx__parallel_for(&w->executor, list_task, 3, &job);
    else
        list_task(0, 3, 0, &job);
    const uint64_t *overlaps = job.overlaps;
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (overlaps[k] < overlaps[axis])
            axis = k;
    st->sweep_axis = axis;
    *live = job.live[axis]; // inert boxes are +inf..-inf on every axis
    st->use_grid = (double)overlaps[axis] > BPX_SWEEP_MAX_CANDIDATES * *live;
    st->counted_n = n;
    st->listed = true;
    st->indexed = false;
    st->counters.lists_made++;
    return true;
}

// Rebuilds the fat boxes, the lists (see make_lists) and the fat pairs by one sweep or the grid
// (into st->fat_pairs), and the exact pairs into block 0.
static bpx_status full_rebuild(bpx_world *w, sap_state *st)
{
    uint32_t n = w->n;
    sap_arrays *a = &st->a;
    if (!st->checked) // for cur (a warm attempt this cycle has made it)
        check_boxes(w, st);
    set_margins(w, st);
    fatten_all(w, st);
    uint32_t live = 0;
    st->listed = st->indexed = false;
    bool counted = st->use_grid && n - n / 8 <= st->counted_n && st->counted_n <= n + n / 8;
    if (!counted && !make_lists(w, st, n, &live))
        return BPX_ERR_OUT_OF_MEMORY;
    int axis = st->sweep_axis;
    if (!st->use_grid) {
        const uint64_t *ends = a->ends[axis];
        const uint32_t inf_key = coord_key(1.0f / 0.0f);
        uint32_t k = 0;
        for (size_t e = 0; e < 2 * (size_t)n; e++) // the minima of the live boxes, in order
            if (!(ends[e] & MAX_BIT) && (uint32_t)(ends[e] >> 32) != inf_key)
                a->sorted_ids[k++] = (uint32_t)ends[e] & BOX_MASK;
    }
    bpx_status status = st->use_grid ? grid_pairs(w, st, a->fat) : sweep(w, st, a->fat, axis, live);
    if (status != BPX_OK)
        return status;
    // Few boxes of even extents on the swept axis: warm cycles scan (see mend_scan).
    double sum = 0.0;
    float widest = 0.0f;
    if (!st->use_grid) // else a->lo and a->hi hold the grid's input, not the sweep order
        for (uint32_t k = 0; k < live; k++) {
            double e = (double)a->hi[0][k] - (double)a->lo[0][k];
            sum += e;
            widest = float_above(e) > widest ? float_above(e) : widest;
        }
    st->scan_width = widest;
    st->scan = !st->use_grid && n <= SCAN_MAX_BOXES &&
               (double)widest <= SCAN_WIDTH_RATIO * (live ? sum / live : 0.0);
    if (st->scan)
        scan_list(st, n, live);

    // Keep the fat pairs, with room for the warm cycles to come; block 0 gets the exact ones.
    bpx_pair_list *found = &w->blocks[0].hits;
    size_t room = found->count + found->count / 2 + FIRST_CHANGES;
    size_t changes = FIRST_CHANGES + n / 16;
    st->fat_pairs.count = st->changes.count = 0;
    if (!bpx__list_reserve(&st->fat_pairs, room) || !bpx__list_reserve(&st->merged, room) ||
        !bpx__list_reserve(&st->changes, changes) || !bpx__list_reserve(&st->spare, changes))
        return BPX_ERR_OUT_OF_MEMORY;
    for (int k = 0; k < 3; k++) {
        st->axis_changes[k].count = 0;
        if (!bpx__list_reserve(&st->axis_changes[k], changes))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    if (found->count)
        memcpy(st->fat_pairs.pairs, found->pairs, found->count * sizeof(bpx_pair));
    st->fat_pairs.count = found->count;
    found->count = filter_pairs(w, st, found->pairs);
    return BPX_OK;
}

// The pairs by one sweep over the minima of the sweep axis the lists last chose, radix sorted
// (or by the grid, if they chose it); no endpoint lists (the next cycle will not mend).
static bpx_status lite_rebuild(bpx_world *w, sap_state *st)
{
    uint32_t n = w->n;
    sap_arrays *a = &st->a;
    if (!reserve_radix(st, 1, n))
        return BPX_ERR_OUT_OF_MEMORY;
    if (!st->checked) // for cur (a warm attempt this cycle has made it)
        check_boxes(w, st);
    if (st->use_grid)
        return grid_pairs(w, st, a->cur);
    const uint32_t inf_key = coord_key(1.0f / 0.0f);
    uint64_t *words = a->words[0], *sorted = a->words[1];
    for (uint32_t i = 0; i < n; i++)
        words[i] = end_word(coord_key(a->cur[i].min[st->sweep_axis]), i);
    bpx__radix_sort_words(words, sorted, n, st->radix[0]);
    uint32_t live = n;
    while (live > 0 && (uint32_t)(sorted[live - 1] >> 32) == inf_key) // inert: min +inf, last
        live--;
    for (uint32_t k = 0; k < live; k++)
        a->sorted_ids[k] = (uint32_t)sorted[k];
    return sweep(w, st, a->cur, st->sweep_axis, live);
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
    st->checked = false;
    bpx_status status = BPX_OK;
    if (warm) {
        mend_result r = warm_cycle(w, st);
        if (r == MEND_NO_MEMORY)
            return BPX_ERR_OUT_OF_MEMORY;
        st->give_ups = r == MEND_DONE ? 0 : st->give_ups + 1;
        st->waited = 0;
        warm = r == MEND_DONE;
    } else {
        st->waited++;
    }
    bool lists = true; // the lists describe this cycle at its end
    if (warm) {
        // Block 0 gets the exact pairs; the other blocks, left by the last rebuild, are
        // dropped.
        status = bpx__emitter_reserve_blocks(w, 1);
        if (status != BPX_OK)
            return status;
        bpx_block *out = &w->blocks[0];
        out->hits.count = 0;
        if (!bpx__list_reserve(&out->hits, st->fat_pairs.count))
            return BPX_ERR_OUT_OF_MEMORY;
        out->hits.count = filter_pairs(w, st, out->hits.pairs);
        out->tests = st->fat_pairs.count;
        out->status = BPX_OK;
        w->block_count = 1;
        w->planned_n = UINT32_MAX;
    } else {
        // The lists are wanted only when the next cycle may mend: while coherent, or on the
        // cycle before a retry.
        lists = st->give_ups < 2 || st->waited + 1 >= RETRY_EVERY;
        status = lists ? full_rebuild(w, st) : lite_rebuild(w, st);
        if (status != BPX_OK)
            return status;
    }
    w->stats.rebuilt = !warm;
    st->n = n;
    st->valid = lists;
    return BPX_OK;
}

bpx_sap_counters bpx__sap_counters(const bpx_world *w)
{
    const sap_state *st = w->backend == &bpx__sap_backend ? w->backend_state : NULL;
    return st ? st->counters : (bpx_sap_counters){0, 0};
}

static bool sap_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size,
             "3-axis fat endpoint lists mended by insertion; rebuild sweep %s (grid when dense)",
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
