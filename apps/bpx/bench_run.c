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
        snprintf(out, size, "opencl %s", v->centres ? "centres" : "boxes");
    } else if (v->backend == BPX_BACKEND_REFERENCE) {
        snprintf(out, size, "reference");
    } else if (v->simd != BPX_SIMD_AUTO && v->simd != bpx_simd_best()) {
        snprintf(out, size, "%s %s %dt", bpx_backend_name(v->backend), bpx_simd_name(v->simd),
                 v->threads);
    } else {
        snprintf(out, size, "%s %dt", bpx_backend_name(v->backend), v->threads);
    }
}

int bench_frame_at(const bench_frames *frames, int cycle)
{
    if (frames->once || frames->count < 2)
        return cycle % frames->count;
    int period = 2 * frames->count - 2, k = cycle % period;
    return k < frames->count ? k : period - k;
}

// One variant's state: a world or a peer, and where its boxes come from.
typedef struct runner {
    const bench_variant *v;
    const bench_frames *frames;
    bpx_world *world;
    bench_peer *peer;
    bpx_box *scratch; // peers on two-phase frames: the frame's boxes
    double create_s;  // peers: creation, with the first frame's proxies and pairs
} runner;

static const bpx_box *frame_boxes(runner *r, int f)
{
    const bench_frames *fr = r->frames;
    if (fr->boxes)
        return fr->boxes[f];
    const float *c = fr->centres + (size_t)f * 3 * fr->n;
    for (uint32_t i = 0; i < fr->n; i++)
        for (int a = 0; a < 3; a++) {
            // As the library's updater: min = centre + minimum, max = centre - minimum.
            float m = fr->minima[3 * (size_t)i + a], centre = c[3 * (size_t)i + a];
            r->scratch[i].min[a] = centre + m;
            r->scratch[i].max[a] = centre - m;
        }
    return r->scratch;
}

