// The hybrid backend: the CPU and a device share one cycle (the paper's future work). Paper
// modules: the emitter, joining the two sides' ordered streams; the comparators are two other
// backends', composed through the backend contract (core/backend.h): each side is a state slot,
// boxes of its own and a pair sink, and hybrid never looks inside either backend.
//
// Space is cut along x. The CPU (auto) gets the boxes that reach below the cut, the device (cuda
// where a GPU is usable, else opencl) those that reach above it, and both run at once: the
// device side on a thread of this backend's own, the CPU side on the caller's, with the world's
// workers. A pair is kept by
// the side that holds its corner (the larger of the two min x): x < cut on the CPU, else on
// the device. The corner lies in both boxes, so both reach that side, and no pair is found
// twice (the rule libbpx_mpi uses between ranks). Each side's pairs, mapped back to world ids
// in ascending order, are already in (i, j) order: one merge gives the cycle's list.
//
// The cut follows the measured speed: each cycle the device gets the share of the boxes (by
// centre x) that would have made both sides take equally long last cycle, smoothed.
//
// The split, the corner rule and the merge run on this world's own workers, in chunks that
// each know where their output goes (counted first, then written): beside a GPU that takes a
// few milliseconds for a million boxes, they must not be a serial tail.
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "core/clock.h"
#include "core/log.h"
#include "core/validate.h"
#include "parallel/pool.h"

enum {
    SAMPLES = 1024,         // centres sampled to place the cut
    BALANCED_MIN_N = 20000, // below it, a measured split sends everything to the CPU
    CHUNKS_MAX = 64,        // of the boxes, of each side's pairs, of the merged pairs
    CHUNK_MIN = 16384,      // items; fewer go to one chunk
};

// One side: a backend run through the contract on boxes of its own.
typedef struct side {
    const bpx_backend_impl *impl;
    void *state; // the backend's
    bpx_world_def def;
    bpx_executor executor; // the device side's: one worker (the device does the work)
    bpx_box_arrays boxes;  // SoA, padded
    uint32_t *ids;         // world id of each box, ascending
    uint32_t n, capacity;  // boxes; capacity of ids
    uint64_t version;      // of the side's boxes (a new set every cycle)
    bpx_emitter sink;
    bpx_pair_list pairs; // the sink's blocks joined
    bpx_error error;
    bpx_cycle cycle;
    uint64_t ns;
    bpx_status status;
} side;

typedef struct hybrid {
    side cpu, device;
    float share; // of the boxes given to the device, by centre x
    float sample[SAMPLES];
    pthread_t thread;
    pthread_mutex_t lock;
    pthread_cond_t wake;
    int job;  // 1: the device side has a cycle to run; 0: done
    bool quit, started;
} hybrid;

static bpx_backend device_backend(void)
{
    if (bpx_backend_query(BPX_BACKEND_CUDA).available)
        return BPX_BACKEND_CUDA;
    if (bpx_backend_query(BPX_BACKEND_OPENCL).available)
        return BPX_BACKEND_OPENCL;
    return BPX_BACKEND_COUNT;
}

static const bpx_backend_impl *device_impl(bpx_backend id)
{
#if BPX_HAVE_CUDA
    if (id == BPX_BACKEND_CUDA)
        return &bpx__cuda_backend;
#endif
#if BPX_HAVE_OPENCL
    if (id == BPX_BACKEND_OPENCL)
        return &bpx__opencl_backend;
#endif
    (void)id;
    return NULL;
}

static bool hybrid_query(const bpx_world_def *def, const char **reason, char *detail,
                         size_t size)
{
    (void)def;
    bpx_backend device = device_backend();
    if (device == BPX_BACKEND_COUNT) {
        *reason = "needs a device: neither the cuda nor the opencl backend is usable here";
        return false;
    }
    snprintf(detail, size, "cpu + %s", bpx_backend_name(device));
    return true;
}

// The side's cycle, then its pairs joined into one ordered list.
static void run_side(side *s)
{
    uint64_t start = bpx__now_ns();
    bpx__error_clear(&s->error);
    bpx_status status = s->impl->compare(&s->state, &s->cycle);
    size_t total = 0;
    if (status == BPX_OK)
        status = bpx__emitter_total(&s->sink, &total);
    s->pairs.count = 0;
    if (status == BPX_OK && !bpx__list_reserve(&s->pairs, total))
        status = BPX_ERR_OUT_OF_MEMORY;
    if (status == BPX_OK) {
        bpx__emitter_merge(&s->sink, s->pairs.pairs);
        s->pairs.count = total;
    }
    if (status == BPX_ERR_OUT_OF_MEMORY || status == BPX_ERR_TOO_MANY_PAIRS) {
        bpx__emitter_release(&s->sink); // as the world does: a cycle too big leaves none held
        bpx__list_free(&s->pairs);
    }
    if (status != BPX_OK && s->error.status != status)
        bpx__error(&s->error, status, UINT32_MAX, -1, "%s", bpx_status_string(status));
    s->status = status;
    s->ns = bpx__now_ns() - start;
}

