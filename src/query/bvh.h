// The queries' tree: a bounding volume hierarchy over the world's live boxes, built in Morton
// order (a linear BVH) and refitted while the same objects only move.
#pragma once

#include "core/world.h"

/// Boxes per leaf at most: a leaf's boxes are tested one after another from contiguous memory.
#define BPX_BVH_LEAF 4
/// Deepest tree: 31 key bits (30 Morton, 1 large) split by bit, then equal keys halved.
#define BPX_BVH_MAX_DEPTH 64

/// A node, 32 bytes, in depth-first order: an inner node's first child is the next node.
typedef struct bpx_bvh_node {
    float lo[3];
    uint32_t second; ///< inner: index of the second child; leaf: its first item
    float hi[3];
    uint32_t count; ///< 0 for an inner node; a leaf's number of items
} bpx_bvh_node;

typedef struct bpx_bvh {
    bpx_bvh_node *nodes;
    uint32_t node_count;
    uint32_t node_capacity;
    // The live boxes in leaf order, and their ids.
    bpx_box *items;
    uint32_t *ids;
    uint32_t item_count;
    uint32_t item_capacity;
    // Build scratch: Morton keys and ids, twice for the radix sort.
    uint32_t *keys;
    uint32_t *scratch;
    uint32_t scratch_capacity;

    bool valid;            // matches the world's boxes of `version`
    uint64_t version;      // the world's boxes_version it was made from
    uint32_t world_n;      // the world's n then
    double looseness;      // inner nodes' area over the boxes' area, at the last build
    uint64_t builds, refits, last_update_ns;
} bpx_bvh;

/// Brings the tree up to date with the world's current boxes: a refit when the same ids are
/// live and the tree stays tight, else a rebuild. Returns OUT_OF_MEMORY and leaves the tree
/// invalid (never wrong) when memory runs out.
bpx_status bpx__bvh_update(bpx_bvh *tree, const bpx_world *world);

void bpx__bvh_free(bpx_bvh *tree);
