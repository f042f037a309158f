// bpx_mpi against the single-process world: run under mpiexec with 1, 2, 3, 4 and 8 ranks.
// Every rank builds the same global scene and the same reference world; each passes the boxes
// of the objects it owns (by several ownership rules, moving between cycles), and the gathered
// pairs and events must be exactly the reference's, mapped to global ids.
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <math.h>

#include <bpx/mpi.h>

#include "check.h"
#include "scenes.h"

static int rank, ranks;

typedef enum ownership {
    OWN_ROUND_ROBIN, // object k on rank k mod ranks
    OWN_RANDOM,      // a random rank per object per cycle
    OWN_RANK0,       // everything on rank 0, the others pass nothing
    OWN_HOME,        // where bpx_mpi_world_home_ranks says (the cheap way)
    OWN_NOT_LAST,    // round robin over all ranks but the last, which passes nothing
    OWN_COUNT
} ownership;
static const char *ownership_names[] = {"round_robin", "random", "rank0", "home", "not_last"};

// Distinct 64-bit ids in scrambled order (splitmix64's finaliser is a bijection).
static uint64_t object_id(size_t k)
{
    uint64_t x = (uint64_t)k + 0x9e3779b97f4a7c15u;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9u;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebu;
    return x ^ (x >> 31);
}

static int compare_pairs(const void *p, const void *q)
{
    const bpx_mpi_pair *x = p, *y = q;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    return (x->b > y->b) - (x->b < y->b);
}

// Local pairs (i, j) as global pairs, sorted.
static bpx_mpi_pair *to_global(const bpx_pair *local, size_t count)
{
    bpx_mpi_pair *out = check_alloc(count * sizeof *out);
    for (size_t k = 0; k < count; k++) {
        uint64_t a = object_id(local[k].i), b = object_id(local[k].j);
        out[k] = a < b ? (bpx_mpi_pair){a, b} : (bpx_mpi_pair){b, a};
    }
    qsort(out, count, sizeof *out, compare_pairs);
    return out;
}

static bool same_pairs(const bpx_mpi_pair *x, size_t nx, const bpx_mpi_pair *y, size_t ny)
{
    return nx == ny && (nx == 0 || memcmp(x, y, nx * sizeof *x) == 0);
}

// Every rank's list to root, sorted (for events, which the library does not gather).
static bpx_mpi_pair *gather_list(const bpx_mpi_pair *mine, size_t count, size_t *total)
{
    int n = (int)count, *counts = check_alloc(sizeof(int) * (size_t)ranks),
        *displs = check_alloc(sizeof(int) * (size_t)ranks);
    MPI_Allgather(&n, 1, MPI_INT, counts, 1, MPI_INT, MPI_COMM_WORLD);
    size_t sum = 0;
    for (int r = 0; r < ranks; r++) {
        displs[r] = (int)sum * 16;
        sum += (size_t)counts[r];
        counts[r] *= 16;
    }
    bpx_mpi_pair *all = check_alloc(sum * sizeof *all);
    MPI_Allgatherv(mine, n * 16, MPI_BYTE, all, counts, displs, MPI_BYTE, MPI_COMM_WORLD);
    qsort(all, sum, sizeof *all, compare_pairs);
    free(counts);
    free(displs);
    *total = sum;
    return all;
}

// The scene, its filters and the reference world, the same on every rank.
typedef struct scene {
    bpx_box *boxes;
    bpx_mpi_filter *filters; // NULL: none
    size_t n;
    bpx_world *reference;
} scene;

static void scene_reference(scene *s, bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.track_events = events;
    def.backend = BPX_BACKEND_AUTO;
    CHECK_STATUS(bpx_world_create(&def, &s->reference), BPX_OK);
}

typedef struct run {
    bpx_mpi_world *world;
    uint64_t *ids;
    bpx_box *boxes;
    bpx_mpi_filter *filters;
    int *home;
    int *owner;          // per object: the rank that passed it this cycle
    bpx_mpi_pair *index; // (id, object) sorted by id, to find an object by its id
    size_t index_count;
    scene_rng rng;
    // This object goes to rank moved_to whatever the ownership (SIZE_MAX: none).
    size_t moved_object;
    int moved_to;
} run;

