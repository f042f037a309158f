// bpx bench: timing one variant (a bpx backend or a peer library) over a set of frames.
// SPDX-License-Identifier: MIT
//
// Method: a fresh world (or peer) per variant; its first cycle is timed alone ("cold": buffers
// grow, sorts start from scratch, the paper's "incl sort"; for a peer, its creation with the
// first frame's proxies and pairs); then untimed warm-up cycles, then
// timed cycles on a monotonic clock until the budget is spent. A bpx cycle is what a frame pays:
// set_boxes (or update_centres) + collide. A peer cycle is its own equivalent: every proxy moved,
// then its pair update. Every cycle's pair count is checked against the frame's exact count.
#define _POSIX_C_SOURCE 200809L
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "peers.h"

static FILE *markdown_copy;

void bench_set_markdown_copy(FILE *file)
{
    markdown_copy = file;
}

void bench_printf(const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    vprintf(fmt, args);
    va_end(args);
    if (markdown_copy) {
        va_start(args, fmt);
        vfprintf(markdown_copy, fmt, args);
        va_end(args);
    }
}

void bench_progress(const char *fmt, ...)
{
    static int shown = -1;
    if (shown < 0)
        shown = isatty(STDERR_FILENO);
    if (!shown)
        return;
    fputs("\r\033[K", stderr);
    if (fmt) {
        va_list args;
        va_start(args, fmt);
        vfprintf(stderr, fmt, args);
        va_end(args);
    }
    fflush(stderr);
}

void bench_print_machine(int threads)
{
    char model[256] = "unknown CPU";
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (f) {
        char line[512];
        while (fgets(line, sizeof line, f))
            if (strncmp(line, "model name", 10) == 0) {
                const char *colon = strchr(line, ':');
                if (colon) {
                    snprintf(model, sizeof model, "%s", colon + 2);
                    model[strcspn(model, "\n")] = '\0';
                }
                break;
            }
        fclose(f);
    }
    bench_printf("machine: %s, %ld online CPUs; widest SIMD %s (%d lanes); threads %d; bpx %s\n\n",
                 model, sysconf(_SC_NPROCESSORS_ONLN), bpx_simd_name(bpx_simd_best()),
                 bpx_simd_lanes(BPX_SIMD_AUTO), threads, bpx_version());
}

void bench_variant_name(const bench_variant *v, char *out, size_t size)
{
    if (v->peer >= 0) {
        const bench_peer_info *info = bench_peer_get(v->peer);
        snprintf(out, size, "%s", info ? info->name : "?");
    } else if (v->backend == BPX_BACKEND_OPENCL) {
        static const char *const forced[] = {"boxes", "brute", "sweep", "tree"};
        int m = v->opencl_method;
        snprintf(out, size, "opencl %s",
                 m > 0 && m < 4 ? forced[m]
                 : v->centres   ? "centres"
                                : "boxes");
    } else if (v->backend == BPX_BACKEND_REFERENCE) {
        snprintf(out, size, "reference");
    } else if (v->simd != BPX_SIMD_AUTO && v->simd != bpx_simd_best()) {
        snprintf(out, size, "%s %s %dt", bpx_backend_name(v->backend), bpx_simd_name(v->simd),
                 v->threads);
    } else {
        snprintf(out, size, "%s %dt", bpx_backend_name(v->backend), v->threads);
    }
}

// --- Motion ------------------------------------------------------------------------------------

static void mover_boxes(bench_mover *m)
{
    const bench_motion *mo = m->motion;
    for (uint32_t i = 0; i < mo->n; i++)
        for (int a = 0; a < 3; a++) {
            float c = m->centres[3 * (size_t)i + a], mn = mo->minima[3 * (size_t)i + a];
            m->boxes[i].min[a] = c + mn;
            m->boxes[i].max[a] = c - mn;
        }
}

int bench_mover_init(bench_mover *m, const bench_motion *motion)
{
    size_t n = motion->n ? motion->n : 1;
    *m = (bench_mover){.motion = motion,
                       .centres = malloc(sizeof(float) * 3 * n),
                       .velocity = malloc(sizeof(float) * 3 * n),
                       .boxes = malloc(sizeof(bpx_box) * n)};
    if (!m->centres || !m->velocity || !m->boxes) {
        bench_mover_free(m);
        return -1;
    }
    memcpy(m->centres, motion->centres, sizeof(float) * 3 * motion->n);
    memcpy(m->velocity, motion->velocity, sizeof(float) * 3 * motion->n);
    mover_boxes(m);
    return 0;
}

