// Determinism: the ordered pair list hashes the same for every backend, SIMD width, worker count
// (1, 2, 3, 8) and host task system (inline reversed, deferred to finish in shuffled chunks with
// varying worker ids, a 2-thread pool), and on repeated cycles of one world. `--opencl`: the
// opencl backend alone, each comparator path forced and auto; skipped (77) without a device.
#define _POSIX_C_SOURCE 200809L

#include <pthread.h>
#include <stdatomic.h>

#include "pairs_util.h"
#include "scenes.h"

typedef struct scene_case {
    scene_kind kind;
    uint32_t n;
    uint64_t seed;
    bpx_box *boxes;
    uint64_t hash;
    size_t count;
} scene_case;

static scene_case cases[] = {
    {SCENE_DENSE, 1234, 11, NULL, 0, 0},       {SCENE_DENSE, 5000, 12, NULL, 0, 0},
    {SCENE_TOUCHING, 1234, 13, NULL, 0, 0},    {SCENE_SHARED_COORD, 4099, 14, NULL, 0, 0},
    {SCENE_MIXED_SIZES, 1234, 15, NULL, 0, 0}, {SCENE_UNIFORM_DENSITY, 5000, 16, NULL, 0, 0},
    {SCENE_SIGNED_ZERO, 1000, 17, NULL, 0, 0}, {SCENE_DENORMAL, 1000, 18, NULL, 0, 0},
    {SCENE_ALL_OVERLAP, 33, 19, NULL, 0, 0},   {SCENE_SPARSE, 2, 20, NULL, 0, 0},
    // Within the rtl backend's limit (BPX_RTL_MAX_BOXES), which skips the others.
    {SCENE_DENSE, 512, 21, NULL, 0, 0},        {SCENE_TOUCHING, 300, 22, NULL, 0, 0},
};
enum { case_count = sizeof cases / sizeof cases[0] };

static const char *name_or(const char *s)
{
    return s ? s : "?";
}

// ---------------------------------------------------------------------------------------------
// Test task systems

typedef enum hook_mode {
    HOOKS_NONE,           // bpx's own threads
    HOOKS_INLINE_REVERSE, // enqueue runs every range inline, last range first, returns NULL
    HOOKS_DEFERRED,       // enqueue only records; finish runs shuffled random-size chunks
    HOOKS_POOL2,          // two pthreads take chunks from a shared queue
    HOOKS_MODE_COUNT
} hook_mode;

static const char *const hook_names[HOOKS_MODE_COUNT] = {"none", "inline-reverse", "deferred",
                                                         "pool2"};

typedef struct job {
    bpx_task_fn *task;
    void *task_context;
    int item_count;
    int chunk;
    int next; // first item not yet taken (pool)
    int done; // items finished (pool)
    struct job *link;
} job;

typedef struct task_system {
    hook_mode mode;
    int worker_count;
    scene_rng rng;
    // Pool state.
    pthread_mutex_t mutex;
    pthread_cond_t work;
    pthread_cond_t finished;
    job *queue;
    bool stop;
    pthread_t threads[2];
    // Misuse seen inside callbacks (CHECK is not thread-safe), checked on the main thread.
    atomic_int bad_calls;
    atomic_int enqueues;
    atomic_int pending;
} task_system;

static int chunk_for(int item_count, int min_range)
{
    int chunk = min_range > 1 ? min_range : 1;
    return chunk > item_count ? (item_count > 0 ? item_count : 1) : chunk;
}

// Ranges [b, e) of at least min_range (the last one absorbs the remainder).
static int split_ranges(int item_count, int min_range, scene_rng *rng, int *starts, int max)
{
    int count = 0;
    int pos = 0;
    int min = chunk_for(item_count, min_range);
    while (pos < item_count && count < max - 1) {
        starts[count++] = pos;
        int len = min + (rng ? (int)scene_rng_below(rng, (uint32_t)min * 3u + 1u) : 0);
        pos += len;
        if (item_count - pos < min) {
            pos = item_count;
        }
    }
    if (pos < item_count) {
        // Out of slots: one last range to the end.
        starts[count++] = pos;
    }
    starts[count] = item_count;
    return count;
}

