// The distributed world: creation, errors, accessors and the gather. The cycle is in cycle.c.
#include "mpi_world.h"

#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

uint64_t bpx_mpi__cpu_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

void bpx_mpi__fail(bpx_mpi_world *w, bpx_status status, uint64_t id, size_t index, int axis,
                   const char *format, ...)
{
    bpx_mpi_error *e = &w->error;
    e->status = status;
    e->rank = w->rank;
    e->id = id;
    e->index = index;
    e->axis = axis;
    int used = snprintf(e->message, sizeof e->message, "rank %d: ", w->rank);
    va_list args;
    va_start(args, format);
    vsnprintf(e->message + used, sizeof e->message - (size_t)used, format, args);
    va_end(args);
}

void bpx_mpi__clear_error(bpx_mpi_world *w)
{
    memset(&w->error, 0, sizeof w->error);
    w->error.status = BPX_OK;
    w->error.rank = -1;
    w->error.index = SIZE_MAX;
    w->error.axis = -1;
}

bpx_status bpx_mpi__agree(bpx_mpi_world *w)
{
    int mine = w->error.status != BPX_OK ? w->rank : w->size, first;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, w->comm);
    if (first == w->size)
        return BPX_OK;
    MPI_Bcast(&w->error, (int)sizeof w->error, MPI_BYTE, first, w->comm);
    return w->error.status;
}

// The radix sort of bpx_mpi__sort_ids and bpx_mpi__sort_ids_from: from src (positions 0..n-1
// as the order) when it is not NULL, else from *keys and *order.
static void radix_sort(const uint64_t *src, uint64_t **keys, uint32_t **order, uint64_t **keys_tmp,
                       uint32_t **order_tmp, size_t n)
{
    // 11-bit digits (six passes at most; an 8 KB histogram stays in L1), all histograms from one
    // read of the keys, and digits every key shares are skipped: ids below 2^22 take two passes.
    // Keys already in order (one rank, or callers that keep their arrays sorted) cost one read.
    enum { BITS = 11, DIGITS = 6, RADIX = 1 << BITS };
    const uint64_t *k0 = src ? src : *keys;
    size_t sorted = n > 0;
    while (sorted < n && k0[sorted - 1] <= k0[sorted])
        sorted++;
    bool moved = false;
    if (sorted < n) {
        uint32_t count[DIGITS][RADIX]; // 48 KB
        memset(count, 0, sizeof count);
        for (size_t i = 0; i < n; i++) {
            uint64_t k = k0[i];
            for (int d = 0; d < DIGITS; d++)
                count[d][(k >> (d * BITS)) & (RADIX - 1)]++;
        }
        for (int d = 0; d < DIGITS; d++) {
            uint32_t *c = count[d];
            if (c[(k0[0] >> (d * BITS)) & (RADIX - 1)] == n)
                continue; // every key has this digit
            uint32_t sum = 0;
            for (int v = 0; v < RADIX; v++) {
                uint32_t here = c[v];
                c[v] = sum;
                sum += here;
            }
            const uint64_t *k_in = moved ? *keys : k0;
            uint64_t *k_out = *keys_tmp;
            if (order && !moved && src) { // the first pass from src: positions are the order
                uint32_t *o_out = *order_tmp;
                for (size_t i = 0; i < n; i++) {
                    uint32_t to = c[(k_in[i] >> (d * BITS)) & (RADIX - 1)]++;
                    k_out[to] = k_in[i];
                    o_out[to] = (uint32_t)i;
                }
            } else if (order) {
                const uint32_t *o_in = *order;
                uint32_t *o_out = *order_tmp;
                for (size_t i = 0; i < n; i++) {
                    uint32_t to = c[(k_in[i] >> (d * BITS)) & (RADIX - 1)]++;
                    k_out[to] = k_in[i];
                    o_out[to] = o_in[i];
                }
            } else {
                for (size_t i = 0; i < n; i++)
                    k_out[c[(k_in[i] >> (d * BITS)) & (RADIX - 1)]++] = k_in[i];
            }
            if (order) {
                uint32_t *ot = *order;
                *order = *order_tmp;
                *order_tmp = ot;
            }
            uint64_t *kt = *keys;
            *keys = *keys_tmp;
            *keys_tmp = kt;
            moved = true;
        }
    }
    if (src && !moved) { // in order already (or all one key): a copy
        if (n > 0)
            memcpy(*keys, src, n * sizeof *src);
        for (size_t i = 0; order && i < n; i++)
            (*order)[i] = (uint32_t)i;
    }
}

