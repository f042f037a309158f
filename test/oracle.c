// bpx tests: the oracle of a world (oracle.h), for test_soak.c and fuzz/fuzz_api.c.
// SPDX-License-Identifier: MIT
#include "oracle.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

__attribute__((noreturn)) static void oracle_abort(const char *what)
{
    fprintf(stderr, "oracle: %s\n", what);
    fflush(stderr);
    abort();
}

static void *oracle_alloc(size_t size)
{
    void *p = malloc(size ? size : 1);
    if (!p)
        oracle_abort("out of memory");
    return p;
}

// Every setting of an id back to a new box's.
static void unfilter(oracle_model *m, uint32_t id)
{
    m->category[id] = 1;
    m->mask[id] = UINT32_MAX;
    m->group[id] = 0;
    m->user_data[id] = 0;
}

static uint64_t pair_key(uint32_t i, uint32_t j)
{
    return i < j ? (uint64_t)i << 32 | j : (uint64_t)j << 32 | i;
}

// Drops the excluded pairs with an id that `gone` says goes.
static void drop_exclusions(oracle_model *m, bool (*gone)(const oracle_model *, uint32_t, uint32_t),
                            uint32_t arg)
{
    uint32_t kept = 0;
    for (uint32_t k = 0; k < m->excluded_count; k++) {
        uint64_t key = m->excluded[k];
        if (!gone(m, (uint32_t)(key >> 32), arg) && !gone(m, (uint32_t)key, arg))
            m->excluded[kept++] = key;
    }
    m->excluded_count = kept;
}

void oracle_init(oracle_model *m, uint32_t capacity)
{
    m->capacity = capacity;
    m->n = 0;
    m->boxes = oracle_alloc(capacity * sizeof *m->boxes);
    m->live = oracle_alloc(capacity * sizeof *m->live);
    m->category = oracle_alloc(capacity * sizeof *m->category);
    m->mask = oracle_alloc(capacity * sizeof *m->mask);
    m->group = oracle_alloc(capacity * sizeof *m->group);
    m->user_data = oracle_alloc(capacity * sizeof *m->user_data);
    m->excluded = oracle_alloc(4 * (size_t)capacity * sizeof *m->excluded);
    m->excluded_count = 0;
    m->pending = oracle_alloc(capacity * sizeof *m->pending);
    m->freed = oracle_alloc(capacity * sizeof *m->freed);
    m->pending_count = m->free_count = 0;
    memset(m->boxes, 0, capacity * sizeof *m->boxes);
    memset(m->pending, 0, capacity * sizeof *m->pending);
    memset(m->freed, 0, capacity * sizeof *m->freed);
    for (uint32_t id = 0; id < capacity; id++) {
        m->live[id] = false;
        unfilter(m, id);
    }
}

void oracle_free(oracle_model *m)
{
    free(m->boxes);
    free(m->live);
    free(m->category);
    free(m->mask);
    free(m->group);
    free(m->user_data);
    free(m->excluded);
    free(m->pending);
    free(m->freed);
    memset(m, 0, sizeof *m);
}

// set_boxes keeps an id's settings when it is live and below both counts (kept).
static bool not_kept(const oracle_model *m, uint32_t id, uint32_t kept)
{
    return id >= kept || !m->live[id];
}

void oracle_copy(oracle_model *dst, const oracle_model *src)
{
    if (dst->boxes)
        oracle_free(dst);
    oracle_init(dst, src->capacity);
    uint32_t c = src->capacity;
    dst->n = src->n;
    memcpy(dst->boxes, src->boxes, c * sizeof *src->boxes);
    memcpy(dst->live, src->live, c * sizeof *src->live);
    memcpy(dst->category, src->category, c * sizeof *src->category);
    memcpy(dst->mask, src->mask, c * sizeof *src->mask);
    memcpy(dst->group, src->group, c * sizeof *src->group);
    memcpy(dst->user_data, src->user_data, c * sizeof *src->user_data);
    memcpy(dst->excluded, src->excluded, src->excluded_count * sizeof *src->excluded);
    dst->excluded_count = src->excluded_count;
    memcpy(dst->pending, src->pending, src->pending_count * sizeof *src->pending);
    dst->pending_count = src->pending_count;
    memcpy(dst->freed, src->freed, src->free_count * sizeof *src->freed);
    dst->free_count = src->free_count;
}

