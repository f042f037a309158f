// bpx bench --profile: where a cycle's time goes, stage by stage, beside the machine's memory
// floor measured in the same run. SPDX-License-Identifier: MIT
//
// Per scene and size: the floor's three passes (floor.c, bpx_memfloor's: a sequential copy, a
// prefetched random gather and scatter of n 32-byte records) on the run's thread count; then per
// backend a fresh world with bpx_world_def.profile on, its warm-up, and timed cycles whose
// stages (bpx_cycle_stats.stages) are averaged. Each stage is read against its floor: a
// sequential stage's bytes at the copy's bandwidth, a gather's or scatter's records at the
// floor's time per record. The same cycles are then run with the profile off, for what the
// profile itself costs. Peak memory is the library's own count (bpx_allocated_peak) from the
// world's creation on. Every cycle's pair count is checked against the exact one.

#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cmd.h"
#include "floor.h"

enum { MAX_ROWS = 2 * BPX_MAX_STAGES, MAX_BACKENDS = 8 };

typedef struct stage_sum {
    char name[48];
    bpx_access access;
    double ns, read, written, random;
} stage_sum;

typedef struct profile_result {
    int cycles;
    double cycle_ns, cycle_min_ns; // mean and least wall time per cycle (set_boxes + collide)
    double pairs;                  // mean per cycle
    int mismatches;
    int64_t peak_bytes; // the library's allocations at their peak, less those before
    unsigned ran;       // 1 << the backends the cycles ran (auto)
    stage_sum rows[MAX_ROWS];
    int row_count;
} profile_result;

static stage_sum *row_for(profile_result *r, const bpx_stage_stats *s)
{
    char name[48];
    snprintf(name, sizeof name, "%s: %s", s->backend, s->name);
    for (int k = 0; k < r->row_count; k++)
        if (strcmp(r->rows[k].name, name) == 0)
            return &r->rows[k];
    if (r->row_count == MAX_ROWS)
        return NULL;
    stage_sum *row = &r->rows[r->row_count++];
    *row = (stage_sum){.access = s->access};
    snprintf(row->name, sizeof row->name, "%s", name);
    return row;
}

// Plays cycles [0, warmup + timed) of the scene on a fresh world; the timed ones are booked.
static int play(bpx_backend backend, int threads, bool profile, const scale_scene *sc, int warmup,
                int timed, profile_result *out)
{
    *out = (profile_result){0};
    bench_mover mover;
    if (bench_mover_init(&mover, &sc->motion) != 0) {
        cli_error("bench", "out of memory");
        return -1;
    }
    int64_t before = bpx_allocated_bytes();
    bpx_reset_allocated_peak();
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = threads;
    def.capacity_hint = sc->motion.n;
    def.profile = profile;
    bpx_world *w = NULL;
    bpx_status status = bpx_world_create(&def, &w);
    out->cycle_min_ns = INFINITY;
    for (int c = 0; c < warmup + timed && status == BPX_OK; c++) {
        if (c > 0)
            bench_mover_step(&mover);
        double start = cli_now_s();
        status = bpx_world_set_boxes(w, mover.boxes, sc->motion.n);
        if (status == BPX_OK)
            status = bpx_world_collide(w);
        double elapsed = (cli_now_s() - start) * 1e9;
        if (status != BPX_OK)
            break;
        bpx_cycle_stats stats = bpx_world_stats(w);
        uint64_t truth = 0;
        // The exact counts were made before (bench_truth_count only reads them here).
        if (bench_truth_count((bench_truth *)&sc->truth, c, &truth) != 0)
            status = BPX_ERR_BAD_STATE;
        out->mismatches += stats.pair_count != truth;
        if (c < warmup)
            continue;
        out->cycles++;
        out->cycle_ns += elapsed;
        out->cycle_min_ns = fmin(out->cycle_min_ns, elapsed);
        out->pairs += (double)stats.pair_count;
        out->ran |= 1u << bpx_world_backend(w);
        for (uint32_t k = 0; k < stats.stage_count; k++) {
            const bpx_stage_stats *s = &stats.stages[k];
            stage_sum *row = row_for(out, s);
            if (!row)
                continue;
            row->ns += (double)s->ns;
            row->read += (double)s->bytes_read;
            row->written += (double)s->bytes_written;
            row->random += (double)s->random;
        }
    }
    if (status != BPX_OK)
        cli_error("bench", "%s: %s", bpx_backend_name(backend),
                  w ? bpx_world_error(w)->message : bpx_status_string(status));
    out->peak_bytes = bpx_allocated_peak() - before;
    bpx_world_destroy(w);
    bench_mover_free(&mover);
    if (status != BPX_OK)
        return -1;
    double c = out->cycles ? out->cycles : 1;
    out->cycle_ns /= c;
    out->pairs /= c;
    for (int k = 0; k < out->row_count; k++) {
        stage_sum *row = &out->rows[k];
        row->ns /= c, row->read /= c, row->written /= c, row->random /= c;
    }
    return 0;
}

