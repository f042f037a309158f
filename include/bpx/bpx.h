// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// The one header to include. The library follows the paper's pipeline (Woulfe, Dingliana &
// Manzke 2007):
//   updater    boxes from origin-centred extents + per-cycle centres, or set directly
//   comparator the pair test, in backends (reference, brute SIMD/threads, ...)
//   emitter    per-lane/per-thread hits merged into one stream ordered by (i, j)
//   interface  the world: state between cycles, counts and per-stage timings
//
// Typical frame loop:
//   bpx_world_def def = bpx_default_world_def();
//   def.worker_count = 4;
//   bpx_world *world;
//   if (bpx_world_create(&def, &world) != BPX_OK) ...
//   bpx_world_load_extents(world, minima, n);          // once: origin-centred minima
//   each frame:
//     bpx_world_update_centres(world, centres);        // 3 floats per object
//     bpx_world_collide(world);
//     size_t count; const bpx_pair *pairs = bpx_world_pairs(world, &count);
//   bpx_world_destroy(world);
//
// Threading: a world is used by one thread at a time; different worlds are independent.
#pragma once

#include "base.h"
#include "neighbors.h"
#include "overlap.h"
#include "query.h"
#include "types.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bpx_world bpx_world;

/// A world definition with every field at its default.
BPX_API bpx_world_def bpx_default_world_def(void);

/// Checks a definition as bpx_world_create does and names the first field out of range in err
/// (may be NULL): create has no world to keep its message in (it also logs it, level 0).
/// Errors: NULL_ARGUMENT, INVALID_ARGUMENT.
BPX_API bpx_status bpx_world_def_check(const bpx_world_def *def, bpx_error *err);

/// Creates a world. On success *out_world owns threads and memory until bpx_world_destroy.
/// Errors: NULL_ARGUMENT, INVALID_ARGUMENT (worker_count, hooks given singly, a period
/// negative, NaN or infinite, contact margins on a periodic world: bpx_world_def_check says which),
/// BACKEND_UNAVAILABLE (backend or forced SIMD width not usable here), OUT_OF_MEMORY.
/// On error *out_world is NULL and nothing is leaked.
BPX_API bpx_status bpx_world_create(const bpx_world_def *def, bpx_world **out_world);

/// Joins the world's threads and frees all its memory. NULL is allowed.
BPX_API void bpx_world_destroy(bpx_world *world);

/// The world's last error (status BPX_OK when the last call succeeded). Valid until the next call
/// on this world; do not free.
BPX_API const bpx_error *bpx_world_error(const bpx_world *world);

// ---------------------------------------------------------------------------------------------
// Updater

/// Initialisation phase: loads n objects' origin-centred boxes as their minima (x, y, z per
/// object, 3n floats). Maxima are the negated minima, so each minimum must be finite and <= 0.
/// The world's box count becomes n and, until the first bpx_world_update_centres, every box sits
/// at the origin ([minimum, -minimum]). The world is then in the two-phase mode, which
/// bpx_world_set_boxes leaves: update_centres works, add_boxes is refused. Removed ids come back
/// and filters follow the rule of bpx_world_set_boxes.
/// Errors: NULL_ARGUMENT (minima NULL with n > 0), TOO_MANY_BOXES, NOT_FINITE,
/// MIN_GREATER_THAN_MAX (a minimum > 0), OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_world_load_extents(bpx_world *world, const float *minima, uint32_t n);

/// Updating phase: current centres (x, y, z per object, 3n floats for the n loaded extents).
/// Box i becomes [centre_i + minimum_i, centre_i - minimum_i] per axis.
/// Errors: BAD_STATE (not in the two-phase mode: no extents loaded, or bpx_world_set_boxes
/// since), NULL_ARGUMENT, NOT_FINITE (a centre, or a box coordinate that overflowed). On error
/// the world keeps its previous boxes.
BPX_API bpx_status bpx_world_update_centres(bpx_world *world, const float *centres);

