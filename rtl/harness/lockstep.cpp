// bpx RTL lockstep harness: runs the Verilated chip (rtl/bpx_board.sv: the chip plus the
// board's SSRAM) and the C model (bpx_model_run_boxes with its per-clock trace hook) on the same
// boxes and compares every clock: phase, whether the comparator addresses its RAMs, the 2M port
// addresses (discarded ports included), the maximum address, the registered hits and their
// row, the stall, the emitted pair, the fullest FIFO and the collision count. At the end: the
// clock count, the collision-count register, the collision RAM in emitter order against
// bpx_model_emitted, and the sorted pairs against bpx_find_pairs(BPX_BACKEND_REFERENCE).
// Some scenes hold the collision output back (col_ready low on random clocks), the model's
// collision_ready hook giving the same pattern.
//
// Built once per configuration (BPX_RTL_M, BPX_RTL_DEPTH, BPX_RTL_FDEPTH, BPX_RTL_LAT and the
// Verilated class VTOP). Exit status 0 when every scene matches, 1 otherwise.
#include <algorithm>
#include <cfloat>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <verilated.h>

#include "bpx/bpx.h"
#include "bpx/model.h"

#include VTOP_HEADER

static constexpr int M = BPX_RTL_M;
static constexpr uint32_t DEPTH = BPX_RTL_DEPTH;
static constexpr uint32_t FDEPTH = BPX_RTL_FDEPTH;
static constexpr int LAT = BPX_RTL_LAT;
static constexpr int PORTS = 2 * M;

static int clog2(uint32_t v)
{
    int b = 0;
    while ((1ull << b) < v)
        b++;
    return b;
}
static const int AW = clog2(DEPTH + 2 * M) + 1;

// Bits [lo, lo + w) of a Verilated output of any width.
template <typename T> static uint64_t bits(const T &v, int lo, int w)
{
    return (static_cast<uint64_t>(v) >> lo) & ((w >= 64) ? ~0ull : ((1ull << w) - 1));
}
template <std::size_t N> static uint64_t bits(const VlWide<N> &v, int lo, int w)
{
    uint64_t out = 0;
    for (int b = 0; b < w; b++)
        out |= (uint64_t)((v[(lo + b) / 32] >> ((lo + b) % 32)) & 1u) << b;
    return out;
}

struct Clock { // one clock, as the model's trace hook saw it
    int phase;
    bool addressing;
    uint32_t ports[PORTS];
    uint32_t max_address;
    uint64_t hits;
    uint32_t hit_row;
    bool stalled;
    bool emitted;
    bpx_pair pair;
    uint32_t fifo_fill_max;
};

static void on_clock(const bpx_model_clock *c, void *user)
{
    auto *clocks = static_cast<std::vector<Clock> *>(user);
    Clock k{};
    k.phase = c->phase;
    k.addressing = c->addressing;
    if (c->addressing)
        for (int p = 0; p < PORTS; p++)
            k.ports[p] = c->ports[p];
    k.max_address = c->max_address;
    k.hits = c->hits;
    k.hit_row = c->hit_row;
    k.stalled = c->stalled;
    k.emitted = c->emitted;
    k.pair = c->pair;
    k.fifo_fill_max = c->fifo_fill_max;
    if (c->clock != clocks->size()) {
        std::fprintf(stderr, "model trace skipped a clock (%" PRIu64 ")\n", c->clock);
        std::exit(1);
    }
    clocks->push_back(k);
}

