// bpx_mpi: the broad phase over MPI ranks. SPDX-License-Identifier: MIT
//
// A distributed world on a communicator. Each rank owns some objects (the application decides
// which) and passes their boxes with 64-bit global ids every cycle; bpx splits space into one
// region per rank (recursive coordinate bisection at sampled medians), sends a copy of each box
// to every other rank whose region it touches, and finds the pairs. Built as its own library
// (libbpx_mpi) when CMake finds MPI; the core library has no MPI dependency.
//
// Each step (every rank calls, in the same order; the calls marked collective must be made by
// every rank of the communicator):
//   bpx_mpi_world_collide(world, ids, boxes, filters, count);   // collective
//   const bpx_mpi_pair *pairs = bpx_mpi_world_pairs(world, &n); // this rank's share, sorted
//
// The rules, exact whatever the number of ranks or threads:
// - Regions are half-open cells [lo, hi) of one bisection tree that together cover all of
//   space (the outer ones reach to infinity). Boxes are closed, as in the core library.
// - Each overlapping pair is reported exactly once, on the rank whose region holds the minimum
//   corner of the two boxes' intersection (max of the two minima, per axis). That point lies in
//   both boxes, so both reach that rank. On it, pairs are sorted by (a, b), a < b.
// - The union over ranks is the pair set of the single-process world on the same boxes and
//   filters (ids mapped), and bpx_mpi_world_gather_pairs gives it to one rank sorted, the same
//   bytes for 1, 2, ... ranks and any worker count.
// - Events (def.track_events): a pair's begin or end is reported once, on the rank
//   bpx_mpi_event_rank(a, b, ranks) (a hash of the pair, so that it stays put when the pair's
//   corner moves to another region), sorted by (a, b).
// - Ownership is free: an object may be passed by any one rank each cycle. Boxes whose centre
//   lies in the rank's own region cost only the copies near borders; an application that keeps
//   its objects on the rank bpx_mpi_world_home_ranks names (moving the few that crossed a border,
//   as particle codes do) sends the least. A box passed elsewhere is sent whole every cycle.
// - Ids must be unique over all ranks, wherever the boxes lie: an id twice in one rank's input
//   is an input error (BPX_ERR_INVALID_ARGUMENT, naming both positions); an id two ranks give
//   fails the cycle (BPX_ERR_INVALID_ARGUMENT, naming both ranks). For the second, each id has
//   a directory rank (a hash of the id) that knows who gives it; a cycle sends it only the ids a
//   rank began or stopped giving since the last successful collide (8 bytes each, with the box
//   records), so steady cycles send a few and a rank's first sends all of its own.
// - Where the data is: a pair is often reported on a rank that passed neither object (its
//   corner's rank). bpx_mpi_world_pair_ranks tells, per pair, the ranks that passed a and b;
//   fetching what the narrow phase needs from them is the application's job.
// - Errors are collective: every rank returns the same status, and bpx_mpi_world_error gives
//   every rank the same message, naming the rank (and id, and position in its input) that found
//   it; when several ranks fail, the lowest one's error is reported. An input error (NULL
//   arrays, NaN or infinite coordinate, min > max, count > BPX_MAX_BOXES, an id twice) leaves
//   the world as it was. An error found later in the cycle (an id two ranks give, memory) leaves
//   pairs and events reading as none (BAD_STATE for events) until a collide succeeds; that one
//   reports events against the last successful collide. An error of MPI itself aborts: the
//   world's duplicate communicator has MPI_ERRORS_ARE_FATAL, since a rank that failed a
//   collective could not keep step with the others.
// - Threads: MPI is called only from the thread that calls bpx_mpi (MPI_THREAD_FUNNELED is
//   enough); the rank's bpx world may run worker threads of its own (def.local.worker_count).
// - Memory: a rank holds the records it sends and receives, about 70 bytes per box it tests
//   (ids, order, boxes, filters, source ranks), 40 per box it passes and 24 to 48 per id its
//   directory holds (the id checks), its bpx_world (with every pair the rank finds,
//   those the corner rule drops included), and 24 bytes per pair it reports, twice (this cycle's
//   and the last); the root of a gather holds 32 bytes per pair of the whole set. Buffers grow
//   and are kept, so steady cycles do not allocate.
#pragma once

#include <mpi.h>

#include "bpx.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bpx_mpi_world bpx_mpi_world;

/// An overlapping pair by global ids, a < b.
typedef struct bpx_mpi_pair {
    uint64_t a;
    uint64_t b;
} bpx_mpi_pair;

/// The ranks that passed the two objects of a pair (bpx_mpi_world_pair_ranks).
typedef struct bpx_mpi_pair_ranks {
    int a;
    int b;
} bpx_mpi_pair_ranks;

/// Per object collision filter, as bpx_world_set_filters: a and b can pair only if
/// (category_a & mask_b) && (category_b & mask_a).
typedef struct bpx_mpi_filter {
    uint32_t category;
    uint32_t mask;
} bpx_mpi_filter;