/// General mode: sets the n current boxes directly (any shape each cycle; rotating objects).
/// Leaves the two-phase mode: bpx_world_update_centres is BAD_STATE until the next
/// bpx_world_load_extents, and bpx_world_add_boxes works. Ids become 0 .. n-1, all in use
/// (removed ones come back). An id is the same object before and after, as events see it, so an
/// id in use below both the old and the new n keeps its filter; every other id (one beyond the
/// old n, beyond the new n, or removed before the call) starts again unfiltered.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES, NOT_FINITE, MIN_GREATER_THAN_MAX, OUT_OF_MEMORY;
/// the error names the first offending box. On error the world is unchanged.
BPX_API bpx_status bpx_world_set_boxes(bpx_world *world, const bpx_box *boxes, uint32_t n);

/// General mode in float64 (bpx_box64, neighbors.h): sets the n current boxes as doubles, exact.
/// The world keeps them; the comparator runs on them rounded outward to float32 (so no pair is
/// lost) and every candidate is decided on the doubles (closed intervals, compared exactly), so
/// pairs, image pairs (periodic worlds) and events are the exact float64 answer: boxes 1 ulp
/// apart at 1e6, or at 1e-30, do not pair, where their float32 roundings would. Ids, filters
/// and the modes as bpx_world_set_boxes. Float64 boxes are set whole: add, move and remove by
/// id are BAD_STATE until bpx_world_set_boxes or bpx_world_load_extents gives the world float32
/// boxes again. Queries see the float32 boxes rounded outward. Not with contact margins
/// (BAD_STATE), snapshots (BAD_STATE while float64 boxes are set) or device-resident calls.
/// Cost: a rounding pass and a copy of the doubles per call, and per candidate pair one test
/// of 48 bytes of doubles.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES, NOT_FINITE, MIN_GREATER_THAN_MAX (naming the first bad
/// box and axis), BAD_STATE, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_world_set_boxes64(bpx_world *world, const bpx_box64 *boxes, uint32_t n);

/// Number of boxes in the world (the paper's n register): the highest id in use + 1 when boxes
/// were added and removed one by one.
BPX_API uint32_t bpx_world_box_count(const bpx_world *world);

// ---------------------------------------------------------------------------------------------
// Objects added and removed between cycles (general mode, like a physics engine's proxies)
//
// A box's id is its index in pairs. Ids are dense and stable: removing a box frees its id, and
// a freed id is handed out again only after the next collide has reported the removed box's
// pairs as ended, so events never confuse an old object with a new one. These calls change
// the current boxes in place; bpx_world_set_boxes replaces them all (ids 0 .. n-1).

/// Adds count boxes; out_ids receives their ids (freed ids first, then new ones at the end).
/// Errors: NULL_ARGUMENT, NOT_FINITE / MIN_GREATER_THAN_MAX (naming the box's position in the
/// batch), TOO_MANY_BOXES, OUT_OF_MEMORY, BAD_STATE in the two-phase mode (load_extents).
BPX_API bpx_status bpx_world_add_boxes(bpx_world *world, const bpx_box *boxes, uint32_t count,
                                       uint32_t *out_ids);
/// Removes boxes by id. Errors: NULL_ARGUMENT, INVALID_ARGUMENT (an id not in use, or twice in
/// the batch; the error's index is its position in ids). Nothing is removed on error.
BPX_API bpx_status bpx_world_remove_boxes(bpx_world *world, const uint32_t *ids, uint32_t count);
/// Moves boxes: boxes[k] becomes the box of ids[k]. Errors as add and remove.
BPX_API bpx_status bpx_world_move_boxes(bpx_world *world, const uint32_t *ids,
                                        const bpx_box *boxes, uint32_t count);

