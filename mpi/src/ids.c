// Ids given twice. Each rank sorts its own ids every call: an id twice there is an input error.
// Across ranks, each id has an id rank (a hash of it) whose directory holds the ids of its share,
// each with the rank that gave it in the last successful collide. A call sends each id rank only
// the change, the ids a rank began or stopped giving since then, in the exchange of box records
// that happens anyway (after the records for that rank). Steady cycles, where a few objects
// change ranks, send a few ids; a rank's first call sends all of its own. The directory checks
// the ids added against each other and against those it holds that their rank did not drop in
// the same call, and takes the change only once the whole call has succeeded, on every rank.
#include <string.h>

#include "mpi_world.h"

// splitmix64's finaliser: the id rank takes the high half, the directory's slot the low bits.
static uint64_t mix(uint64_t x)
{
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9u;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebu;
    return x ^ (x >> 31);
}

int bpx_mpi__id_rank(uint64_t id, int ranks)
{
    return (int)((mix(id) >> 32) % (uint64_t)ranks);
}

static size_t slot_of(uint64_t id, size_t cap)
{
    return (size_t)mix(id) & (cap - 1);
}

// The slot that holds id, or the empty one where it would go.
static size_t find(const bpx_mpi_world *w, uint64_t id)
{
    size_t mask = w->dir_cap - 1, s = slot_of(id, w->dir_cap);
    while (w->dir_ranks[s] != 0 && w->dir_ids[s] != id)
        s = (s + 1) & mask;
    return s;
}

static void insert(bpx_mpi_world *w, uint64_t id, int rank)
{
    size_t s = find(w, id);
    w->dir_count += w->dir_ranks[s] == 0;
    w->dir_ids[s] = id;
    w->dir_ranks[s] = rank + 1;
}

// Linear probing's deletion without tombstones: later entries of the run move into the hole
// unless their own slot lies (cyclically) after it.
static void erase(bpx_mpi_world *w, uint64_t id)
{
    size_t mask = w->dir_cap - 1, hole = find(w, id);
    if (w->dir_ranks[hole] == 0)
        return;
    for (size_t s = (hole + 1) & mask; w->dir_ranks[s] != 0; s = (s + 1) & mask) {
        size_t home = slot_of(w->dir_ids[s], w->dir_cap);
        bool stays = hole <= s ? hole < home && home <= s : hole < home || home <= s;
        if (!stays) {
            w->dir_ids[hole] = w->dir_ids[s];
            w->dir_ranks[hole] = w->dir_ranks[s];
            hole = s;
        }
    }
    w->dir_ranks[hole] = 0;
    w->dir_count--;
}

// A directory of cap slots (a power of two) with the same ids. 0, or -1 with it unchanged.
static int rehash(bpx_mpi_world *w, size_t cap)
{
    uint64_t *ids = bpx_mpi__alloc(cap * sizeof *ids);
    int *ranks = bpx_mpi__alloc(cap * sizeof *ranks);
    if (!ids || !ranks) {
        bpx_mpi__free(ids, cap * sizeof *ids);
        bpx_mpi__free(ranks, cap * sizeof *ranks);
        return -1;
    }
    memset(ranks, 0, cap * sizeof *ranks);
    uint64_t *old_ids = w->dir_ids;
    int *old_ranks = w->dir_ranks;
    size_t old_cap = w->dir_cap;
    w->dir_ids = ids;
    w->dir_ranks = ranks;
    w->dir_cap = cap;
    w->dir_count = 0;
    for (size_t s = 0; s < old_cap; s++)
        if (old_ranks[s] != 0)
            insert(w, old_ids[s], old_ranks[s] - 1);
    bpx_mpi__free(old_ids, old_cap * sizeof *old_ids);
    bpx_mpi__free(old_ranks, old_cap * sizeof *old_ranks);
    return 0;
}