typedef struct bpx_mpi_world_def {
    /// The rank's own world: backend, SIMD width, worker threads, task hooks.
    /// local.track_events is ignored (events are kept by bpx_mpi over global ids).
    bpx_world_def local;
    /// Keep the pair set and report the pairs that began and ended with each collide. Must be
    /// the same on every rank (creation fails with INVALID_ARGUMENT otherwise).
    bool track_events;
    /// Recompute the regions when the most loaded rank holds more than this many times the mean
    /// number of boxes (its own inside its region plus the copies it receives). 0 = 1.25. The
    /// first collide always computes them.
    double rebalance_threshold;
    /// Centres each rank contributes to a bisection (0 = 65536 / ranks, at least 32, at most
    /// 4096; samples_per_rank x ranks at most 2^24). Every rank receives all of them, so the cost
    /// of a rebalance grows with this. A rebalance that could not lower the imbalance (all
    /// centres in one point, say) is not repeated until the imbalance grows past what it was.
    uint32_t samples_per_rank;
} bpx_mpi_world_def;

/// The error of the last collective call (create, collide, gather, migrate), the same on every
/// rank. After a successful one: status BPX_OK, rank -1, id 0, index SIZE_MAX, axis -1 and an
/// empty message.
typedef struct bpx_mpi_error {
    bpx_status status;
    int rank;       ///< the rank that found it (-1 for none)
    uint64_t id;    ///< the object's global id, when one is involved (else 0)
    size_t index;   ///< its position in that rank's input (SIZE_MAX when none)
    int axis;       ///< 0..2 for a coordinate, else -1
    char message[224];
} bpx_mpi_error;

/// Per-cycle figures of this rank. Times are wall-clock nanoseconds; cpu_ns is the process's
/// CPU time over the cycle (with oversubscribed ranks, wall time counts the waits for a core).
typedef struct bpx_mpi_stats {
    uint64_t cycle_count;     ///< successful collides since creation
    uint64_t own_count;       ///< boxes this rank passed
    uint64_t foreign_count;   ///< of those, boxes whose centre lies in another rank's region
    uint64_t present_count;   ///< boxes this rank tested: own ones in its region + received
    uint64_t copies_sent;     ///< box records sent to other ranks
    uint64_t copies_received; ///< box records received
    uint64_t bytes_sent;      ///< payload bytes sent to other ranks (what a rank passes to
                              ///< itself is not counted): box records (32 bytes, 40 with
                              ///< filters), ids for the directories (8 bytes each, in whole
                              ///< records per rank) and event records (24 bytes); not MPI's
                              ///< own headers
    uint64_t bytes_received;  ///< the same, received from other ranks
    uint64_t messages_sent;   ///< destinations other than this rank that got data this cycle
                              ///< (boxes, ids or events)
    uint64_t pair_count;      ///< pairs reported by this rank
    uint64_t total_pair_count;///< pairs reported by all ranks (the whole set's size)
    double imbalance;         ///< most boxes tested by a rank / mean over ranks
    bool decomposed;          ///< this cycle computed the regions (first cycle or rebalance)
    uint64_t decomposition_count;
    uint64_t decompose_ns;    ///< sampling, gathering samples and bisecting
    uint64_t route_ns;        ///< finding each box's regions and packing the records
    uint64_t exchange_ns;     ///< the all-to-all exchanges of counts and records
    uint64_t local_ns;        ///< sorting by id and the rank's own bpx_world collide
    uint64_t select_ns;       ///< keeping the pairs whose corner is in this rank's region
    uint64_t events_ns;       ///< events: the change, its exchange and arbitration
    uint64_t total_ns;        ///< the whole collide
    uint64_t migrated_sent;     ///< the last bpx_mpi_world_migrate: objects sent away,
    uint64_t migrated_received; ///< objects received,
    uint64_t migrate_bytes_sent;///< and the bytes sent (id, box and payload each)
    uint64_t cpu_ns;          ///< process CPU time over the whole collide (MPI's waits spin)
    uint64_t compute_cpu_ns;  ///< process CPU time of the work outside MPI calls: routing,
                              ///< packing, sorting, the rank's collide, selecting the pairs
} bpx_mpi_stats;

/// The change of the pair set made by the last collide, on the event rank of each pair.
typedef struct bpx_mpi_pair_events {
    const bpx_mpi_pair *began;
    size_t began_count;
    const bpx_mpi_pair *ended;
    size_t ended_count;
} bpx_mpi_pair_events;

/// A definition with every field at its default.
BPX_API bpx_mpi_world_def bpx_mpi_default_world_def(void);

/// Collective. Creates a world on a duplicate of comm (MPI must be initialised). Errors, the
/// same on every rank: NULL_ARGUMENT, INVALID_ARGUMENT (a def field out of range on any rank),
/// those of bpx_world_create, OUT_OF_MEMORY. On error *out_world is NULL; when err is not NULL
/// it receives the detail.
BPX_API bpx_status bpx_mpi_world_create(MPI_Comm comm, const bpx_mpi_world_def *def,
                                        bpx_mpi_world **out_world, bpx_mpi_error *err);

/// Collective (it frees the duplicate communicator). NULL is allowed on every rank.
BPX_API void bpx_mpi_world_destroy(bpx_mpi_world *world);

