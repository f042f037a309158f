// bpx bench peers: Box2D 2.4's broad phase (b2BroadPhase over b2DynamicTree) with the pair set
// b2ContactManager keeps. SPDX-License-Identifier: MIT
//
// Box2D is a 2D engine: the tree indexes each box's x-y projection. A cycle does what a
// b2World::Step does to its broad phase: every fixture's proxy moved (MoveProxy with the new
// AABB and the displacement of its centre), b2ContactManager::FindNewContacts (UpdatePairs: each
// reported pair added unless it is already a contact), and b2ContactManager::Collide's broad
// phase part (a contact whose fat AABBs stopped overlapping, TestOverlap, is destroyed). The
// contacts are kept here in a hash set of (i, j) keys instead of Box2D's per-body edge lists.
#include <cstdio>
#include <exception>
#include <new>
#include <vector>

#include <box2d/b2_broad_phase.h>
#include <box2d/b2_common.h>

#include "peer_class.h"

#ifndef BPX_PEER_BOX2D_VERSION
#define BPX_PEER_BOX2D_VERSION "2.4" // the package's version, from CMake
#endif

namespace
{

// Proxy ids are int32 tree nodes, 2 n - 1 of them, in an array whose capacity doubles.
constexpr uint32_t kMaxProxies = 1u << 29;

// A set of pairs (i < j, key i << 32 | j): a dense list to walk and an open-addressing table
// (linear probing, backward-shift deletion) to find. Grows by doubling; never shrinks, so after
// the largest pair set so far it allocates nothing.
class PairSet
{
  public:
    static constexpr uint64_t kEmpty = ~uint64_t(0);

    void reserve(size_t pairs)
    {
        list_.reserve(pairs);
        size_t want = 64;
        while (want < 2 * pairs) {
            want *= 2;
        }
        if (want > slots_.size()) {
            rehash(want);
        }
    }

    // Adds key; false when it was there.
    bool insert(uint64_t key)
    {
        if (2 * (list_.size() + 1) > slots_.size()) {
            rehash(slots_.empty() ? 64 : 2 * slots_.size());
        }
        size_t k = home(key);
        while (slots_[k] != kEmpty) {
            if (slots_[k] == key) {
                return false;
            }
            k = (k + 1) & mask_;
        }
        slots_[k] = key;
        list_.push_back(key);
        return true;
    }

    // Keeps the keys for which keep(key) is true, in list order.
    template <typename Keep> void filter(Keep keep)
    {
        size_t kept = 0;
        for (size_t k = 0; k < list_.size(); k++) {
            uint64_t key = list_[k];
            if (keep(key)) {
                list_[kept++] = key;
            } else {
                erase_slot(key);
            }
        }
        list_.resize(kept);
    }

    size_t size() const { return list_.size(); }
    const std::vector<uint64_t> &keys() const { return list_; }

  private:
    size_t home(uint64_t key) const { return (size_t)((key * 0x9E3779B97F4A7C15ull) >> shift_); }

    void rehash(size_t slot_count)
    {
        std::vector<uint64_t> fresh(slot_count, kEmpty);
        slots_.swap(fresh);
        mask_ = slot_count - 1;
        shift_ = 64;
        for (size_t s = slot_count; s > 1; s >>= 1) {
            shift_--;
        }
        for (uint64_t key : list_) {
            size_t k = home(key);
            while (slots_[k] != kEmpty) {
                k = (k + 1) & mask_;
            }
            slots_[k] = key;
        }
    }

    void erase_slot(uint64_t key)
    {
        size_t hole = home(key);
        while (slots_[hole] != key) {
            hole = (hole + 1) & mask_;
        }
        // Backward shift: pull later entries of the probe run into the hole when their home
        // position does not lie cyclically in (hole, at].
        for (size_t at = (hole + 1) & mask_; slots_[at] != kEmpty; at = (at + 1) & mask_) {
            size_t h = home(slots_[at]);
            bool stays = hole <= at ? (hole < h && h <= at) : (hole < h || h <= at);
            if (!stays) {
                slots_[hole] = slots_[at];
                hole = at;
            }
        }
        slots_[hole] = kEmpty;
    }

    std::vector<uint64_t> list_;
    std::vector<uint64_t> slots_;
    size_t mask_ = 0;
    int shift_ = 64;
};

struct Box2DPeer {
    uint32_t n = 0;
    b2BroadPhase broadphase;
    std::vector<int32> proxy;   // box index -> proxy id (tree node)
    std::vector<b2Vec2> centre; // box index -> last centre, for the displacement
    PairSet contacts;

