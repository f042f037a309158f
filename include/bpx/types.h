// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// Plain data types: boxes, pairs, backends, world definition, statistics.
#pragma once

#include <stdbool.h>

#include "base.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Largest box count a world or one-shot call accepts. Pair indices are 32-bit and pair counts
/// 64-bit (size_t), so this is a sanity bound, not a format limit: it keeps every count of boxes
/// plus padding, and every byte size of a per-box array, far from wrapping.
///
/// Limits, each answered by a status and a message (test/test_limits.c), never by a wrapped
/// index or a silent truncation:
/// - More than BPX_MAX_BOXES boxes requested (up to 2^32 - 1): set_boxes, load_extents,
///   add_boxes (old count + added), bpx_find_pairs and bpx_validate_boxes return
///   BPX_ERR_TOO_MANY_BOXES naming the count, before reading the array; a capacity_hint past
///   it makes bpx_world_create return BPX_ERR_INVALID_ARGUMENT.
/// - Memory: a box costs about 56 bytes in a world (two sets of six floats, the per-id arrays)
///   plus what the backend keeps (sap: about as much again; grid: about 30 bytes, since it
///   borrows the spare set during collide), and a pair 8 bytes, held about three times (the
///   backend's lists, the world's merged copy); 10 million uniform boxes with the grid take
///   under 1 GB at the peak (93 bytes a box, docs/performance.md). An allocation that fails, at
///   any n, gives BPX_ERR_OUT_OF_MEMORY ("no memory for 10000000 boxes"; for a collide the
///   backend and n), and the world keeps its previous state.
/// - More than 2^32 - 1 pairs in one cycle (all of 92,683 boxes overlapping each other, say):
///   reference and brute emit rows in order and count in size_t, so they report them all,
///   memory allowing (16 bytes a pair at the peak: 69 GB for 4.3 billion); prune, sap, grid and
///   opencl's sort-and-sweep order pairs with 32-bit offsets and return
///   BPX_ERR_TOO_MANY_PAIRS; auto reports what the backend it chose reports. Short of memory,
///   every backend returns BPX_ERR_OUT_OF_MEMORY first. bpx_cycle_stats.pair_count is 64-bit.
#define BPX_MAX_BOXES (1u << 30)

/// An axis-aligned bounding box: six IEEE single-precision floats, in this order in memory
/// (min x, min y, min z, max x, max y, max z). Closed: a box with min == max is a point or a plane,
/// and boxes that touch overlap. Valid when every coordinate is finite and min <= max per axis.
typedef struct bpx_box {
    float min[3];
    float max[3];
} bpx_box;

/// One overlapping pair: indices into the box array, i < j. Pair lists are always sorted by
/// (i, j) ascending: the same bytes from every backend, SIMD width and thread count.
typedef struct bpx_pair {
    uint32_t i;
    uint32_t j;
} bpx_pair;

/// The backends, each keeping the same contract (see bpx_overlap in overlap.h).
/// Names for the command line: bpx_backend_name() / bpx_backend_from_name().
typedef enum bpx_backend {
    BPX_BACKEND_AUTO = 0,  ///< "auto": each cycle, brute, prune or grid by n (the default)
    BPX_BACKEND_REFERENCE, ///< "reference": Algorithm 1 verbatim, scalar, one thread. The oracle.
    BPX_BACKEND_BRUTE,     ///< "brute": the paper's comparator on CPU SIMD lanes and threads
    BPX_BACKEND_PRUNE,     ///< "prune": single-axis sort and sweep (box pruning), SIMD, threads
    BPX_BACKEND_SAP,       ///< "sap": sweep and prune with temporal coherence: sorted endpoint
                           ///< lists on x, y, z kept between cycles and mended by insertion
                           ///< sort, so a coherent cycle costs O(n + swaps); rebuilt by radix
                           ///< sort when that gets dear. Mending on one thread
    BPX_BACKEND_GRID,      ///< "grid": spatial split for millions of boxes
    BPX_BACKEND_MODEL,     ///< "model": cycle-accurate model of the paper's FPGA design
    BPX_BACKEND_OPENCL,    ///< "opencl": the comparator on an OpenCL device (PoCL, GPUs, FPGAs)
    BPX_BACKEND_CUDA,      ///< "cuda": a tree built each cycle on a CUDA GPU (brute force in one
                           ///< block up to 1024 boxes); device-resident cycles in bpx/cuda.h
    BPX_BACKEND_HYBRID,    ///< "hybrid": the CPU (auto) and a device (cuda, else opencl) share
                           ///< each cycle, space cut along x by their measured speed
    BPX_BACKEND_RTL,       ///< "rtl": the chip's RTL (rtl/*.sv) simulated by Verilator, clock by
                           ///< clock; at most BPX_RTL_MAX_BOXES boxes. Built when Verilator is
                           ///< found; unavailable otherwise ("built without Verilator")
    BPX_BACKEND_COUNT
} bpx_backend;