static uint32_t fbits(float f)
{
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

struct Harness {
    VerilatedContext ctx;
    std::unique_ptr<VTOP> top{new VTOP{&ctx}};
    uint64_t total_clocks = 0;
    uint64_t total_stalls = 0;
    uint64_t total_pairs = 0;

    void tick()
    {
        top->clk = 1;
        top->eval();
        top->clk = 0;
        top->eval();
    }
    void reg_write(int addr, uint32_t value)
    {
        top->reg_we = 1;
        top->reg_addr = addr;
        top->reg_wdata = value;
        tick();
        top->reg_we = 0;
        top->eval();
    }
    uint32_t reg_read(int addr)
    {
        top->reg_addr = addr;
        top->eval();
        return top->reg_rdata;
    }

    std::vector<Clock> trace; // the model's clocks of its last call

    // The collision port's ready, a function of the clock alone (the model's hook is called
    // only for the clocks it steps): ready on ready_percent of the clocks, drawn by a hash.
    uint32_t ready_percent = 100;
    uint64_t ready_seed = 0;
    bool ready(uint64_t clock) const
    {
        if (ready_percent >= 100)
            return true;
        uint64_t x = (clock + 1) * 0x9e3779b97f4a7c15ull ^ ready_seed;
        x ^= x >> 31;
        x *= 0xbf58476d1ce4e5b9ull;
        x ^= x >> 29;
        return x % 100 < ready_percent;
    }
    static bool model_ready(uint64_t clock, void *user)
    {
        return static_cast<const Harness *>(user)->ready(clock);
    }

    bpx_model *new_model()
    {
        bpx_model_config config = bpx_model_default_config();
        config.m = M;
        config.ram_depth = DEPTH;
        config.fifo_depth = FDEPTH;
        config.ssram_latency = LAT;
        config.trace = on_clock;
        config.trace_user = &trace;
        config.collision_ready = model_ready;
        config.collision_ready_user = this;
        bpx_model *model = nullptr;
        if (bpx_model_create(&config, &model) != BPX_OK) {
            std::fprintf(stderr, "bpx_model_create failed\n");
            std::exit(2);
        }
        return model;
    }

    // One run of the chip next to the model's last call (its clocks in `trace`, its status and
    // report given): the host writes words[b][i] to bank b, address i (b < banks), then N and
    // CONTROL (start, mode). ref: the boxes whose reference pairs the chip must find (NULL: an
    // initialisation run, no pairs). Returns the number of mismatches (printing the first few).
    int run(const std::string &name, uint32_t n, int mode, int banks,
            const std::vector<float> *words, bpx_status status, const bpx_model_report &report,
            bpx_model *model, const std::vector<bpx_box> *ref_boxes, bool expect_overflow)
    {
        int bad = 0;
        auto fail = [&](const char *what, uint64_t clock, uint64_t rtl, uint64_t want) {
            if (bad < 8)
                std::fprintf(stderr, "  %s: clock %" PRIu64 ": %s: rtl %" PRIu64 " model %" PRIu64 "\n",
                             name.c_str(), clock, what, rtl, want);
            bad++;
        };
        // The host writes the SSRAM, then N and CONTROL.
        for (uint32_t i = 0; i < n && i < DEPTH; i++)
            for (int b = 0; b < banks; b++) {
                top->host_we = 1;
                top->host_bank = b;
                top->host_addr = i;
                top->host_data = fbits(words[b][i]);
                tick();
            }
        top->host_we = 0;
        reg_write(0, n);
        reg_write(1, 1u | (uint32_t)mode << 1);

        std::vector<bpx_pair> written; // the collision SSRAM, as the chip wrote it
        uint64_t clock = 0, emitted_before = 0;
        const bool lockstep = status == BPX_OK || status == BPX_ERR_TOO_MANY_BOXES;
        const uint64_t limit = (uint64_t)trace.size() + 100000;
        while (top->phase != 7 && clock < limit) {
            // Before the edge: phase, addresses, registered hits, stall.
            const Clock *m = lockstep && clock < trace.size() ? &trace[clock] : nullptr;
            if (lockstep && !m) {
                fail("model stopped; rtl clock", clock, 1, 0);
            } else if (m) {
                if (top->phase != m->phase)
                    fail("phase", clock, top->phase, m->phase);
                if ((bool)top->t_addressing != m->addressing)
                    fail("addressing", clock, top->t_addressing, m->addressing);
                if (m->addressing) {
                    if (top->t_max != m->max_address)
                        fail("max address", clock, top->t_max, m->max_address);
                    for (int p = 0; p < PORTS; p++) {
                        uint64_t a = bits(top->t_ports, p * AW, AW);
                        uint64_t want = m->ports[p];
                        uint64_t got = a <= top->t_max ? a : BPX_MODEL_DISCARDED;
                        if (got != want)
                            fail(("port " + std::to_string(p)).c_str(), clock, got, want);
                    }
                }
                uint64_t hits = top->t_hits_valid ? (uint64_t)top->t_hits : 0;
                if (hits != m->hits)
                    fail("hits", clock, hits, m->hits);
                if (top->t_hits_valid && hits && top->t_hit_row != m->hit_row)
                    fail("hit row", clock, top->t_hit_row, m->hit_row);
                if ((bool)top->t_stalled != m->stalled)
                    fail("stall", clock, top->t_stalled, m->stalled);
                total_stalls += top->t_stalled;
            }
            top->col_ready = ready(clock);
            if (top->col_we && top->col_ready) // the collision SSRAM takes the pair
                written.push_back({(uint32_t)top->col_i, (uint32_t)top->col_j});
            tick();
            // After the edge: the emitter's output register, the FIFOs, the count register.
            if (m) {
                if ((bool)top->t_emitted != m->emitted)
                    fail("emitted", clock, top->t_emitted, m->emitted);
                if (m->emitted && top->t_emitted) {
                    if (top->t_pair_i != m->pair.i)
                        fail("pair i", clock, top->t_pair_i, m->pair.i);
                    if (top->t_pair_j != m->pair.j)
                        fail("pair j", clock, top->t_pair_j, m->pair.j);
                }
                if (top->t_fill_max != m->fifo_fill_max)
                    fail("fifo fill max", clock, top->t_fill_max, m->fifo_fill_max);
                if (top->t_count != emitted_before)
                    fail("count register", clock, top->t_count, emitted_before);
                emitted_before += m->emitted && ready(clock + 1); // taken at the next edge
            }
            clock++;
        }
        top->col_ready = 1;
        if (top->phase != 7)
            fail("rtl never finished", clock, clock, 0);
        if (lockstep && clock != trace.size())
            fail("clocks", clock, clock, trace.size());

        if (reg_read(3) != DEPTH)
            fail("DEPTH register", clock, reg_read(3), DEPTH);
        const uint32_t st = reg_read(1);
        const bool rtl_error = st & 2u, rtl_overflow = st & 4u;
        if (rtl_error != (status == BPX_ERR_TOO_MANY_BOXES))
            fail("error flag", clock, rtl_error, status == BPX_ERR_TOO_MANY_BOXES);
        if (rtl_overflow != expect_overflow)
            fail("overflow flag", clock, rtl_overflow, expect_overflow);
        if (!expect_overflow && status != BPX_OK && status != BPX_ERR_TOO_MANY_BOXES)
            fail("model status", clock, 0, (uint64_t)status);
        if (status == BPX_OK && ref_boxes) {
            const uint32_t count = reg_read(2);
            if (count != report.collisions)
                fail("COUNT register", clock, count, report.collisions);
            size_t emitted_count = 0;
            const bpx_pair *emitted = bpx_model_emitted(model, &emitted_count);
            if (written.size() != emitted_count)
                fail("collisions written", clock, written.size(), emitted_count);
            for (size_t k = 0; k < written.size() && k < emitted_count; k++)
                if (written[k].i != emitted[k].i || written[k].j != emitted[k].j)
                    fail("collision RAM entry", k, (uint64_t)written[k].i << 32 | written[k].j,
                         (uint64_t)emitted[k].i << 32 | emitted[k].j);
            // Against the reference: the chip's pairs, sorted.
            std::vector<bpx_pair> sorted = written;
            for (auto &p : sorted)
                if (p.i > p.j)
                    std::swap(p.i, p.j);
            std::sort(sorted.begin(), sorted.end(), [](const bpx_pair &a, const bpx_pair &b) {
                return a.i != b.i ? a.i < b.i : a.j < b.j;
            });
            size_t ref_count = 0;
            bpx_find_pairs(ref_boxes->data(), n, BPX_BACKEND_REFERENCE, nullptr, 0, &ref_count, nullptr);
            std::vector<bpx_pair> ref(ref_count + 1);
            if (bpx_find_pairs(ref_boxes->data(), n, BPX_BACKEND_REFERENCE, ref.data(), ref.size(),
                               &ref_count, nullptr) != BPX_OK)
                fail("reference failed", 0, 0, 0);
            ref.resize(ref_count);
            if (sorted.size() != ref.size())
                fail("pairs vs reference (count)", clock, sorted.size(), ref.size());
            else
                for (size_t k = 0; k < ref.size(); k++)
                    if (sorted[k].i != ref[k].i || sorted[k].j != ref[k].j) {
                        fail("pair vs reference", k, (uint64_t)sorted[k].i << 32 | sorted[k].j,
                             (uint64_t)ref[k].i << 32 | ref[k].j);
                        break;
                    }
            total_pairs += written.size();
        }
        std::printf("%-28s n=%-5u clocks=%-7" PRIu64 " pairs=%-6" PRIu64 " stalls=%-6" PRIu64
                    " mismatches=%d\n",
                    name.c_str(), n, clock, (uint64_t)report.collisions, report.stall_clocks, bad);
        total_clocks += clock;
        return bad;
    }

    // General boxes (mode 0): bpx_model_run_boxes next to the chip.
    int boxes(const std::string &name, const std::vector<bpx_box> &b)
    {
        const uint32_t n = (uint32_t)b.size();
        std::vector<float> words[6];
        for (int k = 0; k < 6; k++)
            words[k].resize(n);
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                words[a][i] = b[i].min[a];
                words[3 + a][i] = b[i].max[a];
            }
        bpx_model *model = new_model();
        trace.clear();
        bpx_model_report report{};
        bpx_status status = bpx_model_run_boxes(model, b.data(), n, &report);
        int bad = run(name, n, 0, 6, words, status, report, model, &b, false);
        bpx_model_destroy(model);
        return bad;
    }

    // The paper's two phases: minima once (mode 1, bpx_model_load_extents), then each cycle's
    // centres (mode 2, bpx_model_run_centres). minima and each centres entry hold 3n floats.
    int centres(const std::string &name, const std::vector<float> &minima,
                const std::vector<std::vector<float>> &cycles, bool expect_overflow = false)
    {
        const uint32_t n = (uint32_t)(minima.size() / 3);
        std::vector<float> words[3];
        bpx_model *model = new_model();
        trace.clear();
        bpx_model_report report{};
        bpx_status status = bpx_model_load_extents(model, minima.data(), n, &report);
        for (int a = 0; a < 3; a++) {
            words[a].resize(n);
            for (uint32_t i = 0; i < n; i++)
                words[a][i] = minima[3 * i + a];
        }
        int bad = run(name + " (init)", n, 1, 3, words, status, report, model, nullptr, false);
        for (size_t c = 0; c < cycles.size(); c++) {
            const std::vector<float> &cen = cycles[c];
            std::vector<bpx_box> b(n);
            for (uint32_t i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) {
                    words[a][i] = cen[3 * i + a];
                    volatile float cc = cen[3 * i + a], mm = minima[3 * i + a];
                    b[i].min[a] = cc + mm;
                    b[i].max[a] = cc - mm;
                }
            trace.clear();
            report = bpx_model_report{};
            status = bpx_model_run_centres(model, cen.data(), &report);
            bad += run(name + " (cycle " + std::to_string(c) + ")", n, 2, 3, words, status, report,
                       model, &b, expect_overflow);
        }
        bpx_model_destroy(model);
        return bad;
    }
};

