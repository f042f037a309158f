// bpx bench's second part: random scenes at scale, every variant in turns per size, the
// summary against the fastest peer, the opencl link table and the plots.
// SPDX-License-Identifier: MIT

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cmd.h"
#include "peers.h"
#include "scenes.h"

const char *const bench_scene_names[SCENES] = {"uniform", "heavy", "resting"};

const float bench_scene_steps[SCENES] = {0.05f, 0.05f, 0.001f};

int bench_cmd_make_scene(int scene, uint32_t n, uint64_t seed, double step, int cycles,
                      scale_scene *s)
{
    *s = (scale_scene){0};
    size_t count = n ? n : 1;
    bpx_box *boxes = malloc(sizeof(bpx_box) * count);
    s->minima = malloc(sizeof(float) * 3 * count);
    s->centres = malloc(sizeof(float) * 3 * count);
    s->velocity = malloc(sizeof(float) * 3 * count);
    if (!boxes || !s->minima || !s->centres || !s->velocity) {
        free(boxes);
        return -1;
    }
    if (scene == 1)
        scene_heavy_tailed_density(n, seed, boxes);
    else
        scene_uniform_density(n, 1.0f, seed, boxes);
    float v = step > 0 ? (float)step : bench_scene_steps[scene];
    scene_rng rng;
    scene_rng_seed(&rng, seed ^ 0x9e3779b97f4a7c15ull);
    s->motion = (bench_motion){.n = n, .minima = s->minima, .centres = s->centres,
                               .velocity = s->velocity};
    for (int a = 0; a < 3; a++) {
        s->motion.lo[a] = n ? INFINITY : 0.0f;
        s->motion.hi[a] = n ? -INFINITY : 1.0f;
    }
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            size_t k = 3 * (size_t)i + a;
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            s->minima[k] = -half;
            s->centres[k] = boxes[i].min[a] + half;
            s->velocity[k] = scene_rng_range(&rng, -v, v);
            s->motion.lo[a] = fminf(s->motion.lo[a], boxes[i].min[a]);
            s->motion.hi[a] = fmaxf(s->motion.hi[a], boxes[i].max[a]);
        }
    free(boxes);
    s->frames = (bench_frames){.n = n, .motion = &s->motion, .truth = &s->truth};
    for (int a = 0; a < 3; a++) {
        // Boxes are centre -+ half extent, which can round an ulp past a wall.
        float pad = (s->motion.hi[a] - s->motion.lo[a]) * 1e-6f + 1e-6f;
        s->frames.bounds_min[a] = s->motion.lo[a] - pad;
        s->frames.bounds_max[a] = s->motion.hi[a] + pad;
    }
    return bench_truth_init(&s->truth, &s->motion, cycles);
}

void bench_cmd_free_scene(scale_scene *s)
{
    bench_truth_free(&s->truth);
    free(s->minima);
    free(s->centres);
    free(s->velocity);
}

static void print_link_table(const link_row *rows, int count)
{
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    bench_printf("\nopencl on %s; device-clock means per cycle (transfers as the device's events "
                 "see them):\n\n"
                 "| scene | n | link | bytes in | bytes out | in us | out us | kernels us | "
                 "communication share | cycle median us |\n"
                 "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|\n",
                 info.detail);
    for (int k = 0; k < count; k++) {
        const bench_result *r = &rows[k].r;
        double link = r->in_us + r->out_us, total = link + r->device_us;
        bench_printf("| %s | %u | %s | %.0f | %.0f | %.2f | %.2f | %.2f | %.1f %% | %.2f |\n",
                     rows[k].scene, rows[k].n, rows[k].centres ? "centres" : "boxes", r->bytes_in, r->bytes_out,
                     r->in_us, r->out_us, r->device_us,
                     total > 0 ? 100.0 * link / total : 0.0, r->median_us);
    }
}

