// The distributed world's state, shared by the files of libbpx_mpi.
#pragma once

#include <bpx/mpi.h>

#include "core/clock.h" // bpx__now_ns
#include "decompose.h"
#include "mpi_alloc.h"

/// One box as it travels: global id and box, then the filter when any rank uses filters.
#define BPX_MPI_RECORD_BYTES 32
#define BPX_MPI_RECORD_FILTER_BYTES 40

/// An input box that is not among the boxes this rank tests (own_pos_tmp in a cycle).
#define BPX_MPI_NOT_HERE UINT32_MAX

/// A candidate begin or end, sent to the pair's event rank.
typedef struct bpx_mpi_event_record {
    uint64_t a, b;
    uint32_t began; // 1 began, 0 ended
    uint32_t pad;
} bpx_mpi_event_record;

/// A box this rank tests, as its pairs need it: one 16-byte read for a pair's second box.
typedef struct bpx_mpi_present {
    uint64_t id;
    int source;      ///< the rank that passed the box
    uint32_t inside; ///< the box lies wholly in this rank's region: its pairs' corners do too
} bpx_mpi_present;

struct bpx_mpi_world {
    MPI_Comm comm;
    int rank, size;
    bpx_mpi_world_def def;
    bpx_world *local;
    bpx_mpi_error error;
    bpx_mpi_stats stats;

    bpx_mpi_rcb_tree tree;
    bool have_tree;
    bool rebalance_asked;     // by bpx_mpi_world_rebalance, for the next collide
    bool rebalance_next;      // the last cycle's imbalance passed the threshold
    bool local_filtered;      // the local world holds filters from an earlier cycle
    double settled_imbalance; // the imbalance just after the last decomposition (0: none yet)
    bool measure_settled;     // the next successful cycle sets it

    MPI_Datatype record_type[2]; // 32 and 40 bytes
    MPI_Datatype pair_type, event_type, sample_type;

    // Per rank: counts and displacements for all-to-all and gathers; touched ranks scratch.
    int *send_counts, *send_displs, *recv_counts, *recv_displs, *cursor, *touched;

    bpx_mpi_rcb_sample *samples;
    size_t samples_cap;
    unsigned char *send, *recv; // box records
    size_t send_cap, recv_cap;  // in bytes

    // The boxes this rank tests. Arrival positions: first this rank's own boxes in its region
    // (own_index: where in the caller's input), then the records received. ids and order (the
    // arrival position) are sorted by id; boxes and filters are then gathered in that order.
    uint64_t *ids, *ids_tmp;
    uint32_t *order, *order_tmp, *own_index;
    bpx_box *boxes;
    uint32_t *category, *mask;
    bpx_mpi_present *present; // per box, in that order: what the pairs are reported with
    size_t present_cap;

    // This rank's pairs: the last successful cycle's, and the next one's being made.
    bpx_mpi_pair *pairs, *next;
    bpx_mpi_pair_ranks *ranks, *next_ranks; // who passed each pair's objects (same capacities)
    size_t pair_count, pairs_cap, next_count, next_cap;
    bool pairs_valid;

    // Events.
    bpx_mpi_event_record *ev_send, *ev_recv;
    size_t ev_send_cap, ev_recv_cap;
    bpx_mpi_pair *began, *ended;
    size_t began_count, ended_count, began_cap, ended_cap;
    bool events_valid;

    // Ids given twice (ids.c). own_ids: this call's input ids, sorted, with their positions in
    // the input in own_pos (own_ids_tmp and own_pos_tmp: the sort's twins; then own_ids_tmp
    // holds the ids this rank added since the last successful collide, dropped_out those it
    // dropped, and in the cycle own_pos_tmp gives each input box's arrival position,
    // BPX_MPI_NOT_HERE for one that went elsewhere only); last_ids: those of the last successful
    // collide. With more than one rank, dir_ids
    // and dir_ranks are this rank's directory, a hash table (linear probing, at most half full)
    // of the ids whose id rank is this one, each with the rank that gave it in the last
    // successful collide (plus one; 0 is an empty slot); added and dropped, the changes the
    // ranks sent in this call, by the rank they came from (added_rank, by arrival).
    uint64_t *own_ids, *own_ids_tmp, *last_ids, *dropped_out;
    uint32_t *own_pos, *own_pos_tmp;
    size_t own_ids_cap, own_ids_tmp_cap, own_pos_cap, own_pos_tmp_cap, last_ids_cap;
    size_t own_ids_count, last_ids_count, dropped_out_cap, added_out_count, dropped_out_count;
    // The last successful collide's order, kept for the next call's sort (ids.c): own_pos
    // holds its positions while last_pos_valid; after one migrate since, order_hint says that
    // home maps each of those positions to its new one (-1: the object left), hint_stay
    // objects stayed and the input then holds hint_count. Scratch for the arrivals' sort.
    bool last_pos_valid, order_hint;
    size_t hint_stay, hint_count;
    uint64_t *arrive_ids, *arrive_ids_tmp;
    uint32_t *arrive_pos, *arrive_pos_tmp;
    size_t arrive_cap;
    uint64_t *dir_ids;
    int *dir_ranks;
    size_t dir_cap, dir_count; // slots (a power of two, or 0), ids held
    uint64_t *added, *added_tmp, *dropped, *dropped_tmp;
    uint32_t *added_order, *added_order_tmp;
    int *added_rank;
    size_t added_count, dropped_count, added_cap, dropped_cap;
    // Per rank, for the exchange: box records, ids added and ids dropped (3 ints each, sent and
    // received); where the ids for each rank go in the send buffer (2 words each).
    int *plan_send, *plan_recv;
    size_t *id_cursor;

