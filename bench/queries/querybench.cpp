// bpx_querybench: bpx's queries (include/bpx/query.h) against the broad-phase queries of Bullet
// (btDbvtBroadphase rayTest / aabbTest) and Box2D 2.4 (b2DynamicTree RayCast / Query), on the
// same boxes and the same queries, in one run. SPDX-License-Identifier: MIT
//
//   bpx_querybench [--sizes 100000,1000000] [--scenes uniform,heavy,long,long_any]
//                  [--rays 1000000] [--regions 1000000]
//                  [--sweeps 100000] [--workers 2] [--rounds 1] [--peers all]
//   bpx_querybench --modes 1 [--sizes ...] [--rays ...] [--rounds ...]
//
// --modes 1 prints instead the ray modes and the read-only path's threads (issue 31): all hits,
// any hit and the closest on the same rays (bpx_world_query_shared, one thread), and 1, 2, 4, 8
// threads at once querying one prepared world, on a uniform scene (one overlap per box) and a
// dense one (16).
//
// --rounds R runs every column R times, alternating (bpx, then each peer, R times), and reports
// the medians: ratios side by side on a shared machine. --peers picks the peers (a comma list of
// bullet, box2d, embree; "all" by default).
//
// Rays: closest hit from a random origin inside the world along a random unit direction, up to
// a quarter of the world's side. Regions: boxes of side 2..4 at random places, every hit.
// Sweeps: a scene box moved by a random translation of length 5, closest hit. Scenes: the
// benchmark's uniform-density and heavy-tailed boxes, and boxes 50× longer on x or on a random
// axis each (scenes.h), all about one overlap per box.
//
// What each peer answers: Bullet's rayTest visits every proxy whose box the segment crosses
// (its broad phase does not shorten the ray as hits are found; the callback here computes each
// hit's distance and keeps the nearest); its swept box is rayTest with the box's extents.
// Box2D's tree is 2D: it answers for the boxes' x-y projections, fattened by b2_aabbExtension
// (0.1), and its ray callback clips the ray at each hit as Box2D's own ray casts do. Both run
// on one thread; bpx on one and on --workers.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <bpx/bpx.h>

extern "C" {
#include "scenes.h"
}

#ifdef BPX_QB_HAVE_BULLET
#include <btBulletCollisionCommon.h>
#endif
#ifdef BPX_QB_HAVE_BOX2D
#include <box2d/b2_dynamic_tree.h>
#endif
#ifdef BPX_QB_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

#ifdef BPX_COUNT_VISITS // a measuring build of bpx: nodes entered by closest casts
extern "C" uint64_t bpx__visits;
#endif