// The capacities of the own arrays and their twins trade places (after their pointers did).
static void swap_own_caps(bpx_mpi_world *w)
{
    size_t c = w->own_ids_cap;
    w->own_ids_cap = w->own_ids_tmp_cap;
    w->own_ids_tmp_cap = c;
    c = w->own_pos_cap;
    w->own_pos_cap = w->own_pos_tmp_cap;
    w->own_pos_tmp_cap = c;
}

// The own arrays and their twins trade places, with their capacities.
static void swap_own(bpx_mpi_world *w)
{
    uint64_t *k = w->own_ids;
    w->own_ids = w->own_ids_tmp;
    w->own_ids_tmp = k;
    uint32_t *p = w->own_pos;
    w->own_pos = w->own_pos_tmp;
    w->own_pos_tmp = p;
    swap_own_caps(w);
}

// Sorts the caller's count ids (left as they are) into own_ids, their positions into own_pos.
// An input in order but for some objects at its end (as bpx_mpi_world_migrate leaves the
// arrivals) costs a sort of those and one merge.
static void sort_own(bpx_mpi_world *w, const uint64_t *ids, size_t count)
{
    size_t sorted = count > 0;
    while (sorted < count && ids[sorted - 1] <= ids[sorted])
        sorted++;
    size_t tail = count - sorted;
    if (tail > count / 4) {
        uint64_t *before = w->own_ids;
        bpx_mpi__sort_ids_from(ids, &w->own_ids, &w->own_pos, &w->own_ids_tmp, &w->own_pos_tmp,
                               count);
        if (w->own_ids != before) // the sort swapped the pointers: the capacities follow
            swap_own_caps(w);
        return;
    }
    // The tail sorted in the twins (the own arrays as scratch), then merged after the prefix
    // into whichever pair it is not in.
    uint64_t *tk = w->own_ids_tmp, *sk = w->own_ids;
    uint32_t *tp = w->own_pos_tmp, *sp = w->own_pos;
    if (tail > 0)
        memcpy(tk, ids + sorted, tail * sizeof *ids);
    for (size_t k = 0; k < tail; k++)
        tp[k] = (uint32_t)(sorted + k);
    bpx_mpi__sort_ids(&tk, &tp, &sk, &sp, tail);
    bool into_twins = tk == w->own_ids;
    uint64_t *out = into_twins ? w->own_ids_tmp : w->own_ids;
    uint32_t *pos = into_twins ? w->own_pos_tmp : w->own_pos;
    size_t i = 0, j = 0, k = 0;
    while (i < sorted && j < tail) {
        if (tk[j] < ids[i])
            out[k] = tk[j], pos[k++] = tp[j++];
        else
            out[k] = ids[i], pos[k++] = (uint32_t)i++;
    }
    for (; i < sorted; i++)
        out[k] = ids[i], pos[k++] = (uint32_t)i;
    for (; j < tail; j++)
        out[k] = tk[j], pos[k++] = tp[j];
    if (into_twins)
        swap_own(w);
}

