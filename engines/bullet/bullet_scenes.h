// Bullet dynamics scenes for test_bullet and bpx_bulletbench, built the same way whatever the
// broad phase, so two worlds differ only in it. SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include <btBulletDynamicsCommon.h>

#include "bpx_bullet.h"

namespace bullet_scenes
{

// A dynamics world that times its broad phase: updateAabbs (each object's AABB from its shape,
// then setAabb) and computeOverlappingPairs (calculateOverlappingPairs).
class TimedWorld : public btDiscreteDynamicsWorld
{
public:
    using btDiscreteDynamicsWorld::btDiscreteDynamicsWorld;
    double aabb_seconds = 0, pairs_seconds = 0;

    void updateAabbs() override
    {
        auto t0 = std::chrono::steady_clock::now();
        btDiscreteDynamicsWorld::updateAabbs();
        aabb_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    void computeOverlappingPairs() override
    {
        auto t0 = std::chrono::steady_clock::now();
        btDiscreteDynamicsWorld::computeOverlappingPairs();
        pairs_seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
};

enum class Broadphase { Dbvt, Bpx };

inline const char *broadphase_name(Broadphase b)
{
    return b == Broadphase::Dbvt ? "btDbvtBroadphase" : "btBpxBroadphase";
}

// A world and everything in it. Body k has user index k (statics included), in creation order,
// which is also the order of the broad phases' unique ids.
struct Sim {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    std::unique_ptr<btBroadphaseInterface> broadphase;
    btSequentialImpulseConstraintSolver solver;
    std::unique_ptr<TimedWorld> world;
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<btRigidBody *> bodies;
    std::vector<std::unique_ptr<btTypedConstraint>> constraints;

    explicit Sim(Broadphase kind, const bpx_world_def *def = nullptr)
    {
        if (kind == Broadphase::Dbvt)
            broadphase.reset(new btDbvtBroadphase());
        else
            broadphase.reset(new btBpxBroadphase(nullptr, def));
        world.reset(new TimedWorld(&dispatcher, broadphase.get(), &solver, &config));
        world->setGravity(btVector3(0, -10, 0));
    }
    ~Sim()
    {
        // Empty the pair cache first, last pair first (O(1) each): removing a body scans the
        // whole cache for its pairs, O(n pairs) for each of n bodies otherwise.
        btOverlappingPairCache *cache = broadphase->getOverlappingPairCache();
        while (cache->getNumOverlappingPairs() > 0) {
            btBroadphasePair &last =
                cache->getOverlappingPairArrayPtr()[cache->getNumOverlappingPairs() - 1];
            cache->removeOverlappingPair(last.m_pProxy0, last.m_pProxy1, &dispatcher);
        }
        for (auto &c : constraints)
            world->removeConstraint(c.get());
        for (btRigidBody *body : bodies) {
            world->removeRigidBody(body);
            delete body;
        }
        world.reset(); // before the broad phase it uses
    }
    Sim(const Sim &) = delete;
    Sim &operator=(const Sim &) = delete;

    btCollisionShape *shape(btCollisionShape *s)
    {
        shapes.emplace_back(s);
        return s;
    }
    // mass 0: static.
    btRigidBody *body(btCollisionShape *s, btScalar mass, const btVector3 &at,
                      const btQuaternion &rotation = btQuaternion::getIdentity())
    {
        btVector3 inertia(0, 0, 0);
        if (mass > 0)
            s->calculateLocalInertia(mass, inertia);
        btRigidBody::btRigidBodyConstructionInfo info(mass, nullptr, s, inertia);
        info.m_startWorldTransform = btTransform(rotation, at);
        btRigidBody *b = new btRigidBody(info);
        b->setUserIndex((int)bodies.size());
        bodies.push_back(b);
        world->addRigidBody(b);
        return b;
    }
    void constraint(btTypedConstraint *c, bool disableLinkedCollisions)
    {
        constraints.emplace_back(c);
        world->addConstraint(c, disableLinkedCollisions);
    }
};

// A reproducible stream of numbers in [0, 1): the same scene for both worlds and every run.
struct Lcg {
    uint64_t state;
    explicit Lcg(uint64_t seed) : state(seed * 6364136223846793005ull + 1442695040888963407ull) {}
    float next()
    {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return (float)((state >> 40) & 0xFFFFFF) / 16777216.0f;
    }
    float range(float lo, float hi) { return lo + (hi - lo) * next(); }
};

inline void ground(Sim &sim, float half = 50)
{
    sim.body(sim.shape(new btBoxShape(btVector3(half, 0.5f, half))), 0, btVector3(0, -0.5f, 0));
}

// Falling stacks: stacks x stacks columns of height boxes, each a little off its column.
inline void scene_stacks(Sim &sim, int stacks, int height)
{
    ground(sim);
    btCollisionShape *box = sim.shape(new btBoxShape(btVector3(0.5f, 0.5f, 0.5f)));
    Lcg rng(1);
    for (int sx = 0; sx < stacks; sx++)
        for (int sz = 0; sz < stacks; sz++)
            for (int k = 0; k < height; k++) {
                btVector3 at((sx - stacks / 2) * 3.0f + rng.range(-0.15f, 0.15f),
                             0.5f + 1.05f * k + 0.2f,
                             (sz - stacks / 2) * 3.0f + rng.range(-0.15f, 0.15f));
                btQuaternion turn(btVector3(0, 1, 0), rng.range(-0.3f, 0.3f));
                sim.body(box, 1, at, turn);
            }
}

// A pile: spheres and boxes dropped into a walled pit.
inline void scene_pile(Sim &sim, int count)
{
    ground(sim);
    btCollisionShape *wall_x = sim.shape(new btBoxShape(btVector3(0.5f, 4, 5.5f)));
    btCollisionShape *wall_z = sim.shape(new btBoxShape(btVector3(5.5f, 4, 0.5f)));
    sim.body(wall_x, 0, btVector3(-5, 4, 0));
    sim.body(wall_x, 0, btVector3(5, 4, 0));
    sim.body(wall_z, 0, btVector3(0, 4, -5));
    sim.body(wall_z, 0, btVector3(0, 4, 5));
    btCollisionShape *sphere = sim.shape(new btSphereShape(0.4f));
    btCollisionShape *box = sim.shape(new btBoxShape(btVector3(0.35f, 0.3f, 0.4f)));
    Lcg rng(2);
    for (int k = 0; k < count; k++) {
        btVector3 at(rng.range(-4, 4), 1 + 0.12f * k + rng.range(0, 0.5f), rng.range(-4, 4));
        btQuaternion turn(btVector3(rng.next(), rng.next(), rng.next() + 0.1f).normalized(),
                          rng.range(0, 3));
        sim.body(k % 2 ? box : sphere, 1, at, turn);
    }
}

// Jointed chains: one hangs from a point and swings down onto the ground (ball joints), one
// falls as a row of hinged links; linked bodies do not collide.
inline void scene_chain(Sim &sim, int links)
{
    ground(sim);
    btCollisionShape *link = sim.shape(new btBoxShape(btVector3(0.45f, 0.15f, 0.15f)));
    btCollisionShape *capsule = sim.shape(new btCapsuleShapeX(0.15f, 0.7f));
    btRigidBody *previous = nullptr;
    for (int k = 0; k < links; k++) { // along +x from the anchor at (0, 8, 0)
        btRigidBody *b = sim.body(link, 1, btVector3(0.5f + k * 1.0f, 8, 0.01f * k));
        if (!previous)
            sim.constraint(new btPoint2PointConstraint(*b, btVector3(-0.5f, 0, 0)), true);
        else
            sim.constraint(new btPoint2PointConstraint(*previous, *b, btVector3(0.5f, 0, 0),
                                                       btVector3(-0.5f, 0, 0)),
                           true);
        previous = b;
    }
    previous = nullptr;
    for (int k = 0; k < links; k++) { // a hinged row falling on the first chain's path
        btRigidBody *b = sim.body(capsule, 1, btVector3(2 + k * 1.0f, 4 + 0.05f * k, 2));
        if (previous) {
            btHingeConstraint *hinge =
                new btHingeConstraint(*previous, *b, btVector3(0.5f, 0, 0), btVector3(-0.5f, 0, 0),
                                      btVector3(0, 0, 1), btVector3(0, 0, 1));
            hinge->setLimit(-1.2f, 1.2f);
            sim.constraint(hinge, true);
        }
        previous = b;
    }
}

// A gas: count spheres and boxes drifting in zero gravity at a few metres a second, about one
// body per 8 cubic metres, so most steps have many moving bodies and few contacts: the case
// where the broad phase is most of a step.
inline void scene_gas(Sim &sim, int count)
{
    sim.world->setGravity(btVector3(0, 0, 0));
    const float side = std::cbrt(8.0f * (float)count);
    btCollisionShape *sphere = sim.shape(new btSphereShape(0.4f));
    btCollisionShape *box = sim.shape(new btBoxShape(btVector3(0.35f, 0.3f, 0.4f)));
    Lcg rng(3);
    for (int k = 0; k < count; k++) {
        btVector3 at(rng.range(0, side), rng.range(0, side), rng.range(0, side));
        btRigidBody *b = sim.body(k % 2 ? box : sphere, 1, at);
        b->setLinearVelocity(btVector3(rng.range(-3, 3), rng.range(-3, 3), rng.range(-3, 3)));
        b->setAngularVelocity(btVector3(rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)));
    }
}

// Rain: count bodies falling from heights spread over 0 .. 2 side onto a ground of side x side:
// the bodies in the air pass each other and land a few at a time.
inline void scene_rain(Sim &sim, int count)
{
    const float side = std::sqrt(2.0f * (float)count);
    ground(sim, side / 2 + 2);
    btCollisionShape *sphere = sim.shape(new btSphereShape(0.4f));
    btCollisionShape *box = sim.shape(new btBoxShape(btVector3(0.35f, 0.3f, 0.4f)));
    Lcg rng(4);
    for (int k = 0; k < count; k++) {
        btVector3 at(rng.range(-side / 2, side / 2), rng.range(1, 1 + 2 * side),
                     rng.range(-side / 2, side / 2));
        sim.body(k % 2 ? box : sphere, 1, at);
    }
}

} // namespace bullet_scenes