    // b2BroadPhase::UpdatePairs' callback, as b2ContactManager::AddPair: a pair reported again
    // while already a contact is ignored.
    void AddPair(void *user_a, void *user_b)
    {
        uint32_t a = (uint32_t) reinterpret_cast<uintptr_t>(user_a);
        uint32_t b = (uint32_t) reinterpret_cast<uintptr_t>(user_b);
        if (a == b) {
            return;
        }
        uint64_t key = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
        contacts.insert(key);
    }

    void drop_separated()
    {
        contacts.filter([this](uint64_t key) {
            return broadphase.TestOverlap(proxy[(uint32_t)(key >> 32)], proxy[(uint32_t)key]);
        });
    }
};

inline b2AABB xy_aabb(const bpx_box &b)
{
    b2AABB aabb;
    aabb.lowerBound.Set(b.min[0], b.min[1]);
    aabb.upperBound.Set(b.max[0], b.max[1]);
    return aabb;
}

void *box2d_create(int, const bpx_box *boxes, uint32_t n, const float *, const float *, char *err,
                   size_t err_size)
{
    Box2DPeer *peer = nullptr;
    try {
        peer = new Box2DPeer();
        peer->n = n;
        peer->proxy.resize(n);
        peer->centre.resize(n);
        peer->contacts.reserve(2 * (size_t)n);
        for (uint32_t i = 0; i < n; i++) {
            b2AABB aabb = xy_aabb(boxes[i]);
            peer->centre[i] = aabb.GetCenter();
            peer->proxy[i] =
                peer->broadphase.CreateProxy(aabb, reinterpret_cast<void *>(uintptr_t(i)));
        }
        peer->broadphase.UpdatePairs(peer);
        return peer;
    } catch (const std::bad_alloc &) {
        bench_peer_set_error(err, err_size, "box2d-tree: out of memory for n = %u", n);
    } catch (const std::exception &e) {
        bench_peer_set_error(err, err_size, "box2d-tree: %s", e.what());
    } catch (...) {
        bench_peer_set_error(err, err_size, "box2d-tree: unknown exception");
    }
    delete peer;
    return nullptr;
}

int box2d_cycle(void *impl, const bpx_box *boxes)
{
    Box2DPeer *peer = static_cast<Box2DPeer *>(impl);
    try {
        for (uint32_t i = 0; i < peer->n; i++) {
            b2AABB aabb = xy_aabb(boxes[i]);
            b2Vec2 c = aabb.GetCenter();
            peer->broadphase.MoveProxy(peer->proxy[i], aabb, c - peer->centre[i]);
            peer->centre[i] = c;
        }
        peer->broadphase.UpdatePairs(peer);
        peer->drop_separated();
        return 0;
    } catch (...) {
        return -1;
    }
}

uint64_t box2d_pair_count(const void *impl)
{
    return static_cast<const Box2DPeer *>(impl)->contacts.size();
}

void box2d_visit_pairs(const void *impl, bench_peer_visit_fn *visit, void *context)
{
    for (uint64_t key : static_cast<const Box2DPeer *>(impl)->contacts.keys()) {
        visit(context, (uint32_t)(key >> 32), (uint32_t)key);
    }
}

void box2d_destroy(void *impl)
{
    try {
        delete static_cast<Box2DPeer *>(impl);
    } catch (...) {
    }
}

struct ClassTable {
    char detail[240];
    bench_peer_class classes[1];

    ClassTable()
    {
        std::snprintf(detail, sizeof detail,
                      "Box2D %s (b2_version %d.%d.%d) b2BroadPhase/b2DynamicTree, 2D: x-y only; "
                      "fat AABBs +%g (b2_aabbExtension), +%gx displacement; contacts kept as "
                      "b2ContactManager does",
                      BPX_PEER_BOX2D_VERSION, (int)b2_version.major, (int)b2_version.minor,
                      (int)b2_version.revision, (double)b2_aabbExtension,
                      (double)b2_aabbMultiplier);
        classes[0].info.name = "box2d-tree";
        classes[0].info.detail = detail;
        classes[0].info.max_n = kMaxProxies;
        classes[0].info.slow_n = UINT32_MAX;
        classes[0].variant = 0;
        classes[0].create = box2d_create;
        classes[0].cycle = box2d_cycle;
        classes[0].pair_count = box2d_pair_count;
        classes[0].visit_pairs = box2d_visit_pairs;
        classes[0].destroy = box2d_destroy;
    }
};

} // namespace

extern "C" const bench_peer_class *bench_peer_box2d_classes(int *count)
{
    static const ClassTable table; // built once, thread-safe (C++11 function-local static)
    *count = 1;
    return table.classes;
}
