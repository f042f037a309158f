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
                       (void **)&w->category,  (void **)&w->mask,      (void **)&w->present};
    const size_t sizes[] = {sizeof *w->ids,       sizeof *w->ids_tmp,   sizeof *w->order,
                            sizeof *w->order_tmp, sizeof *w->own_index, sizeof *w->boxes,
                            sizeof *w->category,  sizeof *w->mask,      sizeof *w->present};
    return bpx_mpi__reserve(arrays, sizes, 9, &w->present_cap, n) == 0;
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
    size_t own_present;       // own boxes in this rank's region
    size_t copies_sent;       // box records to other ranks
    size_t copies_received;   // and from them
    size_t send_total;        // records sent, id slots included (to itself too)
    size_t recv_total;        // records received, id slots included
    size_t id_slots_sent;     // records' worth of ids sent to other ranks
    size_t id_slots_received; // and received from them
    size_t added, dropped;    // ids this rank's directory receives
} route_result;

// Records' worth of ids: after a rank's box records, its ids added then dropped, 8 bytes each,
// in whole records so that one exchange of one record type carries both.
static size_t id_slots(size_t ids, size_t record_bytes)
{
    return (ids * 8 + record_bytes - 1) / record_bytes;
}

// Counts what goes where, exchanges the counts and reserves every buffer of the exchange.
static bpx_status plan_exchange(bpx_mpi_world *w, const bpx_box *boxes, size_t count,
                                size_t record_bytes, route_result *out)
{
    memset(w->plan_send, 0, 3 * sizeof(int) * (size_t)w->size);
    size_t own = 0, foreign = 0;
    uint64_t sent = 0;
    uint64_t cpu = bpx_mpi__cpu_ns();
    uint32_t *arrival = w->own_pos_tmp; // per input box: 0 inside the region, for pack
    for (size_t i = 0; i < count; i++) {
        if (bpx_mpi__rcb_inside(&w->tree, w->rank, &boxes[i])) {
            arrival[i] = 0;
            own++; // most boxes: no copies, no descent
            continue;
        }
        arrival[i] = BPX_MPI_NOT_HERE;
        int touched = bpx_mpi__rcb_touching(&w->tree, &boxes[i], w->touched);
        for (int t = 0; t < touched; t++) {
            int r = w->touched[t];
            if (r == w->rank)
                own++;
            else if (w->plan_send[3 * r] < INT_MAX)
                w->plan_send[3 * r]++, sent++;
        }
        float c[3];
        bpx_mpi__rcb_centre(&boxes[i], c);
        foreign += !bpx_mpi__rcb_holds(&w->tree, w->rank, c);
    }
    if (w->size > 1)
        bpx_mpi__ids_count(w, w->plan_send);
    w->stats.compute_cpu_ns += bpx_mpi__cpu_ns() - cpu;
    MPI_Alltoall(w->plan_send, 3, MPI_INT, w->plan_recv, 3, MPI_INT, w->comm);
    route_result route = {.own_present = own};
    for (int r = 0; r < w->size; r++) {
        const int *o = &w->plan_send[3 * r], *i = &w->plan_recv[3 * r];
        size_t slots_out = id_slots((size_t)o[1] + (size_t)o[2], record_bytes);
        size_t slots_in = id_slots((size_t)i[1] + (size_t)i[2], record_bytes);
        size_t records_out = (size_t)o[0] + slots_out, records_in = (size_t)i[0] + slots_in;
        w->send_counts[r] = (int)(records_out < INT_MAX ? records_out : INT_MAX);
        w->recv_counts[r] = (int)(records_in < INT_MAX ? records_in : INT_MAX);
        w->send_displs[r] = (int)(route.send_total < INT_MAX ? route.send_total : INT_MAX);
        w->recv_displs[r] = (int)(route.recv_total < INT_MAX ? route.recv_total : INT_MAX);
        route.send_total += records_out;
        route.recv_total += records_in;
        route.copies_sent += (size_t)o[0];
        route.copies_received += (size_t)i[0];
        if (r != w->rank) {
            route.id_slots_sent += slots_out;
            route.id_slots_received += slots_in;
        }
        route.added += (size_t)i[1];
        route.dropped += (size_t)i[2];
    }
    *out = route;
    w->stats.foreign_count = foreign;
    size_t present = own + route.copies_received;
    if (sent > INT_MAX || route.send_total > INT_MAX || route.recv_total > INT_MAX ||
        present > BPX_MAX_BOXES || route.added > INT_MAX || route.dropped > INT_MAX)
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_BOXES, 0, SIZE_MAX, -1,
                      "%zu records to send and %zu to receive, %zu boxes to test are past MPI's "
                      "int counts or BPX_MAX_BOXES",
                      route.send_total, route.recv_total, present);
    else if (bpx_mpi__grow((void **)&w->send, &w->send_cap, route.send_total * record_bytes, 1) ||
             bpx_mpi__grow((void **)&w->recv, &w->recv_cap, route.recv_total * record_bytes, 1) ||
             !reserve_present(w, present) ||
             (w->size > 1 && bpx_mpi__ids_reserve(w, route.added, route.dropped) != 0))
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                      "no memory to exchange %zu and test %zu boxes", route.send_total, present);
    return bpx_mpi__agree(w);
}