static void run_job_shuffled(task_system *ts, job *j)
{
    enum { max_ranges = 4096 };
    int starts[max_ranges + 1];
    int order[max_ranges];
    int ranges = split_ranges(j->item_count, j->chunk, &ts->rng, starts, max_ranges);
    for (int r = 0; r < ranges; r++) {
        order[r] = r;
    }
    for (int r = ranges; r > 1; r--) {
        int k = (int)scene_rng_below(&ts->rng, (uint32_t)r);
        int t = order[r - 1];
        order[r - 1] = order[k];
        order[k] = t;
    }
    for (int r = 0; r < ranges; r++) {
        int w = (int)scene_rng_below(&ts->rng, (uint32_t)ts->worker_count);
        j->task(starts[order[r]], starts[order[r] + 1], w, j->task_context);
    }
}

static void *pool_thread(void *arg);

static void *test_enqueue(bpx_task_fn *task, int item_count, int min_range, void *task_context,
                          void *user_context)
{
    task_system *ts = user_context;
    atomic_fetch_add(&ts->enqueues, 1);
    if (!task || item_count < 0 || min_range < 0) {
        atomic_fetch_add(&ts->bad_calls, 1);
        return NULL;
    }
    if (ts->mode == HOOKS_INLINE_REVERSE) {
        enum { max_ranges = 4096 };
        int starts[max_ranges + 1];
        int ranges = split_ranges(item_count, min_range, NULL, starts, max_ranges);
        for (int r = ranges - 1; r >= 0; r--) {
            task(starts[r], starts[r + 1], r % ts->worker_count, task_context);
        }
        return NULL;
    }
    job *j = check_alloc(sizeof *j);
    j->task = task;
    j->task_context = task_context;
    j->item_count = item_count;
    j->chunk = chunk_for(item_count, min_range);
    j->next = 0;
    j->done = 0;
    j->link = NULL;
    atomic_fetch_add(&ts->pending, 1);
    if (ts->mode == HOOKS_POOL2) {
        pthread_mutex_lock(&ts->mutex);
        job **tail = &ts->queue;
        while (*tail) {
            tail = &(*tail)->link;
        }
        *tail = j;
        pthread_cond_broadcast(&ts->work);
        pthread_mutex_unlock(&ts->mutex);
    }
    return j;
}

static void test_finish(void *user_task, void *user_context)
{
    task_system *ts = user_context;
    job *j = user_task;
    if (ts->mode == HOOKS_INLINE_REVERSE) {
        if (j) {
            atomic_fetch_add(&ts->bad_calls, 1);
        }
        return;
    }
    if (!j) {
        atomic_fetch_add(&ts->bad_calls, 1);
        return;
    }
    if (ts->mode == HOOKS_DEFERRED) {
        run_job_shuffled(ts, j);
    } else {
        pthread_mutex_lock(&ts->mutex);
        while (j->done < j->item_count) {
            pthread_cond_wait(&ts->finished, &ts->mutex);
        }
        job **link = &ts->queue;
        while (*link && *link != j) {
            link = &(*link)->link;
        }
        if (*link) {
            *link = j->link;
        }
        pthread_mutex_unlock(&ts->mutex);
    }
    atomic_fetch_sub(&ts->pending, 1);
    free(j);
}

static void *pool_thread(void *arg)
{
    task_system *ts = ((void **)arg)[0];
    int worker = (int)(intptr_t)((void **)arg)[1];
    free(arg);
    pthread_mutex_lock(&ts->mutex);
    for (;;) {
        job *j = ts->queue;
        while (j && j->next >= j->item_count) {
            j = j->link;
        }
        if (!j) {
            if (ts->stop) {
                break;
            }
            pthread_cond_wait(&ts->work, &ts->mutex);
            continue;
        }
        int begin = j->next;
        int end = begin + j->chunk;
        if (j->item_count - end < j->chunk) {
            end = j->item_count;
        }
        j->next = end;
        pthread_mutex_unlock(&ts->mutex);
        j->task(begin, end, worker, j->task_context);
        pthread_mutex_lock(&ts->mutex);
        j->done += end - begin;
        if (j->done >= j->item_count) {
            pthread_cond_broadcast(&ts->finished);
        }
    }
    pthread_mutex_unlock(&ts->mutex);
    return NULL;
}

