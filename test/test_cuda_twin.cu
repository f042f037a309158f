// The cuda backend's tree comparator run on the host: the same per-item code as the kernels
// (src/cuda/tree.cuh: centres, Morton codes, Karras's build, the refit, the walk), driven by
// loops in place of the grid and a stable sort in place of CUB's radix sort (both order the
// Morton codes with ties by id). Its pairs must be exactly the reference's on every scene kind,
// with removed (inert) boxes among them. The small comparator (small.cuh: warps and lanes in
// loops) and the device's updater (update.cuh) are held to Algorithm 1 and the host's updater
// the same way. Compiled by nvcc, it needs no GPU: this is how machines
// without one (CI) prove the algorithm that test_cuda runs on the device.
#include <algorithm>
#include <cstdio>
#include <numeric>
#include <vector>

#include "cuda/tree.cuh"
#include "cuda/small.cuh"
#include "cuda/update.cuh"

#include "check.h"
#include "scenes.h"

namespace {

std::vector<bpx_pair> twin_pairs(const std::vector<bpx_box> &boxes)
{
    const uint32_t n = (uint32_t)boxes.size();
    std::vector<bpx_pair> pairs;
    if (n < 2)
        return pairs;
    uint32_t scene[6] = {~0u, ~0u, ~0u, 0, 0, 0};
    std::vector<float> centres(3 * (size_t)n);
    for (uint32_t i = 0; i < n; i++) {
        const bpx_box &b = boxes[i];
        bpx_tree::centre(b.min, b.max, &centres[3 * (size_t)i]);
        if (!bpx_tree::live(b.min[0], b.max[0]))
            continue;
        for (int a = 0; a < 3; a++) {
            scene[a] = std::min(scene[a], bpx_tree::order_key(centres[3 * (size_t)i + a]));
            scene[3 + a] = std::max(scene[3 + a], bpx_tree::order_key(centres[3 * (size_t)i + a]));
        }
    }
    std::vector<uint32_t> code(n), ids(n);
    for (uint32_t i = 0; i < n; i++)
        code[i] = bpx_tree::live(boxes[i].min[0], boxes[i].max[0])
                      ? bpx_tree::morton(&centres[3 * (size_t)i], scene)
                      : ~0u;
    std::iota(ids.begin(), ids.end(), 0u);
    // By the bits the device's radix sort orders by; the codes keep all theirs, as CUB's do.
    const uint32_t sorted_bits =
        BPX_CUDA_MORTON_SORT_BITS < 32 ? (1u << BPX_CUDA_MORTON_SORT_BITS) - 1 : ~0u;
    std::stable_sort(ids.begin(), ids.end(), [&](uint32_t a, uint32_t b) {
        return (code[a] & sorted_bits) < (code[b] & sorted_bits);
    });
    std::vector<uint32_t> keys(n);
    std::vector<float4> leaf_lo(n), leaf_hi(n);
    for (uint32_t t = 0; t < n; t++) {
        const bpx_box &b = boxes[ids[t]];
        keys[t] = code[ids[t]];
        leaf_lo[t] = make_float4(b.min[0], b.min[1], b.min[2], bpx_tree::float_of(ids[t]));
        leaf_hi[t] = make_float4(b.max[0], b.max[1], b.max[2], 0.0f);
    }
    std::vector<uint32_t> leaf_parent(n, ~0u), node_parent(n, ~0u), arrivals(n, 0);
    std::vector<bpx_cuda_node> nodes(n - 1);
    for (int i = 0; i < (int)n - 1; i++)
        bpx_tree::build_node(keys.data(), (int)n, i, leaf_parent.data(), node_parent.data());
    // Every leaf and every internal node but the root has a parent (else no refit can run).
    bool tree = true;
    for (uint32_t t = 0; t < n; t++)
        tree = tree && leaf_parent[t] != ~0u;
    for (uint32_t i = 1; i + 1 < n; i++)
        tree = tree && node_parent[i] != ~0u;
    CHECK_MSG(tree, "a leaf or a node has no parent (n = %u)", n);
    if (!tree)
        return pairs;
    // Leaves one after another: each runs to the root or to the first node its sibling has not
    // reached, as any interleaving of the device's threads does.
    for (uint32_t t = 0; t < n; t++)
        bpx_tree::refit_leaf(t, leaf_lo.data(), leaf_hi.data(), leaf_parent.data(),
                             node_parent.data(), nodes.data(),
                             [&](uint32_t p) { return arrivals[p]++; });
    for (uint32_t i = 0; i + 1 < n; i++)
        CHECK_MSG(arrivals[i] == 2, "node %u: %u arrivals", i, arrivals[i]);
    // The pairs as the device packs them, after padding keys (all ones) as on the device path,
    // ordered by the bits its radix sort orders by, then unpacked.
    const int bits = bpx_tree::key_bits(n);
    std::vector<unsigned long long> found;
    for (uint32_t t = 0; t + 1 < n; t++)
        bpx_tree::walk(t, nodes.data(), leaf_lo.data(), leaf_hi.data(), leaf_parent.data(),
                       node_parent.data(), [&](uint32_t i, uint32_t j) {
                           found.push_back(bpx_tree::pair_key(i, j, bits));
                       });
    const size_t count = found.size();
    found.resize(count + 3, ~0ull);
    const unsigned long long sorted_key_bits = 2 * bits < 64 ? (1ull << (2 * bits)) - 1 : ~0ull;
    std::stable_sort(found.begin(), found.end(), [&](unsigned long long a, unsigned long long b) {
        return (a & sorted_key_bits) < (b & sorted_key_bits);
    });
    for (size_t k = 0; k < count; k++)
        pairs.push_back(bpx_tree::key_pair(found[k], bits));
    return pairs;
}

void check_scene(const std::vector<bpx_box> &boxes, const char *what)
{
    std::vector<bpx_pair> got = twin_pairs(boxes);
    // The reference (Algorithm 1) where it is quick, else sap, which test_differential checks
    // against it.
    uint32_t n = (uint32_t)boxes.size();
    std::vector<bpx_pair> want;
    if (n <= 3000) { // Algorithm 1 itself; inert boxes fail its comparisons like any box would
        for (uint32_t i = 0; i < n; i++)
            for (uint32_t j = i + 1; j < n; j++)
                if (bpx_overlap(&boxes[i], &boxes[j]))
                    want.push_back(bpx_pair{i, j});
    } else {
        size_t count = 0;
        bpx_status s = bpx_find_pairs(boxes.data(), n, BPX_BACKEND_SAP, nullptr, 0, &count, nullptr);
        CHECK(s == BPX_OK || s == BPX_ERR_CAPACITY);
        want.resize(count);
        CHECK(bpx_find_pairs(boxes.data(), n, BPX_BACKEND_SAP, want.data(), count, &count,
                             nullptr) == BPX_OK);
    }
    size_t diff = 0;
    while (diff < got.size() && diff < want.size() && got[diff].i == want[diff].i &&
           got[diff].j == want[diff].j)
        diff++;
    CHECK_MSG(got.size() == want.size() && diff == got.size(),
              "%s: %zu pairs, want %zu, first difference at %zu", what, got.size(), want.size(),
              diff);
}

// A world on Algorithm 1, for the host's updater.
bpx_world *reference_world()
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_REFERENCE;
    bpx_world *w = nullptr;
    CHECK(bpx_world_create(&def, &w) == BPX_OK);
    return w;
}

