// sap's warm cycle: the boxes that left their fat boxes get new ones, the lists (or the scan
// list, scan.c) are mended, and the fat pairs whose overlap changed are merged.
//
// A warm cycle (O(n + p_fat) plus the mending, k the fat pairs that may have changed):
//  1. One pass (ranges on the workers) copies the boxes (AoS, for the exact filter) and lists
//     the boxes that left their fat boxes.
//  2. None: nothing to mend. A few (at most n / 64 + 16): each in turn gets a new fat box, and its
//     six endpoints are found by where (each word's index in its list, kept by every move, since a
//     binary search per endpoint would be most of this mend at 1k boxes; made after a rebuild by
//     the first such mend) and moved to their places, the lists sorted at every step. More (or
//     boxes were added): the moved boxes' endpoints take their new words in place and each list is
//     mended by one pass of insertion sort (the three at once on the workers). Insertion swaps
//     exactly the endpoints whose relative order changed, and the order of min_a and max_b is the
//     truth of lo_a <= hi_b, so a pair whose fat overlap changed has at least one of its six
//     conditions flipped: it is met at least once as a swap of a min with a max, and noted when the
//     fat boxes' overlap before and after the step differ (box by box: b's old and new fat box
//     against the other's current one; all at once: old against old, new against new).
//  3. The noted pairs (few when the scene is coherent) are sorted and merged into the fat
//     pairs: each is kept iff the fat boxes overlap now, whether or not it was there before. So
//     a pair noted twice, or noted and then turned back, costs nothing but a test.
//  4. The fat pairs are filtered by the exact overlap (the second box prefetched: it is
//     anywhere in memory) into block 0, already in (i, j) order.
//
// Growth (add_boxes appending ids) stays warm: a new box enters as if it had been inert last
// cycle (max at the front, min at the back of each list) and the one-pass mend sorts it in. An
// id freed by remove_boxes keeps its fat box (its inert box lies in any box) until it is reused;
// its stale fat pairs never pass the exact filter. Both cost O(n) moves per box, like
// AxisSweep3's insert and remove, and fall under the move budget (rebuild.c; without lists,
// growth past what the budget allows rebuilds untried).

#include <string.h>

#include "sap_internal.h"

// Sorts a change list by (i, j) (bottom-up merge sort through st->spare: O(k log k), no
// allocation past the spare's high-water mark) and drops repeats (a pair met on several axes).
static bool sort_unique(bpx_sap_state *st, bpx_pair_list *list)
{
    size_t count = list->count;
    if (count < 2)
        return true;
    st->spare.count = 0;
    if (!bpx__list_reserve(&st->spare, count))
        return false;
    bpx_pair *src = list->pairs, *dst = st->spare.pairs;
    for (size_t width = 1; width < count; width *= 2) {
        for (size_t lo = 0; lo < count; lo += 2 * width) {
            size_t mid = lo + width < count ? lo + width : count;
            size_t hi = mid + width < count ? mid + width : count;
            size_t a = lo, b = mid, out = lo;
            while (a < mid && b < hi)
                dst[out++] = pair_word(src[b]) < pair_word(src[a]) ? src[b++] : src[a++];
            while (a < mid)
                dst[out++] = src[a++];
            while (b < hi)
                dst[out++] = src[b++];
        }
        bpx_pair *t = src;
        src = dst;
        dst = t;
    }
    if (src != list->pairs) { // an odd number of passes left it in the spare: swap the lists
        bpx_pair_list t = *list;
        *list = st->spare;
        list->count = count;
        st->spare = t;
    }
    size_t kept = 1;
    for (size_t k = 1; k < count; k++)
        if (pair_word(list->pairs[k]) != pair_word(list->pairs[kept - 1]))
            list->pairs[kept++] = list->pairs[k];
    list->count = kept;
    return true;
}