static size_t object_of(const run *r, uint64_t id)
{
    size_t lo = 0, hi = r->index_count;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (r->index[mid].a < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < r->index_count && r->index[lo].a == id ? (size_t)r->index[lo].b : SIZE_MAX;
}

// This rank's share of the scene this cycle.
static size_t take_share(run *r, const scene *s, ownership how)
{
    size_t count = 0;
    if (how == OWN_HOME)
        CHECK_STATUS(bpx_mpi_world_home_ranks(r->world, s->boxes, s->n, r->home), BPX_OK);
    for (size_t k = 0; k < s->n; k++) {
        int owner = 0;
        switch (how) {
        case OWN_ROUND_ROBIN:
            owner = (int)(k % (size_t)ranks);
            break;
        case OWN_RANDOM:
            owner = (int)scene_rng_below(&r->rng, (uint32_t)ranks);
            break;
        case OWN_RANK0:
            owner = 0;
            break;
        case OWN_HOME:
            owner = r->home[k];
            break;
        default:
            owner = ranks == 1 ? 0 : (int)(k % (size_t)(ranks - 1));
            break;
        }
        if (k == r->moved_object)
            owner = r->moved_to;
        r->owner[k] = owner;
        if (owner != rank)
            continue;
        r->ids[count] = object_id(k);
        r->boxes[count] = s->boxes[k];
        if (s->filters)
            r->filters[count] = s->filters[k];
        count++;
    }
    return count;
}

// After a successful call the error reads as none, as bpx_mpi_error documents: status OK, rank
// -1, id 0, index SIZE_MAX, axis -1, no message.
static void check_no_error(const bpx_mpi_error *e, const char *call)
{
    CHECK_MSG(e->status == BPX_OK && e->rank == -1 && e->id == 0 && e->index == SIZE_MAX &&
                  e->axis == -1 && e->message[0] == '\0',
              "after %s: status %s rank %d id %llu index %zu axis %d '%.100s'", call,
              check_status_name(e->status), e->rank, (unsigned long long)e->id, e->index, e->axis,
              e->message);
}

// One cycle on both sides, then every check of the result.
static void cycle(run *r, scene *s, ownership how, int root)
{
    size_t count = take_share(r, s, how);
    char context[sizeof check_context];
    memcpy(context, check_context, sizeof context);
    check_set_context("%.200s own=%s", context, ownership_names[how]);
    bpx_status status =
        bpx_mpi_world_collide(r->world, r->ids, r->boxes, s->filters ? r->filters : NULL, count);
    CHECK_MSG(status == BPX_OK, "%s: %s", check_status_name(status),
              bpx_mpi_world_error(r->world)->message);
    check_no_error(bpx_mpi_world_error(r->world), "collide");
    bpx_world *ref = s->reference;
    CHECK_STATUS(bpx_world_set_boxes(ref, s->boxes, (uint32_t)s->n), BPX_OK);
    { // the reference gets the defaults when the scene has no filters (this cycle)
        uint32_t *cat = check_alloc(s->n * 4), *mask = check_alloc(s->n * 4);
        for (size_t k = 0; k < s->n; k++)
            cat[k] = s->filters ? s->filters[k].category : 1,
            mask[k] = s->filters ? s->filters[k].mask : 0xFFFFFFFFu;
        CHECK_STATUS(bpx_world_set_filters(ref, NULL, cat, mask, (uint32_t)s->n), BPX_OK);
        free(cat);
        free(mask);
    }
    CHECK_STATUS(bpx_world_collide(ref), BPX_OK);
    size_t want_count;
    const bpx_pair *want_local = bpx_world_pairs(ref, &want_count);
    bpx_mpi_pair *want = to_global(want_local, want_count);

    // This rank's share: sorted, each pair's corner in its region.
    size_t mine_count;
    const bpx_mpi_pair *mine = bpx_mpi_world_pairs(r->world, &mine_count);
    float lo[3], hi[3];
    CHECK_STATUS(bpx_mpi_world_region(r->world, rank, lo, hi), BPX_OK);
    for (size_t k = 1; k < mine_count; k++)
        CHECK(compare_pairs(&mine[k - 1], &mine[k]) < 0);
    // Each pair names the ranks that passed its objects.
    size_t ranks_count;
    const bpx_mpi_pair_ranks *from = bpx_mpi_world_pair_ranks(r->world, &ranks_count);
    CHECK_EQ_U64(ranks_count, mine_count);
    for (size_t k = 0; k < mine_count && from; k++) {
        size_t a = object_of(r, mine[k].a), b = object_of(r, mine[k].b);
        CHECK(a < s->n && b < s->n && from[k].a == r->owner[a] && from[k].b == r->owner[b]);
    }
    bpx_mpi_stats st = bpx_mpi_world_stats(r->world);
    CHECK_EQ_U64(st.total_pair_count, want_count);
    CHECK_EQ_U64(st.pair_count, mine_count);
    CHECK_EQ_U64(st.own_count, count);
    // Payload bytes count what reached other ranks only, not what a rank sends itself (events of
    // pairs whose event rank is its own): the ranks' sums agree, a rank sent bytes exactly when
    // it sent some other rank a message, and a lone rank sends nothing.
    uint64_t io[2] = {st.bytes_sent, st.bytes_received}, io_sum[2];
    MPI_Allreduce(io, io_sum, 2, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    CHECK_EQ_U64(io_sum[0], io_sum[1]);
    CHECK_MSG((st.messages_sent == 0) == (st.bytes_sent == 0), "%llu bytes in %llu messages",
              (unsigned long long)st.bytes_sent, (unsigned long long)st.messages_sent);
    if (ranks == 1)
        CHECK(st.bytes_sent == 0 && st.bytes_received == 0 && st.messages_sent == 0);

    // The whole set on root.
    const bpx_mpi_pair *all = NULL;
    size_t all_count = 0;
    CHECK_STATUS(bpx_mpi_world_gather_pairs(r->world, root, &all, &all_count), BPX_OK);
    check_no_error(bpx_mpi_world_error(r->world), "gather");
    if (rank == root)
        CHECK_MSG(same_pairs(all, all_count, want, want_count), "gathered %zu pairs, want %zu",
                  all_count, want_count);
    else
        CHECK(all == NULL && all_count == 0);

    // Events: each on its event rank, together the reference's.
    bpx_pair_events want_events;
    if (bpx_world_pair_events(ref, &want_events) == BPX_OK) {
        bpx_mpi_pair_events ev;
        CHECK_STATUS(bpx_mpi_world_pair_events(r->world, &ev), BPX_OK);
        for (size_t k = 0; k < ev.began_count; k++)
            CHECK(bpx_mpi_event_rank(ev.began[k].a, ev.began[k].b, ranks) == rank);
        for (size_t k = 0; k < ev.ended_count; k++)
            CHECK(bpx_mpi_event_rank(ev.ended[k].a, ev.ended[k].b, ranks) == rank);
        size_t nb, ne;
        bpx_mpi_pair *began = gather_list(ev.began, ev.began_count, &nb);
        bpx_mpi_pair *ended = gather_list(ev.ended, ev.ended_count, &ne);
        bpx_mpi_pair *wb = to_global(want_events.began, want_events.began_count);
        bpx_mpi_pair *we = to_global(want_events.ended, want_events.ended_count);
        CHECK_MSG(same_pairs(began, nb, wb, want_events.began_count), "began %zu, want %zu", nb,
                  want_events.began_count);
        CHECK_MSG(same_pairs(ended, ne, we, want_events.ended_count), "ended %zu, want %zu", ne,
                  want_events.ended_count);
        free(began), free(ended), free(wb), free(we);
    }
    free(want);
    memcpy(check_context, context, sizeof context);
}

static run run_open(const scene *s, bpx_mpi_world_def def, uint64_t seed)
{
    run r;
    memset(&r, 0, sizeof r);
    bpx_mpi_error err;
    CHECK_STATUS(bpx_mpi_world_create(MPI_COMM_WORLD, &def, &r.world, &err), BPX_OK);
    check_no_error(&err, "create");
    check_no_error(bpx_mpi_world_error(r.world), "create");
    size_t cap = s->n + 64;
    r.ids = check_alloc(cap * sizeof *r.ids);
    r.boxes = check_alloc(cap * sizeof *r.boxes);
    r.filters = check_alloc(cap * sizeof *r.filters);
    r.home = check_alloc(cap * sizeof *r.home);
    r.owner = check_alloc(cap * sizeof *r.owner);
    r.index = check_alloc(cap * sizeof *r.index);
    r.index_count = cap;
    for (size_t k = 0; k < cap; k++)
        r.index[k] = (bpx_mpi_pair){object_id(k), k};
    qsort(r.index, cap, sizeof *r.index, compare_pairs);
    scene_rng_seed(&r.rng, seed);
    r.moved_object = SIZE_MAX;
    return r;
}

static void run_close(run *r)
{
    bpx_mpi_world_destroy(r->world);
    free(r->ids), free(r->boxes), free(r->filters), free(r->home), free(r->owner), free(r->index);
}

static scene scene_make(size_t n, bool filters, bool events, uint64_t seed)
{
    scene s = {check_alloc((n + 64) * sizeof(bpx_box)), NULL, n, NULL};
    if (filters) {
        scene_rng rng;
        scene_rng_seed(&rng, seed ^ 0xf11e);
        s.filters = check_alloc((n + 64) * sizeof *s.filters);
        for (size_t k = 0; k < n + 64; k++) // a few groups that ignore each other
            s.filters[k] = (bpx_mpi_filter){1u << scene_rng_below(&rng, 3),
                                            scene_rng_below(&rng, 4) ? 0xFFFFFFFFu : 0x5u};
    }
    scene_reference(&s, events);
    return s;
}

static void scene_free(scene *s)
{
    bpx_world_destroy(s->reference);
    free(s->boxes);
    free(s->filters);
}

// Every scene kind of the pair tests, each owned four ways in turn, with and without filters.
static void test_scene_kinds(void)
{
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        size_t n = kind == SCENE_ALL_OVERLAP || kind == SCENE_DENSE ? 90 : 400;
        for (int filtered = 0; filtered < 2; filtered++) {
            check_set_context("kind=%s filters=%d ranks=%d", scene_kind_name(kind), filtered,
                              ranks);
            scene s = scene_make(n, filtered, true, (uint64_t)kind);
            CHECK(scene_generate(kind, (uint32_t)n, 1000 + (uint64_t)kind, s.boxes) == 0);
            bpx_mpi_world_def def = bpx_mpi_default_world_def();
            def.track_events = true;
            run r = run_open(&s, def, (uint64_t)kind);
            for (int c = 0; c < OWN_COUNT; c++)
                cycle(&r, &s, (ownership)c, c % ranks);
            run_close(&r);
            scene_free(&s);
        }
    }
}

// Moving boxes over many cycles, workers 1 and 2 on each rank, events on.
static void test_moving(int workers, bool heavy)
{
    size_t n = 3000;
    check_set_context("moving heavy=%d workers=%d ranks=%d", heavy, workers, ranks);
    scene s = scene_make(n, false, true, 7);
    if (heavy)
        scene_heavy_tailed_density((uint32_t)n, 7, s.boxes);
    else
        scene_uniform_density((uint32_t)n, 1.0f, 7, s.boxes);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    def.local.worker_count = workers;
    run r = run_open(&s, def, 7);
    scene_rng motion;
    scene_rng_seed(&motion, 99);
    for (int c = 0; c < 14; c++) {
        ownership how = c == 0 ? OWN_ROUND_ROBIN : heavy && c % 3 == 0 ? OWN_RANDOM : OWN_HOME;
        cycle(&r, &s, how, 0);
        scene_move(s.boxes, (uint32_t)n, 0.4f, &motion);
    }
    bpx_mpi_world_rebalance(r.world); // forced: the regions change under the events
    uint64_t before = bpx_mpi_world_stats(r.world).decomposition_count;
    cycle(&r, &s, OWN_HOME, 0);
    CHECK_EQ_U64(bpx_mpi_world_stats(r.world).decomposition_count, before + 1);
    run_close(&r);
    scene_free(&s);
}

// All boxes crowd into one rank's region, with rebalancing off; then a rebalance.
static void test_clustered(void)
{
    size_t n = 1500;
    check_set_context("clustered ranks=%d", ranks);
    scene s = scene_make(n, false, true, 11);
    scene_uniform_density((uint32_t)n, 1.0f, 11, s.boxes);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    def.rebalance_threshold = 1e9;
    run r = run_open(&s, def, 11);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    // Shrink everything towards the centre of box 0, well inside one region.
    float c[3];
    for (int k = 0; k < 3; k++)
        c[k] = 0.5f * s.boxes[0].min[k] + 0.5f * s.boxes[0].max[k];
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            s.boxes[i].min[k] = c[k] + (s.boxes[i].min[k] - c[k]) * 0.001f;
            s.boxes[i].max[k] = c[k] + (s.boxes[i].max[k] - c[k]) * 0.001f;
            if (s.boxes[i].min[k] > s.boxes[i].max[k])
                s.boxes[i].max[k] = s.boxes[i].min[k];
        }
    for (int cyc = 0; cyc < 3; cyc++)
        cycle(&r, &s, cyc == 1 ? OWN_RANDOM : OWN_HOME, cyc % ranks);
    if (ranks > 1)
        CHECK(bpx_mpi_world_stats(r.world).imbalance > 1.5);
    bpx_mpi_world_rebalance(r.world);
    cycle(&r, &s, OWN_HOME, 0);
    cycle(&r, &s, OWN_HOME, 0);
    run_close(&r);
    scene_free(&s);
}

