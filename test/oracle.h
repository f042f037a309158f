// bpx tests: the oracle of a world, written without the library's code, shared by test_soak.c
// and fuzz/fuzz_api.c (oracle.c). A model of what a world holds (per id: its box, whether it is
// live, its filter; the ids handed out and those waiting for reuse) follows the calls a test
// makes, and says what the world must answer: its pairs (Algorithm 1 over the live ids, filters
// applied), the ids add_boxes gives, a cycle's events (the difference of two sorted pair
// lists), and the status and the box or position a call that must fail names.
//
// It checks nothing itself: each test checks the world against it with its own harness
// (check.h's CHECK, the fuzzer's FUZZ_CHECK). SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <bpx/bpx.h>

/// What a world holds, per id below `capacity` (the ids the model can follow).
typedef struct oracle_model {
    uint32_t capacity;
    uint32_t n; // ids handed out, live or removed: bpx_world_box_count
    bpx_box *boxes;
    bool *live;
    uint32_t *category, *mask;        // the filter: unfiltered is category 1, mask all ones
    int32_t *group;                   // 0 unless set
    uint64_t *user_data;              // 0 unless set
    uint64_t *excluded;               // excluded pairs, (smaller id << 32 | larger), unordered
    uint32_t excluded_count;
    uint32_t *pending, pending_count; // removed since the last cycle: reusable after it
    uint32_t *freed, free_count;      // reusable: add_boxes takes the last first
} oracle_model;

/// An empty world's model (no ids). Aborts without memory.
void oracle_init(oracle_model *m, uint32_t capacity);
void oracle_free(oracle_model *m);
/// dst becomes a copy of src (dst's own memory freed first when it has any).
void oracle_copy(oracle_model *dst, const oracle_model *src);

/// set_boxes / load_extents of n boxes: ids 0 .. n-1 live, none waiting for reuse; a filter
/// stays on an id that was live and is below both counts. The caller writes the boxes.
void oracle_reset(oracle_model *m, uint32_t n);
/// The count of ids after add_boxes of `count` boxes (reused ids first).
uint32_t oracle_count_after_add(const oracle_model *m, uint32_t count);
/// add_boxes of one box: the id the world gives it (a reused one, else the next), live and
/// unfiltered. Aborts past the model's capacity.
uint32_t oracle_add(oracle_model *m, const bpx_box *box);
/// remove_boxes of one live id: reusable after the next successful cycle.
void oracle_remove(oracle_model *m, uint32_t id);
void oracle_move(oracle_model *m, uint32_t id, const bpx_box *box);
void oracle_set_filter(oracle_model *m, uint32_t id, uint32_t category, uint32_t mask);
void oracle_set_group(oracle_model *m, uint32_t id, int32_t group);
/// Excludes (on) or includes (off) the pair of two different ids.
void oracle_exclude(oracle_model *m, uint32_t i, uint32_t j, bool on);
bool oracle_excluded(const oracle_model *m, uint32_t i, uint32_t j);
/// A cycle succeeded: the ids removed before it are reusable, in no excluded pair.
void oracle_collided(oracle_model *m);
/// id is handed out and live.
bool oracle_is_live(const oracle_model *m, uint32_t id);
/// Any id carries a filter other than unfiltered, a group, or an excluded pair.
bool oracle_filtered(const oracle_model *m);

/// The pairs the world must report: Algorithm 1 over the live ids, in (i, j) order, without
/// excluded pairs, then by groups (a shared non-zero group: positive pairs, negative never),
/// then filters. The first `capacity` go to out; returns how many there are.
size_t oracle_pairs(const oracle_model *m, bpx_pair *out, size_t capacity);
/// The same, into an array it allocates (free() it). Aborts without memory.
size_t oracle_pairs_alloc(const oracle_model *m, bpx_pair **out);

/// The closed intervals overlap on every axis (touching boxes do; a NaN bound never does).
bool oracle_overlap(const bpx_box *a, const bpx_box *b);
/// Two pair lists are the same bytes.
bool oracle_same_pairs(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb);
/// The pairs of a that are not in b, both sorted by (i, j), into out (room for na): began is
/// difference(now, before), ended difference(before, now). Returns how many.
size_t oracle_difference(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb, bpx_pair *out);

/// The status the library gives an invalid box, and the axis it names (a non-finite
/// coordinate first, then min > max); BPX_OK and -1 for a valid one.
bpx_status oracle_box_problem(const bpx_box *b, int *axis);
/// The first invalid box of an array: its status, index and axis (BPX_OK: none).
bpx_status oracle_boxes_problem(const bpx_box *boxes, uint32_t n, uint32_t *index, int *axis);
/// Ids for remove_boxes / move_boxes: each live and named once, else INVALID_ARGUMENT naming
/// the first bad position.
bpx_status oracle_ids_problem(const oracle_model *m, const uint32_t *ids, uint32_t count,
                              uint32_t *index);
