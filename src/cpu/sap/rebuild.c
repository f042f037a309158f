// sap's cold cycle.
//
// A cold cycle rebuilds: on the first cycle; when n shrank, or grew by more than an eighth;
// after a failed cycle; when a warm cycle passes MOVES_PER_BOX * n + MOVES_BASE element moves (a
// quarter of that past CACHED_BOXES; in the one-pass mend, a third of it per list, each abandoned
// part way, or early when its first part projects far past it, and the other lists stop too); and,
// after two such give-ups in a row, on every cycle but one in RETRY_EVERY, so that incoherent
// motion does not pay a wasted attempt each cycle. A full rebuild makes new fat boxes and margins,
// sorts each axis's 2n fat endpoint words with the radix sort of sort.c (minima listed before
// maxima; the sort is stable, so ties come out in word order), then sweeps the fat boxes once: the
// prune kernel, on the world's workers, in min order of the axis whose intervals overlap least
// (counted in O(n) from the sorted lists, so boxes that all share one x interval make the sweep
// quadratic only if y and z overlap as much); the emitter's counting sorts put the fat pairs in
// (i, j) order, and the exact filter gives the cycle's pairs. When even that axis meets more than
// BPX_SWEEP_MAX_CANDIDATES boxes per box (hundreds of thousands of boxes at constant density: the
// sweep's cost grows like n^(5/3)), the grid finds the fat pairs instead, so a rebuild at a
// million boxes costs a grid cycle, not seconds. The rebuilds after one that chose the grid keep
// the choice (while n stays within an eighth) and make no lists: the first warm cycle that must
// mend makes them, unless even the fewest moves expected put its mend past the budget (then it
// rebuilds untried, as does growth without lists). While the motion is incoherent (two give-ups in
// a row), a cycle not followed by an attempt only sorts the n minima of that axis and sweeps the
// boxes themselves (prune's work, no lists). bpx_cycle_stats.rebuilt tells warm and cold apart.
// There is no "boxes replaced wholesale" trigger: set_boxes is the general mode's per-cycle call,
// so a replaced scene is told from a moved one by the move budget alone, as prune does.

#include <math.h>
#include <string.h>

#include "sap_internal.h"

// Sweeps the `live` boxes of sorted_ids (ids in min order of `axis`), each as `boxes` has it,
// into block 0, in (i, j) order.
static bpx_status sweep(const bpx_cycle *cycle, bpx_sap_state *st, const bpx_box *boxes, int axis,
                        uint32_t live, const uint64_t *since)
{
    bpx_sap_arrays *a = &st->a;
    const int order[3] = {axis, axis == 0 ? 1 : 0, axis == 2 ? 1 : 2}; // slot 0: swept axis
    for (int s = 0; s < 3; s++) {
        float *slo = a->lo[s], *shi = a->hi[s];
        for (uint32_t k = 0; k < live; k++) {
            const bpx_box *box = &boxes[a->sorted_ids[k]];
            slo[k] = box->min[order[s]];
            shi[k] = box->max[order[s]];
        }
        for (uint32_t k = live; k < live + PAD; k++) {
            slo[k] = 1.0f / 0.0f;
            shi[k] = -1.0f / 0.0f;
        }
    }
    for (uint32_t k = live; k < live + PAD; k++)
        a->sorted_ids[k] = 0;

    int blocks = (int)((live + ROWS_PER_BLOCK - 1) / ROWS_PER_BLOCK);
    if (blocks < 1)
        blocks = 1;
    bpx_status status = bpx__emitter_own_blocks(cycle->sink, blocks);
    if (status != BPX_OK)
        return status;
    for (int k = 0; k < blocks; k++) {
        uint32_t begin = (uint32_t)k * ROWS_PER_BLOCK;
        cycle->sink->blocks[k].row_begin = begin;
        cycle->sink->blocks[k].row_end =
            live - begin < ROWS_PER_BLOCK ? live : begin + ROWS_PER_BLOCK;
    }
    bpx_profile *prof = cycle->profile;
    uint64_t t = 0;
    if (prof) { // the boxes in sweep order: a box fetched from anywhere per id
        t = *since;
        bpx__profile_add(prof, "sap", "gather", &t, BPX_ACCESS_GATHER, 4 * (uint64_t)live +
                         24 * (uint64_t)live, 24 * (uint64_t)live, live);
    }
    bpx_sorted sorted = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]},
                         a->sorted_ids, live};
    bpx__prune_sweep_blocks(cycle, &sorted, blocks);
    uint64_t hits = 0;
    for (int k = 0; prof && k < blocks; k++)
        hits += cycle->sink->blocks[k].hits.count;
    // The sorted boxes read once (more where a box meets many), a pair written per hit.
    bpx__profile_add(prof, "sap", "sweep", &t, BPX_ACCESS_SEQUENTIAL, 28 * (uint64_t)live,
                     8 * hits, 0);
    status = bpx__emitter_sort_blocks(cycle->sink, cycle->n, &st->merged, &st->spare, a->counts);
    // The hits gathered into one list, counted by i and scattered to their i's place (a
    // record each at random: the sweep finds them in sweep order), then each i's run put in j
    // order; the counts are n words.
    uint64_t n64 = cycle->n;
    bpx__profile_add(prof, "sap", "order", &t, BPX_ACCESS_SCATTER, 4 * 8 * hits + 8 * n64,
                     3 * 8 * hits + 4 * n64, hits);
    return status;
}