void bench_mover_step(bench_mover *m)
{
    const bench_motion *mo = m->motion;
    for (size_t k = 0; k < 3 * (size_t)mo->n; k++) {
        int a = (int)(k % 3);
        float c = m->centres[k] + m->velocity[k], half = -mo->minima[k];
        if (c - half < mo->lo[a]) { // bounce: back inside, moving away from the wall
            c = mo->lo[a] + half;
            m->velocity[k] = fabsf(m->velocity[k]);
        } else if (c + half > mo->hi[a]) {
            c = mo->hi[a] - half;
            m->velocity[k] = -fabsf(m->velocity[k]);
        }
        m->centres[k] = c;
    }
    mover_boxes(m);
    m->cycle++;
}

void bench_mover_free(bench_mover *m)
{
    free(m->centres);
    free(m->velocity);
    free(m->boxes);
    *m = (bench_mover){0};
}

int bench_truth_init(bench_truth *t, const bench_motion *motion, int capacity)
{
    *t = (bench_truth){.capacity = capacity};
    bpx_world_def def = bpx_default_world_def();
    if (!(t->counts = malloc(sizeof(uint64_t) * (size_t)capacity)) ||
        bench_mover_init(&t->mover, motion) != 0 || bpx_world_create(&def, &t->world) != BPX_OK) {
        bench_truth_free(t);
        return -1;
    }
    return 0;
}

int bench_truth_count(bench_truth *t, int cycle, uint64_t *count)
{
    if (cycle >= t->capacity)
        return -1;
    for (; t->done <= cycle; t->done++) {
        if (t->done > 0)
            bench_mover_step(&t->mover);
        if (bpx_world_set_boxes(t->world, t->mover.boxes, t->mover.motion->n) != BPX_OK ||
            bpx_world_collide(t->world) != BPX_OK) {
            cli_error("bench", "exact pairs: %s", bpx_world_error(t->world)->message);
            return -1;
        }
        t->counts[t->done] = bpx_world_stats(t->world).pair_count;
    }
    *count = t->counts[cycle];
    return 0;
}

void bench_truth_free(bench_truth *t)
{
    bpx_world_destroy(t->world);
    bench_mover_free(&t->mover);
    free(t->counts);
    *t = (bench_truth){0};
}

// --- One variant ---------------------------------------------------------------------------

// One variant's state: a world or a peer, and where its boxes come from.
typedef struct runner {
    const bench_variant *v;
    const bench_frames *frames;
    bpx_world *world;
    bench_peer *peer;
    bench_mover mover; // motion: this replay's boxes
    bpx_box *boxes;    // recorded frames, for peers: the cycle's boxes
    float *centres;    // recorded frames, for two-phase variants: the cycle's centres
    double create_s;   // peers: creation, with the first cycle's proxies and pairs
} runner;

// The boxes of cycle c (cycles come in order; untimed work).
static const bpx_box *cycle_boxes(runner *r, int c)
{
    const bench_frames *fr = r->frames;
    if (fr->motion) {
        while (r->mover.cycle < c)
            bench_mover_step(&r->mover);
        return r->mover.boxes;
    }
    const float *centres = fr->centres + (size_t)c * 3 * fr->n;
    for (uint32_t i = 0; i < fr->n; i++)
        for (int a = 0; a < 3; a++) {
            // As the library's updater: min = centre + minimum, max = centre - minimum.
            float m = fr->minima[3 * (size_t)i + a], centre = centres[3 * (size_t)i + a];
            r->boxes[i].min[a] = centre + m;
            r->boxes[i].max[a] = centre - m;
        }
    return r->boxes;
}

// The centres of cycle c, for the two-phase updater. Recorded frames are copied out of the
// recording first (untimed), as a peer's boxes are made from them just before its cycle: every
// variant's input is then freshly written, as an engine's just-integrated state would be, and
// none streams its cycle's input from a recording of tens of MB.
static const float *cycle_centres(runner *r, int c)
{
    const bench_frames *fr = r->frames;
    if (!fr->motion) {
        memcpy(r->centres, fr->centres + (size_t)c * 3 * fr->n, sizeof(float) * 3 * fr->n);
        return r->centres;
    }
    cycle_boxes(r, c);
    return r->mover.centres;
}