// ---- scenes ---------------------------------------------------------------------------------

static bpx_box box(float x0, float y0, float z0, float x1, float y1, float z1)
{
    return bpx_box{{x0, y0, z0}, {x1, y1, z1}};
}

// Random boxes on an integer grid (touching faces happen often), extents 0..size.
static std::vector<bpx_box> random_grid(std::mt19937 &rng, uint32_t n, int span, int size)
{
    std::uniform_int_distribution<int> pos(0, span), ext(0, size);
    std::vector<bpx_box> out;
    for (uint32_t i = 0; i < n; i++) {
        float x = (float)pos(rng), y = (float)pos(rng), z = (float)pos(rng);
        out.push_back(box(x, y, z, x + ext(rng), y + ext(rng), z + ext(rng)));
    }
    return out;
}

// Random boxes with arbitrary float bit patterns (any finite value, both signs).
static std::vector<bpx_box> random_bits(std::mt19937 &rng, uint32_t n)
{
    std::vector<bpx_box> out;
    auto any = [&]() {
        for (;;) {
            uint32_t u = rng();
            if ((u >> 23 & 0xff) == 0xff)
                continue;
            float f;
            std::memcpy(&f, &u, 4);
            return f;
        }
    };
    for (uint32_t i = 0; i < n; i++) {
        bpx_box b;
        for (int a = 0; a < 3; a++) {
            float p = any(), q = any();
            // Mostly small-magnitude boxes around a few shared values, so some overlap.
            if (rng() % 2) {
                p = (float)(int)(rng() % 7) - 3.0f;
                q = p + (float)(rng() % 3);
            }
            b.min[a] = std::min(p, q);
            b.max[a] = std::max(p, q);
        }
        out.push_back(b);
    }
    return out;
}