typedef struct floor_figures {
    double copy_ms, gather_ms, scatter_ms; // n records, the run's threads
    uint32_t n;
} floor_figures;

// A stage's floor in ms: its bytes at the copy's bandwidth, or its random records at the
// gather's or scatter's time per record.
static double floor_ms(const floor_figures *f, const stage_sum *s)
{
    double per_record_ms;
    switch (s->access) {
    case BPX_ACCESS_GATHER:
        per_record_ms = f->gather_ms / f->n;
        return s->random * per_record_ms;
    case BPX_ACCESS_SCATTER:
        per_record_ms = f->scatter_ms / f->n;
        return s->random * per_record_ms;
    default: {
        double bytes_per_ms = 2.0 * BPX_FLOOR_RECORD * f->n / f->copy_ms; // read + written
        return (s->read + s->written) / bytes_per_ms;
    }
    }
}

static const char *access_name(bpx_access a)
{
    return a == BPX_ACCESS_GATHER ? "gather" : a == BPX_ACCESS_SCATTER ? "scatter" : "sequential";
}

static void print_backend(const char *scene, uint32_t n, int threads, bpx_backend backend,
                          const profile_result *on, const profile_result *off,
                          const floor_figures *f)
{
    char ran[64] = "";
    if (backend == BPX_BACKEND_AUTO) {
        size_t used = 0;
        for (int b = 0; b < BPX_BACKEND_COUNT; b++)
            if (on->ran & (1u << b))
                used += (size_t)snprintf(ran + used, sizeof ran - used, "%s%s",
                                         used ? "+" : " (ran ", bpx_backend_name((bpx_backend)b));
        if (used)
            snprintf(ran + used, sizeof ran - used, ")");
    }
    double cycle_ms = on->cycle_ns * 1e-6;
    bench_printf("#### %s%s, %s, n = %u, %d thread%s\n\n", bpx_backend_name(backend), ran, scene, n,
                 threads, threads > 1 ? "s" : "");
    bench_printf("%d timed cycles, %.0f pairs a cycle; cycle (set_boxes + collide) mean %.2f ms, "
                 "least %.2f ms; with the profile off, the same cycles on a fresh world: mean "
                 "%.2f ms, least %.2f ms (profile on / off: %.3f, means). Peak memory: %.1f bytes "
                 "a box (%.1f MB, the library's allocations at their peak from the world's "
                 "creation on, bpx_allocated_peak).\n\n",
                 on->cycles, on->pairs, cycle_ms, on->cycle_min_ns * 1e-6, off->cycle_ns * 1e-6,
                 off->cycle_min_ns * 1e-6, off->cycle_ns > 0 ? on->cycle_ns / off->cycle_ns : NAN,
                 (double)on->peak_bytes / (n ? n : 1), (double)on->peak_bytes / 1e6);
    bench_printf("| stage | ms | share | MB read | MB written | GB/s | access | random records "
                 "| floor ms | x floor |\n|---|---:|---:|---:|---:|---:|---|---:|---:|---:|\n");
    double sum_ms = 0, sum_floor = 0, sum_read = 0, sum_written = 0;
    for (int k = 0; k < on->row_count; k++) {
        const stage_sum *s = &on->rows[k];
        double ms = s->ns * 1e-6, fl = floor_ms(f, s);
        sum_ms += ms, sum_floor += fl, sum_read += s->read, sum_written += s->written;
        bench_printf("| %s | %.2f | %.1f %% | %.1f | %.1f | %.2f | %s | ", s->name, ms,
                     cycle_ms > 0 ? 100.0 * ms / cycle_ms : 0.0, s->read / 1e6, s->written / 1e6,
                     ms > 0 ? (s->read + s->written) / (ms * 1e6) : 0.0, access_name(s->access));
        if (s->access == BPX_ACCESS_SEQUENTIAL)
            bench_printf("- | ");
        else
            bench_printf("%.0f | ", s->random);
        if (fl > 0)
            bench_printf("%.2f | %.2f |\n", fl, ms / fl);
        else
            bench_printf("%.2f | - |\n", fl);
    }
    double rest = cycle_ms - sum_ms;
    bench_printf("| (not in a stage) | %.2f | %.1f %% | | | | | | | |\n", rest,
                 cycle_ms > 0 ? 100.0 * rest / cycle_ms : 0.0);
    bench_printf("| **cycle** | **%.2f** | 100 %% | %.1f | %.1f | %.2f | | | **%.2f** | **%.2f** "
                 "|\n\n",
                 cycle_ms, sum_read / 1e6, sum_written / 1e6,
                 cycle_ms > 0 ? (sum_read + sum_written) / (cycle_ms * 1e6) : 0.0, sum_floor,
                 sum_floor > 0 ? cycle_ms / sum_floor : NAN);
    double any = f->scatter_ms < f->gather_ms ? f->scatter_ms : f->gather_ms;
    bench_printf(
        "Distance to the floor: the cycle is %.2fx the sum of its stages' floors (%.2f ms), "
        "%.1fx one random pass over the n boxes (the least any spatial method pays: "
        "%.2f ms).\n\n",
        sum_floor > 0 ? cycle_ms / sum_floor : NAN, sum_floor, any > 0 ? cycle_ms / any : NAN, any);
}

