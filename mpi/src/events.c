// Events over global ids. A pair's corner may move to another rank's region between cycles, so
// a rank alone cannot tell a pair that moved from one that began or ended: each rank sends the
// change of its own list to the pair's event rank, where a "began here" and an "ended there" of
// the same pair cancel out.
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "mpi_world.h"

static int compare_records(const void *p, const void *q)
{
    const bpx_mpi_event_record *x = p, *y = q;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return (int)x->began - (int)y->began;
}

// Walks the two sorted lists; with out == NULL it counts per destination, else it writes.
static void diff(bpx_mpi_world *w, bpx_mpi_event_record *out, bool *overflow)
{
    const bpx_mpi_pair *old = w->pairs, *now = w->next;
    size_t i = 0, j = 0, n_old = w->pair_count, n_now = w->next_count;
    while (i < n_old || j < n_now) {
        const bpx_mpi_pair *p;
        uint32_t began;
        if (j >= n_now || (i < n_old && bpx_mpi__pair_less(&old[i], &now[j])))
            p = &old[i++], began = 0;
        else if (i >= n_old || bpx_mpi__pair_less(&now[j], &old[i]))
            p = &now[j++], began = 1;
        else {
            i++, j++;
            continue;
        }
        int to = bpx_mpi_event_rank(p->a, p->b, w->size);
        if (out)
            out[w->cursor[to]++] = (bpx_mpi_event_record){p->a, p->b, began, 0};
        else if (w->send_counts[to] < INT_MAX)
            w->send_counts[to]++;
        else
            *overflow = true;
    }
}

bpx_status bpx_mpi__events(bpx_mpi_world *w)
{
    // What the cycle's exchange of boxes sent each rank, kept in cursor until the packing below:
    // a rank that got nothing there and gets events here is one more message.
    memcpy(w->cursor, w->send_counts, sizeof(int) * (size_t)w->size);
    memset(w->send_counts, 0, sizeof(int) * (size_t)w->size);
    bool overflow = false;
    diff(w, NULL, &overflow);
    MPI_Alltoall(w->send_counts, 1, MPI_INT, w->recv_counts, 1, MPI_INT, w->comm);
    size_t send_total = 0, recv_total = 0;
    for (int r = 0; r < w->size; r++) {
        w->send_displs[r] = (int)send_total;
        w->recv_displs[r] = (int)recv_total;
        send_total += (size_t)w->send_counts[r];
        recv_total += (size_t)w->recv_counts[r];
        w->stats.messages_sent += r != w->rank && w->send_counts[r] > 0 && w->cursor[r] == 0;
    }
    if (overflow || send_total > INT_MAX || recv_total > INT_MAX)
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_PAIRS, 0, SIZE_MAX, -1,
                      "%zu events to send, %zu to receive: past MPI's int counts", send_total,
                      recv_total);
    else if (bpx_mpi__grow((void **)&w->ev_send, &w->ev_send_cap, send_total,
                           sizeof(bpx_mpi_event_record)) ||
             bpx_mpi__grow((void **)&w->ev_recv, &w->ev_recv_cap, recv_total,
                           sizeof(bpx_mpi_event_record)) ||
             bpx_mpi__grow((void **)&w->began, &w->began_cap, recv_total, sizeof(bpx_mpi_pair)) ||
             bpx_mpi__grow((void **)&w->ended, &w->ended_cap, recv_total, sizeof(bpx_mpi_pair)))
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1, "no memory for %zu + %zu events",
                      send_total, recv_total);
    bpx_status status = bpx_mpi__agree(w);
    if (status != BPX_OK)
        return status;
    memcpy(w->cursor, w->send_displs, sizeof(int) * (size_t)w->size);
    diff(w, w->ev_send, &overflow);
    MPI_Alltoallv(w->ev_send, w->send_counts, w->send_displs, w->event_type, w->ev_recv,
                  w->recv_counts, w->recv_displs, w->event_type, w->comm);
    // The events of pairs whose event rank is this one travel to itself: not bytes sent.
    size_t self_sent = (size_t)w->send_counts[w->rank],
           self_received = (size_t)w->recv_counts[w->rank];
    w->stats.bytes_sent += (send_total - self_sent) * sizeof(bpx_mpi_event_record);
    w->stats.bytes_received += (recv_total - self_received) * sizeof(bpx_mpi_event_record);

    // Each rank's list holds a pair at most once, so a pair arrives at most twice: as ended by
    // the rank that reported it last cycle and as began by the one that reports it now.
    if (recv_total > 1)
        qsort(w->ev_recv, recv_total, sizeof(bpx_mpi_event_record), compare_records);
    w->began_count = w->ended_count = 0;
    for (size_t k = 0; k < recv_total; k++) {
        const bpx_mpi_event_record *e = &w->ev_recv[k];
        if (k + 1 < recv_total && e[1].a == e->a && e[1].b == e->b) {
            k++; // moved between regions: still overlapping
            continue;
        }
        bpx_mpi_pair p = {e->a, e->b};
        if (e->began)
            w->began[w->began_count++] = p;
        else
            w->ended[w->ended_count++] = p;
    }
    return BPX_OK;
}