static void side_free(side *s)
{
    if (s->state && s->impl && s->impl->destroy)
        s->impl->destroy(s->state);
    bpx__emitter_free(&s->sink);
    bpx__list_free(&s->pairs);
    bpx__box_arrays_free(&s->boxes);
    bpx__free(s->ids, sizeof(uint32_t) * s->capacity);
}

static void *device_thread(void *arg)
{
    hybrid *h = arg;
    pthread_mutex_lock(&h->lock);
    for (;;) {
        while (!h->job && !h->quit)
            pthread_cond_wait(&h->wake, &h->lock);
        if (h->quit)
            break;
        pthread_mutex_unlock(&h->lock);
        run_side(&h->device);
        pthread_mutex_lock(&h->lock);
        h->job = 0;
        pthread_cond_broadcast(&h->wake);
    }
    pthread_mutex_unlock(&h->lock);
    return NULL;
}

static void hybrid_destroy(void *state)
{
    hybrid *h = state;
    if (h->started) {
        pthread_mutex_lock(&h->lock);
        h->quit = true;
        pthread_cond_broadcast(&h->wake);
        pthread_mutex_unlock(&h->lock);
        pthread_join(h->thread, NULL);
    }
    pthread_cond_destroy(&h->wake);
    pthread_mutex_destroy(&h->lock);
    side_free(&h->cpu);
    side_free(&h->device);
    bpx__free(h, sizeof *h);
}

static bpx_status make_state(const bpx_world_def *def, hybrid **out)
{
    hybrid *h = bpx__alloc(sizeof *h);
    if (!h)
        return BPX_ERR_OUT_OF_MEMORY;
    memset(h, 0, sizeof *h);
    pthread_mutex_init(&h->lock, NULL);
    pthread_cond_init(&h->wake, NULL);
    h->share = def->hybrid_device_share > 0 ? def->hybrid_device_share : 0.5f;
    // The cpu side: auto on the world's workers. The device side: its backend, made when the
    // device first gets boxes, so that a world that stays small never opens the device.
    h->cpu.impl = &bpx__auto_backend;
    h->cpu.def = *def;
    h->cpu.def.backend = BPX_BACKEND_AUTO;
    h->device.def = *def;
    h->device.def.backend = device_backend();
    h->device.def.worker_count = 1;
    h->device.def.enqueue_task = NULL;
    h->device.def.finish_task = NULL;
    h->device.def.user_task_context = NULL;
    h->device.impl = device_impl(h->device.def.backend);
    h->device.executor = (bpx_executor){.worker_count = 1};
    side *sides[2] = {&h->cpu, &h->device};
    for (int k = 0; k < 2; k++) {
        sides[k]->sink.planned_n = UINT32_MAX;
        bpx__error_clear(&sides[k]->error);
    }
    if (!h->device.impl || pthread_create(&h->thread, NULL, device_thread, h) != 0) {
        hybrid_destroy(h);
        return BPX_ERR_OUT_OF_MEMORY;
    }
    h->started = true;
    *out = h;
    return BPX_OK;
}

// Room for n boxes on a side (at most every box goes to one side).
static bool reserve(side *s, uint32_t n)
{
    if (n <= s->capacity && s->ids)
        return true;
    uint32_t capacity = n + n / 2 + 64;
    if (capacity < n) // past 2^32
        capacity = n;
    uint32_t *ids = bpx__alloc(sizeof(uint32_t) * capacity);
    if (!ids || !bpx__box_arrays_reserve(&s->boxes, capacity)) {
        bpx__free(ids, sizeof(uint32_t) * capacity);
        return false;
    }
    bpx__free(s->ids, sizeof(uint32_t) * s->capacity);
    s->ids = ids;
    s->capacity = capacity;
    return true;
}

// The side's view of its cycle: its boxes (padded), the world's SIMD width.
static void prepare_cycle(side *s, bpx_simd simd, const bpx_executor *executor)
{
    bpx__box_arrays_pad(&s->boxes, s->n);
    const bpx_box_arrays *b = &s->boxes;
    s->cycle = (bpx_cycle){
        .boxes = {{b->lo[0], b->lo[1], b->lo[2]}, {b->hi[0], b->hi[1], b->hi[2]}, s->n},
        .n = s->n,
        .boxes_version = ++s->version,
        .def = &s->def,
        .simd = simd,
        .executor = executor,
        .sink = &s->sink,
        .error = &s->error,
    };
}

