// One distributed cycle: check the input, (re)decompose, route the boxes to the regions they
// touch, exchange them, find the pairs on each rank and keep those whose corner is here.
#include <limits.h>
#include <string.h>

#include "mpi_world.h"

static bpx_status check_input(bpx_mpi_world *w, const uint64_t *ids, const bpx_box *boxes,
                              size_t count)
{
    if (count > 0 && (!ids || !boxes)) {
        bpx_mpi__fail(w, BPX_ERR_NULL_ARGUMENT, 0, SIZE_MAX, -1, "%s is NULL with count %zu",
                      !ids ? "ids" : "boxes", count);
        return w->error.status;
    }
    if (count > BPX_MAX_BOXES) {
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_BOXES, 0, SIZE_MAX, -1,
                      "%zu boxes exceed BPX_MAX_BOXES (%u)", count, BPX_MAX_BOXES);
        return w->error.status;
    }
    bpx_error e;
    bpx_status s = bpx_validate_boxes(boxes, (uint32_t)count, &e);
    if (s != BPX_OK) {
        const char *what = strstr(e.message, ": "); // "box 5: min x is nan" -> "min x is nan"
        bpx_mpi__fail(w, s, ids[e.index], e.index, e.axis, "id %llu (box %u of its input): %s",
                      (unsigned long long)ids[e.index], e.index, what ? what + 2 : e.message);
    }
    return s;
}

// Samples of this rank's centres to all ranks, then the same bisection everywhere.
static bpx_status decompose(bpx_mpi_world *w, const bpx_box *boxes, size_t count)
{
    size_t take = count < w->def.samples_per_rank ? count : w->def.samples_per_rank;
    int mine = (int)take;
    MPI_Allgather(&mine, 1, MPI_INT, w->recv_counts, 1, MPI_INT, w->comm);
    size_t total = 0;
    for (int r = 0; r < w->size; r++) {
        w->recv_displs[r] = (int)total;
        total += (size_t)w->recv_counts[r];
    }
    if (total > INT_MAX ||
        bpx_mpi__grow((void **)&w->samples, &w->samples_cap, total, sizeof(bpx_mpi_rcb_sample)))
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                      "no memory for %zu samples of centres", total);
    bpx_status status = bpx_mpi__agree(w);
    if (status != BPX_OK)
        return status;
    for (size_t i = 0; i < take; i++) { // evenly strided: the same picks every run
        bpx_mpi_rcb_sample *out = &w->samples[(size_t)w->recv_displs[w->rank] + i];
        const bpx_box *b = &boxes[(size_t)((unsigned __int128)i * count / take)];
        bpx_mpi__rcb_centre(b, out->centre);
        out->weight = (float)((double)count / (double)take);
    }
    MPI_Allgatherv(MPI_IN_PLACE, 0, w->sample_type, w->samples, w->recv_counts, w->recv_displs,
                   w->sample_type, w->comm);
    bpx_mpi__rcb_build(&w->tree, w->samples, total);
    w->have_tree = true;
    w->stats.decomposed = true;
    w->stats.decomposition_count++;
    return BPX_OK;
}

static bool reserve_present(bpx_mpi_world *w, size_t n)
{
    void **arrays[] = {(void **)&w->ids,       (void **)&w->ids_tmp,   (void **)&w->order,
                       (void **)&w->order_tmp, (void **)&w->own_index, (void **)&w->boxes,
                       (void **)&w->category,  (void **)&w->mask,      (void **)&w->inside,
                       (void **)&w->source};
    const size_t sizes[] = {sizeof *w->ids,       sizeof *w->ids_tmp,   sizeof *w->order,
                            sizeof *w->order_tmp, sizeof *w->own_index, sizeof *w->boxes,
                            sizeof *w->category,  sizeof *w->mask,      sizeof *w->inside,
                            sizeof *w->source};
    return bpx_mpi__reserve(arrays, sizes, 10, &w->present_cap, n) == 0;
}

