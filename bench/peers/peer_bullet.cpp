// bpx bench peers: Bullet 3's broad phases (btAxisSweep3, bt32BitAxisSweep3, btDbvtBroadphase,
// btSimpleBroadphase) used as a btCollisionWorld uses them. SPDX-License-Identifier: MIT
//
// Each proxy's client object is its box index + 1 (btSimpleBroadphase takes a proxy whose client
// object is NULL for a free slot and skips it). The pair set is the broad phase's own
// btHashedOverlappingPairCache (the default one); a real btCollisionDispatcher is passed to
// every call, as btCollisionWorld does, so pair removal goes the engine's way.
#include <cmath>
#include <cstdio>
#include <exception>
#include <new>
#include <vector>

#include <BulletCollision/BroadphaseCollision/btAxisSweep3.h>
#include <BulletCollision/BroadphaseCollision/btBroadphaseProxy.h>
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>
#include <BulletCollision/BroadphaseCollision/btSimpleBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletCollision/CollisionDispatch/btDefaultCollisionConfiguration.h>
#include <LinearMath/btScalar.h>

#include "peer_class.h"

#if defined(BT_USE_DOUBLE_PRECISION)
#error "bench peers expect single-precision Bullet (bullet.pc), the precision of bpx's boxes"
#endif

namespace
{

enum Variant { SAP16, SAP32, DBVT, SIMPLE };

// btAxisSweep3 keeps handle and edge indices in 16 bits: its constructor accepts fewer than
// 32767 handles, one of them Bullet's own sentinel.
constexpr uint32_t kSap16MaxProxies = 32766;
// bt32BitAxisSweep3: 2 (n + 1) edges per axis indexed by 32-bit integers; stay far below.
constexpr uint32_t kSap32MaxProxies = (1u << 30) - 2;
// btSimpleBroadphase: proxies in an int-indexed array.
constexpr uint32_t kSimpleMaxProxies = (1u << 30) - 2;
// btSimpleBroadphase tests all n (n - 1) / 2 pairs each cycle, each with a hash look-up:
// about 0.3 s per cycle at n = 5000 on one core of a 2-core Xeon (Ice Lake). Skipped above.
constexpr uint32_t kSimpleSlowN = 5000;
// The sweep and prunes insert one proxy at a time, each sorted into place on three axes: O(n)
// per proxy, O(n^2) to create (2 s at n = 10000, 20 s at 30000, minutes at 100000), though a
// cycle stays cheap. Skipped above the 16-bit variant's limit.
constexpr uint32_t kSap32SlowN = kSap16MaxProxies;

struct BulletPeer {
    Variant variant = SAP16;
    uint32_t n = 0;
    btDefaultCollisionConfiguration *config = nullptr;
    btCollisionDispatcher *dispatcher = nullptr;
    btBroadphaseInterface *broadphase = nullptr;
    std::vector<btBroadphaseProxy *> proxies;

    BulletPeer() = default;
    BulletPeer(const BulletPeer &) = delete;
    BulletPeer &operator=(const BulletPeer &) = delete;