// Boxes as the paper's two-phase mode keeps them: centres (x, y, z per object), origin-centred
// minima (<= 0) as the world loads them, and the same minima as three planes of n, as the device
// keeps them.
struct two_phase {
    std::vector<float> centres, minima, planes;
    explicit two_phase(const std::vector<bpx_box> &boxes)
    {
        const size_t n = boxes.size(), floats = 3 * n + 3;
        centres.resize(floats), minima.resize(floats), planes.resize(floats);
        for (size_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                centres[3 * i + a] = 0.5f * boxes[i].min[a] + 0.5f * boxes[i].max[a];
                minima[3 * i + a] = -(0.5f * boxes[i].max[a] - 0.5f * boxes[i].min[a]);
                planes[(size_t)a * n + i] = minima[3 * i + a];
            }
    }
};

// The small comparator (small.cuh) as its kernel runs it, lanes and warps in loops: each row's
// hit words (a ballot: bit l for lane l), the rows' counts scanned, each hit written at its place.
std::vector<bpx_pair> small_twin(const bpx_small::input &in, uint32_t n)
{
    std::vector<uint32_t> masks((size_t)n * 32), counts(n);
    uint32_t total =
        bpx_small::rows_on_host(in, n, masks.data(), 32, counts.data(), [](uint32_t, int) {});
    std::vector<bpx_pair> pairs(total, bpx_pair{~0u, ~0u});
    bpx_small::pairs_on_host(n, masks.data(), 32, [&](uint32_t at, bpx_pair p) {
        CHECK(at < pairs.size() && pairs[at].i == ~0u); // each place once
        if (at < pairs.size())
            pairs[at] = p;
    });
    return pairs;
}