// ---------------------------------------------------------------------------------------------
// The cycle's own work, in chunks on the world's workers

typedef struct chunked {
    hybrid *h;
    bpx_soa soa;
    float cut;
    size_t per_chunk[3]; // items per chunk: boxes, a side's pairs (each side), merged pairs
    int chunks[2];       // of the cpu's pairs, of the device's
    // Per chunk: what it counted, then (after the prefix sums) where its output starts.
    size_t cpu_at[CHUNKS_MAX + 1], device_at[CHUNKS_MAX + 1], kept_at[2 * CHUNKS_MAX + 1];
    const bpx_pair *found[2]; // each side's pairs, in its local ids
    size_t found_count[2];
    bpx_pair *kept;           // the cpu's kept pairs, then the device's, as world ids
    size_t kept_count[2];
    bpx_pair *merged;
    bool write;               // the counting pass, or the writing pass
} chunked;

static int chunks_for(const bpx_cycle *c, size_t items)
{
    size_t chunks = items / CHUNK_MIN;
    if (chunks > CHUNKS_MAX)
        chunks = CHUNKS_MAX;
    return c->def->worker_count > 1 && chunks > 1 ? (int)chunks : 1;
}

static void run_chunks(const bpx_cycle *c, bpx_task_fn *task, int chunks, chunked *job)
{
    if (chunks == 1)
        task(0, 1, 0, job);
    else
        bpx__parallel_for(c->executor, task, chunks, job);
}

// Turns per-chunk counts in at[0 .. chunks) into where each chunk starts; at[chunks]: the total.
static void starts(size_t *at, int chunks)
{
    size_t sum = 0;
    for (int c = 0; c <= chunks; c++) {
        size_t count = c < chunks ? at[c] : 0;
        at[c] = sum;
        sum += count;
    }
}

// Each box to the side(s) it reaches: the cpu below the cut, the device from it on.
static void split_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    chunked *job = context;
    bpx_soa soa = job->soa;
    side *cpu = &job->h->cpu, *device = &job->h->device;
    for (int c = begin; c < end; c++) {
        uint32_t first = (uint32_t)(c * job->per_chunk[0]);
        uint32_t last = (uint32_t)((c + 1) * job->per_chunk[0]);
        if (last > soa.n)
            last = soa.n;
        size_t to_cpu = job->write ? job->cpu_at[c] : 0;
        size_t to_device = job->write ? job->device_at[c] : 0;
        for (uint32_t i = first; i < last; i++) {
            if (!(soa.lo[0][i] <= soa.hi[0][i]))
                continue; // a removed id's inert box
            bool below = soa.lo[0][i] < job->cut, above = soa.hi[0][i] >= job->cut;
            if (job->write) {
                side *sides[2] = {below ? cpu : NULL, above ? device : NULL};
                size_t *to[2] = {&to_cpu, &to_device};
                for (int k = 0; k < 2; k++)
                    if (sides[k]) {
                        size_t at = (*to[k])++;
                        for (int a = 0; a < 3; a++) {
                            sides[k]->boxes.lo[a][at] = soa.lo[a][i];
                            sides[k]->boxes.hi[a][at] = soa.hi[a][i];
                        }
                        sides[k]->ids[at] = i;
                    }
            } else {
                to_cpu += below;
                to_device += above;
            }
        }
        if (!job->write) {
            job->cpu_at[c] = to_cpu;
            job->device_at[c] = to_device;
        }
    }
}

// The corner rule over a chunk of one side's pairs: the pairs whose corner (the larger min x)
// is on this side, mapped to world ids (ascending with the local ones, so still in order).
static void keep_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    chunked *job = context;
    for (int c = begin; c < end; c++) {
        int k = c < job->chunks[0] ? 0 : 1, chunk = k == 0 ? c : c - job->chunks[0];
        const side *s = k == 0 ? &job->h->cpu : &job->h->device;
        size_t first = chunk * job->per_chunk[1 + k], last = first + job->per_chunk[1 + k];
        if (last > job->found_count[k])
            last = job->found_count[k];
        const bpx_pair *pairs = job->found[k];
        size_t kept = 0, at = job->write ? job->kept_at[c] : 0;
        for (size_t p = first; p < last; p++) {
            uint32_t i = pairs[p].i, j = pairs[p].j;
            const float *lo_x = s->boxes.lo[0];
            float corner = lo_x[i] > lo_x[j] ? lo_x[i] : lo_x[j];
            if ((corner >= job->cut) != (k == 1))
                continue;
            if (job->write)
                job->kept[at++] = (bpx_pair){s->ids[i], s->ids[j]};
            kept++;
        }
        if (!job->write)
            job->kept_at[c] = kept;
    }
}

