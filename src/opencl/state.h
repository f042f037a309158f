// The opencl backend's state (one per world) and the calls its files share: buffers.c (device
// memory, events, launches, transfers), update.c (the updater), brute.c, sweep.c and tree.c (the
// comparator's three paths), sort.c (scans and sorts), opencl.c (the cycle and the public calls),
// resident.c (cycles whose pairs stay on the device).

#pragma once

#include <string.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "device.h"
#include "opencl_internal.h"

enum kernel_id {
    K_UPDATE,
    K_CONVERT,
    K_VALIDATE,
    K_BRUTE_COUNT,
    K_BRUTE_EMIT,
    K_SCAN_REDUCE,
    K_SCAN_SUMS,
    K_SCAN_APPLY,
    K_RADIX_COUNT,
    K_RADIX_SCATTER,
    K_SWEEP_KEYS,
    K_SWEEP_GATHER,
    K_SWEEP_COUNT,
    K_SWEEP_WRITE,
    K_SWEEP_INTERLEAVE,
    K_BRUTE_SMALL,
    K_RADIX_COUNT64,
    K_RADIX_SCATTER64,
    K_TREE_RESET,
    K_TREE_BOUNDS,
    K_TREE_CODES,
    K_TREE_BUILD,
    K_TREE_REFIT,
    K_TREE_WALK,
    K_TREE_UNPACK,
    K_VALIDATE_CENTRES,
    K_TREE_COUNT,
    K_COUNT
};

enum {
    // Commands whose events a cycle keeps (flushed, a wait, when full): a device-resident cycle
    // has at most about 140 (the tree at 2^32 boxes: two radix sorts of 32 and 64 bits).
    EVENTS_MAX = 256,
    DEFAULT_PAIR_CAPACITY = 65536,
    // Auto method: the tree from this many boxes on, unless the last cycle found more than
    // DENSE_PAIRS_PER_BOX pairs per box (then ordering the pairs costs more than brute force's
    // second pass). The tree beats the sweep from 4096 boxes on PoCL and its margin grows with
    // n (the sweep's candidates grow like n^(5/3)), so auto no longer takes the sweep; it stays
    // as a forced path. Measured on PoCL: docs/opencl.md.
    TREE_MIN_N = 2048,
    DENSE_PAIRS_PER_BOX = 16,
    // Device bytes per box: keys (2 x 16), per-row count and stash (4 + 16), input (24).
    BYTES_PER_BOX = 2 * 16 + 4 + 4 * BPX_CL_STASH + 24,
    // Streaming keeps two blocks of keys and of input.
    BYTES_PER_STREAMED_BOX = BYTES_PER_BOX + 2 * 16 + 24,
    REGISTER_SLOTS = 4, // 0: brute count, 1: sweep count, 2: scratch scans, 3: tree tests
};

enum { EV_IN, EV_OUT, EV_DEVICE, EV_CLASSES };

typedef enum bpx_cl_source {
    SOURCE_HOST,           // the world's boxes, uploaded as six planes (24 bytes per box)
    SOURCE_CENTRES,        // this cycle's centres (12 bytes per object) + minima kept on the device
    SOURCE_BUFFER,         // the caller's device buffer of bpx_box (nothing uploaded)
    SOURCE_CENTRES_BUFFER, // the caller's device buffer of centres + minima kept on the device
} bpx_cl_source;

// A device-resident cycle's progress (resident.c).
typedef enum bpx_cl_resident_phase {
    RESIDENT_NONE,    // no device cycle's result (none yet, or a host cycle since)
    RESIDENT_PENDING, // enqueued; its count is on its way to resident_host
    RESIDENT_DONE,    // waited for: resident_found and resident_status hold its outcome
} bpx_cl_resident_phase;

typedef struct bpx_cl_buffer {
    cl_mem mem;
    size_t size;
} bpx_cl_buffer;

typedef struct bpx_cl_pinned {
    cl_mem mem;
    void *host;
    size_t size;
} bpx_cl_pinned;