/// Most boxes the rtl backend takes: the chip's on-chip RAMs (its DEPTH, the paper's 512). The
/// RTL has no off-chip tiles, so a cycle with more returns BPX_ERR_TOO_MANY_BOXES, naming the
/// limit (docs/rtl.md).
#define BPX_RTL_MAX_BOXES 512u

/// SIMD instruction set of the brute-force comparator. AUTO picks the widest the CPU supports;
/// forcing a narrower one is for tests and benchmarks. Lanes: scalar 1, SSE2/NEON 4, AVX2 8,
/// AVX-512 16.
typedef enum bpx_simd {
    BPX_SIMD_AUTO = 0,
    BPX_SIMD_SCALAR,
    BPX_SIMD_SSE2,
    BPX_SIMD_AVX2,
    BPX_SIMD_AVX512,
    BPX_SIMD_NEON,
    BPX_SIMD_COUNT
} bpx_simd;

/// Task system hooks, so a host engine can run bpx's parallel work on its own scheduler.
///
/// bpx splits a job into `item_count` independent items and calls enqueue once per job. The host
/// runs task(begin, end, worker, task_context) over ranges [begin, end) that together cover
/// [0, item_count) exactly once, each range at least `min_range` long where possible, with
/// worker in [0, worker_count). It returns a handle that bpx passes to finish, which must block
/// until every range has run. It may instead run everything inline and return NULL.
/// The output never depends on how the host splits the items.
typedef void bpx_task_fn(int begin, int end, int worker, void *task_context);
typedef void *bpx_enqueue_task_fn(bpx_task_fn *task, int item_count, int min_range,
                                  void *task_context, void *user_context);
typedef void bpx_finish_task_fn(void *user_task, void *user_context);

/// OpenCL device types, for bpx_world_def.opencl_device_type (a mask; 0 = any).
enum {
    BPX_OPENCL_GPU = 1,
    BPX_OPENCL_CPU = 2,
    BPX_OPENCL_ACCELERATOR = 4, ///< FPGAs and other accelerators
};

/// OpenCL comparator paths, for bpx_world_def.opencl_method.
enum {
    BPX_OPENCL_AUTO = 0,  ///< brute force for small or dense sets, the tree for the rest
    BPX_OPENCL_BRUTE = 1, ///< the paper's comparator: every pair, tiles in local memory
    BPX_OPENCL_SWEEP = 2, ///< device radix sort of the min-x keys, then a sweep (never auto)
    BPX_OPENCL_TREE = 3,  ///< a linear BVH over Morton-ordered centres, built every cycle
};