// How many of the first d merged pairs come from a (the rest from b): both ascending, no pair
// in both (each is kept by one side).
static size_t co_rank(size_t d, const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb)
{
    size_t lo = d > nb ? d - nb : 0, hi = d < na ? d : na;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (bpx__pair_less(a[mid], b[d - mid - 1]))
            lo = mid + 1; // a[mid] is among the first d
        else
            hi = mid;
    }
    return lo;
}

// One chunk of the merged list: its start on each side by co-rank, then a plain merge.
static void merge_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    chunked *job = context;
    const bpx_pair *a = job->kept, *b = job->kept + job->kept_count[0];
    size_t na = job->kept_count[0], nb = job->kept_count[1], total = na + nb;
    for (int c = begin; c < end; c++) {
        size_t d0 = c * job->per_chunk[2], d1 = d0 + job->per_chunk[2];
        if (d1 > total)
            d1 = total;
        if (d0 >= d1)
            continue;
        size_t i = co_rank(d0, a, na, b, nb), j = d0 - i;
        size_t i_end = co_rank(d1, a, na, b, nb), j_end = d1 - i_end;
        bpx_pair *out = job->merged + d0;
        while (i < i_end && j < j_end)
            *out++ = bpx__pair_less(b[j], a[i]) ? b[j++] : a[i++];
        while (i < i_end)
            *out++ = a[i++];
        while (j < j_end)
            *out++ = b[j++];
    }
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

// The cut that gives the device about `share` of the boxes: a quantile of sampled centres.
static float place_cut(hybrid *h, bpx_soa soa, float share)
{
    if (share <= 0.0f)
        return INFINITY;
    uint32_t m = 0, step = soa.n / SAMPLES + 1;
    for (uint32_t i = 0; i < soa.n && m < SAMPLES; i += step)
        if (soa.lo[0][i] <= soa.hi[0][i]) // removed ids hold inert boxes (min > max)
            h->sample[m++] = 0.5f * soa.lo[0][i] + 0.5f * soa.hi[0][i];
    if (m == 0)
        return INFINITY;
    if (share >= 1.0f)
        return -INFINITY;
    qsort(h->sample, m, sizeof(float), compare_floats);
    uint32_t k = (uint32_t)((1.0f - share) * (float)m);
    return h->sample[k < m ? k : m - 1];
}