typedef struct bpx_cl_state {
    const bpx_cl_device *dev;
    cl_command_queue queue;
    cl_kernel kernels[K_COUNT];
    unsigned tile;
    size_t first_pair_capacity;
    uint64_t limit; // device bytes this world may use
    uint64_t used;  // device bytes held now

    bpx_cl_source source;
    bool minima_on_device; // the current extents are in `minima`
    cl_mem user_buffer;    // SOURCE_BUFFER, SOURCE_CENTRES_BUFFER (retained)

    bpx_cl_pinned up;         // uploads: six planes, two regions (row block, column block)
    bpx_cl_pinned up_centres; // the centres of the last update_centres
    bpx_cl_pinned down;       // pair read-back
    bpx_cl_pinned reg;        // count registers read-back
    bpx_cl_buffer registers;  // REGISTER_SLOTS ulongs
    bpx_cl_buffer check;      // bpx_validate's answer
    bpx_cl_buffer input, minima;
    bpx_cl_buffer lo, hi, lo_b, hi_b;
    bpx_cl_buffer row_count, stash, group_sum, group_long;
    bpx_cl_buffer pairs;
    // Sort and sweep.
    bpx_cl_buffer keys[2], values[2], sorted_lo, sorted_hi, counts, offsets, sums, hist,
        hist_offsets;
    bpx_cl_buffer pi[2], pj[2];
    // The tree (Morton codes and ids use keys[] and values[] above).
    bpx_cl_buffer leaf_parent, node_parent, nodes, flags, tree_small, walk_tests, pair_keys[2];

    cl_event events[EVENTS_MAX];
    unsigned char event_class[EVENTS_MAX];
    int event_count;
    uint64_t ns[EV_CLASSES];
    uint64_t bytes_in, bytes_out, tests;
    uint64_t last_pairs; // the previous cycle's, for the auto method
    bool pairs_known;    // last_pairs holds a cycle's count (sizes device-resident buffers)
    bool small_off;      // the small-set kernel's pairs did not fit under the memory limit

    uint32_t *row_hist; // streaming: per-row counts of one row block (host)
    size_t row_hist_count;

    // Device-resident cycles (resident.c): the caller's count buffer (one cl_ulong), its pinned
    // copy on the host, and the last such cycle.
    bpx_cl_buffer resident_count;
    bpx_cl_pinned resident_host;
    bpx_cl_resident_phase resident;
    cl_ulong resident_capacity; // pairs the cycle could write
    uint64_t resident_found;    // RESIDENT_DONE: its count
    bpx_status resident_status; // RESIDENT_DONE: its outcome

    bpx__opencl_counters counters;
} bpx_cl_state;

#define CL_CHECK(st, call, what)                                                                   \
    do {                                                                                           \
        cl_int check_err_ = (call);                                                                \
        if (check_err_ != CL_SUCCESS)                                                              \
            return bpx__cl_cl_fail((st), check_err_, (what));                                      \
    } while (0)

#define TRY(expr)                                                                                  \
    do {                                                                                           \
        bpx_status try_status_ = (expr);                                                           \
        if (try_status_ != BPX_OK)                                                                 \
            return try_status_;                                                                    \
    } while (0)

static inline size_t round_up(size_t value, size_t multiple)
{
    return (value + multiple - 1) / multiple * multiple;
}

typedef struct bpx_cl_arg {
    size_t size;
    const void *value;
} bpx_cl_arg;

#define ARG(x) ((bpx_cl_arg){sizeof(x), &(x)})

// ---------------------------------------------------------------------------------------------
// Across the files of this folder

// buffers.c: errors, events, device and pinned buffers, launches and transfers, the state.
bpx_status bpx__cl_cl_fail(bpx_cl_state *st, cl_int err, const char *what);
void bpx__cl_events_flush(bpx_cl_state *st);
void bpx__cl_dbuf_release(bpx_cl_state *st, bpx_cl_buffer *b);
bpx_status bpx__cl_dbuf_reserve(bpx_cl_state *st, bpx_cl_buffer *b, size_t size);
bpx_status bpx__cl_pinned_reserve(bpx_cl_state *st, bpx_cl_pinned *p, size_t size);
bpx_status bpx__cl_launch(bpx_cl_state *st, int k, size_t global, size_t local, int arg_count,
                          const bpx_cl_arg *args);
