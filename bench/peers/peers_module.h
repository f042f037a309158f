// bpx bench peers: what the peers' module (bpx_peers.so, built from peers.c and the shims, linked
// with Bullet and Box2D) hands the program that opens it (peers_loader.c, in bpx and
// test_peers): the functions of peers.h, by one exported symbol. Private to bench/peers.
// SPDX-License-Identifier: MIT
#pragma once

#include "peers.h"

#ifdef __cplusplus
extern "C" {
#endif

/// The module's one exported symbol: a function returning its table.
#define BENCH_PEERS_MODULE_ENTRY "bpx_bench_peers_module"
/// Raised whenever the table or peers.h's types change; the loader refuses another version.
#define BENCH_PEERS_MODULE_VERSION 1

typedef struct bench_peers_module {
    int version;          // BENCH_PEERS_MODULE_VERSION
    int (*count)(void);
    const bench_peer_info *(*get)(int index);
    int (*find)(const char *name);
    bench_peer *(*create)(int index, const bpx_box *boxes, uint32_t n, const float bounds_min[3],
                          const float bounds_max[3], char *err, size_t err_size);
    int (*cycle)(bench_peer *p, const bpx_box *boxes);
    uint64_t (*pair_count)(const bench_peer *p);
    uint64_t (*exact_pairs)(const bench_peer *p, const bpx_box *boxes, bpx_pair *out,
                            uint64_t capacity);
    void (*destroy)(bench_peer *p);
} bench_peers_module;

typedef const bench_peers_module *bench_peers_module_fn(void);

#ifdef __cplusplus
}
#endif
