// bpx demo: the paper's test scenario (Woulfe et al. 2007, section 5): spheres in a box, the
// central loop broad phase -> narrow phase -> collision response -> physics -> display, timed per
// stage; pictures as PNG files and/or a live window; statistics; an AABB trace on request.
// SPDX-License-Identifier: MIT

#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "bpx_trace.h"
#include "demo_cmd.h"
#include "demo_png.h"
#include "demo_render.h"
#include "demo_window.h"

// The paper's Table 2, "collisions" column: mean per cycle, n = 50, 100, ..., 500.
static const double paper_collisions[10] = {7.47,  12.588, 20.413, 26.703, 35.628,
                                            44.61, 51.416, 60.053, 64.427, 76.079};

// mkdir -p: creates dir and its missing parents.
static int make_dirs(const char *dir)
{
    char path[4096];
    size_t len = strlen(dir);
    if (len == 0 || len >= sizeof path)
        return -1;
    memcpy(path, dir, len + 1);
    for (size_t k = 1; k <= len; k++) {
        if (path[k] != '/' && path[k] != '\0')
            continue;
        char saved = path[k];
        path[k] = '\0';
        if (mkdir(path, 0777) != 0 && errno != EEXIST)
            return -1;
        path[k] = saved;
    }
    struct stat st;
    return stat(dir, &st) == 0 && S_ISDIR(st.st_mode) ? 0 : -1;
}

static void sleep_until_ns(uint64_t target)
{
    uint64_t now = demo_now_ns();
    if (target <= now)
        return;
    uint64_t wait = target - now;
    struct timespec ts = {(time_t)(wait / 1000000000u), (long)(wait % 1000000000u)};
    nanosleep(&ts, NULL);
}

static bpx_world_def world_def_of(const demo_options *o)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = o->backend;
    def.worker_count = o->threads;
    return def;
}

// --table2: n = 50 .. 500 headless, mean pairs per cycle next to the paper's collisions.
static int run_table2(const demo_options *o)
{
    long cycles = o->cycles_set ? o->cycles : TABLE2_CYCLES;
    if (cycles < 1)
        return cli_usage_error(command, "--table2 needs at least one cycle");
    bpx_world_def def = world_def_of(o);
    if (o->json)
        printf("[\n");
    else
        printf("| n | box W x D (m) | mean AABB pairs per cycle (bpx) | paper's \"collisions\" | "
               "ratio | mean sphere contacts per cycle | broad phase ms per cycle |\n"
               "|---:|---|---:|---:|---:|---:|---:|\n");
    for (int row = 0; row < 10; row++) {
        demo_params p = o->params;
        p.sphere_count = 50u * (uint32_t)(row + 1);
        demo_error err;
        demo_sim *sim;
        if (demo_sim_create(&p, &def, &sim, &err) != 0) {
            cli_error(command, "%s", err.message);
            return CLI_EXIT_ERROR;
        }
        demo_totals t;
        demo_cmd_start_totals(sim, &t);
        for (long c = 0; c < cycles; c++) {
            demo_step step;
            if (demo_sim_step(sim, &step, &err) != 0) {
                cli_error(command, "%s", err.message);
                demo_sim_destroy(sim);
                return CLI_EXIT_ERROR;
            }
            demo_cmd_accumulate(&t, &step);
        }
        double pairs = per_cycle(t.pairs, &t);
        if (o->json)
            printf("  {\"n\": %u, \"box_m\": [%g, %g, %g], \"cycles\": %ld, \"pairs_per_cycle\": "
                   "%.6g, \"paper_collisions\": %g, \"ratio\": %.4g, \"contacts_per_cycle\": "
                   "%.6g, \"broad_phase_ms_per_cycle\": %.6g}%s\n",
                   p.sphere_count, t.box[0], t.box[1], t.box[2], cycles, pairs,
                   paper_collisions[row], pairs / paper_collisions[row], per_cycle(t.contacts, &t),
                   per_cycle(t.broad_ns, &t) * 1e-6, row < 9 ? "," : "");
        else
            printf("| %u | %g x %g | %.2f | %.3f | %.2f | %.2f | %.4f |\n", p.sphere_count,
                   t.box[0], t.box[2], pairs, paper_collisions[row], pairs / paper_collisions[row],
                   per_cycle(t.contacts, &t), per_cycle(t.broad_ns, &t) * 1e-6);
        fflush(stdout);
        demo_sim_destroy(sim);
    }
    if (o->json)
        printf("]\n");
    else
        printf("\n%ld cycles of %.6g s per row, seed %llu, bpx backend %s, %d thread(s).\n", cycles,
               o->params.dt, (unsigned long long)o->params.seed, bpx_backend_name(o->backend),
               o->threads);
    return CLI_EXIT_OK;
}