// Speed-up of b over a (a / b), or NAN where either is missing.
static double ratio(double a, double b)
{
    return a > 0 && b > 0 ? a / b : NAN;
}

static void print_ratio(double r)
{
    if (isnan(r))
        bench_printf(" - |");
    else
        bench_printf(" %.1fx |", r);
}

static bench_series *series_for(scale_state *st, int scene, const bench_variant *v)
{
    char name[BENCH_NAME_SIZE];
    bench_variant_name(v, name, sizeof name);
    for (int k = 0; k < st->series_count[scene]; k++)
        if (strcmp(st->series[scene][k].name, name) == 0)
            return &st->series[scene][k];
    if (st->series_count[scene] == BENCH_MAX_VARIANTS)
        return NULL;
    bench_series *s = &st->series[scene][st->series_count[scene]++];
    snprintf(s->name, sizeof s->name, "%s", name);
    s->peer = v->peer >= 0;
    for (int k = 0; k < BENCH_MAX_SIZES; k++)
        s->us[k] = NAN;
    return s;
}

// Warm-up: long enough for fat boxes (bpx sap's margin is 1/16 of the box size, Bullet's and
// Box2D's 0.05 and 0.1) to turn over at the scene's speed, so the timed cycles show the steady
// state and not the first cycles after the fat boxes were made, where a box at rest costs
// nothing (at 0.001 per cycle: 150 cycles; sap at 1M averages 38 ms over 13 cycles after
// creation, 41 ms over 360; bullet-dbvt 68 ms, then 250 ms: `bpx bench --backend
// sap,bullet-dbvt --sizes 1000000 --scene resting --seconds 15`). Slow variants stop warming up
// after 20 times the timed budget (10 with --quick).
static bench_budget warmup_budget(const bench_options *o, int scene)
{
    double step = o->step > 0 ? o->step : bench_scene_steps[scene];
    double turnover = ceil(0.15 / step);
    int warmup = turnover < 5 ? 5 : turnover > 1000 ? 1000 : (int)turnover;
    return (bench_budget){o->seconds, o->max_cycles, warmup, (o->quick ? 10 : 20) * o->seconds};
}

