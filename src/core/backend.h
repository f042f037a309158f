// The backend contract: what a comparator backend sees, what it may keep, and what it gives back.
//
// A backend realises the paper's comparator (and, on a device, the updater and the emitter's
// ordering too). It is a table of functions (bpx_backend_impl) over an opaque state of its own,
// and it sees the world only through this narrow view, never `struct bpx_world`:
//
//   in      the cycle's boxes (bpx_cycle.boxes: structure of arrays, 64-byte aligned, padded
//           with inert boxes to a whole number of BPX_PAD_LANES, all finite with min <= max),
//           the world's definition (read only: options, thread count), the SIMD width, the
//           workers (bpx__parallel_for on bpx_cycle.executor), and a version number that
//           changes whenever the boxes change;
//   kept    *state, made by the backend on its first call and freed by its destroy hook; the
//           backend is told when the boxes were replaced and how (boxes_set), for a backend
//           that keeps them elsewhere (a device);
//   out     the cycle's pairs, through the pair sink (bpx_emitter, below): hits in (i, j)
//           order block by block, or in any order followed by bpx__emitter_sort_blocks; a
//           report of what the cycle did beyond its pairs (bpx_backend_report); a status, and
//           where the backend can name what failed (a device box and its axis), an error
//           written with bpx__error into bpx_cycle.error.
//
// The world owns everything else and applies it around the backend: objects and their ids
// (a removed id is an inert box, which no backend can pair), filters (applied to the sink's
// hits after compare), events, queries, the merged pair list and the world's flags. `auto`
// composes the CPU backends through this same contract: it keeps each delegate's state slot
// and calls its functions, never looking inside.
#pragma once

#include "bpx/bpx.h"
#include "core/profile.h"  // bpx_profile, a cycle's stages when profiled
#include "core/validate.h" // bpx__error, the error reporter
#include "parallel/pool.h"

/// Box arrays are padded (to a multiple of this many boxes, plus this many) with boxes that can
/// never overlap anything (min = +inf, max = -inf: "inert" boxes), so comparators read whole
/// groups of vectors (4 steps of the widest, 16 lanes) from any vector-aligned start and need no
/// tail loop.
#define BPX_PAD_LANES 64

/// Boxes in structure-of-arrays form: lo[axis][i], hi[axis][i], 64-byte aligned, padded.
typedef struct bpx_soa {
    const float *lo[3];
    const float *hi[3];
    uint32_t n;
} bpx_soa;

/// Six SoA arrays with their capacity in boxes (padding included): the world's boxes, and boxes
/// of a backend's own (hybrid's sides), made with bpx__box_arrays_* (boxes.c). One block:
/// lo[0] is its start, 6 * capacity floats (the spare set is lent whole as a cycle's scratch).
typedef struct bpx_box_arrays {
    float *lo[3];
    float *hi[3];
    uint32_t capacity;
} bpx_box_arrays;

/// Boxes plus padding: n rounded up to whole groups of BPX_PAD_LANES, plus one more group.
uint32_t bpx__boxes_padded(uint32_t n);
/// Makes b hold n boxes plus padding; contents are not kept. False when memory ran out (b is
/// then as it was).
bool bpx__box_arrays_reserve(bpx_box_arrays *b, uint32_t n);
/// Pads b after n boxes with inert ones.
void bpx__box_arrays_pad(bpx_box_arrays *b, uint32_t n);
void bpx__box_arrays_free(bpx_box_arrays *b);

/// A growable list of pairs; memory is kept between cycles.
typedef struct bpx_pair_list {
    bpx_pair *pairs;
    size_t count;
    size_t capacity;
} bpx_pair_list;

/// One slot of the pair sink: a run of comparator rows [row_begin, row_end) (row i holds the
/// pairs (i, j), j > i) and the hits found there, in (i, j) order. Slots depend on n only, never
/// on threads, and are concatenated in order, so the output is the same for any thread count or
/// schedule. `stage` is scratch for a comparator that finds hits of several rows at once and
/// must put them back in row order.
typedef struct bpx_block {
    uint32_t row_begin;
    uint32_t row_end;
    bpx_pair_list hits;
    bpx_pair_list stage;
    uint64_t tests;
    bpx_status status;
} bpx_block;

/// The pair sink: the collision emitter's blocks. A backend either plans blocks over the rows
/// (bpx__emitter_plan, _plan_rows) and fills each in (i, j) order from its workers, or takes
/// one block (bpx__emitter_one_block) for a list it orders itself, or lays out blocks of its own
/// (bpx__emitter_own_blocks) whose hits come in any order and are put in order by
/// bpx__emitter_sort_blocks. The world then joins the blocks
/// in block order into the one ordered list.
typedef struct bpx_emitter {
    bpx_block *blocks;
    int block_count;
    int block_capacity;
    uint32_t planned_n; // n the blocks were planned for (UINT32_MAX: none, or a backend's own)
} bpx_emitter;