/// Collective. One cycle: this rank's count boxes with their global ids, then the exchange and
/// the pairs. filters may be NULL: this rank's boxes then have the default filter (category 1,
/// mask 0xFFFFFFFF), as in a bpx_world. count may be 0 (NULLs allowed then). On an input error
/// the pairs, events and regions are as they were (the stats describe the failed call).
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES (count, or the boxes a rank tests, past BPX_MAX_BOXES;
/// copies to send past MPI's int counts), NOT_FINITE, MIN_GREATER_THAN_MAX, INVALID_ARGUMENT
/// (an id twice in this rank's input, or given by two ranks), OUT_OF_MEMORY, TOO_MANY_PAIRS
/// (events past MPI's int counts), and those of the rank's bpx_world_collide.
BPX_API bpx_status bpx_mpi_world_collide(bpx_mpi_world *world, const uint64_t *ids,
                                         const bpx_box *boxes, const bpx_mpi_filter *filters,
                                         size_t count);

/// This rank's pairs from the last successful collide, sorted by (a, b). Owned by the world.
BPX_API const bpx_mpi_pair *bpx_mpi_world_pairs(const bpx_mpi_world *world, size_t *count);

/// Parallel to bpx_mpi_world_pairs: for each pair, the ranks that passed objects a and b in the
/// last successful collide. Owned by the world.
BPX_API const bpx_mpi_pair_ranks *bpx_mpi_world_pair_ranks(const bpx_mpi_world *world,
                                                           size_t *count);

/// This rank's events of the last collide (def.track_events, else BAD_STATE).
BPX_API bpx_status bpx_mpi_world_pair_events(const bpx_mpi_world *world,
                                             bpx_mpi_pair_events *events);

/// Collective. Gathers every rank's pairs to root, sorted by (a, b): on root, *pairs and
/// *count receive the whole set (owned by the world, valid until its next call); elsewhere
/// NULL and 0. Errors: INVALID_ARGUMENT (root out of range), OUT_OF_MEMORY on root,
/// TOO_MANY_PAIRS (past MPI's int counts), BAD_STATE (no successful collide to gather).
BPX_API bpx_status bpx_mpi_world_gather_pairs(bpx_mpi_world *world, int root,
                                              const bpx_mpi_pair **pairs, size_t *count);

/// The error of the last call on this world.
BPX_API const bpx_mpi_error *bpx_mpi_world_error(const bpx_mpi_world *world);

/// The last cycle's figures on this rank.
BPX_API bpx_mpi_stats bpx_mpi_world_stats(const bpx_mpi_world *world);

/// The region of a rank: lo[k] <= x < hi[k] per axis (infinite at the outside; a region can be
/// empty, lo == hi, when many centres share a coordinate). BAD_STATE
/// before the first successful collide; INVALID_ARGUMENT for a rank out of range.
BPX_API bpx_status bpx_mpi_world_region(const bpx_mpi_world *world, int rank, float lo[3],
                                        float hi[3]);

/// Local (no communication): for each box, the rank whose region holds its centre, where the
/// object is cheapest to pass. BAD_STATE before the first collide.
BPX_API bpx_status bpx_mpi_world_home_ranks(const bpx_mpi_world *world, const bpx_box *boxes,
                                            size_t count, int *ranks);

/// Collective. Moves each object to its home rank (as bpx_mpi_world_home_ranks, by the regions
/// of the last collide) together with payload_size bytes of the caller's data per object, so
/// that only the objects that crossed a border travel. On entry ids, boxes and payload (NULL
/// when payload_size is 0) hold this rank's *count objects in arrays with room for capacity;
/// on return they hold its objects after the move: those that stayed, in their order, then the
/// arrivals by source rank and their order there, and *count their number. *needed (may be
/// NULL) receives the count this rank has, or would have, after the move. The next collide on
/// these arrays, as they are, reuses the last collide's order of the ids through the move
/// instead of sorting them again (checked against the ids: any other input is sorted anew).
/// Errors, the same on every rank, with nothing moved and *count unchanged: CAPACITY when any
/// rank lacks room (*needed tells each rank the room it needs; call again with more),
/// BAD_STATE before the first collide, NULL_ARGUMENT, INVALID_ARGUMENT (*count > capacity,
/// payload_size over 1 MB), NOT_FINITE or MIN_GREATER_THAN_MAX (a box), OUT_OF_MEMORY,
/// TOO_MANY_BOXES (more than 2^31 - 1 objects to send or receive, MPI's int counts).
BPX_API bpx_status bpx_mpi_world_migrate(bpx_mpi_world *world, uint64_t *ids, bpx_box *boxes,
                                         void *payload, size_t payload_size, size_t capacity,
                                         size_t *count, size_t *needed);

/// Asks the next collide to recompute the regions whatever the balance (collective in effect:
/// the regions are recomputed if any rank asked).
BPX_API void bpx_mpi_world_rebalance(bpx_mpi_world *world);

/// The rank that reports the events of pair (a, b) among ranks ranks.
BPX_API int bpx_mpi_event_rank(uint64_t a, uint64_t b, int ranks);

#ifdef __cplusplus
}
#endif