/// How a world is made. Get one from bpx_default_world_def(), change fields, pass it to
/// bpx_world_create(). A zero field means its default.
typedef struct bpx_world_def {
    /// Comparator backend. Default BPX_BACKEND_AUTO.
    bpx_backend backend;
    /// SIMD width for brute; default BPX_SIMD_AUTO (widest supported). Forcing one this build or
    /// CPU lacks fails creation with BPX_ERR_BACKEND_UNAVAILABLE, whatever the backend.
    bpx_simd simd;
    /// Threads working on one cycle, the caller's included. 0 or 1: the calling thread only.
    /// With no task hooks, bpx starts worker_count - 1 threads of its own. Range 0..256.
    int worker_count;
    /// Microseconds a built-in worker spins waiting for the next cycle before it sleeps
    /// (0 = default 200; negative = never spin). Spinning trades CPU for wake-up latency.
    int spin_us;
    /// Boxes to reserve memory for up front (0 = grow on demand). Purely a hint.
    uint32_t capacity_hint;
    /// Optional task system; both or neither. When set, worker_count tells how many workers
    /// it has and no threads are started.
    bpx_enqueue_task_fn *enqueue_task;
    bpx_finish_task_fn *finish_task;
    void *user_task_context;
    /// Keep the pair set between cycles and report the pairs that began and ended with each
    /// collide (bpx_world_pair_events). Costs one pass over the pairs per cycle. Default false.
    bool track_events;
    /// OpenCL backend: the platform, numbered from 1 in clGetPlatformIDs order (`bpx devices`
    /// shows P:D from 0, so P:D there is P+1, D+1 here); 0 = any platform (default).
    int opencl_platform;
    /// OpenCL backend: the device within the platform, from 1; 0 = the best one allowed: the
    /// first GPU, else accelerator, else CPU, platforms in order (default).
    int opencl_device;
    /// OpenCL backend: device types allowed, BPX_OPENCL_GPU | _CPU | _ACCELERATOR; 0 = any.
    int opencl_device_type;
    /// OpenCL backend: comparator path, BPX_OPENCL_AUTO (default: by n), _BRUTE, _SWEEP or _TREE.
    int opencl_method;
    /// OpenCL backend: device memory this world may use, in bytes; 0 = half of the device's
    /// global memory. Boxes beyond it are streamed in blocks and pairs read out in windows.
    uint64_t opencl_memory_limit;
    /// OpenCL backend: most boxes per streamed block (0 = as many as the memory limit allows;
    /// rounded down to whole tiles). Smaller values force streaming (tests, shared devices).
    uint32_t opencl_block_boxes;
    /// OpenCL backend: first capacity of the device's pair buffer, in pairs (0 = 65536). A
    /// cycle that finds more grows it and emits again: no pair is ever lost.
    uint32_t opencl_pair_capacity;
    /// OpenCL backend: extra options for the kernel build (an FPGA toolchain's, say); NULL for
    /// none. Never needed for correctness; fast-math options are refused. The string must live
    /// as long as the world (it is read again when the world first uses the device).
    const char *opencl_build_options;
    /// Hybrid backend: the share of the boxes (cut along x by their centres) given to the
    /// device, in (0, 1]; 0 (default) = balanced each cycle by both sides' measured speed, with
    /// everything on the CPU below 20,000 boxes, where a device's launch costs more than it saves.
    float hybrid_device_share;
    /// Contact margins, for speculative contacts and steady begin/end events (0 and 0, the
    /// default: the exact pairs). With gap = the largest over the axes of the distance between
    /// the two boxes' intervals (max(b.min - a.max, a.min - b.max), in double; <= 0 when they
    /// overlap): a pair begins when gap <= begin_margin, and a pair of the last collide goes on
    /// while gap <= end_margin, so boxes that jitter near the edge do not flicker in and out.
    /// Finite, >= 0, end_margin >= begin_margin (0: end_margin = begin_margin). The exact
    /// overlap of a reported pair is bpx_overlap(a, b). Cost with margins: a pass over the boxes
    /// to grow them by end_margin / 2 for the comparator, and a gap test per pair found.
    float begin_margin;
    float end_margin;
    /// Periodic boundaries: > 0 makes the axis periodic with that period (an orthorhombic cell;
    /// its origin does not matter and boxes need not be wrapped into it), 0 leaves it open
    /// (default 0, 0, 0). Finite, >= 0 and below 2^1000, else bpx_world_create returns
    /// INVALID_ARGUMENT (bpx_world_def_check names the axis). A periodic world pairs i and j
    /// when any image of j (j moved by whole periods) overlaps i; bpx_world_pairs stays the
    /// distinct (i, j) pairs and bpx_world_image_pairs gives every image with its shift. Not
    /// with contact margins (INVALID_ARGUMENT); queries ignore the period. Double, as
    /// bpx_neighbor_def.period. docs/neighbors.md, "Periodic worlds".
    double period[3];
    /// Profile each cycle's stages into bpx_cycle_stats.stages (time and bytes per stage; see
    /// bpx_stage_stats). Off (default): no clock read or count beyond the usual three timings,
    /// and the same pairs either way. On: two clock reads per stage, and in grid's tests one per
    /// column to tell its sorts from its tests (about 1% of a cycle at a million boxes).
    bool profile;
} bpx_world_def;

/// The change in the pair set made by the last collide, both lists sorted by (i, j).
typedef struct bpx_pair_events {
    const bpx_pair *began; ///< in this cycle's set and not in the previous one's
    size_t began_count;
    const bpx_pair *ended; ///< in the previous cycle's set and not in this one's
    size_t ended_count;
} bpx_pair_events;

