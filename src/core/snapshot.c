// Snapshot and restore (include/bpx/bpx.h): a world's state as bytes and back, for rollback
// and replays. The layout, all in the machine's byte order (the header says which):
//
//   header   magic "BPXSNAP", a zero byte; u32 format version; u32 0x01020304 (byte order);
//            u64 total size; u64 checksum of everything after the header
//   counts   u32 n, u32 extent count, u32 pending, u32 free, u32 excluded pairs, u32 flags
//            (EXTENTS, OBJECTS, and one bit per id column present), u64 last pairs
//   boxes    six float arrays of n: min x, min y, min z, max x, max y, max z (removed ids
//            inert: min +inf, max -inf)
//   extents  three float arrays of `extent count` (the two-phase minima), when EXTENTS
//   objects  n bytes (1: removed), the pending ids, the free ids, when OBJECTS
//   columns  category, mask (u32), group (i32), user data (u64): n values each, when present
//   excluded the excluded pairs as u64 keys (smaller id << 32 | larger)
//   pairs    the last successful collide's pairs (the events' "before"; ids may be past n
//            after set_boxes to fewer), (i, j) u32 each
//   period   three doubles, bpx_world_def.period (0 on open axes; version 2 on)
//
// A restore reads and checks all of it before it changes anything: then it can only succeed.
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"
#include "boxes.h"
#include "objects.h"
#include "validate.h"

static const char magic[8] = "BPXSNAP";
enum {
    FORMAT_VERSION = 3, // 2: the period; 3: the pair filter's decisions
    BYTE_ORDER_MARK = 0x01020304,
    HEADER_SIZE = 8 + 4 + 4 + 8 + 8,
    HAS_EXTENTS = 1,
    HAS_OBJECTS = 2,
    HAS_COLUMN = 4, // << column index: category, mask, group, user data
    SAVED_COLUMNS = 4, // the exclusion counts (column 4) are rebuilt from the pairs
};

// A multiply-xorshift over 8-byte words in four interleaved lanes (so the multiplies overlap),
// folded at the end: every step is a bijection, so any one changed word changes the sum; many
// GB/s, well below the cost of a collide.
static uint64_t mix(uint64_t h, uint64_t v)
{
    h = (h ^ v) * 0x100000001B3ull;
    return h ^ (h >> 29);
}

static uint64_t checksum(const uint8_t *p, size_t size)
{
    uint64_t lane[4] = {0x9E3779B97F4A7C15ull ^ size, 1, 2, 3};
    size_t k = 0;
    for (; k + 32 <= size; k += 32)
        for (int l = 0; l < 4; l++) {
            uint64_t v;
            memcpy(&v, p + k + 8 * l, 8);
            lane[l] = mix(lane[l], v);
        }
    uint64_t h = lane[0];
    for (int l = 1; l < 4; l++)
        h = mix(h, lane[l]);
    for (; k < size; k++)
        h = mix(h, p[k]);
    return h;
}

// ---------------------------------------------------------------------------------------------
// Writing: a first pass with no buffer measures, the second writes.

typedef struct writer {
    uint8_t *out; // NULL: measure only
    size_t at;
} writer;

static void put(writer *wr, const void *data, size_t size)
{
    if (wr->out && size)
        memcpy(wr->out + wr->at, data, size);
    wr->at += size;
}

static void put_u32(writer *wr, uint32_t v)
{
    put(wr, &v, sizeof v);
}

static void put_u64(writer *wr, uint64_t v)
{
    put(wr, &v, sizeof v);
}

