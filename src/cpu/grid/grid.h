// The grid backend's layout, shared by the passes (which build it) and the kernels that test it
// (grid_kernel.h, compiled once per instruction set as grid_<isa>.c).
#pragma once

#include "cpu/backends.h"

enum {
    BPX_GRID_LEVELS = 12,   // level l has cells 4^l times the side of level 0's
    BPX_GRID_Q_BITS = 22,   // level-0 cell coordinates per axis: 0 .. 2^22 - 1
    BPX_GRID_KEY_BITS = 26, // a box's key: level << 28 | span z << 27 | span y << 26 | column
    BPX_GRID_SPAN_Y = 1 << 26,
    BPX_GRID_SPAN_Z = 1 << 27,
};

/// Per position: where the box lies relative to the column. FIRST_*: the column holds the box's
/// min corner on that axis (else the box started one cell before); SPAN_*: the box covers 2
/// cells on that axis. A pair is reported only in the column holding the larger of the two min
/// cells on y and on z, that is where at least one of the two is FIRST on each axis.
enum {
    BPX_GRID_FIRST_Y = 1,
    BPX_GRID_FIRST_Z = 2,
    BPX_GRID_HOME = 3, // the column of the box's min corner: it looks up the coarser levels here
    BPX_GRID_SPANS_Y = 4,
    BPX_GRID_SPANS_Z = 8,
};

/// Boxes in the grid, level by level: a level-l box spans at most 2 cells of side 4^l * s per
/// axis, and lies in each column ((y, z) cell at its level) it covers: 1 to 4 positions. A column
/// is a run of positions sorted by min x. Levels at the top holding few boxes are "big" instead:
/// those boxes are tested against every box by the big kernel.
typedef struct bpx_grid_level {
    uint32_t count;        // boxes at this level
    uint32_t first_column; // global index of its column (0, 0); columns are y-major
    uint32_t ny, nz;       // columns per axis
} bpx_grid_level;

typedef struct bpx_grid_layout {
    const float *lo[3], *hi[3];   // positions: columns in order, each sorted by min x; padded
    const uint32_t *id;           // box id at each position
    const uint32_t *cx;           // x cell of min x at the box's level, at each position
    const uint8_t *flags;         // BPX_GRID_FIRST_* | BPX_GRID_SPANS_*, at each position
    const uint32_t *column_start; // per global column (windowed levels), plus one
    bpx_grid_level level[BPX_GRID_LEVELS];
    int windowed;                 // levels 0 .. windowed - 1 are in columns; the rest are big
    // Big boxes: tested against the world's boxes in id order.
    bpx_soa boxes;
    const uint32_t *big_ids;
    uint32_t big_count;
    const uint32_t *key; // per box id: level << BPX_GRID_KEY_BITS | column (the big kernel's
                         // rule needs to know which boxes are big)
} bpx_grid_layout;

/// One column's sorted run: positions 0 .. count - 1 (arrays padded after it).
typedef struct bpx_grid_run {
    const float *lo[3], *hi[3];
    const uint32_t *id, *cx;
    const uint8_t *flags;
    uint32_t count;
} bpx_grid_run;

/// Tests the boxes of global column c at level l, given as a run: each against the rest of the
/// run, and from its home column against the columns it covers at every populated windowed
/// level above (g's arrays). Each pair is reported once; hits (min id, max id), unordered.
typedef void bpx_grid_column_fn(const bpx_grid_layout *g, int l, uint32_t c,
                                const bpx_grid_run *run, bpx_block *out);
/// Tests big box g->big_ids[b] against boxes [j0, j1) in id order (j0 a multiple of 64, j1 at
/// most n rounded up to 64): small boxes always, big ones only with a larger id.
typedef void bpx_grid_big_fn(const bpx_grid_layout *g, uint32_t b, uint32_t j0, uint32_t j1,
                             bpx_block *out);

/// What the key pass needs of the cycle's grid: cells q = floor((v - origin) * inv) clamped to
/// [0, top] per axis (x cut 2^fine_bits times finer), and each level's columns.
typedef struct bpx_grid_cells {
    float origin[3], inv[3], top[3]; // top: exact (below 2^24)
    int fine_bits;
    uint32_t first_column[BPX_GRID_LEVELS], nz[BPX_GRID_LEVELS];
} bpx_grid_cells;

/// What a key pass saw of the live boxes: the range of their min corners and their largest
/// extent (the grid's parameters next cycle, keys.c).
typedef struct bpx_grid_seen {
    float lo_min[3], lo_max[3], largest;
} bpx_grid_seen;

/// Keys of boxes [begin, end) into key[] (BPX_GRID_INERT for inert boxes); folds what it saw
/// into *seen. Written as plain loops over lanes, which each ISA's file compiles to vectors.
typedef void bpx_grid_keys_fn(const bpx_grid_cells *cells, const bpx_soa *s, uint32_t begin,
                              uint32_t end, uint32_t *key, bpx_grid_seen *seen);

/// The cell of coordinate v on one axis: monotone in v (rounding is), clamped to [0, top] (top
/// exact, below 2^24). The key pass and the scatter both use it.
static inline uint32_t bpx__grid_cell(float v, float origin, float inv, float top)
{
    float x = (v - origin) * inv;
    x = x > 0.0f ? x : 0.0f;
    x = x < top ? x : top;
    return (uint32_t)(int32_t)x;
}

/// Level of a box key, and its global column.
static inline uint32_t bpx__grid_key_level(uint32_t key)
{
    return key >> 28;
}
static inline uint32_t bpx__grid_key_column(uint32_t key)
{
    return key & ((1u << BPX_GRID_KEY_BITS) - 1);
}
/// Key of removed (inert) boxes: in no column, never tested.
#define BPX_GRID_INERT UINT32_MAX
