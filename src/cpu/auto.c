// The auto backend: each cycle, the CPU backend that should be fastest for what it observes.
// Paper modules: none of its own; it composes brute, prune, sap and grid through the backend
// contract (core/backend.h), keeping each one's state slot and never looking inside.
//
// The rule (measured with `bpx bench`; docs/performance.md has the runs):
//   n <= 128                       brute: no sort to pay for, a few SIMD steps per row
//   boxes nearly at rest, n > 96   sap:   its fat boxes absorb small moves, so a cycle touches
//                                         only the few boxes that left theirs
//   sweep candidates per box <= C  prune: one sort on x, a sweep that meets few boxes per box
//   above                          grid:  the sweep's candidates grow like n^(2/3) per box at
//                                         constant density; cells keep them constant
// Two statistics of the x axis, taken each cycle in one pass over the boxes (over every
// (n / AUTO_SAMPLE)-th box past 4 AUTO_SAMPLE boxes):
//   candidates per box ~ n * mean x extent / x span: the boxes a sweep along x meets per box if
//     they are spread evenly (for random scenes at constant density it is n^(2/3) / 2); it
//     grows with n and with the sizes, so a heavy tail of big boxes moves the choice to grid;
//   motion ~ mean |change of min x| since last cycle / mean x extent: how fast boxes leave the
//     fat boxes sap keeps (a margin of 1/16 of the mean extent, at most a quarter of the
//     extents' upper quartile), which is what sap pays for.
// The choice depends on the boxes only, so it (and so the work done) is reproducible; the output
// is the same whichever backend runs. Each delegate keeps its own state between cycles.
#include <math.h>
#include <stdio.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "backends.h"
#include "core/alloc.h"

enum {
    // Brute and prune cross between 100 and 150 boxes on Table 2's scenario (mean us per cycle:
    // n = 100 brute 1.68, prune 2.07; n = 150 brute 2.84-4.45, prune 2.95-3.79; `bpx bench
    // --table2 --backend brute,prune`).
    AUTO_BRUTE_MAX = 128,
    // Past this many boxes the statistics come from every (n / AUTO_SAMPLE)-th box: a pass over
    // all boxes costs 10% of grid's cycle at 1M (auto 2t 139 ms against grid 2t 122 ms, `bpx
    // bench --backend auto,grid --sizes 1000000 --scene uniform --threads 2`).
    AUTO_SAMPLE = 16384,
};
// sap below this motion (boxes moving at constant velocity, `bpx bench --backend sap,prune,grid
// --sizes 10000,100000 --scene resting --step S`): at 0.0005 sap is 1.5x (10k) to 1.8x (100k)
// faster than the best of prune and grid, at 0.0015 even with prune at 10k and 1.2x faster than
// grid at 100k, at 0.005 slower than both. Leaving sap takes twice the motion of entering it, so
// the choice doesn't flicker.
static const double AUTO_SAP_MAX_MOTION = 0.002;

typedef struct auto_state {
    void *states[BPX_BACKEND_COUNT]; // each delegate's backend_state
    bpx_backend last;                // the delegate of the last cycle (AUTO before the first)
    float *last_min_x;               // last cycle's min x per box, to measure motion
    uint32_t last_n, capacity;
} auto_state;

static const bpx_backend_impl *impl_of(bpx_backend id)
{
    switch (id) {
    case BPX_BACKEND_BRUTE:
        return &bpx__brute_backend;
    case BPX_BACKEND_SAP:
        return &bpx__sap_backend;
    case BPX_BACKEND_GRID:
        return &bpx__grid_backend;
    default:
        return &bpx__prune_backend;
    }
}

// The choice before any cycle has run: n alone.
static bpx_backend choice_by_n(uint32_t n)
{
    return n <= AUTO_BRUTE_MAX ? BPX_BACKEND_BRUTE : BPX_BACKEND_PRUNE;
}

bpx_backend bpx__auto_choice(const void *state, uint32_t n)
{
    const auto_state *st = state;
    return st && st->last != BPX_BACKEND_AUTO ? st->last : choice_by_n(n);
}