static void soa_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    bpx_sap_arrays *a = &job->st->a;
    for (int c = begin; c < end; c++)
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            for (int axis = 0; axis < 3; axis++) {
                a->lo[axis][i] = job->boxes[i].min[axis];
                a->hi[axis][i] = job->boxes[i].max[axis];
            }
}

// The pairs of `boxes` (all n, by id) by the grid, into block 0 in (i, j) order: for rebuilds
// where one axis's sweep would meet too many boxes per box (millions at constant density).
static bpx_status grid_pairs(const bpx_cycle *cycle, bpx_sap_state *st, const bpx_box *boxes)
{
    bpx_sap_arrays *a = &st->a;
    uint32_t n = cycle->n, padded = (n + PAD - 1) / PAD * PAD;
    bpx_sap_job job = {.st = st, .n = n, .chunks = bpx__sap_chunks_for(cycle, n), .boxes = boxes};
    uint64_t t = bpx__profile_clock(cycle->profile);
    if (job.chunks == 1)
        soa_task(0, 1, 0, &job);
    else
        bpx__parallel_for(cycle->executor, soa_task, (int)job.chunks, &job);
    for (int axis = 0; axis < 3; axis++)
        for (uint32_t i = n; i < padded; i++) {
            a->lo[axis][i] = 1.0f / 0.0f;
            a->hi[axis][i] = -1.0f / 0.0f;
        }
    // The boxes (AoS) copied into the grid's input (SoA).
    bpx__profile_add(cycle->profile, "sap", "soa", &t, BPX_ACCESS_SEQUENTIAL, 24 * (uint64_t)n,
                     24 * (uint64_t)padded, 0);
    bpx_soa soa = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]}, n};
    bpx__grid_forget(st->grid); // its last call may be long ago, on other boxes
    return bpx__grid_find(cycle, &st->grid, soa);
}

// What the margins need of a range of boxes: per axis, the live (non-inert) boxes, the sum of
// their extents and the bounds of their coordinates.
typedef struct margin_part {
    double sum[3];
    float low[3], high[3];
    uint32_t live[3];
} margin_part;

typedef struct margin_job {
    const bpx_box *cur;
    uint32_t n, chunks;
    margin_part part[CHUNKS_MAX];
} margin_job;

static void margin_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    margin_job *job = context;
    for (int c = begin; c < end; c++) {
        margin_part p = {{0.0, 0.0, 0.0},
                         {INFINITY, INFINITY, INFINITY},
                         {-INFINITY, -INFINITY, -INFINITY},
                         {0, 0, 0}};
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            for (int axis = 0; axis < 3; axis++) {
                const bpx_box *b = &job->cur[i];
                bool in = b->min[axis] <= b->max[axis]; // inert boxes are min > max
                p.sum[axis] += in ? (double)b->max[axis] - (double)b->min[axis] : 0.0;
                p.live[axis] += in;
                p.low[axis] = in && b->min[axis] < p.low[axis] ? b->min[axis] : p.low[axis];
                p.high[axis] = in && b->max[axis] > p.high[axis] ? b->max[axis] : p.high[axis];
            }
        job->part[c] = p;
    }
}