bpx_status bpx__cl_write_buffer(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size,
                                const void *host, bool blocking);
bpx_status bpx__cl_fill(bpx_cl_state *st, cl_mem mem, unsigned char byte, size_t size);
bpx_status bpx__cl_copy(bpx_cl_state *st, cl_mem src, size_t src_offset, cl_mem dst, size_t size);
bpx_status bpx__cl_read_buffer(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size,
                               void *host);
bpx_status bpx__cl_read_later(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size, void *host);
bpx_status bpx__cl_read_register(bpx_cl_state *st, cl_uint slot, uint64_t *value);
bpx_status bpx__cl_read_pairs(bpx_cl_state *st, cl_mem pairs, size_t count, bpx_pair_list *out);
void bpx__cl_state_free(bpx_cl_state *st);
/// The backend's state, made on first use for the world's definition.
bpx_status bpx__cl_state_get(void **state, const bpx_world_def *def, bpx_cl_state **out);
// update.c: the updater.
bpx_status bpx__cl_upload_minima(bpx_cl_state *st, const bpx_cycle *cycle);
bpx_status bpx__cl_upload_keys(bpx_cl_state *st, const bpx_cycle *cycle, uint32_t first,
                               uint32_t count, uint32_t padded, size_t region_offset,
                               bpx_cl_buffer *lo, bpx_cl_buffer *hi);
// brute.c: the tiled comparator, whole, small or streamed.
bpx_status bpx__cl_brute_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block);
bpx_status bpx__cl_brute_small(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block);
bpx_status bpx__cl_brute_streamed(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block,
                                  uint32_t block_boxes);
// The device-resident form of each path (resident.c runs them): the whole set, room for at
// least `need` pairs (DEVICE_MEMORY, before anything is enqueued, past the memory limit),
// *capacity the pairs the cycle may write into st->pairs, the count to the cl_ulong at `count`.
// Nothing is read back.
bpx_status bpx__cl_brute_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                  cl_mem count, cl_ulong *capacity);
// sort.c: scans and radix sorts.
unsigned bpx__cl_bits_for(uint32_t max_value);
bpx_status bpx__cl_sum(bpx_cl_state *st, cl_mem in, uint32_t count, cl_uint slot);
bpx_status bpx__cl_scan(bpx_cl_state *st, cl_mem in, uint32_t count, cl_mem out, cl_uint slot);
bpx_status bpx__cl_radix_sort(bpx_cl_state *st, bpx_cl_buffer *keys, bpx_cl_buffer *values,
                              uint32_t count, unsigned bits, int *result);
bpx_status bpx__cl_radix_sort64(bpx_cl_state *st, bpx_cl_buffer *keys, uint32_t count,
                                unsigned bits, int *result);
// sweep.c: sort and sweep.
bpx_status bpx__cl_sweep_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block);
bpx_status bpx__cl_sweep_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                  cl_mem count, cl_ulong *capacity);
// tree.c: the linear BVH.
bpx_status bpx__cl_tree_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block);
bpx_status bpx__cl_tree_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                 cl_mem count, cl_ulong *capacity);
// opencl.c: what the host's cycle and the device-resident one share.
bpx_status bpx__cl_check_source(bpx_cl_state *st, const bpx_cycle *cycle);
bool bpx__cl_streamed(const bpx_cl_state *st, const bpx_cycle *cycle, uint32_t *forced);
int bpx__cl_method(const bpx_cl_state *st, const bpx_cycle *cycle);
void bpx__cl_release_sweep_buffers(bpx_cl_state *st);
// resident.c: waits for a pending device-resident cycle and keeps its outcome for
// bpx_opencl_finish (OK at once when none is pending). Every call that uses the queue's
// staging or events first settles.
void bpx__cl_resident_settle(bpx_cl_state *st);
// resident.c: the device-resident calls (core/backend.h's bpx_device_ops).
bpx_status bpx__cl_collide_device(void **state, bpx_cycle *cycle, void *stream);
bpx_status bpx__cl_device_pairs(void **state, bpx_cycle *cycle, void **pairs, void **count,
                                size_t *capacity);
bpx_status bpx__cl_finish(void **state, bpx_cycle *cycle, uint64_t *found);
