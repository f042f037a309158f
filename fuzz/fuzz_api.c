// Fuzzes the API: the input is a world's definition and a sequence of operations on it.
// SPDX-License-Identifier: MIT
//
// A model of the world (boxes, live and removed ids, the ids waiting for reuse, filters: the
// oracle that test_soak.c uses too, test/oracle.h; and the last cycle's pairs) runs beside it.
// Every call's status is predicted from the model and checked; every collide is checked against
// Algorithm 1 (brute force over the model's live boxes, filters applied), and with track_events
// its began and ended lists against the model's last pairs; every error is checked to leave the
// world as it was (box count, last pairs, and the next collide against the unchanged model). An
// operation can make one allocation of the next call fail (bpx_set_allocator), so out-of-memory
// paths are walked too.
//
// Input: byte 0 the backend (every CPU one), byte 1 the options (workers, events, SIMD), then
// operations, an opcode byte and its arguments each. Running out of bytes ends the sequence;
// bulk data past the end (a large set_boxes) comes from a generator seeded by the input.
#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include <bpx/bpx.h>

#include "fuzz_check.h"
#include "oracle.h" // test/

enum {
    MAX_N = 640,  // boxes in a world: past auto's brute limit (128), small enough to check
    MAX_BATCH = 8, // boxes or ids per add / remove / move / set_filters
    NO_FAILURE = -1,
};

// ---------------------------------------------------------------------------------------------
// Reading the input

typedef struct input {
    const uint8_t *data;
    size_t size, at;
    uint64_t rng; // for bulk data past the input's end
} input;

static bool more(const input *in)
{
    return in->at < in->size;
}

static uint8_t byte(input *in)
{
    if (in->at < in->size)
        return in->data[in->at++];
    in->rng ^= in->rng << 13, in->rng ^= in->rng >> 7, in->rng ^= in->rng << 17;
    return (uint8_t)(in->rng >> 24);
}

static uint32_t u32(input *in)
{
    uint32_t v = 0;
    for (int k = 0; k < 4; k++)
        v = v << 8 | byte(in);
    return v;
}

static float bits_to_float(uint32_t bits)
{
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

// A coordinate: mostly small multiples of 1/4 (so faces touch and boxes overlap often), else
// a special value, else any 32 bits (NaN, infinities, subnormals, huge values).
static float coordinate(input *in)
{
    static const float special[] = {0.0f,     -0.0f,    FLT_MAX,  -FLT_MAX, FLT_MIN,
                                    -FLT_MIN, 1e-45f,   INFINITY, -INFINITY, NAN,
                                    3e38f,    -3e38f,   1e30f,    0.5f,     -1.0f};
    uint8_t b = byte(in);
    if (b < 0xE0)
        return (float)((int)b - 0x70) * 0.25f;
    if (b < 0xF8)
        return special[(b - 0xE0) % (sizeof special / sizeof special[0])];
    return bits_to_float(u32(in));
}

// A box: a corner and a size (usually valid), or six coordinates as they come.
static bpx_box box(input *in)
{
    bpx_box b;
    uint8_t how = byte(in);
    if (how < 0xF0) {
        for (int a = 0; a < 3; a++) {
            b.min[a] = coordinate(in);
            b.max[a] = b.min[a] + (float)(byte(in) & 0x1F) * 0.25f;
        }
    } else {
        for (int a = 0; a < 3; a++)
            b.min[a] = coordinate(in), b.max[a] = coordinate(in);
    }
    return b;
}

// A count of boxes for set_boxes / load_extents: mostly small, sometimes past auto's brute
// limit, so prune, sap and grid run too.
static uint32_t world_size(input *in)
{
    uint8_t b = byte(in);
    if (b < 0xC0)
        return b % 40;
    return 100 + (uint32_t)(b - 0xC0) * (MAX_N - 100) / 0x3F;
}

// An id: mostly one near the range in use, sometimes any 32 bits.
static uint32_t some_id(input *in, uint32_t n)
{
    uint8_t b = byte(in);
    if (b < 0xF8)
        return b % (n + 2);
    return u32(in);
}

// ---------------------------------------------------------------------------------------------
// Allocation failure: the `fail_at`-th allocation from now fails (counting from 0).

static atomic_long fail_at = NO_FAILURE;
static atomic_long failures;

static void *fuzz_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    if (atomic_load(&fail_at) >= 0 && atomic_fetch_sub(&fail_at, 1) == 0) {
        atomic_fetch_add(&failures, 1);
        return NULL;
    }
    return aligned_alloc(alignment, size);
}