static int runner_open(runner *r)
{
    const bench_frames *fr = r->frames;
    char name[BENCH_NAME_SIZE];
    bench_variant_name(r->v, name, sizeof name);
    size_t n = fr->n ? fr->n : 1;
    if ((fr->motion && bench_mover_init(&r->mover, fr->motion) != 0) ||
        (!fr->motion && r->v->peer >= 0 && !(r->boxes = malloc(sizeof(bpx_box) * n))) ||
        (!fr->motion && r->v->peer < 0 && r->v->centres &&
         !(r->centres = malloc(sizeof(float) * 3 * n)))) {
        cli_error("bench", "%s: out of memory", name);
        return -1;
    }
    if (r->v->peer >= 0) {
        char err[256] = "";
        const bpx_box *first = cycle_boxes(r, 0);
        double start = cli_now_s();
        r->peer = bench_peer_create(r->v->peer, first, fr->n, fr->bounds_min, fr->bounds_max, err,
                                    sizeof err);
        r->create_s = cli_now_s() - start;
        if (!r->peer) {
            cli_error("bench", "%s: %s", name, err);
            return -1;
        }
        return 0;
    }
    bpx_world_def def = bpx_default_world_def();
    def.backend = r->v->backend;
    def.simd = r->v->simd;
    def.worker_count = r->v->threads;
    def.opencl_method = r->v->opencl_method;
    def.capacity_hint = fr->n;
    bpx_status status = bpx_world_create(&def, &r->world);
    if (status == BPX_OK && r->v->centres)
        status =
            bpx_world_load_extents(r->world, fr->motion ? fr->motion->minima : fr->minima, fr->n);
    if (status != BPX_OK) {
        cli_error("bench", "cannot set up %s: %s", name,
                  r->world ? bpx_world_error(r->world)->message : bpx_status_string(status));
        return -1;
    }
    return 0;
}

// Runs cycle c; returns its time in seconds, or a negative value after printing the error.
static double runner_cycle(runner *r, int c, bpx_cycle_stats *stats)
{
    const bench_frames *fr = r->frames;
    if (r->peer) {
        const bpx_box *boxes = cycle_boxes(r, c);
        double start = cli_now_s();
        int rc = bench_peer_cycle(r->peer, boxes);
        double elapsed = cli_now_s() - start;
        if (rc != 0) {
            cli_error("bench", "%s failed", bench_peer_get(r->v->peer)->name);
            return -1;
        }
        return elapsed;
    }
    const float *centres = r->v->centres ? cycle_centres(r, c) : NULL;
    const bpx_box *boxes = centres ? NULL : cycle_boxes(r, c);
    double start = cli_now_s();
    bpx_status status = centres ? bpx_world_update_centres(r->world, centres)
                                : bpx_world_set_boxes(r->world, boxes, fr->n);
    if (status == BPX_OK)
        status = bpx_world_collide(r->world);
    double elapsed = cli_now_s() - start;
    if (status != BPX_OK) {
        cli_error("bench", "%s: %s", bpx_backend_name(r->v->backend),
                  bpx_world_error(r->world)->message);
        return -1;
    }
    *stats = bpx_world_stats(r->world);
    return elapsed;
}

static void runner_close(runner *r)
{
    bpx_world_destroy(r->world);
    if (r->peer)
        bench_peer_destroy(r->peer);
    bench_mover_free(&r->mover);
    free(r->boxes);
    free(r->centres);
}

// --- A variant in steps ----------------------------------------------------------------------

struct bench_session {
    runner r;
    bench_budget budget;
    double *samples; // timed cycles' us, budget.max_cycles (or frames->count) of them
    bool once;       // recorded frames, each played once (else a motion, timed for seconds)
    int total, c, timed, warm_end;
    double warm_spent, spent, pairs, exact, link[5], cold_pairs[2];
    bench_result out;
};

// Whether cycle s->c is timed: motion cycles after the cold one and the warm-up (which slow
// variants, a second per cycle at a million boxes, cut short), recorded frames after the first.
static bool timed_next(const bench_session *s)
{
    if (s->once || s->warm_end != 0)
        return s->c > 0;
    return s->c > 0 &&
           (s->c > s->budget.warmup || (s->c > 1 && s->warm_spent > s->budget.warmup_seconds));
}