// The element that would be at `want` were v sorted (Hoare's selection: linear, in place); v
// holds no NaN.
static float select_at(float *v, int count, int want)
{
    int left = 0, right = count - 1;
    while (left < right) {
        float pivot = v[left + (right - left) / 2];
        int i = left, j = right;
        while (i <= j) {
            while (v[i] < pivot)
                i++;
            while (v[j] > pivot)
                j--;
            if (i <= j) {
                float t = v[i];
                v[i++] = v[j];
                v[j--] = t;
            }
        }
        if (want <= j) // [left, j] <= pivot <= [i, right]; between them, the pivot
            right = j;
        else if (want >= i)
            left = i;
        else
            return v[want];
    }
    return v[want];
}

// The upper quartile of the boxes' extents on `axis` that have one (not inert, not a point on
// that axis), over a sample of at most MARGIN_SAMPLE boxes: one from each of MARGIN_SAMPLE equal
// runs of indexes, at a place in the run that a hash of the run's number picks (so no regular
// layout of the boxes, points and boxes taking turns say, lines up with the sample). The places
// depend on n only: the same for any worker count. -1 when fewer than MARGIN_SAMPLE_MIN of the
// sampled boxes have an extent there.
static double sample_quartile(const bpx_box *cur, uint32_t n, int axis)
{
    float extent[MARGIN_SAMPLE];
    uint32_t taken = 0, runs = n < MARGIN_SAMPLE ? n : MARGIN_SAMPLE;
    for (uint32_t k = 0; k < runs; k++) {
        uint32_t first = (uint32_t)((uint64_t)k * n / runs);
        uint32_t length = (uint32_t)((uint64_t)(k + 1) * n / runs) - first;
        uint32_t i = first + (uint32_t)(((k + 1) * 2654435761u) >> 7) % length;
        float e = cur[i].max[axis] - cur[i].min[axis]; // inert boxes: min +inf > max -inf
        if (e > 0.0f)
            extent[taken++] = e;
    }
    if (taken < MARGIN_SAMPLE_MIN)
        return -1.0;
    return select_at(extent, (int)taken, (int)(taken * 3 / 4));
}

// The fat margins: on each axis, the (non-inert) boxes' mean extent / MARGIN_DIVISOR, but never
// wider than the upper quartile of the extents (sample_quartile) / MARGIN_QUARTILE_DIVISOR: a
// few boxes far larger than the rest (3% spanning the scene on one axis, say) would otherwise
// give every box a margin of their size, every pair of fat boxes would overlap, and the fat pairs
// would grow as n^2 (the denormal scene at 20,000 boxes: 6 GB and 10 s a cycle, at 40,000 out of
// memory; bounded, 21 MB and 0.04 s, and 132 MB and 0.5 s at 120,000; a bound of the whole
// quartile took 1 GB and 2.7 s there). The bound leaves the uniform, heavy-tailed, clustered and
// resting scenes as they were (their mean extent is about the quartile); it trims the
// mixed-size scene's margins by up to 1.8 times at a million boxes (its mean extent is 4 to 7
// quartiles). Point boxes (no extent) are not sampled, so a scene of mostly points keeps its
// margin. One pass
// for the three axes (a pass per axis would cost 12 ms more at a million boxes), in ranges on
// the workers that depend on n only, summed in order, so the margins are the same for any worker
// count. With them, the fewest endpoint moves a box that leaves its fat box is expected to cost:
// its two endpoints on the axis it left by, each past a margin's worth of the list at the list's
// mean density (denser clusters cost more, so this errs low), on the axis where that is least.
static void set_margins(const bpx_cycle *cycle, bpx_sap_state *st)
{
    margin_job job = {.cur = st->a.cur, .n = cycle->n, .chunks = cycle->n / PARALLEL_MIN + 1};
    job.chunks = job.chunks < CHUNKS_MAX ? job.chunks : CHUNKS_MAX;
    if (job.chunks > 1 && cycle->executor->worker_count > 1)
        bpx__parallel_for(cycle->executor, margin_task, (int)job.chunks, &job);
    else
        margin_task(0, (int)job.chunks, 0, &job);
    margin_part all = job.part[0];
    for (uint32_t c = 1; c < job.chunks; c++)
        for (int axis = 0; axis < 3; axis++) {
            const margin_part *p = &job.part[c];
            all.sum[axis] += p->sum[axis];
            all.live[axis] += p->live[axis];
            all.low[axis] = p->low[axis] < all.low[axis] ? p->low[axis] : all.low[axis];
            all.high[axis] = p->high[axis] > all.high[axis] ? p->high[axis] : all.high[axis];
        }
    double least = INFINITY;
    for (int axis = 0; axis < 3; axis++) {
        uint32_t live = all.live[axis];
        double mean = live ? all.sum[axis] / live : 0.0;
        double quartile = sample_quartile(st->a.cur, cycle->n, axis);
        double margin = mean / MARGIN_DIVISOR;
        if (quartile >= 0.0 && margin > quartile / MARGIN_QUARTILE_DIVISOR)
            margin = quartile / MARGIN_QUARTILE_DIVISOR;
        st->margin[axis] = margin < 1e30 ? (float)margin : 0.0f;
        double ends = 2.0 * live, span = (double)all.high[axis] - (double)all.low[axis];
        double passed = span > 0.0 ? fmin(ends, (double)st->margin[axis] * ends / span) : ends;
        least = fmin(least, 2.0 * passed);
    }
    st->least_moves = (float)least; // finite: boxes are, and at most 4n
}

