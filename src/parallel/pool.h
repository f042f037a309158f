// The built-in thread pool, and parallel_for over either it or the host's task hooks.
#pragma once

#include "bpx/types.h"

typedef struct bpx_pool bpx_pool;

/// Starts thread_count threads (the caller works too, so a pool of k threads gives k + 1 workers).
/// spin_us: how long an idle thread spins before sleeping (negative: never spins).
/// Returns NULL if memory or threads could not be had; nothing is leaked then.
bpx_pool *bpx__pool_create(int thread_count, int spin_us);
void bpx__pool_destroy(bpx_pool *pool);

/// How work is spread for one world: the host's hooks, the built-in pool, or neither (serial).
typedef struct bpx_executor {
    bpx_pool *pool;
    int worker_count;
    bpx_enqueue_task_fn *enqueue_task;
    bpx_finish_task_fn *finish_task;
    void *user_task_context;
} bpx_executor;

/// Runs task over [0, item_count), items in any order and on any worker, and returns when all
/// are done. Ranges are handed out one item at a time by the pool (items are the load balance).
void bpx__parallel_for(const bpx_executor *executor, bpx_task_fn *task, int item_count,
                       void *task_context);