// The last successful collide's order carried over (its ids at their positions), moved where
// the migrate since then put each (home), the arrivals (the input's end) sorted and merged in,
// then checked against the input in one gather: two passes where a sort takes three. Positions
// are distinct by construction (old ones mapped one to one, arrivals past the stayers), so ids
// that match make this the input's sorted order. false: the input is not that; nothing used.
static bool sort_own_from_last(bpx_mpi_world *w, const uint64_t *ids, size_t count)
{
    const int *moved = w->order_hint ? w->home : NULL;
    size_t last = w->last_ids_count, stay = moved ? w->hint_stay : last;
    if ((moved ? w->hint_count : last) != count || stay > count)
        return false;
    size_t arrived = count - stay;
    void **arrays[] = {(void **)&w->arrive_ids, (void **)&w->arrive_ids_tmp,
                       (void **)&w->arrive_pos, (void **)&w->arrive_pos_tmp};
    const size_t sizes[] = {sizeof *w->arrive_ids, sizeof *w->arrive_ids_tmp,
                            sizeof *w->arrive_pos, sizeof *w->arrive_pos_tmp};
    if (bpx_mpi__reserve(arrays, sizes, 4, &w->arrive_cap, arrived) != 0)
        return false; // the full sort needs no more memory
    uint64_t *ak = w->arrive_ids, *ak_tmp = w->arrive_ids_tmp;
    uint32_t *ap = w->arrive_pos, *ap_tmp = w->arrive_pos_tmp;
    if (arrived > 0)
        memcpy(ak, ids + stay, arrived * sizeof *ids);
    for (size_t k = 0; k < arrived; k++)
        ap[k] = (uint32_t)(stay + k);
    bpx_mpi__sort_ids(&ak, &ap, &ak_tmp, &ap_tmp, arrived);

    const uint64_t *was = w->last_ids;
    const uint32_t *was_pos = w->own_pos;
    uint64_t *out = w->own_ids_tmp;
    uint32_t *pos = w->own_pos_tmp;
    size_t k = 0, j = 0;
    for (size_t i = 0; i < last; i++) {
        uint32_t p = was_pos[i];
        if (moved) {
            if (moved[p] < 0)
                continue;
            p = (uint32_t)moved[p];
        }
        for (; j < arrived && ak[j] < was[i] && k < count; j++)
            out[k] = ak[j], pos[k++] = ap[j];
        if (k == count)
            return false;
        out[k] = was[i], pos[k++] = p;
    }
    for (; j < arrived && k < count; j++)
        out[k] = ak[j], pos[k++] = ap[j];
    if (k != count || j != arrived)
        return false;
    for (size_t i = 0; i < count; i++)
        if (ids[pos[i]] != out[i])
            return false;
    swap_own(w);
    return true;
}

// One pass over this call's sorted ids, and with more than one rank the last successful
// collide's: an id twice here (its index in own_ids, or 0 for none), and the change: the ids
// added (to own_ids_tmp, free after the sort) and dropped (to dropped_out). Runs the two share
// go by in blocks (steady cycles change few ids; last_ids has no id twice).
static size_t diff_own(bpx_mpi_world *w)
{
    enum { BLOCK = 32 };
    const uint64_t *now = w->own_ids, *was = w->last_ids;
    size_t i = 0, j = 0, n_now = w->own_ids_count, n_was = w->size > 1 ? w->last_ids_count : 0;
    size_t added = 0, dropped = 0;
    bool changes = w->size > 1;
    while (i < n_now) {
        if (i > 0 && now[i] == now[i - 1])
            return i;
        if (j < n_was && was[j] < now[i]) {
            w->dropped_out[dropped++] = was[j++];
        } else if (j < n_was && was[j] == now[i]) {
            i++, j++;
            while (i + BLOCK <= n_now && j + BLOCK <= n_was &&
                   memcmp(now + i, was + j, BLOCK * sizeof *now) == 0)
                i += BLOCK, j += BLOCK;
        } else {
            if (changes)
                w->own_ids_tmp[added++] = now[i];
            i++;
        }
    }
    while (j < n_was)
        w->dropped_out[dropped++] = was[j++];
    w->added_out_count = added;
    w->dropped_out_count = dropped;
    return 0;
}

