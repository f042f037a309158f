// btBpxBroadphase: Bullet's broad-phase interface on a bpx world. SPDX-License-Identifier: MIT
#include "bpx_bullet.h"

#include <cmath>
#include <cstdio>
#include <new>
#include <stdexcept>
#include <string>

#include <LinearMath/btAlignedAllocator.h>

struct btBpxBroadphase::Proxy : btBroadphaseProxy {
    uint32_t id = 0;
    bool dirty = false;  // listed in m_dirty: its AABB goes to bpx with the next flush
    bool parked = false; // its AABB is no valid bpx box (NaN, min > max): it pairs with nothing
    int sentGroup = 1;   // the filter bpx has for it (bpx's default: category 1, every mask bit)
    int sentMask = -1;
};

namespace
{

// Throws for a bpx error: bad_alloc when out of memory, else runtime_error naming the call (an
// error here is a bug in the adapter: it passes only ids it holds and boxes it checked).
void check(bpx_status status, bpx_world *world, const char *what)
{
    if (status == BPX_OK)
        return;
    if (status == BPX_ERR_OUT_OF_MEMORY)
        throw std::bad_alloc();
    const bpx_error *error = bpx_world_error(world);
    throw std::runtime_error(std::string("btBpxBroadphase: ") + what + ": " +
                             (error && error->message[0] ? error->message
                                                         : bpx_status_string(status)));
}

// The proxy's AABB as a bpx box; false (and a point at the origin) when bpx would refuse it.
bool to_box(const btVector3 &lo, const btVector3 &hi, bpx_box &box)
{
    bool valid = true;
    for (int a = 0; a < 3; a++) {
        box.min[a] = lo[a];
        box.max[a] = hi[a];
        if (!std::isfinite(box.min[a]) || !std::isfinite(box.max[a]) || box.min[a] > box.max[a])
            valid = false;
    }
    if (!valid)
        box = bpx_box{{0, 0, 0}, {0, 0, 0}};
    return valid;
}

bool same_xyz(const btVector3 &a, const btVector3 &b)
{
    return a.x() == b.x() && a.y() == b.y() && a.z() == b.z();
}

} // namespace

btBpxBroadphase::btBpxBroadphase(btOverlappingPairCache *pairCache, const bpx_world_def *def)
{
    m_def = def ? *def : bpx_default_world_def();
    m_def.track_events = true; // the cache is kept by the pairs that began and ended
    bpx_status status = bpx_world_create(&m_def, &m_world);
    if (status == BPX_ERR_OUT_OF_MEMORY)
        throw std::bad_alloc();
    if (status != BPX_OK)
        throw std::invalid_argument(std::string("btBpxBroadphase: bpx_world_create: ") +
                                    bpx_status_string(status));
    m_pairCache = pairCache;
    if (!m_pairCache) { // as btDbvtBroadphase makes its own
        void *memory = btAlignedAlloc(sizeof(btHashedOverlappingPairCache), 16);
        m_pairCache = new (memory) btHashedOverlappingPairCache();
        m_ownsPairCache = true;
    }
}

btBpxBroadphase::~btBpxBroadphase()
{
    for (Proxy *proxy : m_proxies)
        delete proxy;
    bpx_world_destroy(m_world);
    if (m_ownsPairCache) {
        m_pairCache->~btOverlappingPairCache();
        btAlignedFree(m_pairCache);
    }
}

btBroadphaseProxy *btBpxBroadphase::createProxy(const btVector3 &aabbMin, const btVector3 &aabbMax,
                                                int /*shapeType*/, void *userPtr,
                                                int collisionFilterGroup, int collisionFilterMask,
                                                btDispatcher * /*dispatcher*/)
{
    Proxy *proxy = new Proxy();
    proxy->m_clientObject = userPtr;
    proxy->m_collisionFilterGroup = collisionFilterGroup;
    proxy->m_collisionFilterMask = collisionFilterMask;
    proxy->m_aabbMin = aabbMin;
    proxy->m_aabbMax = aabbMax;
    bpx_box box;
    bool valid = to_box(aabbMin, aabbMax, box);
    bpx_status status = bpx_world_add_boxes(m_world, &box, 1, &proxy->id);
    if (status != BPX_OK) {
        delete proxy;
        check(status, m_world, "add_boxes");
    }
    proxy->m_uniqueId = ++m_gid;
    if (proxy->id >= m_proxies.size())
        m_proxies.resize(proxy->id + 1, nullptr);
    m_proxies[proxy->id] = proxy;
    m_liveCount++;
    // Bullet's rule, (group_a & mask_b) && (group_b & mask_a), is bpx's filter: filtered pairs
    // never reach the cache. Unfiltered proxies (group 1, all mask bits) need no call.
    if (!valid || collisionFilterGroup != 1 || collisionFilterMask != -1)
        sendFilter(proxy, !valid);
    return proxy;
}