    ~BulletPeer()
    {
        if (broadphase && variant == DBVT) {
            // btDbvtBroadphase allocates each proxy and frees it only in destroyProxy, which
            // also scans the whole pair cache for the proxy's pairs. Empty the cache first
            // (O(1) per pair), so the n destroyProxy calls stay O(n log n), not O(n pairs).
            btOverlappingPairCache *cache = broadphase->getOverlappingPairCache();
            while (cache->getNumOverlappingPairs() > 0) {
                btBroadphasePair &last =
                    cache->getOverlappingPairArrayPtr()[cache->getNumOverlappingPairs() - 1];
                cache->removeOverlappingPair(last.m_pProxy0, last.m_pProxy1, dispatcher);
            }
            for (btBroadphaseProxy *proxy : proxies) {
                if (proxy) {
                    broadphase->destroyProxy(proxy, dispatcher);
                }
            }
        }
        // The sweep-and-prune and simple broad phases keep their proxies in arrays of their
        // own: deleting the broad phase frees them (destroyProxy one by one would cost O(n)
        // each for sweep and prune).
        delete broadphase;
        delete dispatcher;
        delete config;
    }
};

inline btVector3 lower(const bpx_box &b)
{
    return btVector3(b.min[0], b.min[1], b.min[2]);
}

inline btVector3 upper(const bpx_box &b)
{
    return btVector3(b.max[0], b.max[1], b.max[2]);
}

// The world box handed to a sweep and prune: the caller's bounds widened by 1% of their span
// (at least 1e-3 of their magnitude, at least 1e-3), so that no box sits on the clamped rim of
// the integer grid and a flat bound (all boxes in one plane) still has a span.
bool sap_world(const float lo_in[3], const float hi_in[3], btVector3 &lo, btVector3 &hi, char *err,
               size_t err_size, const char *name)
{
    for (int a = 0; a < 3; a++) {
        double l = lo_in[a], h = hi_in[a];
        double magnitude = std::fmax(std::fabs(l), std::fabs(h));
        double pad = std::fmax(0.01 * (h - l), 1e-3 * std::fmax(magnitude, 1.0));
        float fl = (float)(l - pad), fh = (float)(h + pad);
        float span = fh - fl;
        if (!std::isfinite(fl) || !std::isfinite(fh) || !std::isfinite(span) || !(span > 0.0f)) {
            bench_peer_set_error(err, err_size,
                                 "%s: bounds %g .. %g on axis %d are too wide to quantise in "
                                 "single precision",
                                 name, l, h, a);
            return false;
        }
        lo[a] = fl;
        hi[a] = fh;
    }
    return true;
}

void *bullet_create(int variant_int, const bpx_box *boxes, uint32_t n, const float bounds_min[3],
                    const float bounds_max[3], char *err, size_t err_size)
{
    const Variant variant = (Variant)variant_int;
    static const char *const names[] = {"bullet-sap", "bullet-sap32", "bullet-dbvt",
                                        "bullet-simple"};
    const char *name = names[variant];
    BulletPeer *peer = nullptr;
    try {
        peer = new BulletPeer();
        peer->variant = variant;
        peer->n = n;
        peer->proxies.assign(n, nullptr);
        peer->config = new btDefaultCollisionConfiguration();
        peer->dispatcher = new btCollisionDispatcher(peer->config);
        btVector3 lo, hi;
        switch (variant) {
        case SAP16:
            if (!sap_world(bounds_min, bounds_max, lo, hi, err, err_size, name)) {
                delete peer;
                return nullptr;
            }
            // The ray-cast accelerator (a second, btDbvtBroadphase, updated on every setAabb)
            // serves ray queries only: off, so a cycle times the sweep and prune alone.
            peer->broadphase =
                new btAxisSweep3(lo, hi, (unsigned short)(n < 2 ? 2 : n), nullptr, true);
            break;
        case SAP32:
            if (!sap_world(bounds_min, bounds_max, lo, hi, err, err_size, name)) {
                delete peer;
                return nullptr;
            }
            peer->broadphase = new bt32BitAxisSweep3(lo, hi, n < 2 ? 2u : n, nullptr, true);
            break;
        case DBVT:
            peer->broadphase = new btDbvtBroadphase();
            break;
        case SIMPLE:
            peer->broadphase = new btSimpleBroadphase(n < 1 ? 1 : (int)n);
            break;
        }
        for (uint32_t i = 0; i < n; i++) {
            btBroadphaseProxy *proxy = peer->broadphase->createProxy(
                lower(boxes[i]), upper(boxes[i]), BOX_SHAPE_PROXYTYPE,
                reinterpret_cast<void *>(static_cast<uintptr_t>(i) + 1),
                int(btBroadphaseProxy::DefaultFilter), int(btBroadphaseProxy::AllFilter),
                peer->dispatcher);
            if (!proxy) {
                bench_peer_set_error(err, err_size, "%s: createProxy failed for box %u", name, i);
                delete peer;
                return nullptr;
            }
            peer->proxies[i] = proxy;
        }
        peer->broadphase->calculateOverlappingPairs(peer->dispatcher);
        return peer;
    } catch (const std::bad_alloc &) {
        bench_peer_set_error(err, err_size, "%s: out of memory for n = %u", name, n);
    } catch (const std::exception &e) {
        bench_peer_set_error(err, err_size, "%s: %s", name, e.what());
    } catch (...) {
        bench_peer_set_error(err, err_size, "%s: unknown exception", name);
    }
    delete peer;
    return nullptr;
}

int bullet_cycle(void *impl, const bpx_box *boxes)
{
    BulletPeer *peer = static_cast<BulletPeer *>(impl);
    try {
        btBroadphaseInterface *bp = peer->broadphase;
        btDispatcher *dispatcher = peer->dispatcher;
        btBroadphaseProxy *const *proxies = peer->proxies.data();
        for (uint32_t i = 0; i < peer->n; i++) {
            bp->setAabb(proxies[i], lower(boxes[i]), upper(boxes[i]), dispatcher);
        }
        bp->calculateOverlappingPairs(dispatcher);
        return 0;
    } catch (...) {
        return -1;
    }
}

uint64_t bullet_pair_count(const void *impl)
{
    const BulletPeer *peer = static_cast<const BulletPeer *>(impl);
    return (uint64_t)peer->broadphase->getOverlappingPairCache()->getNumOverlappingPairs();
}

void bullet_visit_pairs(const void *impl, bench_peer_visit_fn *visit, void *context)
{
    const BulletPeer *peer = static_cast<const BulletPeer *>(impl);
    btOverlappingPairCache *cache = peer->broadphase->getOverlappingPairCache();
    const int count = cache->getNumOverlappingPairs();
    const btBroadphasePair *pairs = cache->getOverlappingPairArrayPtr();
    for (int k = 0; k < count; k++) {
        uintptr_t a = reinterpret_cast<uintptr_t>(pairs[k].m_pProxy0->m_clientObject);
        uintptr_t b = reinterpret_cast<uintptr_t>(pairs[k].m_pProxy1->m_clientObject);
        visit(context, (uint32_t)(a - 1), (uint32_t)(b - 1));
    }
}

void bullet_destroy(void *impl)
{
    try {
        delete static_cast<BulletPeer *>(impl);
    } catch (...) {
    }
}

struct ClassTable {
    char version[16];
    char detail[4][200];
    bench_peer_class classes[4];

