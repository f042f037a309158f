// The grid backend's tests (grid.c and its passes lay the boxes out), written once over the wide-float layer
// like brute_kernel.h; a per-ISA file includes its wide header, names the functions with
// BPX_GRID_COLUMNS / BPX_GRID_BIG, then this.
//
// A box lies in every column it covers at its level, so two boxes of one level that overlap
// share a column: the one with the larger min cell on y and on z, which both cover (cells are
// monotone in the coordinate). There, sorted by min x, the first of the two finds the other by
// sweeping forward while min x <= its max x; in the other columns they share, the rule drops
// the pair. A box of a finer level looks, from its home column only, into the columns it covers
// at each coarser level: a window of each run, from the first box whose x cell is >= its own
// there minus one (a coarser box spans at most 2 cells, so none before it can reach) to the last
// whose min x is <= its max x; the same rule keeps one column. Every test is the exact
// comparison of overlap.h.
#include <math.h>

#include "grid.h"

#if !defined(BPX_GRID_COLUMN) || !defined(BPX_GRID_BIG) || !defined(BPX_GRID_KEYS)
#error "define BPX_GRID_COLUMN, BPX_GRID_BIG and BPX_GRID_KEYS before including grid_kernel.h"
#endif

typedef struct bpx_grid_probe {
    bpx_wf lx, hx, ly, hy, lz, hz;
    uint32_t id;
} bpx_grid_probe;

// A against positions k, k+1, ... < end while their min x is <= A's max x (the run is sorted,
// so the lanes in reach are a prefix). A hit counts where the other box has every flag of
// `need` (the column rule). False when memory ran out.
static inline bool grid_scan(const bpx_grid_run *g, const bpx_grid_probe *a, uint32_t k,
                             uint32_t end, uint32_t need, bpx_block *out)
{
    const uint32_t all = (uint32_t)((1ull << BPX_W) - 1);
    while (k < end) {
        bpx_wm reach = bpx_wm_le(bpx_wf_loadu(g->lo[0] + k), a->hx);
        bpx_wm m = bpx_wm_le_and(reach, a->lx, bpx_wf_loadu(g->hi[0] + k));
        m = bpx_wm_le_and(m, bpx_wf_loadu(g->lo[1] + k), a->hy);
        m = bpx_wm_le_and(m, a->ly, bpx_wf_loadu(g->hi[1] + k));
        m = bpx_wm_le_and(m, bpx_wf_loadu(g->lo[2] + k), a->hz);
        m = bpx_wm_le_and(m, a->lz, bpx_wf_loadu(g->hi[2] + k));
        uint32_t left = end - k;
        uint32_t valid = left >= BPX_W ? all : (uint32_t)((1ull << left) - 1);
        uint32_t bits = bpx_wm_bits(m) & valid;
        out->tests += BPX_W;
        if (bits) {
            bpx_pair_list *hits = &out->hits;
            if (hits->capacity - hits->count < BPX_W && !bpx__list_reserve(hits, BPX_W))
                return false;
            bpx_pair *p = hits->pairs + hits->count;
            do {
                uint32_t lane = (uint32_t)__builtin_ctz(bits);
                bits &= bits - 1;
                if ((g->flags[k + lane] & need) != need)
                    continue;
                uint32_t b = g->id[k + lane];
                p->i = a->id < b ? a->id : b;
                p->j = a->id < b ? b : a->id;
                p++;
            } while (bits);
            hits->count = (size_t)(p - hits->pairs);
        }
        if ((bpx_wm_bits(reach) & valid) != all)
            return true;
        k += BPX_W;
    }
    return true;
}

// First position in [at, end) whose x cell is >= want (cx is sorted along a run).
static inline uint32_t grid_lower_bound(const uint32_t *cx, uint32_t at, uint32_t end,
                                        uint32_t want)
{
    while (at < end) {
        uint32_t mid = at + (end - at) / 2;
        if (cx[mid] < want)
            at = mid + 1;
        else
            end = mid;
    }
    return at;
}