void oracle_reset(oracle_model *m, uint32_t n)
{
    if (n > m->capacity)
        oracle_abort("set_boxes past the model's capacity");
    uint32_t kept = n < m->n ? n : m->n;
    drop_exclusions(m, not_kept, kept);
    for (uint32_t id = 0; id < m->capacity; id++) {
        if (id >= kept || !m->live[id])
            unfilter(m, id);
        m->live[id] = id < n;
    }
    m->pending_count = m->free_count = 0;
    m->n = n;
}

uint32_t oracle_count_after_add(const oracle_model *m, uint32_t count)
{
    uint32_t reused = count < m->free_count ? count : m->free_count;
    return m->n + (count - reused);
}

uint32_t oracle_add(oracle_model *m, const bpx_box *box)
{
    uint32_t id = m->free_count ? m->freed[--m->free_count] : m->n;
    if (id >= m->capacity)
        oracle_abort("add_boxes past the model's capacity");
    if (id == m->n)
        m->n++;
    m->live[id] = true;
    unfilter(m, id);
    m->boxes[id] = *box;
    return id;
}

void oracle_remove(oracle_model *m, uint32_t id)
{
    m->live[id] = false;
    m->pending[m->pending_count++] = id;
}

void oracle_move(oracle_model *m, uint32_t id, const bpx_box *box)
{
    m->boxes[id] = *box;
}

void oracle_set_filter(oracle_model *m, uint32_t id, uint32_t category, uint32_t mask)
{
    m->category[id] = category;
    m->mask[id] = mask;
}

void oracle_set_group(oracle_model *m, uint32_t id, int32_t group)
{
    m->group[id] = group;
}

bool oracle_excluded(const oracle_model *m, uint32_t i, uint32_t j)
{
    uint64_t key = pair_key(i, j);
    for (uint32_t k = 0; k < m->excluded_count; k++)
        if (m->excluded[k] == key)
            return true;
    return false;
}

void oracle_exclude(oracle_model *m, uint32_t i, uint32_t j, bool on)
{
    uint64_t key = pair_key(i, j);
    for (uint32_t k = 0; k < m->excluded_count; k++)
        if (m->excluded[k] == key) {
            if (!on)
                m->excluded[k] = m->excluded[--m->excluded_count];
            return;
        }
    if (!on)
        return;
    if (m->excluded_count == 4 * m->capacity)
        oracle_abort("too many excluded pairs for the model");
    m->excluded[m->excluded_count++] = key;
}

static bool is_pending(const oracle_model *m, uint32_t id, uint32_t unused)
{
    (void)unused;
    for (uint32_t k = 0; k < m->pending_count; k++)
        if (m->pending[k] == id)
            return true;
    return false;
}

void oracle_collided(oracle_model *m)
{
    drop_exclusions(m, is_pending, 0);
    for (uint32_t k = 0; k < m->pending_count; k++)
        m->freed[m->free_count++] = m->pending[k];
    m->pending_count = 0;
}

bool oracle_is_live(const oracle_model *m, uint32_t id)
{
    return id < m->n && m->live[id];
}

bool oracle_filtered(const oracle_model *m)
{
    for (uint32_t id = 0; id < m->n; id++)
        if (m->category[id] != 1 || m->mask[id] != UINT32_MAX || m->group[id] != 0)
            return true;
    return m->excluded_count > 0;
}

bool oracle_overlap(const bpx_box *a, const bpx_box *b)
{
    for (int k = 0; k < 3; k++)
        if (!(a->min[k] <= b->max[k] && b->min[k] <= a->max[k]))
            return false;
    return true;
}

