// bpx_bulletbench: Bullet's stepSimulation with btDbvtBroadphase and with btBpxBroadphase, side
// by side. SPDX-License-Identifier: MIT
//
//   bpx_bulletbench [--sizes 1000,10000,100000] [--scene gas|rain] [--steps 60] [--warmup 10]
//                   [--rounds 3] [--backend NAME] [--threads N] [--no-deterministic]
//                   [--only dbvt|bpx]
//
// For each size and round, each broad phase in turn (the order alternates between rounds) builds
// the scene, steps it --warmup steps, then times --steps steps: the whole stepSimulation, and
// its broad-phase part (updateAabbs: every object's AABB and setAabb; computeOverlappingPairs).
// Reported: medians over the rounds of the mean per step. The contact manifolds (body pair,
// contact count) of every timed step are hashed: both broad phases must give the same hashes,
// which needs Bullet's deterministic pair order (on unless --no-deterministic) and no sleeping.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <tuple>
#include <vector>

#include "bullet_scenes.h"

using namespace bullet_scenes;

namespace
{

struct Options {
    std::vector<int> sizes{1000, 10000, 100000};
    std::string scene = "gas";
    int steps = 60, warmup = 10, rounds = 3;
    bpx_world_def def = bpx_default_world_def();
    bool deterministic = true;
    int only = -1; // 0: btDbvtBroadphase only, 1: btBpxBroadphase only (for profiling)
};

struct Run {
    double step_ms = 0, broad_ms = 0, aabb_ms = 0, build_s = 0;
    uint64_t contact_hash = 0;
    size_t pairs = 0, contacts = 0;
};

uint64_t mix(uint64_t h, uint64_t v)
{
    h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
    return h;
}

uint64_t contact_hash(Sim &sim, size_t &count)
{
    std::vector<std::tuple<int, int, int>> list;
    for (int k = 0; k < sim.dispatcher.getNumManifolds(); k++) {
        btPersistentManifold *m = sim.dispatcher.getManifoldByIndexInternal(k);
        if (m->getNumContacts() == 0)
            continue;
        int i = m->getBody0()->getUserIndex(), j = m->getBody1()->getUserIndex();
        list.emplace_back(std::min(i, j), std::max(i, j), m->getNumContacts());
    }
    std::sort(list.begin(), list.end());
    uint64_t h = 1;
    for (auto &[i, j, n] : list)
        h = mix(mix(mix(h, (uint64_t)i), (uint64_t)j), (uint64_t)n);
    count = list.size();
    return h;
}

Run run(const Options &o, Broadphase kind, int n)
{
    Run r;
    auto t0 = std::chrono::steady_clock::now();
    Sim sim(kind, &o.def);
    if (o.scene == "rain")
        scene_rain(sim, n);
    else
        scene_gas(sim, n);
    sim.world->getDispatchInfo().m_deterministicOverlappingPairs = o.deterministic;
    for (btRigidBody *b : sim.bodies)
        b->setActivationState(DISABLE_DEACTIVATION);
    r.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    for (int s = 0; s < o.warmup; s++)
        sim.world->stepSimulation(1.0f / 60, 1, 1.0f / 60);
    sim.world->aabb_seconds = sim.world->pairs_seconds = 0;
    double total = 0;
    r.contact_hash = 1;
    for (int s = 0; s < o.steps; s++) {
        auto a = std::chrono::steady_clock::now();
        sim.world->stepSimulation(1.0f / 60, 1, 1.0f / 60);
        total += std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
        size_t c = 0;
        r.contact_hash = mix(r.contact_hash, contact_hash(sim, c));
        r.contacts += c;
        r.pairs += (size_t)sim.broadphase->getOverlappingPairCache()->getNumOverlappingPairs();
    }
    r.step_ms = total * 1e3 / o.steps;
    r.broad_ms = (sim.world->aabb_seconds + sim.world->pairs_seconds) * 1e3 / o.steps;
    r.aabb_ms = sim.world->aabb_seconds * 1e3 / o.steps;
    return r;
}

double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    size_t m = v.size() / 2;
    return v.size() % 2 ? v[m] : (v[m - 1] + v[m]) / 2;
}

std::vector<int> parse_sizes(const char *s)
{
    std::vector<int> out;
    for (const char *p = s; *p;) {
        out.push_back(std::atoi(p));
        const char *comma = std::strchr(p, ',');
        if (!comma)
            break;
        p = comma + 1;
    }
    return out;
}

