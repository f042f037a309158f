// bpx bench peers: the module's entry (see peers_module.h). SPDX-License-Identifier: MIT
#include <bpx/bpx.h>

#include "peers_module.h"

#if defined(__GNUC__)
#define BENCH_PEERS_EXPORT __attribute__((visibility("default")))
#else
#define BENCH_PEERS_EXPORT
#endif

BENCH_PEERS_EXPORT const bench_peers_module *bpx_bench_peers_module(void);

const bench_peers_module *bpx_bench_peers_module(void)
{
    static const bench_peers_module module = {
        .version = BENCH_PEERS_MODULE_VERSION,
        .count = bench_peer_count,
        .get = bench_peer_get,
        .find = bench_peer_find,
        .create = bench_peer_create,
        .cycle = bench_peer_cycle,
        .pair_count = bench_peer_pair_count,
        .exact_pairs = bench_peer_exact_pairs,
        .destroy = bench_peer_destroy,
    };
    return &module;
}