/// How a profiled stage reaches memory, for reading it against the machine's floor
/// (bench/floor): in address order, or one record at a time at addresses spread over memory.
typedef enum bpx_access {
    BPX_ACCESS_SEQUENTIAL = 0, ///< streams its bytes in order (or works in cache)
    BPX_ACCESS_GATHER,         ///< reads `random` records from spread addresses
    BPX_ACCESS_SCATTER,        ///< writes `random` records to spread addresses
} bpx_access;

/// The most stages one profiled cycle reports (bpx_cycle_stats.stages).
#define BPX_MAX_STAGES 20

/// One stage of a profiled cycle (bpx_world_def.profile): its wall-clock time on the calling
/// thread (a pass split over the workers counts once, from its start to its last worker's end),
/// and the bytes it reads and writes, computed from the sizes of the arrays it touches (not
/// counted by hardware: a byte read twice from cache counts twice, and bytes that stay in cache
/// count as if they went to memory). A stage run several times in a cycle (a warm attempt, then
/// a rebuild) is summed under its name.
typedef struct bpx_stage_stats {
    const char *name;       ///< static, e.g. "keys", "scatter", "tests", "order"
    const char *backend;    ///< the backend that ran it ("grid", "sap"; "world" for its own)
    uint64_t ns;            ///< wall-clock nanoseconds
    uint64_t bytes_read;    ///< bytes the stage reads (see above)
    uint64_t bytes_written; ///< bytes the stage writes
    uint64_t random;        ///< GATHER / SCATTER: records reached at spread addresses (else 0)
    bpx_access access;      ///< its memory pattern, for the floor it is read against
} bpx_stage_stats;

/// Per-cycle figures, like the paper's registers (n, collision count) plus stage timings.
/// Times are wall-clock nanoseconds of the last cycle on a monotonic clock.
typedef struct bpx_cycle_stats {
    uint32_t box_count;     ///< n, the boxes in the world
    uint64_t pair_count;    ///< collisions found by the last bpx_world_collide*
    uint64_t pair_tests;    ///< box-pair tests the comparator made (incl. discarded padding lanes)
    uint64_t update_ns;     ///< updater: last set_boxes / update_centres (validation included)
    uint64_t compare_ns;    ///< comparator: the pair tests, all workers
    uint64_t emit_ns;       ///< collision emitter: merging per-block hits into one ordered stream
    uint64_t cycle_count;   ///< completed bpx_world_collide* calls since creation
    /// sap backend: the last cycle rebuilt its state from scratch (a cold cycle: the first, or
    /// after n shrank or the boxes moved too far to mend; the paper's "incl sort"), instead of
    /// mending last cycle's ("excl sort"). Always false for the other backends.
    bool rebuilt;
    /// OpenCL and CUDA backends (others leave these 0), last cycle, on the device's clock: time
    /// spent moving data to the device (centres or boxes), from the device (the count register
    /// and the pairs), and running kernels (updater, comparator, emitter, sort). The paper's
    /// communication share is (in + out) / (in + out + device).
    uint64_t transfer_in_ns;
    uint64_t transfer_out_ns;
    uint64_t device_ns;
    uint64_t bytes_in;  ///< OpenCL, CUDA: bytes sent to the device last cycle (12 per object in the
                        ///< two-phase mode once the extents are there, 24 per box otherwise)
    uint64_t bytes_out; ///< OpenCL, CUDA: bytes read back last cycle (8 per pair + the register)
    float device_share; ///< hybrid: the share of the boxes the device got last cycle (0 .. 1)
    /// With bpx_world_def.profile: the last cycle's stages in the order they ran (the updater's
    /// first, the world's merge of the pairs last; grid, sap, prune and auto report theirs,
    /// the other backends none of their own). 0 stages without it.
    uint32_t stage_count;
    bpx_stage_stats stages[BPX_MAX_STAGES];
} bpx_cycle_stats;

/// Detail of an error from a call that has no world (one-shot). index is the first offending
/// box (or UINT32_MAX when no box is involved), axis 0..2 (or -1).
typedef struct bpx_error {
    bpx_status status;
    uint32_t index;
    int axis;
    char message[192];
} bpx_error;

/// What a backend is on this machine.
typedef struct bpx_backend_info {
    bpx_backend backend;
    const char *name;   ///< "brute"
    bool available;     ///< usable on this machine and build
    const char *reason; ///< why not, when unavailable ("" otherwise)
    char detail[96];    ///< e.g. "avx512, 16 lanes" (m = lanes)
} bpx_backend_info;

#ifdef __cplusplus
}
#endif