/// Collision filtering, applied inside the broad phase (no filtered pair is ever emitted or
/// counted): boxes a and b can pair only if (category_a & mask_b) && (category_b & mask_a).
/// Every box starts with category 1 and mask 0xFFFFFFFF (pairs with everything). ids may be
/// NULL for ids 0 .. count-1. A filter stays with its id until the box is removed (add_boxes
/// hands the id out unfiltered again) or set_boxes / load_extents drop it (see set_boxes).
/// Errors: NULL_ARGUMENT, INVALID_ARGUMENT (an id not in use: >= n, or removed; the error's
/// index is its position in ids), OUT_OF_MEMORY. Nothing is changed on error.
BPX_API bpx_status bpx_world_set_filters(bpx_world *world, const uint32_t *ids,
                                         const uint32_t *categories, const uint32_t *masks,
                                         uint32_t count);

/// Groups (Box2D's rule), for boxes that must never pair (a ragdoll's links, a robot's joints)
/// or always pair: two boxes in the same non-zero group always pair when the group is positive
/// and never when it is negative, whatever their categories and masks; boxes in different
/// groups, or in group 0 (every box starts there), follow the category rule. ids as in
/// bpx_world_set_filters, and a group stays with its id as a filter does. Errors as set_filters.
BPX_API bpx_status bpx_world_set_groups(bpx_world *world, const uint32_t *ids,
                                        const int32_t *groups, uint32_t count);

/// Excluded pairs: boxes i and j never pair, whatever their groups and filters, until the pair
/// is included again. (i, j) and (j, i) are the same pair; excluding one twice is the same as
/// once; any number may be excluded. An exclusion lasts while both ids hold their boxes: it goes
/// when either box is removed (by the next collide, with the id's pairs) or dropped by set_boxes
/// / load_extents under the rule of filters. Cost: each overlapping pair whose two boxes are
/// both in some excluded pair costs one hash lookup; other pairs cost two reads.
/// Errors: NULL_ARGUMENT, INVALID_ARGUMENT (an id not in use, or i == j; the error's index is
/// the pair's position), OUT_OF_MEMORY. Nothing is changed on error.
BPX_API bpx_status bpx_world_exclude_pairs(bpx_world *world, const bpx_pair *pairs,
                                           uint32_t count);
/// Ends exclusions; a pair that is not excluded is left as it is. Errors as exclude_pairs.
BPX_API bpx_status bpx_world_include_pairs(bpx_world *world, const bpx_pair *pairs,
                                           uint32_t count);
/// Whether the pair is excluded now.
BPX_API bool bpx_world_pair_excluded(const bpx_world *world, uint32_t i, uint32_t j);

/// A pair filter: asked once when a pair would begin (its boxes overlap and it passed groups,
/// exclusions and filters, and it did not at the last collide), never again while it persists.
/// Return true to let it pair, false to keep it out until it stops overlapping (or is filtered
/// out) and begins again, when the filter is asked again. Called by bpx_world_collide* on the
/// calling thread, pairs in (i, j) order, so the same for any worker count.
typedef bool bpx_pair_filter_fn(uint32_t i, uint32_t j, uint64_t user_data_i,
                                uint64_t user_data_j, void *context);

/// Sets the pair filter (NULL: none, the default). Setting one, or another, asks again about
/// every pair at the next collide; so does bpx_world_restore. It must not change the world
/// (such calls return BAD_STATE) and should answer the same for the same pair, so that
/// restored worlds replay alike. Cost: one merge walk over the pairs per collide, two lists of
/// the pairs' size, and the calls for the pairs that begin.
/// Errors: NULL_ARGUMENT (no world), BAD_STATE (called from a callback; the boxes live on a
/// device is fine: the device-resident collide refuses a world with a pair filter).
BPX_API bpx_status bpx_world_set_pair_filter(bpx_world *world, bpx_pair_filter_fn *fn,
                                             void *context);

/// User data: a 64-bit value per box (a pointer, an engine's body handle), 0 until set, handed
/// to query callbacks (bpx_world_query_each). It stays with its id as a filter does.
/// Errors: NULL_ARGUMENT, INVALID_ARGUMENT (an id not in use), OUT_OF_MEMORY.
BPX_API bpx_status bpx_world_set_user_data(bpx_world *world, const uint32_t *ids,
                                           const uint64_t *values, uint32_t count);
/// The user data of a box in use; 0 for an id not in use.
BPX_API uint64_t bpx_world_user_data(const bpx_world *world, uint32_t id);