static void fatten_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    bpx_sap_arrays *a = &job->st->a;
    for (int c = begin; c < end; c++)
        for (uint32_t i = chunk_begin(job->n, job->chunks, (uint32_t)c),
                      i1 = chunk_begin(job->n, job->chunks, (uint32_t)c + 1);
             i < i1; i++)
            a->fat[i] = a->fat_prev[i] = fatten(&a->cur[i], job->st->margin);
}

// Every box's new fat box (ranges on the workers).
static void fatten_all(const bpx_cycle *cycle, bpx_sap_state *st)
{
    bpx_sap_job job = {.st = st, .n = cycle->n, .chunks = bpx__sap_chunks_for(cycle, cycle->n)};
    if (job.chunks == 1)
        fatten_task(0, 1, 0, &job);
    else
        bpx__parallel_for(cycle->executor, fatten_task, (int)job.chunks, &job);
}

// Rebuilds the fat boxes, the lists (see bpx__sap_make_lists) and the fat pairs by one sweep or
// the grid (into st->fat_pairs), and the exact pairs into block 0.
bpx_status bpx__sap_full_rebuild(const bpx_cycle *cycle, bpx_sap_state *st)
{
    uint32_t n = cycle->n;
    bpx_sap_arrays *a = &st->a;
    if (!st->checked) // for cur (a warm attempt this cycle has made it)
        bpx__sap_check_boxes(cycle, st);
    uint64_t t = bpx__profile_clock(cycle->profile), n64 = n;
    set_margins(cycle, st);
    fatten_all(cycle, st);
    // The boxes read twice (margins, fat boxes), the fat boxes written twice (and the last).
    bpx__profile_add(cycle->profile, "sap", "fatten", &t, BPX_ACCESS_SEQUENTIAL, 48 * n64,
                     48 * n64, 0);
    uint32_t live = 0;
    st->listed = st->indexed = false;
    bool counted = st->use_grid && n - n / 8 <= st->counted_n && st->counted_n <= n + n / 8;
    if (!counted && !bpx__sap_make_lists(cycle, st, n, &live))
        return BPX_ERR_OUT_OF_MEMORY;
    int axis = st->sweep_axis;
    t = bpx__profile_clock(cycle->profile);
    if (!st->use_grid) {
        const uint64_t *ends = a->ends[axis];
        const uint32_t inf_key = coord_key(1.0f / 0.0f);
        uint32_t k = 0;
        for (size_t e = 0; e < 2 * (size_t)n; e++) // the minima of the live boxes, in order
            if (!(ends[e] & MAX_BIT) && (uint32_t)(ends[e] >> 32) != inf_key)
                a->sorted_ids[k++] = (uint32_t)ends[e] & BOX_MASK;
    }
    bpx_status status =
        st->use_grid ? grid_pairs(cycle, st, a->fat) : sweep(cycle, st, a->fat, axis, live, &t);
    if (status != BPX_OK)
        return status;
    // Few boxes of even extents on the swept axis: warm cycles scan (see bpx__sap_mend_scan).
    double sum = 0.0;
    float widest = 0.0f;
    if (!st->use_grid) // else a->lo and a->hi hold the grid's input, not the sweep order
        for (uint32_t k = 0; k < live; k++) {
            double e = (double)a->hi[0][k] - (double)a->lo[0][k];
            sum += e;
            widest = float_above(e) > widest ? float_above(e) : widest;
        }
    st->scan_width = widest;
    st->scan = !st->use_grid && n <= SCAN_MAX_BOXES &&
               (double)widest <= SCAN_WIDTH_RATIO * (live ? sum / live : 0.0);
    if (st->scan)
        bpx__sap_scan_list(st, n, live);

    // Keep the fat pairs, with room for the warm cycles to come; block 0 gets the exact ones.
    bpx_pair_list *found = &cycle->sink->blocks[0].hits;
    size_t room = found->count + found->count / 2 + FIRST_CHANGES;
    size_t changes = FIRST_CHANGES + n / 16;
    st->fat_pairs.count = st->changes.count = 0;
    if (!bpx__list_reserve(&st->fat_pairs, room) || !bpx__list_reserve(&st->merged, room) ||
        !bpx__list_reserve(&st->changes, changes) || !bpx__list_reserve(&st->spare, changes))
        return BPX_ERR_OUT_OF_MEMORY;
    for (int k = 0; k < 3; k++) {
        st->axis_changes[k].count = 0;
        if (!bpx__list_reserve(&st->axis_changes[k], changes))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    t = bpx__profile_clock(cycle->profile);
    if (found->count)
        memcpy(st->fat_pairs.pairs, found->pairs, found->count * sizeof(bpx_pair));
    st->fat_pairs.count = found->count;
    // The fat pairs kept for the warm cycles to come.
    bpx__profile_add(cycle->profile, "sap", "copy", &t, BPX_ACCESS_SEQUENTIAL,
                     8 * (uint64_t)found->count, 8 * (uint64_t)found->count, 0);
    found->count = bpx__sap_filter_pairs(cycle, st, found->pairs);
    return BPX_OK;
}

// The pairs by one sweep over the minima of the sweep axis the lists last chose, radix sorted
// (or by the grid, if they chose it); no endpoint lists (the next cycle will not mend).
bpx_status bpx__sap_rebuild_without_lists(const bpx_cycle *cycle, bpx_sap_state *st)
{
    uint32_t n = cycle->n;
    bpx_sap_arrays *a = &st->a;
    if (!bpx__sap_reserve_radix(st, 1, n))
        return BPX_ERR_OUT_OF_MEMORY;
    if (!st->checked) // for cur (a warm attempt this cycle has made it)
        bpx__sap_check_boxes(cycle, st);
    if (st->use_grid)
        return grid_pairs(cycle, st, a->cur);
    const uint32_t inf_key = coord_key(1.0f / 0.0f);
    uint64_t *words = a->words[0], *sorted = a->words[1];
    uint64_t t = bpx__profile_clock(cycle->profile), n64 = n;
    for (uint32_t i = 0; i < n; i++)
        words[i] = end_word(coord_key(a->cur[i].min[st->sweep_axis]), i);
    // Read: the boxes (AoS, a coordinate of each line); written: a word per box.
    bpx__profile_add(cycle->profile, "sap", "keys", &t, BPX_ACCESS_SEQUENTIAL, 24 * n64, 8 * n64,
                     0);
    bpx__radix_sort_words(words, sorted, n, st->radix[0]);
    bpx__profile_add(cycle->profile, "sap", "sort", &t, BPX_ACCESS_SEQUENTIAL, 3 * 8 * n64,
                     3 * 8 * n64, 0);
    uint32_t live = n;
    while (live > 0 && (uint32_t)(sorted[live - 1] >> 32) == inf_key) // inert: min +inf, last
        live--;
    for (uint32_t k = 0; k < live; k++)
        a->sorted_ids[k] = (uint32_t)sorted[k];
    return sweep(cycle, st, a->cur, st->sweep_axis, live, &t);
}