// The small comparator on SoA boxes and on centres + minima, against Algorithm 1 on the boxes the
// host's updater makes (bpx_world_update_centres: the same pairs).
void check_small(const std::vector<bpx_box> &boxes, const char *what)
{
    const uint32_t n = (uint32_t)boxes.size();
    std::vector<float> soa(6 * (size_t)n + 6);
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            soa[(size_t)a * n + i] = boxes[i].min[a];
            soa[(size_t)(3 + a) * n + i] = boxes[i].max[a];
        }
    bpx_small::input in = {{&soa[0], &soa[n], &soa[2 * (size_t)n]},
                           {&soa[3 * (size_t)n], &soa[4 * (size_t)n], &soa[5 * (size_t)n]},
                           nullptr, nullptr, 0};
    std::vector<bpx_pair> want;
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = i + 1; j < n; j++)
            if (bpx_overlap(&boxes[i], &boxes[j]))
                want.push_back(bpx_pair{i, j});
    std::vector<bpx_pair> got = small_twin(in, n);
    CHECK_MSG(got.size() == want.size() &&
                  (want.empty() ||
                   memcmp(got.data(), want.data(), sizeof(bpx_pair) * want.size()) == 0),
              "%s: small comparator %zu pairs, want %zu", what, got.size(), want.size());
    // Centres: the boxes the host's updater makes from them, on a reference world.
    two_phase split(boxes);
    std::vector<float> &centres = split.centres, &minima = split.minima, &planes = split.planes;
    bpx_world *w = reference_world();
    if (bpx_world_load_extents(w, minima.data(), n) == BPX_OK &&
        bpx_world_update_centres(w, centres.data()) == BPX_OK) {
        CHECK(bpx_world_collide(w) == BPX_OK);
        size_t count = 0;
        const bpx_pair *host = bpx_world_pairs(w, &count);
        in.centres = centres.data(), in.minima = planes.data(), in.stride = n;
        got = small_twin(in, n);
        CHECK_MSG(got.size() == count &&
                      (count == 0 || memcmp(got.data(), host, sizeof(bpx_pair) * count) == 0),
                  "%s: small comparator on centres %zu pairs, host's updater %zu", what,
                  got.size(), count);
    }
    bpx_world_destroy(w);
}

// The device's updater (update.cuh) against the host's (bpx_world_update_centres on a reference
// world): the boxes it makes give the same pairs, and the first object whose box is not finite,
// with its axis, is the one the host names.
void check_updater(const std::vector<bpx_box> &boxes, const char *what)
{
    const uint32_t n = (uint32_t)boxes.size();
    two_phase split(boxes);
    std::vector<float> &centres = split.centres, &minima = split.minima, &planes = split.planes;
    bpx_world *w = reference_world();
    CHECK(bpx_world_load_extents(w, minima.data(), n) == BPX_OK);
    for (int bad = 0; bad < 3; bad++) {
        // bad 1: object n/2's centre NaN on y, infinite on z; bad 2: also an overflow at n/3, on z.
        if (bad == 1 && n > 2)
            centres[3 * (size_t)(n / 2) + 1] = NAN, centres[3 * (size_t)(n / 2) + 2] = INFINITY;
        if (bad == 2 && n > 2)
            centres[3 * (size_t)(n / 3) + 2] = 3e38f, planes[2 * (size_t)n + n / 3] = -3e38f;
        if (bad == 2 && n > 2) { // the world's minima must say the same
            minima[3 * (size_t)(n / 3) + 2] = -3e38f;
            CHECK(bpx_world_load_extents(w, minima.data(), n) == BPX_OK);
        }
        std::vector<bpx_box> made(n);
        uint32_t first = UINT32_MAX;
        int first_axis = -1;
        for (uint32_t i = 0; i < n; i++) {
            int axis =
                bpx_update::box_of(centres.data(), planes.data(), planes.data() + n,
                                   planes.data() + 2 * (size_t)n, i, made[i].min, made[i].max);
            if (axis >= 0 && first == UINT32_MAX)
                first = i, first_axis = axis;
        }
        bpx_status s = bpx_world_update_centres(w, centres.data());
        if (first == UINT32_MAX) {
            CHECK_MSG(s == BPX_OK, "%s: the host refused centres the updater took", what);
            CHECK(bpx_world_collide(w) == BPX_OK);
            size_t count = 0;
            const bpx_pair *want = bpx_world_pairs(w, &count);
            std::vector<bpx_pair> got;
            for (uint32_t i = 0; i < n; i++)
                for (uint32_t j = i + 1; j < n; j++)
                    if (bpx_overlap(&made[i], &made[j]))
                        got.push_back(bpx_pair{i, j});
            CHECK_MSG(got.size() == count &&
                          (count == 0 || memcmp(got.data(), want, sizeof(bpx_pair) * count) == 0),
                      "%s: updater pairs %zu, host %zu", what, got.size(), count);
        } else {
            const bpx_error *e = bpx_world_error(w);
            CHECK_MSG(s == BPX_ERR_NOT_FINITE && e->index == first && e->axis == first_axis,
                      "%s bad %d: updater names %u axis %d, host %u axis %d", what, bad, first,
                      first_axis, e->index, e->axis);
        }
    }
    bpx_world_destroy(w);
}

} // namespace

