// The id checks of libbpx_mpi (mpi/src/ids.c) in a white box, without MPI: a rank's own ids with
// and without a repeat; the change it sends each id rank against a plain set difference; and its
// directory against a plain model over random rounds of ids added, dropped and moved between
// ranks, some of them giving an id twice. After every round the hash table must hold exactly the
// model's ids, each found where find() looks, with the rank that gives it.
#include "../src/ids.c" // find() and the table itself

#include "check.h"
#include "scenes.h"

enum { SOURCES = 5, UNIVERSE = 4000, ROUNDS = 400 };

static uint64_t id_of(size_t u)
{
    return (uint64_t)u * 0x9e3779b97f4a7c15u + 7; // distinct, spread over 64 bits
}

static bool in(const uint64_t *ids, size_t n, uint64_t id)
{
    for (size_t k = 0; k < n; k++)
        if (ids[k] == id)
            return true;
    return false;
}

static void test_own(void)
{
    check_set_context("own ids");
    bpx_mpi_world w;
    memset(&w, 0, sizeof w);
    w.rank = 2;
    w.size = 4;
    scene_rng rng;
    scene_rng_seed(&rng, 1);
    uint64_t ids[600];
    for (int round = 0; round < 60; round++) {
        size_t n = 2 + scene_rng_below(&rng, 599);
        // In no order; in order; in order but for a tenth at the end (as migrate leaves them).
        int layout = round % 3;
        for (size_t k = 0; k < n; k++) // even: apart from the tail's odd ones
            ids[k] = layout == 0 ? id_of(k * 7 + (size_t)round) : 2 * (1000 * k + (size_t)round);
        for (size_t k = n - n / 10; layout == 2 && k < n; k++)
            ids[k] = 2 * (1000000 * (uint64_t)scene_rng_below(&rng, (uint32_t)n) + k) + 1;
        size_t first = SIZE_MAX, second = SIZE_MAX;
        if (round % 2 && n >= 2) { // one id twice
            first = scene_rng_below(&rng, (uint32_t)n - 1);
            second = first + 1 + scene_rng_below(&rng, (uint32_t)(n - first - 1));
            ids[second] = ids[first];
        }
        bpx_mpi__clear_error(&w);
        bpx_status got = bpx_mpi__ids_check_own(&w, ids, n);
        if (first == SIZE_MAX) {
            CHECK_STATUS(got, BPX_OK);
            for (size_t k = 1; k < n; k++)
                CHECK(w.own_ids[k - 1] < w.own_ids[k]);
            for (size_t k = 0; k < n; k++) // each with its position
                CHECK(w.own_pos[k] < n && ids[w.own_pos[k]] == w.own_ids[k]);
        } else {
            CHECK_STATUS(got, BPX_ERR_INVALID_ARGUMENT);
            CHECK(w.error.id == ids[first] && w.error.index == second && w.error.rank == 2);
            char what[96];
            snprintf(what, sizeof what, "boxes %zu and %zu of its input", first, second);
            CHECK_MSG(strstr(w.error.message, what) != NULL, "'%s'", w.error.message);
        }
    }
    bpx_mpi__ids_free(&w);
}

// The change between two calls' ids, counted and packed per id rank.
static void test_change(void)
{
    check_set_context("change");
    enum { P = 4, N = 500 };
    bpx_mpi_world w;
    memset(&w, 0, sizeof w);
    w.size = P;
    scene_rng rng;
    scene_rng_seed(&rng, 2);
    uint64_t was[N], now[N];
    size_t n_was = 0, n_now = 0;
    for (int round = 0; round < 20; round++) {
        n_now = 0;
        for (size_t u = 0; u < N; u++)
            if (scene_rng_below(&rng, 4) != 0 || (round % 5 == 0 && u % 3 == 0))
                now[n_now++] = id_of(u);
        for (size_t k = n_now; k > 1; k--) { // shuffled: the order of an input is free
            size_t j = scene_rng_below(&rng, (uint32_t)k);
            uint64_t t = now[k - 1];
            now[k - 1] = now[j];
            now[j] = t;
        }
        CHECK_STATUS(bpx_mpi__ids_check_own(&w, now, n_now), BPX_OK);
        int plan[3 * P] = {0}, want[3 * P] = {0};
        bpx_mpi__ids_count(&w, plan);
        for (size_t k = 0; k < n_now; k++)
            if (!in(was, n_was, now[k]))
                want[3 * bpx_mpi__id_rank(now[k], P) + 1]++;
        for (size_t k = 0; k < n_was; k++)
            if (!in(now, n_now, was[k]))
                want[3 * bpx_mpi__id_rank(was[k], P) + 2]++;
        CHECK(memcmp(plan, want, sizeof plan) == 0);
        // Packed: rank r's added ids, then its dropped ones, each where the cursor said.
        uint64_t out[2 * N];
        size_t cursor[2 * P], at = 0;
        for (int r = 0; r < P; r++) {
            cursor[2 * r] = at;
            cursor[2 * r + 1] = at + (size_t)plan[3 * r + 1];
            at += (size_t)plan[3 * r + 1] + (size_t)plan[3 * r + 2];
        }
        bpx_mpi__ids_pack(&w, (unsigned char *)out, cursor);
        at = 0;
        for (int r = 0; r < P; r++)
            for (int kind = 0; kind < 2; kind++)
                for (int k = 0; k < plan[3 * r + 1 + kind]; k++, at++) {
                    uint64_t id = out[at];
                    CHECK(bpx_mpi__id_rank(id, P) == r);
                    CHECK(kind == 0 ? in(now, n_now, id) && !in(was, n_was, id)
                                    : in(was, n_was, id) && !in(now, n_now, id));
                }
        bpx_mpi__ids_commit(&w); // now's ids are the last ones
        memcpy(was, now, sizeof now);
        n_was = n_now;
    }
    bpx_mpi__ids_free(&w);
}

