// The grid's scatter (4.): each box to the columns it covers, in chunks of box ids on the
// workers, whole cache lines streamed out.

#include <string.h>

#include "grid_internal.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

// Entries are 32 bytes, positions 64-byte aligned in pairs: an entry at an even position waits
// in the stash until the odd one after it comes from the same chunk, and the two go out as one
// whole line, bypassing the cache (no read for ownership of a line about to be overwritten).
// Entries whose other half belongs to another chunk (a range's ends) are stored plainly.
static inline void put_line(bpx_grid_entry *to, const bpx_grid_entry *first,
                            const bpx_grid_entry *second)
{
#if defined(__SSE2__)
    const __m128i *a = (const __m128i *)(const void *)first;
    const __m128i *b = (const __m128i *)(const void *)second;
    __m128i *d = (__m128i *)(void *)to;
    __m128i a0 = _mm_loadu_si128(a), a1 = _mm_loadu_si128(a + 1);
    __m128i b0 = _mm_loadu_si128(b), b1 = _mm_loadu_si128(b + 1);
    _mm_stream_si128(d, a0);
    _mm_stream_si128(d + 1, a1);
    _mm_stream_si128(d + 2, b0);
    _mm_stream_si128(d + 3, b1);
#else
    to[0] = *first;
    to[1] = *second;
#endif
}

static inline void put(bpx_grid_state *st, bpx_grid_entry *stash, uint32_t *stash_at,
                       uint32_t column, uint32_t at, const bpx_grid_entry *e)
{
    if (!(at & 1)) {
        stash[column] = *e;
        stash_at[column] = at;
    } else if (stash_at[column] == at - 1) {
        put_line(entry_at(st, at - 1), &stash[column], e); // one column: one side of split
    } else {
        *entry_at(st, at) = *e;
    }
}

void bpx__grid_scatter_task(int begin, int end, int worker, void *context)
{
    bpx_grid_job *job = context;
    bpx_grid_state *st = job->st;
    const bpx_soa *s = &job->soa;
    const bpx_grid_params *p = &st->params;
    uint32_t windowed = (uint32_t)st->layout.windowed, columns = p->columns;
    uint32_t wcolumns = st->wcolumns;
    bpx_grid_entry *stash = st->stash + (size_t)worker * wcolumns;
    uint32_t *stash_at = st->stash_at + (size_t)worker * wcolumns;
    for (int c = begin; c < end; c++) {
        const bpx_grid_chunk *ch = &st->chunks[c];
        uint32_t *offset = st->hist + (size_t)c * columns;
        memset(stash_at, 0xff, sizeof(uint32_t) * wcolumns);
        for (uint32_t i = ch->begin; i < ch->end; i++) {
            uint32_t key = st->key[i];
            uint32_t l = bpx__grid_key_level(key);
            if (l >= windowed) // big or inert
                continue;
            float lx = s->lo[0][i];
            uint32_t cx = cell_of(lx, p->origin[0], p->inv[0], p->top[0]);
            uint32_t spans = (key & BPX_GRID_SPAN_Y ? BPX_GRID_SPANS_Y : 0) |
                             (key & BPX_GRID_SPAN_Z ? BPX_GRID_SPANS_Z : 0);
            bpx_grid_entry e = {{lx, s->lo[1][i], s->lo[2][i]},
                                {s->hi[0][i], s->hi[1][i], s->hi[2][i]},
                                i,
                                cx | (spans | BPX_GRID_HOME) << 24};
            uint32_t column = bpx__grid_key_column(key), nz = st->layout.level[l].nz;
            put(st, stash, stash_at, column, offset[column]++, &e);
            if (key & BPX_GRID_SPAN_Z) {
                e.fx = cx | (spans | BPX_GRID_FIRST_Y) << 24;
                put(st, stash, stash_at, column + 1, offset[column + 1]++, &e);
            }
            if (key & BPX_GRID_SPAN_Y) {
                e.fx = cx | (spans | BPX_GRID_FIRST_Z) << 24;
                put(st, stash, stash_at, column + nz, offset[column + nz]++, &e);
                if (key & BPX_GRID_SPAN_Z) {
                    e.fx = cx | spans << 24;
                    put(st, stash, stash_at, column + nz + 1, offset[column + nz + 1]++, &e);
                }
            }
        }
        // Entries still waiting: the last of their column's range, at an even position.
        for (uint32_t k = 0; k < wcolumns; k++)
            if (stash_at[k] != UINT32_MAX && stash_at[k] + 1 == offset[k])
                *entry_at(st, stash_at[k]) = stash[k];
    }
#if defined(__SSE2__)
    _mm_sfence(); // the streamed lines are visible before the tests read them
#endif
}
