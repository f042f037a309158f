// The world's private state, shared by the interface, the updater, the backends and the emitter.
#pragma once

#include "bpx/bpx.h"
#include "parallel/pool.h"

/// Box arrays are padded (to a multiple of this many boxes, plus this many) with boxes that can
/// never overlap anything (min = +inf, max = -inf), so comparators read whole groups of vectors
/// (4 steps of the widest, 16 lanes) from any vector-aligned start and need no tail loop.
#define BPX_PAD_LANES 64

/// Boxes in structure-of-arrays form: lo[axis][i], hi[axis][i], 64-byte aligned, padded.
typedef struct bpx_soa {
    const float *lo[3];
    const float *hi[3];
    uint32_t n;
} bpx_soa;

/// Six SoA arrays with their capacity in boxes (padding included).
typedef struct bpx_box_arrays {
    float *lo[3];
    float *hi[3];
    uint32_t capacity;
} bpx_box_arrays;

/// A growable list of pairs; memory is kept between cycles.
typedef struct bpx_pair_list {
    bpx_pair *pairs;
    size_t count;
    size_t capacity;
} bpx_pair_list;

/// One slot of the collision emitter: a run of comparator rows [row_begin, row_end) and the hits
/// found there, in (i, j) order. Slots depend on n only, never on threads, and are concatenated
/// in order, so the output is the same for any thread count or schedule. `stage` is scratch for
/// a comparator that finds hits of several rows at once and must put them back in row order.
typedef struct bpx_block {
    uint32_t row_begin;
    uint32_t row_end;
    bpx_pair_list hits;
    bpx_pair_list stage;
    uint64_t tests;
    bpx_status status;
} bpx_block;

/// Boxes sorted by min x, in SoA form, with the original index of each; padded after n with
/// boxes whose min x is +inf, so a sweep stops there without a bounds check.
typedef struct bpx_sorted {
    const float *lo[3];
    const float *hi[3];
    const uint32_t *id;
    uint32_t n;
} bpx_sorted;

/// A comparator backend: fills the world's blocks for its current boxes.
typedef struct bpx_backend_impl {
    bpx_backend id;
    const char *name;
    /// Whether usable here; on false, *reason says why. detail gets ISA / lanes / device.
    bool (*query)(const bpx_world_def *def, const char **reason, char *detail, size_t size);
    bpx_status (*compare)(bpx_world *world);
    /// Frees world->backend_state (may be NULL when the backend keeps none).
    void (*destroy)(bpx_world *world);
    /// Optional: told after set_boxes / load_extents (centres NULL) or update_centres (the
    /// cycle's 3n validated centres) changed the boxes, for a backend that runs the updater
    /// itself (opencl: only the centres cross the link). Must not fail; may ignore the call.
    void (*boxes_set)(bpx_world *world, const float *centres);
} bpx_backend_impl;

struct bpx_world {
    bpx_world_def def;
    const bpx_backend_impl *backend;
    bpx_simd simd;
    bpx_executor executor;

    // Current boxes (updater output, comparator input), and a spare set the updater writes and
    // checks in one pass before swapping it in, so that bad input leaves the world unchanged.
    uint32_t n;
    bpx_box_arrays boxes;
    bpx_box_arrays spare;

    // Initialisation-phase data: origin-centred minima, one array per axis.
    uint32_t extent_count;
    uint32_t extent_capacity;
    bool extents_loaded;
    float *minima[3];

    // Collision emitter.
    bpx_block *blocks;
    int block_count;
    int block_capacity;
    uint32_t planned_n; // n the blocks were planned for (UINT32_MAX: none)
    bpx_pair_list pairs; // merged output owned by the world
    bool merged;         // pairs holds the last cycle (else only the blocks do)
    bool result_valid;   // the blocks hold a complete last cycle

    void *backend_state; // owned by the backend, freed by its destroy hook

    // Objects added and removed one by one (objects.c). Removed ids hold inert boxes (min +inf,
    // max -inf, like the padding) until reused; ids wait in `pending` until the next collide
    // has reported their pairs as ended, then in `free` for reuse.
    uint32_t object_capacity; // length of the per-id arrays below
    uint8_t *dead;            // per id: 0 live, 1 removed
    uint32_t *pending_ids;
    uint32_t pending_count;
    uint32_t *free_ids;
    uint32_t free_count;
    uint32_t *category; // per id; NULL until filters are first set
    uint32_t *mask;