void bpx_mpi__sort_ids(uint64_t **keys, uint32_t **order, uint64_t **keys_tmp, uint32_t **order_tmp,
                       size_t n)
{
    radix_sort(NULL, keys, order, keys_tmp, order_tmp, n);
}

void bpx_mpi__sort_ids_from(const uint64_t *src, uint64_t **keys, uint32_t **order,
                            uint64_t **keys_tmp, uint32_t **order_tmp, size_t n)
{
    radix_sort(src, keys, order, keys_tmp, order_tmp, n);
}

bpx_mpi_world_def bpx_mpi_default_world_def(void)
{
    bpx_mpi_world_def def;
    memset(&def, 0, sizeof def);
    def.local = bpx_default_world_def();
    def.rebalance_threshold = 1.25;
    return def;
}

static void free_buffers(bpx_mpi_world *w)
{
    int *tables[] = {w->send_counts, w->send_displs, w->recv_counts,
                     w->recv_displs, w->cursor,      w->touched};
    for (size_t i = 0; i < sizeof tables / sizeof tables[0]; i++)
        bpx_mpi__free(tables[i], (size_t)w->size * sizeof(int));
#define FREE_ARRAY(field, cap) bpx_mpi__free(w->field, (cap) * sizeof *w->field)
    FREE_ARRAY(samples, w->samples_cap);
    FREE_ARRAY(send, w->send_cap);
    FREE_ARRAY(recv, w->recv_cap);
    FREE_ARRAY(ids, w->present_cap);
    FREE_ARRAY(ids_tmp, w->present_cap);
    FREE_ARRAY(order, w->present_cap);
    FREE_ARRAY(order_tmp, w->present_cap);
    FREE_ARRAY(own_index, w->present_cap);
    FREE_ARRAY(boxes, w->present_cap);
    FREE_ARRAY(category, w->present_cap);
    FREE_ARRAY(mask, w->present_cap);
    FREE_ARRAY(present, w->present_cap);
    FREE_ARRAY(pairs, w->pairs_cap);
    FREE_ARRAY(ranks, w->pairs_cap);
    FREE_ARRAY(next, w->next_cap);
    FREE_ARRAY(next_ranks, w->next_cap);
    FREE_ARRAY(ev_send, w->ev_send_cap);
    FREE_ARRAY(ev_recv, w->ev_recv_cap);
    FREE_ARRAY(began, w->began_cap);
    FREE_ARRAY(ended, w->ended_cap);
    FREE_ARRAY(gathered, w->gathered_cap);
    FREE_ARRAY(gather_tmp, w->gather_tmp_cap);
    FREE_ARRAY(home, w->home_cap);
    FREE_ARRAY(plan_send, 3 * (size_t)w->size);
    FREE_ARRAY(plan_recv, 3 * (size_t)w->size);
    FREE_ARRAY(id_cursor, 2 * (size_t)w->size);
#undef FREE_ARRAY
    bpx_mpi__ids_free(w);
    bpx_mpi__rcb_free(&w->tree);
}

static void free_types(bpx_mpi_world *w)
{
    MPI_Datatype *types[] = {&w->record_type[0], &w->record_type[1], &w->pair_type, &w->event_type,
                             &w->sample_type};
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (*types[i] != MPI_DATATYPE_NULL)
            MPI_Type_free(types[i]);
}

static MPI_Datatype bytes_type(int bytes)
{
    MPI_Datatype type;
    MPI_Type_contiguous(bytes, MPI_BYTE, &type);
    MPI_Type_commit(&type);
    return type;
}

