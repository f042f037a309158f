// bpx bench peers: FCL's dynamic AABB tree (fcl::DynamicAABBTreeCollisionManager<double>), the
// broad phase of MoveIt, Drake's older releases and many robotics stacks. SPDX-License-Identifier:
// MIT
//
// A cycle is what an FCL user pays each step: every object's world AABB set, manager.update()
// (every leaf's box copied from its object, the tree refitted bottom-up, then rebalanced:
// incrementally, or top-down when it has grown too unbalanced), and manager.collide(), whose
// callback collects each reported pair into a vector (cleared each cycle, never shrunk).
//
// The objects' AABBs are set directly (a CollisionObject subclass writes its protected `aabb`),
// not by setTransform + computeAABB on a box shape: that is the same box FCL would compute for an
// axis-aligned box shape, exactly (no float -> centre/half-extent rounding), and cheaper, so the
// peer's time is, if anything, lower than an application's. The leaves are exact boxes (no
// margin) and AABB::overlap is closed on both ends, so FCL's pairs are exactly bpx's.
//
// double, the precision libfcl.so is compiled for (fcl::DynamicAABBTreeCollisionManagerd); every
// float box is exact in double.
#include <cstdio>
#include <exception>
#include <memory>
#include <new>
#include <vector>

#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/config.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/narrowphase/collision_object.h>

#include "peer_class.h"

namespace
{

using S = double;

// A collision object whose world AABB the peer sets itself.
class BoxObject : public fcl::CollisionObject<S>
{
  public:
    BoxObject(const std::shared_ptr<fcl::CollisionGeometry<S>> &shape, uint32_t index)
        : fcl::CollisionObject<S>(shape)
    {
        setUserData(reinterpret_cast<void *>(uintptr_t(index)));
    }

    void set_box(const bpx_box &b)
    {
        aabb.min_ = fcl::Vector3<S>(b.min[0], b.min[1], b.min[2]);
        aabb.max_ = fcl::Vector3<S>(b.max[0], b.max[1], b.max[2]);
    }
};

struct FclPeer {
    uint32_t n = 0;
    std::shared_ptr<fcl::CollisionGeometry<S>> shape;
    std::vector<std::unique_ptr<BoxObject>> objects;
    fcl::DynamicAABBTreeCollisionManager<S> manager;
    std::vector<uint64_t> pairs; // (a << 32 | b) as reported this cycle

    void collide()
    {
        pairs.clear();
        manager.collide(this, &FclPeer::on_pair);
    }

    // CollisionCallBack: false = keep going.
    static bool on_pair(fcl::CollisionObject<S> *o1, fcl::CollisionObject<S> *o2, void *data)
    {
        FclPeer *peer = static_cast<FclPeer *>(data);
        uint32_t a = (uint32_t) reinterpret_cast<uintptr_t>(o1->getUserData());
        uint32_t b = (uint32_t) reinterpret_cast<uintptr_t>(o2->getUserData());
        peer->pairs.push_back((uint64_t)a << 32 | b);
        return false;
    }
};

void *fcl_create(int, const bpx_box *boxes, uint32_t n, const float *, const float *, char *err,
                 size_t err_size)
{
    FclPeer *peer = nullptr;
    try {
        peer = new FclPeer();
        peer->n = n;
        // One shape shared by every object: only the AABBs set below are ever read.
        peer->shape = std::make_shared<fcl::Box<S>>(1.0, 1.0, 1.0);
        peer->objects.reserve(n);
        std::vector<fcl::CollisionObject<S> *> raw(n);
        for (uint32_t i = 0; i < n; i++) {
            peer->objects.emplace_back(new BoxObject(peer->shape, i));
            peer->objects[i]->set_box(boxes[i]);
            raw[i] = peer->objects[i].get();
        }
        peer->pairs.reserve(2 * (size_t)n);
        if (n > 0) {
            peer->manager.registerObjects(raw); // bulk build (top-down), as FCL recommends
        }
        peer->manager.setup();
        peer->collide();
        return peer;
    } catch (const std::bad_alloc &) {
        bench_peer_set_error(err, err_size, "fcl-tree: out of memory for n = %u", n);
    } catch (const std::exception &e) {
        bench_peer_set_error(err, err_size, "fcl-tree: %s", e.what());
    } catch (...) {
        bench_peer_set_error(err, err_size, "fcl-tree: unknown exception");
    }
    delete peer;
    return nullptr;
}

int fcl_cycle(void *impl, const bpx_box *boxes)
{
    FclPeer *peer = static_cast<FclPeer *>(impl);
    try {
        for (uint32_t i = 0; i < peer->n; i++) {
            peer->objects[i]->set_box(boxes[i]);
        }
        peer->manager.update();
        peer->collide();
        return 0;
    } catch (...) {
        return -1;
    }
}

uint64_t fcl_pair_count(const void *impl)
{
    return static_cast<const FclPeer *>(impl)->pairs.size();
}

void fcl_visit_pairs(const void *impl, bench_peer_visit_fn *visit, void *context)
{
    for (uint64_t key : static_cast<const FclPeer *>(impl)->pairs) {
        visit(context, (uint32_t)(key >> 32), (uint32_t)key);
    }
}

void fcl_destroy(void *impl)
{
    try {
        delete static_cast<FclPeer *>(impl);
    } catch (...) {
    }
}

struct ClassTable {
    char detail[240];
    bench_peer_class classes[1];

    ClassTable()
    {
        fcl::DynamicAABBTreeCollisionManager<S> defaults;
        std::snprintf(detail, sizeof detail,
                      "FCL %s DynamicAABBTreeCollisionManager<double>: exact leaves, update() "
                      "refits then rebalances (incremental %d passes, top-down past %d levels "
                      "unbalanced); collide() pairs to a vector",
                      FCL_VERSION, defaults.tree_incremental_balance_pass,
                      defaults.max_tree_nonbalanced_level);
        classes[0].info.name = "fcl-tree";
        classes[0].info.detail = detail;
        classes[0].info.max_n = UINT32_MAX;
        classes[0].info.slow_n = UINT32_MAX;
        classes[0].variant = 0;
        classes[0].create = fcl_create;
        classes[0].cycle = fcl_cycle;
        classes[0].pair_count = fcl_pair_count;
        classes[0].visit_pairs = fcl_visit_pairs;
        classes[0].destroy = fcl_destroy;
    }
};

} // namespace

extern "C" const bench_peer_class *bench_peer_fcl_classes(int *count)
{
    static const ClassTable table;
    *count = 1;
    return table.classes;
}