int main()
{
    static const uint32_t sizes[] = {0, 1, 2, 3, 5, 17, 64, 257, 1000, 2500};
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        for (uint32_t n : sizes) {
            std::vector<bpx_box> boxes(n ? n : 1);
            boxes.resize(n);
            CHECK(scene_generate((scene_kind)kind, n, 3 + n, boxes.data()) == 0);
            char what[96];
            snprintf(what, sizeof what, "%s n=%u", scene_kind_name((scene_kind)kind), n);
            check_scene(boxes, what);
            // Removed ids: inert boxes (min +inf, max -inf) scattered through the array.
            for (uint32_t i = 0; i < n; i += 7)
                for (int a = 0; a < 3; a++)
                    boxes[i].min[a] = INFINITY, boxes[i].max[a] = -INFINITY;
            snprintf(what, sizeof what, "%s n=%u with inert boxes", scene_kind_name((scene_kind)kind), n);
            check_scene(boxes, what);
        }
    }
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        for (uint32_t n : {2u, 3u, 31u, 32u, 33u, 64u, 65u, 500u, 1000u, 1024u}) {
            std::vector<bpx_box> boxes(n);
            CHECK(scene_generate((scene_kind)kind, n, 13 + n, boxes.data()) == 0);
            char what[96];
            snprintf(what, sizeof what, "small %s n=%u", scene_kind_name((scene_kind)kind), n);
            check_small(boxes, what);
        }
    }
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        for (uint32_t n : {0u, 1u, 3u, 300u, 2000u}) {
            std::vector<bpx_box> boxes(n ? n : 1);
            boxes.resize(n);
            CHECK(scene_generate((scene_kind)kind, n, 11 + n, boxes.data()) == 0);
            char what[96];
            snprintf(what, sizeof what, "updater %s n=%u", scene_kind_name((scene_kind)kind), n);
            check_updater(boxes, what);
        }
    }
    // The benchmark's scenes, larger: uniform and heavy-tailed sizes.
    for (uint32_t n : {20000u, 60000u}) {
        std::vector<bpx_box> boxes(n);
        scene_uniform_density(n, 1.0f, 9, boxes.data());
        check_scene(boxes, "uniform");
        scene_heavy_tailed_density(n, 9, boxes.data());
        check_scene(boxes, "heavy");
    }
    // A live box alone in the top cell (Morton code 0x3FFFFFFF) after an inert id: the inert
    // box's code (~0u) must still sort after it, or the codes are out of order and the build
    // makes no tree.
    for (uint32_t n : {3u, 40u, 2500u}) {
        std::vector<bpx_box> boxes(n);
        CHECK(scene_generate(SCENE_SPARSE, n, 5, boxes.data()) == 0);
        for (int a = 0; a < 3; a++) {
            boxes[n - 1].min[a] = 1e6f, boxes[n - 1].max[a] = 1e6f + 1.0f;
            boxes[0].min[a] = INFINITY, boxes[0].max[a] = -INFINITY;
        }
        char what[96];
        snprintf(what, sizeof what, "n=%u, top cell after an inert box", n);
        check_scene(boxes, what);
    }
    return check_finish("test_cuda_twin", 1);
}