namespace
{

double now_s()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

struct Workload {
    std::vector<bpx_box> boxes;
    std::vector<bpx_query> rays, regions, sweeps;
    float lo[3], hi[3];
};

float uniform(scene_rng *r, float lo, float hi)
{
    return scene_rng_range(r, lo, hi);
}

void unit_direction(scene_rng *r, float d[3])
{
    for (;;) {
        double v[3], len2 = 0;
        for (int a = 0; a < 3; a++) {
            v[a] = uniform(r, -1.0f, 1.0f);
            len2 += v[a] * v[a];
        }
        if (len2 > 0.01 && len2 <= 1.0) {
            for (int a = 0; a < 3; a++)
                d[a] = (float)(v[a] / std::sqrt(len2));
            return;
        }
    }
}

// The scenes (scenes.h), all about one overlap per box: uniform, heavy-tailed sizes, boxes 50×
// longer along x (long) or along a random axis each (long_any).
const char *const scene_names[] = {"uniform", "heavy", "long", "long_any"};

bool make_boxes(const std::string &scene, uint32_t n, bpx_box *out)
{
    if (scene == "uniform")
        scene_uniform_density(n, 1.0f, 42, out);
    else if (scene == "heavy")
        scene_heavy_tailed_density(n, 42, out);
    else if (scene == "long" || scene == "long_any")
        scene_elongated_density(n, 50.0f, scene == "long_any", 42, out);
    else
        return false;
    return true;
}

Workload make(const std::string &scene, uint32_t n, uint32_t rays, uint32_t regions,
              uint32_t sweeps)
{
    Workload w;
    w.boxes.resize(n);
    make_boxes(scene, n, w.boxes.data());
    for (int a = 0; a < 3; a++) {
        w.lo[a] = INFINITY;
        w.hi[a] = -INFINITY;
    }
    for (const bpx_box &b : w.boxes)
        for (int a = 0; a < 3; a++) {
            w.lo[a] = std::fmin(w.lo[a], b.min[a]);
            w.hi[a] = std::fmax(w.hi[a], b.max[a]);
        }
    scene_rng r;
    scene_rng_seed(&r, 7);
    float reach = 0.25f * (w.hi[0] - w.lo[0]);
    for (uint32_t k = 0; k < rays; k++) {
        float o[3], d[3];
        for (int a = 0; a < 3; a++)
            o[a] = uniform(&r, w.lo[a], w.hi[a]);
        unit_direction(&r, d);
        w.rays.push_back(bpx_query_ray(o, d, reach, true));
    }
    for (uint32_t k = 0; k < regions; k++) {
        bpx_box b;
        for (int a = 0; a < 3; a++) {
            b.min[a] = uniform(&r, w.lo[a], w.hi[a]);
            b.max[a] = b.min[a] + uniform(&r, 2.0f, 4.0f);
        }
        w.regions.push_back(bpx_query_box(b));
    }
    for (uint32_t k = 0; k < sweeps; k++) {
        float d[3];
        unit_direction(&r, d);
        w.sweeps.push_back(bpx_query_sweep(w.boxes[scene_rng_below(&r, n)], d, 5.0f, true));
    }
    return w;
}

// ---------------------------------------------------------------------------------------------
// bpx

struct BpxResult {
    double ns_per_query;
    uint64_t hits;
};

BpxResult run_bpx(bpx_world *world, const std::vector<bpx_query> &queries)
{
    std::vector<size_t> offsets(queries.size() + 1);
    size_t total = 0;
    double t0 = now_s();
    bpx_status s = bpx_world_query_batch(world, queries.data(), (uint32_t)queries.size(),
                                         offsets.data(), nullptr, 0, &total);
    double t1 = now_s();
    if (s != BPX_OK && s != BPX_ERR_CAPACITY) {
        std::fprintf(stderr, "bpx: %s\n", bpx_world_error(world)->message);
        std::exit(1);
    }
    return {1e9 * (t1 - t0) / (double)queries.size(), total};
}

bpx_world *make_world(const Workload &w, int workers)
{
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *world = nullptr;
    if (bpx_world_create(&def, &world) != BPX_OK ||
        bpx_world_set_boxes(world, w.boxes.data(), (uint32_t)w.boxes.size()) != BPX_OK) {
        std::fprintf(stderr, "bpx: cannot make the world\n");
        std::exit(1);
    }
    return world;
}

// The slab test in the peers' callbacks: the distance along (o, d) where it enters the box
// [lo, hi] grown by the moving box's half extents, or -1.
double enter(const float o[3], const float d[3], const float lo[3], const float hi[3],
             const float grow[3], double max_t)
{
    double t0 = 0.0, t1 = max_t;
    for (int a = 0; a < 3; a++) {
        double l = (double)lo[a] - grow[a], h = (double)hi[a] + grow[a];
        if (d[a] == 0.0f) {
            if (o[a] < l || o[a] > h)
                return -1.0;
            continue;
        }
        double inv = 1.0 / d[a], ta = (l - o[a]) * inv, tb = (h - o[a]) * inv;
        t0 = std::fmax(t0, std::fmin(ta, tb));
        t1 = std::fmin(t1, std::fmax(ta, tb));
    }
    return t0 <= t1 ? t0 : -1.0;
}

// A ray or sweep as a centre, half extents and a direction.
void as_ray(const bpx_query &q, float o[3], float grow[3])
{
    for (int a = 0; a < 3; a++) {
        if (q.kind == BPX_QUERY_RAY) {
            o[a] = q.origin[a];
            grow[a] = 0.0f;
        } else {
            o[a] = 0.5f * (q.box.min[a] + q.box.max[a]);
            grow[a] = 0.5f * (q.box.max[a] - q.box.min[a]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Bullet

#ifdef BPX_QB_HAVE_BULLET
struct BulletCast : btBroadphaseRayCallback {
    const std::vector<bpx_box> *boxes;
    float o[3], d[3], grow[3];
    double best;
    uint32_t best_id;
    uint64_t tests = 0;
    bool process(const btBroadphaseProxy *proxy) override
    {
        uint32_t id = (uint32_t)(uintptr_t)proxy->m_clientObject;
        const bpx_box &b = (*boxes)[id];
        double t = enter(o, d, b.min, b.max, grow, best);
        if (t >= 0.0 && (t < best || (t == best && id < best_id))) {
            best = t;
            best_id = id;
        }
        tests++;
        return true;
    }
};

struct BulletCount : btBroadphaseAabbCallback {
    uint64_t hits = 0;
    bool process(const btBroadphaseProxy *) override
    {
        hits++;
        return true;
    }
};

struct Bullet {
    btDbvtBroadphase broadphase;
    std::vector<btBroadphaseProxy *> proxies;
    explicit Bullet(const std::vector<bpx_box> &boxes)
    {
        for (size_t i = 0; i < boxes.size(); i++) {
            const bpx_box &b = boxes[i];
            proxies.push_back(broadphase.createProxy(btVector3(b.min[0], b.min[1], b.min[2]),
                                                     btVector3(b.max[0], b.max[1], b.max[2]), 0,
                                                     (void *)(uintptr_t)i, 1, 1, nullptr));
        }
    }
    ~Bullet()
    {
        // destroyProxy scans the pair cache for the proxy's pairs: empty it first (O(1) a pair).
        btOverlappingPairCache *cache = broadphase.getOverlappingPairCache();
        while (cache->getNumOverlappingPairs() > 0) {
            btBroadphasePair &last =
                cache->getOverlappingPairArrayPtr()[cache->getNumOverlappingPairs() - 1];
            cache->removeOverlappingPair(last.m_pProxy0, last.m_pProxy1, nullptr);
        }
        for (btBroadphaseProxy *p : proxies)
            broadphase.destroyProxy(p, nullptr);
    }
    uint64_t cast(const std::vector<bpx_box> &boxes, const bpx_query &q)
    {
        BulletCast cb;
        cb.boxes = &boxes;
        as_ray(q, cb.o, cb.grow);
        std::memcpy(cb.d, q.direction, sizeof cb.d);
        cb.best = q.max_fraction;
        cb.best_id = UINT32_MAX;
        btVector3 from(cb.o[0], cb.o[1], cb.o[2]);
        btVector3 dir(q.direction[0], q.direction[1], q.direction[2]);
        btVector3 to = from + dir * q.max_fraction;
        for (int a = 0; a < 3; a++) {
            cb.m_rayDirectionInverse[a] = dir[a] == 0.0f ? BT_LARGE_FLOAT : 1.0f / dir[a];
            cb.m_signs[a] = cb.m_rayDirectionInverse[a] < 0.0f;
        }
        cb.m_lambda_max = q.max_fraction;
        btVector3 grow(cb.grow[0], cb.grow[1], cb.grow[2]);
        broadphase.rayTest(from, to, cb, -grow, grow);
        return cb.best_id != UINT32_MAX;
    }
    uint64_t region(const bpx_query &q)
    {
        BulletCount cb;
        broadphase.aabbTest(btVector3(q.box.min[0], q.box.min[1], q.box.min[2]),
                            btVector3(q.box.max[0], q.box.max[1], q.box.max[2]), cb);
        return cb.hits;
    }
};
#endif

// ---------------------------------------------------------------------------------------------
// Box2D (2D: x-y)

#ifdef BPX_QB_HAVE_BOX2D
struct Box2D {
    b2DynamicTree tree;
    uint64_t hits = 0;
    const std::vector<bpx_box> *boxes = nullptr;
    float o[3], d[3], grow[3];
    explicit Box2D(const std::vector<bpx_box> &all) : boxes(&all)
    {
        for (size_t i = 0; i < all.size(); i++) {
            b2AABB aabb;
            aabb.lowerBound.Set(all[i].min[0], all[i].min[1]);
            aabb.upperBound.Set(all[i].max[0], all[i].max[1]);
            tree.CreateProxy(aabb, (void *)(uintptr_t)i);
        }
    }
    bool QueryCallback(int32)
    {
        hits++;
        return true;
    }
    // The hit's fraction of the segment, clipping the ray there (Box2D's closest-hit idiom).
    float RayCastCallback(const b2RayCastInput &input, int32 proxy)
    {
        uint32_t id = (uint32_t)(uintptr_t)tree.GetUserData(proxy);
        const bpx_box &b = (*boxes)[id];
        float o2[3] = {o[0], o[1], 0.0f}, d2[3] = {d[0], d[1], 0.0f};
        float lo[3] = {b.min[0], b.min[1], -1.0f}, hi[3] = {b.max[0], b.max[1], 1.0f};
        double len = input.maxFraction;
        double t = enter(o2, d2, lo, hi, grow, len);
        if (t < 0.0)
            return input.maxFraction;
        hits = 1;
        return (float)t;
    }
    uint64_t cast(const bpx_query &q)
    {
        as_ray(q, o, grow);
        std::memcpy(d, q.direction, sizeof d);
        grow[2] = 0.0f;
        b2RayCastInput input;
        input.p1.Set(o[0], o[1]);
        input.p2.Set(o[0] + d[0], o[1] + d[1]);
        input.maxFraction = q.max_fraction;
        hits = 0;
        if (q.kind == BPX_QUERY_SWEEP) { // Box2D casts rays only: grow the tree query instead
            b2AABB aabb;
            aabb.lowerBound.Set(std::fmin(q.box.min[0], q.box.min[0] + 5 * d[0]),
                                std::fmin(q.box.min[1], q.box.min[1] + 5 * d[1]));
            aabb.upperBound.Set(std::fmax(q.box.max[0], q.box.max[0] + 5 * d[0]),
                                std::fmax(q.box.max[1], q.box.max[1] + 5 * d[1]));
            tree.Query(this, aabb);
            return hits;
        }
        tree.RayCast(this, input);
        return hits;
    }
    uint64_t region(const bpx_query &q)
    {
        b2AABB aabb;
        aabb.lowerBound.Set(q.box.min[0], q.box.min[1]);
        aabb.upperBound.Set(q.box.max[0], q.box.max[1]);
        hits = 0;
        tree.Query(this, aabb);
        return hits;
    }
};
#endif

// ---------------------------------------------------------------------------------------------
// Embree 3: the boxes as user geometry (bounds and a slab test in a callback), rays only.

#ifdef BPX_QB_HAVE_EMBREE
void embree_bounds(const RTCBoundsFunctionArguments *args)
{
    const bpx_box &b = static_cast<const bpx_box *>(args->geometryUserPtr)[args->primID];
    *args->bounds_o =
        RTCBounds{b.min[0], b.min[1], b.min[2], 0.0f, b.max[0], b.max[1], b.max[2], 0.0f};
}

void embree_intersect(const RTCIntersectFunctionNArguments *args)
{
    if (!args->valid[0])
        return;
    const bpx_box &b = static_cast<const bpx_box *>(args->geometryUserPtr)[args->primID];
    RTCRayHit *rh = reinterpret_cast<RTCRayHit *>(args->rayhit);
    float o[3] = {rh->ray.org_x, rh->ray.org_y, rh->ray.org_z};
    float d[3] = {rh->ray.dir_x, rh->ray.dir_y, rh->ray.dir_z}, grow[3] = {0, 0, 0};
    double t = enter(o, d, b.min, b.max, grow, rh->ray.tfar);
    if (t >= 0.0 && t < rh->ray.tfar) {
        rh->ray.tfar = (float)t;
        rh->hit.primID = args->primID;
        rh->hit.geomID = args->geomID;
    }
}

struct Embree {
    RTCDevice device;
    RTCScene scene;
    double build_s;
    explicit Embree(const std::vector<bpx_box> &boxes)
    {
        device = rtcNewDevice("threads=1");
        scene = rtcNewScene(device);
        RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(geometry, (unsigned)boxes.size());
        rtcSetGeometryUserData(geometry, const_cast<bpx_box *>(boxes.data()));
        rtcSetGeometryBoundsFunction(geometry, embree_bounds, nullptr);
        rtcSetGeometryIntersectFunction(geometry, embree_intersect);
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene, geometry);
        rtcReleaseGeometry(geometry);
        double t0 = now_s();
        rtcCommitScene(scene);
        build_s = now_s() - t0;
    }
    ~Embree()
    {
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
    }
    uint64_t cast(const bpx_query &q)
    {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRayHit rh{};
        rh.ray.org_x = q.origin[0];
        rh.ray.org_y = q.origin[1];
        rh.ray.org_z = q.origin[2];
        rh.ray.dir_x = q.direction[0];
        rh.ray.dir_y = q.direction[1];
        rh.ray.dir_z = q.direction[2];
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = q.max_fraction;
        rh.ray.mask = ~0u;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &context, &rh);
        return rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
};
#endif

template <class F> double time_each(const std::vector<bpx_query> &qs, F f, uint64_t *hits)
{
    double t0 = now_s();
    uint64_t h = 0;
    for (const bpx_query &q : qs)
        h += f(q);
    *hits = h;
    return 1e9 * (now_s() - t0) / (double)qs.size();
}

std::vector<uint32_t> parse_list(const char *s)
{
    std::vector<uint32_t> v;
    while (*s) {
        v.push_back((uint32_t)std::strtoul(s, const_cast<char **>(&s), 10));
        if (*s == ',')
            s++;
    }
    return v;
}

double median(std::vector<double> v)
{
    if (v.empty())
        return NAN;
    std::sort(v.begin(), v.end());
    size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

bool listed(const std::string &peers, const char *name)
{
    return peers == "all" ||
           ("," + peers + ",").find(std::string(",") + name + ",") != std::string::npos;
}

// Ray modes and threads on the read-only path (see the header comment).
int mode_rows(const std::vector<uint32_t> &sizes, uint32_t ray_count, int rounds)
{
    std::printf("# bpx rays on one prepared world: ns per ray (lower is better), one thread, "
                "bpx_world_query_shared; median of %d alternating round(s). Threads: rays per "
                "second of T threads at once over one thread's (this machine: %u hardware "
                "threads)\n\n",
                rounds, std::thread::hardware_concurrency());
    std::printf("| scene | boxes | all hits | any hit | closest | all / any | hits per ray (all) "
                "| 2 threads | 4 threads | 8 threads |\n|---|---:|---:|---:|---:|---:|---:|---:|"
                "---:|---:|\n");
    for (float density : {1.0f, 16.0f})
        for (uint32_t n : sizes) {
            std::vector<bpx_box> boxes(n);
            scene_uniform_density(n, density, 42, boxes.data());
            float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (const bpx_box &b : boxes)
                for (int a = 0; a < 3; a++)
                    lo[a] = std::fmin(lo[a], b.min[a]), hi[a] = std::fmax(hi[a], b.max[a]);
            scene_rng r;
            scene_rng_seed(&r, 7);
            std::vector<bpx_query> all(ray_count), any, closest;
            for (bpx_query &q : all) {
                float o[3], d[3];
                for (int a = 0; a < 3; a++)
                    o[a] = uniform(&r, lo[a], hi[a]);
                unit_direction(&r, d);
                q = bpx_query_ray(o, d, 0.25f * (hi[0] - lo[0]), false);
            }
            any = closest = all;
            for (bpx_query &q : any)
                q.any = true;
            for (bpx_query &q : closest)
                q.closest = true;
            bpx_world_def def = bpx_default_world_def();
            bpx_world *world = nullptr;
            if (bpx_world_create(&def, &world) != BPX_OK ||
                bpx_world_set_boxes(world, boxes.data(), n) != BPX_OK ||
                bpx_world_prepare_queries(world) != BPX_OK) {
                std::fprintf(stderr, "bpx: cannot make the world\n");
                return 1;
            }
            std::vector<bpx_hit> hits(n);
            auto shared = [&](const std::vector<bpx_query> &qs, size_t first, size_t step,
                              bpx_hit *out, uint64_t *total) {
                uint64_t sum = 0;
                for (size_t k = first; k < qs.size(); k += step) {
                    size_t count = 0;
                    bpx_world_query_shared(world, &qs[k], out, n, &count, nullptr);
                    sum += count;
                }
                *total = sum;
            };
            auto timed = [&](const std::vector<bpx_query> &qs, uint64_t *total) {
                double t0 = now_s();
                shared(qs, 0, 1, hits.data(), total);
                return 1e9 * (now_s() - t0) / (double)qs.size();
            };
            auto threads_rate = [&](int count) {
                std::vector<std::thread> pool;
                std::vector<std::vector<bpx_hit>> outs(count, std::vector<bpx_hit>(n));
                std::vector<uint64_t> totals(count);
                double t0 = now_s();
                for (int t = 0; t < count; t++)
                    pool.emplace_back(shared, std::cref(closest), (size_t)t, (size_t)count,
                                      outs[t].data(), &totals[t]);
                for (std::thread &t : pool)
                    t.join();
                return (double)closest.size() / (now_s() - t0);
            };
            std::vector<double> t_all, t_any, t_closest, s2, s4, s8;
            uint64_t all_hits = 0, any_hits = 0, closest_hits = 0;
            for (int round = 0; round < rounds; round++) {
                t_all.push_back(timed(all, &all_hits));
                t_any.push_back(timed(any, &any_hits));
                t_closest.push_back(timed(closest, &closest_hits));
                double one = threads_rate(1);
                s2.push_back(threads_rate(2) / one);
                s4.push_back(threads_rate(4) / one);
                s8.push_back(threads_rate(8) / one);
            }
            if (any_hits != closest_hits) // both: one hit per ray that hits anything
                std::fprintf(stderr, "note: any %llu hits, closest %llu\n",
                             (unsigned long long)any_hits, (unsigned long long)closest_hits);
            std::printf("| %s | %u | %.0f | %.0f | %.0f | %.1f× | %.1f | %.2f× | %.2f× | %.2f× |\n",
                        density > 1.0f ? "dense (16 per box)" : "uniform (1 per box)", n,
                        median(t_all), median(t_any), median(t_closest),
                        median(t_all) / median(t_any), (double)all_hits / (double)all.size(),
                        median(s2), median(s4), median(s8));
            std::fflush(stdout);
            bpx_world_destroy(world);
        }
    return 0;
}

} // namespace

int main(int argc, char **argv)
{
    std::vector<uint32_t> sizes = {100000, 1000000};
    uint32_t rays = 1000000, regions = 1000000, sweeps = 100000;
    int workers = 2, rounds = 1;
    std::string peers = "all";
    std::vector<std::string> scenes(std::begin(scene_names), std::end(scene_names));
    bool modes = false;
    for (int i = 1; i < argc; i++)
        if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
            std::printf("bpx_querybench [--sizes 100000,1000000] [--scenes "
                        "uniform,heavy,long,long_any]\n    [--rays N] [--regions N] [--sweeps N] "
                        "[--workers 2] [--rounds 1] [--peers all|bullet,box2d,embree]\n"
                        "bpx_querybench --modes 1 [--sizes ...] [--rays ...] [--rounds ...]\n");
            return 0;
        }
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--scenes")) {
            scenes.clear();
            for (const char *at = argv[i + 1]; *at;) {
                const char *comma = std::strchr(at, ',');
                std::string name = comma ? std::string(at, comma) : std::string(at);
                bpx_box probe;
                if (!make_boxes(name, 1, &probe)) {
                    std::fprintf(stderr, "unknown scene %s\n", name.c_str());
                    return 2;
                }
                scenes.push_back(name);
                at = comma ? comma + 1 : at + name.size();
            }
        } else if (!std::strcmp(argv[i], "--sizes"))
            sizes = parse_list(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--rays"))
            rays = (uint32_t)std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--regions"))
            regions = (uint32_t)std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--sweeps"))
            sweeps = (uint32_t)std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--workers"))
            workers = std::atoi(argv[i + 1]);
        else if (!std::strcmp(argv[i], "--rounds"))
            rounds = std::max(1, std::atoi(argv[i + 1]));
        else if (!std::strcmp(argv[i], "--peers"))
            peers = argv[i + 1];
        else if (!std::strcmp(argv[i], "--modes"))
            modes = std::atoi(argv[i + 1]) != 0;
        else {
            std::fprintf(stderr, "unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (modes)
        return mode_rows(sizes, rays, rounds);
    bool use_bullet = listed(peers, "bullet"), use_box2d = listed(peers, "box2d");
    bool use_embree = listed(peers, "embree");
    (void)use_bullet, (void)use_box2d, (void)use_embree;
    std::printf("# bpx queries: ns per query (lower is better); bpx 1t = one thread, bpx %dt = "
                "batch on %d workers; median of %d alternating round(s), ratios of the medians\n\n",
                workers, workers, rounds);
    std::printf("| scene | boxes | query | bpx 1t | bpx %dt | bullet-dbvt | box2d-tree (2D) | "
                "embree (rays) | bullet / bpx 1t | box2d / bpx 1t | embree / bpx 1t | "
                "hits per query |\n",
                workers);
    std::printf("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    std::vector<std::string> first_rows;
    for (const std::string &scene_name : scenes)
        for (uint32_t n : sizes) {
            Workload w = make(scene_name, n, rays, regions, sweeps);
            const char *scene = scene_name.c_str();
            // The first query after the boxes were set builds the tree, on a fresh world each
            // round: against that world's first collide.
            bpx_query probe = w.regions[0];
            size_t count = 0;
            std::vector<double> builds, refits, collides, ratios;
            bpx_query_stats qs = {};
            std::vector<bpx_box> moved = w.boxes;
            scene_rng r;
            scene_rng_seed(&r, 3);
            scene_move(moved.data(), n, 0.1f, &r);
            for (int round = 0; round < rounds; round++) {
                bpx_world *fresh = make_world(w, workers);
                double t0 = now_s();
                bpx_world_query(fresh, &probe, nullptr, 0, &count);
                builds.push_back(now_s() - t0);
                bpx_world_set_boxes(fresh, moved.data(), n);
                t0 = now_s();
                bpx_world_query(fresh, &probe, nullptr, 0, &count);
                refits.push_back(now_s() - t0);
                qs = bpx_world_query_stats(fresh);
                t0 = now_s();
                bpx_world_collide(fresh);
                collides.push_back(now_s() - t0);
                ratios.push_back(builds.back() / collides.back());
                bpx_world_destroy(fresh);
            }
            char row[320];
            std::snprintf(row, sizeof row,
                          "| %s | %u | %.1f ms | %.1f ms | %.1f ms | %.2f | %llu builds, %llu "
                          "refits, %u nodes |",
                          scene, n, 1e3 * median(builds), 1e3 * median(refits),
                          1e3 * median(collides), median(ratios), (unsigned long long)qs.builds,
                          (unsigned long long)qs.refits, qs.nodes);
            std::string each;
            for (double ratio : ratios) {
                char one[16];
                std::snprintf(one, sizeof one, " %.2f", ratio);
                each += one;
            }
            first_rows.push_back(std::string(row) + each + " |");
            bpx_world *one = make_world(w, 1), *many = make_world(w, workers);
            bpx_world_query(one, &probe, nullptr, 0, &count);
            bpx_world_query(many, &probe, nullptr, 0, &count);
#ifdef BPX_QB_HAVE_BULLET
            std::unique_ptr<Bullet> bullet(use_bullet ? new Bullet(w.boxes) : nullptr);
#endif
#ifdef BPX_QB_HAVE_BOX2D
            std::unique_ptr<Box2D> box2d(use_box2d ? new Box2D(w.boxes) : nullptr);
#endif
#ifdef BPX_QB_HAVE_EMBREE
            std::unique_ptr<Embree> embree(use_embree ? new Embree(w.boxes) : nullptr);
#endif
            const std::vector<bpx_query> *sets[3] = {&w.rays, &w.regions, &w.sweeps};
            const char *names[3] = {"ray closest", "region", "swept box closest"};
            for (int k = 0; k < 3; k++) {
                const std::vector<bpx_query> &qs_k = *sets[k];
                if (qs_k.empty())
                    continue;
                std::vector<double> b1s, bms, bullets, box2ds, embrees;
                uint64_t b1_hits = 0;
                for (int round = 0; round < rounds; round++) {
#ifdef BPX_COUNT_VISITS
                    bpx__visits = 0;
#endif
                    BpxResult b1 = run_bpx(one, qs_k);
#ifdef BPX_COUNT_VISITS
                    if (round == 0)
                        std::fprintf(stderr, "visits: %s %u %s: %.2f nodes per query\n", scene, n,
                                     names[k], (double)bpx__visits / (double)qs_k.size());
#endif
                    BpxResult bm = run_bpx(many, qs_k);
                    b1s.push_back(b1.ns_per_query);
                    bms.push_back(bm.ns_per_query);
                    b1_hits = b1.hits;
                    uint64_t hits = 0;
#ifdef BPX_QB_HAVE_BULLET
                    if (bullet) {
                        bullets.push_back(time_each(
                            qs_k,
                            [&](const bpx_query &q) {
                                return k == 1 ? bullet->region(q) : bullet->cast(w.boxes, q);
                            },
                            &hits));
                        if (hits != b1.hits && round == 0)
                            std::fprintf(stderr, "note: %s %s n=%u: bullet %llu hits, bpx %llu\n",
                                         scene, names[k], n, (unsigned long long)hits,
                                         (unsigned long long)b1.hits);
                    }
#endif
#ifdef BPX_QB_HAVE_BOX2D
                    if (box2d)
                        box2ds.push_back(time_each(
                            qs_k,
                            [&](const bpx_query &q) {
                                return k == 1 ? box2d->region(q) : box2d->cast(q);
                            },
                            &hits));
#endif
#ifdef BPX_QB_HAVE_EMBREE
                    if (embree && k == 0) {
                        embrees.push_back(time_each(
                            qs_k, [&](const bpx_query &q) { return embree->cast(q); }, &hits));
                        if (hits != b1.hits && round == 0)
                            std::fprintf(stderr, "note: %s rays n=%u: embree %llu hits, bpx %llu\n",
                                         scene, n, (unsigned long long)hits,
                                         (unsigned long long)b1.hits);
                    }
#endif
                    (void)hits;
                }
                double b1 = median(b1s), bm = median(bms), bullet_ns = median(bullets);
                double box2d_ns = median(box2ds), embree_ns = median(embrees);
                std::printf("| %s | %u | %s | %.0f | %.0f | %.0f | %.0f | %.0f | %.1f× | %.1f× | "
                            "%.2f× | %.2f |\n",
                            scene, n, names[k], b1, bm, bullet_ns, box2d_ns, embree_ns,
                            bullet_ns / b1, box2d_ns / b1, embree_ns / b1,
                            (double)b1_hits / (double)qs_k.size());
                if (rounds > 1 && !embrees.empty()) {
                    std::printf("|  |  | (rounds: embree / bpx 1t |");
                    for (size_t k2 = 0; k2 < embrees.size(); k2++)
                        std::printf(" %.2f", embrees[k2] / b1s[k2]);
                    std::printf(") |  |  |  |  |  |  |  |  |\n");
                }
                std::fflush(stdout);
            }
            bpx_world_destroy(one);
            bpx_world_destroy(many);
        }
    std::printf(
        "\n# the first query after set_boxes: the tree built from scratch on a fresh world, "
        "then after every box moved (a refit), against that world's first collide (auto, "
        "%d workers); medians of %d round(s), build / collide the median of the rounds' "
        "ratios\n\n",
        workers, rounds);
    std::printf(
        "| scene | boxes | build | refit | collide | build / collide | tree | rounds' build "
        "/ collide |\n|---|---:|---:|---:|---:|---:|---|---|\n");
    for (const std::string &row : first_rows)
        std::printf("%s\n", row.c_str());
    return 0;
}