// Live ids i and j pair: their boxes overlap, the pair is not excluded, and a shared non-zero
// group says yes (positive), or else each passes the other's filter,
// (category[i] & mask[j]) && (category[j] & mask[i]).
static bool pair(const oracle_model *m, uint32_t i, uint32_t j)
{
    if (!oracle_overlap(&m->boxes[i], &m->boxes[j]) || oracle_excluded(m, i, j))
        return false;
    if (m->group[i] == m->group[j] && m->group[i] != 0)
        return m->group[i] > 0;
    return (m->category[i] & m->mask[j]) && (m->category[j] & m->mask[i]);
}

size_t oracle_pairs(const oracle_model *m, bpx_pair *out, size_t capacity)
{
    size_t count = 0;
    for (uint32_t i = 0; i < m->n; i++) {
        if (!m->live[i])
            continue;
        for (uint32_t j = i + 1; j < m->n; j++)
            if (m->live[j] && pair(m, i, j)) {
                if (count < capacity)
                    out[count] = (bpx_pair){i, j};
                count++;
            }
    }
    return count;
}

size_t oracle_pairs_alloc(const oracle_model *m, bpx_pair **out)
{
    size_t count = 0, capacity = 64;
    bpx_pair *pairs = oracle_alloc(capacity * sizeof *pairs);
    for (uint32_t i = 0; i < m->n; i++) {
        if (!m->live[i])
            continue;
        for (uint32_t j = i + 1; j < m->n; j++) {
            if (!m->live[j] || !pair(m, i, j))
                continue;
            if (count == capacity) {
                capacity *= 2;
                bpx_pair *grown = realloc(pairs, capacity * sizeof *pairs);
                if (!grown)
                    oracle_abort("out of memory");
                pairs = grown;
            }
            pairs[count++] = (bpx_pair){i, j};
        }
    }
    *out = pairs;
    return count;
}

bool oracle_same_pairs(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb)
{
    return na == nb && (na == 0 || (a && b && memcmp(a, b, na * sizeof *a) == 0));
}

static bool pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

size_t oracle_difference(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb, bpx_pair *out)
{
    size_t x = 0, y = 0, count = 0;
    while (x < na) {
        if (y == nb || pair_less(a[x], b[y]))
            out[count++] = a[x++];
        else if (pair_less(b[y], a[x]))
            y++;
        else
            x++, y++;
    }
    return count;
}

bpx_status oracle_box_problem(const bpx_box *b, int *axis)
{
    for (int a = 0; a < 3; a++)
        if (!isfinite(b->min[a]) || !isfinite(b->max[a]))
            return *axis = a, BPX_ERR_NOT_FINITE;
    for (int a = 0; a < 3; a++)
        if (!(b->min[a] <= b->max[a]))
            return *axis = a, BPX_ERR_MIN_GREATER_THAN_MAX;
    return *axis = -1, BPX_OK;
}

static bool box_valid(const bpx_box *b)
{
    for (int a = 0; a < 3; a++)
        if (!(-FLT_MAX <= b->min[a] && b->min[a] <= b->max[a] && b->max[a] <= FLT_MAX))
            return false;
    return true;
}

bpx_status oracle_boxes_problem(const bpx_box *boxes, uint32_t n, uint32_t *index, int *axis)
{
    for (uint32_t i = 0; i < n; i++)
        if (!box_valid(&boxes[i])) {
            *index = i;
            return oracle_box_problem(&boxes[i], axis);
        }
    return BPX_OK;
}

bpx_status oracle_ids_problem(const oracle_model *m, const uint32_t *ids, uint32_t count,
                              uint32_t *index)
{
    for (uint32_t k = 0; k < count; k++) {
        if (!oracle_is_live(m, ids[k]))
            return *index = k, BPX_ERR_INVALID_ARGUMENT;
        for (uint32_t e = 0; e < k; e++)
            if (ids[e] == ids[k])
                return *index = k, BPX_ERR_INVALID_ARGUMENT;
    }
    return BPX_OK;
}
