// bpx bench peers: the registry and the checks every peer shares. SPDX-License-Identifier: MIT
//
// Each library shim (peer_bullet.cpp, peer_box2d.cpp, peer_fcl.cpp) hands over a table of
// bench_peer_class; this file numbers them, checks the arguments once for all, and holds the
// untimed exact-pair filter, so a shim only wraps its library's broad phase.
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <bpx/bpx.h>

#include "peer_class.h"

struct bench_peer {
    const bench_peer_class *cls;
    void *impl;
    uint32_t n;
};

typedef const bench_peer_class *bench_peer_list_fn(int *count);

// The shims compiled in (CMake defines BPX_PEER_HAVE_*), in CLI listing order.
static bench_peer_list_fn *const peer_lists[] = {
#if defined(BPX_PEER_HAVE_BULLET)
    bench_peer_bullet_classes,
#endif
#if defined(BPX_PEER_HAVE_BOX2D)
    bench_peer_box2d_classes,
#endif
#if defined(BPX_PEER_HAVE_FCL)
    bench_peer_fcl_classes,
#endif
    NULL,
};

void bench_peer_set_error(char *err, size_t err_size, const char *fmt, ...)
{
    if (!err || err_size == 0) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, err_size, fmt, ap);
    va_end(ap);
}

static const bench_peer_class *peer_class_at(int index)
{
    if (index < 0) {
        return NULL;
    }
    for (size_t l = 0; peer_lists[l]; l++) {
        int count = 0;
        const bench_peer_class *classes = peer_lists[l](&count);
        if (index < count) {
            return &classes[index];
        }
        index -= count;
    }
    return NULL;
}

int bench_peer_count(void)
{
    int total = 0;
    for (size_t l = 0; peer_lists[l]; l++) {
        int count = 0;
        peer_lists[l](&count);
        total += count;
    }
    return total;
}

const bench_peer_info *bench_peer_get(int index)
{
    const bench_peer_class *cls = peer_class_at(index);
    return cls ? &cls->info : NULL;
}

int bench_peer_find(const char *name)
{
    if (!name) {
        return -1;
    }
    for (int k = 0;; k++) {
        const bench_peer_info *info = bench_peer_get(k);
        if (!info) {
            return -1;
        }
        if (strcmp(info->name, name) == 0) {
            return k;
        }
    }
}

bench_peer *bench_peer_create(int index, const bpx_box *boxes, uint32_t n,
                              const float bounds_min[3], const float bounds_max[3], char *err,
                              size_t err_size)
{
    bench_peer_set_error(err, err_size, "%s", "");
    const bench_peer_class *cls = peer_class_at(index);
    if (!cls) {
        bench_peer_set_error(err, err_size, "no peer with index %d (%d compiled in)", index,
                             bench_peer_count());
        return NULL;
    }
    const char *name = cls->info.name;
    if (n > cls->info.max_n) {
        bench_peer_set_error(err, err_size, "%s: n = %u is above its limit of %u proxies", name, n,
                             cls->info.max_n);
        return NULL;
    }
    if (n > 0 && (!boxes || !bounds_min || !bounds_max)) {
        bench_peer_set_error(err, err_size, "%s: boxes or bounds NULL with n = %u", name, n);
        return NULL;
    }
    bpx_error box_err;
    if (bpx_validate_boxes(boxes, n, &box_err) != BPX_OK) {
        bench_peer_set_error(err, err_size, "%s: %s", name, box_err.message);
        return NULL;
    }
    // Bounds: finite, ordered, and holding the first frame (a cheap check of the caller's
    // promise that they hold every frame).
    float lo[3] = {0.0f, 0.0f, 0.0f}, hi[3] = {1.0f, 1.0f, 1.0f};
    if (bounds_min && bounds_max) {
        for (int a = 0; a < 3; a++) {
            lo[a] = bounds_min[a];
            hi[a] = bounds_max[a];
            if (!isfinite(lo[a]) || !isfinite(hi[a]) || lo[a] > hi[a]) {
                bench_peer_set_error(err, err_size,
                                     "%s: bounds on axis %d are not finite and ordered "
                                     "(%g .. %g)",
                                     name, a, (double)lo[a], (double)hi[a]);
                return NULL;
            }
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            if (boxes[i].min[a] < lo[a] || boxes[i].max[a] > hi[a]) {
                bench_peer_set_error(err, err_size, "%s: box %u lies outside the bounds on axis %d",
                                     name, i, a);
                return NULL;
            }
        }
    }
    bench_peer *p = malloc(sizeof *p);
    if (!p) {
        bench_peer_set_error(err, err_size, "%s: out of memory", name);
        return NULL;
    }
    p->cls = cls;
    p->n = n;
    p->impl = cls->create(cls->variant, boxes, n, lo, hi, err, err_size);
    if (!p->impl) {
        if (err && err_size && !err[0]) {
            bench_peer_set_error(err, err_size, "%s: creation failed", name);
        }
        free(p);
        return NULL;
    }
    return p;
}