bpx_status bpx_mpi__ids_check_own(bpx_mpi_world *w, const uint64_t *ids, size_t count)
{
    w->own_ids_count = w->added_out_count = w->dropped_out_count = 0;
    // own_pos keeps the last order only if it need not grow (growing does not keep contents).
    bool from_last = w->last_pos_valid && count <= w->own_pos_cap;
    if (bpx_mpi__grow((void **)&w->own_ids, &w->own_ids_cap, count, sizeof *w->own_ids) ||
        bpx_mpi__grow((void **)&w->own_ids_tmp, &w->own_ids_tmp_cap, count,
                      sizeof *w->own_ids_tmp) ||
        bpx_mpi__grow((void **)&w->own_pos, &w->own_pos_cap, count, sizeof *w->own_pos) ||
        bpx_mpi__grow((void **)&w->own_pos_tmp, &w->own_pos_tmp_cap, count,
                      sizeof *w->own_pos_tmp) ||
        (w->size > 1 && bpx_mpi__grow((void **)&w->dropped_out, &w->dropped_out_cap,
                                      w->last_ids_count, sizeof *w->dropped_out))) {
        bpx_mpi__fail(w, BPX_ERR_OUT_OF_MEMORY, 0, SIZE_MAX, -1, "no memory to sort %zu ids",
                      count);
        w->last_pos_valid = w->order_hint = false;
        return w->error.status;
    }
    if (!from_last || !sort_own_from_last(w, ids, count))
        sort_own(w, ids, count);
    w->last_pos_valid = w->order_hint = false; // own_pos holds this call's order now
    w->own_ids_count = count;
    size_t k = diff_own(w);
    if (k == 0)
        return BPX_OK;
    size_t a = w->own_pos[k - 1], b = w->own_pos[k];
    size_t first = a < b ? a : b, second = a < b ? b : a;
    uint64_t id = w->own_ids[k];
    bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, id, second, -1,
                  "id %llu is given twice by this rank (boxes %zu and %zu of its input)",
                  (unsigned long long)id, first, second);
    return w->error.status;
}

void bpx_mpi__ids_count(const bpx_mpi_world *w, int *plan)
{
    for (size_t k = 0; k < w->added_out_count; k++)
        plan[3 * bpx_mpi__id_rank(w->own_ids_tmp[k], w->size) + 1]++;
    for (size_t k = 0; k < w->dropped_out_count; k++)
        plan[3 * bpx_mpi__id_rank(w->dropped_out[k], w->size) + 2]++;
}

void bpx_mpi__ids_pack(const bpx_mpi_world *w, unsigned char *out, size_t *cursor)
{
    for (size_t k = 0; k < w->added_out_count; k++) {
        uint64_t id = w->own_ids_tmp[k];
        memcpy(out + 8 * cursor[2 * bpx_mpi__id_rank(id, w->size)]++, &id, 8);
    }
    for (size_t k = 0; k < w->dropped_out_count; k++) {
        uint64_t id = w->dropped_out[k];
        memcpy(out + 8 * cursor[2 * bpx_mpi__id_rank(id, w->size) + 1]++, &id, 8);
    }
}

int bpx_mpi__ids_reserve(bpx_mpi_world *w, size_t added, size_t dropped)
{
    w->added_count = w->dropped_count = 0;
    void **adds[] = {(void **)&w->added, (void **)&w->added_tmp, (void **)&w->added_order,
                     (void **)&w->added_order_tmp, (void **)&w->added_rank};
    const size_t add_sizes[] = {sizeof *w->added, sizeof *w->added_tmp, sizeof *w->added_order,
                                sizeof *w->added_order_tmp, sizeof *w->added_rank};
    void **drops[] = {(void **)&w->dropped, (void **)&w->dropped_tmp};
    const size_t drop_sizes[] = {sizeof *w->dropped, sizeof *w->dropped_tmp};
    if (bpx_mpi__reserve(adds, add_sizes, 5, &w->added_cap, added) ||
        bpx_mpi__reserve(drops, drop_sizes, 2, &w->dropped_cap, dropped))
        return -1;
    // At most half full once the ids added are in (dropped ones only make room).
    size_t need = w->dir_count + added;
    if (need > SIZE_MAX / 8)
        return -1;
    if (2 * need <= w->dir_cap)
        return 0;
    size_t cap = 64;
    while (cap < 2 * need)
        cap *= 2;
    return rehash(w, cap);
}

void bpx_mpi__ids_receive(bpx_mpi_world *w, int from, const unsigned char *ids, size_t added,
                          size_t dropped)
{
    if (added > 0) {
        memcpy(w->added + w->added_count, ids, added * 8);
        for (size_t k = 0; k < added; k++)
            w->added_rank[w->added_count + k] = from;
        w->added_count += added;
    }
    if (dropped > 0) {
        memcpy(w->dropped + w->dropped_count, ids + added * 8, dropped * 8);
        w->dropped_count += dropped;
    }
}