static int profile_size(const bench_options *o, int scene, uint32_t n)
{
    int threads = o->threads;
    double step = o->step > 0 ? o->step : bench_scene_steps[scene];
    double turnover = ceil(0.15 / step);
    int warmup = turnover < 5 ? 5 : turnover > 1000 ? 1000 : (int)turnover;
    // Timed cycles: --cycles, else about --seconds' worth at ~100 ns a box (at least 3).
    int timed = o->cycles_given ? o->max_cycles
                                : (int)fmax(3.0, fmin(200.0, o->seconds / (n * 100e-9 + 1e-6)));
    scale_scene sc;
    bench_progress("bpx bench --profile: %s n = %u: exact pairs", bench_scene_names[scene], n);
    if (bench_cmd_make_scene(scene, n, o->seed, o->step, warmup + timed, &sc) != 0) {
        bench_cmd_free_scene(&sc);
        cli_error("bench", "cannot make the %s scene of %u boxes", bench_scene_names[scene], n);
        return -1;
    }
    // Every exact count first, so that nothing else allocates while a world's peak is taken.
    uint64_t count;
    if (bench_truth_count(&sc.truth, warmup + timed - 1, &count) != 0) {
        bench_cmd_free_scene(&sc);
        return -1;
    }
    floor_figures f = {.n = n};
    bpx_floor fl;
    bench_progress("bpx bench --profile: %s n = %u: memory floor", bench_scene_names[scene], n);
    if (bpx_floor_open(&fl, n) != 0) {
        bench_cmd_free_scene(&sc);
        cli_error("bench", "no memory for the floor's %u records", n);
        return -1;
    }
    f.copy_ms = bpx_floor_time(&fl, BPX_FLOOR_COPY, threads);
    f.gather_ms = bpx_floor_time(&fl, BPX_FLOOR_GATHER, threads);
    f.scatter_ms = bpx_floor_time(&fl, BPX_FLOOR_SCATTER, threads);
    bpx_floor_close(&fl);
    double mb = (double)n * BPX_FLOOR_RECORD / 1e6;
    bench_printf("### %s, n = %u, %d thread%s\n\n", bench_scene_names[scene], n, threads,
                 threads > 1 ? "s" : "");
    bench_printf("Memory floor, measured now (bpx_memfloor's passes: %u records of %d bytes, "
                 "%.1f MB, %d thread%s, best of %d):\n\n"
                 "| pass | ms | ns per record | GB/s (read + written) |\n|---|---:|---:|---:|\n"
                 "| sequential copy | %.2f | %.2f | %.2f |\n"
                 "| random gather (prefetched) | %.2f | %.2f | %.2f |\n"
                 "| random scatter (prefetched) | %.2f | %.2f | %.2f |\n\n",
                 n, BPX_FLOOR_RECORD, mb, threads, threads > 1 ? "s" : "", BPX_FLOOR_ROUNDS,
                 f.copy_ms, f.copy_ms * 1e6 / n, 2 * mb / f.copy_ms, f.gather_ms,
                 f.gather_ms * 1e6 / n, 2 * mb / f.gather_ms, f.scatter_ms, f.scatter_ms * 1e6 / n,
                 2 * mb / f.scatter_ms);
    bench_printf("A stage's floor: sequential, its bytes read and written at the copy's "
                 "bandwidth; gather or scatter, its random records at the floor's time per "
                 "record. Bytes are computed from the sizes of the arrays a stage touches "
                 "(bpx_stage_stats), not counted by the hardware.\n\n");

    static const bpx_backend defaults[] = {BPX_BACKEND_GRID, BPX_BACKEND_SAP, BPX_BACKEND_AUTO};
    bpx_backend backends[MAX_BACKENDS];
    int count_b = 0;
    if (o->name_count == 0) {
        for (size_t k = 0; k < sizeof defaults / sizeof defaults[0]; k++)
            backends[count_b++] = defaults[k];
    } else {
        for (int k = 0; k < o->name_count && count_b < MAX_BACKENDS; k++) {
            bpx_backend b;
            if (bpx_backend_from_name(o->names[k], &b) == BPX_OK)
                backends[count_b++] = b; // peers have no stages: left out
        }
    }
    int code = 0, mismatches = 0;
    for (int k = 0; k < count_b && code == 0; k++) {
        profile_result *on = calloc(2, sizeof *on), *off = on ? on + 1 : NULL;
        if (!on) {
            cli_error("bench", "out of memory");
            code = -1;
            break;
        }
        bench_progress("bpx bench --profile: %s n = %u: %s", bench_scene_names[scene], n,
                       bpx_backend_name(backends[k]));
        code = play(backends[k], threads, true, &sc, warmup, timed, on);
        if (code == 0)
            code = play(backends[k], threads, false, &sc, warmup, timed, off);
        if (code == 0) {
            bench_progress(NULL);
            print_backend(bench_scene_names[scene], n, threads, backends[k], on, off, &f);
            mismatches += on->mismatches + off->mismatches;
        }
        free(on);
    }
    bench_progress(NULL);
    bench_cmd_free_scene(&sc);
    if (code == 0 && mismatches) {
        cli_error("bench", "%d cycles reported a pair count other than the exact one", mismatches);
        code = -1;
    }
    return code;
}

int bench_cmd_run_profile(const bench_options *o)
{
    bench_print_machine(o->threads);
    for (int s = 0; s < SCENES; s++) {
        bool wanted = o->scenes_given ? o->scenes[s] : s == 0; // default: uniform
        for (int k = 0; k < o->size_count && wanted; k++)
            if (profile_size(o, s, o->sizes[k]) != 0)
                return -1;
    }
    return 0;
}