// Everything a run owns, released in one place.
typedef struct demo_run {
    demo_sim *sim;
    demo_renderer *renderer;
    demo_window *window;
    bpx_trace_writer *trace;
    bpx_box *boxes;
    unsigned char *capture;
    char *frame_path;
} demo_run;

static int release(demo_run *run, int code)
{
    if (run->trace) {
        bpx_trace_error terr;
        if (bpx_trace_writer_close(run->trace, &terr) != BPX_TRACE_OK && code == CLI_EXIT_OK) {
            cli_error(command, "%s", terr.message);
            code = CLI_EXIT_ERROR;
        }
        run->trace = NULL;
    }
    demo_window_close(run->window);
    demo_renderer_destroy(run->renderer);
    demo_sim_destroy(run->sim);
    free(run->boxes);
    free(run->capture);
    free(run->frame_path);
    return code;
}

static void overlay(demo_renderer *renderer, const demo_sim *sim, const demo_step *s,
                    const demo_totals *t, bool timings)
{
    char lines[3][160];
    const demo_params *p = demo_sim_params(sim);
    snprintf(lines[0], sizeof lines[0], "bpx demo  n=%u  cycle %llu  t=%.2f s  backend %s",
             p->sphere_count, (unsigned long long)demo_sim_cycle(sim),
             (double)demo_sim_cycle(sim) * p->dt, bpx_backend_name(demo_sim_backend(sim)));
    snprintf(lines[1], sizeof lines[1], "pairs %llu (mean %.1f/cycle)  contacts %llu  walls %llu",
             (unsigned long long)s->pairs, per_cycle(t->pairs, t), (unsigned long long)s->contacts,
             (unsigned long long)s->wall_hits);
    snprintf(lines[2], sizeof lines[2],
             "ms: broad %.3f  narrow %.3f  response %.3f  physics %.3f  display %.2f",
             (double)s->broad_ns * 1e-6, (double)s->narrow_ns * 1e-6, (double)s->response_ns * 1e-6,
             (double)s->physics_ns * 1e-6,
             t->cycles > 1 ? t->display_ns / (double)(t->cycles - 1) * 1e-6 : 0.0);
    const char *text[3] = {lines[0], lines[1], lines[2]};
    demo_renderer_overlay(renderer, text, timings ? 3 : 2);
}

