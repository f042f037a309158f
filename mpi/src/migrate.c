// Moving objects to their home ranks with the caller's data: what a particle code does after
// each step, so that bpx's own exchange stays down to the copies near borders.
#include <limits.h>
#include <string.h>

#include "mpi_world.h"

#define MIGRATE_MAX_PAYLOAD (1u << 20)

static bpx_status check(bpx_mpi_world *w, const uint64_t *ids, const bpx_box *boxes,
                        const void *payload, size_t payload_size, size_t capacity,
                        const size_t *count)
{
    if (!count) {
        bpx_mpi__fail(w, BPX_ERR_NULL_ARGUMENT, 0, SIZE_MAX, -1, "count is NULL");
    } else if (*count > capacity) {
        bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1,
                      "count %zu is over capacity %zu", *count, capacity);
    } else if (capacity > 0 && (!ids || !boxes || (payload_size > 0 && !payload))) {
        bpx_mpi__fail(w, BPX_ERR_NULL_ARGUMENT, 0, SIZE_MAX, -1, "%s is NULL with capacity %zu",
                      !ids     ? "ids"
                      : !boxes ? "boxes"
                               : "payload",
                      capacity);
    } else if (payload_size > MIGRATE_MAX_PAYLOAD) {
        bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, 0, SIZE_MAX, -1, "payload_size %zu is over 1 MB",
                      payload_size);
    } else if (!w->have_tree) {
        bpx_mpi__fail(w, BPX_ERR_BAD_STATE, 0, SIZE_MAX, -1,
                      "no regions yet: migrate after the first successful collide");
    } else if (*count > BPX_MAX_BOXES) {
        bpx_mpi__fail(w, BPX_ERR_TOO_MANY_BOXES, 0, SIZE_MAX, -1, "%zu objects exceed %u", *count,
                      BPX_MAX_BOXES);
    } else {
        bpx_error e;
        bpx_status s = bpx_validate_boxes(boxes, (uint32_t)*count, &e);
        if (s != BPX_OK) {
            const char *what = strstr(e.message, ": ");
            bpx_mpi__fail(w, s, ids[e.index], e.index, e.axis, "id %llu (object %u): %s",
                          (unsigned long long)ids[e.index], e.index, what ? what + 2 : e.message);
        }
    }
    return w->error.status;
}