// A box over every region (up to +-FLT_MAX), and boxes lying exactly on the cuts.
static void test_huge_and_borders(void)
{
    size_t n = 1200;
    check_set_context("huge and borders ranks=%d", ranks);
    scene s = scene_make(n + 40, true, true, 13);
    scene_uniform_density((uint32_t)n, 1.0f, 13, s.boxes);
    s.n = n;
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    run r = run_open(&s, def, 13);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    s.boxes[n] = (bpx_box){{-FLT_MAX, -FLT_MAX, -FLT_MAX}, {FLT_MAX, FLT_MAX, FLT_MAX}};
    s.boxes[n + 1] = (bpx_box){{-1e30f, -1e30f, -1e30f}, {1e30f, 1e30f, 1e30f}};
    size_t m = n + 2;
    // Pairs of boxes that touch on each finite cut, and points on it.
    for (int q = 0; q < ranks && m + 4 <= n + 40; q++) {
        float lo[3], hi[3];
        CHECK_STATUS(bpx_mpi_world_region(r.world, q, lo, hi), BPX_OK);
        for (int a = 0; a < 3 && m + 4 <= n + 40; a++) {
            if (!isfinite(lo[a]))
                continue;
            float v = lo[a];
            bpx_box left = s.boxes[q % n], right;
            left.max[a] = v;
            left.min[a] = v - 1.0f;
            right = left;
            right.min[a] = v;
            right.max[a] = v + 0.5f;
            bpx_box point = left, flat = left;
            point.min[a] = point.max[a] = v;
            flat.min[a] = flat.max[a] = v;
            for (int k = 0; k < 3; k++)
                if (k != a)
                    point.max[k] = point.min[k];
            s.boxes[m++] = left, s.boxes[m++] = right, s.boxes[m++] = point, s.boxes[m++] = flat;
        }
    }
    s.n = m;
    for (int c = 0; c < OWN_COUNT; c++)
        cycle(&r, &s, (ownership)c, (c + 1) % ranks);
    run_close(&r);
    scene_free(&s);
}

