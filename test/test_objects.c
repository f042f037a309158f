// Objects added, removed and moved between cycles; collision filters, groups, excluded pairs and
// user data; begin/end events. Every cycle is checked against an oracle kept beside the world: a
// double loop over bpx_overlap on the live boxes, filtered by exclusions, groups, category and
// mask; events against the difference of consecutive oracle sets. Run for every available backend and 1 and 3 workers.
#include <math.h>

#include "pairs_util.h"
#include "scenes.h"

enum { max_ids = 700, cycles = 40 };

typedef struct shadow {
    bpx_box boxes[max_ids]; // inert (min +inf, max -inf) where not live
    bool live[max_ids];
    bool pending[max_ids]; // removed since the last collide: the id must not come back yet
    uint32_t category[max_ids];
    uint32_t mask[max_ids];
    int32_t group[max_ids];
    uint64_t user_data[max_ids];
    bool excluded[max_ids][max_ids]; // both halves set
    uint32_t n; // ids in use so far (high-water mark)
} shadow;

// A new id: every setting at its default, in no excluded pair.
static void shadow_reset_id(shadow *s, uint32_t id)
{
    s->category[id] = 1;
    s->mask[id] = UINT32_MAX;
    s->group[id] = 0;
    s->user_data[id] = 0;
    for (uint32_t k = 0; k < max_ids; k++)
        s->excluded[id][k] = s->excluded[k][id] = false;
}

// Box2D's rule, after the exclusions.
static bool shadow_may_pair(const shadow *s, uint32_t i, uint32_t j)
{
    if (s->excluded[i][j])
        return false;
    if (s->group[i] == s->group[j] && s->group[i] != 0)
        return s->group[i] > 0;
    return (s->category[i] & s->mask[j]) && (s->category[j] & s->mask[i]);
}

static const bpx_box inert = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};

// The pair filter of the runs: a pure function of the pair, so the pairs it lets through are
// known; each call is counted, to check it is asked once per beginning pair.
static size_t filter_calls;
static bool pair_filter_fn(uint32_t i, uint32_t j, uint64_t data_i, uint64_t data_j, void *context)
{
    (void)data_i, (void)data_j, (void)context;
    filter_calls++;
    return (i * 31u + j * 17u) % 5u != 0;
}

// The pairs that pass groups, exclusions and filters (the pair filter's candidates) into
// candidates, and those the pair filter also lets through into out.
static void expected_pairs(const shadow *s, pair_list *out, pair_list *candidates)
{
    pair_list_brute(out, s->boxes, s->n);
    size_t kept = 0;
    for (size_t k = 0; k < out->count; k++) {
        bpx_pair p = out->pairs[k];
        out->pairs[kept] = p;
        kept += shadow_may_pair(s, p.i, p.j);
    }
    out->count = kept;
    pair_list_set(candidates, out->pairs, out->count);
    kept = 0;
    for (size_t k = 0; k < out->count; k++) {
        bpx_pair p = out->pairs[k];
        out->pairs[kept] = p;
        kept += (p.i * 31u + p.j * 17u) % 5u != 0;
    }
    out->count = kept;
}

// a - b for sorted lists.
static void difference(const pair_list *a, const pair_list *b, pair_list *out)
{
    pair_list_reserve(out, a->count);
    out->count = 0;
    size_t j = 0;
    for (size_t k = 0; k < a->count; k++) {
        bpx_pair p = a->pairs[k];
        while (j < b->count && (b->pairs[j].i < p.i || (b->pairs[j].i == p.i && b->pairs[j].j < p.j)))
            j++;
        if (!(j < b->count && b->pairs[j].i == p.i && b->pairs[j].j == p.j))
            out->pairs[out->count++] = p;
    }
}

static bpx_box random_box(scene_rng *r, float world)
{
    bpx_box b;
    for (int a = 0; a < 3; a++) {
        float c = scene_rng_range(r, 0.0f, world), h = scene_rng_range(r, 0.2f, 3.0f);
        b.min[a] = c - h;
        b.max[a] = c + h;
    }
    return b;
}

