// The tree's upkeep: its memory, the choice between refit and rebuild, and the refit (block by
// block on the world's workers). The build is bvh_keys.c and bvh_build.c.
#if defined(__linux__)
#define _DEFAULT_SOURCE // madvise
#include <sys/mman.h>
#endif

#include "bvh.h"

#include <math.h>
#include <string.h>

#include "core/alloc.h"
#include "core/clock.h"

/// A refitted tree is rebuilt once its nodes' area, relative to the root's, grows past this
/// factor of what the last build gave: a looser tree costs every query more.
#define BPX_BVH_REBUILD_LOOSENESS 1.3

// Big arrays in 2 MiB pages where the OS has them on request (Linux's transparent huge pages
// in "madvise" mode): a first build faults in a twentieth of the pages, and a walk of the tree,
// a cache miss per node, misses the TLB far less.
static void advise_huge(void *memory, size_t size)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const uintptr_t huge = (uintptr_t)2 << 20;
    uintptr_t begin = ((uintptr_t)memory + huge - 1) & ~(huge - 1);
    uintptr_t end = ((uintptr_t)memory + size) & ~(huge - 1);
    if (memory && end > begin)
        (void)madvise((void *)begin, end - begin, MADV_HUGEPAGE); // a hint: failure is fine
#else
    (void)memory;
    (void)size;
#endif
}

bool bpx__bvh_reserve_nodes(bpx_bvh *t, size_t count, size_t keep)
{
    if (count <= t->node_capacity)
        return true;
    size_t cap = count + count / 4 + 16;
    bpx_bvh_node *nodes = bpx__alloc(sizeof(bpx_bvh_node) * cap);
    if (!nodes)
        return false;
    advise_huge(nodes, sizeof(bpx_bvh_node) * cap);
    if (keep)
        memcpy(nodes, t->nodes, sizeof(bpx_bvh_node) * keep);
    bpx__free(t->nodes, sizeof(bpx_bvh_node) * t->node_capacity);
    t->nodes = nodes;
    t->node_capacity = cap;
    return true;
}

static void release(bpx_bvh *t)
{
    bpx__free(t->words, sizeof(uint64_t) * t->item_capacity);
    bpx__free(t->words_scratch, sizeof(uint64_t) * t->item_capacity);
    bpx__free(t->boxes, sizeof(bpx_bvh_box) * t->item_capacity);
    bpx__free(t->counts, sizeof(uint32_t) * t->count_capacity);
}

// Room for a tree over n ids. A rebuild rewrites everything, so the arrays are replaced, not
// grown: all new or, when memory runs out, all old.
static bool reserve(bpx_bvh *t, uint32_t n)
{
    if (n <= t->item_capacity && t->words)
        return true;
    uint32_t cap = n + n / 4 + 16;
    bpx_bvh fresh = *t;
    fresh.item_capacity = cap;
    fresh.count_capacity = bpx__bvh_count_words(cap);
    fresh.words = bpx__alloc(sizeof(uint64_t) * cap);
    fresh.words_scratch = bpx__alloc(sizeof(uint64_t) * cap);
    fresh.boxes = bpx__alloc(sizeof(bpx_bvh_box) * cap);
    fresh.counts = bpx__alloc(sizeof(uint32_t) * fresh.count_capacity);
    bool ok = fresh.words && fresh.words_scratch && fresh.boxes && fresh.counts;
    release(ok ? t : &fresh);
    if (ok) {
        advise_huge(fresh.boxes, sizeof(bpx_bvh_box) * cap);
        advise_huge(fresh.words, sizeof(uint64_t) * cap);
        advise_huge(fresh.words_scratch, sizeof(uint64_t) * cap);
        fresh.node_count = 0;
        fresh.block_count = 0;
        *t = fresh;
    }
    t->valid = false;
    return ok;
}

static void lane_union(bpx_bvh_node *node, int k, const bpx_bvh_node *child)
{
    float lo[3], hi[3];
    bpx__bvh_node_bounds(child, lo, hi);
    for (int a = 0; a < 3; a++) {
        node->lo[a][k] = lo[a];
        node->hi[a][k] = hi[a];
    }
}