void btBpxBroadphase::destroyProxy(btBroadphaseProxy *absproxy, btDispatcher *dispatcher)
{
    Proxy *proxy = static_cast<Proxy *>(absproxy);
    check(bpx_world_remove_boxes(m_world, &proxy->id, 1), m_world, "remove_boxes");
    // bpx reports the box's pairs as ended with the next collide; they leave the cache now, as
    // with btDbvtBroadphase, and the null slot tells calculateOverlappingPairs to skip them.
    // bpx hands the id out again only after that collide.
    m_proxies[proxy->id] = nullptr;
    m_liveCount--;
    m_pairCache->removeOverlappingPairsContainingProxy(proxy, dispatcher);
    delete proxy;
}

void btBpxBroadphase::setAabb(btBroadphaseProxy *absproxy, const btVector3 &aabbMin,
                              const btVector3 &aabbMax, btDispatcher * /*dispatcher*/)
{
    Proxy *proxy = static_cast<Proxy *>(absproxy);
    if (!proxy->dirty) {
        // btCollisionWorld sets every object's AABB each step, resting and static ones too.
        if (same_xyz(aabbMin, proxy->m_aabbMin) && same_xyz(aabbMax, proxy->m_aabbMax))
            return;
        proxy->dirty = true;
        m_dirty.push_back(proxy->id);
    }
    proxy->m_aabbMin = aabbMin;
    proxy->m_aabbMax = aabbMax;
}

void btBpxBroadphase::getAabb(btBroadphaseProxy *proxy, btVector3 &aabbMin,
                              btVector3 &aabbMax) const
{
    aabbMin = proxy->m_aabbMin;
    aabbMax = proxy->m_aabbMax;
}

void btBpxBroadphase::sendFilter(Proxy *proxy, bool parked)
{
    proxy->parked = parked;
    proxy->sentGroup = proxy->m_collisionFilterGroup;
    proxy->sentMask = proxy->m_collisionFilterMask;
    uint32_t category = parked ? 0 : (uint32_t)proxy->sentGroup;
    uint32_t mask = parked ? 0 : (uint32_t)proxy->sentMask;
    check(bpx_world_set_filters(m_world, &proxy->id, &category, &mask, 1), m_world,
          "set_filters");
}

// The AABBs set since the last flush go to bpx in one batch (and a filter changed on a moved
// proxy's fields, as btDbvtBroadphase sees such a change when the proxy moves).
void btBpxBroadphase::flushMoves()
{
    if (m_dirty.empty())
        return;
    m_moveIds.clear();
    m_moveBoxes.clear();
    for (uint32_t id : m_dirty) {
        Proxy *proxy = m_proxies[id];
        if (!proxy) // destroyed since its setAabb
            continue;
        proxy->dirty = false;
        bpx_box box;
        bool valid = to_box(proxy->m_aabbMin, proxy->m_aabbMax, box);
        if (valid == proxy->parked || proxy->sentGroup != proxy->m_collisionFilterGroup ||
            proxy->sentMask != proxy->m_collisionFilterMask)
            sendFilter(proxy, !valid);
        m_moveIds.push_back(id);
        m_moveBoxes.push_back(box);
    }
    m_dirty.clear();
    check(bpx_world_move_boxes(m_world, m_moveIds.data(), m_moveBoxes.data(),
                               (uint32_t)m_moveIds.size()),
          m_world, "move_boxes");
}

void btBpxBroadphase::calculateOverlappingPairs(btDispatcher *dispatcher)
{
    flushMoves();
    check(bpx_world_collide(m_world), m_world, "collide");
    bpx_pair_events events;
    check(bpx_world_pair_events(m_world, &events), m_world, "pair_events");
    // Ended first: a pair of a destroyed proxy left the cache with it (its slot is null).
    for (size_t k = 0; k < events.ended_count; k++) {
        Proxy *a = m_proxies[events.ended[k].i], *b = m_proxies[events.ended[k].j];
        if (a && b)
            m_pairCache->removeOverlappingPair(a, b, dispatcher);
    }
    // The cache applies its own needsBroadphaseCollision (group/mask, overlap filter callback).
    for (size_t k = 0; k < events.began_count; k++)
        m_pairCache->addOverlappingPair(m_proxies[events.began[k].i],
                                        m_proxies[events.began[k].j]);
}