static void run(bpx_backend backend, int workers, uint64_t seed)
{
    check_set_seed(seed);
    scene_rng r;
    scene_rng_seed(&r, seed);
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = workers;
    def.track_events = true;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (!w)
        return;
    static shadow s;
    memset(&s, 0, sizeof s);
    for (uint32_t id = 0; id < max_ids; id++) {
        s.boxes[id] = inert;
        shadow_reset_id(&s, id);
    }
    const float world = 40.0f;
    pair_list want = {0}, before = {0}, began = {0}, ended = {0};
    pair_list candidates = {0}, last_candidates = {0}, asked = {0};
    CHECK_STATUS(bpx_world_set_pair_filter(w, pair_filter_fn, NULL), BPX_OK);
    bpx_box batch[64];
    uint32_t ids[64];
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("backend=%s workers=%d cycle=%d", bpx_backend_name(backend), workers,
                          cycle);
        // Add a batch.
        uint32_t adds = scene_rng_below(&r, cycle == 0 ? 64 : 24);
        for (uint32_t k = 0; k < adds; k++)
            batch[k] = random_box(&r, world);
        if (s.n + adds <= max_ids && s.n + adds <= check_backend_max_boxes(backend)) {
            CHECK_STATUS(bpx_world_add_boxes(w, batch, adds, ids), BPX_OK);
            for (uint32_t k = 0; k < adds; k++) {
                uint32_t id = ids[k];
                CHECK(id < max_ids && !s.live[id] && !s.pending[id]);
                if (id >= max_ids)
                    continue;
                s.live[id] = true;
                s.boxes[id] = batch[k];
                shadow_reset_id(&s, id);
                if (id >= s.n)
                    s.n = id + 1;
            }
            CHECK(bpx_world_box_count(w) == s.n);
        }
        // Remove a batch of live ids.
        uint32_t removes = 0;
        for (uint32_t id = 0; id < s.n && removes < 16; id++)
            if (s.live[id] && scene_rng_below(&r, 6) == 0)
                ids[removes++] = id;
        CHECK_STATUS(bpx_world_remove_boxes(w, ids, removes), BPX_OK);
        for (uint32_t k = 0; k < removes; k++) {
            s.live[ids[k]] = false;
            s.pending[ids[k]] = true;
            s.boxes[ids[k]] = inert;
        }
        // Move some live boxes a little (coherent motion), in one batch.
        uint32_t moves = 0;
        for (uint32_t id = 0; id < s.n && moves < 64; id++)
            if (s.live[id] && scene_rng_below(&r, 2) == 0) {
                bpx_box b = s.boxes[id];
                float d = scene_rng_range(&r, -0.7f, 0.7f);
                int a = (int)scene_rng_below(&r, 3);
                b.min[a] += d;
                b.max[a] += d;
                ids[moves] = id;
                batch[moves++] = b;
                s.boxes[id] = b;
            }
        CHECK_STATUS(bpx_world_move_boxes(w, ids, batch, moves), BPX_OK);
        // Filters on a few live ids: two groups that ignore each other.
        if (cycle % 7 == 3) {
            uint32_t count = 0, cats[64], masks[64];
            for (uint32_t id = 0; id < s.n && count < 64; id++)
                if (s.live[id] && scene_rng_below(&r, 3) == 0) {
                    ids[count] = id;
                    cats[count] = scene_rng_below(&r, 2) ? 2u : 4u;
                    masks[count] = cats[count] == 2u ? ~4u : ~2u;
                    s.category[id] = cats[count];
                    s.mask[id] = masks[count];
                    count++;
                }
            CHECK_STATUS(bpx_world_set_filters(w, ids, cats, masks, count), BPX_OK);
        }
        // Groups: a few live ids into two never-pair groups, one always-pair group, or back to 0.
        if (cycle % 5 == 1) {
            static const int32_t choices[4] = {-1, -2, 3, 0};
            uint32_t count = 0;
            int32_t groups[64];
            for (uint32_t id = 0; id < s.n && count < 64; id++)
                if (s.live[id] && scene_rng_below(&r, 3) == 0) {
                    ids[count] = id;
                    groups[count] = choices[scene_rng_below(&r, 4)];
                    s.group[id] = groups[count++];
                }
            CHECK_STATUS(bpx_world_set_groups(w, ids, groups, count), BPX_OK);
        }
        // Excluded pairs: some of the pairs overlapping now and some at random; later a few
        // included again (and one never excluded: a no-op).
        if (cycle % 4 == 2 || cycle % 6 == 5) {
            bool include = cycle % 6 == 5;
            bpx_pair pairs[48];
            uint32_t count = 0;
            for (size_t k = 0; k < before.count && count < 24; k++)
                if (scene_rng_below(&r, 4) == 0 && s.live[before.pairs[k].i] &&
                    s.live[before.pairs[k].j])
                    pairs[count++] = before.pairs[k];
            for (int tries = 0; tries < 200 && count < 48 && s.n > 1; tries++) {
                uint32_t i = scene_rng_below(&r, s.n), j = scene_rng_below(&r, s.n);
                if (i != j && s.live[i] && s.live[j])
                    pairs[count++] = scene_rng_below(&r, 2) ? (bpx_pair){i, j} : (bpx_pair){j, i};
            }
            for (uint32_t k = 0; k < count; k++) {
                bpx_pair p = pairs[k];
                if (include && scene_rng_below(&r, 2) == 0 && !s.excluded[p.i][p.j])
                    continue;
                s.excluded[p.i][p.j] = s.excluded[p.j][p.i] = !include;
            }
            if (include)
                CHECK_STATUS(bpx_world_include_pairs(w, pairs, count), BPX_OK);
            else
                CHECK_STATUS(bpx_world_exclude_pairs(w, pairs, count), BPX_OK);
            for (uint32_t k = 0; k < count; k++)
                CHECK(bpx_world_pair_excluded(w, pairs[k].i, pairs[k].j) ==
                      s.excluded[pairs[k].i][pairs[k].j]);
        }
        // User data on some live ids; every live id reads back its own.
        uint32_t tagged = 0;
        uint64_t values[64];
        for (uint32_t id = 0; id < s.n && tagged < 64; id++)
            if (s.live[id] && scene_rng_below(&r, 5) == 0) {
                ids[tagged] = id;
                values[tagged] = s.user_data[id] = ((uint64_t)id << 40) ^ (uint64_t)cycle * 977u;
                tagged++;
            }
        CHECK_STATUS(bpx_world_set_user_data(w, ids, values, tagged), BPX_OK);
        for (uint32_t id = 0; id < s.n; id++)
            CHECK(bpx_world_user_data(w, id) == (s.live[id] ? s.user_data[id] : 0));

        filter_calls = 0;
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        size_t count = 0;
        const bpx_pair *got = bpx_world_pairs(w, &count);
        expected_pairs(&s, &want, &candidates);
        CHECK_PAIRS_EQ(want.pairs, want.count, got, count);
        difference(&candidates, &last_candidates, &asked); // the pairs that began
        CHECK_MSG(filter_calls == asked.count, "pair filter asked %zu times, %zu pairs began",
                  filter_calls, asked.count);
        pair_list_set(&last_candidates, candidates.pairs, candidates.count);

        bpx_pair_events ev;
        CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
        difference(&want, &before, &began);
        difference(&before, &want, &ended);
        CHECK_PAIRS_EQ(began.pairs, began.count, ev.began, ev.began_count);
        CHECK_PAIRS_EQ(ended.pairs, ended.count, ev.ended, ev.ended_count);
        pair_list_set(&before, want.pairs, want.count);
        memset(s.pending, 0, sizeof s.pending); // reported: the ids may come back now
    }
    pair_list_free(&want);
    pair_list_free(&before);
    pair_list_free(&began);
    pair_list_free(&ended);
    pair_list_free(&candidates);
    pair_list_free(&last_candidates);
    pair_list_free(&asked);
    bpx_world_destroy(w);
}