static void task_system_init(task_system *ts, hook_mode mode, int worker_count, uint64_t seed)
{
    memset(ts, 0, sizeof *ts);
    ts->mode = mode;
    ts->worker_count = worker_count > 0 ? worker_count : 1;
    scene_rng_seed(&ts->rng, seed);
    atomic_init(&ts->bad_calls, 0);
    atomic_init(&ts->enqueues, 0);
    atomic_init(&ts->pending, 0);
    pthread_mutex_init(&ts->mutex, NULL);
    pthread_cond_init(&ts->work, NULL);
    pthread_cond_init(&ts->finished, NULL);
    if (mode == HOOKS_POOL2) {
        for (int t = 0; t < 2; t++) {
            void **arg = check_alloc(2 * sizeof(void *));
            arg[0] = ts;
            arg[1] = (void *)(intptr_t)t;
            if (pthread_create(&ts->threads[t], NULL, pool_thread, arg) != 0) {
                fprintf(stderr, "pthread_create failed\n");
                exit(2);
            }
        }
    }
}

static void task_system_destroy(task_system *ts)
{
    if (ts->mode == HOOKS_POOL2) {
        pthread_mutex_lock(&ts->mutex);
        ts->stop = true;
        pthread_cond_broadcast(&ts->work);
        pthread_mutex_unlock(&ts->mutex);
        for (int t = 0; t < 2; t++) {
            pthread_join(ts->threads[t], NULL);
        }
    }
    pthread_mutex_destroy(&ts->mutex);
    pthread_cond_destroy(&ts->work);
    pthread_cond_destroy(&ts->finished);
}

// ---------------------------------------------------------------------------------------------

static uint64_t hash_pairs(const bpx_pair *pairs, size_t count)
{
    return check_fnv1a(pairs, sizeof(bpx_pair) * count);
}

static int total_enqueues_parallel;