// The rank a present box came from: own boxes first, then the records by sender.
static int source_rank(const bpx_mpi_world *w, size_t at, size_t own)
{
    if (at < own)
        return w->rank;
    int lo = 0, hi = w->size - 1; // the last rank whose first record is at or before `at`
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if ((size_t)w->recv_displs[mid] <= at - own)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

typedef struct route_result {
    size_t own_present, send_total, recv_total;
} route_result;

// Counts what goes where, exchanges the counts and reserves every buffer of the exchange.
static bpx_status plan_exchange(bpx_mpi_world *w, const bpx_box *boxes, size_t count,
                                size_t record_bytes, route_result *out)
{
    memset(w->send_counts, 0, sizeof(int) * (size_t)w->size);
    size_t own = 0, foreign = 0;
    uint64_t sent = 0;
    uint64_t cpu = bpx_mpi__cpu_ns();
    for (size_t i = 0; i < count; i++) {
        if (bpx_mpi__rcb_inside(&w->tree, w->rank,
                                &boxes[i])) { // most boxes: no copies, no descent
            own++;
            continue;
        }
        int touched = bpx_mpi__rcb_touching(&w->tree, &boxes[i], w->touched);
        for (int t = 0; t < touched; t++) {
            int r = w->touched[t];
            if (r == w->rank)
                own++;
            else if (w->send_counts[r] < INT_MAX)
                w->send_counts[r]++, sent++;
        }
        float c[3];
        bpx_mpi__rcb_centre(&boxes[i], c);
        foreign += !bpx_mpi__rcb_holds(&w->tree, w->rank, c);
    }
    w->stats.compute_cpu_ns += bpx_mpi__cpu_ns() - cpu;
    MPI_Alltoall(w->send_counts, 1, MPI_INT, w->recv_counts, 1, MPI_INT, w->comm);
    size_t send_total = 0, recv_total = 0;
    for (int r = 0; r < w->size; r++) {
        w->send_displs[r] = (int)(send_total < INT_MAX ? send_total : INT_MAX);
        w->recv_displs[r] = (int)(recv_total < INT_MAX ? recv_total : INT_MAX);
        send_total += (size_t)w->send_counts[r];
        recv_total += (size_t)w->recv_counts[r];
    }
    *out = (route_result){own, send_total, recv_total};
    w->stats.foreign_count = foreign;
    if (sent > INT_MAX || send_total > INT_MAX || own + recv_total > BPX_MAX_BOXES)
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_BOXES, 0, SIZE_MAX, -1,
                      "%llu copies to send and %zu boxes to test are past MPI's int counts or "
                      "BPX_MAX_BOXES",
                      (unsigned long long)sent, own + recv_total);
    else if (bpx_mpi__grow((void **)&w->send, &w->send_cap, send_total * record_bytes, 1) ||
             bpx_mpi__grow((void **)&w->recv, &w->recv_cap, recv_total * record_bytes, 1) ||
             !reserve_present(w, own + recv_total))
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                      "no memory to exchange %zu and test %zu boxes", send_total, own + recv_total);
    return bpx_mpi__agree(w);
}

// Packs the records for other ranks and notes this rank's own boxes in its region.
static void pack(bpx_mpi_world *w, const uint64_t *ids, const bpx_box *boxes,
                 const bpx_mpi_filter *filters, size_t count, size_t record_bytes)
{
    memcpy(w->cursor, w->send_displs, sizeof(int) * (size_t)w->size);
    size_t own = 0;
    for (size_t i = 0; i < count; i++) {
        if (bpx_mpi__rcb_inside(&w->tree, w->rank, &boxes[i])) {
            w->ids[own] = ids[i];
            w->own_index[own++] = (uint32_t)i;
            continue;
        }
        bpx_mpi_filter f = filters ? filters[i] : (bpx_mpi_filter){1, 0xFFFFFFFFu};
        int touched = bpx_mpi__rcb_touching(&w->tree, &boxes[i], w->touched);
        for (int t = 0; t < touched; t++) {
            int r = w->touched[t];
            if (r == w->rank) {
                w->ids[own] = ids[i];
                w->own_index[own++] = (uint32_t)i;
                continue;
            }
            unsigned char *rec = w->send + (size_t)w->cursor[r]++ * record_bytes;
            memcpy(rec, &ids[i], 8);
            memcpy(rec + 8, &boxes[i], sizeof(bpx_box));
            if (record_bytes == BPX_MPI_RECORD_FILTER_BYTES)
                memcpy(rec + 32, &f, sizeof f);
        }
    }
}

// The ids of the records received, after the own ones; every arrival position in order.
static void unpack(bpx_mpi_world *w, size_t own, size_t recv_total, size_t record_bytes)
{
    for (size_t k = 0; k < recv_total; k++)
        memcpy(&w->ids[own + k], w->recv + k * record_bytes, 8);
    for (size_t k = 0; k < own + recv_total; k++)
        w->order[k] = (uint32_t)k;
}