// Empty ranks and an empty world.
static void test_empty(void)
{
    check_set_context("empty ranks=%d", ranks);
    scene s = scene_make(0, false, false, 17);
    run r = run_open(&s, bpx_mpi_default_world_def(), 17);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    cycle(&r, &s, OWN_RANK0, 0);
    run_close(&r);
    scene_free(&s);
}

// The same message on every rank, naming the rank that failed.
static void check_collective(bpx_mpi_world *w, bpx_status got, bpx_status want, int culprit,
                             uint64_t id)
{
    CHECK_MSG(got == want, "got %s, want %s", check_status_name(got), check_status_name(want));
    const bpx_mpi_error *e = bpx_mpi_world_error(w);
    char root_message[sizeof e->message];
    memcpy(root_message, e->message, sizeof root_message);
    MPI_Bcast(root_message, (int)sizeof root_message, MPI_CHAR, 0, MPI_COMM_WORLD);
    CHECK_MSG(strcmp(root_message, e->message) == 0, "rank %d says '%.100s'", rank, e->message);
    CHECK(e->status == want && e->rank == culprit);
    char who[32], what[32];
    snprintf(who, sizeof who, "rank %d", culprit);
    snprintf(what, sizeof what, "%llu", (unsigned long long)id);
    CHECK_MSG(strstr(e->message, who) != NULL, "'%.200s' lacks the rank", e->message);
    if (id)
        CHECK_MSG(strstr(e->message, what) != NULL, "'%.200s' lacks the id", e->message);
}

