// test_bullet: btBpxBroadphase against btDbvtBroadphase. SPDX-License-Identifier: MIT
//
// 1. Dynamics scenes (falling stacks, a pile of spheres and boxes, jointed chains whose linked
//    bodies do not collide), stepped in two worlds that differ only in the broad phase. Each
//    step: btBpxBroadphase's pair cache holds exactly the pairs whose AABBs overlap (a brute
//    force check), which are btDbvtBroadphase's cache pairs less those whose AABBs no longer
//    overlap (its tree's enlarged boxes, its lazy removal); the contact manifolds (body pair,
//    contact count) are the same; and so are the bodies' transforms, bit for bit.
// 2. Proxy churn straight on the broad phases: create, destroy, move, teleport, filters, an
//    overlap filter callback, NaN boxes, resetPool.
// 3. Queries on a settled pile: aabbTest visits, and btCollisionWorld's ray and convex casts.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "bullet_scenes.h"

using namespace bullet_scenes;

namespace
{

int failures = 0;

#define CHECK(cond, ...)                                                                         \
    do {                                                                                         \
        if (!(cond)) {                                                                           \
            std::printf("FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond);                          \
            std::printf(__VA_ARGS__);                                                            \
            std::printf("\n");                                                                   \
            failures++;                                                                          \
        }                                                                                        \
    } while (0)

using Pair = std::pair<int, int>;
using Pairs = std::vector<Pair>;

// A proxy's index: its collision object's user index in the worlds, client pointer - 1 in churn.
int (*proxy_index)(const btBroadphaseProxy *) = nullptr;

int object_index(const btBroadphaseProxy *p)
{
    return static_cast<const btCollisionObject *>(p->m_clientObject)->getUserIndex();
}

int client_index(const btBroadphaseProxy *p)
{
    return (int)(reinterpret_cast<uintptr_t>(p->m_clientObject) - 1);
}

Pair make_pair_of(const btBroadphaseProxy *a, const btBroadphaseProxy *b)
{
    int i = proxy_index(a), j = proxy_index(b);
    return i < j ? Pair(i, j) : Pair(j, i);
}

bool overlap(const btBroadphaseProxy *a, const btBroadphaseProxy *b)
{
    for (int k = 0; k < 3; k++)
        if (!(a->m_aabbMin[k] <= b->m_aabbMax[k] && b->m_aabbMin[k] <= a->m_aabbMax[k]))
            return false;
    return true;
}

// The cache's pairs; exact_only keeps those whose proxies' AABBs overlap.
Pairs cache_pairs(const btOverlappingPairCache *cache, bool exact_only)
{
    Pairs out;
    const btBroadphasePair *p = cache->getOverlappingPairArrayPtr();
    for (int k = 0; k < cache->getNumOverlappingPairs(); k++)
        if (!exact_only || overlap(p[k].m_pProxy0, p[k].m_pProxy1))
            out.push_back(make_pair_of(p[k].m_pProxy0, p[k].m_pProxy1));
    std::sort(out.begin(), out.end());
    return out;
}

// Every pair of the proxies whose AABBs overlap and that the cache would take, brute force.
Pairs brute_pairs(const std::vector<btBroadphaseProxy *> &proxies,
                  const btOverlappingPairCache *cache)
{
    Pairs out;
    for (size_t a = 0; a < proxies.size(); a++)
        for (size_t b = a + 1; b < proxies.size(); b++)
            if (proxies[a] && proxies[b] && overlap(proxies[a], proxies[b]) &&
                cache->needsBroadphaseCollision(proxies[a], proxies[b]))
                out.push_back(make_pair_of(proxies[a], proxies[b]));
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<btBroadphaseProxy *> sim_proxies(Sim &sim)
{
    std::vector<btBroadphaseProxy *> out;
    for (btRigidBody *b : sim.bodies)
        out.push_back(b->getBroadphaseHandle());
    return out;
}

// (body, body, contacts) of every manifold with contacts, sorted.
std::vector<std::tuple<int, int, int>> contacts(Sim &sim)
{
    std::vector<std::tuple<int, int, int>> out;
    for (int k = 0; k < sim.dispatcher.getNumManifolds(); k++) {
        btPersistentManifold *m = sim.dispatcher.getManifoldByIndexInternal(k);
        if (m->getNumContacts() == 0)
            continue;
        int i = m->getBody0()->getUserIndex(), j = m->getBody1()->getUserIndex();
        out.emplace_back(std::min(i, j), std::max(i, j), m->getNumContacts());
    }
    std::sort(out.begin(), out.end());
    return out;
}

bool same_transforms(Sim &a, Sim &b)
{
    for (size_t k = 0; k < a.bodies.size(); k++) {
        const btTransform &ta = a.bodies[k]->getWorldTransform();
        const btTransform &tb = b.bodies[k]->getWorldTransform();
        for (int r = 0; r < 3; r++)
            if (std::memcmp(&ta.getBasis()[r], &tb.getBasis()[r], 3 * sizeof(btScalar)) != 0)
                return false;
        if (std::memcmp(&ta.getOrigin(), &tb.getOrigin(), 3 * sizeof(btScalar)) != 0)
            return false;
    }
    return true;
}

void prepare(Sim &sim)
{
    // Narrow phase and solver in unique-id order, so both worlds see their pairs in one order
    // whatever order their caches hold them in; no sleeping, which islands (the caches' pairs)
    // would decide.
    sim.world->getDispatchInfo().m_deterministicOverlappingPairs = true;
    for (btRigidBody *b : sim.bodies)
        b->setActivationState(DISABLE_DEACTIVATION);
}

template <class Build>
void run_scene(const char *name, Build build, int steps)
{
    proxy_index = object_index;
    Sim dbvt(Broadphase::Dbvt), bpx(Broadphase::Bpx);
    build(dbvt);
    build(bpx);
    prepare(dbvt);
    prepare(bpx);
    size_t pair_total = 0, contact_total = 0, dbvt_extra = 0;
    int same_steps = 0, failures_before = failures;
    for (int step = 0; step < steps && failures == failures_before; step++) {
        dbvt.world->stepSimulation(1.0f / 60, 1, 1.0f / 60);
        bpx.world->stepSimulation(1.0f / 60, 1, 1.0f / 60);
        const btOverlappingPairCache *cache_b = bpx.broadphase->getOverlappingPairCache();
        const btOverlappingPairCache *cache_d = dbvt.broadphase->getOverlappingPairCache();
        Pairs in_bpx = cache_pairs(cache_b, false);
        Pairs truth = brute_pairs(sim_proxies(bpx), cache_b);
        Pairs dbvt_exact = cache_pairs(cache_d, true);
        Pairs dbvt_truth = brute_pairs(sim_proxies(dbvt), cache_d);
        CHECK(in_bpx == truth, "%s step %d: bpx cache %zu pairs, brute force %zu", name, step,
              in_bpx.size(), truth.size());
        CHECK(dbvt_exact == dbvt_truth, "%s step %d: dbvt misses a pair", name, step);
        CHECK(in_bpx == dbvt_exact, "%s step %d: bpx %zu pairs, dbvt %zu overlapping", name,
              step, in_bpx.size(), dbvt_exact.size());
        auto cb = contacts(bpx), cd = contacts(dbvt);
        CHECK(cb == cd, "%s step %d: contact manifolds bpx %zu, dbvt %zu", name, step, cb.size(),
              cd.size());
        CHECK(same_transforms(bpx, dbvt), "%s step %d: transforms differ", name, step);
        same_steps += failures == failures_before;
        pair_total += in_bpx.size();
        contact_total += cb.size();
        dbvt_extra += cache_d->getNumOverlappingPairs() - dbvt_exact.size();
    }
    std::printf("%-7s %4zu bodies, %d steps: %d identical (pairs, contact manifolds, transforms); "
                "%zu pairs and %zu touching pairs in all; btDbvtBroadphase held %zu more pairs "
                "whose AABBs did not overlap\n",
                name, bpx.bodies.size(), steps, same_steps, pair_total, contact_total,
                dbvt_extra);
}

// --- Churn -------------------------------------------------------------------------------------

struct RejectSevenths : btOverlapFilterCallback {
    bool needBroadphaseCollision(btBroadphaseProxy *a, btBroadphaseProxy *b) const override
    {
        bool groups = (a->m_collisionFilterGroup & b->m_collisionFilterMask) != 0 &&
                      (b->m_collisionFilterGroup & a->m_collisionFilterMask) != 0;
        return groups && (client_index(a) + client_index(b)) % 7 != 0;
    }
};

void churn()
{
    proxy_index = client_index;
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase dbvt;
    btBpxBroadphase bpx;
    RejectSevenths reject;
    dbvt.getOverlappingPairCache()->setOverlapFilterCallback(&reject);
    bpx.getOverlappingPairCache()->setOverlapFilterCallback(&reject);
    const int slots = 300;
    std::vector<btBroadphaseProxy *> pd(slots, nullptr), pb(slots, nullptr);
    Lcg rng(5);
    const int groups[] = {1, 2, 4, 1};
    const int masks[] = {-1, -1 ^ 2, 1 | 4, -1};
    auto random_box = [&](btVector3 &lo, btVector3 &hi) {
        btVector3 c(rng.range(0, 30), rng.range(0, 30), rng.range(0, 30));
        btVector3 h(rng.range(0.2f, 2), rng.range(0.2f, 2), rng.range(0.2f, 2));
        lo = c - h;
        hi = c + h;
    };
    size_t pair_total = 0;
    int rounds = 150;
    for (int round = 0; round < rounds; round++) {
        for (int op = 0; op < 60; op++) {
            int s = (int)(rng.next() * slots);
            float what = rng.next();
            btVector3 lo, hi;
            if (!pd[s]) { // create
                random_box(lo, hi);
                int f = (int)(rng.next() * 4);
                void *client = reinterpret_cast<void *>((uintptr_t)s + 1);
                pd[s] = dbvt.createProxy(lo, hi, 0, client, groups[f], masks[f], &dispatcher);
                pb[s] = bpx.createProxy(lo, hi, 0, client, groups[f], masks[f], &dispatcher);
            } else if (what < 0.25f) { // destroy
                dbvt.destroyProxy(pd[s], &dispatcher);
                bpx.destroyProxy(pb[s], &dispatcher);
                pd[s] = pb[s] = nullptr;
            } else if (what < 0.4f) { // teleport
                random_box(lo, hi);
                dbvt.setAabb(pd[s], lo, hi, &dispatcher);
                bpx.setAabb(pb[s], lo, hi, &dispatcher);
            } else { // move a little, twice (the second setAabb of a step wins)
                for (int twice = 0; twice < 2; twice++) {
                    btVector3 d(rng.range(-0.3f, 0.3f), rng.range(-0.3f, 0.3f),
                                rng.range(-0.3f, 0.3f));
                    lo = pb[s]->m_aabbMin + d;
                    hi = pb[s]->m_aabbMax + d;
                    dbvt.setAabb(pd[s], lo, hi, &dispatcher);
                    bpx.setAabb(pb[s], lo, hi, &dispatcher);
                }
            }
        }
        dbvt.calculateOverlappingPairs(&dispatcher);
        bpx.calculateOverlappingPairs(&dispatcher);
        Pairs in_bpx = cache_pairs(bpx.getOverlappingPairCache(), false);
        Pairs truth = brute_pairs(pb, bpx.getOverlappingPairCache());
        Pairs dbvt_exact = cache_pairs(dbvt.getOverlappingPairCache(), true);
        CHECK(in_bpx == truth, "churn round %d: bpx %zu pairs, brute force %zu", round,
              in_bpx.size(), truth.size());
        CHECK(in_bpx == dbvt_exact, "churn round %d: bpx %zu pairs, dbvt %zu overlapping", round,
              in_bpx.size(), dbvt_exact.size());
        pair_total += in_bpx.size();
    }
    CHECK(bpx.proxyCount() == (int)std::count_if(pb.begin(), pb.end(),
                                                 [](btBroadphaseProxy *p) { return p; }),
          "proxy count");

    for (int s = 0; s < slots; s++) { // empty both, then resetPool
        if (pd[s]) {
            dbvt.destroyProxy(pd[s], &dispatcher);
            bpx.destroyProxy(pb[s], &dispatcher);
            pd[s] = pb[s] = nullptr;
        }
    }
    bpx.calculateOverlappingPairs(&dispatcher);
    CHECK(bpx.getOverlappingPairCache()->getNumOverlappingPairs() == 0, "pairs left");
    bpx.resetPool(&dispatcher);
    bpx.getOverlappingPairCache()->setOverlapFilterCallback(nullptr);
    // A NaN box pairs with nothing until it is valid again.
    btVector3 lo(1, 1, 1), hi(2, 2, 2), nan(std::nanf(""), 0, 0);
    btBroadphaseProxy *p1 = bpx.createProxy(lo, hi, 0, (void *)1, 1, -1, &dispatcher);
    btBroadphaseProxy *p2 = bpx.createProxy(lo + nan, hi, 0, (void *)2, 1, -1, &dispatcher);
    CHECK(p1->m_uniqueId == 1 && p2->m_uniqueId == 2, "resetPool: unique ids %d %d",
          p1->m_uniqueId, p2->m_uniqueId);
    bpx.calculateOverlappingPairs(&dispatcher);
    CHECK(bpx.getOverlappingPairCache()->getNumOverlappingPairs() == 0, "a NaN box paired");
    bpx.setAabb(p2, lo, hi, &dispatcher);
    bpx.calculateOverlappingPairs(&dispatcher);
    CHECK(bpx.getOverlappingPairCache()->getNumOverlappingPairs() == 1, "valid again: no pair");
    bpx.setAabb(p2, lo, hi + nan, &dispatcher);
    bpx.calculateOverlappingPairs(&dispatcher);
    CHECK(bpx.getOverlappingPairCache()->getNumOverlappingPairs() == 0, "NaN again: a pair");
    btVector3 wlo, whi;
    bpx.getBroadphaseAabb(wlo, whi);
    CHECK(wlo == lo && whi == hi, "getBroadphaseAabb");
    bpx.destroyProxy(p1, &dispatcher);
    bpx.destroyProxy(p2, &dispatcher);
    std::printf("churn   %d rounds of 60 creates, destroys, moves and teleports over %d slots "
                "with filters: %zu pairs in all, the same as btDbvtBroadphase's overlapping "
                "ones and brute force; NaN boxes, resetPool\n",
                rounds, slots, pair_total);
}

// --- Queries -----------------------------------------------------------------------------------

struct Recorder : btBroadphaseAabbCallback {
    std::vector<int> seen;
    bool process(const btBroadphaseProxy *proxy) override
    {
        seen.push_back(object_index(proxy));
        return true;
    }
};

void queries()
{
    proxy_index = object_index;
    Sim dbvt(Broadphase::Dbvt), bpx(Broadphase::Bpx);
    for (Sim *s : {&dbvt, &bpx}) {
        scene_pile(*s, 200);
        prepare(*s);
        for (int step = 0; step < 90; step++)
            s->world->stepSimulation(1.0f / 60, 1, 1.0f / 60);
    }
    CHECK(same_transforms(dbvt, bpx), "queries: the piles differ");
    Lcg rng(6);
    int boxes = 0, rays = 0, sweeps = 0;
    size_t box_hits = 0, ray_hits = 0;
    for (int q = 0; q < 200; q++) {
        btVector3 c(rng.range(-6, 6), rng.range(-1, 8), rng.range(-6, 6));
        btVector3 h(rng.range(0, 1.5f), rng.range(0, 1.5f), rng.range(0, 1.5f));
        Recorder rd, rb;
        dbvt.broadphase->aabbTest(c - h, c + h, rd);
        bpx.broadphase->aabbTest(c - h, c + h, rb);
        std::vector<int> truth;
        for (btRigidBody *b : bpx.bodies) {
            btBroadphaseProxy *p = b->getBroadphaseHandle();
            bool hit = true;
            for (int k = 0; k < 3; k++)
                hit = hit && p->m_aabbMin[k] <= c[k] + h[k] && c[k] - h[k] <= p->m_aabbMax[k];
            if (hit)
                truth.push_back(b->getUserIndex());
        }
        std::sort(rb.seen.begin(), rb.seen.end());
        std::vector<int> dbvt_exact;
        for (int i : rd.seen)
            if (std::binary_search(truth.begin(), truth.end(), i))
                dbvt_exact.push_back(i);
        std::sort(dbvt_exact.begin(), dbvt_exact.end());
        CHECK(rb.seen == truth, "aabbTest %d: %zu visited, %zu overlap", q, rb.seen.size(),
              truth.size());
        CHECK(dbvt_exact == truth, "aabbTest %d: dbvt misses one", q);
        boxes++;
        box_hits += truth.size();

        // A ray through the pit, all hits and the closest, through the worlds.
        btVector3 from(rng.range(-8, 8), rng.range(0, 10), rng.range(-8, 8));
        btVector3 to(rng.range(-8, 8), rng.range(-1, 6), rng.range(-8, 8));
        btCollisionWorld::AllHitsRayResultCallback all_d(from, to), all_b(from, to);
        dbvt.world->rayTest(from, to, all_d);
        bpx.world->rayTest(from, to, all_b);
        auto hits = [](const btCollisionWorld::AllHitsRayResultCallback &cb) {
            std::vector<std::pair<int, float>> out;
            for (int k = 0; k < cb.m_collisionObjects.size(); k++)
                out.emplace_back(cb.m_collisionObjects[k]->getUserIndex(), cb.m_hitFractions[k]);
            std::sort(out.begin(), out.end());
            return out;
        };
        CHECK(hits(all_d) == hits(all_b), "ray %d: %d hits dbvt, %d bpx", q,
              all_d.m_collisionObjects.size(), all_b.m_collisionObjects.size());
        btCollisionWorld::ClosestRayResultCallback one_d(from, to), one_b(from, to);
        dbvt.world->rayTest(from, to, one_d);
        bpx.world->rayTest(from, to, one_b);
        CHECK(one_d.m_collisionObject == nullptr
                  ? one_b.m_collisionObject == nullptr
                  : one_b.m_collisionObject &&
                        one_d.m_collisionObject->getUserIndex() ==
                            one_b.m_collisionObject->getUserIndex() &&
                        one_d.m_closestHitFraction == one_b.m_closestHitFraction,
              "closest ray %d", q);
        rays++;
        ray_hits += all_b.m_collisionObjects.size();

        // A sphere swept along the same segment: the closest hit.
        btSphereShape ball(0.3f);
        btTransform t0(btQuaternion::getIdentity(), from), t1(btQuaternion::getIdentity(), to);
        btCollisionWorld::ClosestConvexResultCallback sw_d(from, to), sw_b(from, to);
        dbvt.world->convexSweepTest(&ball, t0, t1, sw_d);
        bpx.world->convexSweepTest(&ball, t0, t1, sw_b);
        CHECK(sw_d.m_hitCollisionObject == nullptr
                  ? sw_b.m_hitCollisionObject == nullptr
                  : sw_b.m_hitCollisionObject &&
                        sw_d.m_hitCollisionObject->getUserIndex() ==
                            sw_b.m_hitCollisionObject->getUserIndex() &&
                        sw_d.m_closestHitFraction == sw_b.m_closestHitFraction,
              "sweep %d", q);
        sweeps++;
    }
    std::printf("queries %d aabbTests (%zu proxies in all), %d rays (all hits and closest; %zu "
                "hits), %d sphere sweeps on a settled pile of %zu bodies: as btDbvtBroadphase\n",
                boxes, box_hits, rays, ray_hits, sweeps, bpx.bodies.size());
}

} // namespace

int main()
{
    run_scene("stacks", [](Sim &s) { scene_stacks(s, 5, 8); }, 200);
    run_scene("pile", [](Sim &s) { scene_pile(s, 300); }, 200);
    run_scene("chain", [](Sim &s) { scene_chain(s, 20); }, 200);
    churn();
    queries();
    if (failures) {
        std::printf("test_bullet: %d failures\n", failures);
        return 1;
    }
    std::printf("test_bullet: ok\n");
    return 0;
}