// Called right after the call under test, so that the checks' own calls never fail.
static void disarm(void)
{
    atomic_store(&fail_at, NO_FAILURE);
}

static void fuzz_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

// ---------------------------------------------------------------------------------------------
// The model

typedef struct model {
    oracle_model o; // the world's ids, boxes and filters (test/oracle.h)
    bool two_phase;
    float minima[MAX_N][3];
    // The last collide: its pairs when it succeeded, and what events should say.
    bool result_valid;
    bpx_pair *pairs;
    size_t pair_count;
    bpx_pair *previous; // pairs of the last successful collide, for events
    size_t previous_count;
    bool have_previous;
    bool events_valid;
    bool track_events;
} model;

static void check_same_pairs(const char *what, const bpx_pair *got, size_t got_count,
                             const bpx_pair *want, size_t want_count)
{
    FUZZ_CHECK(got_count == want_count, "%s: %zu pairs, the reference %zu", what, got_count,
               want_count);
    FUZZ_CHECK(want_count == 0 || (got && memcmp(got, want, want_count * sizeof *got) == 0),
               "%s: pairs differ from the reference", what);
}

// ---------------------------------------------------------------------------------------------
// The run

// A snapshot the run took, with the model as it was then (op_snapshot, op_restore).
typedef struct saved {
    void *bytes;
    size_t size;
    model m; // m.o, m.pairs and m.previous are copies the saved state owns
} saved;

typedef struct run {
    bpx_world *world;
    model m;
    input in;
    bool inject; // an allocation of this call may fail
    saved save;
} run;

static const char *const op_names[] = {
    "set_boxes", "load_extents", "update_centres", "add_boxes",    "remove_boxes",
    "move_boxes", "set_filters", "collide",        "collide_into", "fail_next",
    "copy_pairs", "find_pairs", "set_groups",   "exclude_pairs", "set_user_data",
    "snapshot",   "restore",
};
enum { OP_COUNT = sizeof op_names / sizeof op_names[0] };

// What the world shows that an error must leave alone: box count and the last pairs.
typedef struct snapshot {
    uint32_t n;
    bool pairs_valid;
    bpx_pair *pairs;
    size_t count;
} snapshot;

static snapshot take_snapshot(run *r)
{
    snapshot s = {.n = bpx_world_box_count(r->world)};
    FUZZ_CHECK(s.n == r->m.o.n, "box count %u, the model's %u", s.n, r->m.o.n);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(r->world, &count);
    s.pairs_valid = pairs != NULL || count > 0;
    FUZZ_CHECK(r->m.result_valid || (pairs == NULL && count == 0),
               "pairs readable after a failed collide");
    if (r->m.result_valid)
        check_same_pairs("pairs", pairs, count, r->m.pairs, r->m.pair_count);
    s.count = count;
    s.pairs = malloc((count ? count : 1) * sizeof *s.pairs);
    FUZZ_CHECK(s.pairs != NULL, "out of memory");
    if (count)
        memcpy(s.pairs, pairs, count * sizeof *pairs);
    return s;
}

static void check_unchanged(run *r, const snapshot *s, const char *op)
{
    FUZZ_CHECK(bpx_world_box_count(r->world) == s->n, "%s: a failed call changed n from %u to %u",
               op, s->n, bpx_world_box_count(r->world));
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(r->world, &count);
    check_same_pairs(op, pairs, count, s->pairs, s->count);
}

// The status a call returned against the one the model predicts. With an allocation made to
// fail, OUT_OF_MEMORY may stand for any error, and for success when the library has a way
// round it (it must then still be right: the model goes on as for success).
static bool accept(run *r, const char *op, bpx_status got, bpx_status want, long failures_before)
{
    bool failed_alloc = atomic_load(&failures) > failures_before;
    if (got == BPX_ERR_OUT_OF_MEMORY && failed_alloc)
        return false;
    FUZZ_CHECK(got == want, "%s: status %s, predicted %s (%s)", op, bpx_status_string(got),
               bpx_status_string(want), bpx_world_error(r->world)->message);
    if (got != BPX_OK) {
        const bpx_error *e = bpx_world_error(r->world);
        FUZZ_CHECK(e->status == got && e->message[0] != '\0', "%s: error %s without a message",
                   op, bpx_status_string(got));
    }
    return got == BPX_OK;
}