static void write_state(bpx_world *w, writer *wr)
{
    id_column c[BPX_ID_COLUMNS];
    bpx__objects_columns(w, c);
    uint32_t n = w->n, flags = 0;
    if (w->extents_loaded)
        flags |= HAS_EXTENTS;
    if (w->dead)
        flags |= HAS_OBJECTS;
    for (int k = 0; k < SAVED_COLUMNS; k++)
        if (*c[k].data)
            flags |= HAS_COLUMN << k;
    const bpx_pair_list *last = &w->previous;
    put_u32(wr, n);
    put_u32(wr, w->extents_loaded ? w->extent_count : 0);
    put_u32(wr, w->dead ? w->pending_count : 0);
    put_u32(wr, w->dead ? w->free_count : 0);
    put_u32(wr, w->excluded.count);
    put_u32(wr, flags);
    put_u64(wr, last->count);
    for (int a = 0; a < 3; a++)
        put(wr, w->boxes.lo[a], sizeof(float) * n);
    for (int a = 0; a < 3; a++)
        put(wr, w->boxes.hi[a], sizeof(float) * n);
    if (flags & HAS_EXTENTS)
        for (int a = 0; a < 3; a++)
            put(wr, w->minima[a], sizeof(float) * w->extent_count);
    if (flags & HAS_OBJECTS) {
        put(wr, w->dead, n);
        put(wr, w->pending_ids, sizeof(uint32_t) * w->pending_count);
        put(wr, w->free_ids, sizeof(uint32_t) * w->free_count);
    }
    for (int k = 0; k < SAVED_COLUMNS; k++)
        if (flags & (HAS_COLUMN << k))
            put(wr, *c[k].data, c[k].size * n);
    for (uint32_t s = 0; s < w->excluded.capacity; s++)
        if (w->excluded.keys[s] != BPX_PAIR_SET_EMPTY)
            put_u64(wr, w->excluded.keys[s]);
    put(wr, last->pairs, sizeof(bpx_pair) * last->count);
    put(wr, w->def.period, sizeof w->def.period);
    // The pair filter's decisions on the pairs that persist: a restored world does not ask
    // again about them (a filter's answer may depend on its own state, which is the caller's).
    put_u64(wr, w->candidates.count);
    put_u64(wr, w->rejected.count);
    put(wr, w->candidates.pairs, sizeof(bpx_pair) * w->candidates.count);
    put(wr, w->rejected.pairs, sizeof(bpx_pair) * w->rejected.count);
}