int cmd_demo(int argc, char **argv)
{
    demo_options o = {
        .params = demo_default_params(),
        .backend = BPX_BACKEND_AUTO,
        .threads = 1,
        .cycles = DEFAULT_CYCLES,
        .out_dir = DEFAULT_OUT,
        .every = DEFAULT_EVERY,
        .pace = true,
        .width = 640,
        .height = 480,
    };
    int code = demo_cmd_parse_args(argc, argv, &o);
    if (code != PARSE_CONTINUE)
        return code;
    if (o.table2)
        return run_table2(&o);

    demo_run run = {0};
    demo_error err;
    bpx_world_def def = world_def_of(&o);
    if (demo_sim_create(&o.params, &def, &run.sim, &err) != 0) {
        cli_error(command, "%s", err.message);
        return CLI_EXIT_ERROR;
    }
    const demo_params *p = demo_sim_params(run.sim);
    uint32_t n = p->sphere_count;

    // Pictures: headless by default; with --window only when asked for. The directory gets
    // stats.json even when this build cannot write PNG files.
    bool use_out = o.every > 0 && (!o.window || o.out_set || o.every_set);
    bool pictures = use_out;
    if (pictures && !demo_png_available()) {
        fprintf(stderr, "bpx demo: running without libpng, so no pictures are written: %s\n",
                demo_png_unavailable());
        pictures = false;
    }
    if (use_out && make_dirs(o.out_dir) != 0) {
        cli_error(command, "cannot create the directory %s: %s", o.out_dir, strerror(errno));
        return release(&run, CLI_EXIT_ERROR);
    }
    if (o.window && !demo_window_available()) {
        cli_error(command, "--window is not available without SDL2: %s",
                  demo_window_unavailable());
        return release(&run, CLI_EXIT_ERROR);
    }
    if (pictures || o.window) {
        double box[3];
        demo_sim_box_size(run.sim, box);
        if (demo_renderer_create(o.width, o.height, box, &run.renderer, &err) != 0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    size_t path_cap = strlen(o.out_dir) + 64;
    run.frame_path = malloc(path_cap);
    run.boxes = malloc((size_t)n * sizeof *run.boxes);
    if (o.screenshot)
        run.capture = malloc((size_t)o.width * o.height * 3);
    if (!run.frame_path || !run.boxes || (o.screenshot && !run.capture)) {
        cli_error(command, "out of memory");
        return release(&run, CLI_EXIT_ERROR);
    }
    if (o.record) {
        bpx_trace_error terr;
        if (bpx_trace_writer_open(o.record, n, &run.trace, &terr) != BPX_TRACE_OK) {
            cli_error(command, "%s", terr.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    if (o.window) {
        if (demo_window_open(o.width, o.height, "bpx demo: spheres in a box", &run.window, &err) !=
            0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
        fprintf(stderr, "bpx demo: window %dx%d, SDL video driver %s, renderer %s\n", o.width,
                o.height, demo_window_driver(run.window), demo_window_renderer(run.window));
    }

    demo_totals t;
    demo_cmd_start_totals(run.sim, &t);
    t.width = o.width;
    t.height = o.height;
    bool captured = false;
    uint64_t start_ns = demo_now_ns();
    for (long c = 0; o.cycles == 0 || c < o.cycles; c++) {
        demo_step step;
        if (demo_sim_step(run.sim, &step, &err) != 0) {
            cli_error(command, "cycle %ld: %s", c, err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
        demo_cmd_accumulate(&t, &step);
        if (run.trace) {
            bpx_trace_error terr;
            demo_sim_boxes(run.sim, run.boxes);
            if (bpx_trace_write_cycle(run.trace, run.boxes, &terr) != BPX_TRACE_OK) {
                cli_error(command, "%s", terr.message);
                return release(&run, CLI_EXIT_ERROR);
            }
        }

        // 5. Display: render once, then the PNG file and/or the window.
        uint64_t d0 = demo_now_ns();
        bool last = o.cycles != 0 && c + 1 == o.cycles;
        bool picture = pictures && (c + 1) % o.every == 0;
        if (picture || run.window) {
            demo_renderer_draw(run.renderer, demo_sim_positions(run.sim), n, p->radius);
            overlay(run.renderer, run.sim, &step, &t, run.window != NULL);
        }
        if (picture) {
            snprintf(run.frame_path, path_cap, "%s/frame_%06ld.png", o.out_dir, c + 1);
            if (demo_png_write(run.frame_path, demo_renderer_pixels(run.renderer), o.width,
                               o.height, &err) != 0) {
                cli_error(command, "%s", err.message);
                return release(&run, CLI_EXIT_ERROR);
            }
            t.pictures++;
        }
        bool closing = false;
        if (run.window) {
            // Without a known last cycle (--cycles 0), keep the latest frame for --screenshot.
            unsigned char *capture = run.capture && (last || o.cycles == 0) ? run.capture : NULL;
            if (demo_window_show(run.window, demo_renderer_pixels(run.renderer), capture, &err) !=
                0) {
                cli_error(command, "%s", err.message);
                return release(&run, CLI_EXIT_ERROR);
            }
            captured = captured || capture != NULL;
            closing = demo_window_should_close(run.window);
        }
        t.display_ns += (double)(demo_now_ns() - d0);
        if (closing)
            break;
        if (run.window && o.pace)
            sleep_until_ns(start_ns + (uint64_t)((double)(c + 1) * p->dt * 1e9));
    }
    t.wall_s = (double)(demo_now_ns() - start_ns) * 1e-9;
    demo_cmd_finish_totals(run.sim, &t);

    if (o.screenshot) {
        if (!captured) {
            cli_error(command, "no frame was shown, so there is no screenshot");
            return release(&run, CLI_EXIT_ERROR);
        }
        if (demo_png_write(o.screenshot, run.capture, o.width, o.height, &err) != 0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    if (run.trace) {
        // Close the trace first: its header's cycle count is final before we report it.
        bpx_trace_error terr;
        bpx_trace_status closed = bpx_trace_writer_close(run.trace, &terr);
        run.trace = NULL;
        if (closed != BPX_TRACE_OK) {
            cli_error(command, "%s", terr.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    const char *picture_dir = use_out ? o.out_dir : NULL;
    if (o.json)
        demo_cmd_print_json(stdout, &o, run.sim, &t, picture_dir);
    else
        demo_cmd_print_tables(&o, run.sim, &t, picture_dir);
    if (use_out) {
        snprintf(run.frame_path, path_cap, "%s/stats.json", o.out_dir);
        FILE *f = fopen(run.frame_path, "w");
        if (f)
            demo_cmd_print_json(f, &o, run.sim, &t, picture_dir);
        if (!f || fclose(f) != 0) {
            cli_error(command, "cannot write %s", run.frame_path);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    return release(&run, CLI_EXIT_OK);
}