/// The pairs that began and ended with the last collide (def.track_events must be set, else
/// BAD_STATE). The first collide reports every pair as began. Lists are owned by the world and
/// valid until the next call that changes it.
BPX_API bpx_status bpx_world_pair_events(const bpx_world *world, bpx_pair_events *events);

// ---------------------------------------------------------------------------------------------
// Comparator + collision emitter

/// Finds every overlapping pair among the current boxes into the world's own buffer, which grows
/// as needed and is kept between cycles (after the first cycles, no allocation).
/// Errors: OUT_OF_MEMORY (the pair set does not fit in memory; no partial result is reported).
/// A periodic world also: TOO_MANY_BOXES when its cell is too small for its boxes (a box lies or
/// reaches more than 2^29 periods from the origin, or the boxes with their images pass
/// BPX_MAX_BOXES), the message naming the box and axis.
/// After an error, pairs and events read as none (pair_events: BAD_STATE) until a collide
/// succeeds; that one reports its events against the last successful collide, and ids removed
/// before it are still held back until then.
BPX_API bpx_status bpx_world_collide(bpx_world *world);

/// The pairs of the last successful collide, sorted by (i, j). *count receives their number
/// (may be NULL). Owned by the world; valid until the next call that changes the world.
BPX_API const bpx_pair *bpx_world_pairs(bpx_world *world, size_t *count);

/// Periodic worlds (bpx_world_def.period): the last successful collide's pairs over every
/// periodic image, sorted by (i, j, shift): box i and box j moved by shift[a] * period[a] on each
/// axis overlap (closed intervals, decided exactly on the float32 coordinates; shift 0 on open
/// axes; shifts relative to the boxes as given, which need not lie in the cell). A pair of boxes
/// that meet in several images (a box wider than half a period) is listed once per image, and
/// (i, i, shift) with the shift's first non-zero component positive when a box meets its own
/// image (a box at least a period wide). bpx_world_pairs holds the distinct (i, j), i < j, of
/// these; filters, groups, exclusions and the pair filter decide on (i, j), and an image is
/// listed when its (i, j) passed them; a box and its own image, when the box would pair with a
/// box of its own category, mask and group (exclusions and the pair filter never see (i, i)).
/// Events are on (i, j): a pair begins when its first image appears and ends when its last
/// goes. For an open world: the pairs, shift 0. Owned by the world; valid until the next call
/// that changes it; NULL with *count 0 when there is no result (or no memory to make it).
/// Cost of a periodic collide: docs/neighbors.md.
BPX_API const bpx_image_pair *bpx_world_image_pairs(bpx_world *world, size_t *count);

/// The world's period (bpx_world_def.period, or the last restored snapshot's); 0 on open axes.
BPX_API void bpx_world_period(const bpx_world *world, double period[3]);

/// Like bpx_world_collide, but the emitter writes straight into caller memory.
/// *count receives the number of pairs found. If it exceeds capacity, returns BPX_ERR_CAPACITY,
/// writes nothing to out, and loses nothing: the full set is readable with bpx_world_pairs() or
/// bpx_world_copy_pairs() without running the cycle again.
BPX_API bpx_status bpx_world_collide_into(bpx_world *world, bpx_pair *out, size_t capacity,
                                          size_t *count);

/// Copies the last cycle's pairs into out. Returns CAPACITY (and the needed count) if too small.
BPX_API bpx_status bpx_world_copy_pairs(const bpx_world *world, bpx_pair *out, size_t capacity,
                                        size_t *count);

/// Counts and timings of the last cycle.
BPX_API bpx_cycle_stats bpx_world_stats(const bpx_world *world);

/// The backend the world resolved to (never AUTO; for auto, the one its last cycle ran, which
/// can change from cycle to cycle) and its SIMD width.
BPX_API bpx_backend bpx_world_backend(const bpx_world *world);
BPX_API bpx_simd bpx_world_simd(const bpx_world *world);

// ---------------------------------------------------------------------------------------------
// Snapshot and restore (rollback netcode, replays, checkpoints)