static void errors(void)
{
    check_set_context("object errors");
    bpx_world_def def = bpx_default_world_def();
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    bpx_box boxes[3] = {{{0, 0, 0}, {1, 1, 1}}, {{0.5f, 0, 0}, {2, 1, 1}}, {{5, 5, 5}, {6, 6, 6}}};
    uint32_t ids[3];
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 3, ids), BPX_OK);
    CHECK(ids[0] == 0 && ids[1] == 1 && ids[2] == 2);
    bpx_pair_events ev;
    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_ERR_BAD_STATE); // not tracking

    uint32_t bad[2] = {1, 7};
    CHECK_STATUS(bpx_world_remove_boxes(w, bad, 2), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->index == 1);
    uint32_t twice[2] = {2, 2};
    CHECK_STATUS(bpx_world_remove_boxes(w, twice, 2), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->index == 1);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK); // nothing was removed by the failed calls
    size_t count;
    bpx_world_pairs(w, &count);
    CHECK(count == 1);

    uint32_t one = 1;
    CHECK_STATUS(bpx_world_remove_boxes(w, &one, 1), BPX_OK);
    CHECK_STATUS(bpx_world_remove_boxes(w, &one, 1), BPX_ERR_INVALID_ARGUMENT); // already gone
    bpx_box nan_box = {{0, NAN, 0}, {1, 1, 1}};
    uint32_t id;
    CHECK_STATUS(bpx_world_add_boxes(w, &nan_box, 1, &id), BPX_ERR_NOT_FINITE);
    CHECK_STATUS(bpx_world_move_boxes(w, &one, boxes, 1), BPX_ERR_INVALID_ARGUMENT);
    // Id 1 is pending until a collide reports its pairs ended: a new box gets a fresh id.
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 1, &id), BPX_OK);
    CHECK(id == 3);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 1, &id), BPX_OK);
    CHECK(id == 1);
    uint32_t cat = 1, mask = 1;
    uint32_t far = 99;
    CHECK_STATUS(bpx_world_set_filters(w, &far, &cat, &mask, 1), BPX_ERR_INVALID_ARGUMENT);

    float minima[3] = {-1, -1, -1};
    CHECK_STATUS(bpx_world_load_extents(w, minima, 1), BPX_OK);
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 1, &id), BPX_ERR_BAD_STATE);
    bpx_world_destroy(w);
}