/// What a cycle did beyond its pairs, for bpx_cycle_stats; zero unless the backend says.
typedef struct bpx_backend_report {
    bool rebuilt;   // state kept between cycles was rebuilt from scratch
    bool resident;  // finish: a device-resident cycle's outcome (its pair count) is reported
    bool timed;     // finish: and its tests, times and bytes below
    uint64_t tests; // a device-resident cycle's pair tests (a host cycle's are the blocks')
    uint64_t transfer_in_ns, transfer_out_ns, device_ns;
    uint64_t bytes_in, bytes_out;
    float device_share; // hybrid: the boxes' share given to the device
} bpx_backend_report;

/// The paper's initialisation-phase data: each object's origin-centred minima, minima[axis][i],
/// for count objects (count 0: none loaded; the boxes came whole).
typedef struct bpx_extents {
    const float *minima[3];
    uint32_t count;
} bpx_extents;

/// One cycle, as a backend sees it.
typedef struct bpx_cycle {
    bpx_soa boxes;                // the cycle's boxes; n = boxes.n
    uint32_t n;                   // boxes.n
    uint64_t boxes_version;       // changes whenever the boxes do
    bool inert_ids;               // some ids are removed objects (inert boxes the caller chose)
    bpx_extents extents;          // for a backend that runs the updater itself
    const bpx_world_def *def;     // the world's definition (worker_count resolved)
    bpx_simd simd;                // the SIMD width to use (resolved)
    const bpx_executor *executor; // the workers
    bpx_emitter *sink;            // where the pairs go
    bpx_error *error;             // a backend that can name what failed writes it here
    bpx_backend_report report;    // out
    bpx_profile *profile;         // bpx_world_def.profile: the stages go here; else NULL
    // Memory the backend may use during this call only, contents not kept (the world's spare
    // boxes, dead until the next update writes them whole); NULL when none.
    void *scratch;
    size_t scratch_bytes;
} bpx_cycle;

/// How the boxes were replaced (told to boxes_set): by whole boxes (set_boxes, or objects added,
/// removed or moved by id), by newly loaded extents, or by the cycle's centres (the paper's
/// updating phase: centres[3 i + axis], each box = centre ± minima[axis][i]).
typedef struct bpx_boxes_change {
    const float *centres; // NULL unless by centres
    bpx_extents extents;
    uint64_t boxes_version;
    bool inert_ids;
} bpx_boxes_change;

/// The calls of a device backend (include/bpx/opencl.h, cuda.h, alike): the caller's boxes or
/// centres already in device memory in, the pairs left there. The world makes the checks of its
/// own state (objects by id, filters, events, loaded extents) and keeps its books (the boxes on
/// the device, the host's pairs no longer the last cycle's, stats) around them (core/device.c).
/// Each sees the same view as compare; `state` is the backend's (made when NULL).
typedef struct bpx_device_ops {
    /// Checks the caller's n boxes (bpx_box each) or, with `centres`, n centres (3 floats each,
    /// with cycle->extents), naming a bad one in cycle->error. Changes nothing.
    bpx_status (*check_input)(void **state, bpx_cycle *cycle, void *input, uint32_t n,
                              bool centres);
    /// Takes checked input for the cycles to come (cycle->boxes_version is the world's new one).
    /// Boxes are always taken; centres may fail to be (naming why in cycle->error), and then
    /// nothing changed.
    bpx_status (*use_input)(void **state, bpx_cycle *cycle, void *input, uint32_t n, bool centres);
    /// Enqueues a whole cycle on `stream` (NULL: the backend's own) and returns.
    bpx_status (*collide)(void **state, bpx_cycle *cycle, void *stream);
    /// The last device cycle's pairs, count and room (opencl: BAD_STATE when there is none;
    /// cuda: NULL pointers then).
    bpx_status (*pairs)(void **state, bpx_cycle *cycle, void **pairs, void **count,
                        size_t *capacity);
    /// Waits for the last device cycle: *found pairs, its report in cycle->report (resident set
    /// when there was a cycle to report).
    bpx_status (*finish)(void **state, bpx_cycle *cycle, uint64_t *found);
    /// The device's handles: context and device (opencl; NULL on cuda), the queue or stream.
    bpx_status (*handles)(void **state, bpx_cycle *cycle, void **context, void **queue,
                          void **device);
} bpx_device_ops;