static int run_size(scale_state *st, int scene, int size_index)
{
    const bench_options *o = st->o;
    uint32_t n = o->sizes[size_index];
    scale_scene sc;
    bench_progress("bpx bench: %s n = %u: exact pairs", bench_scene_names[scene], n);
    bench_budget budget = warmup_budget(o, scene);
    if (bench_cmd_make_scene(scene, n, o->seed, o->step, 1 + budget.warmup + budget.max_cycles,
                             &sc) != 0) {
        bench_cmd_free_scene(&sc);
        cli_error("bench", "cannot make the %s scene of %u boxes", bench_scene_names[scene], n);
        return -1;
    }
    bench_variant variants[BENCH_MAX_VARIANTS];
    bench_result results[BENCH_MAX_VARIANTS];
    int count = bench_cmd_list_variants(o, n, variants);
    int code = 0;
    // Every variant's cold cycle and warm-up, then the timed cycles in BENCH_ROUNDS turns, each
    // round starting one variant later: noise that drifts over seconds (a shared VM) falls on
    // every variant of the row alike, and so stays out of their ratios.
    bench_session *sessions[BENCH_MAX_VARIANTS] = {0};
    for (int v = 0; v < count && code == 0; v++) {
        char name[BENCH_NAME_SIZE];
        bench_variant_name(&variants[v], name, sizeof name);
        bench_progress("bpx bench: %s n = %u: %s (%d/%d)", bench_scene_names[scene], n, name, v + 1,
                       count);
        code = bench_open(&variants[v], &sc.frames, &budget, &sessions[v]);
    }
    for (int round = 0; round < BENCH_ROUNDS && code == 0; round++) {
        bench_progress("bpx bench: %s n = %u: timed round %d/%d", bench_scene_names[scene], n,
                       round + 1, BENCH_ROUNDS);
        for (int k = 0; k < count && code == 0; k++)
            code = bench_step(sessions[(k + round) % count], budget.seconds / BENCH_ROUNDS,
                              INT_MAX);
    }
    for (int v = 0; v < count; v++) {
        if (code == 0)
            bench_close(sessions[v], &results[v]);
        else
            bench_abandon(sessions[v]);
    }
    bench_progress(NULL);
    bench_cmd_free_scene(&sc);
    if (code != 0)
        return -1;

    double sap_us = NAN, peer_us = NAN, best_us = INFINITY;
    for (int v = 0; v < count; v++) {
        char name[BENCH_NAME_SIZE];
        bench_variant_name(&variants[v], name, sizeof name);
        double m = results[v].mean_us;
        if (variants[v].peer >= 0 && !(m >= peer_us)) { // the first peer, or a faster one
            peer_us = m;
            snprintf(st->summary[scene][size_index].peer, BENCH_NAME_SIZE, "%s", name);
        }
        if (variants[v].peer < 0 && variants[v].backend != BPX_BACKEND_REFERENCE && m < best_us) {
            best_us = m;
            snprintf(st->summary[scene][size_index].best, BENCH_NAME_SIZE, "%s", name);
        }
        if (variants[v].peer < 0 && variants[v].backend == BPX_BACKEND_SAP &&
            variants[v].threads == 1)
            sap_us = m; // "vs sap": against the one-thread row, as the paper's SOLID
    }
    st->summary[scene][size_index].best_us = best_us;
    st->summary[scene][size_index].peer_us = peer_us;
    for (int v = 0; v < count; v++) {
        const bench_variant *var = &variants[v];
        const bench_result *r = &results[v];
        char name[BENCH_NAME_SIZE], check[64];
        bench_variant_name(var, name, sizeof name);
        if (r->mismatches)
            snprintf(check, sizeof check, "**%d cycles wrong**", r->mismatches);
        else if (var->peer < 0 && var->backend == BPX_BACKEND_SAP)
            snprintf(check, sizeof check, "ok; %d of %d rebuilt", r->rebuilt, r->cycles);
        else if (var->peer < 0 && var->backend == BPX_BACKEND_AUTO) {
            int used = snprintf(check, sizeof check, "ok; ran");
            for (int b = 0; b < BPX_BACKEND_COUNT; b++)
                if (r->ran & (1u << b) && used < (int)sizeof check)
                    used += snprintf(check + used, sizeof check - (size_t)used, " %s",
                                     bpx_backend_name((bpx_backend)b));
        } else if (var->peer >= 0 && r->exact_pairs > 0)
            snprintf(check, sizeof check, "ok (reports %.2fx)", r->pairs / r->exact_pairs);
        else
            snprintf(check, sizeof check, "ok");
        st->mismatches += r->mismatches;
        bench_printf("| %s | %u | %s | %.1f | %.1f | %.2f | %.2f | %.2f |",
                     bench_scene_names[scene], n, name, r->exact_pairs, r->cold_us, r->mean_us,
                     r->median_us, r->p99_us);
        print_ratio(ratio(sap_us, r->mean_us));
        print_ratio(ratio(peer_us, r->mean_us));
        bench_printf(" %s |\n", check);
        bench_series *s = series_for(st, scene, var);
        if (s && var->backend != BPX_BACKEND_REFERENCE)
            s->us[size_index] = r->mean_us;
        if (var->peer < 0 && var->backend == BPX_BACKEND_OPENCL && st->link_count < MAX_LINK_ROWS)
            st->links[st->link_count++] = (link_row){bench_scene_names[scene], n, var->centres, *r};
        if (st->csv)
            fprintf(st->csv, "%s,%u,%s,%s,%d,%d,%.2f,%.2f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d\n",
                    bench_scene_names[scene], n, name,
                    var->peer >= 0 ? "peer" : bpx_simd_name(var->simd == BPX_SIMD_AUTO
                                                                ? bpx_simd_best()
                                                                : var->simd),
                    var->threads, r->cycles, r->pairs, r->exact_pairs, r->cold_us, r->mean_us,
                    r->median_us, r->p99_us, r->min_us, ratio(sap_us, r->mean_us),
                    ratio(peer_us, r->mean_us), r->mismatches);
    }
    fflush(stdout);
    return 0;
}