// Calls callback.process for each proxy the query hits, in bpx's order (by fraction, then id);
// with no query (one bpx would refuse: an infinite or NaN coordinate), for every proxy: nothing
// is missed, and Bullet's callbacks make the exact test.
void btBpxBroadphase::visit(const bpx_query *query, btBroadphaseAabbCallback &callback)
{
    flushMoves();
    // A callback may query again: the outer query's ids stay in m_hitIds, the inner in its own.
    std::vector<uint32_t> nested;
    std::vector<uint32_t> &ids = m_queryDepth == 0 ? m_hitIds : nested;
    ids.clear();
    size_t count = 0;
    bpx_status status = query ? bpx_world_query(m_world, query, nullptr, 0, &count)
                              : BPX_ERR_INVALID_ARGUMENT;
    if (status == BPX_ERR_CAPACITY) { // the usual case: the hits are read where bpx keeps them
        size_t total = 0;
        const bpx_hit *hits = bpx_world_query_hits(m_world, nullptr, nullptr, &total);
        for (size_t k = 0; k < total; k++)
            ids.push_back(hits[k].id);
    } else if (status == BPX_ERR_OUT_OF_MEMORY) {
        throw std::bad_alloc();
    } else if (status != BPX_OK) {
        for (uint32_t id = 0; id < m_proxies.size(); id++)
            if (m_proxies[id])
                ids.push_back(id);
    }
    m_queryDepth++;
    for (uint32_t id : ids) {
        Proxy *proxy = m_proxies[id];
        if (proxy) // a callback may have destroyed it
            callback.process(proxy);
    }
    m_queryDepth--;
}

void btBpxBroadphase::rayTest(const btVector3 &rayFrom, const btVector3 &rayTo,
                              btBroadphaseRayCallback &rayCallback, const btVector3 &aabbMin,
                              const btVector3 &aabbMax)
{
    // The cast shape's box at the start; for a ray, the point rayFrom.
    bpx_box start;
    if (!to_box(rayFrom + aabbMin, rayFrom + aabbMax, start)) {
        visit(nullptr, rayCallback);
        return;
    }
    const btVector3 delta = rayTo - rayFrom;
    const float length = delta.length();
    // Bullet's callbacks keep m_lambda_max along the unit direction (btDbvtBroadphase clips the
    // ray there): as a fraction of delta.
    float fraction = length > 0 ? rayCallback.m_lambda_max / length : 0.0f;
    if (!(fraction >= 0)) // NaN
        fraction = 0;
    const float direction[3] = {delta.x(), delta.y(), delta.z()};
    bpx_query query;
    if (!(length > 0) || fraction == 0) {
        query = bpx_query_box(start);
    } else if (same_xyz(aabbMin, btVector3(0, 0, 0)) && same_xyz(aabbMax, btVector3(0, 0, 0))) {
        const float origin[3] = {rayFrom.x(), rayFrom.y(), rayFrom.z()};
        query = bpx_query_ray(origin, direction, fraction, false);
    } else {
        query = bpx_query_sweep(start, direction, fraction, false);
    }
    visit(&query, rayCallback);
}

void btBpxBroadphase::aabbTest(const btVector3 &aabbMin, const btVector3 &aabbMax,
                               btBroadphaseAabbCallback &callback)
{
    bpx_box box;
    if (!to_box(aabbMin, aabbMax, box)) {
        visit(nullptr, callback);
        return;
    }
    const bpx_query query = bpx_query_box(box);
    visit(&query, callback);
}

void btBpxBroadphase::getBroadphaseAabb(btVector3 &aabbMin, btVector3 &aabbMax) const
{
    bool any = false;
    for (const Proxy *proxy : m_proxies) {
        if (!proxy || proxy->parked)
            continue;
        if (!any) {
            aabbMin = proxy->m_aabbMin;
            aabbMax = proxy->m_aabbMax;
            any = true;
        } else {
            aabbMin.setMin(proxy->m_aabbMin);
            aabbMax.setMax(proxy->m_aabbMax);
        }
    }
    if (!any)
        aabbMin = aabbMax = btVector3(0, 0, 0);
}

void btBpxBroadphase::resetPool(btDispatcher * /*dispatcher*/)
{
    if (m_liveCount != 0) // as btDbvtBroadphase: only an empty broad phase starts again
        return;
    bpx_world *fresh = nullptr;
    bpx_status status = bpx_world_create(&m_def, &fresh);
    if (status == BPX_ERR_OUT_OF_MEMORY)
        throw std::bad_alloc();
    if (status != BPX_OK)
        return; // it worked in the constructor; keep the old world rather than none
    bpx_world_destroy(m_world);
    m_world = fresh;
    m_proxies.clear();
    m_dirty.clear();
    m_gid = 0;
}

void btBpxBroadphase::printStats()
{
    bpx_cycle_stats stats = bpx_world_stats(m_world);
    std::printf("btBpxBroadphase: %d proxies (bpx ids %u), %d pairs in the cache, backend %s; "
                "last collide: %llu pairs, %.1f us compare, %.1f us emit\n",
                m_liveCount, stats.box_count, m_pairCache->getNumOverlappingPairs(),
                bpx_backend_name(bpx_world_backend(m_world)),
                (unsigned long long)stats.pair_count, stats.compare_ns / 1e3,
                stats.emit_ns / 1e3);
}