    // Events (track_events): the previous cycle's pairs, and what changed.
    bpx_pair_list previous;
    bpx_pair_list began;
    bpx_pair_list ended;
    bool events_valid;

    // Queries (src/query/): their tree and results, made by the first query. boxes_version
    // counts every change to the boxes, so the tree knows when it is stale.
    struct bpx_query_state *query;
    uint64_t boxes_version;
    bool boxes_on_device; // the boxes live in a device buffer (opencl, cuda): no queries

    bpx_cycle_stats stats;
    bpx_error error;
};

/// The order of every pair list: by i, then j.
static inline bool bpx__pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

static inline bpx_soa bpx__world_soa(const bpx_world *w)
{
    const bpx_box_arrays *b = &w->boxes;
    return (bpx_soa){{b->lo[0], b->lo[1], b->lo[2]}, {b->hi[0], b->hi[1], b->hi[2]}, w->n};
}

// Queries (src/query/query.c).
typedef struct bpx_query_state bpx_query_state;
void bpx__query_free(bpx_world *w);

// Emitter (emitter.c).
/// Makes room for `count` blocks (new ones zeroed), for comparators that lay out their own.
bpx_status bpx__emitter_reserve_blocks(bpx_world *w, int count);
/// For comparators that emit one ordered list: one block over every row (planned again when n
/// changed), emptied; *out is that block.
bpx_status bpx__emitter_one_block(bpx_world *w, bpx_block **out);
/// Splits rows 0..n-1 into blocks of about equal pair tests; one block when `single`.
bpx_status bpx__emitter_plan(bpx_world *w, bool single);
/// Splits rows 0..n-1 into blocks of `rows` rows each (for comparators whose rows cost about
/// the same; blocks are claimed dynamically, which evens out the rest).
bpx_status bpx__emitter_plan_rows(bpx_world *w, uint32_t rows);
/// Makes room for `extra` more pairs (grows geometrically; kept across cycles).
bool bpx__list_reserve(bpx_pair_list *list, size_t extra);
/// Appends src to dst; false when memory ran out.
bool bpx__list_append(bpx_pair_list *dst, const bpx_pair_list *src);
/// Total hits over blocks, or the first block error.
bpx_status bpx__emitter_total(const bpx_world *w, size_t *total);
/// For comparators whose hits come out of order (sweeps, grids): gathers every block's hits,
/// puts them in (i, j) order (two stable counting sorts, O(n + pairs); counts holds n + 1
/// words) and hands the result to block 0, the other blocks left empty. a and b are scratch
/// lists kept by the caller between cycles.
bpx_status bpx__emitter_sort_blocks(bpx_world *w, bpx_pair_list *a, bpx_pair_list *b,
                                    uint32_t *counts);
/// Concatenates the blocks, in order, into out (which holds at least the total).
void bpx__emitter_merge(const bpx_world *w, bpx_pair *out);
void bpx__emitter_free(bpx_world *w);
/// Frees every block's hits and the merged list, after a cycle that ran out of memory or pairs:
/// what the failed cycle grew them to is given back, and the next cycle starts small again.
void bpx__emitter_release(bpx_world *w);

// Backends.
extern const bpx_backend_impl bpx__reference_backend;
extern const bpx_backend_impl bpx__brute_backend;
extern const bpx_backend_impl bpx__prune_backend;
extern const bpx_backend_impl bpx__sap_backend;
extern const bpx_backend_impl bpx__grid_backend;
extern const bpx_backend_impl bpx__auto_backend;
/// The backend auto ran last cycle (before the first: the one it will pick for n boxes).
bpx_backend bpx__auto_choice(const bpx_world *w);
extern const bpx_backend_impl bpx__model_backend;
extern const bpx_backend_impl bpx__opencl_backend;
extern const bpx_backend_impl bpx__cuda_backend;
extern const bpx_backend_impl bpx__hybrid_backend;