bpx_status bpx_mpi_world_migrate(bpx_mpi_world *w, uint64_t *ids, bpx_box *boxes, void *payload,
                                 size_t payload_size, size_t capacity, size_t *count,
                                 size_t *needed)
{
    bpx_mpi__clear_error(w);
    bpx_status status = check(w, ids, boxes, payload, payload_size, capacity, count);
    if ((status = bpx_mpi__agree(w)) != BPX_OK)
        return status;
    size_t n = *count, record = 8 + sizeof(bpx_box) + payload_size;
    unsigned char *data = payload;
    // The next collide may carry the last one's order over this move (ids.c) when this is the
    // first move since, of the same objects. home is rewritten from here on.
    bool carry = w->last_pos_valid && !w->order_hint && n == w->last_ids_count;
    w->last_pos_valid = w->order_hint = false;

    // Where each object goes.
    memset(w->send_counts, 0, sizeof(int) * (size_t)w->size);
    if (bpx_mpi__grow((void **)&w->home, &w->home_cap, n, sizeof *w->home)) {
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1, "no memory for %zu objects", n);
        n = 0; // still takes part in the exchange of counts below
    }
    size_t leaving = 0;
    for (size_t i = 0; i < n; i++) {
        float c[3];
        bpx_mpi__rcb_centre(&boxes[i], c);
        int home =
            bpx_mpi__rcb_holds(&w->tree, w->rank, c) ? w->rank : bpx_mpi__rcb_locate(&w->tree, c);
        w->home[i] = home;
        if (home != w->rank) {
            w->send_counts[home]++;
            leaving++;
        }
    }
    MPI_Alltoall(w->send_counts, 1, MPI_INT, w->recv_counts, 1, MPI_INT, w->comm);
    size_t arriving = 0;
    for (int r = 0; r < w->size; r++)
        arriving += (size_t)w->recv_counts[r];
    size_t after = n - leaving + arriving;
    if (w->error.status == BPX_OK) {
        if (leaving > INT_MAX || arriving > INT_MAX ||
            (leaving > 0 && record > SIZE_MAX / leaving) ||
            (arriving > 0 && record > SIZE_MAX / arriving))
            bpx_mpi__fail(w, BPX_ERR_TOO_MANY_BOXES, 0, SIZE_MAX, -1,
                          "%zu objects out and %zu in are past MPI's int counts", leaving,
                          arriving);
        else if (after > capacity)
            bpx_mpi__fail(w, BPX_ERR_CAPACITY, 0, SIZE_MAX, -1,
                          "%zu objects after the move, room for %zu", after, capacity);
        else if (bpx_mpi__grow((void **)&w->send, &w->send_cap, leaving * record, 1) ||
                 bpx_mpi__grow((void **)&w->recv, &w->recv_cap, arriving * record, 1))
            bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1,
                          "no memory to move %zu and receive %zu objects", leaving, arriving);
    }
    bpx_status mine = w->error.status;
    if (needed && (mine == BPX_OK || mine == BPX_ERR_CAPACITY))
        *needed = after; // with CAPACITY, every rank learns the room it needs
    if ((status = bpx_mpi__agree(w)) != BPX_OK)
        return status;

    // Pack the leavers by destination, keep the stayers in order at the front, then unpack.
    size_t sent = 0, received = 0;
    for (int r = 0; r < w->size; r++) {
        w->send_displs[r] = (int)sent;
        w->recv_displs[r] = (int)received;
        sent += (size_t)w->send_counts[r];
        received += (size_t)w->recv_counts[r];
    }
    memcpy(w->cursor, w->send_displs, sizeof(int) * (size_t)w->size);
    size_t stay = 0;
    for (size_t i = 0; i < n; i++) {
        int home = w->home[i];
        w->home[i] = home == w->rank ? (int)stay : -1; // where it is now, for the next collide
        if (home == w->rank) {
            ids[stay] = ids[i];
            boxes[stay] = boxes[i];
            if (payload_size)
                memmove(data + stay * payload_size, data + i * payload_size, payload_size);
            stay++;
            continue;
        }
        unsigned char *rec = w->send + (size_t)w->cursor[home]++ * record;
        memcpy(rec, &ids[i], 8);
        memcpy(rec + 8, &boxes[i], sizeof(bpx_box));
        if (payload_size)
            memcpy(rec + 8 + sizeof(bpx_box), data + i * payload_size, payload_size);
    }
    MPI_Datatype type;
    MPI_Type_contiguous((int)record, MPI_BYTE, &type);
    MPI_Type_commit(&type);
    MPI_Alltoallv(w->send, w->send_counts, w->send_displs, type, w->recv, w->recv_counts,
                  w->recv_displs, type, w->comm);
    MPI_Type_free(&type);
    for (size_t k = 0; k < received; k++) {
        const unsigned char *rec = w->recv + k * record;
        memcpy(&ids[stay + k], rec, 8);
        memcpy(&boxes[stay + k], rec + 8, sizeof(bpx_box));
        if (payload_size)
            memcpy(data + (stay + k) * payload_size, rec + 8 + sizeof(bpx_box), payload_size);
    }
    *count = stay + received;
    w->last_pos_valid = w->order_hint = carry;
    w->hint_stay = stay;
    w->hint_count = stay + received;
    w->stats.migrated_sent = sent;
    w->stats.migrated_received = received;
    w->stats.migrate_bytes_sent = sent * record;
    return BPX_OK;
}
