// bpx bench peers, as bpx (and test_peers) sees them: peers.h's functions answered by the peers'
// module, bpx_peers.so, opened at run time, so that bpx starts on a machine without Bullet or
// Box2D. Without the module, or when it cannot be loaded (Bullet or Box2D missing, or the test
// hook BPX_NO_DLOPEN), there are no peers and bench_peers_unavailable() says why.
// SPDX-License-Identifier: MIT
//
// Where the module is looked for, first found wins:
//   $BPX_PEERS_MODULE             a path (only there, when set and not empty)
//   <bpx's folder>/bpx_peers.so   the build tree: build/<preset>/
//   <bpx's folder>/BPX_PEERS_INSTALL_DIR/bpx_peers.so   installed: <prefix>/lib/bpx/
#define _DEFAULT_SOURCE // readlink
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "dynload.h"
#include "peers_module.h"

#ifndef BPX_PEERS_MODULE_FILE
#define BPX_PEERS_MODULE_FILE "bpx_peers.so"
#endif
#ifndef BPX_PEERS_INSTALL_DIR
#define BPX_PEERS_INSTALL_DIR "../lib/bpx"
#endif

static pthread_once_t once = PTHREAD_ONCE_INIT;
static const bench_peers_module *module;
static char why[4096] = "not loaded";

// The folder of the running program, with a trailing '/', or "" where it cannot be known.
static void program_dir(char *dir, size_t size)
{
    dir[0] = '\0';
    ssize_t len = readlink("/proc/self/exe", dir, size - 1);
    if (len <= 0)
        return;
    dir[len] = '\0';
    char *slash = strrchr(dir, '/');
    if (slash)
        slash[1] = '\0';
    else
        dir[0] = '\0';
}

static void load(void)
{
    char dir[1024], paths[2][1200];
    int path_count = 0;
    const char *chosen = getenv("BPX_PEERS_MODULE");
    if (!chosen || !*chosen) {
        chosen = NULL;
        program_dir(dir, sizeof dir);
        snprintf(paths[path_count++], sizeof paths[0], "%s%s", dir, BPX_PEERS_MODULE_FILE);
        snprintf(paths[path_count++], sizeof paths[0], "%s%s/%s", dir, BPX_PEERS_INSTALL_DIR,
                 BPX_PEERS_MODULE_FILE);
        for (int k = 0; k < path_count && !chosen; k++)
            if (access(paths[k], F_OK) == 0)
                chosen = paths[k];
        if (!chosen) {
            snprintf(why, sizeof why,
                     "no peers: %s is neither at %s nor at %s (it is built when CMake finds "
                     "Bullet or Box2D: see bench/peers)",
                     BPX_PEERS_MODULE_FILE, paths[0], paths[1]);
            return;
        }
    }
    char err[1536];
    void *handle = bpx_dynload_open(chosen, err, sizeof err);
    bench_peers_module_fn *entry = NULL;
    if (handle)
        entry = (bench_peers_module_fn *)bpx_dynload_symbol(handle, chosen,
                                                             BENCH_PEERS_MODULE_ENTRY, err,
                                                             sizeof err);
    if (!entry) {
        // A library the module needs that is not installed shows in dlerror's text, by name.
        snprintf(why, sizeof why,
                 "no peers: %s; the peers need Bullet, Box2D and FCL (Debian: libbullet3.24, "
                 "libbox2d2, libfcl0.7)", err);
        return;
    }
    const bench_peers_module *m = entry();
    if (!m || m->version != BENCH_PEERS_MODULE_VERSION) {
        snprintf(why, sizeof why, "no peers: %s is of another bpx (module version %d, not %d)",
                 chosen, m ? m->version : -1, BENCH_PEERS_MODULE_VERSION);
        return;
    }
    module = m;
    if (m->count() == 0)
        snprintf(why, sizeof why, "no peers: %s has none compiled in", chosen);
    else
        why[0] = '\0';
}

const char *bench_peers_unavailable(void)
{
    pthread_once(&once, load);
    return why[0] ? why : NULL;
}

int bench_peer_count(void)
{
    pthread_once(&once, load);
    return module ? module->count() : 0;
}

const bench_peer_info *bench_peer_get(int index)
{
    pthread_once(&once, load);
    return module ? module->get(index) : NULL;
}

int bench_peer_find(const char *name)
{
    pthread_once(&once, load);
    return module ? module->find(name) : -1;
}

bench_peer *bench_peer_create(int index, const bpx_box *boxes, uint32_t n,
                              const float bounds_min[3], const float bounds_max[3], char *err,
                              size_t err_size)
{
    pthread_once(&once, load);
    if (!module) {
        if (err && err_size)
            snprintf(err, err_size, "%s", why);
        return NULL;
    }
    return module->create(index, boxes, n, bounds_min, bounds_max, err, err_size);
}

// A peer exists only where the module made it: these need no check.
int bench_peer_cycle(bench_peer *p, const bpx_box *boxes)
{
    return module->cycle(p, boxes);
}

uint64_t bench_peer_pair_count(const bench_peer *p)
{
    return module->pair_count(p);
}

uint64_t bench_peer_exact_pairs(const bench_peer *p, const bpx_box *boxes, bpx_pair *out,
                                uint64_t capacity)
{
    return module->exact_pairs(p, boxes, out, capacity);
}

void bench_peer_destroy(bench_peer *p)
{
    if (p)
        module->destroy(p);
}
