// The cuda backend's tree comparator run on the host: the same per-item code as the kernels
// (src/cuda/tree.cuh: centres, Morton codes, Karras's build, the refit, the walk), driven by
// loops in place of the grid and a stable sort in place of CUB's radix sort (both order the
// Morton codes with ties by id). Its pairs must be exactly the reference's on every scene kind,
// with removed (inert) boxes among them. Compiled by nvcc, it needs no GPU: this is how machines
// without one (CI) prove the algorithm that test_cuda runs on the device.
#include <algorithm>
#include <cstdio>
#include <numeric>
#include <vector>

#include "cuda/tree.cuh"

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
        bpx_tree::walk(
            t, nodes.data(), leaf_lo.data(), leaf_hi.data(),
            [&](uint32_t i, uint32_t j) { found.push_back(bpx_tree::pair_key(i, j, bits)); });
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