// A coarser column a finer column's boxes may cover: its run, and a pointer into it that only
// moves forward (the finer boxes come in min x order).
typedef struct bpx_grid_window {
    uint32_t at, end;
    uint32_t y, z; // the column at its level
} bpx_grid_window;

enum { GRID_UP_MAX = 4 * (BPX_GRID_LEVELS - 1) };

static bool grid_column(const bpx_grid_layout *g, int l, uint32_t c, const bpx_grid_run *r,
                        bpx_block *out)
{
    const bpx_grid_level *lv = &g->level[l];
    const uint32_t s = 0, e = r->count;
    if (s == e)
        return true;
    // The coarser levels' runs, all in g's arrays.
    const bpx_grid_run up = {{g->lo[0], g->lo[1], g->lo[2]}, {g->hi[0], g->hi[1], g->hi[2]},
                             g->id, g->cx, g->flags, 0};
    uint32_t y = (c - lv->first_column) / lv->nz, z = (c - lv->first_column) % lv->nz;
    // The coarser columns this column's home boxes may cover: (y or y+1, z or z+1) >> shift.
    bpx_grid_window w[GRID_UP_MAX];
    int first_window[BPX_GRID_LEVELS + 1];
    int count = 0;
    for (int m = l + 1; m < g->windowed; m++) {
        first_window[m] = count;
        if (!g->level[m].count)
            continue;
        int shift = 2 * (m - l);
        const bpx_grid_level *mv = &g->level[m];
        uint32_t y0 = y >> shift, y1 = (y + 1) >> shift, z0 = z >> shift, z1 = (z + 1) >> shift;
        for (uint32_t ym = y0; ym <= y1 && ym < mv->ny; ym++)
            for (uint32_t zm = z0; zm <= z1 && zm < mv->nz; zm++) {
                uint32_t cm = mv->first_column + ym * mv->nz + zm;
                uint32_t at = g->column_start[cm], end = g->column_start[cm + 1];
                uint32_t want = r->cx[s] >> shift;
                at = grid_lower_bound(g->cx, at, end, want ? want - 1 : 0);
                w[count++] = (bpx_grid_window){at, end, ym, zm};
            }
    }
    first_window[g->windowed > l + 1 ? g->windowed : l + 1] = count;
    for (uint32_t p = s; p < e; p++) {
        const bpx_grid_probe a = {bpx_wf_set1(r->lo[0][p]),
                                  bpx_wf_set1(r->hi[0][p]),
                                  bpx_wf_set1(r->lo[1][p]),
                                  bpx_wf_set1(r->hi[1][p]),
                                  bpx_wf_set1(r->lo[2][p]),
                                  bpx_wf_set1(r->hi[2][p]),
                                  r->id[p]};
        uint32_t flags = r->flags[p];
        if (!grid_scan(r, &a, p + 1, e, ~flags & BPX_GRID_HOME, out))
            return false;
        if ((flags & BPX_GRID_HOME) != BPX_GRID_HOME || !count)
            continue;
        // Home: the box's cells here are (y .. y + spans y, z .. z + spans z).
        uint32_t yh = y + ((flags & BPX_GRID_SPANS_Y) != 0);
        uint32_t zh = z + ((flags & BPX_GRID_SPANS_Z) != 0);
        for (int m = l + 1; m < g->windowed; m++) {
            int shift = 2 * (m - l);
            uint32_t want = r->cx[p] >> shift;
            want = want ? want - 1 : 0;
            uint32_t y0 = y >> shift, y1 = yh >> shift, z0 = z >> shift, z1 = zh >> shift;
            for (int k = first_window[m]; k < first_window[m + 1]; k++) {
                if (w[k].y > y1 || w[k].z > z1)
                    continue;
                uint32_t at = w[k].at;
                while (at < w[k].end && g->cx[at] < want)
                    at++;
                w[k].at = at;
                // Kept where the larger min cell is this column's: the other box must start
                // here on each axis where this box started before.
                uint32_t need = (w[k].y == y0 ? 0 : BPX_GRID_FIRST_Y) |
                                (w[k].z == z0 ? 0 : BPX_GRID_FIRST_Z);
                if (!grid_scan(&up, &a, at, w[k].end, need, out))
                    return false;
            }
        }
    }
    return true;
}