int bench_cmd_run_scale(scale_state *st)
{
    const bench_options *o = st->o;
    bench_printf("Random scenes at constant density (about one overlap per box; \"heavy\": 1%%\n"
                 "of boxes 4..8 and 0.01%% 16..32 times the others' size), every box moving at\n"
                 "its own constant velocity (up to %s per axis and cycle, boxes ~1 wide;\n"
                 "\"resting\": %s) and bouncing off the scene's walls. Per variant: cold = first\n"
                 "cycle of a fresh world (peers: their creation with the first cycle's boxes),\n"
                 "then warm-up (0.15 / step cycles, at least 5: fat boxes turn over), then\n"
                 "timed cycles for %.2f s (at least one), in %d turns taken by the row's\n"
                 "variants in rotation (slow drift of a shared machine falls on all alike);\n"
                 "us per cycle (bpx:\n"
                 "set_boxes + collide; peers: move every proxy + their pair update). vs sap / vs\n"
                 "fastest peer: their mean over this row's (means, as the paper's; sap's cycles\n"
                 "are cheap or dear). check: every cycle's pairs against the exact count (peers\n"
                 "report more: fat or quantised boxes).\n\n",
                 o->step > 0 ? "--step" : "0.05", o->step > 0 ? "--step" : "0.001", o->seconds,
                 BENCH_ROUNDS);
    bench_printf("| scene | n | variant | pairs/cycle | cold us | mean us | median us | p99 us | "
                 "vs sap | vs fastest peer | check |\n"
                 "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|\n");
    for (int scene = 0; scene < SCENES; scene++)
        for (int k = 0; o->scenes[scene] && k < o->size_count; k++)
            if (run_size(st, scene, k) != 0)
                return -1;

    bench_printf("\nbpx's best against the fastest peer (means, us per cycle):\n\n"
                 "| scene | n | best bpx | us | fastest peer | us | bpx speed-up |\n"
                 "|---|---:|---|---:|---|---:|---:|\n");
    for (int scene = 0; scene < SCENES; scene++)
        for (int k = 0; o->scenes[scene] && k < o->size_count; k++) {
            const scale_summary *s = &st->summary[scene][k];
            bench_printf("| %s | %u | %s | %.2f | %s |", bench_scene_names[scene], o->sizes[k],
                         s->best, s->best_us, isfinite(s->peer_us) ? s->peer : "-");
            if (isfinite(s->peer_us))
                bench_printf(" %.2f |", s->peer_us);
            else
                bench_printf(" - |");
            print_ratio(ratio(s->peer_us, s->best_us));
            bench_printf("\n");
        }
    if (st->link_count > 0)
        print_link_table(st->links, st->link_count);
    return 0;
}

int bench_cmd_write_plots(const scale_state *st)
{
    const bench_options *o = st->o;
    for (int scene = 0; scene < SCENES; scene++) {
        if (!o->scenes[scene] || o->size_count == 0)
            continue;
        char path[4096], title[160];
        snprintf(path, sizeof path, "%s/scale_%s.svg", o->out_dir, bench_scene_names[scene]);
        snprintf(title, sizeof title,
                 "bpx bench: %s scene, mean time per cycle (dashed: peer libraries)",
                 bench_scene_names[scene]);
        if (bench_plot_svg(path, title, o->sizes, o->size_count, st->series[scene],
                           st->series_count[scene]) != 0) {
            cli_error("bench", "cannot write %s", path);
            return -1;
        }
        fprintf(stderr, "bpx bench: wrote %s\n", path);
    }
    return 0;
}