// Every how many boxes the statistics look at one (the same for the same n), and how many they
// look at: last cycle's min x is kept for those only.
static uint32_t sample_stride(uint32_t n)
{
    return n > 4 * AUTO_SAMPLE ? n / AUTO_SAMPLE : 1;
}

static uint32_t sample_count(uint32_t n)
{
    uint32_t stride = sample_stride(n);
    return n / stride + (n % stride != 0);
}

// The statistics' sums in LANES independent lanes (chains of adds that do not wait on each
// other). Inert boxes (min +inf, max -inf) add nothing and leave min and max as they are.
enum { LANES = 4 };
typedef struct auto_sums {
    float extent[LANES], moved[LANES], low[LANES], high[LANES];
    uint32_t live[LANES];
} auto_sums;

// Samples [from, count), every `stride`-th box, one at a time.
static void add_samples(auto_sums *a, const float *lo, const float *hi, const float *last,
                        uint32_t from, uint32_t count, uint32_t stride)
{
    for (uint32_t s = from; s < count; s++) {
        uint32_t k = s % LANES;
        float l = lo[(size_t)s * stride], h = hi[(size_t)s * stride];
        if (!(l <= h))
            continue;
        a->live[k]++;
        a->extent[k] += h - l;
        a->low[k] = l < a->low[k] ? l : a->low[k]; // not fminf: a call into libm here
        a->high[k] = h > a->high[k] ? h : a->high[k];
        if (last) // inf if just added
            a->moved[k] += fabsf(l - last[s]);
    }
}

#if defined(__SSE2__)
// Every box (stride 1), LANES at a time; returns how many it took (the rest: add_samples).
// Box by box, this pass would cost 3 us of sap's 19 at resting 1k.
static uint32_t add_boxes_sse2(auto_sums *a, const float *lo, const float *hi, const float *last,
                               uint32_t count)
{
    const __m128 zero = _mm_setzero_ps(), magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    __m128 extent = zero, moved = zero, low = _mm_set1_ps(INFINITY), high = _mm_set1_ps(-INFINITY);
    __m128i live = _mm_setzero_si128();
    uint32_t i = 0;
    for (; i + 4 <= count; i += 4) {
        __m128 l = _mm_loadu_ps(lo + i), h = _mm_loadu_ps(hi + i);
        __m128 in = _mm_cmple_ps(l, h);
        live = _mm_sub_epi32(live, _mm_castps_si128(in));                // a true lane is -1
        extent = _mm_add_ps(extent, _mm_max_ps(_mm_sub_ps(h, l), zero)); // inert: -inf
        low = _mm_min_ps(low, l);
        high = _mm_max_ps(high, h);
        if (last) { // inert now: inf - x or NaN, masked off
            __m128 d = _mm_and_ps(_mm_sub_ps(l, _mm_loadu_ps(last + i)), magnitude);
            moved = _mm_add_ps(moved, _mm_and_ps(d, in));
        }
    }
    _mm_storeu_ps(a->extent, extent);
    _mm_storeu_ps(a->moved, moved);
    _mm_storeu_ps(a->low, low);
    _mm_storeu_ps(a->high, high);
    _mm_storeu_si128((__m128i *)(void *)a->live, live);
    return i;
}
#endif