static bpx_status check_def(bpx_mpi_world *w, const bpx_mpi_world_def *def)
{
    if (!(def->rebalance_threshold == 0 || def->rebalance_threshold >= 1.0)) {
        bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1,
                      "rebalance_threshold %g is below 1 (0 means the default)",
                      def->rebalance_threshold);
        return w->error.status;
    }
    if ((uint64_t)def->samples_per_rank * (uint64_t)w->size > 1u << 24) {
        bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1,
                      "samples_per_rank %u x %d ranks is over 2^24 samples", def->samples_per_rank,
                      w->size);
        return w->error.status;
    }
    return BPX_OK;
}

bpx_status bpx_mpi_world_create(MPI_Comm comm, const bpx_mpi_world_def *def,
                                bpx_mpi_world **out_world, bpx_mpi_error *err)
{
    if (out_world)
        *out_world = NULL;
    bpx_mpi_world *w = bpx_mpi__alloc(sizeof *w);
    if (w)
        memset(w, 0, sizeof *w);
    bpx_mpi_world scratch; // reports errors when even the world could not be allocated
    memset(&scratch, 0, sizeof scratch);
    bpx_mpi_world *e = w ? w : &scratch;
    e->comm = comm;
    MPI_Comm_rank(comm, &e->rank);
    MPI_Comm_size(comm, &e->size);
    bpx_mpi__clear_error(e);
    e->record_type[0] = e->record_type[1] = e->pair_type = e->event_type = e->sample_type =
        MPI_DATATYPE_NULL;
    if (!w)
        bpx_mpi__fail(e, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1, "no memory for the world");
    else if (!def || !out_world)
        bpx_mpi__fail(e, BPX_ERR_NULL_ARGUMENT, 0, SIZE_MAX, -1, "%s is NULL",
                      !def ? "def" : "out_world");
    else if (check_def(w, def) == BPX_OK) {
        w->def = *def;
        if (w->def.rebalance_threshold == 0)
            w->def.rebalance_threshold = 1.25;
        if (w->def.samples_per_rank == 0) {
            uint32_t s = 65536u / (uint32_t)w->size;
            w->def.samples_per_rank = s < 32 ? 32 : s > 4096 ? 4096 : s;
        }
        w->def.local.track_events = false;
        size_t p = (size_t)w->size;
        w->send_counts = bpx_mpi__alloc(p * sizeof(int));
        w->send_displs = bpx_mpi__alloc(p * sizeof(int));
        w->recv_counts = bpx_mpi__alloc(p * sizeof(int));
        w->recv_displs = bpx_mpi__alloc(p * sizeof(int));
        w->cursor = bpx_mpi__alloc(p * sizeof(int));
        w->touched = bpx_mpi__alloc(p * sizeof(int));
        w->plan_send = bpx_mpi__alloc(3 * p * sizeof(int));
        w->plan_recv = bpx_mpi__alloc(3 * p * sizeof(int));
        w->id_cursor = bpx_mpi__alloc(2 * p * sizeof(size_t));
        if (!w->send_counts || !w->send_displs || !w->recv_counts || !w->recv_displs ||
            !w->cursor || !w->touched || !w->plan_send || !w->plan_recv || !w->id_cursor ||
            bpx_mpi__rcb_init(&w->tree, w->size) != 0)
            bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                          "no memory for the per-rank tables of %d ranks", w->size);
        else {
            bpx_status s = bpx_world_create(&w->def.local, &w->local);
            if (s != BPX_OK)
                bpx_mpi__fail(w, s, 0, SIZE_MAX, -1, "the rank's world: %s", bpx_status_string(s));
        }
    }
    // Nothing collective before this point: a rank that failed still agrees with the others.
    bpx_status status = bpx_mpi__agree(e);
    if (status == BPX_OK) { // events change which collectives a cycle makes: all or none
        int events = w->def.track_events, first;
        MPI_Allreduce(&events, &first, 1, MPI_INT, MPI_MIN, comm);
        if (first != events)
            bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1,
                          "def.track_events is true here and false on another rank");
        status = bpx_mpi__agree(w);
    }
    if (err)
        *err = e->error;
    if (status != BPX_OK) {
        if (w) {
            bpx_world_destroy(w->local);
            free_buffers(w);
            bpx_mpi__free(w, sizeof *w);
        }
        return status;
    }
    MPI_Comm_dup(comm, &w->comm);
    MPI_Comm_set_errhandler(w->comm, MPI_ERRORS_ARE_FATAL);
    w->record_type[0] = bytes_type(BPX_MPI_RECORD_BYTES);
    w->record_type[1] = bytes_type(BPX_MPI_RECORD_FILTER_BYTES);
    w->pair_type = bytes_type((int)sizeof(bpx_mpi_pair));
    w->event_type = bytes_type((int)sizeof(bpx_mpi_event_record));
    w->sample_type = bytes_type((int)sizeof(bpx_mpi_rcb_sample));
    *out_world = w;
    return BPX_OK;
}