// The directory of one id rank against a model: owner[u] = the rank giving id u, plus one.
static void test_directory(void)
{
    check_set_context("directory");
    bpx_mpi_world w;
    memset(&w, 0, sizeof w);
    w.size = SOURCES;
    static int owner[UNIVERSE];
    static uint64_t adds[SOURCES][UNIVERSE + 1], drops[SOURCES][UNIVERSE];
    static unsigned char buffer[16 * UNIVERSE + 8];
    size_t n_add[SOURCES], n_drop[SOURCES];
    static int new_owner[UNIVERSE];
    scene_rng rng;
    scene_rng_seed(&rng, 3);
    int conflicts = 0, held_most = 0;
    for (int round = 0; round < ROUNDS; round++) {
        memset(n_add, 0, sizeof n_add);
        memset(n_drop, 0, sizeof n_drop);
        memcpy(new_owner, owner, sizeof owner);
        // Grow for a while, then churn at about the same size, with a burst now and then.
        uint32_t changes = round % 50 == 0 ? 1500 : 1 + scene_rng_below(&rng, 60);
        uint32_t add_bias = round < ROUNDS / 4 ? 3 : 1;
        for (uint32_t c = 0; c < changes; c++) {
            size_t u = scene_rng_below(&rng, UNIVERSE);
            if (new_owner[u] != owner[u])
                continue; // one change per id and round
            int from = owner[u] - 1, to = (int)scene_rng_below(&rng, SOURCES);
            uint32_t what = scene_rng_below(&rng, 2 + add_bias);
            if (owner[u] == 0) {
                adds[to][n_add[to]++] = id_of(u), new_owner[u] = to + 1;
            } else if (what == 0 || to == from) {
                drops[from][n_drop[from]++] = id_of(u), new_owner[u] = 0;
            } else { // moved: dropped by one rank, added by another in the same call
                drops[from][n_drop[from]++] = id_of(u), new_owner[u] = to + 1;
                adds[to][n_add[to]++] = id_of(u);
            }
        }
        // A quarter of the rounds give one id twice: one held and kept, or two new adds.
        bool twice = scene_rng_below(&rng, 4) == 0;
        if (twice) {
            size_t u = scene_rng_below(&rng, UNIVERSE);
            while (!(owner[u] != 0 && new_owner[u] == owner[u]) &&
                   !(owner[u] == 0 && new_owner[u] == 0))
                u = (u + 1) % UNIVERSE;
            int by = (int)scene_rng_below(&rng, SOURCES);
            if (owner[u] != 0 && by == owner[u] - 1)
                by = (by + 1) % SOURCES;
            adds[by][n_add[by]++] = id_of(u);
            if (owner[u] == 0) {
                int other = (by + 1 + (int)scene_rng_below(&rng, SOURCES - 1)) % SOURCES;
                adds[other][n_add[other]++] = id_of(u);
            }
        }
        size_t added = 0, dropped = 0;
        for (int r = 0; r < SOURCES; r++)
            added += n_add[r], dropped += n_drop[r];
        CHECK(bpx_mpi__ids_reserve(&w, added, dropped) == 0);
        for (int r = 0; r < SOURCES; r++) {
            memcpy(buffer, adds[r], n_add[r] * 8);
            memcpy(buffer + n_add[r] * 8, drops[r], n_drop[r] * 8);
            bpx_mpi__ids_receive(&w, r, buffer, n_add[r], n_drop[r]);
        }
        bpx_mpi__clear_error(&w);
        bpx_mpi__ids_check(&w);
        CHECK_MSG((w.error.status != BPX_OK) == twice, "round %d: %s", round, w.error.message);
        if (w.error.status == BPX_OK) {
            bpx_mpi__ids_commit(&w);
            memcpy(owner, new_owner, sizeof owner);
        } else {
            conflicts++;
        }
        // The table holds the model: every id where find() looks, with its rank, and no other.
        size_t held = 0;
        for (size_t u = 0; u < UNIVERSE; u++) {
            size_t s = find(&w, id_of(u));
            CHECK_MSG(w.dir_ranks[s] == owner[u], "round %d id %zu: %d, want %d", round, u,
                      w.dir_ranks[s], owner[u]);
            held += owner[u] != 0;
        }
        CHECK_EQ_U64(w.dir_count, held);
        CHECK(2 * w.dir_count <= w.dir_cap);
        held_most = held > (size_t)held_most ? (int)held : held_most;
    }
    CHECK(conflicts > ROUNDS / 8 && held_most > UNIVERSE / 2);
    bpx_mpi__ids_free(&w);
}

