// After the first cycles, a cycle allocates nothing: every backend, a coherent scene, both the
// general mode (set_boxes) and the paper's two phases (update_centres), 1 and 2 workers.
// Counts the library's allocations through the allocator hook.
#include <stdatomic.h>

#include "pairs_util.h"
#include "scenes.h"

static _Atomic long allocations;

static void *counting_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    atomic_fetch_add(&allocations, 1);
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static void counting_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

enum { full_n = 3000, warmup = 4, measured = 12 };

static void run(bpx_backend backend, int workers, bool two_phase)
{
    // rtl: 400 of the 512 boxes the chip holds. (At 512 this scene's pair count passes 512 in
    // cycle 9, and the world's merged list grows then: a new high, not a backend's allocation.)
    const uint32_t n = full_n <= check_backend_max_boxes(backend) ? full_n : 400u;
    check_set_context("backend=%s workers=%d %s n=%u", bpx_backend_name(backend), workers,
                      two_phase ? "update_centres" : "set_boxes", n);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    float *minima = check_alloc(sizeof(float) * 3 * n), *centres = check_alloc(sizeof(float) * 3 * n);
    scene_uniform_density(n, 1.0f, 7, boxes);
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            minima[3 * i + a] = -half;
            centres[3 * i + a] = boxes[i].min[a] + half;
        }
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = workers;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (two_phase)
        CHECK_STATUS(bpx_world_load_extents(w, minima, n), BPX_OK);
    scene_rng r;
    scene_rng_seed(&r, 7);
    long before = 0;
    for (int cycle = 0; cycle < warmup + measured; cycle++) {
        if (cycle == warmup)
            before = atomic_load(&allocations);
        // Coherent motion: every box moves a little each cycle.
        for (uint32_t k = 0; k < 3 * n; k++)
            centres[k] += scene_rng_range(&r, -0.02f, 0.02f);
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                float half = -minima[3 * i + a];
                boxes[i].min[a] = centres[3 * i + a] - half;
                boxes[i].max[a] = centres[3 * i + a] + half;
            }
        CHECK_STATUS(two_phase ? bpx_world_update_centres(w, centres)
                               : bpx_world_set_boxes(w, boxes, n),
                     BPX_OK);
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    }
    long during = atomic_load(&allocations) - before;
    CHECK_MSG(during == 0, "%ld allocations in %d cycles after %d warm-up cycles", during,
              measured, warmup);
    bpx_world_destroy(w);
    free(boxes);
    free(minima);
    free(centres);
}

int main(void)
{
    bpx_set_allocator(counting_alloc, counting_free, NULL);
    int ran = 0;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        if (!bpx_backend_query((bpx_backend)b).available)
            continue;
        for (int workers = 1; workers <= 2; workers++)
            for (int two_phase = 0; two_phase <= 1; two_phase++) {
                run((bpx_backend)b, workers, two_phase);
                ran++;
            }
    }
    bpx_set_allocator(NULL, NULL, NULL);
    return check_finish("test_steady", ran);
}