void bpx_mpi_world_destroy(bpx_mpi_world *w)
{
    if (!w)
        return;
    free_types(w);
    MPI_Comm_free(&w->comm);
    bpx_world_destroy(w->local);
    free_buffers(w);
    bpx_mpi__free(w, sizeof *w);
}

const bpx_mpi_error *bpx_mpi_world_error(const bpx_mpi_world *w)
{
    return &w->error;
}

bpx_mpi_stats bpx_mpi_world_stats(const bpx_mpi_world *w)
{
    return w->stats;
}

const bpx_mpi_pair *bpx_mpi_world_pairs(const bpx_mpi_world *w, size_t *count)
{
    if (count)
        *count = w->pairs_valid ? w->pair_count : 0;
    return w->pairs_valid ? w->pairs : NULL;
}

const bpx_mpi_pair_ranks *bpx_mpi_world_pair_ranks(const bpx_mpi_world *w, size_t *count)
{
    if (count)
        *count = w->pairs_valid ? w->pair_count : 0;
    return w->pairs_valid ? w->ranks : NULL;
}

bpx_status bpx_mpi_world_pair_events(const bpx_mpi_world *w, bpx_mpi_pair_events *events)
{
    if (!events)
        return BPX_ERR_NULL_ARGUMENT;
    memset(events, 0, sizeof *events);
    if (!w->def.track_events || !w->events_valid)
        return BPX_ERR_BAD_STATE;
    *events = (bpx_mpi_pair_events){w->began, w->began_count, w->ended, w->ended_count};
    return BPX_OK;
}

bpx_status bpx_mpi_world_region(const bpx_mpi_world *w, int rank, float lo[3], float hi[3])
{
    if (!lo || !hi)
        return BPX_ERR_NULL_ARGUMENT;
    if (rank < 0 || rank >= w->size)
        return BPX_ERR_INVALID_ARGUMENT;
    if (!w->have_tree)
        return BPX_ERR_BAD_STATE;
    memcpy(lo, w->tree.lo[rank], sizeof(float[3]));
    memcpy(hi, w->tree.hi[rank], sizeof(float[3]));
    return BPX_OK;
}

bpx_status bpx_mpi_world_home_ranks(const bpx_mpi_world *w, const bpx_box *boxes, size_t count,
                                    int *ranks)
{
    if (count > 0 && (!boxes || !ranks))
        return BPX_ERR_NULL_ARGUMENT;
    if (!w->have_tree)
        return BPX_ERR_BAD_STATE;
    for (size_t i = 0; i < count; i++) {
        float c[3];
        bpx_mpi__rcb_centre(&boxes[i], c);
        ranks[i] = bpx_mpi__rcb_locate(&w->tree, c);
    }
    return BPX_OK;
}

void bpx_mpi_world_rebalance(bpx_mpi_world *w)
{
    w->rebalance_asked = true;
}

int bpx_mpi_event_rank(uint64_t a, uint64_t b, int ranks)
{
    // splitmix64's finaliser over both ids: pairs spread evenly over the ranks.
    uint64_t x = a * 0x9e3779b97f4a7c15u ^ (b + 0x632be59bd9b4e019u);
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9u;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebu;
    x ^= x >> 31;
    return ranks > 0 ? (int)(x % (uint64_t)ranks) : 0;
}