// Pairs of one collide (which must succeed).
static size_t pair_count(bpx_world *w)
{
    size_t count = 0;
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    bpx_world_pairs(w, &count);
    return count;
}

// set_boxes leaves the two-phase mode (issue 22: load_extents(5), set_boxes(300), removing ids
// 250..259 and update_centres wrote past the end of the 5-object arrays and shrank n to 5).
static void mode_changes(void)
{
    check_set_context("two-phase mode and set_boxes");
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (!w)
        return;
    float minima[3 * 5], centres[3 * 5];
    for (int k = 0; k < 3 * 5; k++) {
        minima[k] = -0.5f;
        centres[k] = k % 3 == 0 ? 0.75f * (float)(k / 3) : 0.0f; // neighbours overlap on x
    }
    enum { n = 300 };
    static bpx_box boxes[n], shadow_boxes[n];
    for (uint32_t i = 0; i < n; i++)
        boxes[i] = (bpx_box){{(float)i, 0, 0}, {(float)i + 1.5f, 1, 1}}; // pairs (i, i + 1)
    CHECK_STATUS(bpx_world_load_extents(w, minima, 5), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    uint32_t ids[10];
    for (uint32_t k = 0; k < 10; k++)
        ids[k] = 250 + k;
    CHECK_STATUS(bpx_world_remove_boxes(w, ids, 10), BPX_OK);
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_ERR_BAD_STATE);
    CHECK(strstr(bpx_world_error(w)->message, "load_extents") != NULL);
    CHECK_EQ_U64(bpx_world_box_count(w), n);
    memcpy(shadow_boxes, boxes, sizeof boxes);
    for (uint32_t k = 0; k < 10; k++)
        shadow_boxes[ids[k]] = inert;
    pair_list want = {0};
    pair_list_brute(&want, shadow_boxes, n);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t count = 0;
    const bpx_pair *got = bpx_world_pairs(w, &count);
    CHECK_PAIRS_EQ(want.pairs, want.count, got, count);
    uint32_t id = UINT32_MAX;
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 1, &id), BPX_OK); // general mode again
    CHECK(id >= 250 && id < 260);

    check_set_context("load_extents enters the two-phase mode again");
    CHECK_STATUS(bpx_world_load_extents(w, minima, 5), BPX_OK);
    CHECK_EQ_U64(bpx_world_box_count(w), 5);
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 1, &id), BPX_ERR_BAD_STATE);
    uint32_t two = 2;
    CHECK_STATUS(bpx_world_remove_boxes(w, &two, 1), BPX_OK);
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
    CHECK(pair_count(w) == 2); // (0, 1) and (3, 4): the removed id stays out
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
    CHECK(pair_count(w) == 2);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_ERR_BAD_STATE);
    CHECK_EQ_U64(bpx_world_box_count(w), 3);
    CHECK(pair_count(w) == 2);
    pair_list_free(&want);
    bpx_world_destroy(w);
}