// The order carried from one call to the next (sort_own_from_last): over moves as
// bpx_mpi_world_migrate makes them (stayers kept in order, leavers out, arrivals at the end),
// over an unchanged input, and over inputs changed behind its back (two entries swapped, an id
// replaced, one given twice): always the sorted ids with their positions, or the repeat found.
static void test_carried_order(void)
{
    check_set_context("carried order");
    enum { N = 3000 };
    bpx_mpi_world w;
    memset(&w, 0, sizeof w);
    w.rank = 1;
    w.size = 3;
    scene_rng rng;
    scene_rng_seed(&rng, 4);
    uint64_t ids[N], next_id = 0;
    size_t n = 1000;
    for (size_t k = 0; k < n; k++)
        ids[k] = id_of(next_id++);
    w.home = check_alloc(N * sizeof *w.home);
    for (int round = 0; round < 200; round++) {
        int kind = (int)scene_rng_below(&rng, 6);
        if (kind <= 2) { // a move: each stays with probability 9/10, some arrive
            bool carry = w.last_pos_valid && !w.order_hint && n == w.last_ids_count;
            size_t stay = 0, arrive = scene_rng_below(&rng, 120);
            for (size_t i = 0; i < n; i++) {
                bool stays = scene_rng_below(&rng, 10) != 0;
                w.home[i] = stays ? (int)stay : -1;
                if (stays)
                    ids[stay++] = ids[i];
            }
            for (size_t k = 0; k < arrive && stay + k < N; k++)
                ids[stay + k] = id_of(next_id++);
            n = stay + arrive < N ? stay + arrive : N;
            w.last_pos_valid = w.order_hint = carry;
            w.hint_stay = stay;
            w.hint_count = n;
            if (kind == 1) // a second move before the call: the first one's map is gone
                w.last_pos_valid = w.order_hint = false;
        } else if (kind == 3 && n >= 2) { // two entries swapped behind its back
            size_t a = scene_rng_below(&rng, (uint32_t)n), b = scene_rng_below(&rng, (uint32_t)n);
            uint64_t t = ids[a];
            ids[a] = ids[b];
            ids[b] = t;
        } else if (kind == 4 && n >= 1) { // an id replaced by a new one
            ids[scene_rng_below(&rng, (uint32_t)n)] = id_of(next_id++);
        } // kind 5: the same input again
        size_t first = SIZE_MAX, second = SIZE_MAX;
        uint64_t kept = 0;
        if (round % 7 == 6 && n >= 2) { // one id twice, then put back
            first = scene_rng_below(&rng, (uint32_t)n - 1);
            second = first + 1 + scene_rng_below(&rng, (uint32_t)(n - first - 1));
            kept = ids[second];
            ids[second] = ids[first];
        }
        bpx_mpi__clear_error(&w);
        bpx_status got = bpx_mpi__ids_check_own(&w, ids, n);
        if (first != SIZE_MAX) {
            CHECK_STATUS(got, BPX_ERR_INVALID_ARGUMENT);
            CHECK(w.error.id == ids[first] && w.error.index == second);
            ids[second] = kept;
            continue; // a failed call commits nothing
        }
        CHECK_STATUS(got, BPX_OK);
        for (size_t k = 1; k < n; k++)
            CHECK(w.own_ids[k - 1] < w.own_ids[k]);
        for (size_t k = 0; k < n; k++)
            CHECK(w.own_pos[k] < n && ids[w.own_pos[k]] == w.own_ids[k]);
        w.added_count = w.dropped_count = 0; // this white box keeps no directory
        bpx_mpi__ids_commit(&w);
    }
    free(w.home);
    bpx_mpi__ids_free(&w);
}

int main(void)
{
    test_own();
    test_change();
    test_directory();
    test_carried_order();
    return check_finish("test_mpi_ids", 1);
}