// Measures the two statistics (and keeps this cycle's min x for the next) and picks.
static bpx_backend choose(const bpx_cycle *c, auto_state *st)
{
    uint32_t n = c->n;
    if (n <= AUTO_BRUTE_MAX)
        return BPX_BACKEND_BRUTE;
    const float *lo = c->boxes.lo[0], *hi = c->boxes.hi[0];
    bool have_last = st->last_min_x && st->last_n == n;
    uint32_t stride = sample_stride(n), sampled = sample_count(n);
    auto_sums a = {0};
    for (int k = 0; k < LANES; k++)
        a.low[k] = INFINITY, a.high[k] = -INFINITY;
    const float *last = have_last ? st->last_min_x : NULL;
    uint32_t done = 0;
#if defined(__SSE2__)
    if (stride == 1)
        done = add_boxes_sse2(&a, lo, hi, last, sampled);
#endif
    add_samples(&a, lo, hi, last, done, sampled, stride);
    double extent = 0, moved = 0;
    float low = INFINITY, high = -INFINITY;
    uint32_t live = 0;
    for (int k = 0; k < LANES; k++) {
        extent += a.extent[k];
        moved += a.moved[k];
        low = a.low[k] < low ? a.low[k] : low;
        high = a.high[k] > high ? a.high[k] : high;
        live += a.live[k];
    }
    if (st->capacity >= sampled) {
        for (uint32_t i = 0, k = 0; k < sampled; i += stride, k++)
            st->last_min_x[k] = lo[i];
        st->last_n = n;
    } else {
        st->last_n = 0; // no room (allocation failed): no motion measured next cycle
    }
    double span = (double)high - (double)low;
    if (live * stride <= AUTO_BRUTE_MAX || !(span > 0) || !isfinite(span))
        return live * stride <= AUTO_BRUTE_MAX ? BPX_BACKEND_BRUTE : BPX_BACKEND_PRUNE;
    double motion = moved / extent;             // mean |move| / mean extent
    double candidates = extent * stride / span; // live * (mean extent) / span
    double limit = st->last == BPX_BACKEND_SAP ? 2 * AUTO_SAP_MAX_MOTION : AUTO_SAP_MAX_MOTION;
    if (have_last && motion < limit)
        return BPX_BACKEND_SAP;
    return candidates <= BPX_SWEEP_MAX_CANDIDATES ? BPX_BACKEND_PRUNE : BPX_BACKEND_GRID;
}

static bpx_status auto_compare(void **state, bpx_cycle *c)
{
    auto_state *st = *state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (auto_state){.last = BPX_BACKEND_AUTO};
        *state = st;
    }
    uint32_t wanted = sample_count(c->n);
    if (wanted > st->capacity && c->n > AUTO_BRUTE_MAX) {
        // Room for the motion statistic. On failure auto goes on without it (no sap).
        uint32_t capacity = wanted + wanted / 2;
        float *grown = bpx__alloc(sizeof(float) * capacity);
        if (grown) {
            bpx__free(st->last_min_x, sizeof(float) * st->capacity);
            st->last_min_x = grown;
            st->capacity = capacity;
            st->last_n = 0;
        }
    }
    uint64_t t = bpx__profile_clock(c->profile);
    bpx_backend id = choose(c, st);
    if (c->profile && c->n > AUTO_BRUTE_MAX) { // it reads min x and max x of a sample, and
        uint64_t sampled = sample_count(c->n);  // keeps min x for the next
        bpx__profile_add(c->profile, "auto", "choose", &t, BPX_ACCESS_SEQUENTIAL, 8 * sampled,
                         4 * sampled, 0);
    }
    bpx_status status = impl_of(id)->compare(&st->states[id], c);
    st->last = id;
    return status;
}

static void auto_destroy(void *state)
{
    auto_state *st = state;
    const bpx_backend delegates[] = {BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE, BPX_BACKEND_SAP,
                                     BPX_BACKEND_GRID};
    for (size_t k = 0; k < sizeof delegates / sizeof delegates[0]; k++) {
        const bpx_backend_impl *impl = impl_of(delegates[k]);
        if (st->states[delegates[k]] && impl->destroy)
            impl->destroy(st->states[delegates[k]]);
    }
    bpx__free(st->last_min_x, sizeof(float) * st->capacity);
    bpx__free(st, sizeof *st);
}

static bool auto_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    // Every delegate runs on any SIMD width the CPU has (scalar at worst).
    char inner[96];
    if (!bpx__brute_backend.query(def, reason, inner, sizeof inner))
        return false;
    snprintf(detail, size,
             "brute to n = %d; then sap near rest, prune to %.0f sweep candidates per box, grid "
             "beyond (%.40s)",
             AUTO_BRUTE_MAX, BPX_SWEEP_MAX_CANDIDATES, inner);
    return true;
}

const bpx_backend_impl bpx__auto_backend = {
    .id = BPX_BACKEND_AUTO,
    .name = "auto",
    .query = auto_query,
    .compare = auto_compare,
    .destroy = auto_destroy,
};