bpx_status bpx_world_snapshot(const bpx_world *world, void *buffer, size_t capacity,
                              size_t *size)
{
    if (!world || !size || (capacity && !buffer))
        return BPX_ERR_NULL_ARGUMENT;
    if (world->boxes_on_device || world->boxes64_set) // float64 boxes: not in the format yet
        return BPX_ERR_BAD_STATE;
    bpx_world *w = (bpx_world *)world; // read only: the column table takes a mutable world
    writer measure = {NULL, HEADER_SIZE};
    write_state(w, &measure);
    *size = measure.at;
    if (measure.at > capacity)
        return BPX_ERR_CAPACITY;
    uint8_t *out = buffer;
    writer body = {out, HEADER_SIZE};
    write_state(w, &body);
    writer head = {out, 0};
    put(&head, magic, sizeof magic);
    put_u32(&head, FORMAT_VERSION);
    put_u32(&head, BYTE_ORDER_MARK);
    put_u64(&head, measure.at);
    put_u64(&head, checksum(out + HEADER_SIZE, measure.at - HEADER_SIZE));
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Reading: every section located and checked first.

typedef struct reader {
    const uint8_t *data;
    size_t at, size;
} reader;

// The next `size` bytes, or NULL when the buffer ends first.
static const void *take(reader *r, size_t size)
{
    if (size > r->size - r->at)
        return NULL;
    const void *p = r->data + r->at;
    r->at += size;
    return p;
}

static uint32_t read_u32(const void *p)
{
    uint32_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

static uint64_t read_u64(const void *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

static float read_float(const uint8_t *array, size_t i)
{
    float v;
    memcpy(&v, array + sizeof(float) * i, sizeof v);
    return v;
}

// Where each section lies in the buffer (byte pointers: the sections need not be aligned).
typedef struct sections {
    const uint8_t *base;
    uint32_t n, extent_count, pending, freed, excluded, flags;
    uint64_t last;
    const uint8_t *lo[3], *hi[3], *minima[3];
    const uint8_t *dead, *pending_ids, *free_ids;
    const uint8_t *columns[SAVED_COLUMNS];
    const uint8_t *keys, *pairs, *period;
    uint64_t decided, refused; // the pair filter's candidates and the rejected among them
    const uint8_t *decided_pairs, *refused_pairs;
} sections;

// The offset of p in the buffer, for messages.
static size_t at(const sections *s, const uint8_t *p)
{
    return (size_t)(p - s->base);
}

static bpx_status bad(bpx_world *w, size_t offset, const char *what)
{
    return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                      "restore: %s (byte %zu)", what, offset);
}

static bpx_status locate(bpx_world *w, reader *r, sections *s)
{
    const uint8_t *head = take(r, HEADER_SIZE);
    if (!head)
        return bad(w, r->size, "shorter than a snapshot's header");
    if (memcmp(head, magic, sizeof magic) != 0)
        return bad(w, 0, "not a bpx snapshot");
    if (read_u32(head + 12) != BYTE_ORDER_MARK)
        return bad(w, 12, "written on a machine of the other byte order");
    uint32_t version = read_u32(head + 8);
    if (version != FORMAT_VERSION) {
        char what[128];
        snprintf(what, sizeof what,
                 "format version %u, and this library reads version %d only (version 1 had no "
                 "period, version 2 no pair filter decisions)",
                 version, FORMAT_VERSION);
        return bad(w, 8, what);
    }
    if (read_u64(head + 16) != r->size)
        return bad(w, 16, "its size is not the buffer's: truncated, or more than one");
    if (read_u64(head + 24) != checksum(r->data + HEADER_SIZE, r->size - HEADER_SIZE))
        return bad(w, 24, "the checksum does not match: the bytes were changed");
    const uint8_t *counts = take(r, 6 * 4 + 8);
    if (!counts)
        return bad(w, r->at, "truncated in its counts");
    s->n = read_u32(counts);
    s->extent_count = read_u32(counts + 4);
    s->pending = read_u32(counts + 8);
    s->freed = read_u32(counts + 12);
    s->excluded = read_u32(counts + 16);
    s->flags = read_u32(counts + 20);
    s->last = read_u64(counts + 24);
    if (s->n > BPX_MAX_BOXES)
        return bad(w, HEADER_SIZE, "more boxes than BPX_MAX_BOXES");
    bool extents = s->flags & HAS_EXTENTS, objects = s->flags & HAS_OBJECTS;
    if ((extents && s->extent_count != s->n) || (!extents && s->extent_count) ||
        (!objects && (s->pending || s->freed)) || s->pending > s->n || s->freed > s->n ||
        s->flags >> (2 + SAVED_COLUMNS))
        return bad(w, HEADER_SIZE, "its counts do not hold together");
    size_t n = s->n;
    for (int a = 0; a < 6; a++) {
        const uint8_t **to = a < 3 ? &s->lo[a] : &s->hi[a - 3];
        if (!(*to = take(r, sizeof(float) * n)))
            return bad(w, r->at, "truncated in its boxes");
    }
    for (int a = 0; a < 3 && extents; a++)
        if (!(s->minima[a] = take(r, sizeof(float) * n)))
            return bad(w, r->at, "truncated in its extents");
    if (objects && (!(s->dead = take(r, n)) ||
                    !(s->pending_ids = take(r, sizeof(uint32_t) * s->pending)) ||
                    !(s->free_ids = take(r, sizeof(uint32_t) * s->freed))))
        return bad(w, r->at, "truncated in its objects");
    static const size_t column_size[SAVED_COLUMNS] = {4, 4, 4, 8};
    for (int k = 0; k < SAVED_COLUMNS; k++)
        if ((s->flags & (HAS_COLUMN << k)) && !(s->columns[k] = take(r, column_size[k] * n)))
            return bad(w, r->at, "truncated in its filters, groups or user data");
    if (!(s->keys = take(r, sizeof(uint64_t) * s->excluded)))
        return bad(w, r->at, "truncated in its excluded pairs");
    if (s->last > (SIZE_MAX - r->at) / sizeof(bpx_pair) ||
        !(s->pairs = take(r, sizeof(bpx_pair) * s->last)))
        return bad(w, r->at, "truncated in its pairs");
    if (!(s->period = take(r, 3 * sizeof(double))))
        return bad(w, r->at, "truncated in its period");
    const uint8_t *decisions = take(r, 16);
    if (!decisions)
        return bad(w, r->at, "truncated in its pair filter decisions");
    s->decided = read_u64(decisions);
    s->refused = read_u64(decisions + 8);
    if (s->refused > s->decided || s->decided > (SIZE_MAX - r->at) / sizeof(bpx_pair) ||
        !(s->decided_pairs = take(r, sizeof(bpx_pair) * s->decided)) ||
        !(s->refused_pairs = take(r, sizeof(bpx_pair) * s->refused)))
        return bad(w, r->at, "truncated in its pair filter decisions");
    if (r->at != r->size)
        return bad(w, r->at, "bytes after its last section");
    return BPX_OK;
}

// The sections' values: boxes valid (removed ids inert), ids in range and removed, each once;
// minima finite and <= 0; excluded pairs of two live ids, once each; pairs sorted, of ids < n.
// Whether every box is valid and live (the common case), in one branch-free pass per axis.
static bool all_live_and_valid(const sections *s)
{
    bool bad = false;
    for (int a = 0; a < 3; a++)
        for (uint32_t i = 0; i < s->n; i++) {
            float lo = read_float(s->lo[a], i), hi = read_float(s->hi[a], i);
            // lo <= hi with both finite: fails for NaN, infinities and min > max.
            bad |= !(lo <= hi) | (lo < -FLT_MAX) | (hi > FLT_MAX);
        }
    for (uint32_t i = 0; s->dead && i < s->n; i++)
        bad |= s->dead[i] != 0;
    return !bad;
}

static bpx_pair read_pair(const uint8_t *pairs, uint64_t k)
{
    bpx_pair p;
    memcpy(&p, pairs + sizeof(bpx_pair) * k, sizeof p);
    return p;
}

// NULL when the count pairs are sorted pairs (i < j) of ids, else the first that is not.
static const uint8_t *sorted_pairs(const uint8_t *pairs, uint64_t count)
{
    bpx_pair before = {0, 0};
    for (uint64_t k = 0; k < count; k++) {
        bpx_pair p = read_pair(pairs, k);
        if (p.i >= p.j || p.j >= BPX_MAX_BOXES || (k && !bpx__pair_less(before, p)))
            return pairs + sizeof(bpx_pair) * k;
        before = p;
    }
    return NULL;
}

static bpx_status check_values(bpx_world *w, const sections *s)
{
    for (uint32_t i = all_live_and_valid(s) ? s->n : 0; i < s->n; i++) {
        bool removed = s->dead && s->dead[i];
        if (s->dead && s->dead[i] > 1)
            return bad(w, at(s, s->dead + i), "an id's removed flag is neither 0 nor 1");
        for (int a = 0; a < 3; a++) {
            float lo = read_float(s->lo[a], i), hi = read_float(s->hi[a], i);
            bool ok = removed ? lo == INFINITY && hi == -INFINITY
                              : isfinite(lo) && isfinite(hi) && lo <= hi;
            if (!ok)
                return bad(w, at(s, s->lo[a] + sizeof(float) * i),
                           removed ? "a removed id's box is not inert"
                                   : "a box is not finite, or has min > max");
        }
    }
    for (int a = 0; a < 3 && (s->flags & HAS_EXTENTS); a++)
        for (uint32_t i = 0; i < s->n; i++) {
            float m = read_float(s->minima[a], i);
            if (!isfinite(m) || m > 0.0f)
                return bad(w, at(s, s->minima[a] + sizeof(float) * i),
                           "an extent's minimum is not finite and <= 0");
        }
    // Pending and free ids: removed ids, each in at most one of the two lists.
    uint8_t *seen = s->n ? bpx__alloc(s->n) : NULL;
    if (s->n && !seen)
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    if (seen)
        memset(seen, 0, s->n);
    bpx_status status = BPX_OK;
    for (uint32_t k = 0; k < s->pending + s->freed && status == BPX_OK; k++) {
        const uint8_t *p = k < s->pending ? s->pending_ids + 4 * (size_t)k
                                          : s->free_ids + 4 * (size_t)(k - s->pending);
        uint32_t id = read_u32(p);
        if (id >= s->n || !s->dead[id] || seen[id])
            status = bad(w, at(s, p), "a pending or free id is out of range, live, or listed twice");
        else
            seen[id] = k < s->pending ? 1 : 2;
    }
    // An excluded pair's ids are live, or removed and still pending: a removed id's exclusions
    // go at the next collide (objects.c), so a snapshot between the two holds them.
    for (uint32_t k = 0; k < s->excluded && status == BPX_OK; k++) {
        const uint8_t *p = s->keys + 8 * (size_t)k;
        uint64_t key = read_u64(p);
        uint32_t i = (uint32_t)(key >> 32), j = (uint32_t)key;
        if (i >= j || j >= s->n ||
            (s->dead && ((s->dead[i] && seen[i] != 1) || (s->dead[j] && seen[j] != 1))))
            status = bad(w, at(s, p), "an excluded pair is not of two different ids in use");
    }
    bpx__free(seen, s->n);
    if (status != BPX_OK)
        return status;
    for (int a = 0; a < 3; a++) {
        double p;
        memcpy(&p, s->period + sizeof p * a, sizeof p);
        if (!(p >= 0 && p < 0x1p1000))
            return bad(w, at(s, s->period + sizeof p * a),
                       "a period is negative, NaN, infinite or past 2^1000");
        if (p > 0 && bpx__world_margins(w))
            return bad(w, at(s, s->period + sizeof p * a),
                       "a periodic snapshot, and this world has contact margins, which a "
                       "periodic world does not support");
    }
    // Ids may be past n: set_boxes to fewer boxes keeps the last pairs, for the events that
    // end them, and the decisions about them.
    const uint8_t *q = sorted_pairs(s->pairs, s->last);
    if (q)
        return bad(w, at(s, q), "the last pairs are not sorted pairs of two ids");
    if ((q = sorted_pairs(s->decided_pairs, s->decided)) ||
        (q = sorted_pairs(s->refused_pairs, s->refused)))
        return bad(w, at(s, q), "the pair filter's decisions are not sorted pairs of two ids");
    // Each refused pair is one of the decided (both sorted: one walk).
    uint64_t d = 0;
    for (uint64_t k = 0; k < s->refused; k++) {
        bpx_pair p = read_pair(s->refused_pairs, k), c = {0, 0};
        while (d < s->decided && bpx__pair_less(c = read_pair(s->decided_pairs, d), p))
            d++;
        if (d == s->decided || c.i != p.i || c.j != p.j)
            return bad(w, at(s, s->refused_pairs + sizeof(bpx_pair) * k),
                       "a pair the filter refused is not among the pairs it decided");
    }
    return BPX_OK;
}

bpx_status bpx_world_restore(bpx_world *w, const void *buffer, size_t size)
{
    bpx_status status = bpx__world_enter(w, "restore");
    if (status != BPX_OK)
        return status;
    if (!buffer && size)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "buffer is NULL");
    reader r = {buffer, 0, size};
    sections s = {.base = buffer};
    if ((status = locate(w, &r, &s)) != BPX_OK || (status = check_values(w, &s)) != BPX_OK)
        return status;

    // Everything that can fail, into memory the world's state does not depend on yet: the
    // spare boxes, minima arrays, the per-id arrays and columns (grown, or made at their
    // defaults, which change nothing), the excluded set, room for the last pairs.
    uint32_t n = s.n;
    bool extents = s.flags & HAS_EXTENTS;
    float *minima[3] = {0};
    bool grow_minima = extents && n > w->extent_capacity;
    bpx_pair_set excluded = {0};
    id_column c[BPX_ID_COLUMNS];
    bpx__objects_columns(w, c);
    bool ok = bpx__box_arrays_reserve(&w->spare, n);
    // update_centres swaps the two sets and never allocates: in the two-phase mode both must
    // hold n boxes.
    bpx_box_arrays grown = {0};
    if (ok && extents && bpx__boxes_padded(n) > w->boxes.capacity)
        ok = bpx__box_arrays_reserve(&grown, n);
    for (int a = 0; a < 3 && grow_minima && ok; a++)
        ok = (minima[a] = bpx__alloc(sizeof(float) * n)) != NULL;
    bool objects = (s.flags & ~(uint32_t)HAS_EXTENTS) || w->dead || s.excluded;
    ok = ok && (!objects || bpx__objects_reserve(w, n));
    for (int k = 0; k < SAVED_COLUMNS && ok; k++)
        if (s.flags & (HAS_COLUMN << k))
            ok = bpx__objects_use_column(w, c[k].data);
    if (ok && s.excluded)
        ok = bpx__objects_use_column(w, c[4].data) && bpx__pair_set_reserve(&excluded, s.excluded);
    // Room for s.last pairs and the decisions, keeping what the lists hold.
    bpx_pair_list *lists[3] = {&w->previous, &w->candidates, &w->rejected};
    uint64_t needed[3] = {s.last, s.decided, s.refused};
    for (int k = 0; k < 3 && ok; k++) {
        size_t count = lists[k]->count;
        lists[k]->count = 0;
        ok = bpx__list_reserve(lists[k], needed[k]);
        lists[k]->count = count;
    }
    if (!ok) {
        for (int a = 0; a < 3; a++)
            bpx__free(minima[a], sizeof(float) * n);
        bpx__pair_set_free(&excluded);
        bpx__box_arrays_free(&grown);
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "restore: no memory for %u boxes", n);
    }

    // Nothing fails from here.
    if (grown.capacity) {
        bpx__box_arrays_free(&w->boxes);
        w->boxes = grown;
    }
    for (int a = 0; a < 3 && n; a++) {
        memcpy(w->spare.lo[a], s.lo[a], sizeof(float) * n);
        memcpy(w->spare.hi[a], s.hi[a], sizeof(float) * n);
    }
    bpx__boxes_swap_in_spare(w, n);
    if (grow_minima) {
        for (int a = 0; a < 3; a++) {
            bpx__free(w->minima[a], sizeof(float) * w->extent_capacity);
            w->minima[a] = minima[a];
        }
        w->extent_capacity = n;
    }
    for (int a = 0; a < 3 && extents && n; a++)
        memcpy(w->minima[a], s.minima[a], sizeof(float) * n);
    w->extents_loaded = extents;
    w->extent_count = extents ? n : 0;
    if (w->dead) {
        memset(w->dead, 0, w->object_capacity);
        if (s.dead && n)
            memcpy(w->dead, s.dead, n);
        if (s.pending)
            memcpy(w->pending_ids, s.pending_ids, sizeof(uint32_t) * s.pending);
        if (s.freed)
            memcpy(w->free_ids, s.free_ids, sizeof(uint32_t) * s.freed);
        w->pending_count = s.pending;
        w->free_count = s.freed;
    }
    for (int k = 0; k < BPX_ID_COLUMNS; k++) {
        if (!*c[k].data)
            continue;
        uint32_t from = 0;
        if (k < SAVED_COLUMNS && (s.flags & (HAS_COLUMN << k))) {
            if (n)
                memcpy(*c[k].data, s.columns[k], c[k].size * n);
            from = n;
        }
        bpx__objects_fill_column(&c[k], from, w->object_capacity);
    }
    bpx__pair_set_free(&w->excluded);
    w->excluded = excluded;
    for (uint32_t k = 0; k < s.excluded; k++) {
        uint64_t key = read_u64(s.keys + 8 * (size_t)k);
        if (bpx__pair_set_add(&w->excluded, key)) {
            w->exclusions[key >> 32]++;
            w->exclusions[(uint32_t)key]++;
        }
    }
    if (s.last)
        memcpy(w->previous.pairs, s.pairs, sizeof(bpx_pair) * s.last);
    w->previous.count = s.last;
    memcpy(w->def.period, s.period, sizeof w->def.period);
    bpx__objects_forget_decisions(w);
    if (s.decided)
        memcpy(w->candidates.pairs, s.decided_pairs, sizeof(bpx_pair) * s.decided);
    if (s.refused)
        memcpy(w->rejected.pairs, s.refused_pairs, sizeof(bpx_pair) * s.refused);
    w->candidates.count = s.decided;
    w->rejected.count = s.refused;
    w->boxes64_set = false; // the snapshot's boxes are float32
    // The last result is not the restored world's: pairs and events read as none until the
    // next collide, which reports its events against the restored pairs.
    w->result_valid = w->merged = w->events_valid = false;
    w->emitter.planned_n = UINT32_MAX;
    bpx__world_boxes_replaced(w);
    return BPX_OK;
}