// Packs the records for other ranks, and the ids for their directories after them, and notes
// where this rank's own boxes in its region arrive among the boxes it tests (own first).
static void pack(bpx_mpi_world *w, const uint64_t *ids, const bpx_box *boxes,
                 const bpx_mpi_filter *filters, size_t count, size_t record_bytes)
{
    memcpy(w->cursor, w->send_displs, sizeof(int) * (size_t)w->size);
    uint32_t *arrival = w->own_pos_tmp; // per input box: plan_exchange's inside test, then
                                        // its arrival position (the id sort is done with it)
    size_t own = 0;
    for (size_t i = 0; i < count; i++) {
        if (arrival[i] != BPX_MPI_NOT_HERE) { // wholly inside: read no box
            arrival[i] = (uint32_t)own;
            w->own_index[own++] = (uint32_t)i;
            continue;
        }
        bpx_mpi_filter f = filters ? filters[i] : (bpx_mpi_filter){1, 0xFFFFFFFFu};
        int touched = bpx_mpi__rcb_touching(&w->tree, &boxes[i], w->touched);
        for (int t = 0; t < touched; t++) {
            int r = w->touched[t];
            if (r == w->rank) {
                arrival[i] = (uint32_t)own;
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
    if (w->size == 1)
        return;
    for (int r = 0; r < w->size; r++) { // in words (records are 32 or 40 bytes)
        size_t at = ((size_t)w->send_displs[r] + (size_t)w->plan_send[3 * r]) * record_bytes / 8;
        w->id_cursor[2 * r] = at;
        w->id_cursor[2 * r + 1] = at + (size_t)w->plan_send[3 * r + 1];
    }
    bpx_mpi__ids_pack(w, w->send, w->id_cursor);
}

// Hands the ids received to the directory, then moves the box records down over the room they
// took, so that the records lie together by source rank, as recv_displs and recv_counts then
// say.
static void take_ids(bpx_mpi_world *w, size_t record_bytes)
{
    if (w->size == 1)
        return;
    for (int r = 0; r < w->size; r++) {
        const int *i = &w->plan_recv[3 * r];
        const unsigned char *at =
            w->recv + ((size_t)w->recv_displs[r] + (size_t)i[0]) * record_bytes;
        bpx_mpi__ids_receive(w, r, at, (size_t)i[1], (size_t)i[2]);
    }
    size_t boxes = 0;
    for (int r = 0; r < w->size; r++) {
        size_t here = (size_t)w->plan_recv[3 * r];
        if (here > 0 && boxes != (size_t)w->recv_displs[r])
            memmove(w->recv + boxes * record_bytes,
                    w->recv + (size_t)w->recv_displs[r] * record_bytes, here * record_bytes);
        w->recv_displs[r] = (int)boxes;
        w->recv_counts[r] = (int)here;
        boxes += here;
    }
}

// The ids of the records received, with their arrival positions (after the own ones).
static void unpack(bpx_mpi_world *w, size_t own, size_t recv_total, size_t record_bytes)
{
    for (size_t k = 0; k < recv_total; k++) {
        memcpy(&w->ids[own + k], w->recv + k * record_bytes, 8);
        w->order[own + k] = (uint32_t)(own + k);
    }
}

// The ids of the boxes this rank tests, sorted, with their arrival positions in order: its own,
// sorted already with the input's (ids.c), less those that went elsewhere only, merged with the
// records received, sorted here (few, for callers that keep objects at home).
static void sort_present(bpx_mpi_world *w, size_t n, size_t own)
{
    size_t m = n - own;
    uint64_t *rk = w->ids + own, *rk_tmp = w->ids_tmp + own;
    uint32_t *ro = w->order + own, *ro_tmp = w->order_tmp + own;
    bpx_mpi__sort_ids(&rk, &ro, &rk_tmp, &ro_tmp, m);
    bool into_twins = rk == w->ids + own; // the output goes to the pair they are not in
    uint64_t *out = into_twins ? w->ids_tmp : w->ids;
    uint32_t *order = into_twins ? w->order_tmp : w->order;
    const uint64_t *ok = w->own_ids;
    const uint32_t *pos = w->own_pos, *arrival = w->own_pos_tmp;
    size_t i = 0, j = 0, k = 0, n_own = w->own_ids_count;
    for (; i < n_own; i++) {
        uint32_t at = arrival[pos[i]];
        if (at == BPX_MPI_NOT_HERE)
            continue;
        while (j < m && rk[j] < ok[i])
            out[k] = rk[j], order[k++] = ro[j++];
        out[k] = ok[i], order[k++] = at;
    }
    for (; j < m; j++)
        out[k] = rk[j], order[k++] = ro[j];
    if (into_twins) { // they share present_cap
        uint64_t *t = w->ids;
        w->ids = w->ids_tmp;
        w->ids_tmp = t;
        uint32_t *o = w->order;
        w->order = w->order_tmp;
        w->order_tmp = o;
    }
}

// Sorts the present boxes by id (so local pairs (i, j) come out in global (a, b) order),
// gathers them from the caller's arrays and the records, checks that no id came twice, and runs
// the rank's own world.
static void find_local(bpx_mpi_world *w, const bpx_box *boxes, const bpx_mpi_filter *filters,
                       size_t n, size_t own, size_t record_bytes, bool with_filters)
{
    sort_present(w, n, own);
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
        w->present[k] = (bpx_mpi_present){w->ids[k], source_rank(w, from, own),
                                          (uint32_t)bpx_mpi__rcb_inside(&w->tree, w->rank,
                                                                        &w->boxes[k])};
        if (gather_filters) {
            w->category[k] = f.category;
            w->mask[k] = f.mask;
        }
        if (k > 0 && w->ids[k] == w->ids[k - 1]) { // a guard: the id checks have caught it
            int a = w->present[k - 1].source, b = w->present[k].source;
            bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, w->ids[k], SIZE_MAX, -1,
                          "id %llu is given twice (by ranks %d and %d)",
                          (unsigned long long)w->ids[k], a < b ? a : b, a < b ? b : a);
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
        const bpx_mpi_present *p = &w->present[i], *q = &w->present[j];
        if (!(p->inside | q->inside)) { // near a border: where is the corner?
            const bpx_box *a = &w->boxes[i], *b = &w->boxes[j];
            float corner[3];
            for (int d = 0; d < 3; d++)
                corner[d] = a->min[d] > b->min[d] ? a->min[d] : b->min[d];
            if (!bpx_mpi__rcb_holds(&w->tree, w->rank, corner))
                continue;
        }
        w->next_ranks[kept] = (bpx_mpi_pair_ranks){p->source, q->source};
        w->next[kept++] = (bpx_mpi_pair){p->id, q->id};
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
    if (check_input(w, ids, boxes, count) == BPX_OK) {
        uint64_t cpu = bpx_mpi__cpu_ns();
        t = bpx__now_ns();
        bpx_mpi__ids_check_own(w, ids, count);
        st->local_ns = bpx__now_ns() - t;
        st->compute_cpu_ns += bpx_mpi__cpu_ns() - cpu;
    }
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
    take_ids(w, record_bytes);
    unpack(w, route.own_present, route.copies_received, record_bytes);
    st->route_ns = (packed - t) + (bpx__now_ns() - exchanged);
    st->exchange_ns = exchanged - packed;
    size_t n = route.own_present + route.copies_received;
    st->present_count = n;
    st->copies_sent = route.copies_sent;
    st->copies_received = route.copies_received;
    st->bytes_sent = (route.copies_sent + route.id_slots_sent) * record_bytes;
    st->bytes_received = (route.copies_received + route.id_slots_received) * record_bytes;
    for (int r = 0; r < w->size; r++)
        st->messages_sent += r != w->rank && w->send_counts[r] > 0;

    // 4. Ids given by two ranks, then this rank's pairs.
    t = bpx__now_ns();
    if (w->size > 1)
        bpx_mpi__ids_check(w);
    if (w->error.status == BPX_OK)
        find_local(w, boxes, filters, n, route.own_present, record_bytes, with_filters);
    st->local_ns += bpx__now_ns() - t;
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
    cpu = bpx_mpi__cpu_ns();
    bpx_mpi__ids_commit(w); // every rank succeeded: the ids of this call are the last ones
    st->compute_cpu_ns += bpx_mpi__cpu_ns() - cpu;
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