int bench_peer_cycle(bench_peer *p, const bpx_box *boxes)
{
    if (!p || (p->n > 0 && !boxes)) {
        return -1;
    }
    return p->cls->cycle(p->impl, boxes);
}

uint64_t bench_peer_pair_count(const bench_peer *p)
{
    return p ? p->cls->pair_count(p->impl) : 0;
}

// --- exact pairs: the smallest `capacity` pairs kept in a max-heap in out, then sorted ---------

typedef struct exact_filter {
    const bpx_box *boxes;
    uint32_t n;
    bpx_pair *heap;
    uint64_t capacity;
    uint64_t heap_size;
    uint64_t count;
} exact_filter;

static bool pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

static void heap_sift_down(bpx_pair *h, uint64_t size, uint64_t k)
{
    for (;;) {
        uint64_t big = k, l = 2 * k + 1, r = l + 1;
        if (l < size && pair_less(h[big], h[l])) {
            big = l;
        }
        if (r < size && pair_less(h[big], h[r])) {
            big = r;
        }
        if (big == k) {
            return;
        }
        bpx_pair t = h[k];
        h[k] = h[big];
        h[big] = t;
        k = big;
    }
}

static void heap_push(bpx_pair *h, uint64_t *size, bpx_pair p)
{
    uint64_t k = (*size)++;
    h[k] = p;
    while (k > 0) {
        uint64_t parent = (k - 1) / 2;
        if (!pair_less(h[parent], h[k])) {
            break;
        }
        bpx_pair t = h[k];
        h[k] = h[parent];
        h[parent] = t;
        k = parent;
    }
}

static void exact_visit(void *context, uint32_t a, uint32_t b)
{
    exact_filter *f = context;
    if (a == b || a >= f->n || b >= f->n || !bpx_overlap(&f->boxes[a], &f->boxes[b])) {
        return;
    }
    bpx_pair p = {a < b ? a : b, a < b ? b : a};
    f->count++;
    if (f->heap_size < f->capacity) {
        heap_push(f->heap, &f->heap_size, p);
    } else if (f->capacity > 0 && pair_less(p, f->heap[0])) {
        f->heap[0] = p;
        heap_sift_down(f->heap, f->heap_size, 0);
    }
}

uint64_t bench_peer_exact_pairs(const bench_peer *p, const bpx_box *boxes, bpx_pair *out,
                                uint64_t capacity)
{
    if (!p || (p->n > 0 && !boxes)) {
        return 0;
    }
    exact_filter f = {boxes, p->n, out, out ? capacity : 0, 0, 0};
    p->cls->visit_pairs(p->impl, exact_visit, &f);
    for (uint64_t size = f.heap_size; size > 1; size--) { // heap sort: ascending (i, j)
        bpx_pair t = out[0];
        out[0] = out[size - 1];
        out[size - 1] = t;
        heap_sift_down(out, size - 1, 0);
    }
    return f.count;
}

void bench_peer_destroy(bench_peer *p)
{
    if (!p) {
        return;
    }
    p->cls->destroy(p->impl);
    free(p);
}
