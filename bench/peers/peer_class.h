// bpx bench peers: what each library shim gives the registry (peers.c). Private to bench/peers.
// SPDX-License-Identifier: MIT
#pragma once

#include "peers.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Called once per current pair, in any order; a and b are box indices, either way round.
typedef void bench_peer_visit_fn(void *context, uint32_t a, uint32_t b);

/// One peer as a shim implements it. Every function catches everything: no exception leaves.
/// The registry has checked the arguments (index, n <= max_n, boxes valid, bounds finite and
/// ordered) before create is called.
typedef struct bench_peer_class {
    bench_peer_info info;
    /// Shim-specific selector (which Bullet broad phase, say).
    int variant;
    /// The library object with n proxies and its first pair update done; NULL + message.
    void *(*create)(int variant, const bpx_box *boxes, uint32_t n, const float bounds_min[3],
                    const float bounds_max[3], char *err, size_t err_size);
    /// Sets every proxy's box, then the library's own pair update. 0 or -1.
    int (*cycle)(void *impl, const bpx_box *boxes);
    /// The pair count as the library reports it.
    uint64_t (*pair_count)(const void *impl);
    /// Visits every current pair once.
    void (*visit_pairs)(const void *impl, bench_peer_visit_fn *visit, void *context);
    void (*destroy)(void *impl);
} bench_peer_class;

/// Each shim's peers: a static array (built on first call) and its length.
const bench_peer_class *bench_peer_bullet_classes(int *count);
const bench_peer_class *bench_peer_box2d_classes(int *count);
const bench_peer_class *bench_peer_fcl_classes(int *count);

/// snprintf into err when err is not NULL (shared by the shims).
void bench_peer_set_error(char *err, size_t err_size, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#ifdef __cplusplus
}
#endif