static void check_box_error(run *r, const char *op, uint32_t index, int axis)
{
    const bpx_error *e = bpx_world_error(r->world);
    FUZZ_CHECK(e->index == index && e->axis == axis, "%s: error names box %u axis %d, not %u %d",
               op, e->index, e->axis, index, axis);
}

static void op_set_boxes(run *r)
{
    uint32_t n = world_size(&r->in);
    bpx_box *boxes = malloc((n ? n : 1) * sizeof *boxes);
    FUZZ_CHECK(boxes != NULL, "out of memory");
    for (uint32_t i = 0; i < n; i++)
        boxes[i] = box(&r->in);
    uint32_t index = UINT32_MAX;
    int axis = -1;
    bpx_status want = oracle_boxes_problem(boxes, n, &index, &axis);
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_set_boxes(r->world, boxes, n);
    disarm();
    if (accept(r, "set_boxes", got, want, before)) {
        oracle_reset(&r->m.o, n);
        memcpy(r->m.o.boxes, boxes, n * sizeof *boxes);
        r->m.two_phase = false;
    } else if (got == want) {
        check_box_error(r, "set_boxes", index, axis);
    }
    free(boxes);
}

static void op_load_extents(run *r)
{
    uint32_t n = world_size(&r->in);
    float *minima = malloc((n ? n : 1) * 3 * sizeof *minima);
    FUZZ_CHECK(minima != NULL, "out of memory");
    bpx_status want = BPX_OK;
    uint32_t index = UINT32_MAX;
    int axis = -1;
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            uint8_t b = byte(&r->in);
            float v = b < 0xF0 ? -(float)(b & 0x1F) * 0.25f : coordinate(&r->in);
            minima[3 * i + a] = v;
            if (want == BPX_OK && (!isfinite(v) || !(v <= 0.0f))) {
                want = isfinite(v) ? BPX_ERR_MIN_GREATER_THAN_MAX : BPX_ERR_NOT_FINITE;
                index = i, axis = a;
            }
        }
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_load_extents(r->world, minima, n);
    disarm();
    if (accept(r, "load_extents", got, want, before)) {
        oracle_reset(&r->m.o, n);
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                float v = minima[3 * i + a];
                r->m.minima[i][a] = v;
                r->m.o.boxes[i].min[a] = v;
                r->m.o.boxes[i].max[a] = -v;
            }
        r->m.two_phase = true;
    } else if (got == want) {
        check_box_error(r, "load_extents", index, axis);
    }
    free(minima);
}

static void op_update_centres(run *r)
{
    uint32_t n = r->m.o.n;
    float *centres = malloc((n ? n : 1) * 3 * sizeof *centres);
    FUZZ_CHECK(centres != NULL, "out of memory");
    bpx_status want = r->m.two_phase ? BPX_OK : BPX_ERR_BAD_STATE;
    uint32_t index = UINT32_MAX;
    int axis = -1;
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float c = coordinate(&r->in);
            centres[3 * i + a] = c;
            if (want == BPX_OK && r->m.two_phase) {
                float m = r->m.minima[i][a];
                float lo = c + m, hi = c - m;
                if (!(-FLT_MAX <= lo && hi <= FLT_MAX))
                    want = BPX_ERR_NOT_FINITE, index = i, axis = a;
            }
        }
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_update_centres(r->world, centres);
    disarm();
    if (accept(r, "update_centres", got, want, before)) {
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                r->m.o.boxes[i].min[a] = centres[3 * i + a] + r->m.minima[i][a];
                r->m.o.boxes[i].max[a] = centres[3 * i + a] - r->m.minima[i][a];
            }
    } else if (got == want && want == BPX_ERR_NOT_FINITE) {
        check_box_error(r, "update_centres", index, axis);
    }
    free(centres);
}

static void op_add_boxes(run *r)
{
    uint32_t count = byte(&r->in) % (MAX_BATCH + 1);
    bpx_box boxes[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++)
        boxes[k] = box(&r->in);
    uint32_t index = UINT32_MAX;
    int axis = -1;
    bpx_status want = BPX_OK;
    if (r->m.two_phase)
        want = BPX_ERR_BAD_STATE;
    else
        want = oracle_boxes_problem(boxes, count, &index, &axis);
    if (want == BPX_OK && oracle_count_after_add(&r->m.o, count) > MAX_N)
        return; // past what the model holds: not tried
    uint32_t ids[MAX_BATCH + 1];
    memset(ids, 0xAB, sizeof ids);
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_add_boxes(r->world, boxes, count, ids);
    disarm();
    if (accept(r, "add_boxes", got, want, before)) {
        for (uint32_t k = 0; k < count; k++) {
            uint32_t want_id = oracle_add(&r->m.o, &boxes[k]);
            FUZZ_CHECK(ids[k] == want_id, "add_boxes: id %u, expected %u", ids[k], want_id);
        }
        FUZZ_CHECK(ids[count] == 0xABABABABu, "add_boxes wrote past its count");
    } else if (got == want && want != BPX_ERR_BAD_STATE) {
        check_box_error(r, "add_boxes", index, axis);
    }
}