/// A comparator backend.
typedef struct bpx_backend_impl {
    bpx_backend id;
    const char *name;
    /// Whether usable here; on false, *reason says why. detail gets ISA / lanes / device.
    bool (*query)(const bpx_world_def *def, const char **reason, char *detail, size_t size);
    /// Finds the cycle's pairs into cycle->sink. *state is this backend's (NULL before its first
    /// call: the backend makes it). On failure nothing partial need be cleaned up: the world
    /// reports no pairs.
    bpx_status (*compare)(void **state, bpx_cycle *cycle);
    /// Frees a state compare made (never called with NULL).
    void (*destroy)(void *state);
    /// Optional: told after the boxes were replaced, for a backend that runs the updater itself
    /// (opencl, cuda: only the centres cross the link). Must not fail; may ignore the call; may
    /// make *state (def and error as for compare).
    void (*boxes_set)(void **state, const bpx_world_def *def, const bpx_boxes_change *change);
    /// A device backend's own calls (NULL for the others).
    const bpx_device_ops *device;
} bpx_backend_impl;

/// The order of every pair list: by i, then j.
static inline bool bpx__pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

// The pair sink's calls (emitter.c).
/// Makes room for `count` blocks (new ones zeroed).
bpx_status bpx__emitter_reserve_blocks(bpx_emitter *e, int count);
/// For comparators that lay out blocks of their own (rows of their own order, cells): `count`
/// blocks, whose rows and hits the backend sets; hits in any order then go through
/// bpx__emitter_sort_blocks, or a backend that orders its own leaves them (i, j)-ordered.
bpx_status bpx__emitter_own_blocks(bpx_emitter *e, int count);
/// For comparators that emit one ordered list: one block over every row (planned again when n
/// changed), emptied; *out is that block.
bpx_status bpx__emitter_one_block(bpx_emitter *e, uint32_t n, bpx_block **out);
/// Splits rows 0..n-1 into blocks of about equal pair tests; one block when `single`.
bpx_status bpx__emitter_plan(bpx_emitter *e, uint32_t n, bool single);
/// Splits rows 0..n-1 into blocks of `rows` rows each (for comparators whose rows cost about
/// the same; blocks are claimed dynamically, which evens out the rest).
bpx_status bpx__emitter_plan_rows(bpx_emitter *e, uint32_t n, uint32_t rows);
/// Makes room for `extra` more pairs (grows geometrically; kept across cycles).
bool bpx__list_reserve(bpx_pair_list *list, size_t extra);
/// Appends src to dst; false when memory ran out.
bool bpx__list_append(bpx_pair_list *dst, const bpx_pair_list *src);
/// Frees a list's memory.
void bpx__list_free(bpx_pair_list *list);
/// Total hits over blocks, or the first block error.
bpx_status bpx__emitter_total(const bpx_emitter *e, size_t *total);
/// For comparators whose hits come out of order (sweeps, grids): gathers every block's hits,
/// puts them in (i, j) order (two stable counting sorts, O(n + pairs); counts holds n + 1
/// words) and hands the result to block 0, the other blocks left empty. a and b are scratch
/// lists kept by the caller between cycles.
bpx_status bpx__emitter_sort_blocks(bpx_emitter *e, uint32_t n, bpx_pair_list *a, bpx_pair_list *b,
                                    uint32_t *counts);
/// Concatenates the blocks, in order, into out (which holds at least the total).
void bpx__emitter_merge(const bpx_emitter *e, bpx_pair *out);
void bpx__emitter_free(bpx_emitter *e);
/// Frees every block's hits, after a cycle that ran out of memory or pairs: what the failed
/// cycle grew them to is given back, and the next cycle starts small again.
void bpx__emitter_release(bpx_emitter *e);

/// A test hook for a backend's own counters: the world's backend state when its backend is
/// `backend`, else NULL (world.c).
const void *bpx__world_backend_state(const bpx_world *w, const bpx_backend_impl *backend);

// The backends.
extern const bpx_backend_impl bpx__reference_backend;
extern const bpx_backend_impl bpx__brute_backend;
extern const bpx_backend_impl bpx__prune_backend;
extern const bpx_backend_impl bpx__sap_backend;
extern const bpx_backend_impl bpx__grid_backend;
extern const bpx_backend_impl bpx__auto_backend;
/// The backend auto ran last (before the first cycle: the one it will pick for n boxes), given
/// auto's state (NULL before its first cycle).
bpx_backend bpx__auto_choice(const void *state, uint32_t n);
extern const bpx_backend_impl bpx__model_backend;
extern const bpx_backend_impl bpx__opencl_backend;
extern const bpx_backend_impl bpx__cuda_backend;
extern const bpx_backend_impl bpx__hybrid_backend;
extern const bpx_backend_impl bpx__rtl_backend;