static bpx_status hybrid_compare(void **state, bpx_cycle *c)
{
    hybrid *h = *state;
    bpx_status s = BPX_OK;
    if (!h && !device_impl(device_backend()))
        return bpx__error(c->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "hybrid: neither the cuda nor the opencl backend is usable here");
    if (!h && (s = make_state(c->def, &h)) != BPX_OK)
        return bpx__error(c->error, s, UINT32_MAX, -1, "hybrid: could not start: %s",
                          bpx_status_string(s));
    *state = h;
    bpx_block *block;
    if ((s = bpx__emitter_one_block(c->sink, c->n, &block)) != BPX_OK)
        return s;

    // Split: each box to the side(s) it reaches, in id order on each side.
    bpx_soa soa = c->boxes;
    bool fixed = c->def->hybrid_device_share > 0;
    float share = fixed ? c->def->hybrid_device_share : soa.n < BALANCED_MIN_N ? 0.0f : h->share;
    chunked job = {.h = h, .soa = soa, .cut = place_cut(h, soa, share)};
    if (!reserve(&h->cpu, soa.n) || !reserve(&h->device, soa.n))
        return BPX_ERR_OUT_OF_MEMORY;
    int box_chunks = chunks_for(c, soa.n);
    job.per_chunk[0] = (soa.n + box_chunks - 1) / box_chunks;
    run_chunks(c, split_task, box_chunks, &job);
    starts(job.cpu_at, box_chunks);
    starts(job.device_at, box_chunks);
    job.write = true;
    run_chunks(c, split_task, box_chunks, &job);
    h->cpu.n = (uint32_t)job.cpu_at[box_chunks];
    h->device.n = (uint32_t)job.device_at[box_chunks];

    // Both sides at once; the device's only when it has boxes (no launch for nothing).
    bool device_runs = h->device.n > 0;
    prepare_cycle(&h->cpu, c->simd, c->executor);
    prepare_cycle(&h->device, c->simd, &h->device.executor);
    if (device_runs) {
        pthread_mutex_lock(&h->lock);
        h->job = 1;
        pthread_cond_broadcast(&h->wake);
        pthread_mutex_unlock(&h->lock);
    }
    run_side(&h->cpu);
    if (device_runs) {
        pthread_mutex_lock(&h->lock);
        while (h->job)
            pthread_cond_wait(&h->wake, &h->lock);
        pthread_mutex_unlock(&h->lock);
    } else {
        h->device.status = BPX_OK;
        h->device.ns = 0;
    }
    if (h->cpu.status != BPX_OK || h->device.status != BPX_OK) {
        const side *bad = h->cpu.status != BPX_OK ? &h->cpu : &h->device;
        const char *name = bad == &h->cpu ? "cpu" : "device";
        bpx__log(0, "hybrid: the %s side failed: %s", name, bad->error.message);
        return bpx__error(c->error, bad->status, UINT32_MAX, -1, "hybrid, %s side: %s", name,
                          bad->error.message);
    }

    // The corner rule over both sides' pairs, then one merge of the two ordered lists.
    job.write = false;
    job.found[0] = h->cpu.pairs.pairs;
    job.found_count[0] = h->cpu.pairs.count;
    job.found[1] = device_runs ? h->device.pairs.pairs : NULL;
    job.found_count[1] = device_runs ? h->device.pairs.count : 0;
    bpx_pair_list *lists[2] = {&block->stage, &block->hits};
    size_t found = job.found_count[0] + job.found_count[1];
    if (!bpx__list_reserve(lists[0], found) || !bpx__list_reserve(lists[1], found))
        return BPX_ERR_OUT_OF_MEMORY;
    for (int k = 0; k < 2; k++) {
        job.chunks[k] = chunks_for(c, job.found_count[k]);
        job.per_chunk[1 + k] = (job.found_count[k] + job.chunks[k] - 1) / job.chunks[k];
    }
    int keep_chunks = job.chunks[0] + job.chunks[1];
    run_chunks(c, keep_task, keep_chunks, &job);
    for (int k = 0; k < keep_chunks; k++)
        job.kept_count[k < job.chunks[0] ? 0 : 1] += job.kept_at[k];
    starts(job.kept_at, keep_chunks);
    job.kept = lists[0]->pairs;
    job.write = true;
    run_chunks(c, keep_task, keep_chunks, &job);
    size_t total = job.kept_count[0] + job.kept_count[1];
    int merge_chunks = chunks_for(c, total);
    job.per_chunk[2] = (total + merge_chunks - 1) / merge_chunks;
    job.merged = lists[1]->pairs;
    run_chunks(c, merge_task, merge_chunks, &job);
    block->hits.count = total;
    block->tests = 0;
    for (int k = 0; k < (device_runs ? 2 : 1); k++) {
        const bpx_emitter *sink = k == 0 ? &h->cpu.sink : &h->device.sink;
        for (int b = 0; b < sink->block_count; b++)
            block->tests += sink->blocks[b].tests;
    }

    // What the device did, and the next cycle's share from both sides' measured speed.
    const bpx_backend_report ds = h->device.cycle.report;
    c->report.transfer_in_ns = device_runs ? ds.transfer_in_ns : 0;
    c->report.transfer_out_ns = device_runs ? ds.transfer_out_ns : 0;
    c->report.device_ns = device_runs ? ds.device_ns : 0;
    c->report.bytes_in = device_runs ? ds.bytes_in : 0;
    c->report.bytes_out = device_runs ? ds.bytes_out : 0;
    c->report.device_share = soa.n ? (float)h->device.n / (float)soa.n : 0.0f;
    if (!fixed && h->cpu.n > 0 && device_runs && h->cpu.ns > 0 && h->device.ns > 0) {
        double cpu_rate = h->cpu.n / (double)h->cpu.ns;
        double device_rate = h->device.n / (double)h->device.ns;
        float target = (float)(device_rate / (cpu_rate + device_rate));
        float next = 0.5f * h->share + 0.5f * target;
        h->share = next < 0.02f ? 0.02f : next > 0.98f ? 0.98f : next;
    }
    return BPX_OK;
}

const bpx_backend_impl bpx__hybrid_backend = {
    .id = BPX_BACKEND_HYBRID,
    .name = "hybrid",
    .query = hybrid_query,
    .compare = hybrid_compare,
    .destroy = hybrid_destroy,
};
