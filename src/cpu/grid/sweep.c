// The grid's columns sorted by min x (5.) and swept by the kernels (6.), in items of columns on
// the workers.

#include <string.h>

#include "core/clock.h"
#include "grid_internal.h"

// ---------------------------------------------------------------------------------------------
// 5. Per column: sort by min x, write the SoA run (tasks over items of columns)

// Sorts the m entries of a column by min x into r at offset `at`; x cells >> shift.
static void sort_column(const bpx_grid_entry *ent, uint32_t m, bpx_grid_soa *r, size_t at,
                        int shift)
{
    uint32_t *keys = r->keys + at, *ids = r->ids + at;
    for (uint32_t t = 0; t < m; t++) {
        keys[t] = bpx__float_key(ent[t].lo[0]);
        ids[t] = t;
    }
    bool sorted = m <= 16 && bpx__insertion_sort(keys, ids, m, UINT64_MAX);
    if (!sorted) {
        // Fine x cells are min x quantised: bucketing on them leaves little to insertion sort.
        uint32_t low = UINT32_MAX, high = 0;
        for (uint32_t t = 0; t < m; t++) {
            uint32_t fx = ent[t].fx & 0xffffffu;
            low = fx < low ? fx : low;
            high = fx > high ? fx : high;
        }
        uint32_t range = high - low + 1;
        uint32_t *sk = r->scratch_keys + at, *si = r->scratch_ids + at;
        if (range <= 2048 && range <= 8 * m) {
            uint32_t counts[2049];
            memset(counts, 0, sizeof(uint32_t) * (range + 1));
            for (uint32_t t = 0; t < m; t++)
                counts[(ent[t].fx & 0xffffffu) - low + 1]++;
            for (uint32_t b = 0; b < range; b++)
                counts[b + 1] += counts[b];
            for (uint32_t t = 0; t < m; t++) {
                uint32_t to = counts[(ent[t].fx & 0xffffffu) - low]++;
                sk[to] = keys[t];
                si[to] = t;
            }
            memcpy(keys, sk, sizeof(uint32_t) * m);
            memcpy(ids, si, sizeof(uint32_t) * m);
            sorted = bpx__insertion_sort(keys, ids, m, 4 * (uint64_t)m + 64);
        }
        if (!sorted)
            bpx__radix_sort(keys, ids, sk, si, m);
    }
    for (uint32_t t = 0; t < m; t++) {
        const bpx_grid_entry *x = &ent[ids[t]];
        for (int a = 0; a < 3; a++) {
            r->lo[a][at + t] = x->lo[a];
            r->hi[a][at + t] = x->hi[a];
        }
        r->id[at + t] = x->id;
        r->cx[at + t] = (x->fx & 0xffffffu) >> shift;
        r->flags[at + t] = (uint8_t)(x->fx >> 24);
    }
}

// The coarser levels' columns, into the shared positions (level 0 sorts as it tests).
void bpx__grid_sort_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_grid_state *st = ((bpx_grid_job *)context)->st;
    const bpx_grid_layout *g = &st->layout;
    for (int item = begin; item < end; item++) {
        int l = 0;
        for (uint32_t c = st->item_column[item]; c < st->item_column[item + 1]; c++) {
            while (l + 1 < g->windowed && c >= g->level[l + 1].first_column)
                l++;
            uint32_t s = st->column_start[c], e = st->column_start[c + 1];
            if (l > 0 && e > s)
                sort_column(entry_at(st, s), e - s, &st->positions, s,
                            st->params.fine_bits + 2 * l);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 6. Tests

void bpx__grid_test_task(int begin, int end, int worker, void *context)
{
    bpx_grid_job *job = context;
    bpx_grid_state *st = job->st;
    uint64_t task_start = job->profile ? bpx__now_ns() : 0;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->cycle->sink->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        if (b < st->item_count) {
            const bpx_grid_layout *g = &st->layout;
            bpx_grid_soa *own = &st->scratch[worker], *shared = &st->positions;
            int l = 0;
            for (uint32_t c = st->item_column[b]; c < st->item_column[b + 1]; c++) {
                while (l + 1 < g->windowed && c >= g->level[l + 1].first_column)
                    l++;
                uint32_t s = st->column_start[c], e = st->column_start[c + 1];
                if (s == e)
                    continue;
                size_t at = s;
                bpx_grid_soa *r = shared;
                if (l == 0) { // sorted here, while the entries are in cache
                    at = 0;
                    r = own;
                    uint64_t sort_start = job->profile ? bpx__now_ns() : 0;
                    sort_column(entry_at(st, s), e - s, own, 0, st->params.fine_bits);
                    pad_soa(own, e - s);
                    if (job->profile)
                        st->worker_time[worker].sort_ns += bpx__now_ns() - sort_start;
                }
                const bpx_grid_run run = {{r->lo[0] + at, r->lo[1] + at, r->lo[2] + at},
                                          {r->hi[0] + at, r->hi[1] + at, r->hi[2] + at},
                                          r->id + at,
                                          r->cx + at,
                                          r->flags + at,
                                          e - s};
                job->column(g, l, c, &run, block);
                if (block->status != BPX_OK)
                    break;
            }
            continue;
        }
        uint32_t k = (uint32_t)(b - st->item_count);
        uint32_t stop = (job->soa.n + PAD - 1) / PAD * PAD;
        uint32_t j0 = k * BIG_SPAN, j1 = j0 + BIG_SPAN < stop ? j0 + BIG_SPAN : stop;
        // Every big box over a few thousand ids at a time: the boxes are read from memory
        // once per cycle, not once per big box.
        for (uint32_t js = j0; js < j1 && block->status == BPX_OK; js += BIG_STEP) {
            uint32_t je = js + BIG_STEP < j1 ? js + BIG_STEP : j1;
            for (uint32_t box = 0; box < st->layout.big_count && block->status == BPX_OK; box++)
                job->big(&st->layout, box, js, je, block);
        }
    }
    if (job->profile)
        st->worker_time[worker].busy_ns += bpx__now_ns() - task_start;
}
