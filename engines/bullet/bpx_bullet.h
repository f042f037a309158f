// btBpxBroadphase: a drop-in Bullet 3 broad phase backed by a bpx world. SPDX-License-Identifier: MIT
//
//   btBpxBroadphase broadphase;                 // instead of btDbvtBroadphase
//   btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
//
// Each proxy is a bpx box with a stable id. setAabb only records the move; the moves go to bpx in
// one batch when Bullet calls calculateOverlappingPairs (once a step, from
// btCollisionWorld::performDiscreteCollisionDetection), which then collides and hands the pairs
// that began and ended to the overlapping-pair cache (addOverlappingPair, removeOverlappingPair).
// The cache therefore holds exactly the pairs whose AABBs overlap (closed intervals: touching
// boxes overlap) and pass Bullet's group/mask filter, after every calculateOverlappingPairs;
// btDbvtBroadphase holds a superset (its tree's enlarged boxes, and pairs it removes lazily).
// rayTest and aabbTest run bpx's queries. docs/bullet.md says what differs from btDbvtBroadphase.
#pragma once

#include <cstdint>
#include <vector>

#include <BulletCollision/BroadphaseCollision/btBroadphaseInterface.h>
#include <BulletCollision/BroadphaseCollision/btBroadphaseProxy.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>
#include <bpx/bpx.h>

#if defined(BT_USE_DOUBLE_PRECISION)
#error "btBpxBroadphase needs single-precision Bullet: bpx's boxes are floats"
#endif

class btBpxBroadphase : public btBroadphaseInterface
{
public:
    /// pairCache: as btDbvtBroadphase's, NULL for a btHashedOverlappingPairCache of its own.
    /// def: the bpx world's definition (backend, worker threads); NULL for bpx's defaults.
    /// track_events is always set. Throws std::bad_alloc if bpx cannot create the world.
    explicit btBpxBroadphase(btOverlappingPairCache *pairCache = nullptr,
                             const bpx_world_def *def = nullptr);
    ~btBpxBroadphase() override;
    btBpxBroadphase(const btBpxBroadphase &) = delete;
    btBpxBroadphase &operator=(const btBpxBroadphase &) = delete;

    btBroadphaseProxy *createProxy(const btVector3 &aabbMin, const btVector3 &aabbMax,
                                   int shapeType, void *userPtr, int collisionFilterGroup,
                                   int collisionFilterMask, btDispatcher *dispatcher) override;
    void destroyProxy(btBroadphaseProxy *proxy, btDispatcher *dispatcher) override;
    void setAabb(btBroadphaseProxy *proxy, const btVector3 &aabbMin, const btVector3 &aabbMax,
                 btDispatcher *dispatcher) override;
    void getAabb(btBroadphaseProxy *proxy, btVector3 &aabbMin, btVector3 &aabbMax) const override;

    /// Calls rayCallback.process for every proxy whose AABB, grown by -aabbMax .. -aabbMin (the
    /// cast shape's box, as btCollisionWorld::convexSweepTest passes it), the segment from
    /// rayFrom hits within m_lambda_max along the unit direction to rayTo; nearest first.
    void rayTest(const btVector3 &rayFrom, const btVector3 &rayTo,
                 btBroadphaseRayCallback &rayCallback,
                 const btVector3 &aabbMin = btVector3(0, 0, 0),
                 const btVector3 &aabbMax = btVector3(0, 0, 0)) override;
    /// Calls callback.process for every proxy whose AABB overlaps [aabbMin, aabbMax], by id.
    void aabbTest(const btVector3 &aabbMin, const btVector3 &aabbMax,
                  btBroadphaseAabbCallback &callback) override;

    void calculateOverlappingPairs(btDispatcher *dispatcher) override;

    btOverlappingPairCache *getOverlappingPairCache() override { return m_pairCache; }
    const btOverlappingPairCache *getOverlappingPairCache() const override { return m_pairCache; }

    /// The union of all proxies' AABBs (a point at the origin when there are none).
    void getBroadphaseAabb(btVector3 &aabbMin, btVector3 &aabbMax) const override;
    /// With no proxies left: a fresh bpx world, ids and unique ids from the start again.
    void resetPool(btDispatcher *dispatcher) override;
    void printStats() override;

    /// The bpx world, for its statistics (bpx_world_stats) and backend. Do not change its boxes.
    bpx_world *world() { return m_world; }
    int proxyCount() const { return m_liveCount; }

private:
    struct Proxy;
    void flushMoves();
    void sendFilter(Proxy *proxy, bool parked);
    void visit(const bpx_query *query, btBroadphaseAabbCallback &callback);

    bpx_world_def m_def;
    bpx_world *m_world = nullptr;
    btOverlappingPairCache *m_pairCache = nullptr;
    bool m_ownsPairCache = false;
    std::vector<Proxy *> m_proxies;  // by bpx id; null for a free id
    std::vector<uint32_t> m_dirty;   // ids whose AABB changed since the last flush
    std::vector<uint32_t> m_moveIds; // the flush's batch, kept between steps
    std::vector<bpx_box> m_moveBoxes;
    std::vector<uint32_t> m_hitIds; // a query's hits, copied: callbacks may query again
    int m_liveCount = 0;
    int m_gid = 0; // unique ids 1, 2, ... as btDbvtBroadphase hands them out
    int m_queryDepth = 0;
};