// Merges sorted runs [displs[r], displs[r] + counts[r]) of src into one sorted list, pairwise
// (log2 ranks passes); the result ends in *a or *b, which is returned.
static bpx_mpi_pair *merge_runs(bpx_mpi_pair *a, bpx_mpi_pair *b, size_t *starts, size_t runs)
{
    while (runs > 1) {
        size_t out_runs = 0;
        for (size_t r = 0; r < runs; r += 2) {
            size_t lo = starts[r], mid = starts[r + 1], hi = r + 2 <= runs ? starts[r + 2] : mid;
            size_t i = lo, j = mid, k = lo;
            while (i < mid && j < hi) {
                b[k++] = bpx_mpi__pair_less(&a[j], &a[i]) ? a[j++] : a[i++];
            }
            while (i < mid)
                b[k++] = a[i++];
            while (j < hi)
                b[k++] = a[j++];
            starts[out_runs++] = lo;
        }
        starts[out_runs] = starts[runs];
        runs = out_runs;
        bpx_mpi_pair *t = a;
        a = b;
        b = t;
    }
    return a;
}

bpx_status bpx_mpi_world_gather_pairs(bpx_mpi_world *w, int root, const bpx_mpi_pair **pairs,
                                      size_t *count)
{
    if (pairs)
        *pairs = NULL;
    if (count)
        *count = 0;
    bpx_mpi__clear_error(w);
    if (root < 0 || root >= w->size)
        bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1, "root %d is not a rank of %d",
                      root, w->size);
    else if (w->rank == root && (!pairs || !count))
        bpx_mpi__fail(w, BPX_ERR_NULL_ARGUMENT, 0, SIZE_MAX, -1, "%s is NULL on the root",
                      !pairs ? "pairs" : "count");
    else if (!w->pairs_valid)
        bpx_mpi__fail(w, BPX_ERR_BAD_STATE, 0, SIZE_MAX, -1,
                      "no successful collide to gather the pairs of");
    else if (w->pair_count > INT_MAX)
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_PAIRS, 0, SIZE_MAX, -1,
                      "%zu pairs are more than MPI's int counts", w->pair_count);
    bpx_status status = bpx_mpi__agree(w);
    if (status != BPX_OK)
        return status;
    int mine = (int)w->pair_count;
    MPI_Gather(&mine, 1, MPI_INT, w->recv_counts, 1, MPI_INT, root, w->comm);
    size_t total = 0;
    size_t *starts = NULL, starts_bytes = ((size_t)w->size + 1) * sizeof *starts;
    if (w->rank == root) {
        for (int r = 0; r < w->size; r++) {
            w->recv_displs[r] = (int)total;
            total += (size_t)w->recv_counts[r];
            if (total > INT_MAX) {
                bpx_mpi__fail(w, BPX_ERR_TOO_MANY_PAIRS, 0, SIZE_MAX, -1,
                              "%zu pairs in all are more than MPI's int counts", total);
                break;
            }
        }
        starts = bpx_mpi__alloc(starts_bytes);
        if (w->error.status == BPX_OK &&
            (!starts ||
             bpx_mpi__grow((void **)&w->gathered, &w->gathered_cap, total, sizeof(bpx_mpi_pair)) ||
             bpx_mpi__grow((void **)&w->gather_tmp, &w->gather_tmp_cap, total,
                           sizeof(bpx_mpi_pair))))
            bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                          "no memory to gather %zu pairs", total);
    }
    status = bpx_mpi__agree(w);
    if (status != BPX_OK) {
        bpx_mpi__free(starts, starts_bytes);
        return status;
    }
    MPI_Gatherv(w->pairs, mine, w->pair_type, w->gathered, w->recv_counts, w->recv_displs,
                w->pair_type, root, w->comm);
    if (w->rank == root) {
        for (int r = 0; r < w->size; r++)
            starts[r] = (size_t)w->recv_displs[r];
        starts[w->size] = total;
        bpx_mpi_pair *sorted = merge_runs(w->gathered, w->gather_tmp, starts, (size_t)w->size);
        if (sorted != w->gathered) { // keep the result in gathered; tmp becomes the other one
            size_t cap = w->gathered_cap;
            w->gather_tmp = w->gathered;
            w->gathered = sorted;
            w->gathered_cap = w->gather_tmp_cap;
            w->gather_tmp_cap = cap;
        }
        bpx_mpi__free(starts, starts_bytes);
        *pairs = w->gathered;
        *count = total;
    }
    return BPX_OK;
}
