#include "pool.h"

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdbool.h>

#include "core/alloc.h"
#include "core/clock.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define bpx_cpu_relax() _mm_pause()
#elif defined(__aarch64__)
#define bpx_cpu_relax() __asm__ __volatile__("yield")
#else
#define bpx_cpu_relax() ((void)0)
#endif

typedef struct worker_start {
    struct bpx_pool *pool;
    int index;
} worker_start;

// One job at a time. The whole job state workers need to claim an item sits in one atomic word,
// `claim` = job id | item count | next item, so a claim either takes an item of the current job
// or fails: a worker that wakes late can never take an item of a job that is over. The caller
// claims items too and returns when `completed` reaches the count; it never waits for a worker
// that has not woken up, so a sleeping pool costs nothing but the work it does not share.
struct bpx_pool {
    int thread_count; // threads running
    int capacity;     // length of threads[] and starts[]
    int spin_us;
    pthread_t *threads;
    worker_start *starts;

    bpx_task_fn *task; // of the current job; stable while any of its items is unfinished
    void *task_context;
    uint64_t job;
    _Atomic uint64_t claim;
    _Atomic int completed;

    _Atomic int sleepers;
    _Atomic int stop;
    pthread_mutex_t mutex;
    pthread_cond_t wake;
};

enum { ITEM_BITS = 22, JOB_SHIFT = 2 * ITEM_BITS };
#define ITEM_MASK ((1ull << ITEM_BITS) - 1)

static uint64_t pack_claim(uint64_t job, uint64_t count, uint64_t next)
{
    return job << JOB_SHIFT | count << ITEM_BITS | next;
}

static bool has_items(uint64_t claim)
{
    return (claim & ITEM_MASK) < (claim >> ITEM_BITS & ITEM_MASK);
}

// Spinning politely: pause first; after a while also yield, so that more threads than cores
// (oversubscription) still make progress.
static void backoff(int spins)
{
    bpx_cpu_relax();
    if (spins > 4096)
        sched_yield();
}

// Claims and runs items of whatever job is current until none is left.
static void run_items(bpx_pool *pool, int worker)
{
    uint64_t claim = atomic_load(&pool->claim);
    while (has_items(claim)) {
        if (!atomic_compare_exchange_weak(&pool->claim, &claim, claim + 1))
            continue; // claim now holds the fresh value
        int item = (int)(claim & ITEM_MASK);
        pool->task(item, item + 1, worker, pool->task_context);
        atomic_fetch_add(&pool->completed, 1);
        claim = atomic_load(&pool->claim);
    }
}

static bool should_wake(bpx_pool *pool)
{
    return has_items(atomic_load(&pool->claim)) || atomic_load(&pool->stop);
}

static void wait_for_items(bpx_pool *pool)
{
    if (pool->spin_us >= 0) {
        uint64_t deadline = bpx__now_ns() + (uint64_t)pool->spin_us * 1000u;
        for (int spins = 0;; spins++) {
            if (should_wake(pool))
                return;
            backoff(spins);
            if ((spins & 63) == 63 && bpx__now_ns() > deadline)
                break;
        }
    }
    // Sleep. sleepers is raised before claim is re-read (both seq_cst), so a publisher that reads
    // sleepers == 0 has stored the new claim before our read, and we see it.
    pthread_mutex_lock(&pool->mutex);
    atomic_fetch_add(&pool->sleepers, 1);
    while (!should_wake(pool))
        pthread_cond_wait(&pool->wake, &pool->mutex);
    atomic_fetch_sub(&pool->sleepers, 1);
    pthread_mutex_unlock(&pool->mutex);
}

static void *worker_main(void *arg)
{
    const worker_start *start = arg;
    bpx_pool *pool = start->pool;
    for (;;) {
        wait_for_items(pool);
        if (atomic_load(&pool->stop))
            break;
        run_items(pool, start->index);
    }
    return NULL;
}

bpx_pool *bpx__pool_create(int thread_count, int spin_us)
{
    bpx_pool *pool = bpx__alloc(sizeof *pool);
    if (!pool)
        return NULL;
    *pool = (bpx_pool){.capacity = thread_count, .spin_us = spin_us};
    pool->threads = bpx__alloc(sizeof(pthread_t) * (size_t)thread_count);
    pool->starts = bpx__alloc(sizeof(worker_start) * (size_t)thread_count);
    int have_mutex = 0, have_cond = 0;
    if (pool->threads && pool->starts) {
        have_mutex = pthread_mutex_init(&pool->mutex, NULL) == 0;
        have_cond = have_mutex && pthread_cond_init(&pool->wake, NULL) == 0;
    }
    if (!have_cond) {
        if (have_mutex)
            pthread_mutex_destroy(&pool->mutex);
        bpx__free(pool->starts, sizeof(worker_start) * (size_t)thread_count);
        bpx__free(pool->threads, sizeof(pthread_t) * (size_t)thread_count);
        bpx__free(pool, sizeof *pool);
        return NULL;
    }
    for (int t = 0; t < thread_count; t++) {
        pool->starts[t] = (worker_start){pool, t + 1}; // worker 0 is the caller
        if (pthread_create(&pool->threads[t], NULL, worker_main, &pool->starts[t]) != 0)
            break;
        pool->thread_count++;
    }
    if (pool->thread_count < thread_count) {
        bpx__pool_destroy(pool);
        return NULL;
    }
    return pool;
}

void bpx__pool_destroy(bpx_pool *pool)
{
    if (!pool)
        return;
    pthread_mutex_lock(&pool->mutex);
    atomic_store(&pool->stop, 1);
    pthread_cond_broadcast(&pool->wake);
    pthread_mutex_unlock(&pool->mutex);
    for (int t = 0; t < pool->thread_count; t++)
        pthread_join(pool->threads[t], NULL);
    pthread_cond_destroy(&pool->wake);
    pthread_mutex_destroy(&pool->mutex);
    bpx__free(pool->starts, sizeof(worker_start) * (size_t)pool->capacity);
    bpx__free(pool->threads, sizeof(pthread_t) * (size_t)pool->capacity);
    bpx__free(pool, sizeof *pool);
}

static void pool_run(bpx_pool *pool, bpx_task_fn *task, int item_count, void *task_context)
{
    pool->task = task;
    pool->task_context = task_context;
    pool->job = (pool->job + 1) & ((1ull << (64 - JOB_SHIFT)) - 1);
    atomic_store(&pool->completed, 0);
    atomic_store(&pool->claim, pack_claim(pool->job, (uint64_t)item_count, 0)); // publishes
    if (atomic_load(&pool->sleepers) > 0) {
        pthread_mutex_lock(&pool->mutex);
        pthread_cond_broadcast(&pool->wake);
        pthread_mutex_unlock(&pool->mutex);
    }
    run_items(pool, 0);
    for (int spins = 0; atomic_load(&pool->completed) < item_count; spins++)
        backoff(spins);
}

void bpx__parallel_for(const bpx_executor *executor, bpx_task_fn *task, int item_count,
                       void *task_context)
{
    if (item_count <= 0)
        return;
    if (executor->enqueue_task && executor->worker_count > 1 && item_count > 1) {
        void *user_task = executor->enqueue_task(task, item_count, 1, task_context,
                                                 executor->user_task_context);
        if (user_task)
            executor->finish_task(user_task, executor->user_task_context);
        return;
    }
    if (executor->pool && item_count > 1 && (uint64_t)item_count <= ITEM_MASK) {
        pool_run(executor->pool, task, item_count, task_context);
        return;
    }
    task(0, item_count, 0, task_context);
}