int usage()
{
    std::fprintf(stderr, "usage: bpx_bulletbench [--sizes 1000,10000,100000] [--scene gas|rain] "
                         "[--steps 60] [--warmup 10] [--rounds 3] [--backend NAME] "
                         "[--threads N] [--no-deterministic] [--only dbvt|bpx]\n");
    return 2;
}

} // namespace

int main(int argc, char **argv)
{
    Options o;
    for (int k = 1; k < argc; k++) {
        std::string a = argv[k];
        bool more = k + 1 < argc;
        if (a == "--sizes" && more)
            o.sizes = parse_sizes(argv[++k]);
        else if (a == "--scene" && more)
            o.scene = argv[++k];
        else if (a == "--steps" && more)
            o.steps = std::atoi(argv[++k]);
        else if (a == "--warmup" && more)
            o.warmup = std::atoi(argv[++k]);
        else if (a == "--rounds" && more)
            o.rounds = std::atoi(argv[++k]);
        else if (a == "--threads" && more)
            o.def.worker_count = std::atoi(argv[++k]);
        else if (a == "--backend" && more) {
            if (bpx_backend_from_name(argv[++k], &o.def.backend) != BPX_OK)
                return usage();
        } else if (a == "--only" && more) {
            std::string w = argv[++k];
            o.only = w == "dbvt" ? 0 : w == "bpx" ? 1 : -2;
            if (o.only == -2)
                return usage();
        } else if (a == "--no-deterministic")
            o.deterministic = false;
        else
            return usage();
    }
    if (o.scene != "gas" && o.scene != "rain")
        return usage();
    if (o.steps < 1 || o.rounds < 1 || o.warmup < 0)
        return usage();
    std::printf("scene %s, %d warm-up + %d timed steps of 1/60 s, %d rounds (medians), bpx "
                "backend %s, %d bpx threads, deterministic pair order %s\n",
                o.scene.c_str(), o.warmup, o.steps, o.rounds, bpx_backend_name(o.def.backend),
                o.def.worker_count > 1 ? o.def.worker_count : 1, o.deterministic ? "on" : "off");
    std::printf("%8s | %-16s | %9s %9s %9s %9s | %9s %9s | %s\n", "bodies", "broad phase",
                "step ms", "broad ms", "(aabbs)", "other ms", "pairs", "contacts", "build s");
    bool all_same = true;
    for (int n : o.sizes) {
        std::vector<double> step[2], broad[2], aabb[2], build[2];
        Run last[2];
        bool same = true;
        for (int round = 0; round < o.rounds; round++) {
            Run r[2];
            for (int t = 0; t < 2; t++) {
                int which = (round % 2) ? 1 - t : t; // alternate who goes first
                if (o.only >= 0 && which != o.only)
                    continue;
                r[which] = run(o, which ? Broadphase::Bpx : Broadphase::Dbvt, n);
                step[which].push_back(r[which].step_ms);
                broad[which].push_back(r[which].broad_ms);
                aabb[which].push_back(r[which].aabb_ms);
                build[which].push_back(r[which].build_s);
            }
            same = same && r[0].contact_hash == r[1].contact_hash && r[0].contacts == r[1].contacts;
            last[0] = r[0];
            last[1] = r[1];
        }
        for (int w = 0; w < 2; w++) {
            if (step[w].empty())
                continue;
            double s = median(step[w]), b = median(broad[w]);
            std::printf("%8d | %-16s | %9.2f %9.2f %9.2f %9.2f | %9.0f %9.0f | %.2f\n", n,
                        broadphase_name(w ? Broadphase::Bpx : Broadphase::Dbvt), s, b,
                        median(aabb[w]), s - b,
                        (double)last[w].pairs / o.steps, (double)last[w].contacts / o.steps,
                        median(build[w]));
        }
        if (step[0].empty() || step[1].empty())
            continue;
        double ms0 = median(step[0]), ms1 = median(step[1]);
        std::printf("%8d | speed-up: step %.2fx, broad phase %.2fx; contact manifolds %s\n", n,
                    ms0 / ms1, median(broad[0]) / median(broad[1]),
                    same            ? "identical every step"
                    : o.deterministic ? "DIFFER"
                                      : "differ (Bullet's pair order: the simulations part)");
        all_same = all_same && same;
        std::fflush(stdout);
    }
    return all_same || !o.deterministic ? 0 : 1;
}