// Filters across set_boxes: an id in use below both the old and the new n keeps its filter;
// ids removed, dropped or new start unfiltered. set_filters refuses a removed id.
static void filters_and_set_boxes(void)
{
    check_set_context("filters and set_boxes");
    bpx_world_def def = bpx_default_world_def();
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (!w)
        return;
    bpx_box boxes[6];
    for (int i = 0; i < 6; i++)
        boxes[i] = (bpx_box){{0, 0, 0}, {1, 1, 1}}; // every pair overlaps
    uint32_t lone = 2, none = 0; // category 2 against masks of 0: pairs with nothing
    uint32_t id0 = 0, id1 = 1, id2 = 2, id3 = 3;
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK);
    CHECK_STATUS(bpx_world_set_filters(w, &id0, &lone, &none, 1), BPX_OK);
    CHECK(pair_count(w) == 3);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK); // same objects, new boxes
    CHECK(pair_count(w) == 3);

    CHECK_STATUS(bpx_world_set_filters(w, &id3, &lone, &none, 1), BPX_OK);
    CHECK(pair_count(w) == 1);
    CHECK_STATUS(bpx_world_remove_boxes(w, &id1, 1), BPX_OK);
    CHECK_STATUS(bpx_world_set_filters(w, &id1, &lone, &none, 1), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->index == 0);
    CHECK(strstr(bpx_world_error(w)->message, "ids[0] = 1") != NULL);
    uint32_t cats[3] = {1, 1, 1}, masks[3] = {1, 1, 1};
    CHECK_STATUS(bpx_world_set_filters(w, NULL, cats, masks, 3), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->index == 1);
    CHECK(pair_count(w) == 0); // nothing changed: 0 and 3 filtered, 1 removed
    CHECK_STATUS(bpx_world_remove_boxes(w, &id3, 1), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK); // 1 and 3 back, unfiltered
    CHECK(pair_count(w) == 3);

    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 6), BPX_OK); // 4 and 5 new, unfiltered
    CHECK(pair_count(w) == 10);
    CHECK_STATUS(bpx_world_set_filters(w, &id2, &lone, &none, 1), BPX_OK);
    CHECK(pair_count(w) == 6);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 2), BPX_OK); // drops 2: it forgets its filter
    CHECK(pair_count(w) == 0);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK);
    CHECK(pair_count(w) == 3);

    float minima[3 * 4] = {-1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1};
    CHECK_STATUS(bpx_world_load_extents(w, minima, 4), BPX_OK); // the same rule
    CHECK(pair_count(w) == 3);
    bpx_world_destroy(w);
}

