// The grid's first passes: the cycle's cells (1. parameters, serial) and each box's key
// (2. keys, in chunks of box ids on the workers).

#include <math.h>
#include <string.h>

#include "grid_internal.h"

// ---------------------------------------------------------------------------------------------
// 1. Parameters

// Removed ids hold inert boxes (min +inf > max -inf): they take no part.
static inline bool is_inert(const bpx_soa *s, uint32_t i)
{
    return !(s->lo[0][i] <= s->hi[0][i]);
}

static inline float box_size(const bpx_soa *s, uint32_t i)
{
    float e = s->hi[0][i] - s->lo[0][i];
    for (int a = 1; a < 3; a++) {
        float d = s->hi[a][i] - s->lo[a][i];
        e = d > e ? d : e;
    }
    return e;
}

// Sorts sizes (non-negative: +0 to +inf, whose bits order as unsigned integers) by an LSD radix
// sort of their bits, four 8-bit passes: O(count). An insertion sort here took 150 of grid's 190
// us a cycle at 1000 boxes (`bpx bench --backend grid --sizes 1000 --threads 1`).
static void sort_sizes(float *v, uint32_t count)
{
    uint32_t keys[SAMPLE], spare[SAMPLE], counts[257];
    memcpy(keys, v, sizeof(float) * count);
    uint32_t *from = keys, *to = spare;
    for (int shift = 0; shift < 32; shift += 8) {
        memset(counts, 0, sizeof counts);
        for (uint32_t k = 0; k < count; k++)
            counts[(from[k] >> shift & 0xff) + 1]++;
        if (counts[(from[0] >> shift & 0xff) + 1] == count)
            continue; // one digit for all: the order stands
        for (int d = 0; d < 256; d++)
            counts[d + 1] += counts[d];
        for (uint32_t k = 0; k < count; k++)
            to[counts[from[k] >> shift & 0xff]++] = from[k];
        uint32_t *t = from;
        from = to;
        to = t;
    }
    memcpy(v, from, sizeof(float) * count);
}

void bpx__grid_choose_params(const bpx_soa *s, bpx_grid_state *st, bpx_grid_params *p)
{
    uint32_t n = s->n;
    float sample[SAMPLE];
    float lo_min[3] = {INFINITY, INFINITY, INFINITY}, lo_max[3] = {-INFINITY, -INFINITY, -INFINITY};
    uint32_t taken = 0, stride = n / SAMPLE + 1;
    for (uint32_t i = 0; i < n && taken < SAMPLE; i += stride) {
        if (is_inert(s, i))
            continue;
        sample[taken++] = box_size(s, i);
        for (int a = 0; a < 3; a++) {
            lo_min[a] = fminf(lo_min[a], s->lo[a][i]);
            lo_max[a] = fmaxf(lo_max[a], s->lo[a][i]);
        }
    }
    if (st->have_stats)
        for (int a = 0; a < 3; a++) {
            lo_min[a] = st->bounds_lo[a];
            lo_max[a] = st->bounds_hi[a];
        }
    if (!taken || !(lo_min[0] <= lo_max[0])) { // nothing live: any grid will do
        for (int a = 0; a < 3; a++)
            lo_min[a] = lo_max[a] = 0.0f;
        sample[taken++] = 1.0f;
    }
    sort_sizes(sample, taken);

    // Cells GRID_CELL_SIZES times the largest box size that keeps about GRID_SWEEP_BOXES boxes
    // in one sweep (a column's cross-section, (s + e)^2, times an x reach e, the median size)
    // at the scene's density; at least that times the median size.
    double span[3], volume = 1.0, median = (double)sample[taken / 2];
    for (int a = 0; a < 3; a++) {
        span[a] = (double)lo_max[a] - (double)lo_min[a];
        volume *= fmax(span[a], median);
    }
    double density = volume > 0.0 ? (double)(n ? n : 1) / volume : 0.0;
    double reach = fmax(median, 1e-30);
    double cap = density > 0.0 ? (sqrt(GRID_SWEEP_BOXES / (density * reach)) - reach) /
                                     GRID_CELL_SIZES
                               : INFINITY;
    double size = median;
    for (uint32_t k = taken; k-- > taken / 2;)
        if ((double)sample[k] <= cap) {
            size = (double)sample[k];
            break;
        }
    // Sizes even (the whole sample fits): last cycle's exact largest, so that no box goes up.
    if ((double)sample[taken - 1] <= cap && st->have_stats && (double)st->max_extent <= cap)
        size = fmax(size, (double)st->max_extent);
    double side = GRID_CELL_SIZES * size;
    // Cells representable (22 bits a coordinate), never zero, and not too many columns.
    for (int a = 0; a < 3; a++)
        side = fmax(side, span[a] / (double)(1u << (BPX_GRID_Q_BITS - 1)));
    side = fmax(side, 1e-30);
    double columns_max = fmin((double)(n / GRID_BOXES_PER_COLUMN) + 64.0, (double)(1u << 24));
    while ((floor(span[1] / side) + 1.0) * (floor(span[2] / side) + 1.0) > columns_max)
        side *= 1.25;

    float inv = (float)(1.0 / side);
    if (!(inv > 0.0f))
        inv = 1e-38f;
    for (int a = 0; a < 3; a++) {
        p->origin[a] = lo_min[a];
        p->inv[a] = inv;
        double top = floor(span[a] / side);
        p->top[a] = top < (double)((1u << BPX_GRID_Q_BITS) - 1)
                        ? (uint32_t)top
                        : (1u << BPX_GRID_Q_BITS) - 1;
    }
    // About 1024 fine x cells across the scene (exact power-of-two scaling, 24 bits at most).
    p->fine_bits = 0;
    while (p->fine_bits < 4 && (p->top[0] + 1) << (p->fine_bits + 1) <= 1024)
        p->fine_bits++;
    p->inv[0] = inv * (float)(1 << p->fine_bits);
    if (!(p->inv[0] < INFINITY))
        p->inv[0] = inv, p->fine_bits = 0;
    p->top[0] = ((p->top[0] + 1) << p->fine_bits) - 1;
}