void BPX_GRID_COLUMN(const bpx_grid_layout *g, int l, uint32_t c, const bpx_grid_run *run,
                     bpx_block *out)
{
    if (!grid_column(g, l, c, run, out))
        out->status = BPX_ERR_OUT_OF_MEMORY;
}

void BPX_GRID_BIG(const bpx_grid_layout *g, uint32_t b, uint32_t j0, uint32_t j1, bpx_block *out)
{
    const bpx_soa *s = &g->boxes;
    uint32_t i = g->big_ids[b];
    const bpx_wf lx = bpx_wf_set1(s->lo[0][i]), hx = bpx_wf_set1(s->hi[0][i]);
    const bpx_wf ly = bpx_wf_set1(s->lo[1][i]), hy = bpx_wf_set1(s->hi[1][i]);
    const bpx_wf lz = bpx_wf_set1(s->lo[2][i]), hz = bpx_wf_set1(s->hi[2][i]);
    for (uint32_t j = j0; j < j1; j += BPX_W) {
        bpx_wm m = bpx_wm_le(bpx_wf_load(s->lo[0] + j), hx);
        m = bpx_wm_le_and(m, lx, bpx_wf_load(s->hi[0] + j));
        if (!bpx_wm_any(m))
            continue;
        m = bpx_wm_le_and(m, bpx_wf_load(s->lo[1] + j), hy);
        m = bpx_wm_le_and(m, ly, bpx_wf_load(s->hi[1] + j));
        m = bpx_wm_le_and(m, bpx_wf_load(s->lo[2] + j), hz);
        m = bpx_wm_le_and(m, lz, bpx_wf_load(s->hi[2] + j));
        uint32_t bits = bpx_wm_bits(m);
        while (bits) {
            uint32_t k = j + (uint32_t)__builtin_ctz(bits);
            bits &= bits - 1;
            // Small boxes never look for big ones; of two big boxes the smaller id reports.
            uint32_t level = bpx__grid_key_level(g->key[k]);
            if (k == i || (level >= (uint32_t)g->windowed && k < i))
                continue;
            if (!bpx__list_reserve(&out->hits, 1)) {
                out->status = BPX_ERR_OUT_OF_MEMORY;
                return;
            }
            out->hits.pairs[out->hits.count++] = i < k ? (bpx_pair){i, k} : (bpx_pair){k, i};
        }
    }
    out->tests += j1 > j0 ? (uint64_t)(j1 - j0) : 0;
}

// ---------------------------------------------------------------------------------------------
// Keys (keys.c's key pass): GRID_KEY_LANES boxes at a time, every step a select, so that the
// compiler makes each line one vector instruction of this file's ISA.

enum { GRID_KEY_LANES = 16 };