// Groups, excluded pairs and user data over the objects' life: errors name the position; an
// exclusion goes with the box (kept while its id is pending, gone once the id is free) and with
// set_boxes' dropped ids; a positive group pairs boxes whose masks refuse each other.
static void groups_exclusions_user_data(void)
{
    check_set_context("groups, exclusions, user data");
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    bpx_box boxes[4];
    for (int k = 0; k < 4; k++) // all four overlap: six pairs
        boxes[k] = (bpx_box){{0.1f * k, 0, 0}, {1 + 0.1f * k, 1, 1}};
    uint32_t ids[4];
    CHECK_STATUS(bpx_world_add_boxes(w, boxes, 4, ids), BPX_OK);

    bpx_pair self = {2, 2}, unknown = {1, 9};
    bpx_pair batch[2] = {{0, 1}, {3, 3}};
    CHECK_STATUS(bpx_world_exclude_pairs(w, &self, 1), BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_world_exclude_pairs(w, &unknown, 1), BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_world_exclude_pairs(w, batch, 2), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->index == 1);
    CHECK(!bpx_world_pair_excluded(w, 0, 1)); // nothing changed on error
    CHECK_STATUS(bpx_world_exclude_pairs(w, NULL, 1), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_set_groups(w, NULL, NULL, 1), BPX_ERR_NULL_ARGUMENT);
    int32_t group = -1;
    uint32_t far = 4;
    CHECK_STATUS(bpx_world_set_groups(w, &far, &group, 1), BPX_ERR_INVALID_ARGUMENT);
    uint64_t value = 42;
    CHECK_STATUS(bpx_world_set_user_data(w, &far, &value, 1), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_user_data(w, 4) == 0);

    bpx_pair ex[2] = {{1, 0}, {0, 1}}; // the same pair twice: one exclusion
    CHECK_STATUS(bpx_world_exclude_pairs(w, ex, 2), BPX_OK);
    CHECK(bpx_world_pair_excluded(w, 0, 1) && bpx_world_pair_excluded(w, 1, 0));
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 5);
    uint32_t two_three[2] = {2, 3};
    int32_t never[2] = {-1, -1}, always[2] = {5, 5};
    uint32_t lone = 1, none = 0;
    CHECK_STATUS(bpx_world_set_groups(w, two_three, never, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 4); // (2, 3) never
    CHECK_STATUS(bpx_world_set_filters(w, &two_three[0], &lone, &none, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 2); // 2 pairs with nobody; (0, 1) excluded: (0, 3), (1, 3)
    CHECK_STATUS(bpx_world_set_groups(w, two_three, always, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 3); // (2, 3) again, though 2's mask is 0
    value = 7;
    CHECK_STATUS(bpx_world_set_user_data(w, &two_three[0], &value, 1), BPX_OK);
    CHECK(bpx_world_user_data(w, 2) == 7);

    // Removing 1: its exclusion stays while the id is pending, and goes with the next collide.
    uint32_t one = 1;
    CHECK_STATUS(bpx_world_remove_boxes(w, &one, 1), BPX_OK);
    CHECK(bpx_world_pair_excluded(w, 0, 1));
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(!bpx_world_pair_excluded(w, 0, 1));
    uint32_t id;
    CHECK_STATUS(bpx_world_add_boxes(w, &boxes[1], 1, &id), BPX_OK);
    CHECK(id == 1);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 4); // the new 1 pairs with 0 and 3; 2 with 3 only (its group)

    // set_boxes keeps what ids 0 .. 2 had and drops 3's: 2 keeps its data, group and filter.
    bpx_pair ex03 = {0, 3}, ex02 = {0, 2};
    CHECK_STATUS(bpx_world_exclude_pairs(w, &ex03, 1), BPX_OK);
    CHECK_STATUS(bpx_world_exclude_pairs(w, &ex02, 1), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    CHECK(!bpx_world_pair_excluded(w, 0, 3) && bpx_world_pair_excluded(w, 0, 2));
    CHECK(bpx_world_user_data(w, 2) == 7);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(pair_count(w) == 3); // (0, 1), (0, 3), (1, 3): 2 refuses all, 3 left its group
    bpx_world_destroy(w);
}

// The pair filter's rules: a refused pair stays out while it persists, without being asked
// again; a new filter asks again; a filter that calls back into the world gets BAD_STATE.
typedef struct meddler {
    bpx_world *world;
    bpx_status status;
    int calls;
} meddler;

static bool refuse_and_meddle(uint32_t i, uint32_t j, uint64_t di, uint64_t dj, void *context)
{
    (void)i, (void)j, (void)di;
    meddler *m = context;
    m->calls++;
    bpx_box b = {{0, 0, 0}, {1, 1, 1}};
    m->status = bpx_world_set_boxes(m->world, &b, 1);
    return dj != 99; // box 1 carries 99: its pair is refused
}

// The last collide's pair count (pair_count collides itself).
static size_t pairs_now(bpx_world *w)
{
    size_t count = 0;
    bpx_world_pairs(w, &count);
    return count;
}

static void pair_filter_rules(void)
{
    check_set_context("pair filter rules");
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    bpx_box boxes[2] = {{{0, 0, 0}, {1, 1, 1}}, {{0.5f, 0, 0}, {2, 1, 1}}};
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 2), BPX_OK);
    uint32_t one = 1;
    uint64_t ninety_nine = 99;
    CHECK_STATUS(bpx_world_set_user_data(w, &one, &ninety_nine, 1), BPX_OK);
    meddler m = {w, BPX_OK, 0};
    CHECK_STATUS(bpx_world_set_pair_filter(w, refuse_and_meddle, &m), BPX_OK);
    for (int cycle = 0; cycle < 3; cycle++) {
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        CHECK(pairs_now(w) == 0);
    }
    CHECK(m.calls == 1 && m.status == BPX_ERR_BAD_STATE);
    CHECK(bpx_world_box_count(w) == 2); // the meddling did nothing
    bpx_box apart = {{5, 5, 5}, {6, 6, 6}};
    CHECK_STATUS(bpx_world_move_boxes(w, &one, &apart, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_move_boxes(w, &one, &boxes[1], 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK); // began again: asked again
    CHECK(m.calls == 2 && pairs_now(w) == 0);
    ninety_nine = 1;
    CHECK_STATUS(bpx_world_set_user_data(w, &one, &ninety_nine, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK); // persists: not asked, still refused
    CHECK(m.calls == 2 && pairs_now(w) == 0);
    CHECK_STATUS(bpx_world_set_pair_filter(w, refuse_and_meddle, &m), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK); // a new filter asks again
    CHECK(m.calls == 3 && pairs_now(w) == 1);
    bpx_pair_events ev;
    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
    CHECK_MSG(ev.began_count == 1 && ev.ended_count == 0, "began %zu ended %zu", ev.began_count, ev.ended_count);
    CHECK_STATUS(bpx_world_set_pair_filter(w, NULL, NULL), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(m.calls == 3 && pairs_now(w) == 1);
    bpx_world_destroy(w);
}

// Contact margins against an oracle of their rule, for every backend: a pair begins when its
// gap (the largest axis distance between the boxes, in double) is <= begin, and a pair of the
// last collide goes on while its gap is <= end; events follow. Then the flicker they stop, and
// definitions refused.
static double oracle_gap(const bpx_box *a, const bpx_box *b)
{
    double g = -INFINITY;
    for (int k = 0; k < 3; k++) {
        double x = (double)b->min[k] - (double)a->max[k], y = (double)a->min[k] - (double)b->max[k];
        double apart = x > y ? x : y;
        g = apart > g ? apart : g;
    }
    return g;
}

static void margins(bpx_backend backend, int workers)
{
    check_set_context("margins backend=%s workers=%d", bpx_backend_name(backend), workers);
    enum { n = 150 };
    const float begin = 0.25f, end = 0.75f;
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = workers;
    def.track_events = true;
    def.begin_margin = begin;
    def.end_margin = end;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (!w)
        return;
    static bpx_box boxes[n];
    static bool held[n][n];
    memset(held, 0, sizeof held);
    scene_rng r;
    scene_rng_seed(&r, 31 + (uint64_t)backend);
    for (uint32_t i = 0; i < n; i++)
        boxes[i] = random_box(&r, 14.0f);
    pair_list want = {0};
    for (int cycle = 0; cycle < 25; cycle++) {
        for (uint32_t i = 0; i < n; i++) { // jitter: pairs come near, touch, part
            int a = (int)scene_rng_below(&r, 3);
            float d = scene_rng_range(&r, -0.4f, 0.4f);
            boxes[i].min[a] += d;
            boxes[i].max[a] += d;
        }
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        pair_list_reserve(&want, (size_t)n * n / 2);
        want.count = 0;
        size_t began = 0, ended = 0;
        for (uint32_t i = 0; i < n; i++)
            for (uint32_t j = i + 1; j < n; j++) {
                double g = oracle_gap(&boxes[i], &boxes[j]);
                bool now = g <= begin || (g <= end && held[i][j]);
                began += now && !held[i][j];
                ended += !now && held[i][j];
                held[i][j] = now;
                if (now)
                    want.pairs[want.count++] = (bpx_pair){i, j};
            }
        size_t count = 0;
        const bpx_pair *got = bpx_world_pairs(w, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, got, count);
        bpx_pair_events ev;
        CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
        CHECK(ev.began_count == began && ev.ended_count == ended);
    }
    pair_list_free(&want);
    bpx_world_destroy(w);
}

static void margins_rules(void)
{
    check_set_context("margin rules");
    // Two boxes that touch and part by 0.1 every cycle: with no margin, a begin and an end each
    // time; with end_margin 0.5, one begin.
    for (int with = 0; with < 2; with++) {
        bpx_world_def def = bpx_default_world_def();
        def.track_events = true;
        def.end_margin = with ? 0.5f : 0.0f;
        bpx_world *w;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
        size_t events = 0;
        for (int cycle = 0; cycle < 10; cycle++) {
            float x = cycle % 2 ? 1.1f : 1.0f;
            bpx_box boxes[2] = {{{0, 0, 0}, {1, 1, 1}}, {{x, 0, 0}, {x + 1, 1, 1}}};
            CHECK_STATUS(bpx_world_set_boxes(w, boxes, 2), BPX_OK);
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            bpx_pair_events ev;
            CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
            events += ev.began_count + ev.ended_count;
        }
        CHECK_MSG(events == (with ? 1u : 10u), "margin %d: %zu events", with, events);
        bpx_world_destroy(w);
    }
    const float bad[][2] = {{-1.0f, 0.0f}, {NAN, 0.0f}, {0.5f, 0.25f}, {INFINITY, 0.0f},
                            {0.0f, NAN}, {0.0f, -0.5f}};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        bpx_world_def def = bpx_default_world_def();
        def.begin_margin = bad[k][0];
        def.end_margin = bad[k][1];
        bpx_world *w = (bpx_world *)&def;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_INVALID_ARGUMENT);
        CHECK(w == NULL);
    }
}

int main(void)
{
    errors();
    mode_changes();
    filters_and_set_boxes();
    groups_exclusions_user_data();
    pair_filter_rules();
    margins_rules();
    int ran = 0;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        if (!bpx_backend_query((bpx_backend)b).available)
            continue;
        for (int workers = 1; workers <= 3; workers += 2) {
            run((bpx_backend)b, workers, 1000 + (uint64_t)b);
            margins((bpx_backend)b, workers);
            ran++;
        }
    }
    return check_finish("test_objects", ran);
}
