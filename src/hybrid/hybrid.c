// The hybrid backend: the CPU and a device share one cycle (the paper's future work).
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
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/alloc.h"
#include "core/clock.h"
#include "core/log.h"
#include "core/validate.h"
#include "core/world.h"

enum {
    SAMPLES = 1024,         // centres sampled to place the cut
    BALANCED_MIN_N = 20000, // below it, a measured split sends everything to the CPU
};

typedef struct side {
    bpx_world *world;
    bpx_box *boxes;
    uint32_t *ids; // world id of each box, ascending
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

static void hybrid_destroy(bpx_world *w)
{
    hybrid *h = w->backend_state;
    if (!h)
        return;
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
    }
    bpx__free(h, sizeof *h);
    w->backend_state = NULL;
}

static bpx_status make_state(bpx_world *w, hybrid **out)
{
    hybrid *h = bpx__alloc(sizeof *h);
    if (!h)
        return BPX_ERR_OUT_OF_MEMORY;
    memset(h, 0, sizeof *h);
    pthread_mutex_init(&h->lock, NULL);
    pthread_cond_init(&h->wake, NULL);
    h->share = w->def.hybrid_device_share > 0 ? w->def.hybrid_device_share : 0.5f;
    w->backend_state = h;
    bpx_world_def cpu = w->def;
    cpu.backend = BPX_BACKEND_AUTO;
    cpu.track_events = false;
    bpx_status s = bpx_world_create(&cpu, &h->cpu.world);
    if (s == BPX_OK && pthread_create(&h->thread, NULL, device_thread, h) != 0)
        s = BPX_ERR_OUT_OF_MEMORY;
    h->started = s == BPX_OK;
    if (s != BPX_OK) {
        hybrid_destroy(w);
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
    if (!boxes || !ids) {
        bpx__free(boxes, sizeof(bpx_box) * capacity);
        bpx__free(ids, sizeof(uint32_t) * capacity);
        return false;
    }
    bpx__free(s->boxes, sizeof(bpx_box) * s->capacity);
    bpx__free(s->ids, sizeof(uint32_t) * s->capacity);
    s->boxes = boxes;
    s->ids = ids;
    s->capacity = capacity;
    return true;
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
static bpx_status make_device_world(bpx_world *w, hybrid *h)
{
    bpx_world_def device = w->def;
    device.backend = device_backend();
    device.track_events = false;
    device.worker_count = 1; // the device does the work; its host side is light
    device.enqueue_task = NULL;
    device.finish_task = NULL;
    device.user_task_context = NULL;
    return bpx_world_create(&device, &h->device.world);
}

// Keeps one side's pairs whose corner is on its side, as world ids, appended to out in order.
static void keep(const side *s, bpx_soa soa, float cut, bool device, bpx_pair *out,
                 size_t *count)
{
    size_t m, kept = *count;
    const bpx_pair *pairs = bpx_world_pairs(s->world, &m);
    for (size_t k = 0; k < m; k++) {
        uint32_t a = s->ids[pairs[k].i], b = s->ids[pairs[k].j];
        float corner = soa.lo[0][a] > soa.lo[0][b] ? soa.lo[0][a] : soa.lo[0][b];
        if ((corner >= cut) == device)
            out[kept++] = (bpx_pair){a, b};
    }
    *count = kept;
}

static bpx_status hybrid_compare(bpx_world *w)
{
    hybrid *h = w->backend_state;
    bpx_status s = BPX_OK;
    if (!h && (s = make_state(w, &h)) != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "hybrid: could not make its cpu world: %s",
                          bpx_status_string(s));
    bpx_block *block;
    if ((s = bpx__emitter_one_block(w, &block)) != BPX_OK)
        return s;

    // Split: each box to the side(s) it reaches.
    bpx_soa soa = bpx__world_soa(w);
    bool fixed = w->def.hybrid_device_share > 0;
    float share = fixed ? w->def.hybrid_device_share : soa.n < BALANCED_MIN_N ? 0.0f : h->share;
    float cut = place_cut(h, soa, share);
    if (!reserve(&h->cpu, soa.n) || !reserve(&h->device, soa.n))
        return BPX_ERR_OUT_OF_MEMORY;
    h->cpu.n = h->device.n = 0;
    for (uint32_t i = 0; i < soa.n; i++) {
        if (!(soa.lo[0][i] <= soa.hi[0][i]))
            continue; // a removed id's inert box
        bpx_box box = {{soa.lo[0][i], soa.lo[1][i], soa.lo[2][i]},
                       {soa.hi[0][i], soa.hi[1][i], soa.hi[2][i]}};
        if (box.min[0] < cut) {
            h->cpu.boxes[h->cpu.n] = box;
            h->cpu.ids[h->cpu.n++] = i;
        }
        if (box.max[0] >= cut) {
            h->device.boxes[h->device.n] = box;
            h->device.ids[h->device.n++] = i;
        }
    }

    // Both sides at once; the device's only when it has boxes (no launch for nothing).
    bool device_runs = h->device.n > 0;
    if (device_runs && !h->device.world && (s = make_device_world(w, h)) != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "hybrid: could not open the device: %s",
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

    // The corner rule, then one merge of the two ordered lists into the block.
    size_t cpu_found, device_found = 0;
    bpx_world_pairs(h->cpu.world, &cpu_found);
    if (device_runs)
        bpx_world_pairs(h->device.world, &device_found);
    bpx_pair_list *lists[2] = {&block->stage, &block->hits};
    if (!bpx__list_reserve(lists[0], cpu_found + device_found) ||
        !bpx__list_reserve(lists[1], cpu_found + device_found))
        return BPX_ERR_OUT_OF_MEMORY;
    size_t from_cpu = 0, total = 0;
    keep(&h->cpu, soa, cut, false, lists[0]->pairs, &from_cpu);
    size_t from_device = from_cpu;
    if (device_runs)
        keep(&h->device, soa, cut, true, lists[0]->pairs, &from_device);
    const bpx_pair *a = lists[0]->pairs, *b = lists[0]->pairs + from_cpu;
    size_t na = from_cpu, nb = from_device - from_cpu, i = 0, j = 0;
    bpx_pair *out = lists[1]->pairs;
    while (i < na && j < nb)
        out[total++] = bpx__pair_less(b[j], a[i]) ? b[j++] : a[i++];
    while (i < na)
        out[total++] = a[i++];
    while (j < nb)
        out[total++] = b[j++];
    block->hits.count = total;
    block->tests = bpx_world_stats(h->cpu.world).pair_tests +
                   (device_runs ? bpx_world_stats(h->device.world).pair_tests : 0);

    // What the device did, and the next cycle's share from both sides' measured speed.
    bpx_cycle_stats ds = bpx_world_stats(h->device.world);
    w->stats.transfer_in_ns = device_runs ? ds.transfer_in_ns : 0;
    w->stats.transfer_out_ns = device_runs ? ds.transfer_out_ns : 0;
    w->stats.device_ns = device_runs ? ds.device_ns : 0;
    w->stats.bytes_in = device_runs ? ds.bytes_in : 0;
    w->stats.bytes_out = device_runs ? ds.bytes_out : 0;
    w->stats.device_share = soa.n ? (float)h->device.n / (float)soa.n : 0.0f;
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