// Sorts the present boxes by id (so local pairs (i, j) come out in global (a, b) order),
// gathers them from the caller's arrays and the records, checks that no id came twice, and runs
// the rank's own world.
static void find_local(bpx_mpi_world *w, const bpx_box *boxes, const bpx_mpi_filter *filters,
                       size_t n, size_t own, size_t record_bytes, bool with_filters)
{
    bpx_mpi__sort_ids(&w->ids, &w->order, &w->ids_tmp, &w->order_tmp, n);
    bool gather_filters = with_filters || w->local_filtered; // defaults when only last had any
    for (size_t k = 0; k < n; k++) {
        uint32_t from = w->order[k];
        bpx_mpi_filter f = {1, 0xFFFFFFFFu};
        if (from < own) {
            uint32_t i = w->own_index[from];
            w->boxes[k] = boxes[i];
            if (filters)
                f = filters[i];
        } else {
            const unsigned char *rec = w->recv + (size_t)(from - own) * record_bytes;
            memcpy(&w->boxes[k], rec + 8, sizeof(bpx_box));
            if (record_bytes == BPX_MPI_RECORD_FILTER_BYTES)
                memcpy(&f, rec + 32, sizeof f);
        }
        w->inside[k] = (uint8_t)bpx_mpi__rcb_inside(&w->tree, w->rank, &w->boxes[k]);
        w->source[k] = source_rank(w, from, own);
        if (gather_filters) {
            w->category[k] = f.category;
            w->mask[k] = f.mask;
        }
        if (k > 0 && w->ids[k] == w->ids[k - 1]) {
            bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, w->ids[k], SIZE_MAX, -1,
                          "id %llu is given twice (by ranks %d and %d)",
                          (unsigned long long)w->ids[k], w->source[k - 1], w->source[k]);
            return;
        }
    }
    bpx_status s = bpx_world_set_boxes(w->local, w->boxes, (uint32_t)n);
    if (s == BPX_OK && (with_filters || w->local_filtered)) {
        s = bpx_world_set_filters(w->local, NULL, w->category, w->mask, (uint32_t)n);
        if (s == BPX_OK)
            w->local_filtered = with_filters;
    }
    if (s == BPX_OK)
        s = bpx_world_collide(w->local);
    if (s != BPX_OK)
        bpx_mpi__fail(w, s, 0, SIZE_MAX, -1, "its own world of %zu boxes: %s", n,
                      bpx_world_error(w->local)->message);
}

// Keeps the pairs whose intersection's minimum corner lies in this rank's region.
static void select_pairs(bpx_mpi_world *w)
{
    size_t m;
    const bpx_pair *local = bpx_world_pairs(w->local, &m);
    void **arrays[] = {(void **)&w->next, (void **)&w->next_ranks};
    const size_t sizes[] = {sizeof *w->next, sizeof *w->next_ranks};
    if (bpx_mpi__reserve(arrays, sizes, 2, &w->next_cap, m) != 0) {
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1, "no memory for %zu pairs", m);
        return;
    }
    size_t kept = 0;
    for (size_t k = 0; k < m; k++) {
        uint32_t i = local[k].i, j = local[k].j;
        if (!(w->inside[i] | w->inside[j])) { // near a border: where is the corner?
            const bpx_box *a = &w->boxes[i], *b = &w->boxes[j];
            float corner[3];
            for (int d = 0; d < 3; d++)
                corner[d] = a->min[d] > b->min[d] ? a->min[d] : b->min[d];
            if (!bpx_mpi__rcb_holds(&w->tree, w->rank, corner))
                continue;
        }
        w->next_ranks[kept] = (bpx_mpi_pair_ranks){w->source[i], w->source[j]};
        w->next[kept++] = (bpx_mpi_pair){w->ids[i], w->ids[j]};
    }
    w->next_count = kept;
}

static bpx_status failed(bpx_mpi_world *w, bpx_status status)
{
    w->pairs_valid = false;
    w->events_valid = false;
    return status;
}

