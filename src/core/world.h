// The world's private state, shared by the interface, the updater, the backends and the emitter.
#pragma once

#include "backend.h"
#include "pair_set.h"
#include "periodic.h"

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
    bpx_box_arrays grown; // with contact margins: the boxes grown by end_margin / 2, compared

    // Initialisation-phase data: origin-centred minima, one array per axis.
    uint32_t extent_count;
    uint32_t extent_capacity;
    bool extents_loaded;
    float *minima[3];

    // Collision emitter: the backend's pair sink, then the merged list.
    bpx_emitter emitter;
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
    // Per id, each NULL until first set (objects.c's columns): filters, groups, user data, and
    // how many excluded pairs the id is in (0 lets the filter skip the set's lookup).
    uint32_t *category;
    uint32_t *mask;
    int32_t *group;
    uint64_t *user_data;
    uint32_t *exclusions;
    bpx_pair_set excluded; // pairs that never pair (bpx_world_exclude_pairs)

    // The pair filter (bpx_world_set_pair_filter): asked once per pair as it begins. candidates
    // are the last cycle's pairs that passed the other filters, rejected those it refused (both
    // sorted); fresh_* are this cycle's, swapped in when it succeeds.
    bpx_pair_filter_fn *pair_filter;
    void *pair_filter_context;
    bpx_pair_list candidates, rejected, fresh_candidates, fresh_rejected;
    bool in_callback; // a pair filter runs: calls that change the world are refused

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

    bpx_periodic periodic; // def.period set: the image search's state (periodic.c)
    // A periodic world's set_boxes: the boxes' least lo per axis and largest |coordinate|,
    // valid while boxes_version is bounds_version.
    float bounds_low[3], bounds_most;
    uint64_t bounds_version;
    bool bounds_set;

    // bpx_world_set_boxes64: the float64 boxes, which decide each candidate of the float32
    // boxes (rounded outward) that the comparator sees.
    bpx_box64 *boxes64;
    uint32_t boxes64_capacity;
    bool boxes64_set;

    bpx_cycle_stats stats;
    bpx_error error;

    // bpx_world_def.profile: the cycle's stages as they run, copied into stats at its end; and
    // the updater's last call, which the next collide's profile starts with.
    bpx_profile profile;
    bpx_stage_stats update_stage;
};

static inline bpx_soa bpx__world_soa(const bpx_world *w)
{
    const bpx_box_arrays *b = &w->boxes;
    return (bpx_soa){{b->lo[0], b->lo[1], b->lo[2]}, {b->hi[0], b->hi[1], b->hi[2]}, w->n};
}

static inline bpx_extents bpx__world_extents(const bpx_world *w)
{
    if (!w->extents_loaded)
        return (bpx_extents){{NULL, NULL, NULL}, 0};
    return (bpx_extents){{w->minima[0], w->minima[1], w->minima[2]}, w->extent_count};
}

/// Contact margins are on (bpx_world_def.begin_margin / end_margin; end_margin >= begin_margin
/// once the world is made).
static inline bool bpx__world_margins(const bpx_world *w)
{
    return w->def.end_margin > 0.0f;
}

/// The backend's view of the world for one call (core/backend.h).
static inline bpx_cycle bpx__world_cycle(bpx_world *w)
{
    return (bpx_cycle){
        .boxes = bpx__world_soa(w),
        .n = w->n,
        .boxes_version = w->boxes_version,
        .inert_ids = w->dead != NULL,
        .extents = bpx__world_extents(w),
        .def = &w->def,
        .simd = w->simd,
        .executor = &w->executor,
        .sink = &w->emitter,
        .error = &w->error,
        .profile = w->def.profile ? &w->profile : NULL,
    };
}

// Queries (src/query/query.c).
typedef struct bpx_query_state bpx_query_state;
void bpx__query_free(bpx_world *w);
/// Whether a bpx_world_query_each callback of this world is running now.
bool bpx__query_callbacks_running(const bpx_world *w);

/// Tells the backend that every box was replaced (set_boxes does; restore too).
void bpx__world_boxes_replaced(bpx_world *w);

/// The start of every call that changes the world (or its query results): NULL_ARGUMENT for no
/// world; the world's error cleared; BAD_STATE while a query callback of the world runs (the
/// call comes from inside one, or races the readers). `call` names the call in the message.
bpx_status bpx__world_enter(bpx_world *w, const char *call);