// Runs cycle s->c and books it; returns its time in seconds, or -1 after printing the error.
static double session_cycle(bench_session *s)
{
    const bench_frames *frames = s->r.frames;
    int c = s->c;
    bool timed = timed_next(s);
    if (timed && s->warm_end == 0)
        s->warm_end = c;
    bpx_cycle_stats stats = {0};
    double elapsed = runner_cycle(&s->r, c, &stats);
    uint64_t truth = 0;
    if (elapsed < 0 || (frames->motion && bench_truth_count(frames->truth, c, &truth) != 0))
        return -1;
    if (!frames->motion)
        truth = frames->pairs[c];
    s->c++;
    uint64_t reported = stats.pair_count, checked = stats.pair_count;
    if (s->r.peer) {
        reported = bench_peer_pair_count(s->r.peer);
        checked = bench_peer_exact_pairs(s->r.peer, cycle_boxes(&s->r, c), NULL, 0);
    }
    if (checked != truth)
        s->out.mismatches++;
    if (c == 0) {
        // A peer's cold start is its creation: it inserts the first frame and finds its pairs
        // there, as bpx's first collide does.
        s->out.cold_us = (s->r.peer ? s->r.create_s : elapsed) * 1e6;
        s->cold_pairs[0] = (double)reported, s->cold_pairs[1] = (double)checked;
    }
    if (!timed) { // the cold cycle is reported apart; warm-up cycles not at all
        s->warm_spent += c > 0 ? elapsed : 0;
        return elapsed;
    }
    s->samples[s->timed++] = elapsed * 1e6;
    s->out.rebuilt += stats.rebuilt;
    if (s->r.world)
        s->out.ran |= 1u << bpx_world_backend(s->r.world);
    *(stats.rebuilt ? &s->out.rebuilt_us : &s->out.mended_us) += elapsed * 1e6;
    s->spent += elapsed;
    s->pairs += (double)reported;
    s->exact += (double)checked;
    s->link[0] += (double)stats.transfer_in_ns * 1e-3;
    s->link[1] += (double)stats.transfer_out_ns * 1e-3;
    s->link[2] += (double)stats.device_ns * 1e-3;
    s->link[3] += (double)stats.bytes_in;
    s->link[4] += (double)stats.bytes_out;
    return elapsed;
}

static void session_free(bench_session *s)
{
    runner_close(&s->r);
    free(s->samples);
    free(s);
}

int bench_open(const bench_variant *v, const bench_frames *frames, const bench_budget *budget,
               bench_session **out)
{
    *out = NULL;
    bench_session *s = calloc(1, sizeof *s);
    bool once = !frames->motion;
    int total = once ? frames->count : 1 + budget->warmup + budget->max_cycles;
    if (!s || !(s->samples = malloc(sizeof(double) * (size_t)(total > 1 ? total : 1)))) {
        free(s);
        cli_error("bench", "out of memory");
        return -1;
    }
    s->r = (runner){.v = v, .frames = frames};
    s->budget = *budget;
    s->once = once;
    s->total = total;
    if (runner_open(&s->r) != 0) {
        session_free(s);
        return -1;
    }
    while (s->c < s->total && !timed_next(s))
        if (session_cycle(s) < 0) {
            session_free(s);
            return -1;
        }
    *out = s;
    return 0;
}

int bench_step(bench_session *s, double seconds, int cycles)
{
    double slice = 0;
    for (int played = 0;
         s->c < s->total && played < cycles &&
         (s->once || (s->spent < s->budget.seconds && (slice < seconds || s->timed == 0)));
         played++) {
        double elapsed = session_cycle(s);
        if (elapsed < 0)
            return -1;
        slice += elapsed;
    }
    return 0;
}

void bench_close(bench_session *s, bench_result *result)
{
    bench_result *out = &s->out;
    double *samples = s->samples;
    int timed = s->timed;
    double pairs = s->pairs, exact = s->exact;
    if (timed == 0) { // one frame played once: the cold cycle is all there is
        samples[timed++] = out->cold_us;
        pairs = s->cold_pairs[0], exact = s->cold_pairs[1];
    }
    double sum = 0;
    for (int c = 0; c < timed; c++)
        sum += samples[c];
    qsort(samples, (size_t)timed, sizeof *samples, cli_compare_double);
    out->cycles = timed;
    out->rebuilt_us = out->rebuilt ? out->rebuilt_us / out->rebuilt : NAN;
    out->mended_us = timed > out->rebuilt ? out->mended_us / (timed - out->rebuilt) : NAN;
    out->mean_us = sum / timed;
    out->median_us =
        timed % 2 ? samples[timed / 2] : 0.5 * (samples[timed / 2 - 1] + samples[timed / 2]);
    out->p99_us = samples[(int)ceil(0.99 * timed) - 1];
    out->min_us = samples[0];
    out->pairs = pairs / timed;
    out->exact_pairs = exact / timed;
    out->in_us = s->link[0] / timed;
    out->out_us = s->link[1] / timed;
    out->device_us = s->link[2] / timed;
    out->bytes_in = s->link[3] / timed;
    out->bytes_out = s->link[4] / timed;
    *result = *out;
    session_free(s);
}

void bench_abandon(bench_session *s)
{
    if (s)
        session_free(s);
}

int bench_run(const bench_variant *v, const bench_frames *frames, const bench_budget *budget,
              bench_result *out)
{
    *out = (bench_result){0};
    bench_session *s;
    if (bench_open(v, frames, budget, &s) != 0)
        return -1;
    if (bench_step(s, budget->seconds, INT_MAX) != 0) {
        bench_abandon(s);
        return -1;
    }
    bench_close(s, out);
    return 0;
}