bpx_status bpx_mpi_world_collide(bpx_mpi_world *w, const uint64_t *ids, const bpx_box *boxes,
                                 const bpx_mpi_filter *filters, size_t count)
{
    uint64_t start = bpx__now_ns(), cpu_start = bpx_mpi__cpu_ns(), t;
    bpx_mpi__clear_error(w);
    bpx_mpi_stats *st = &w->stats;
    bpx_mpi_stats kept = *st; // the counts since creation and the last migrate's figures
    memset(st, 0, sizeof *st);
    st->cycle_count = kept.cycle_count;
    st->decomposition_count = kept.decomposition_count;
    st->migrated_sent = kept.migrated_sent;
    st->migrated_received = kept.migrated_received;
    st->migrate_bytes_sent = kept.migrate_bytes_sent;
    st->own_count = count;

    // 1. Input, and what every rank must know of the others before anything moves.
    check_input(w, ids, boxes, count);
    int mine[3] = {w->error.status != BPX_OK ? -w->rank : -w->size, filters != NULL && count > 0,
                   w->rebalance_asked || w->rebalance_next || !w->have_tree};
    int all[3];
    MPI_Allreduce(mine, all, 3, MPI_INT, MPI_MAX, w->comm);
    if (-all[0] < w->size) { // the world is as it was
        MPI_Bcast(&w->error, (int)sizeof w->error, MPI_BYTE, -all[0], w->comm);
        return w->error.status;
    }
    bool with_filters = all[1] != 0;
    size_t record_bytes = with_filters ? BPX_MPI_RECORD_FILTER_BYTES : BPX_MPI_RECORD_BYTES;
    MPI_Datatype record = w->record_type[with_filters];

    // 2. Regions.
    if (all[2]) {
        t = bpx__now_ns();
        bpx_status s = decompose(w, boxes, count);
        st->decompose_ns = bpx__now_ns() - t;
        if (s != BPX_OK)
            return failed(w, s);
        w->rebalance_asked = w->rebalance_next = false;
        w->measure_settled = true;
    }

    // 3. Route and exchange.
    t = bpx__now_ns();
    route_result route;
    bpx_status s = plan_exchange(w, boxes, count, record_bytes, &route);
    if (s != BPX_OK)
        return failed(w, s);
    uint64_t cpu = bpx_mpi__cpu_ns();
    pack(w, ids, boxes, filters, count, record_bytes);
    uint64_t packed = bpx__now_ns();
    st->compute_cpu_ns += bpx_mpi__cpu_ns() - cpu;
    MPI_Alltoallv(w->send, w->send_counts, w->send_displs, record, w->recv, w->recv_counts,
                  w->recv_displs, record, w->comm);
    uint64_t exchanged = bpx__now_ns();
    cpu = bpx_mpi__cpu_ns();
    unpack(w, route.own_present, route.recv_total, record_bytes);
    st->route_ns = (packed - t) + (bpx__now_ns() - exchanged);
    st->exchange_ns = exchanged - packed;
    size_t n = route.own_present + route.recv_total;
    st->present_count = n;
    st->copies_sent = route.send_total;
    st->copies_received = route.recv_total;
    st->bytes_sent = route.send_total * record_bytes;
    st->bytes_received = route.recv_total * record_bytes;
    for (int r = 0; r < w->size; r++)
        st->messages_sent += r != w->rank && w->send_counts[r] > 0;

    // 4. This rank's pairs.
    t = bpx__now_ns();
    find_local(w, boxes, filters, n, route.own_present, record_bytes, with_filters);
    st->local_ns = bpx__now_ns() - t;
    t = bpx__now_ns();
    if (w->error.status == BPX_OK)
        select_pairs(w);
    st->select_ns = bpx__now_ns() - t;
    st->compute_cpu_ns += bpx_mpi__cpu_ns() - cpu; // unpack, sort, local collide, select
    if ((s = bpx_mpi__agree(w)) != BPX_OK)
        return failed(w, s);
    uint64_t sums[2] = {n, w->next_count}, totals[2], most;
    MPI_Allreduce(sums, totals, 2, MPI_UINT64_T, MPI_SUM, w->comm);
    MPI_Allreduce(&sums[0], &most, 1, MPI_UINT64_T, MPI_MAX, w->comm);
    st->total_pair_count = totals[1];
    st->imbalance = totals[0] ? (double)most * w->size / (double)totals[0] : 1.0;

    // 5. Events, then the cycle's pairs become the world's.
    if (w->def.track_events) {
        t = bpx__now_ns();
        s = bpx_mpi__events(w);
        st->events_ns = bpx__now_ns() - t;
        if (s != BPX_OK)
            return failed(w, s);
    }
    bpx_mpi_pair *swap = w->pairs;
    bpx_mpi_pair_ranks *swap_ranks = w->ranks;
    size_t swap_cap = w->pairs_cap;
    w->pairs = w->next;
    w->ranks = w->next_ranks;
    w->pairs_cap = w->next_cap;
    w->pair_count = w->next_count;
    w->next = swap;
    w->next_ranks = swap_ranks;
    w->next_cap = swap_cap;
    w->pairs_valid = true;
    w->events_valid = w->def.track_events;
    // Rebalance past the threshold, but not again and again when bisection cannot do better
    // (all centres in one point): only once the imbalance grows past what the last one left.
    if (w->measure_settled) {
        w->settled_imbalance = st->imbalance;
        w->measure_settled = false;
    }
    w->rebalance_next =
        st->imbalance > w->def.rebalance_threshold && st->imbalance > 1.05 * w->settled_imbalance;
    st->pair_count = w->pair_count;
    st->cycle_count++;
    st->total_ns = bpx__now_ns() - start;
    st->cpu_ns = bpx_mpi__cpu_ns() - cpu_start;
    return BPX_OK;
}
