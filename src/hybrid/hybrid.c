// The hybrid backend: the CPU and a device share one cycle (the paper's future work). Paper
// modules: the emitter, joining the two sides' ordered streams; the comparators are two worlds'.
//
// Space is cut along x. The CPU gets the boxes that reach below the cut, the device (cuda where
// a GPU is usable, else opencl) those that reach above it, and both run at once: the device
// world on a thread of this backend's own, the CPU world on the caller's. A pair is kept by
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

typedef struct side {
    bpx_world *world;
    bpx_box *boxes;
    uint32_t *ids; // world id of each box, ascending
    float *lo_x;   // each box's min x, for the corner rule
    uint32_t n, capacity;
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

static void run_side(side *s)
{
    uint64_t start = bpx__now_ns();
    s->status = bpx_world_set_boxes(s->world, s->boxes, s->n);
    if (s->status == BPX_OK)
        s->status = bpx_world_collide(s->world);
    s->ns = bpx__now_ns() - start;
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
    side *sides[2] = {&h->cpu, &h->device};
    for (int k = 0; k < 2; k++) {
        bpx_world_destroy(sides[k]->world);
        bpx__free(sides[k]->boxes, sizeof(bpx_box) * sides[k]->capacity);
        bpx__free(sides[k]->ids, sizeof(uint32_t) * sides[k]->capacity);
        bpx__free(sides[k]->lo_x, sizeof(float) * sides[k]->capacity);
    }
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
    bpx_world_def cpu = *def;
    cpu.backend = BPX_BACKEND_AUTO;
    cpu.track_events = false;
    bpx_status s = bpx_world_create(&cpu, &h->cpu.world);
    if (s == BPX_OK && pthread_create(&h->thread, NULL, device_thread, h) != 0)
        s = BPX_ERR_OUT_OF_MEMORY;
    h->started = s == BPX_OK;
    if (s != BPX_OK) {
        hybrid_destroy(h);
        return s;
    }
    *out = h;
    return BPX_OK;
}

static bool reserve(side *s, uint32_t n)
{
    if (n <= s->capacity)
        return true;
    uint32_t capacity = n + n / 2;
    bpx_box *boxes = bpx__alloc(sizeof(bpx_box) * capacity);
    uint32_t *ids = bpx__alloc(sizeof(uint32_t) * capacity);
    float *lo_x = bpx__alloc(sizeof(float) * capacity);
    if (!boxes || !ids || !lo_x) {
        bpx__free(boxes, sizeof(bpx_box) * capacity);
        bpx__free(ids, sizeof(uint32_t) * capacity);
        bpx__free(lo_x, sizeof(float) * capacity);
        return false;
    }
    bpx__free(s->boxes, sizeof(bpx_box) * s->capacity);
    bpx__free(s->ids, sizeof(uint32_t) * s->capacity);
    bpx__free(s->lo_x, sizeof(float) * s->capacity);
    s->boxes = boxes;
    s->ids = ids;
    s->lo_x = lo_x;
    s->capacity = capacity;
    return true;
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
                bpx_box box = {{soa.lo[0][i], soa.lo[1][i], soa.lo[2][i]},
                               {soa.hi[0][i], soa.hi[1][i], soa.hi[2][i]}};
                side *sides[2] = {below ? cpu : NULL, above ? device : NULL};
                size_t *to[2] = {&to_cpu, &to_device};
                for (int k = 0; k < 2; k++)
                    if (sides[k]) {
                        size_t at = (*to[k])++;
                        sides[k]->boxes[at] = box;
                        sides[k]->ids[at] = i;
                        sides[k]->lo_x[at] = box.min[0];
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
            float corner = s->lo_x[i] > s->lo_x[j] ? s->lo_x[i] : s->lo_x[j];
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

// The device's world, made when the device first gets boxes: a world that stays small never
// opens the device.
static bpx_status make_device_world(const bpx_world_def *def, hybrid *h)
{
    bpx_world_def device = *def;
    device.backend = device_backend();
    device.track_events = false;
    device.worker_count = 1; // the device does the work; its host side is light
    device.enqueue_task = NULL;
    device.finish_task = NULL;
    device.user_task_context = NULL;
    return bpx_world_create(&device, &h->device.world);
}

static bpx_status hybrid_compare(void **state, bpx_cycle *c)
{
    hybrid *h = *state;
    bpx_status s = BPX_OK;
    if (!h && (s = make_state(c->def, &h)) != BPX_OK)
        return bpx__error(c->error, s, UINT32_MAX, -1, "hybrid: could not make its cpu world: %s",
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
    if (device_runs && !h->device.world && (s = make_device_world(c->def, h)) != BPX_OK)
        return bpx__error(c->error, s, UINT32_MAX, -1, "hybrid: could not open the device: %s",
                          bpx_status_string(s));
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
        bpx__log(0, "hybrid: the %s side failed: %s", bad == &h->cpu ? "cpu" : "device",
                 bpx_world_error(bad->world)->message);
        return bad->status;
    }

    // The corner rule over both sides' pairs, then one merge of the two ordered lists.
    job.write = false;
    job.found[0] = bpx_world_pairs(h->cpu.world, &job.found_count[0]);
    job.found[1] = NULL;
    job.found_count[1] = 0;
    if (device_runs)
        job.found[1] = bpx_world_pairs(h->device.world, &job.found_count[1]);
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
    block->tests = bpx_world_stats(h->cpu.world).pair_tests +
                   (device_runs ? bpx_world_stats(h->device.world).pair_tests : 0);

    // What the device did, and the next cycle's share from both sides' measured speed.
    bpx_cycle_stats ds = bpx_world_stats(h->device.world);
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