/// Writes the world's state into buffer: its boxes (and the two-phase extents), every id's state
/// (live, removed, waiting for reuse), filters, groups, user data, excluded pairs, and the last
/// collide's pairs and the pair filter's decisions about them (a restored world asks its filter
/// only about pairs that begin after; set the filter before restoring, as setting one forgets
/// every decision), so that a world restored from it reports on its next collide the same pairs
/// and events, byte for byte, as this one would, and the period (bpx_world_def.period: the
/// pairs depend on it, so the restoring world takes it). Not in it: the rest of the world's
/// definition (backend, workers, track_events: the restoring world keeps its own),
/// statistics, query results.
/// The bytes are versioned and checksummed, for this library on a machine of the same byte
/// order. *size receives the bytes needed; with capacity < *size returns CAPACITY and writes
/// nothing (buffer may be NULL with capacity 0, to ask). Reads the world only.
/// Errors: NULL_ARGUMENT, CAPACITY, BAD_STATE (the boxes live in a device buffer, or are
/// float64: bpx_world_set_boxes64).
BPX_API bpx_status bpx_world_snapshot(const bpx_world *world, void *buffer, size_t capacity,
                                      size_t *size);

/// Replaces the world's state with a snapshot's (from any world: a world can restore another's).
/// Pairs and events then read as none until the next collide, which reports its events against
/// the snapshot's last pairs.
/// Errors: NULL_ARGUMENT; INVALID_ARGUMENT when the bytes are not a snapshot this library reads
/// (another format version or byte order, truncated, changed: the checksum, or a field that
/// does not hold; a periodic snapshot into a world with contact margins), the message naming
/// what and its byte offset; OUT_OF_MEMORY. On error the world is unchanged. Snapshots of
/// format versions 1 and 2 (before periods, before the pair filter's decisions) are refused so.
BPX_API bpx_status bpx_world_restore(bpx_world *world, const void *buffer, size_t size);

// ---------------------------------------------------------------------------------------------
// One-shot

/// All overlapping pairs of an array of boxes, on the calling thread, with the given backend.
/// Writes at most capacity pairs to out and sets *count to the number found. Returns CAPACITY
/// when count > capacity (out untouched; call again with a buffer of *count pairs).
/// err (may be NULL) receives the detail of any error, e.g. the first invalid box.
BPX_API bpx_status bpx_find_pairs(const bpx_box *boxes, uint32_t n, bpx_backend backend,
                                  bpx_pair *out, size_t capacity, size_t *count, bpx_error *err);

/// Checks boxes as every entry point does and reports the first invalid box; within that box a
/// non-finite coordinate is reported before a min > max.
BPX_API bpx_status bpx_validate_boxes(const bpx_box *boxes, uint32_t n, bpx_error *err);

// ---------------------------------------------------------------------------------------------
// Backends and SIMD

/// "auto", "reference", "brute", ... NULL for out-of-range values.
BPX_API const char *bpx_backend_name(bpx_backend backend);
/// Parses a backend name. UNKNOWN_BACKEND if none matches.
BPX_API bpx_status bpx_backend_from_name(const char *name, bpx_backend *out);
/// Whether a backend is usable here, why not, and details (ISA, lanes).
BPX_API bpx_backend_info bpx_backend_query(bpx_backend backend);

/// "auto", "scalar", "sse2", "avx2", "avx512", "neon". NULL for out-of-range values.
BPX_API const char *bpx_simd_name(bpx_simd simd);
BPX_API bpx_status bpx_simd_from_name(const char *name, bpx_simd *out);
/// Lanes of one comparator step (the paper's 2m - 1 pairs per step).
BPX_API int bpx_simd_lanes(bpx_simd simd);
/// Whether this build and this CPU can run the width.
BPX_API bool bpx_simd_supported(bpx_simd simd);
/// The widest supported width: what BPX_SIMD_AUTO resolves to.
BPX_API bpx_simd bpx_simd_best(void);

#ifdef __cplusplus
}
#endif