static void test_errors(void)
{
    check_set_context("errors ranks=%d", ranks);
    size_t n = 200;
    scene s = scene_make(n, false, true, 19);
    scene_uniform_density((uint32_t)n, 1.0f, 19, s.boxes);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    run r = run_open(&s, def, 19);
    float lo[3], hi[3];
    CHECK_STATUS(bpx_mpi_world_region(r.world, 0, lo, hi), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_mpi_world_home_ranks(r.world, s.boxes, 1, r.home), BPX_ERR_BAD_STATE);
    const bpx_mpi_pair *g;
    size_t gc;
    check_collective(r.world, bpx_mpi_world_gather_pairs(r.world, 0, &g, &gc), BPX_ERR_BAD_STATE, 0,
                     0);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    size_t before;
    bpx_mpi_world_pairs(r.world, &before);
    int last = ranks - 1;

    // Input errors on the last rank only: every rank fails alike, the world is unchanged.
    size_t count = take_share(&r, &s, OWN_ROUND_ROBIN);
    uint64_t bad_id = count > 0 ? r.ids[0] : 0; // the last rank's first box goes bad
    MPI_Bcast(&bad_id, 1, MPI_UINT64_T, last, MPI_COMM_WORLD);
    for (int kind = 0; kind < 3; kind++) {
        bpx_box keep = r.boxes[0];
        const uint64_t *ids = r.ids;
        bpx_status want = BPX_ERR_NOT_FINITE;
        if (rank == last) {
            if (kind == 0)
                r.boxes[0].max[1] = NAN;
            else if (kind == 1)
                r.boxes[0].min[2] = r.boxes[0].max[2] + 1.0f;
            else
                ids = NULL;
        }
        if (kind == 1)
            want = BPX_ERR_MIN_GREATER_THAN_MAX;
        if (kind == 2)
            want = BPX_ERR_NULL_ARGUMENT;
        bpx_status got = bpx_mpi_world_collide(r.world, ids, r.boxes, NULL, count);
        check_collective(r.world, got, want, last, kind < 2 ? bad_id : 0);
        if (rank == last && kind < 2)
            CHECK(bpx_mpi_world_error(r.world)->index == 0);
        r.boxes[0] = keep;
        size_t after;
        CHECK(bpx_mpi_world_pairs(r.world, &after) != NULL && after == before);
    }

    // A duplicate id, given by rank 0 (round robin) and again by the last rank. Found after the
    // exchange: the cycle fails everywhere, pairs read as none. On one rank it is an id twice in
    // one input: an input error, the world as it was.
    bool late = ranks > 1;
    count = take_share(&r, &s, OWN_ROUND_ROBIN);
    uint64_t twice = object_id(0); // on rank 0 (round robin); the last rank passes it again
    if (rank == last) {
        r.ids[count] = twice;
        r.boxes[count] = s.boxes[0];
        count++;
    }
    bpx_status got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
    CHECK_MSG(got == BPX_ERR_INVALID_ARGUMENT, "got %s", check_status_name(got));
    const bpx_mpi_error *e = bpx_mpi_world_error(r.world);
    char what[48];
    snprintf(what, sizeof what, "id %llu is given twice", (unsigned long long)twice);
    CHECK_MSG(strstr(e->message, what) != NULL, "'%s'", e->message);
    size_t left;
    const bpx_mpi_pair *pairs_left = bpx_mpi_world_pairs(r.world, &left);
    CHECK(late ? pairs_left == NULL && left == 0 : pairs_left != NULL && left == before);
    bpx_mpi_pair_events ev;
    CHECK_STATUS(bpx_mpi_world_pair_events(r.world, &ev), late ? BPX_ERR_BAD_STATE : BPX_OK);
    if (late)
        check_collective(r.world, bpx_mpi_world_gather_pairs(r.world, 0, &g, &gc),
                         BPX_ERR_BAD_STATE, 0, 0);
    // The next good cycle reports events against the last successful one (cycle checks it).
    scene_rng motion;
    scene_rng_seed(&motion, 5);
    scene_move(s.boxes, (uint32_t)n, 0.5f, &motion);
    cycle(&r, &s, OWN_HOME, 0);
    check_collective(r.world, bpx_mpi_world_gather_pairs(r.world, ranks, &g, &gc),
                     BPX_ERR_INVALID_ARGUMENT, 0, 0);
    run_close(&r);
    scene_free(&s);

    // A bad definition on one rank: creation fails on all.
    bpx_mpi_world_def bad = bpx_mpi_default_world_def();
    if (rank == last)
        bad.rebalance_threshold = 0.5;
    bpx_mpi_world *w = (bpx_mpi_world *)1;
    bpx_mpi_error err;
    CHECK_STATUS(bpx_mpi_world_create(MPI_COMM_WORLD, &bad, &w, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(w == NULL && err.rank == last && strstr(err.message, "rebalance_threshold"));
}

// A point in rank q's region, far from every box of the scenes (rank 0's region reaches -inf on
// every axis, the last rank's +inf: they are the outermost leaves of the bisection).
static bpx_box far_point(bpx_mpi_world *w, int q, float at)
{
    float lo[3], hi[3];
    CHECK_STATUS(bpx_mpi_world_region(w, q, lo, hi), BPX_OK);
    bpx_box b = {{at, at, at}, {at, at, at}};
    for (int k = 0; k < 3; k++)
        CHECK_MSG(lo[k] <= at && at < hi[k], "%g not in [%g, %g) of rank %d", at, lo[k], hi[k], q);
    return b;
}

// A failure of the cycle on every rank alike: the status, the same message everywhere, the id and
// the ranks that gave it.
static void check_duplicate(bpx_mpi_world *w, bpx_status got, uint64_t id, int a, int b)
{
    CHECK_MSG(got == BPX_ERR_INVALID_ARGUMENT, "got %s", check_status_name(got));
    const bpx_mpi_error *e = bpx_mpi_world_error(w);
    char root_message[sizeof e->message];
    memcpy(root_message, e->message, sizeof root_message);
    MPI_Bcast(root_message, (int)sizeof root_message, MPI_CHAR, 0, MPI_COMM_WORLD);
    CHECK_MSG(strcmp(root_message, e->message) == 0, "rank %d says '%.100s'", rank, e->message);
    CHECK(e->status == BPX_ERR_INVALID_ARGUMENT && e->id == id && e->rank >= 0);
    char what[96];
    snprintf(what, sizeof what, "id %llu is given twice (by ranks %d and %d)",
             (unsigned long long)id, a, b);
    CHECK_MSG(strstr(e->message, what) != NULL, "'%.150s' lacks '%.90s'", e->message, what);
    size_t none;
    CHECK(bpx_mpi_world_pairs(w, &none) == NULL && none == 0);
}

// Ids given twice where the two copies never reach one rank: in regions far apart, by one rank or
// by two, new ids or one a rank has given all along. Every rank fails alike; an id twice in one
// rank's input is an input error (the world as it was), one given by two ranks fails the cycle;
// neither leaves a trace in the next cycles, where an object may change ranks as before.
static void test_duplicate_ids(void)
{
    check_set_context("duplicate ids ranks=%d", ranks);
    size_t n = 400;
    scene s = scene_make(n, false, true, 37);
    scene_uniform_density((uint32_t)n, 1.0f, 37, s.boxes);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    def.rebalance_threshold = 1e9; // the regions stay where the first cycle put them
    run r = run_open(&s, def, 37);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    int last = ranks - 1;
    bpx_box in_first = far_point(r.world, 0, -1e6f), in_last = far_point(r.world, last, 1e6f);
    s.boxes[0] = in_first; // object 0: at home on rank 0, alone in its region's far corner
    cycle(&r, &s, OWN_HOME, 0);
    uint64_t extra = object_id(n + 1), zero = object_id(0); // extra: no object of the scene
    size_t before, after;
    bpx_mpi_world_pairs(r.world, &before);

    // 1. The last rank gives a new id twice, in the first region and in its own.
    size_t count = take_share(&r, &s, OWN_HOME);
    if (rank == last) {
        r.ids[count] = extra, r.boxes[count++] = in_first;
        r.ids[count] = extra, r.boxes[count++] = in_last;
    }
    uint64_t second = count - 1; // where the repeat is in the last rank's input
    MPI_Bcast(&second, 1, MPI_UINT64_T, last, MPI_COMM_WORLD);
    bpx_status got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
    check_collective(r.world, got, BPX_ERR_INVALID_ARGUMENT, last, extra);
    CHECK_EQ_U64(bpx_mpi_world_error(r.world)->index, second);
    CHECK(bpx_mpi_world_pairs(r.world, &after) != NULL && after == before);
    bpx_mpi_pair_events ev;
    CHECK_STATUS(bpx_mpi_world_pair_events(r.world, &ev), BPX_OK);
    cycle(&r, &s, OWN_HOME, 0);

    if (ranks > 1) {
        // 2. Rank 0 and the last rank give one new id in the same cycle, each in its region.
        count = take_share(&r, &s, OWN_HOME);
        if (rank == 0)
            r.ids[count] = extra, r.boxes[count++] = in_first;
        if (rank == last)
            r.ids[count] = extra, r.boxes[count++] = in_last;
        got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
        check_duplicate(r.world, got, extra, 0, last);
        CHECK_STATUS(bpx_mpi_world_pair_events(r.world, &ev), BPX_ERR_BAD_STATE);
        // The failed cycle registered nobody's id: the last rank alone may give it now (far
        // from every box, so the pairs stay the scene's), and drop it again.
        count = take_share(&r, &s, OWN_HOME);
        if (rank == last)
            r.ids[count] = extra, r.boxes[count++] = in_last;
        got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
        CHECK_MSG(got == BPX_OK, "%s: %s", check_status_name(got),
                  bpx_mpi_world_error(r.world)->message);
        cycle(&r, &s, OWN_HOME, 0);

        // 3. The last rank gives, far off in its region, the id of object 0, which rank 0 has
        //    given all along.
        count = take_share(&r, &s, OWN_HOME);
        CHECK(rank != 0 || (count > 0 && r.ids[0] == zero));
        if (rank == last)
            r.ids[count] = zero, r.boxes[count++] = in_last;
        got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
        check_duplicate(r.world, got, zero, 0, last);

        // 4. Object 0 moves to the last rank and back (rank 0 stops giving it as the last rank
        //    starts): no duplicate.
        r.moved_object = 0;
        r.moved_to = last;
        cycle(&r, &s, OWN_HOME, 0);
        r.moved_object = SIZE_MAX;
        cycle(&r, &s, OWN_HOME, 0);

        // 5. After cycles where every object changes ranks at random, the last rank gives again
        //    the id of an object some other rank gives in the same call, wholly in rank 0's
        //    region (so the two copies never meet), while all the others move on.
        for (int c = 0; c < 4; c++)
            cycle(&r, &s, OWN_RANDOM, 0);
        float lo[3], hi[3];
        CHECK_STATUS(bpx_mpi_world_region(r.world, 0, lo, hi), BPX_OK);
        int tried = 0;
        for (size_t k = 1; k < n && tried < 3; k++) {
            const bpx_box *b = &s.boxes[k];
            bool inside = true;
            for (int a = 0; a < 3; a++)
                inside = inside && lo[a] <= b->min[a] && b->max[a] < hi[a];
            if (!inside)
                continue;
            count = take_share(&r, &s, OWN_RANDOM); // the same draws on every rank
            if (r.owner[k] == last)
                continue;
            if (rank == last)
                r.ids[count] = object_id(k), r.boxes[count++] = in_last;
            got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
            check_duplicate(r.world, got, object_id(k), r.owner[k], last);
            tried++;
        }
        CHECK(tried == 3);
        cycle(&r, &s, OWN_RANDOM, 0);
    }
    run_close(&r);
    scene_free(&s);
}

// bpx_mpi_world_migrate: objects reach their home ranks with their payload, none lost or
// doubled; CAPACITY moves nothing and names the room needed.
static void test_migrate(void)
{
    size_t n = 2000;
    check_set_context("migrate ranks=%d", ranks);
    scene s = scene_make(n, false, false, 23);
    scene_uniform_density((uint32_t)n, 1.0f, 23, s.boxes);
    run r = run_open(&s, bpx_mpi_default_world_def(), 23);
    size_t count = 0;
    CHECK_STATUS(bpx_mpi_world_migrate(r.world, r.ids, r.boxes, NULL, 0, n, &count, NULL),
                 BPX_ERR_BAD_STATE);
    cycle(&r, &s, OWN_NOT_LAST, 0);
    typedef struct payload {
        uint64_t id;
        float tag[3];
    } payload;
    payload *data = check_alloc(n * sizeof *data);
    uint64_t *ids_before = check_alloc(n * sizeof *ids_before);
    count = take_share(&r, &s, OWN_NOT_LAST);
    for (size_t k = 0; k < count; k++)
        data[k] = (payload){r.ids[k], {r.boxes[k].min[0], (float)k, -1.0f}};
    memcpy(ids_before, r.ids, count * sizeof *r.ids);
    // The room each rank will need: the objects whose centre its region holds.
    CHECK_STATUS(bpx_mpi_world_home_ranks(r.world, s.boxes, n, r.home), BPX_OK);
    size_t at_home = 0;
    for (size_t k = 0; k < n; k++)
        at_home += r.home[k] == rank;
    if (ranks > 1) { // the last rank has nothing and no room: nobody moves anything
        size_t room = rank == ranks - 1 ? 0 : n, asked = count, needed = 0;
        bpx_status got = bpx_mpi_world_migrate(r.world, r.ids, r.boxes, data, sizeof *data, room,
                                               &asked, &needed);
        check_collective(r.world, got, BPX_ERR_CAPACITY, ranks - 1, 0);
        CHECK(memcmp(ids_before, r.ids, count * sizeof *r.ids) == 0);
        CHECK_EQ_U64(asked, count);
        CHECK_EQ_U64(needed, at_home);
    }
    size_t over = n + 1; // more objects than room: refused everywhere
    CHECK_STATUS(bpx_mpi_world_migrate(r.world, r.ids, r.boxes, data, sizeof *data, n, &over, NULL),
                 BPX_ERR_INVALID_ARGUMENT);
    size_t moved = count, needed = 0;
    CHECK_STATUS(
        bpx_mpi_world_migrate(r.world, r.ids, r.boxes, data, sizeof *data, n, &moved, &needed),
        BPX_OK);
    check_no_error(bpx_mpi_world_error(r.world), "migrate after a refused one");
    CHECK_EQ_U64(moved, at_home);
    CHECK_EQ_U64(needed, at_home);
    // Each object is at home, its payload with it; together they are every object once.
    CHECK_STATUS(bpx_mpi_world_home_ranks(r.world, r.boxes, moved, r.home), BPX_OK);
    for (size_t k = 0; k < moved; k++) {
        CHECK(r.home[k] == rank);
        CHECK(data[k].id == r.ids[k] && data[k].tag[0] == r.boxes[k].min[0]);
    }
    bpx_mpi_pair *mine = check_alloc((moved + 1) * sizeof *mine);
    for (size_t k = 0; k < moved; k++)
        mine[k] = (bpx_mpi_pair){r.ids[k], 0};
    size_t total;
    bpx_mpi_pair *all = gather_list(mine, moved, &total);
    bpx_mpi_pair *want = check_alloc((n + 1) * sizeof *want);
    for (size_t k = 0; k < n; k++)
        want[k] = (bpx_mpi_pair){object_id(k), 0};
    qsort(want, n, sizeof *want, compare_pairs);
    CHECK(same_pairs(all, total, want, n));
    bpx_mpi_stats st = bpx_mpi_world_stats(r.world);
    uint64_t sent = st.migrated_sent, sum_sent, sum_received;
    MPI_Allreduce(&sent, &sum_sent, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    MPI_Allreduce(&st.migrated_received, &sum_received, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    CHECK_EQ_U64(sum_sent, sum_received);
    // At home, nothing is foreign, and the pairs are still the reference's.
    CHECK_STATUS(bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, moved), BPX_OK);
    CHECK_EQ_U64(bpx_mpi_world_stats(r.world).foreign_count, 0);
    CHECK_EQ_U64(bpx_mpi_world_stats(r.world).migrated_sent, sent);
    size_t want_pairs;
    bpx_world_pairs(s.reference, &want_pairs);
    CHECK_EQ_U64(bpx_mpi_world_stats(r.world).total_pair_count, want_pairs);
    // A bad box on one rank: refused everywhere, nothing moved.
    float kept_min = moved > 0 ? r.boxes[0].min[0] : 0.0f;
    if (rank == 0 && moved > 0)
        r.boxes[0].min[0] = NAN;
    size_t again = moved;
    bpx_status got =
        bpx_mpi_world_migrate(r.world, r.ids, r.boxes, data, sizeof *data, n, &again, NULL);
    CHECK_MSG(got == BPX_ERR_NOT_FINITE || (got == BPX_OK && ranks == 1 && moved == 0), "%s",
              check_status_name(got));
    CHECK(again == moved);
    if (rank == 0 && moved > 0)
        r.boxes[0].min[0] = kept_min;
    // No payload at all; everyone already home: nothing travels.
    again = moved;
    CHECK_STATUS(bpx_mpi_world_migrate(r.world, r.ids, r.boxes, NULL, 0, n, &again, NULL), BPX_OK);
    check_no_error(bpx_mpi_world_error(r.world), "migrate");
    CHECK(again == moved && bpx_mpi_world_stats(r.world).migrated_sent == 0);
    free(mine), free(all), free(want), free(data), free(ids_before);
    run_close(&r);
    scene_free(&s);
}

// Objects kept at home by migrate while they move: each collide carries the last one's order
// over the move (ids.c), unless the caller changed its arrays since, which it must notice
// (two objects swapped, an id given twice); and two collides on the same arrays. The pairs
// stay the reference's throughout.
static void check_gathered(run *r, scene *s)
{
    CHECK_STATUS(bpx_world_set_boxes(s->reference, s->boxes, (uint32_t)s->n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(s->reference), BPX_OK);
    size_t want_count, all_count;
    const bpx_pair *want_local = bpx_world_pairs(s->reference, &want_count);
    bpx_mpi_pair *want = to_global(want_local, want_count);
    const bpx_mpi_pair *all = NULL;
    CHECK_STATUS(bpx_mpi_world_gather_pairs(r->world, 0, &all, &all_count), BPX_OK);
    if (rank == 0)
        CHECK_MSG(same_pairs(all, all_count, want, want_count), "gathered %zu pairs, want %zu",
                  all_count, want_count);
    free(want);
}

static void test_migrate_cycles(void)
{
    size_t n = 3000;
    check_set_context("migrate cycles ranks=%d", ranks);
    scene s = scene_make(n, false, false, 31);
    scene_uniform_density((uint32_t)n, 1.0f, 31, s.boxes);
    run r = run_open(&s, bpx_mpi_default_world_def(), 31);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0); // the regions
    size_t count = take_share(&r, &s, OWN_ROUND_ROBIN);
    for (int c = 0; c < 8; c++) {
        check_set_context("migrate cycles ranks=%d cycle=%d", ranks, c);
        size_t moved = count;
        CHECK_STATUS(bpx_mpi_world_migrate(r.world, r.ids, r.boxes, NULL, 0, n, &moved, NULL),
                     BPX_OK);
        count = moved;
        if (c == 3 && count >= 2) { // the order carried over no longer holds
            uint64_t id = r.ids[0];
            bpx_box box = r.boxes[0];
            r.ids[0] = r.ids[count - 1], r.boxes[0] = r.boxes[count - 1];
            r.ids[count - 1] = id, r.boxes[count - 1] = box;
        }
        if (c == 5) { // an id twice on rank 0: refused everywhere, then given right
            uint64_t kept = count >= 2 ? r.ids[1] : 0;
            if (rank == 0 && count >= 2)
                r.ids[1] = r.ids[0];
            bpx_status got = bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count);
            int bad = got == BPX_ERR_INVALID_ARGUMENT, rank0_has_two = rank == 0 && count >= 2;
            MPI_Bcast(&rank0_has_two, 1, MPI_INT, 0, MPI_COMM_WORLD);
            CHECK(bad == rank0_has_two || (!rank0_has_two && got == BPX_OK));
            if (rank == 0 && count >= 2)
                r.ids[1] = kept;
        }
        CHECK_STATUS(bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count), BPX_OK);
        check_gathered(&r, &s);
        if (c == 6) { // again on the same arrays
            CHECK_STATUS(bpx_mpi_world_collide(r.world, r.ids, r.boxes, NULL, count), BPX_OK);
            check_gathered(&r, &s);
        }
        // Every object moves a little (the same draws on every rank), and the arrays follow.
        for (size_t k = 0; k < n; k++)
            for (int a = 0; a < 3; a++) {
                float d = scene_rng_range(&r.rng, -0.3f, 0.3f);
                s.boxes[k].min[a] += d, s.boxes[k].max[a] += d;
            }
        for (size_t i = 0; i < count; i++)
            r.boxes[i] = s.boxes[object_of(&r, r.ids[i])];
    }
    run_close(&r);
    scene_free(&s);
}

// Filters switched on and off between cycles (the rank's world must drop the old ones).
static void test_filters_toggle(void)
{
    size_t n = 600;
    check_set_context("filters toggled ranks=%d", ranks);
    scene s = scene_make(n, true, true, 29);
    scene_uniform_density((uint32_t)n, 1.0f, 29, s.boxes);
    bpx_mpi_filter *filters = s.filters;
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    run r = run_open(&s, def, 29);
    for (int c = 0; c < 6; c++) {
        s.filters = c % 3 == 1 ? NULL : filters;
        cycle(&r, &s, c % 2 ? OWN_RANDOM : OWN_ROUND_ROBIN, 0);
    }
    s.filters = filters;
    run_close(&r);
    scene_free(&s);
}

// The regions follow the boxes by themselves once the load drifts past the threshold, and a
// bisection that cannot help (every centre in one point) is not repeated every cycle.
static void test_auto_rebalance(void)
{
    size_t n = 1200;
    check_set_context("auto rebalance ranks=%d", ranks);
    scene s = scene_make(n, false, true, 31);
    scene_uniform_density((uint32_t)n, 1.0f, 31, s.boxes);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = true;
    run r = run_open(&s, def, 31);
    cycle(&r, &s, OWN_ROUND_ROBIN, 0);
    CHECK_EQ_U64(bpx_mpi_world_stats(r.world).decomposition_count, 1);
    // Half the boxes pile up as points on the centre of a box wholly inside rank 0's region.
    float lo[3], hi[3], at[3] = {0, 0, 0};
    CHECK_STATUS(bpx_mpi_world_region(r.world, 0, lo, hi), BPX_OK);
    for (size_t i = 0; i < n; i++) {
        const bpx_box *b = &s.boxes[i];
        bool inside = true;
        for (int k = 0; k < 3; k++)
            inside = inside && lo[k] <= b->min[k] && b->max[k] < hi[k];
        if (inside) {
            for (int k = 0; k < 3; k++)
                at[k] = 0.5f * b->min[k] + 0.5f * b->max[k];
            break;
        }
    }
    for (size_t i = 0; i < n / 2; i++) // distinct ids on one point: allowed
        s.boxes[i] = (bpx_box){{at[0], at[1], at[2]}, {at[0], at[1], at[2]}};
    cycle(&r, &s, OWN_HOME, 0);
    double piled = bpx_mpi_world_stats(r.world).imbalance;
    cycle(&r, &s, OWN_HOME, 0);
    if (ranks > 1) { // one rank holds half the boxes: (ranks + 1) / 2 times the mean
        CHECK_MSG(piled > 1.4, "imbalance %.3f", piled);
        CHECK_EQ_U64(bpx_mpi_world_stats(r.world).decomposition_count, 2);
    }
    for (int c = 0; c < 3; c++) // all in one point: one rank holds them whatever the cuts
        cycle(&r, &s, OWN_HOME, 0);
    uint64_t settled = bpx_mpi_world_stats(r.world).decomposition_count;
    for (size_t i = 0; i < n; i++)
        s.boxes[i] = s.boxes[0];
    for (int c = 0; c < 4; c++)
        cycle(&r, &s, OWN_HOME, 0);
    CHECK(bpx_mpi_world_stats(r.world).decomposition_count <= settled + 1);
    run_close(&r);
    scene_free(&s);
}

// A definition that changes the cycle's collectives must agree over ranks.
static void test_mismatched_def(void)
{
    if (ranks == 1)
        return;
    check_set_context("mismatched def ranks=%d", ranks);
    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    def.track_events = rank == 0;
    bpx_mpi_world *w = (bpx_mpi_world *)1;
    bpx_mpi_error err;
    CHECK_STATUS(bpx_mpi_world_create(MPI_COMM_WORLD, &def, &w, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(w == NULL && strstr(err.message, "track_events") != NULL);
    def = bpx_mpi_default_world_def();
    def.samples_per_rank = (1u << 24) / (uint32_t)ranks + 1;
    CHECK_STATUS(bpx_mpi_world_create(MPI_COMM_WORLD, &def, &w, &err), BPX_ERR_INVALID_ARGUMENT);
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &ranks);
    test_errors();
    test_duplicate_ids();
    test_empty();
    test_scene_kinds();
    test_moving(1, false);
    test_moving(2, true);
    test_clustered();
    test_huge_and_borders();
    test_migrate();
    test_migrate_cycles();
    test_filters_toggle();
    test_auto_rebalance();
    test_mismatched_def();
    int local[2] = {check_failures, check_count}, total[2];
    MPI_Reduce(local, total, 2, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
    int code = 0;
    if (rank == 0) {
        char name[32];
        snprintf(name, sizeof name, "test_mpi (%d ranks)", ranks);
        check_failures = total[0];
        check_count = total[1];
        code = check_finish(name, 1);
    }
    MPI_Bcast(&code, 1, MPI_INT, 0, MPI_COMM_WORLD);
    MPI_Finalize();
    return code;
}