// Nodes [first, first + count): with `leaves`, first every leaf lane from t->boxes (a loop of
// independent reads that overlap their cache misses: the ids are scattered), then in reverse
// (children after parents) every node lane from its child. Returns the nodes' total area; sets
// *dead when a leaf's box is no longer live.
static double refit_nodes(bpx_bvh *t, bool leaves, uint32_t first, uint32_t count, bool *dead)
{
    for (uint32_t k = first; leaves && k < first + count; k++) {
        bpx_bvh_node *node = &t->nodes[k];
        for (uint32_t leaf = node->leaves; leaf; leaf &= leaf - 1) {
            int lane = __builtin_ctz(leaf);
            const bpx_bvh_box *b = &t->boxes[node->child[lane]];
            for (int a = 0; a < 3; a++) {
                node->lo[a][lane] = b->lo[a];
                node->hi[a][lane] = b->hi[a];
            }
            *dead |= !(b->lo[0] <= b->hi[0]);
        }
    }
    double area = 0.0;
    for (uint32_t k = first + count; k-- > first;) {
        bpx_bvh_node *node = &t->nodes[k];
        for (uint32_t inner = ~node->leaves & ((1u << node->lanes) - 1); inner;
             inner &= inner - 1) {
            int lane = __builtin_ctz(inner);
            lane_union(node, lane, &t->nodes[node->child[lane]]);
        }
        float lo[3], hi[3];
        bpx__bvh_node_bounds(node, lo, hi);
        area += bpx__bvh_area(lo, hi);
    }
    return area;
}

void bpx__bvh_top_refit(bpx_bvh *t)
{
    bool dead = false;
    t->blocks[0].area = refit_nodes(t, false, 0, t->blocks[0].count, &dead);
}

double bpx__bvh_looseness(const bpx_bvh *t)
{
    if (!t->node_count)
        return 0.0;
    float lo[3], hi[3];
    bpx__bvh_node_bounds(&t->nodes[0], lo, hi);
    double root = bpx__bvh_area(lo, hi), sum = 0.0;
    if (!(root > 0.0))
        return 1.0;
    for (uint32_t b = 0; b < t->block_count; b++) // in block order: the same sum for any workers
        sum += t->blocks[b].area;
    return sum / root;
}

typedef struct refit_job {
    bpx_bvh *t;
    const bpx_soa *s;
    uint32_t *live; // per chunk of ids: live boxes
    uint8_t *dead;  // per block below the top
} refit_job;

static void copy_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    refit_job *job = context;
    for (int c = begin; c < end; c++)
        job->live[c] = bpx__bvh_copy_chunk(job->t, job->s, (uint32_t)c);
}

static void refit_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    refit_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_bvh_block *block = &job->t->blocks[b + 1];
        bool dead = false;
        block->area = refit_nodes(job->t, true, block->first, block->count, &dead);
        job->dead[b] = dead;
    }
}

// The same live ids, moved: every lane from its box or child. False when the live ids differ
// from the tree's (then it must be rebuilt).
static bool refit(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex)
{
    if (s->n != t->world_n || !t->block_count)
        return false;
    uint32_t chunks = bpx__bvh_chunks(s->n);
    // Scratch, from the build's counts (free now): live boxes per chunk, then a flag per block.
    if (chunks + (t->block_count + 3) / 4 > t->count_capacity)
        return false;
    refit_job job = {t, s, t->counts, (uint8_t *)(t->counts + chunks)};
    bpx__bvh_run(ex, copy_task, chunks, s->n, &job);
    uint32_t live = 0;
    for (uint32_t c = 0; c < chunks; c++)
        live += job.live[c];
    if (live != t->item_count)
        return false;
    // As many live as the tree holds: the same ids when all of the tree's are live (the tree's
    // ids are distinct).
    bpx__bvh_run(ex, refit_task, t->block_count - 1, t->item_count, &job);
    bool dead = false;
    for (uint32_t b = 0; b + 1 < t->block_count; b++)
        dead |= job.dead[b];
    t->blocks[0].area = refit_nodes(t, true, 0, t->blocks[0].count, &dead);
    if (dead)
        return false;
    t->refits++;
    return true;
}

bpx_status bpx__bvh_update(bpx_bvh *t, const bpx_world *w)
{
    if (t->valid && t->version == w->boxes_version)
        return BPX_OK;
    uint64_t start = bpx__now_ns();
    bpx_soa s = bpx__world_soa(w);
    bool refitted = t->valid && refit(t, &s, &w->executor);
    if (refitted && bpx__bvh_looseness(t) > BPX_BVH_REBUILD_LOOSENESS * t->looseness)
        refitted = false;
    t->valid = false;
    if (!refitted) {
        if (!reserve(t, s.n) || !bpx__bvh_rebuild(t, &s, &w->executor))
            return BPX_ERR_OUT_OF_MEMORY;
        t->looseness = bpx__bvh_looseness(t);
        t->builds++;
    }
    t->valid = true;
    t->version = w->boxes_version;
    t->world_n = s.n;
    t->last_update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

void bpx__bvh_free(bpx_bvh *t)
{
    release(t);
    bpx__free(t->nodes, sizeof(bpx_bvh_node) * t->node_capacity);
    bpx__free(t->blocks, sizeof(bpx_bvh_block) * t->block_capacity);
    memset(t, 0, sizeof *t);
}