void bpx__grid_set_levels(bpx_grid_state *st)
{
    const bpx_grid_params *p = &st->params;
    uint32_t first = 0;
    for (int l = 0; l < LEVELS; l++) {
        bpx_grid_level *lv = &st->layout.level[l];
        lv->first_column = first;
        lv->ny = (p->top[1] >> (2 * l)) + 1;
        lv->nz = (p->top[2] >> (2 * l)) + 1;
        first += lv->ny * lv->nz;
    }
    st->params.columns = first;
}

// ---------------------------------------------------------------------------------------------
// 2. Keys (tasks over chunks of box ids)

void bpx__grid_key_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_grid_job *job = context;
    bpx_grid_state *st = job->st;
    const bpx_grid_params *p = &st->params;
    const bpx_grid_level *levels = st->layout.level;
    uint32_t columns = p->columns;
    bpx_grid_cells cells = {.fine_bits = p->fine_bits};
    for (int a = 0; a < 3; a++) {
        cells.origin[a] = p->origin[a];
        cells.inv[a] = p->inv[a];
        cells.top[a] = (float)p->top[a];
    }
    for (int l = 0; l < LEVELS; l++) {
        cells.first_column[l] = levels[l].first_column;
        cells.nz[l] = levels[l].nz;
    }
    for (int c = begin; c < end; c++) {
        bpx_grid_chunk *ch = &st->chunks[c];
        uint32_t *hist = st->hist + (size_t)c * columns;
        memset(hist, 0, sizeof(uint32_t) * columns);
        memset(ch->level_count, 0, sizeof ch->level_count);
        bpx_grid_seen seen = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, 0};
        // A block's keys in vectors, then its counts while the keys are in cache.
        for (uint32_t i0 = ch->begin; i0 < ch->end; i0 += KEY_BLOCK) {
            uint32_t i1 = i0 + KEY_BLOCK < ch->end ? i0 + KEY_BLOCK : ch->end;
            job->keys(&cells, &job->soa, i0, i1, st->key, &seen);
            for (uint32_t i = i0; i < i1; i++) {
                uint32_t key = st->key[i];
                if (key == BPX_GRID_INERT)
                    continue;
                uint32_t l = bpx__grid_key_level(key), column = bpx__grid_key_column(key);
                uint32_t dy = (key & BPX_GRID_SPAN_Y) != 0, dz = (key & BPX_GRID_SPAN_Z) != 0;
                uint32_t nz = levels[l].nz;
                hist[column]++;
                hist[column + dz] += dz;
                hist[column + dy * nz] += dy;
                hist[column + dy * nz + dz] += dy & dz;
                ch->level_count[l]++;
            }
        }
        for (int a = 0; a < 3; a++) {
            ch->lo_min[a] = seen.lo_min[a];
            ch->lo_max[a] = seen.lo_max[a];
        }
        ch->max_extent = seen.largest;
    }
}