int main(int argc, char **argv)
{
    Verilated::commandArgs(argc, argv);
    unsigned seed = argc > 1 ? (unsigned)std::strtoul(argv[1], nullptr, 10) : 1;
    int randoms = argc > 2 ? std::atoi(argv[2]) : 40;
    std::mt19937 rng(seed);
    std::mt19937 ready_rng(seed + 1); // back-pressure patterns: the scenes stay those of rng
    Harness h;
    h.top->col_ready = 1;
    h.top->clk = 0;
    h.top->host_we = 0;
    h.top->reg_we = 0;
    h.top->eval();
    int bad = 0, scenes = 0;
    auto scene = [&](const std::string &name, const std::vector<bpx_box> &b) {
        bad += h.boxes(name, b);
        scenes++;
    };
    std::printf("lockstep: M=%d DEPTH=%u FDEPTH=%u LAT=%d seed=%u\n", M, DEPTH, FDEPTH, LAT, seed);

    for (uint32_t n : {0u, 1u, 2u, 3u, DEPTH - 1, DEPTH})
        scene("random n=" + std::to_string(n), random_grid(rng, n, 6, 2));
    {
        std::vector<bpx_box> all(DEPTH, box(-1, -1, -1, 1, 1, 1));
        scene("all overlapping", all);
        scene("all overlapping n=5", std::vector<bpx_box>(all.begin(), all.begin() + 5));
        // Back-pressure: the collision port ready on a quarter of the clocks, the FIFOs filling.
        h.ready_percent = 25;
        h.ready_seed = ready_rng();
        scene("all overlapping, ready 25%", all);
        h.ready_percent = 100;
    }
    {
        std::vector<bpx_box> none;
        for (uint32_t i = 0; i < DEPTH; i++)
            none.push_back(box(3.0f * i, 0, 0, 3.0f * i + 1, 1, 1));
        scene("none", none);
    }
    {
        std::vector<bpx_box> faces; // unit cubes on a 4 x 4 x k lattice: shared faces, edges, corners
        for (uint32_t i = 0; i < DEPTH; i++) {
            float x = (float)(i % 4), y = (float)(i / 4 % 4), z = (float)(i / 16);
            faces.push_back(box(x, y, z, x + 1, y + 1, z + 1));
        }
        scene("touching faces", faces);
        std::vector<bpx_box> gap; // the same with the faces a float's ulp apart
        for (auto b : faces) {
            for (int a = 0; a < 3; a++)
                b.max[a] = std::nextafter(b.max[a], 0.0f);
            gap.push_back(b);
        }
        scene("faces one ulp apart", gap);
    }
    {
        std::vector<bpx_box> zeros; // boxes meeting at -0 / +0 on every axis
        for (uint32_t i = 0; i < DEPTH; i++) {
            bpx_box b;
            for (int a = 0; a < 3; a++) {
                bool low = (i >> a) & 1;
                b.min[a] = low ? -1.0f : ((i >> (a + 3)) & 1 ? -0.0f : 0.0f);
                b.max[a] = low ? ((i >> (a + 3)) & 1 ? 0.0f : -0.0f) : 1.0f;
            }
            zeros.push_back(b);
        }
        scene("plus/minus zero", zeros);
    }
    {
        std::vector<bpx_box> sub; // subnormal coordinates, touching and one-ulp gaps
        const float t = std::numeric_limits<float>::denorm_min();
        for (uint32_t i = 0; i < DEPTH; i++) {
            float lo = (float)(i % 8) * t * 2 - 7 * t, hi = lo + (i % 3) * t;
            sub.push_back(box(lo, -t * (i % 2), 0.0f, hi, t * (i % 3), (float)(i % 5) * t));
        }
        scene("subnormal coordinates", sub);
    }
    {
        std::vector<bpx_box> big; // +-FLT_MAX and huge boxes
        for (uint32_t i = 0; i < DEPTH; i++) {
            switch (i % 4) {
            case 0: big.push_back(box(-FLT_MAX, -FLT_MAX, -FLT_MAX, FLT_MAX, FLT_MAX, FLT_MAX)); break;
            case 1: big.push_back(box(FLT_MAX, 0, 0, FLT_MAX, 1, 1)); break;
            case 2: big.push_back(box(-FLT_MAX, 0, 0, -FLT_MAX, 1, 1)); break;
            default: big.push_back(box(std::nextafter(FLT_MAX, 0.0f), 0, 0, FLT_MAX, 0, 0)); break;
            }
        }
        scene("FLT_MAX", big);
    }
    {
        std::vector<bpx_box> over(DEPTH + 1, box(0, 0, 0, 1, 1, 1));
        scene("n = DEPTH + 1 (error)", over);
    }
    // The paper's two phases (initialisation, then updating cycles) through the adder.
    auto grid_minima = [&](uint32_t n) {
        std::vector<float> m(3 * n);
        for (auto &v : m)
            v = -0.5f * (float)(rng() % 6);
        return m;
    };
    auto real_centres = [&](uint32_t n, float span) {
        std::uniform_real_distribution<float> u(-span, span);
        std::vector<float> c(3 * n);
        for (auto &v : c)
            v = u(rng);
        return c;
    };
    for (uint32_t n : {0u, 1u, 2u, DEPTH - 1, DEPTH}) {
        bad += h.centres("centres n=" + std::to_string(n), grid_minima(n),
                         {real_centres(n, 6), real_centres(n, 6)});
        scenes++;
    }
    {
        const float t = std::numeric_limits<float>::denorm_min();
        std::vector<float> mins(3 * DEPTH), cen(3 * DEPTH), zc(3 * DEPTH), big(3 * DEPTH),
            bigm(3 * DEPTH), over(3 * DEPTH);
        for (uint32_t k = 0; k < 3 * DEPTH; k++) {
            mins[k] = -(float)(rng() % 4) * t;                   // subnormal extents
            cen[k] = (float)((int)(rng() % 17) - 8) * t;         // subnormal centres
            zc[k] = (rng() % 2) ? 0.0f : -0.0f;                  // +-0 centres
            big[k] = (rng() % 2 ? 1.0f : -1.0f) * 1.5e38f * (float)(rng() % 3) / 2.0f;
            bigm[k] = -1.7e38f * (float)(rng() % 2);             // huge extents, no overflow
            over[k] = 3.0e38f;
        }
        std::vector<float> zm(3 * DEPTH, -0.0f); // zero-size boxes: minima -0
        bad += h.centres("centres subnormal", mins, {cen});
        bad += h.centres("centres +-0, minima -0", zm, {zc});
        bad += h.centres("centres +-0, minima subnormal", mins, {zc});
        bad += h.centres("centres near FLT_MAX", bigm, {big});
        std::vector<float> over_m(3 * DEPTH, -1.0e38f);
        bad += h.centres("centres overflow", over_m, {over}, true);
        scenes += 5;
    }

    for (int r = 0; r < randoms; r++) {
        std::uniform_int_distribution<uint32_t> nd(0, DEPTH);
        uint32_t n = nd(rng);
        // Every third random scene with back-pressure: ready on 5 to 95 % of the clocks.
        h.ready_percent = r % 3 == 2 ? 5 + ready_rng() % 91 : 100;
        h.ready_seed = ready_rng();
        if (r % 2)
            scene("random grid " + std::to_string(r), random_grid(rng, n, 1 + (int)(rng() % 12), (int)(rng() % 4)));
        else
            scene("random bits " + std::to_string(r), random_bits(rng, n));
        h.ready_percent = 100;
    }
    std::printf("lockstep: M=%d DEPTH=%u FDEPTH=%u: %d scenes, %" PRIu64 " clocks, %" PRIu64
                " stall clocks, %" PRIu64 " pairs, %d mismatches\n",
                M, DEPTH, FDEPTH, scenes, h.total_clocks, h.total_stalls, h.total_pairs, bad);
    return bad ? 1 : 0;
}