static void op_remove_boxes(run *r)
{
    uint32_t count = byte(&r->in) % (MAX_BATCH + 1);
    uint32_t ids[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++)
        ids[k] = some_id(&r->in, r->m.o.n);
    uint32_t index = UINT32_MAX;
    bpx_status want = oracle_ids_problem(&r->m.o, ids, count, &index);
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_remove_boxes(r->world, ids, count);
    disarm();
    if (accept(r, "remove_boxes", got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            oracle_remove(&r->m.o, ids[k]);
    } else if (got == want) {
        check_box_error(r, "remove_boxes", index, -1);
    }
}

static void op_move_boxes(run *r)
{
    uint32_t count = byte(&r->in) % (MAX_BATCH + 1);
    uint32_t ids[MAX_BATCH];
    bpx_box boxes[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++) {
        ids[k] = some_id(&r->in, r->m.o.n);
        boxes[k] = box(&r->in);
    }
    uint32_t index = UINT32_MAX;
    int axis = -1;
    bpx_status want = oracle_boxes_problem(boxes, count, &index, &axis);
    if (want == BPX_OK)
        want = oracle_ids_problem(&r->m.o, ids, count, &index);
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_move_boxes(r->world, ids, boxes, count);
    disarm();
    if (accept(r, "move_boxes", got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            oracle_move(&r->m.o, ids[k], &boxes[k]);
    } else if (got == want) {
        check_box_error(r, "move_boxes", index, want == BPX_ERR_INVALID_ARGUMENT ? -1 : axis);
    }
}

static void op_set_filters(run *r)
{
    uint8_t how = byte(&r->in);
    uint32_t count = how % (MAX_BATCH + 1);
    bool by_position = how & 0x80; // ids NULL: ids 0 .. count-1
    uint32_t ids[MAX_BATCH], categories[MAX_BATCH], masks[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++) {
        ids[k] = by_position ? k : some_id(&r->in, r->m.o.n);
        uint8_t bits = byte(&r->in);
        categories[k] = bits & 0x0F ? (uint32_t)(bits & 0x0F) : 0;
        masks[k] = bits & 0x80 ? UINT32_MAX : (uint32_t)(bits >> 4);
    }
    uint32_t index = UINT32_MAX;
    bpx_status want = BPX_OK;
    for (uint32_t k = 0; k < count && want == BPX_OK; k++)
        if (!oracle_is_live(&r->m.o, ids[k]))
            want = BPX_ERR_INVALID_ARGUMENT, index = k;
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_set_filters(r->world, by_position ? NULL : ids, categories, masks,
                                           count);
    disarm();
    if (accept(r, "set_filters", got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            oracle_set_filter(&r->m.o, ids[k], categories[k], masks[k]);
    } else if (got == want) {
        check_box_error(r, "set_filters", index, -1);
    }
}

static void op_set_groups(run *r)
{
    uint8_t how = byte(&r->in);
    uint32_t count = how % (MAX_BATCH + 1);
    bool by_position = how & 0x80;
    uint32_t ids[MAX_BATCH];
    int32_t groups[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++) {
        ids[k] = by_position ? k : some_id(&r->in, r->m.o.n);
        groups[k] = (int32_t)(byte(&r->in) % 5) - 2; // -2 .. 2
    }
    uint32_t index = UINT32_MAX;
    bpx_status want = BPX_OK;
    for (uint32_t k = 0; k < count && want == BPX_OK; k++)
        if (!oracle_is_live(&r->m.o, ids[k]))
            want = BPX_ERR_INVALID_ARGUMENT, index = k;
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_set_groups(r->world, by_position ? NULL : ids, groups, count);
    disarm();
    if (accept(r, "set_groups", got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            oracle_set_group(&r->m.o, ids[k], groups[k]);
    } else if (got == want) {
        check_box_error(r, "set_groups", index, -1);
    }
}

// Excludes or includes a batch of pairs; the world's answer for each is checked after.
static void op_exclude_pairs(run *r)
{
    uint8_t how = byte(&r->in);
    uint32_t count = how % (MAX_BATCH + 1);
    bool include = how & 0x80;
    bpx_pair pairs[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++)
        pairs[k] = (bpx_pair){some_id(&r->in, r->m.o.n), some_id(&r->in, r->m.o.n)};
    uint32_t index = UINT32_MAX;
    bpx_status want = BPX_OK;
    for (uint32_t k = 0; k < count && want == BPX_OK; k++)
        if (!oracle_is_live(&r->m.o, pairs[k].i) || !oracle_is_live(&r->m.o, pairs[k].j) ||
            pairs[k].i == pairs[k].j)
            want = BPX_ERR_INVALID_ARGUMENT, index = k;
    long before = atomic_load(&failures);
    bpx_status got = include ? bpx_world_include_pairs(r->world, pairs, count)
                             : bpx_world_exclude_pairs(r->world, pairs, count);
    disarm();
    const char *op = include ? "include_pairs" : "exclude_pairs";
    if (accept(r, op, got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            oracle_exclude(&r->m.o, pairs[k].i, pairs[k].j, !include);
    } else if (got == want) {
        check_box_error(r, op, index, -1);
    }
    for (uint32_t k = 0; k < count; k++)
        FUZZ_CHECK(bpx_world_pair_excluded(r->world, pairs[k].i, pairs[k].j) ==
                       (pairs[k].i != pairs[k].j && oracle_excluded(&r->m.o, pairs[k].i, pairs[k].j)),
                   "%s: pair (%u, %u) excluded %d, the model says otherwise", op, pairs[k].i,
                   pairs[k].j, bpx_world_pair_excluded(r->world, pairs[k].i, pairs[k].j));
}

static void op_set_user_data(run *r)
{
    uint8_t how = byte(&r->in);
    uint32_t count = how % (MAX_BATCH + 1);
    uint32_t ids[MAX_BATCH];
    uint64_t values[MAX_BATCH];
    for (uint32_t k = 0; k < count; k++) {
        ids[k] = some_id(&r->in, r->m.o.n);
        values[k] = (uint64_t)u32(&r->in) << 32 | byte(&r->in);
    }
    uint32_t index = UINT32_MAX;
    bpx_status want = BPX_OK;
    for (uint32_t k = 0; k < count && want == BPX_OK; k++)
        if (!oracle_is_live(&r->m.o, ids[k]))
            want = BPX_ERR_INVALID_ARGUMENT, index = k;
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_set_user_data(r->world, ids, values, count);
    disarm();
    if (accept(r, "set_user_data", got, want, before)) {
        for (uint32_t k = 0; k < count; k++)
            r->m.o.user_data[ids[k]] = values[k];
    } else if (got == want) {
        check_box_error(r, "set_user_data", index, -1);
    }
    for (uint32_t id = 0; id < r->m.o.n; id++) {
        uint64_t want_value = oracle_is_live(&r->m.o, id) ? r->m.o.user_data[id] : 0;
        FUZZ_CHECK(bpx_world_user_data(r->world, id) == want_value,
                   "user_data(%u) = %llu, the model %llu", id,
                   (unsigned long long)bpx_world_user_data(r->world, id),
                   (unsigned long long)want_value);
    }
}

static bpx_pair *copy_pairs_of(const bpx_pair *pairs, size_t count)
{
    bpx_pair *copy = malloc((count ? count : 1) * sizeof *copy);
    FUZZ_CHECK(copy != NULL, "out of memory");
    if (count)
        memcpy(copy, pairs, count * sizeof *copy);
    return copy;
}

// The model's own memory: its oracle and pair lists.
static void model_copy(model *dst, const model *src)
{
    oracle_model o = dst->o;
    bpx_pair *pairs = dst->pairs, *previous = dst->previous;
    *dst = *src;
    dst->o = o;
    oracle_copy(&dst->o, &src->o);
    free(pairs);
    free(previous);
    dst->pairs = copy_pairs_of(src->pairs, src->pair_count);
    dst->previous = copy_pairs_of(src->previous, src->previous_count);
}

static void saved_free(saved *s)
{
    free(s->bytes);
    free(s->m.pairs);
    free(s->m.previous);
    if (s->m.o.boxes)
        oracle_free(&s->m.o);
    memset(s, 0, sizeof *s);
}

// Takes a snapshot (asking its size first, with a buffer too small at random) and keeps it with
// the model of the moment.
static void op_snapshot(run *r)
{
    size_t size = 0, capacity = byte(&r->in) % 8;
    uint8_t small[8];
    bpx_status got = bpx_world_snapshot(r->world, small, capacity, &size);
    disarm();
    FUZZ_CHECK(got == BPX_ERR_CAPACITY && size > capacity, "snapshot into %zu bytes: %s, %zu",
               capacity, bpx_status_string(got), size);
    void *bytes = malloc(size);
    FUZZ_CHECK(bytes != NULL, "out of memory");
    size_t again = 0;
    FUZZ_CHECK(bpx_world_snapshot(r->world, bytes, size, &again) == BPX_OK && again == size,
               "snapshot of %zu bytes failed", size);
    free(r->save.bytes);
    r->save.bytes = bytes;
    r->save.size = size;
    model_copy(&r->save.m, &r->m);
}

// Restores the kept snapshot, or a copy of it cut short or with one byte changed, which must be
// refused (the world unchanged, checked by the caller).
static void op_restore(run *r)
{
    uint8_t how = byte(&r->in);
    if (!r->save.bytes)
        return;
    size_t size = r->save.size;
    uint8_t *bytes = malloc(size);
    FUZZ_CHECK(bytes != NULL, "out of memory");
    memcpy(bytes, r->save.bytes, size);
    bpx_status want = BPX_OK;
    if (how % 4 == 1) {
        size = u32(&r->in) % size;
        want = BPX_ERR_INVALID_ARGUMENT;
    } else if (how % 4 == 2) {
        bytes[u32(&r->in) % size] ^= (uint8_t)(1u << (how >> 5));
        want = BPX_ERR_INVALID_ARGUMENT;
    }
    long failures_before = atomic_load(&failures);
    bpx_status got = bpx_world_restore(r->world, bytes, size);
    disarm();
    free(bytes);
    if (accept(r, "restore", got, want, failures_before)) {
        model_copy(&r->m, &r->save.m);
        r->m.result_valid = false;
        r->m.events_valid = false;
        size_t count = 1;
        FUZZ_CHECK(bpx_world_pairs(r->world, &count) == NULL || count == 0,
                   "pairs after a restore, before a collide");
    }
}

// After a collide the library reports as done: the model's pairs, events and reusable ids.
static void model_collided(run *r, bpx_pair *want, size_t want_count)
{
    model *m = &r->m;
    if (m->track_events) {
        bpx_pair_events ev;
        FUZZ_CHECK(bpx_world_pair_events(r->world, &ev) == BPX_OK, "no events after a collide");
        const bpx_pair *before = m->have_previous ? m->previous : NULL;
        size_t before_count = m->have_previous ? m->previous_count : 0;
        bpx_pair *diff = malloc((want_count + before_count + 1) * sizeof *diff);
        FUZZ_CHECK(diff != NULL, "out of memory");
        size_t began = oracle_difference(want, want_count, before, before_count, diff);
        check_same_pairs("began", ev.began, ev.began_count, diff, began);
        size_t ended = oracle_difference(before, before_count, want, want_count, diff);
        check_same_pairs("ended", ev.ended, ev.ended_count, diff, ended);
        free(diff);
    }
    free(m->previous);
    m->previous = malloc((want_count ? want_count : 1) * sizeof *want);
    FUZZ_CHECK(m->previous != NULL, "out of memory");
    if (want_count)
        memcpy(m->previous, want, want_count * sizeof *want);
    m->previous_count = want_count;
    m->have_previous = true;
    free(m->pairs);
    m->pairs = want;
    m->pair_count = want_count;
    m->result_valid = true;
    oracle_collided(&m->o);
    bpx_cycle_stats stats = bpx_world_stats(r->world);
    FUZZ_CHECK(stats.pair_count == want_count && stats.box_count == m->o.n,
               "stats: %llu pairs of %u boxes, expected %zu of %u",
               (unsigned long long)stats.pair_count, stats.box_count, want_count, m->o.n);
    FUZZ_CHECK(bpx_world_backend(r->world) != BPX_BACKEND_AUTO, "backend auto after a cycle");
}

// A collide that failed: nothing is readable until the next one succeeds.
static void model_collide_failed(run *r, bpx_pair *want)
{
    free(want);
    r->m.result_valid = false;
    free(r->m.pairs);
    r->m.pairs = NULL;
    r->m.pair_count = 0;
    size_t count = 7;
    FUZZ_CHECK(bpx_world_pairs(r->world, &count) == NULL && count == 0,
               "pairs readable after a failed collide");
    bpx_pair_events ev;
    FUZZ_CHECK(bpx_world_pair_events(r->world, &ev) == BPX_ERR_BAD_STATE,
               "events readable after a failed collide");
}

static void op_collide(run *r)
{
    bpx_pair *want;
    size_t want_count = oracle_pairs_alloc(&r->m.o, &want);
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_collide(r->world);
    disarm();
    if (accept(r, "collide", got, BPX_OK, before)) {
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(r->world, &count);
        check_same_pairs("collide", pairs, count, want, want_count);
        model_collided(r, want, want_count);
    } else {
        model_collide_failed(r, want);
    }
}

static void op_collide_into(run *r)
{
    bpx_pair *want;
    size_t want_count = oracle_pairs_alloc(&r->m.o, &want);
    uint8_t how = byte(&r->in);
    size_t capacity = how < 0x80 ? how % 8 : how < 0xC0 ? want_count : want_count + how % 5;
    if (how >= 0x80 && how < 0xC0 && capacity > 0 && (how & 1))
        capacity--; // one short
    bpx_pair *out = malloc((capacity + 1) * sizeof *out);
    FUZZ_CHECK(out != NULL, "out of memory");
    memset(out, 0xCD, (capacity + 1) * sizeof *out);
    size_t count = 12345;
    long before = atomic_load(&failures);
    bpx_status got = bpx_world_collide_into(r->world, capacity ? out : NULL, capacity, &count);
    disarm();
    bool failed_alloc = atomic_load(&failures) > before;
    if (got == BPX_ERR_OUT_OF_MEMORY && failed_alloc) {
        model_collide_failed(r, want);
        free(out);
        return;
    }
    bpx_status expect = want_count > capacity ? BPX_ERR_CAPACITY : BPX_OK;
    FUZZ_CHECK(got == expect, "collide_into: status %s, predicted %s (%s)",
               bpx_status_string(got), bpx_status_string(expect),
               bpx_world_error(r->world)->message);
    FUZZ_CHECK(count == want_count, "collide_into: count %zu, the reference %zu", count,
               want_count);
    if (got == BPX_OK) {
        check_same_pairs("collide_into", out, count, want, want_count);
        uint8_t guard[sizeof *out];
        memset(guard, 0xCD, sizeof guard);
        FUZZ_CHECK(memcmp(out + capacity, guard, sizeof guard) == 0,
                   "collide_into wrote past its capacity");
    } else {
        uint8_t *bytes = (uint8_t *)out;
        for (size_t k = 0; k < (capacity + 1) * sizeof *out; k++)
            FUZZ_CHECK(bytes[k] == 0xCD, "collide_into wrote to out with CAPACITY");
    }
    free(out);
    // The whole set stays readable, though it did not fit.
    size_t all = 0;
    const bpx_pair *pairs = bpx_world_pairs(r->world, &all);
    check_same_pairs("pairs after collide_into", pairs, all, want, want_count);
    model_collided(r, want, want_count);
}

static void op_copy_pairs(run *r)
{
    size_t capacity = byte(&r->in) % 6;
    bpx_pair out[6];
    size_t count = 99;
    bpx_status got = bpx_world_copy_pairs(r->world, out, capacity, &count);
    disarm();
    size_t have = r->m.result_valid ? r->m.pair_count : 0;
    FUZZ_CHECK(count == have, "copy_pairs: count %zu, expected %zu", count, have);
    FUZZ_CHECK(got == (have > capacity ? BPX_ERR_CAPACITY : BPX_OK), "copy_pairs: status %s",
               bpx_status_string(got));
    if (got == BPX_OK)
        check_same_pairs("copy_pairs", out, count, r->m.pairs, have);
}

// The one-shot call on the model's live boxes, with the backend under test; it knows no
// filters, so its pairs are checked only when no filter is set.
static void op_find_pairs(run *r, bpx_backend backend)
{
    const oracle_model *m = &r->m.o;
    bpx_box *live = malloc((m->n ? m->n : 1) * sizeof *live);
    FUZZ_CHECK(live != NULL, "out of memory");
    uint32_t live_count = 0;
    for (uint32_t i = 0; i < m->n; i++)
        if (m->live[i])
            live[live_count++] = m->boxes[i];
    bool filtered = oracle_filtered(m);
    size_t capacity = byte(&r->in) % 4, count = 0;
    bpx_pair out[4];
    bpx_error err;
    long before = atomic_load(&failures);
    bpx_status got = bpx_find_pairs(live, live_count, backend, out, capacity, &count, &err);
    disarm();
    disarm();
    if (got == BPX_ERR_OUT_OF_MEMORY && atomic_load(&failures) > before) {
        free(live);
        return;
    }
    size_t want_count = 0;
    bpx_pair want[4];
    for (uint32_t i = 0; i < live_count; i++)
        for (uint32_t j = i + 1; j < live_count; j++)
            if (oracle_overlap(&live[i], &live[j])) {
                if (want_count < 4)
                    want[want_count] = (bpx_pair){i, j};
                want_count++;
            }
    free(live);
    if (filtered)
        return;
    FUZZ_CHECK(got == (want_count > capacity ? BPX_ERR_CAPACITY : BPX_OK) && count == want_count,
               "find_pairs: %s, %zu pairs, the reference %zu (%s)", bpx_status_string(got), count,
               want_count, err.message);
    if (got == BPX_OK)
        check_same_pairs("find_pairs", out, count, want, want_count);
}

static const bpx_backend cpu_backends[] = {
    BPX_BACKEND_AUTO, BPX_BACKEND_REFERENCE, BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE,
    BPX_BACKEND_SAP,  BPX_BACKEND_GRID,      BPX_BACKEND_MODEL,
};
enum { CPU_BACKEND_COUNT = sizeof cpu_backends / sizeof cpu_backends[0] };

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    static bool hooked;
    if (!hooked) {
        bpx_set_allocator(fuzz_alloc, fuzz_free, NULL);
        hooked = true;
    }
    atomic_store(&fail_at, NO_FAILURE);
    static run r; // the model is large: not on the stack
    memset(&r, 0, sizeof r);
    r.in = (input){data, size, 0, 0x9E3779B97F4A7C15ull ^ size};
    for (size_t k = 0; k < size && k < 16; k++)
        r.in.rng = r.in.rng * 31 + data[k];
    uint8_t which = byte(&r.in), options = byte(&r.in);
    bpx_backend backend = cpu_backends[which % CPU_BACKEND_COUNT];
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.track_events = options & 1;
    def.worker_count = options & 2 ? 2 : 1;
    def.spin_us = -1; // workers sleep at once: many short worlds on a shared machine
    bpx_simd simd = (bpx_simd)((options >> 2) % BPX_SIMD_COUNT);
    def.simd = bpx_simd_supported(simd) ? simd : BPX_SIMD_AUTO;
    r.m.track_events = def.track_events;
    bpx_status created = bpx_world_create(&def, &r.world);
    if (created == BPX_ERR_BACKEND_UNAVAILABLE)
        return 0;
    FUZZ_CHECK(created == BPX_OK, "create: %s", bpx_status_string(created));
    oracle_init(&r.m.o, MAX_N);
    long arm = NO_FAILURE;
    while (more(&r.in)) {
        uint8_t code = byte(&r.in);
        int op = code % OP_COUNT;
        if (op == 9) { // fail_next: one allocation of the next call fails
            arm = (long)(byte(&r.in) % 24);
            continue;
        }
        snapshot before = take_snapshot(&r);
        atomic_store(&fail_at, arm); // after the snapshot: only the call under test may fail
        arm = NO_FAILURE;
        switch (op) {
        case 0: op_set_boxes(&r); break;
        case 1: op_load_extents(&r); break;
        case 2: op_update_centres(&r); break;
        case 3: op_add_boxes(&r); break;
        case 4: op_remove_boxes(&r); break;
        case 5: op_move_boxes(&r); break;
        case 6: op_set_filters(&r); break;
        case 7: op_collide(&r); break;
        case 8: op_collide_into(&r); break;
        case 10: op_copy_pairs(&r); break;
        case 11: op_find_pairs(&r, backend); break;
        case 12: op_set_groups(&r); break;
        case 13: op_exclude_pairs(&r); break;
        case 14: op_set_user_data(&r); break;
        case 15: op_snapshot(&r); break;
        case 16: op_restore(&r); break;
        }
        bool failed_call = op != 7 && op != 8 && op != 10 && op != 11 &&
                           bpx_world_error(r.world)->status != BPX_OK;
        disarm();
        if (failed_call)
            check_unchanged(&r, &before, op_names[op]);
        free(before.pairs);
    }
    // Last, a collide on whatever the sequence left: every run ends checked.
    op_collide(&r);
    bpx_world_destroy(r.world);
    free(r.m.pairs);
    free(r.m.previous);
    oracle_free(&r.m.o);
    saved_free(&r.save);
    return 0;
}
