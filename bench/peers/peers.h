// bpx bench peers: other libraries' broad phases behind one small C API, so `bpx bench` can time
// them side by side with bpx's backends on the same box frames. SPDX-License-Identifier: MIT
//
// The peers live in a module, bpx_peers.so, linked with Bullet and Box2D, that bpx opens at run
// time (peers_loader.c): bpx itself links neither, and runs without them, with no peers.
//
// Peers compiled in (each only when its library was found at configure time; see README.md):
//   "bullet-sap"    Bullet 3 btAxisSweep3 (incremental sweep and prune, 16-bit quantised)
//   "bullet-sap32"  Bullet 3 bt32BitAxisSweep3 (the same, 32-bit quantised)
//   "bullet-dbvt"   Bullet 3 btDbvtBroadphase (two dynamic AABB trees, fat leaves)
//   "bullet-simple" Bullet 3 btSimpleBroadphase (all pairs, quadratic)
//   "box2d-tree"    Box2D 2.4 b2BroadPhase over b2DynamicTree (2D: the x-y projection)
//   "fcl-tree"      FCL 0.7 DynamicAABBTreeCollisionManager<double> (exact leaves, refit)
//
// No C++ exception crosses this API. A peer is used by one thread at a time.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include <bpx/types.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bench_peer bench_peer;

/// What a peer is. Strings are static (never free them).
typedef struct bench_peer_info {
    /// CLI name: "bullet-sap", "bullet-sap32", "bullet-dbvt", "bullet-simple", "box2d-tree",
    /// "fcl-tree".
    const char *name;
    /// One line: library + version, class, the settings that matter (quantisation, margins).
    const char *detail;
    /// Largest n it accepts at all (btAxisSweep3's 16-bit handles: 32766), else UINT32_MAX.
    uint32_t max_n;
    /// Above this the bench should skip it as too slow, else UINT32_MAX: btSimpleBroadphase's
    /// quadratic cycle, bt32BitAxisSweep3's quadratic creation (one sorted insertion per proxy).
    uint32_t slow_n;
} bench_peer_info;

/// Peers available (0 when no peer library was found at configure time, or when the peers'
/// module cannot be loaded). The first call of any of these loads the module.
int bench_peer_count(void);
/// NULL when the peers' module is loaded and has peers, else why there are none: the module not
/// built, or which library it needs cannot be loaded. (peers_loader.c only.)
const char *bench_peers_unavailable(void);
/// The peer at index in [0, bench_peer_count()); NULL out of range.
const bench_peer_info *bench_peer_get(int index);
/// The index of the peer with this CLI name (exact match), or -1.
int bench_peer_find(const char *name);

/// The peer's broad phase with n proxies inserted from `boxes` (the first frame) and its pair
/// set computed once, as a first engine step would. bounds_min/max must contain every box of
/// every frame the caller will pass (quantising peers map them onto their integer grid; may be
/// NULL when n == 0). Returns NULL and a message in err (may be NULL) on failure: unknown
/// index, n > max_n, boxes NULL with n > 0, bounds not finite, allocation failure, any
/// exception inside the library. Not timed by the bench: creation may be slow (btAxisSweep3
/// inserts one proxy at a time, O(n) each).
bench_peer *bench_peer_create(int index, const bpx_box *boxes, uint32_t n,
                              const float bounds_min[3], const float bounds_max[3], char *err,
                              size_t err_size);

/// One cycle as a physics engine pays it: every proxy's box set to boxes[i] (n boxes, the n of
/// create), then the peer's own pair update, so that its pair set is current. For Box2D that is
/// the pair set b2ContactManager keeps: new pairs from UpdatePairs added, pairs whose fat AABBs
/// stopped overlapping dropped. The caller times this call. Returns 0, or -1 (allocation failure
/// or an exception; the peer is then only fit for bench_peer_destroy).
int bench_peer_cycle(bench_peer *p, const bpx_box *boxes);

/// The peer's current pair count as it reports it (pairs of fat / quantised boxes; for
/// bullet-dbvt stale pairs linger until its incremental clean-up removes them).
uint64_t bench_peer_pair_count(const bench_peer *p);

/// Untimed check: of the peer's current pairs, those whose exact boxes (`boxes`, the frame of the
/// last cycle) overlap by bpx_overlap, as (i, j) with i < j, sorted by (i, j). Writes the first
/// min(count, capacity) of them to out (may be NULL when capacity is 0) and returns the full
/// count. Allocates nothing.
uint64_t bench_peer_exact_pairs(const bench_peer *p, const bpx_box *boxes, bpx_pair *out,
                                uint64_t capacity);

/// Frees the peer and everything its library allocated for it. NULL is allowed.
void bench_peer_destroy(bench_peer *p);

#ifdef __cplusplus
}
#endif