// One configuration over every scene; returns whether the world could be made.
static bool run_config(bpx_backend backend, bpx_simd simd, int workers, hook_mode mode,
                       int opencl_method)
{
    task_system ts;
    task_system_init(&ts, mode, workers, 0x5eed0000u + (uint64_t)workers);
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.simd = simd;
    def.worker_count = workers;
    def.opencl_method = opencl_method;
    if (mode != HOOKS_NONE) {
        def.enqueue_task = test_enqueue;
        def.finish_task = test_finish;
        def.user_task_context = &ts;
    }
    check_set_context("backend=%s simd=%s workers=%d hooks=%s method=%d",
                      name_or(bpx_backend_name(backend)), name_or(bpx_simd_name(simd)), workers,
                      hook_names[mode], opencl_method);
    bpx_world *world = NULL;
    bpx_status s = bpx_world_create(&def, &world);
    CHECK_STATUS(s, BPX_OK);
    if (s != BPX_OK) {
        task_system_destroy(&ts);
        return false;
    }
    for (int c = 0; c < case_count; c++) {
        scene_case *sc = &cases[c];
        if (sc->n > check_backend_max_boxes(backend)) {
            continue;
        }
        check_set_seed(sc->seed);
        check_set_context("scene=%s n=%u backend=%s simd=%s workers=%d hooks=%s method=%d",
                          scene_kind_name(sc->kind), sc->n, name_or(bpx_backend_name(backend)),
                          name_or(bpx_simd_name(simd)), workers, hook_names[mode], opencl_method);
        CHECK_STATUS(bpx_world_set_boxes(world, sc->boxes, sc->n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_EQ_U64(count, sc->count);
        CHECK_MSG(hash_pairs(pairs, count) == sc->hash, "hash %016" PRIx64 " != %016" PRIx64,
                  hash_pairs(pairs, count), sc->hash);
    }
    bpx_world_destroy(world);
    CHECK_EQ_U64(atomic_load(&ts.bad_calls), 0);
    CHECK_EQ_U64(atomic_load(&ts.pending), 0);
    if (mode != HOOKS_NONE && workers > 1) {
        total_enqueues_parallel += atomic_load(&ts.enqueues);
    }
    task_system_destroy(&ts);
    return true;
}

// Several cycles of one world (also after moving and moving back) give the same bytes.
static void test_repeated_cycles(bpx_backend backend, int opencl_method)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.opencl_method = opencl_method;
    def.worker_count = 3;
    bpx_world *world = NULL;
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    if (!world) {
        return;
    }
    for (int c = 0; c < case_count; c++) {
        scene_case *sc = &cases[c];
        check_set_seed(sc->seed);
        check_set_context("repeated cycles scene=%s n=%u", scene_kind_name(sc->kind), sc->n);
        bpx_box *moved = check_alloc(sizeof(bpx_box) * (sc->n ? sc->n : 1));
        memcpy(moved, sc->boxes, sizeof(bpx_box) * sc->n);
        scene_rng r;
        scene_rng_seed(&r, sc->seed);
        scene_move(moved, sc->n, 0.5f, &r);
        CHECK_STATUS(bpx_world_set_boxes(world, sc->boxes, sc->n), BPX_OK);
        for (int cycle = 0; cycle < 3; cycle++) {
            CHECK_STATUS(bpx_world_collide(world), BPX_OK);
            size_t count = 0;
            const bpx_pair *pairs = bpx_world_pairs(world, &count);
            CHECK_EQ_U64(count, sc->count);
            CHECK(hash_pairs(pairs, count) == sc->hash);
            CHECK_EQ_U64(bpx_world_stats(world).pair_count, sc->count);
        }
        uint64_t cycles_before = bpx_world_stats(world).cycle_count;
        CHECK_STATUS(bpx_world_set_boxes(world, moved, sc->n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        CHECK_EQ_U64(bpx_world_stats(world).cycle_count, cycles_before + 1);
        CHECK_STATUS(bpx_world_set_boxes(world, sc->boxes, sc->n), BPX_OK);
        bpx_pair *buf = check_alloc(sizeof(bpx_pair) * (sc->count ? sc->count : 1));
        size_t count = 0;
        CHECK_STATUS(bpx_world_collide_into(world, buf, sc->count, &count), BPX_OK);
        CHECK_EQ_U64(count, sc->count);
        CHECK(hash_pairs(buf, count) == sc->hash);
        free(buf);
        free(moved);
    }
    bpx_world_destroy(world);
}

// The opencl backend's paths, each on 1 and 8 workers (which the device ignores), auto also
// under every task system, then repeated cycles of each path.
static int run_opencl_configs(void)
{
    static const int methods[] = {BPX_OPENCL_AUTO, BPX_OPENCL_BRUTE, BPX_OPENCL_SWEEP,
                                  BPX_OPENCL_TREE};
    int configs = 0;
    for (size_t m = 0; m < sizeof methods / sizeof methods[0]; m++) {
        configs += run_config(BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, HOOKS_NONE, methods[m]);
        configs += run_config(BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 8, HOOKS_NONE, methods[m]);
        test_repeated_cycles(BPX_BACKEND_OPENCL, methods[m]);
    }
    for (int mode = HOOKS_NONE + 1; mode < HOOKS_MODE_COUNT; mode++)
        configs +=
            run_config(BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 2, (hook_mode)mode, BPX_OPENCL_AUTO);
    return configs;
}

int main(int argc, char **argv)
{
    bool opencl_only = argc > 1 && strcmp(argv[1], "--opencl") == 0;
    // --cuda: the cuda backend alone (on the fake device, test/fake_cuda/, in CI).
    bool cuda_only = argc > 1 && strcmp(argv[1], "--cuda") == 0;
    if (cuda_only && !bpx_backend_query(BPX_BACKEND_CUDA).available) {
        printf("test_determinism --cuda: cuda unavailable\n");
        return check_finish("test_determinism --cuda", 0);
    }
    bpx_backend_info opencl = bpx_backend_query(BPX_BACKEND_OPENCL);
    if (opencl_only && !opencl.available) {
        // Skipped only without OpenCL at all (as test_opencl); a device that fails to build the
        // kernels, say, is a failure.
        const char *reason = name_or(opencl.reason);
        printf("test_determinism --opencl: opencl unavailable: %s\n", reason);
        CHECK_MSG(strcmp(reason, "not in this build") == 0 ||
                      strcmp(reason, "no OpenCL platform") == 0,
                  "opencl unavailable: %s", reason);
        return check_finish("test_determinism --opencl", 0);
    }
    printf("test_determinism: seeds");
    for (int c = 0; c < case_count; c++) {
        printf(" %s/%u:%" PRIu64, scene_kind_name(cases[c].kind), cases[c].n, cases[c].seed);
    }
    printf("\n");
    // Reference hashes: the reference backend on the calling thread.
    bpx_pair *ref = NULL;
    for (int c = 0; c < case_count; c++) {
        scene_case *sc = &cases[c];
        sc->boxes = check_alloc(sizeof(bpx_box) * sc->n);
        CHECK(scene_generate(sc->kind, sc->n, sc->seed, sc->boxes) == 0);
        size_t count = 0;
        bpx_pair probe;
        bpx_status s =
            bpx_find_pairs(sc->boxes, sc->n, BPX_BACKEND_REFERENCE, &probe, 0, &count, NULL);
        CHECK(s == BPX_OK || s == BPX_ERR_CAPACITY);
        free(ref);
        ref = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
        CHECK_STATUS(
            bpx_find_pairs(sc->boxes, sc->n, BPX_BACKEND_REFERENCE, ref, count, &sc->count, NULL),
            BPX_OK);
        sc->hash = hash_pairs(ref, sc->count);
        printf("  %-16s n=%-5u pairs=%-8zu fnv1a=%016" PRIx64 "\n", scene_kind_name(sc->kind),
               sc->n, sc->count, sc->hash);
    }
    free(ref);
    fflush(stdout);

    if (opencl_only) {
        int configs = run_opencl_configs();
        for (int c = 0; c < case_count; c++) {
            free(cases[c].boxes);
        }
        return check_finish("test_determinism --opencl", configs > 0);
    }
    static const int worker_counts[] = {1, 2, 3, 8};
    int configs = 0;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        // opencl has its own run (--opencl).
        if (b == BPX_BACKEND_OPENCL || !bpx_backend_query((bpx_backend)b).available ||
            (cuda_only && b != BPX_BACKEND_CUDA)) {
            continue;
        }
        for (int s = 0; s < BPX_SIMD_COUNT; s++) {
            bool forced = s != BPX_SIMD_AUTO;
            if (forced && (!check_backend_has_simd((bpx_backend)b) ||
                           !bpx_simd_supported((bpx_simd)s) || check_quick())) {
                continue;
            }
            for (int m = 0; m < HOOKS_MODE_COUNT; m++) {
                // Task systems with the widest and the narrowest SIMD are enough.
                if (m != HOOKS_NONE && s != BPX_SIMD_AUTO && s != BPX_SIMD_SCALAR) {
                    continue;
                }
                for (size_t w = 0; w < sizeof worker_counts / sizeof worker_counts[0]; w++) {
                    // The pool has worker ids 0 and 1: it needs worker_count >= 2.
                    if (m == HOOKS_POOL2 && worker_counts[w] < 2) {
                        continue;
                    }
                    // Quick: threads only, and not 8 of them on a small machine.
                    if (check_quick() && (worker_counts[w] == 1 || worker_counts[w] == 8)) {
                        continue;
                    }
                    configs += run_config((bpx_backend)b, (bpx_simd)s, worker_counts[w],
                                          (hook_mode)m, 0);
                }
            }
        }
    }
    printf("%d configurations, %d task-hook enqueues with >1 worker\n", configs,
           total_enqueues_parallel);
    if (cuda_only) {
        for (int c = 0; c < case_count; c++)
            free(cases[c].boxes);
        return check_finish("test_determinism --cuda", configs > 0);
    }
    check_set_context("task hooks");
    // A 5000-box cycle on 8 workers must have split work through the host's task system.
    CHECK(total_enqueues_parallel > 0);
    test_repeated_cycles(BPX_BACKEND_AUTO, 0);
    for (int c = 0; c < case_count; c++) {
        free(cases[c].boxes);
    }
    return check_finish("test_determinism", configs > 0);
}