// Moves the endpoint at `at` of box b to its place for word x (the list sorted but for it),
// noting in st->changes every box whose fat overlap with b changes when b's fat box goes from
// `before` to st->a.fat[b] (the other boxes as they are now). Returns the moves, or
// UINT64_MAX when memory ran out.
static uint64_t move_end(bpx_sap_state *st, int axis, uint32_t count, uint32_t at, uint64_t x,
                         const bpx_box *before)
{
    uint64_t *ends = st->a.ends[axis];
    uint32_t *where = st->a.where[axis];
    const bpx_box *fat = st->a.fat;
    uint32_t b = (uint32_t)x & BOX_MASK, from = at;
    if (x > ends[at]) {
        while (at + 1 < count && ends[at + 1] < x) {
            uint64_t next = ends[at + 1];
            uint32_t other = (uint32_t)next & BOX_MASK;
            if (((next ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(before, &fat[other]) &&
                !push(&st->changes, ordered(b, other)))
                return UINT64_MAX;
            ends[at] = next;
            where[end_slot(next)] = at;
            at++;
        }
    } else {
        while (at > 0 && ends[at - 1] > x) {
            uint64_t past = ends[at - 1];
            uint32_t other = (uint32_t)past & BOX_MASK;
            if (((past ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(before, &fat[other]) &&
                !push(&st->changes, ordered(b, other)))
                return UINT64_MAX;
            ends[at] = past;
            where[end_slot(past)] = at;
            at--;
        }
    }
    ends[at] = x;
    where[end_slot(x)] = at;
    return at > from ? at - from : from - at;
}

// Few boxes left their fat boxes: each in turn gets its new fat box, and its six endpoints
// are found (where) and moved to their places, the lists sorted at every step.
static bpx_sap_mend_result mend_few(bpx_sap_state *st, uint32_t n, uint32_t changed,
                                    uint64_t budget)
{
    uint64_t moves = 0;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        bpx_box before = st->a.fat[b];
        st->a.fat[b] = fatten(&st->a.cur[b], st->margin);
        for (int axis = 0; axis < 3; axis++)
            for (int max = 0; max < 2; max++) {
                uint64_t old = fat_word(&before, axis, max, b);
                uint64_t x = fat_word(&st->a.fat[b], axis, max, b);
                if (old == x)
                    continue;
                uint32_t at = st->a.where[axis][end_slot(old)];
                if (at >= 2 * n || st->a.ends[axis][at] != old)
                    return MEND_GAVE_UP; // never, unless this file has a bug: rebuild
                uint64_t m = move_end(st, axis, 2 * n, at, x, &before);
                if (m == UINT64_MAX)
                    return MEND_NO_MEMORY;
                moves += m;
                if (moves > budget)
                    return MEND_GAVE_UP;
            }
    }
    return MEND_DONE;
}

// Word w as its box's fat box has it now, if `moved` flags the box.
static inline uint64_t fresh_word(uint64_t w, const bpx_box *fat, int axis, const uint64_t *moved)
{
    uint32_t b = (uint32_t)w & BOX_MASK;
    return moved[b / 64] >> (b % 64) & 1 ? fat_word(&fat[b], axis, (w & MAX_BIT) != 0, b) : w;
}

// Many boxes left their fat boxes (or boxes were added): every changed box gets its new fat
// box at once, its endpoints take their new words where they are (found by where), and each
// list is mended by one pass of insertion sort. The pass skips the words already in order
// (one compare each for the words in order); a min and a max that swap may change their
// boxes' fat overlap: the pair is noted when overlap(new, new) differs from overlap(old, old).
//
// mend_list mends one axis's list: its budget is a third of the cycle's, and it gives up early
// when its first part projects far past that. The lists are independent: the three run on the
// workers at once (mend_all). While where is not made yet (since the last rebuild), the changed
// boxes' words are renewed as the pass reaches them (`moved` flags them), and where stays
// unmade: a million boxes at rest after a rebuild leave their fat boxes together ~60 cycles
// later, too many to mend, and indexing the lists first would add 45 ms to that give-up on 2
// threads (`bpx bench --backend sap --scene resting --sizes 1000000 --threads 2`).
static inline bpx_sap_mend_result mend_list_as(bpx_sap_state *st, uint32_t n, uint32_t changed,
                                               uint64_t budget, int axis, atomic_bool *stop,
                                               const uint64_t *moved, bool keep_where)
{
    const bpx_box *fat = st->a.fat, *prev = st->a.fat_prev;
    bpx_pair_list *changes = &st->axis_changes[axis];
    uint64_t *ends = st->a.ends[axis];
    uint32_t *where = st->a.where[axis];
    uint64_t moves = 0;
    budget /= 3;
    changes->count = 0;
    if (keep_where) {
        for (uint32_t c = 0; c < changed; c++) {
            uint32_t b = st->a.changed[c];
            ends[where[2 * b]] = fat_word(&fat[b], axis, false, b);
            ends[where[2 * b + 1]] = fat_word(&fat[b], axis, true, b);
        }
    } else if (n > 0) {
        ends[0] = fresh_word(ends[0], fat, axis, moved);
    }
    uint32_t check = CHECK_EVERY;
    for (uint32_t k = 1; k < 2 * n; k++) {
        if (!keep_where) // each word as the pass reaches it, so that a give-up comes early
            ends[k] = fresh_word(ends[k], fat, axis, moved);
        if (ends[k - 1] < ends[k])
            continue;
        uint64_t x = ends[k];
        uint32_t b = (uint32_t)x & BOX_MASK, at = k;
        do {
            uint64_t past = ends[at - 1];
            uint32_t other = (uint32_t)past & BOX_MASK;
            if (((past ^ x) & MAX_BIT) && other != b &&
                overlap(&fat[b], &fat[other]) != overlap(&prev[b], &prev[other]) &&
                !push(changes, ordered(b, other)))
                return MEND_NO_MEMORY;
            ends[at] = past;
            if (keep_where)
                where[end_slot(past)] = at;
            at--;
        } while (at > 0 && ends[at - 1] > x);
        ends[at] = x;
        if (keep_where)
            where[end_slot(x)] = at;
        moves += k - at;
        if (moves > budget)
            return MEND_GAVE_UP;
        if (k >= check) { // projected over the list: far past its budget
            if (atomic_load_explicit(stop, memory_order_relaxed) ||
                moves * (uint64_t)n * 2 / k > 2 * budget)
                return MEND_GAVE_UP;
            check = k + CHECK_EVERY;
        }
    }
    return MEND_DONE;
}

static bpx_sap_mend_result mend_list(bpx_sap_state *st, uint32_t n, uint32_t changed,
                                     uint64_t budget, int axis, atomic_bool *stop,
                                     const uint64_t *moved)
{
    return st->indexed ? mend_list_as(st, n, changed, budget, axis, stop, moved, true)
                       : mend_list_as(st, n, changed, budget, axis, stop, moved, false);
}

static void mend_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    for (int axis = begin; axis < end; axis++) {
        bpx_sap_mend_result r = MEND_GAVE_UP;
        if (!atomic_load_explicit(&job->stop, memory_order_relaxed))
            r = mend_list(job->st, job->n, job->changed, job->budget, axis, &job->stop,
                          job->moved);
        if (r != MEND_DONE)
            atomic_store_explicit(&job->stop, true, memory_order_relaxed);
        job->result[axis] = r;
    }
}

static bpx_sap_mend_result mend_all(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n,
                                    uint32_t changed, uint64_t budget)
{
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        st->a.fat[b] = fatten(&st->a.cur[b], st->margin);
    }
    uint64_t *moved = NULL; // without where: the changed boxes as bits (in a rebuild's array)
    if (!st->indexed) {
        moved = st->a.words[1];
        memset(moved, 0, ((size_t)n + 63) / 64 * sizeof *moved);
        for (uint32_t c = 0; c < changed; c++)
            moved[st->a.changed[c] / 64] |= UINT64_C(1) << (st->a.changed[c] % 64);
    }
    bpx_sap_job job = {.st = st, .n = n, .changed = changed, .budget = budget, .moved = moved};
    atomic_init(&job.stop, false);
    if (n >= PARALLEL_MIN && cycle->executor->worker_count > 1)
        bpx__parallel_for(cycle->executor, mend_task, 3, &job);
    else
        mend_task(0, 3, 0, &job);
    bpx_sap_mend_result r = MEND_DONE; // running out of memory outranks giving up
    size_t noted = 0;
    for (int axis = 0; axis < 3; axis++) {
        if (job.result[axis] == MEND_NO_MEMORY || (job.result[axis] == MEND_GAVE_UP && r == MEND_DONE))
            r = job.result[axis];
        noted += st->axis_changes[axis].count;
    }
    if (r != MEND_DONE)
        return r;
    if (!bpx__list_reserve(&st->changes, noted))
        return MEND_NO_MEMORY;
    for (int axis = 0; axis < 3; axis++) {
        const bpx_pair_list *from = &st->axis_changes[axis];
        if (from->count)
            memcpy(st->changes.pairs + st->changes.count, from->pairs,
                   from->count * sizeof(bpx_pair));
        st->changes.count += from->count;
    }
    return MEND_DONE;
}

// fat_pairs after the changes: each pair noted is in the new list iff the fat boxes overlap now,
// whether or not it was in the old one.
static void merge_changes(bpx_sap_state *st)
{
    const bpx_pair *old = st->fat_pairs.pairs, *maybe = st->changes.pairs;
    size_t old_count = st->fat_pairs.count, maybe_count = st->changes.count;
    const bpx_box *fat = st->a.fat;
    bpx_pair *out = st->merged.pairs;
    size_t o = 0, m = 0, count = 0;
    while (m < maybe_count) {
        uint64_t p = pair_word(maybe[m]);
        while (o < old_count && pair_word(old[o]) < p)
            out[count++] = old[o++];
        if (o < old_count && pair_word(old[o]) == p)
            o++;
        if (overlap(&fat[maybe[m].i], &fat[maybe[m].j]))
            out[count++] = maybe[m];
        m++;
    }
    if (o < old_count)
        memcpy(out + count, old + o, (old_count - o) * sizeof(bpx_pair));
    st->merged.count = count + (old_count - o);
}

// The warm cycle into st->fat_pairs. MEND_GAVE_UP: too many moves (or an inconsistency); the
// caller rebuilds. On MEND_NO_MEMORY the state is invalid (the caller marks it so).
bpx_sap_mend_result bpx__sap_warm_cycle(const bpx_cycle *cycle, bpx_sap_state *st)
{
    uint32_t n = cycle->n;
    bool grown = n > st->n;
    uint64_t budget =
        (uint64_t)MOVES_PER_BOX * n / (n > CACHED_BOXES ? UNCACHED_DIVISOR : 1) + MOVES_BASE;
    uint32_t live;
    if (grown && !st->listed) {
        // A new box enters a list at its two ends and its words travel about 2n places: past
        // the one-pass mend's third of the budget, a rebuild untried. Else the lists first.
        if ((double)(n - st->n) * 2.0 * st->n > (double)budget / 3) {
            st->counters.untried++;
            return MEND_GAVE_UP;
        }
        if (!bpx__sap_make_lists(cycle, st, st->n, &live))
            return MEND_NO_MEMORY;
    }
    if (grown) {
        bpx__sap_append_boxes(st, st->n, n);
        st->indexed = true;
    }
    uint32_t changed = bpx__sap_check_boxes(cycle, st);
    st->checked = true;
    if (st->scan && grown) { // the new boxes enter the scan list as inert, at its end
        int order[3];
        scan_order(st->sweep_axis, order);
        for (uint32_t i = st->n; i < n; i++)
            scan_put(&st->a, i, &st->a.fat[i], order, i);
        bpx__sap_scan_pad(&st->a, n, order);
    }
    if (changed > 0 && !st->listed) {
        // The lists for this mend (see bpx__sap_make_lists), unless even the fewest moves
        // expected put it past the budget (the three lists' moves together are at least that,
        // so one of them would pass its third in the one-pass mend): then a rebuild untried.
        if ((double)changed * st->least_moves > (double)budget) {
            st->counters.untried++;
            return MEND_GAVE_UP;
        }
        if (!bpx__sap_make_lists(cycle, st, n, &live))
            return MEND_NO_MEMORY;
    }
    st->changes.count = 0;
    bpx_sap_mend_result r = MEND_DONE;
    uint64_t t = bpx__profile_clock(cycle->profile);
    if (st->scan) {
        if (changed > 0)
            r = bpx__sap_mend_scan(cycle, st, n, changed);
    } else if (grown || changed > n / FEW_DIVISOR + FEW_BASE) {
        r = mend_all(cycle, st, n, changed, budget);
    } else if (changed > 0) {
        if (!st->indexed) {
            bpx__sap_index_lists(cycle, st, n);
            st->indexed = true;
        }
        r = mend_few(st, n, changed, budget);
    }
    // Bytes: the one-pass mend reads and writes every list once (16 bytes a box each); the
    // others move few words, counted as the changed boxes' six endpoints.
    bool all = !st->scan && (grown || changed > n / FEW_DIVISOR + FEW_BASE);
    uint64_t moved = all ? 3 * 16 * (uint64_t)n : 6 * 8 * (uint64_t)changed;
    if (changed > 0 || grown) // else nothing was mended
        bpx__profile_add(cycle->profile, "sap", "mend", &t, BPX_ACCESS_SEQUENTIAL, moved, moved,
                         0);
    if (r != MEND_DONE)
        return r;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = st->a.changed[c];
        st->a.fat_prev[b] = st->a.fat[b];
    }
    if (st->changes.count > 0) {
        if (!sort_unique(st, &st->changes))
            return MEND_NO_MEMORY;
        st->merged.count = 0;
        if (!bpx__list_reserve(&st->merged, st->fat_pairs.count + st->changes.count))
            return MEND_NO_MEMORY;
        merge_changes(st);
        bpx_pair_list swap = st->fat_pairs;
        st->fat_pairs = st->merged;
        st->merged = swap;
        // The changes sorted, then merged with the fat pairs into a new list.
        uint64_t k = st->changes.count, f = st->fat_pairs.count;
        bpx__profile_add(cycle->profile, "sap", "merge", &t, BPX_ACCESS_SEQUENTIAL,
                         8 * (k + f), 8 * f, 0);
    }
    return MEND_DONE;
}