static bool holds(const uint64_t *sorted, size_t n, uint64_t id)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (sorted[mid] < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && sorted[lo] == id;
}

static void twice(bpx_mpi_world *w, uint64_t id, int a, int b)
{
    bpx_mpi__fail(w, BPX_ERR_INVALID_ARGUMENT, id, SIZE_MAX, -1,
                  "id %llu is given twice (by ranks %d and %d)", (unsigned long long)id,
                  a < b ? a : b, a < b ? b : a);
}

void bpx_mpi__ids_check(bpx_mpi_world *w)
{
    size_t n = w->added_count;
    for (size_t k = 0; k < n; k++)
        w->added_order[k] = (uint32_t)k;
    bpx_mpi__sort_ids(&w->added, &w->added_order, &w->added_tmp, &w->added_order_tmp, n);
    bpx_mpi__sort_ids(&w->dropped, NULL, &w->dropped_tmp, NULL, w->dropped_count);
    for (size_t k = 0; k < n; k++) {
        uint64_t id = w->added[k];
        int by = w->added_rank[w->added_order[k]];
        if (k > 0 && w->added[k - 1] == id) { // two ranks began giving it in this call
            twice(w, id, w->added_rank[w->added_order[k - 1]], by);
            return;
        }
        size_t s = find(w, id);
        if (w->dir_ranks[s] != 0 && !holds(w->dropped, w->dropped_count, id)) {
            twice(w, id, w->dir_ranks[s] - 1, by); // and another gives it still
            return;
        }
    }
}

void bpx_mpi__ids_commit(bpx_mpi_world *w)
{
    uint64_t *ids = w->last_ids;
    size_t cap = w->last_ids_cap;
    w->last_ids = w->own_ids;
    w->last_ids_cap = w->own_ids_cap;
    w->last_ids_count = w->own_ids_count;
    w->last_pos_valid = true;
    w->own_ids = ids;
    w->own_ids_cap = cap;
    w->own_ids_count = 0;
    for (size_t k = 0; k < w->dropped_count; k++)
        erase(w, w->dropped[k]);
    for (size_t k = 0; k < w->added_count; k++)
        insert(w, w->added[k], w->added_rank[w->added_order[k]]);
    w->added_count = w->dropped_count = 0;
}

void bpx_mpi__ids_free(bpx_mpi_world *w)
{
#define FREE_ARRAY(field, cap) bpx_mpi__free(w->field, (cap) * sizeof *w->field)
    FREE_ARRAY(own_ids, w->own_ids_cap);
    FREE_ARRAY(own_ids_tmp, w->own_ids_tmp_cap);
    FREE_ARRAY(own_pos, w->own_pos_cap);
    FREE_ARRAY(own_pos_tmp, w->own_pos_tmp_cap);
    FREE_ARRAY(last_ids, w->last_ids_cap);
    FREE_ARRAY(dropped_out, w->dropped_out_cap);
    FREE_ARRAY(dir_ids, w->dir_cap);
    FREE_ARRAY(dir_ranks, w->dir_cap);
    FREE_ARRAY(added, w->added_cap);
    FREE_ARRAY(added_tmp, w->added_cap);
    FREE_ARRAY(added_order, w->added_cap);
    FREE_ARRAY(added_order_tmp, w->added_cap);
    FREE_ARRAY(added_rank, w->added_cap);
    FREE_ARRAY(dropped, w->dropped_cap);
    FREE_ARRAY(dropped_tmp, w->dropped_cap);
    FREE_ARRAY(arrive_ids, w->arrive_cap);
    FREE_ARRAY(arrive_ids_tmp, w->arrive_cap);
    FREE_ARRAY(arrive_pos, w->arrive_cap);
    FREE_ARRAY(arrive_pos_tmp, w->arrive_cap);
#undef FREE_ARRAY
}
