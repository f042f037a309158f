// bpx scenes: deterministic box sets for tests, benchmarks and the demo.
// SPDX-License-Identifier: MIT
//
// Every scene is a pure function of (kind, n, seed): the same bytes on every run and every
// IEEE-754 platform (no libm, no time, no global state). Every generated box is valid for bpx
// (finite coordinates, min <= max on each axis).
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include <bpx/types.h>

#ifdef __cplusplus
extern "C" {
#endif

// ---------------------------------------------------------------------------------------------
// Seeded PRNG: xoshiro256** seeded through splitmix64.

typedef struct scene_rng {
    uint64_t s[4];
} scene_rng;

/// Seeds the generator; any seed (0 included) gives a valid state.
void scene_rng_seed(scene_rng *r, uint64_t seed);
uint64_t scene_rng_u64(scene_rng *r);
uint32_t scene_rng_u32(scene_rng *r);
/// Uniform in [0, bound) (bound 0 gives 0).
uint32_t scene_rng_below(scene_rng *r, uint32_t bound);
/// Uniform in [0, 1), a multiple of 2^-24.
float scene_rng_float01(scene_rng *r);
/// Uniform in [lo, hi] (computed in double, so any finite lo <= hi works, even -FLT_MAX..FLT_MAX).
float scene_rng_range(scene_rng *r, float lo, float hi);

// ---------------------------------------------------------------------------------------------
// Scene kinds

typedef enum scene_kind {
    SCENE_SPARSE = 0,      ///< "sparse": random boxes, about 0.05 overlaps per box
    SCENE_DENSE,           ///< "dense": random boxes, each overlapping ~10% of the others (>= 8)
    SCENE_CLUSTERED,       ///< "clustered": 2..8 tight clusters far apart in a large empty world
    SCENE_ALL_OVERLAP,     ///< "all_overlap": every box contains one common point (n(n-1)/2 pairs)
    SCENE_NONE_OVERLAP,    ///< "none_overlap": one box per cell of a shuffled grid, gaps between
    SCENE_MIXED_SIZES,     ///< "mixed_sizes": heavy-tailed sizes: ~1% huge, ~10% medium, rest small
    SCENE_TOUCHING,        ///< "touching": integer-lattice boxes whose faces/edges/corners touch
    SCENE_IDENTICAL,       ///< "identical": ~128 exact copies of each of 1 + n/128 boxes, shuffled
    SCENE_ZERO_EXTENT,     ///< "zero_extent": points and planes (min == max on some/all axes)
    SCENE_SIGNED_ZERO,     ///< "signed_zero": -0.0/+0.0 bounds; boxes touch only at zero
    SCENE_HUGE_TINY,       ///< "huge_tiny": coordinates up to +-FLT_MAX and near 1e-30
    SCENE_DENORMAL,        ///< "denormal": subnormal coordinates that touch/overlap/separate
    SCENE_SHARED_COORD,    ///< "shared_coord": most boxes share one x min or x max value
    SCENE_UNIFORM_DENSITY, ///< "uniform_density": constant density, ~1 overlap per box (bench)
    SCENE_KIND_COUNT
} scene_kind;

/// "sparse", "dense", ...; NULL for out-of-range values.
const char *scene_kind_name(scene_kind kind);
/// Parses a name (case-insensitive, '-' and '_' alike). Returns 0 and sets *out, or -1.
int scene_kind_from_name(const char *name, scene_kind *out);

/// Writes n boxes of the given kind to out. Returns 0, or -1 for an unknown kind, out NULL with
/// n > 0, n > BPX_MAX_BOXES, or an allocation failure (only NONE_OVERLAP and TOUCHING allocate,
/// 4 bytes per grid cell, about 4n bytes).
int scene_generate(scene_kind kind, uint32_t n, uint64_t seed, bpx_box *out);

/// Random boxes of side 0.5..1.5 per axis in a cube whose side grows with cbrt(n), so each box
/// overlaps about overlaps_per_box others (pairs ~= n * overlaps_per_box / 2) whatever n is.
void scene_uniform_density(uint32_t n, float overlaps_per_box, uint64_t seed, bpx_box *out);

/// The same density with a heavy tail of sizes, the case that breaks uniform grids: per box,
/// side 0.5..1.5 (~99%), 4..8 (~1%) or 16..32 (~0.01%, at least one box from n = 2). About 1.1
/// overlaps per box whatever n is; each huge box overlaps ~2000 small ones.
void scene_heavy_tailed_density(uint32_t n, uint64_t seed, bpx_box *out);

/// Elongated boxes at the same density (~1 overlap per box): side 0.5..1.5 on two axes and
/// `aspect` times that on the long one, x for every box or (random_axis) a random axis per box,
/// in a cube. The case that splits by centres alone handles badly (nodes as long as their boxes).
void scene_elongated_density(uint32_t n, float aspect, bool random_axis, uint64_t seed,
                             bpx_box *out);

/// Coherent motion: moves every box by its own random displacement in [-step, step]^3 (min and
/// max together, so boxes stay valid).
void scene_move(bpx_box *boxes, uint32_t n, float step, scene_rng *r);

#ifdef __cplusplus
}
#endif