static int runner_open(runner *r)
{
    const bench_frames *fr = r->frames;
    char name[BENCH_NAME_SIZE];
    bench_variant_name(r->v, name, sizeof name);
    if (r->v->peer >= 0) {
        if (!fr->boxes && !(r->scratch = malloc(sizeof(bpx_box) * (fr->n ? fr->n : 1)))) {
            cli_error("bench", "%s: out of memory", name);
            return -1;
        }
        char err[256] = "";
        const bpx_box *first = frame_boxes(r, 0);
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
    def.capacity_hint = fr->n;
    bpx_status status = bpx_world_create(&def, &r->world);
    if (status == BPX_OK && r->v->centres) {
        if (fr->minima) {
            status = bpx_world_load_extents(r->world, fr->minima, fr->n);
        } else {
            // Boxes as the paper's two phases: the first frame's half extents loaded once (the
            // motion keeps sizes), then centres each cycle, computed outside the timed region.
            float *minima = malloc(sizeof(float) * 3 * (fr->n ? fr->n : 1));
            status = minima ? BPX_OK : BPX_ERR_OUT_OF_MEMORY;
            for (uint32_t i = 0; minima && i < fr->n; i++)
                for (int a = 0; a < 3; a++)
                    minima[3 * (size_t)i + a] =
                        -(fr->boxes[0][i].max[a] - fr->boxes[0][i].min[a]) * 0.5f;
            if (status == BPX_OK)
                status = bpx_world_load_extents(r->world, minima, fr->n);
            free(minima);
        }
    }
    if (status != BPX_OK) {
        cli_error("bench", "cannot set up %s: %s", name,
                  r->world ? bpx_world_error(r->world)->message : bpx_status_string(status));
        return -1;
    }
    if (r->v->centres && fr->boxes && !(r->scratch = malloc(sizeof(float) * 3 * (fr->n + 1)))) {
        cli_error("bench", "%s: out of memory", name);
        return -1;
    }
    return 0;
}

// Centres of a box frame for the two-phase updater (outside the timed region).
static const float *frame_centres(runner *r, int f)
{
    const bench_frames *fr = r->frames;
    if (!fr->boxes)
        return fr->centres + (size_t)f * 3 * fr->n;
    float *c = (float *)r->scratch;
    for (uint32_t i = 0; i < fr->n; i++)
        for (int a = 0; a < 3; a++) {
            const bpx_box *b = &fr->boxes[f][i];
            c[3 * (size_t)i + a] = b->min[a] + (b->max[a] - b->min[a]) * 0.5f;
        }
    return c;
}

// Runs one cycle; returns its time in seconds, or a negative value after printing the error.
static double runner_cycle(runner *r, int f, bpx_cycle_stats *stats)
{
    const bench_frames *fr = r->frames;
    if (r->peer) {
        const bpx_box *boxes = frame_boxes(r, f);
        double start = cli_now_s();
        int rc = bench_peer_cycle(r->peer, boxes);
        double elapsed = cli_now_s() - start;
        if (rc != 0) {
            cli_error("bench", "%s failed", bench_peer_get(r->v->peer)->name);
            return -1;
        }
        return elapsed;
    }
    const float *centres = r->v->centres ? frame_centres(r, f) : NULL;
    double start = cli_now_s();
    bpx_status status = centres ? bpx_world_update_centres(r->world, centres)
                                : bpx_world_set_boxes(r->world, fr->boxes[f], fr->n);
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
    free(r->scratch);
}

int bench_run(const bench_variant *v, const bench_frames *frames, const bench_budget *budget,
              double *samples, bench_result *out)
{
    *out = (bench_result){0};
    runner r = {.v = v, .frames = frames};
    if (runner_open(&r) != 0) {
        runner_close(&r);
        return -1;
    }
    int total = frames->once ? frames->count : 1 + budget->warmup + budget->max_cycles;
    int timed = 0;
    int warm_end = 0;
    double warm_spent = 0, spent = 0, pairs = 0, exact = 0, link[5] = {0}, cold_pairs[2] = {0};
    for (int c = 0; c < total && (frames->once || spent < budget->seconds); c++) {
        int f = bench_frame_at(frames, c);
        bpx_cycle_stats stats = {0};
        double elapsed = runner_cycle(&r, f, &stats);
        if (elapsed < 0) {
            runner_close(&r);
            return -1;
        }
        uint64_t reported = stats.pair_count, checked = stats.pair_count;
        if (r.peer) {
            reported = bench_peer_pair_count(r.peer);
            checked = bench_peer_exact_pairs(r.peer, frame_boxes(&r, f), NULL, 0);
        }
        if (frames->pairs && checked != frames->pairs[f])
            out->mismatches++;
        if (c == 0) {
            // A peer's cold start is its creation: it inserts the first frame and finds its
            // pairs there, as bpx's first collide does.
            out->cold_us = (r.peer ? r.create_s : elapsed) * 1e6;
            cold_pairs[0] = (double)reported, cold_pairs[1] = (double)checked;
        }
        // The cold cycle is reported apart; warm-up cycles not at all. Slow variants (a second
        // per cycle at a million boxes) stop warming up after half the budget.
        if (!frames->once && c > 0 && warm_end == 0 &&
            (c > budget->warmup || (c > 1 && warm_spent > 0.5 * budget->seconds)))
            warm_end = c;
        if (frames->once ? c == 0 : warm_end == 0) {
            warm_spent += c > 0 ? elapsed : 0;
            continue;
        }
        samples[timed++] = elapsed * 1e6;
        out->rebuilt += stats.rebuilt;
        if (r.world)
            out->ran |= 1u << bpx_world_backend(r.world);
        *(stats.rebuilt ? &out->rebuilt_us : &out->mended_us) += elapsed * 1e6;
        spent += elapsed;
        pairs += (double)reported;
        exact += (double)checked;
        link[0] += (double)stats.transfer_in_ns * 1e-3;
        link[1] += (double)stats.transfer_out_ns * 1e-3;
        link[2] += (double)stats.device_ns * 1e-3;
        link[3] += (double)stats.bytes_in;
        link[4] += (double)stats.bytes_out;
    }
    runner_close(&r);
    if (timed == 0) { // one frame played once: the cold cycle is all there is
        samples[timed++] = out->cold_us;
        pairs = cold_pairs[0], exact = cold_pairs[1];
    }

    double sum = 0;
    for (int c = 0; c < timed; c++)
        sum += samples[c];
    qsort(samples, (size_t)timed, sizeof *samples, cli_compare_double);
    out->cycles = timed;
    out->rebuilt_us = out->rebuilt ? out->rebuilt_us / out->rebuilt : NAN;
    out->mended_us = timed > out->rebuilt ? out->mended_us / (timed - out->rebuilt) : NAN;
    out->mean_us = sum / timed;
    out->median_us = timed % 2 ? samples[timed / 2]
                               : 0.5 * (samples[timed / 2 - 1] + samples[timed / 2]);
    out->p99_us = samples[(int)ceil(0.99 * timed) - 1];
    out->min_us = samples[0];
    out->pairs = pairs / timed;
    out->exact_pairs = exact / timed;
    out->in_us = link[0] / timed;
    out->out_us = link[1] / timed;
    out->device_us = link[2] / timed;
    out->bytes_in = link[3] / timed;
    out->bytes_out = link[4] / timed;
    return 0;
}