    // Migrate: each object's home rank, then its new position (-1: it left).
    int *home;
    size_t home_cap;

    // Gather.
    bpx_mpi_pair *gathered, *gather_tmp;
    size_t gathered_cap, gather_tmp_cap;
};

/// The order of pair lists: by a, then b.
static inline bool bpx_mpi__pair_less(const bpx_mpi_pair *x, const bpx_mpi_pair *y)
{
    return x->a < y->a || (x->a == y->a && x->b < y->b);
}

/// Sets the world's error on this rank (printf-style message, prefixed with the rank).
void bpx_mpi__fail(bpx_mpi_world *w, bpx_status status, uint64_t id, size_t index, int axis,
                   const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 6, 7)))
#endif
    ;

/// The error of a call that has not failed (yet): status OK, rank -1, id 0, index SIZE_MAX,
/// axis -1, no message (bpx_mpi_error's "none"). Every call that sets the error starts with it.
void bpx_mpi__clear_error(bpx_mpi_world *w);

/// Collective: the lowest rank whose error is set gives it to all. Returns its status, or
/// BPX_OK when no rank failed.
bpx_status bpx_mpi__agree(bpx_mpi_world *w);

/// Sorts keys (with their positions in order) ascending; LSD radix over the bytes that differ,
/// passing between the arrays and their tmp twins (swapped, so the result is in *keys, *order).
/// order and order_tmp may be NULL: the keys alone.
void bpx_mpi__sort_ids(uint64_t **keys, uint32_t **order, uint64_t **keys_tmp, uint32_t **order_tmp,
                       size_t n);

/// As bpx_mpi__sort_ids, from src (left as it is), with positions in src as the order: the
/// result is in *keys and *order.
void bpx_mpi__sort_ids_from(const uint64_t *src, uint64_t **keys, uint32_t **order,
                            uint64_t **keys_tmp, uint32_t **order_tmp, size_t n);

/// The rank whose directory holds id among ranks ranks.
int bpx_mpi__id_rank(uint64_t id, int ranks);

/// Sorts this call's ids into own_ids (their positions into own_pos) and, with more than one
/// rank, finds the change since the last successful collide; an id twice is an input error
/// (INVALID_ARGUMENT, naming its two positions). Local.
bpx_status bpx_mpi__ids_check_own(bpx_mpi_world *w, const uint64_t *ids, size_t count);

/// Counts the ids this rank added and dropped (bpx_mpi__ids_check_own) per id rank r, into
/// plan[3 r + 1] and plan[3 r + 2].
void bpx_mpi__ids_count(const bpx_mpi_world *w, int *plan);

/// Writes those ids to out: each 8 bytes at word cursor[2 r] (added) or cursor[2 r + 1]
/// (dropped) of its id rank r, moving the cursor on.
void bpx_mpi__ids_pack(const bpx_mpi_world *w, unsigned char *out, size_t *cursor);

/// Room for the ids this rank receives and for the directory with them; forgets the last
/// call's. 0, or -1 (no memory) with the directory as it was.
int bpx_mpi__ids_reserve(bpx_mpi_world *w, size_t added, size_t dropped);

/// Takes the ids rank from added (then dropped) from ids, 8 bytes each.
void bpx_mpi__ids_receive(bpx_mpi_world *w, int from, const unsigned char *ids, size_t added,
                          size_t dropped);

/// Checks the ids received against each other and the directory: an id that two ranks give
/// sets the error (INVALID_ARGUMENT, naming both). Changes nothing else.
void bpx_mpi__ids_check(bpx_mpi_world *w);

/// After a successful collide: its ids become the last ones, and the directory takes the change.
void bpx_mpi__ids_commit(bpx_mpi_world *w);

void bpx_mpi__ids_free(bpx_mpi_world *w);

/// Events of the cycle: what changed between w->pairs and w->next, settled on each pair's
/// event rank. Collective.
bpx_status bpx_mpi__events(bpx_mpi_world *w);

/// The process's CPU time in nanoseconds (the wall clock is the core's bpx__now_ns).
uint64_t bpx_mpi__cpu_ns(void);