// Loops over lanes inside loops over axes and levels: each inner loop is one vector step.
static inline void grid_keys_lanes(const bpx_grid_cells *c, const bpx_soa *s, uint32_t i,
                                   uint32_t m, uint32_t *key, float seen[7][GRID_KEY_LANES])
{
    enum { L = GRID_KEY_LANES };
    uint32_t ql[3][L], qh[3][L], l[L], live[L];
    for (uint32_t k = 0; k < m; k++)
        live[k] = s->lo[0][i + k] <= s->hi[0][i + k];
    for (int a = 0; a < 3; a++) {
        const float *lo = s->lo[a] + i, *hi = s->hi[a] + i;
        for (uint32_t k = 0; k < m; k++) {
            ql[a][k] = bpx__grid_cell(lo[k], c->origin[a], c->inv[a], c->top[a]);
            qh[a][k] = bpx__grid_cell(hi[k], c->origin[a], c->inv[a], c->top[a]);
            float low = live[k] ? lo[k] : INFINITY, high = live[k] ? lo[k] : -INFINITY;
            float e = live[k] ? hi[k] - lo[k] : 0.0f;
            seen[a][k] = low < seen[a][k] ? low : seen[a][k];
            seen[3 + a][k] = high > seen[3 + a][k] ? high : seen[3 + a][k];
            seen[6][k] = e > seen[6][k] ? e : seen[6][k];
        }
    }
    for (uint32_t k = 0; k < m; k++) {
        ql[0][k] >>= c->fine_bits;
        qh[0][k] >>= c->fine_bits;
        l[k] = 0;
    }
    // The first level at which the box spans at most 2 cells per axis: spanning more at one
    // level implies spanning more at every finer one, so count the levels where it does (up to
    // the first level where no lane does: most boxes sit at level 0).
    int top = 0;
    for (; top + 1 < BPX_GRID_LEVELS; top++) {
        int sh = 2 * top;
        uint32_t any = 0;
        for (uint32_t k = 0; k < m; k++) {
            uint32_t wide = (qh[0][k] >> sh) - (ql[0][k] >> sh) > 1;
            wide |= (qh[1][k] >> sh) - (ql[1][k] >> sh) > 1;
            wide |= (qh[2][k] >> sh) - (ql[2][k] >> sh) > 1;
            wide &= live[k]; // an inert box (min +inf, max -inf) looks wide at every level
            l[k] += wide;
            any |= wide;
        }
        if (!any)
            break;
    }
    uint32_t y[L], z[L], dy[L], dz[L], first[L], nz[L];
    for (uint32_t k = 0; k < m; k++) {
        y[k] = ql[1][k];
        z[k] = ql[2][k];
        dy[k] = qh[1][k] - ql[1][k];
        dz[k] = qh[2][k] - ql[2][k];
        first[k] = c->first_column[0];
        nz[k] = c->nz[0];
    }
    for (int lev = 1; lev <= top; lev++) {
        int sh = 2 * lev;
        uint32_t f = c->first_column[lev], n = c->nz[lev];
        for (uint32_t k = 0; k < m; k++) {
            bool here = l[k] == (uint32_t)lev;
            y[k] = here ? ql[1][k] >> sh : y[k];
            z[k] = here ? ql[2][k] >> sh : z[k];
            dy[k] = here ? (qh[1][k] >> sh) - (ql[1][k] >> sh) : dy[k];
            dz[k] = here ? (qh[2][k] >> sh) - (ql[2][k] >> sh) : dz[k];
            first[k] = here ? f : first[k];
            nz[k] = here ? n : nz[k];
        }
    }
    uint32_t *out = key + i;
    for (uint32_t k = 0; k < m; k++) {
        uint32_t k_live = l[k] << 28 | dz[k] << 27 | dy[k] << 26 | (first[k] + y[k] * nz[k] + z[k]);
        out[k] = live[k] ? k_live : BPX_GRID_INERT;
    }
}

void BPX_GRID_KEYS(const bpx_grid_cells *c, const bpx_soa *s, uint32_t begin, uint32_t end,
                   uint32_t *key, bpx_grid_seen *out)
{
    float seen[7][GRID_KEY_LANES];
    for (int k = 0; k < GRID_KEY_LANES; k++) {
        for (int a = 0; a < 3; a++) {
            seen[a][k] = out->lo_min[a];
            seen[3 + a][k] = out->lo_max[a];
        }
        seen[6][k] = out->largest;
    }
    uint32_t i = begin;
    for (; i + GRID_KEY_LANES <= end; i += GRID_KEY_LANES)
        grid_keys_lanes(c, s, i, GRID_KEY_LANES, key, seen);
    grid_keys_lanes(c, s, i, end - i, key, seen);
    for (int k = 0; k < GRID_KEY_LANES; k++) {
        for (int a = 0; a < 3; a++) {
            out->lo_min[a] = seen[a][k] < out->lo_min[a] ? seen[a][k] : out->lo_min[a];
            out->lo_max[a] = seen[3 + a][k] > out->lo_max[a] ? seen[3 + a][k] : out->lo_max[a];
        }
        out->largest = seen[6][k] > out->largest ? seen[6][k] : out->largest;
    }
}