    ClassTable()
    {
        const int v = btGetVersion();
        btDbvtBroadphase defaults; // its settings as an engine gets them
        std::snprintf(version, sizeof version, "%d.%02d", v / 100, v % 100);
        std::snprintf(detail[SAP16], sizeof detail[SAP16],
                      "Bullet %s btAxisSweep3: incremental sweep and prune, boxes quantised "
                      "outwards to a 16-bit grid over the bounds (+1%%), ray-cast accelerator off",
                      version);
        std::snprintf(detail[SAP32], sizeof detail[SAP32],
                      "Bullet %s bt32BitAxisSweep3: incremental sweep and prune, boxes quantised "
                      "outwards to a 31-bit grid over the bounds (+1%%, float-limited), ray-cast "
                      "accelerator off",
                      version);
        std::snprintf(detail[DBVT], sizeof detail[DBVT],
                      "Bullet %s btDbvtBroadphase: two dynamic AABB trees, moved leaves refitted +"
                      "%g (gDbvtMargin), velocity prediction %g, stale pairs re-checked %d%%/cycle",
                      version, (double)gDbvtMargin, (double)defaults.m_prediction,
                      defaults.m_cupdates);
        std::snprintf(detail[SIMPLE], sizeof detail[SIMPLE],
                      "Bullet %s btSimpleBroadphase: all n(n-1)/2 pairs tested each cycle, exact "
                      "boxes",
                      version);
        static const char *const names[] = {"bullet-sap", "bullet-sap32", "bullet-dbvt",
                                            "bullet-simple"};
        static const uint32_t max_n[] = {kSap16MaxProxies, kSap32MaxProxies, UINT32_MAX,
                                         kSimpleMaxProxies};
        static const uint32_t slow_n[] = {UINT32_MAX, kSap32SlowN, UINT32_MAX, kSimpleSlowN};
        for (int k = 0; k < 4; k++) {
            classes[k].info.name = names[k];
            classes[k].info.detail = detail[k];
            classes[k].info.max_n = max_n[k];
            classes[k].info.slow_n = slow_n[k];
            classes[k].variant = k;
            classes[k].create = bullet_create;
            classes[k].cycle = bullet_cycle;
            classes[k].pair_count = bullet_pair_count;
            classes[k].visit_pairs = bullet_visit_pairs;
            classes[k].destroy = bullet_destroy;
        }
    }
};

} // namespace

extern "C" const bench_peer_class *bench_peer_bullet_classes(int *count)
{
    static const ClassTable table; // built once, thread-safe (C++11 function-local static)
    *count = 4;
    return table.classes;
}
