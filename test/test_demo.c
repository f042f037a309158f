// bpx tests: the demo's simulation (the paper's test scenario) and its pictures.
// SPDX-License-Identifier: MIT
//
// usage: test_demo SCRATCH_DIR              physics, determinism, renderer
//        test_demo --png SCRATCH_DIR        PNG written, read back, checked (77 without libpng)
//        test_demo --check-png FILE W H     FILE is a W x H PNG and not blank (77 without libpng)
//
// Tolerances (double precision, n = 300, 3000 cycles of 1/60 s with walls):
//   momentum: |p(end) - p(start) - wall impulses| <= 1e-12 * sum |m v| (measured ~1e-16: each
//             impulse adds the same vector to one sphere and subtracts it from the other, so only
//             the rounding of those additions and of the sums remains);
//   energy:   |E(end) - E(start)| / E(start) <= 1e-11 with restitution 1 (measured ~2e-16);
//             with restitution < 1 the energy never rises by more than 1e-12 relative per cycle.
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <sys/stat.h>

#include "bpx_trace.h"
#include "check.h"
#include "demo_png.h"
#include "demo_render.h"
#include "demo_sim.h"

static char scratch[512];

static demo_sim *make_sim(const demo_params *p, bpx_backend backend, int threads)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = threads;
    demo_sim *sim = NULL;
    demo_error err;
    if (demo_sim_create(p, &def, &sim, &err) != 0) {
        fprintf(stderr, "demo_sim_create: %s\n", err.message);
        exit(2);
    }
    return sim;
}

static void step_or_die(demo_sim *sim, demo_step *step)
{
    demo_error err;
    if (demo_sim_step(sim, step, &err) != 0) {
        fprintf(stderr, "demo_sim_step: %s\n", err.message);
        exit(2);
    }
}

static double momentum_scale(const demo_sim *sim)
{
    const double *v = demo_sim_velocities(sim);
    double sum = 0;
    for (uint32_t i = 0; i < demo_sim_count(sim); i++)
        sum +=
            sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
    return sum * demo_sim_params(sim)->mass;
}

static double momentum_error(const demo_sim *sim, const double start[3])
{
    double p[3], j[3], sum = 0;
    demo_sim_momentum(sim, p);
    demo_sim_wall_impulse(sim, j);
    for (int a = 0; a < 3; a++)
        sum += (p[a] - start[a] - j[a]) * (p[a] - start[a] - j[a]);
    return sqrt(sum);
}

// Every sphere entirely inside the box: r <= centre <= size - r on each axis.
static uint32_t spheres_outside(const demo_sim *sim)
{
    double size[3];
    demo_sim_box_size(sim, size);
    double r = demo_sim_params(sim)->radius;
    const double *x = demo_sim_positions(sim);
    uint32_t outside = 0;
    for (uint32_t i = 0; i < demo_sim_count(sim); i++)
        for (int a = 0; a < 3; a++)
            if (!(x[3 * i + a] >= r && x[3 * i + a] <= size[a] - r)) {
                outside++;
                break;
            }
    return outside;
}

static void test_params(void)
{
    check_set_context("parameters");
    demo_params p = demo_default_params();
    demo_error err;
    CHECK(demo_params_check(&p, &err));
    double size[3];
    demo_params_box_size(&p, size);
    // 500 spheres: 23 columns x 22 rows of 50 m spheres with 10 m gaps and 10 m to the walls.
    CHECK(size[0] == 23 * 50 + 22 * 10 + 20 && size[1] == 400 && size[2] == 22 * 50 + 21 * 10 + 20);
    p.layers = 6; // 6 * 50 + 5 * 10 + 2 * 10 = 370 m: fits in 400 m
    CHECK(demo_params_check(&p, &err));
    p.layers = 7; // 430 m: does not
    CHECK(!demo_params_check(&p, &err) && strstr(err.message, "height") != NULL);
    p = demo_default_params();
    p.restitution = 1.5;
    CHECK(!demo_params_check(&p, &err));
    p = demo_default_params();
    p.dt = 1.0; // 40 m/s * sqrt(3) * 1 s > 25 m
    CHECK(!demo_params_check(&p, &err) && strstr(err.message, "--dt") != NULL);
    p = demo_default_params();
    p.sphere_count = 0;
    CHECK(!demo_params_check(&p, &err));
    p = demo_default_params();
    p.mass = 0;
    CHECK(!demo_params_check(&p, &err));
    demo_sim *sim = NULL;
    CHECK(demo_sim_create(&p, NULL, &sim, &err) == -1 && sim == NULL);

    // The initial state: a grid with the documented gaps, velocities in [-40, 40], unique.
    p = demo_default_params();
    p.sphere_count = 50;
    sim = make_sim(&p, BPX_BACKEND_REFERENCE, 1);
    const double *x = demo_sim_positions(sim), *v = demo_sim_velocities(sim);
    CHECK(x[0] == 35 && x[2] == 35 && x[1] == 200); // wall gap 10 + radius 25; mid-height
    CHECK(x[3] == 95);                              // pitch 2r + gap = 60
    uint32_t bad_speed = 0, duplicates = 0;
    for (uint32_t i = 0; i < 50; i++) {
        for (int a = 0; a < 3; a++)
            bad_speed += !(fabs(v[3 * i + a]) <= 40);
        for (uint32_t j = 0; j < i; j++)
            duplicates += memcmp(&v[3 * i], &v[3 * j], 3 * sizeof(double)) == 0;
    }
    CHECK_EQ_U64(bad_speed, 0);
    CHECK_EQ_U64(duplicates, 0);
    CHECK_EQ_U64(spheres_outside(sim), 0);
    // At the start every gap is 10 m, so no two AABBs overlap.
    demo_step step;
    step_or_die(sim, &step);
    CHECK_EQ_U64(step.pairs, 0);
    demo_sim_destroy(sim);
}

static void test_conservation_elastic(void)
{
    check_set_context("elastic, walls, n=300, 3000 cycles");
    demo_params p = demo_default_params();
    p.sphere_count = 300;
    demo_sim *sim = make_sim(&p, BPX_BACKEND_AUTO, 2);
    double e0 = demo_sim_kinetic_energy(sim), p0[3];
    demo_sim_momentum(sim, p0);
    double scale = momentum_scale(sim);
    uint64_t impulses = 0, walls = 0, outside = 0;
    for (int c = 0; c < 3000; c++) {
        demo_step step;
        step_or_die(sim, &step);
        impulses += step.impulses;
        walls += step.wall_hits;
        outside += spheres_outside(sim);
    }
    double de = fabs(demo_sim_kinetic_energy(sim) - e0) / e0;
    double dp = momentum_error(sim, p0) / scale;
    printf("elastic: %llu sphere impulses, %llu wall impulses; energy drift %.3g, momentum drift "
           "%.3g (relative); largest overlap %.3g m, largest speed %.4g m/s\n",
           (unsigned long long)impulses, (unsigned long long)walls, de, dp,
           demo_sim_max_penetration(sim), demo_sim_max_speed(sim));
    CHECK(impulses > 1000 && walls > 1000);
    CHECK_EQ_U64(outside, 0);
    CHECK_MSG(de <= 1e-11, "energy drift %.3g", de);
    CHECK_MSG(dp <= 1e-12, "momentum drift %.3g", dp);
    // Nothing deeper than a few steps' travel: no pair passes through another.
    CHECK_MSG(demo_sim_max_penetration(sim) < 5.0, "overlap %.3g m", demo_sim_max_penetration(sim));
    demo_sim_destroy(sim);
}

static void test_momentum_without_walls(void)
{
    check_set_context("no walls reached, n=400, 600 cycles");
    demo_params p = demo_default_params();
    p.sphere_count = 400;
    p.wall_gap = 3000; // 10 s at under 200 m/s cannot reach a wall
    p.height = 6100;
    demo_sim *sim = make_sim(&p, BPX_BACKEND_AUTO, 1);
    double p0[3];
    demo_sim_momentum(sim, p0);
    double scale = momentum_scale(sim);
    uint64_t impulses = 0, walls = 0;
    for (int c = 0; c < 600; c++) {
        demo_step step;
        step_or_die(sim, &step);
        impulses += step.impulses;
        walls += step.wall_hits;
    }
    double j[3];
    demo_sim_wall_impulse(sim, j);
    CHECK_EQ_U64(walls, 0);
    CHECK(j[0] == 0 && j[1] == 0 && j[2] == 0);
    CHECK(impulses > 100);
    double dp = momentum_error(sim, p0) / scale;
    printf("no walls: %llu impulses, momentum drift %.3g (relative)\n",
           (unsigned long long)impulses, dp);
    CHECK_MSG(dp <= 1e-12, "momentum drift %.3g", dp);
    demo_sim_destroy(sim);
}

static void test_restitution(void)
{
    check_set_context("restitution 0.5");
    demo_params p = demo_default_params();
    p.sphere_count = 200;
    p.restitution = 0.5;
    demo_sim *sim = make_sim(&p, BPX_BACKEND_AUTO, 1);
    double e0 = demo_sim_kinetic_energy(sim), previous = e0, p0[3];
    demo_sim_momentum(sim, p0);
    double scale = momentum_scale(sim);
    uint64_t rises = 0, outside = 0;
    for (int c = 0; c < 3000; c++) {
        demo_step step;
        step_or_die(sim, &step);
        double e = demo_sim_kinetic_energy(sim);
        rises += e > previous * (1 + 1e-12);
        previous = e;
        outside += spheres_outside(sim);
    }
    CHECK_EQ_U64(rises, 0);
    CHECK_EQ_U64(outside, 0);
    CHECK_MSG(previous < 0.5 * e0, "energy %.6g of %.6g", previous, e0);
    CHECK_MSG(momentum_error(sim, p0) / scale <= 1e-12, "momentum drift %.3g",
              momentum_error(sim, p0) / scale);
    demo_sim_destroy(sim);
}

// Two spheres head-on: they bounce, exchanging velocities exactly, and never pass each other.
static void test_head_on(double speed)
{
    check_set_context("head-on at %g m/s each", speed);
    demo_params p = demo_default_params();
    p.sphere_count = 2;
    p.wall_gap = 1000;
    p.height = 2100; // the wall gap holds above and below the grid too
    demo_sim *sim = make_sim(&p, BPX_BACKEND_REFERENCE, 1);
    double size[3];
    demo_sim_box_size(sim, size);
    double mid = 0.5 * size[0];
    double x[6] = {mid - 400, 300, 0.5 * size[2], mid + 400, 300, 0.5 * size[2]};
    double v[6] = {speed, 0, 0, -speed, 0, 0};
    demo_error err;
    CHECK(demo_sim_set_state(sim, x, v, &err) == 0);
    uint64_t passed = 0, impulses = 0;
    int cycles = (int)(800.0 / (2 * speed) / p.dt) + 5; // until just after they meet
    for (int c = 0; c < cycles; c++) {
        demo_step step;
        step_or_die(sim, &step);
        impulses += step.impulses;
        const double *pos = demo_sim_positions(sim);
        passed += pos[0] >= pos[3];
    }
    const double *vel = demo_sim_velocities(sim);
    CHECK_EQ_U64(passed, 0);
    CHECK_EQ_U64(impulses, 1);
    CHECK_MSG(vel[0] == -speed && vel[3] == speed, "velocities %g %g", vel[0], vel[3]);
    // set_state refuses a sphere poking out of the box.
    x[0] = 10;
    CHECK(demo_sim_set_state(sim, x, v, &err) == -1 && strstr(err.message, "outside"));
    demo_sim_destroy(sim);
}

static uint64_t file_hash(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    uint64_t h = 0xcbf29ce484222325ull;
    int c;
    *size = 0;
    while ((c = fgetc(f)) != EOF) {
        h ^= (unsigned char)c;
        h *= 0x100000001b3ull;
        (*size)++;
    }
    fclose(f);
    return h;
}

// Runs n spheres for cycles cycles, recording every cycle's boxes; returns the trace's hash.
static uint64_t record_run(const demo_params *p, bpx_backend backend, int threads, int cycles,
                           const char *path, double *final_pos, bool check_pairs)
{
    demo_sim *sim = make_sim(p, backend, threads);
    uint32_t n = p->sphere_count;
    bpx_box *boxes = check_alloc(sizeof *boxes * n);
    bpx_pair *oracle = check_alloc(sizeof *oracle * (size_t)n * (n - 1) / 2 + 1);
    bpx_trace_writer *w;
    bpx_trace_error err;
    CHECK(bpx_trace_writer_open(path, n, &w, &err) == BPX_TRACE_OK);
    uint64_t mismatches = 0;
    for (int c = 0; c < cycles; c++) {
        demo_step step;
        step_or_die(sim, &step);
        demo_sim_boxes(sim, boxes);
        CHECK(bpx_trace_write_cycle(w, boxes, &err) == BPX_TRACE_OK);
        if (check_pairs) {
            // The recorded boxes are exactly what bpx saw: all pairs of them are bpx's pairs.
            size_t count = 0, found = 0;
            const bpx_pair *pairs = demo_sim_pairs(sim, &count);
            CHECK(bpx_find_pairs(boxes, n, BPX_BACKEND_REFERENCE, oracle,
                                 (size_t)n * (n - 1) / 2 + 1, &found, NULL) == BPX_OK);
            mismatches +=
                found != count || (count > 0 && memcmp(pairs, oracle, count * sizeof *pairs) != 0);
        }
    }
    CHECK_EQ_U64(mismatches, 0);
    CHECK(bpx_trace_writer_close(w, &err) == BPX_TRACE_OK);
    memcpy(final_pos, demo_sim_positions(sim), 3 * sizeof(double) * n);
    free(boxes);
    free(oracle);
    demo_sim_destroy(sim);
    size_t size = 0;
    uint64_t h = file_hash(path, &size);
    CHECK_EQ_U64(size, BPX_TRACE_HEADER_BYTES + (uint64_t)cycles * n * BPX_TRACE_BOX_BYTES);
    return h;
}

static void test_determinism(void)
{
    demo_params p = demo_default_params();
    p.sphere_count = 200;
    p.seed = 5;
    enum { CYCLES = 400 };
    char path[1024];
    snprintf(path, sizeof path, "%s/det_first.trace", scratch);
    double *first_pos = check_alloc(3 * sizeof(double) * p.sphere_count);
    double *pos = check_alloc(3 * sizeof(double) * p.sphere_count);
    check_set_context("determinism: reference, 1 thread");
    uint64_t want = record_run(&p, BPX_BACKEND_REFERENCE, 1, CYCLES, path, first_pos, true);
    int runs = 1;
    static const int thread_counts[] = {1, 3};
    for (int b = BPX_BACKEND_AUTO; b < BPX_BACKEND_COUNT; b++) {
        if (b != BPX_BACKEND_AUTO && !bpx_backend_query((bpx_backend)b).available)
            continue;
        for (int t = 0; t < 2; t++) {
            const char *name = bpx_backend_name((bpx_backend)b);
            check_set_context("determinism: backend %s, %d threads", name, thread_counts[t]);
            snprintf(path, sizeof path, "%s/det_%s_%d.trace", scratch, name, thread_counts[t]);
            uint64_t got =
                record_run(&p, (bpx_backend)b, thread_counts[t], CYCLES, path, pos, false);
            CHECK_MSG(got == want, "trace bytes differ from the reference backend's");
            CHECK(memcmp(pos, first_pos, 3 * sizeof(double) * p.sphere_count) == 0);
            runs++;
        }
    }
    printf("determinism: %d runs (every available backend, 1 and 3 threads) gave the same trace, "
           "hash %016llx\n",
           runs, (unsigned long long)want);
    check_set_context("determinism: another seed");
    p.seed = 6;
    snprintf(path, sizeof path, "%s/det_seed6.trace", scratch);
    CHECK(record_run(&p, BPX_BACKEND_AUTO, 1, CYCLES, path, pos, false) != want);
    free(first_pos);
    free(pos);
}

// Not blank: many colours, and most pixels differ from the empty box.
static void check_picture(const unsigned char *rgb, const unsigned char *empty, int w, int h,
                          int min_colours)
{
    unsigned char *seen = calloc(1u << 21, 1); // one bit per 24-bit colour
    if (!seen)
        exit(2);
    int colours = 0;
    size_t differ = 0, pixels = (size_t)w * h;
    for (size_t k = 0; k < pixels; k++) {
        uint32_t c = (uint32_t)rgb[3 * k] << 16 | (uint32_t)rgb[3 * k + 1] << 8 | rgb[3 * k + 2];
        if (!(seen[c >> 3] & (1u << (c & 7)))) {
            seen[c >> 3] |= (unsigned char)(1u << (c & 7));
            colours++;
        }
        if (empty)
            differ += memcmp(rgb + 3 * k, empty + 3 * k, 3) != 0;
    }
    free(seen);
    CHECK_MSG(colours >= min_colours, "%d colours", colours);
    if (empty)
        CHECK_MSG(differ > pixels / 20, "%zu of %zu pixels differ from the empty box", differ,
                  pixels);
}

// Renders the default scenario after one simulated second at w x h; *empty gets the empty box.
static unsigned char *render_frame(int w, int h, unsigned char **empty)
{
    demo_params p = demo_default_params();
    demo_sim *sim = make_sim(&p, BPX_BACKEND_AUTO, 1);
    for (int c = 0; c < 60; c++) {
        demo_step step;
        step_or_die(sim, &step);
    }
    double size[3];
    demo_sim_box_size(sim, size);
    demo_renderer *r;
    demo_error err;
    CHECK(demo_renderer_create(w, h, size, &r, &err) == 0);
    CHECK(demo_renderer_width(r) == w && demo_renderer_height(r) == h);
    demo_renderer_draw(r, NULL, 0, p.radius);
    *empty = check_alloc((size_t)w * h * 3);
    memcpy(*empty, demo_renderer_pixels(r), (size_t)w * h * 3);
    demo_renderer_draw(r, demo_sim_positions(sim), demo_sim_count(sim), p.radius);
    const char *lines[1] = {"bpx demo test 0123456789"};
    demo_renderer_overlay(r, lines, 1);
    unsigned char *rgb = check_alloc((size_t)w * h * 3);
    memcpy(rgb, demo_renderer_pixels(r), (size_t)w * h * 3);
    demo_renderer_destroy(r);
    demo_sim_destroy(sim);
    // Bad sizes are refused.
    CHECK(demo_renderer_create(8, 8, size, &r, &err) == -1 && r == NULL);
    return rgb;
}

static void test_render(void)
{
    check_set_context("renderer");
    unsigned char *empty;
    unsigned char *rgb = render_frame(320, 240, &empty);
    check_picture(rgb, empty, 320, 240, 200);
    check_picture(empty, NULL, 320, 240, 20);
    free(rgb);
    free(empty);
}

static int test_png(void)
{
    if (!demo_png_available()) {
        printf("test_demo --png: SKIPPED: this build has no libpng\n");
        return CHECK_SKIP;
    }
    check_set_context("png");
    unsigned char *empty;
    unsigned char *rgb = render_frame(640, 480, &empty);
    char path[1024];
    snprintf(path, sizeof path, "%s/frame.png", scratch);
    demo_error err;
    CHECK(demo_png_write(path, rgb, 640, 480, &err) == 0);
    unsigned char *back = NULL;
    int w = 0, h = 0;
    CHECK(demo_png_read(path, &back, &w, &h, &err) == 0);
    CHECK(w == 640 && h == 480);
    if (back && w == 640 && h == 480) {
        CHECK(memcmp(back, rgb, (size_t)w * h * 3) == 0); // lossless
        check_picture(back, empty, w, h, 200);
    }
    free(back);
    // A file that is not a PNG is refused with a message naming it.
    snprintf(path, sizeof path, "%s/not.png", scratch);
    FILE *f = fopen(path, "wb");
    if (f) {
        fputs("not a png", f);
        fclose(f);
    }
    CHECK(demo_png_read(path, &back, &w, &h, &err) == -1 && back == NULL &&
          strstr(err.message, "not.png") != NULL);
    snprintf(path, sizeof path, "%s/no-such-dir/frame.png", scratch);
    CHECK(demo_png_write(path, rgb, 640, 480, &err) == -1);
    free(rgb);
    free(empty);
    return check_finish("test_demo --png", 1);
}

static int check_png_file(const char *path, int want_w, int want_h)
{
    if (!demo_png_available()) {
        printf("test_demo --check-png: SKIPPED: this build has no libpng\n");
        return CHECK_SKIP;
    }
    check_set_context("%s", path);
    unsigned char *rgb = NULL;
    int w = 0, h = 0;
    demo_error err;
    CHECK_MSG(demo_png_read(path, &rgb, &w, &h, &err) == 0, "%s", err.message);
    CHECK_MSG(w == want_w && h == want_h, "%dx%d, want %dx%d", w, h, want_w, want_h);
    if (rgb)
        check_picture(rgb, NULL, w, h, 200);
    free(rgb);
    return check_finish("test_demo --check-png", 1);
}

static int make_scratch(const char *dir)
{
    snprintf(scratch, sizeof scratch, "%s", dir);
    if (mkdir(scratch, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "cannot create %s\n", scratch);
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 5 && strcmp(argv[1], "--check-png") == 0)
        return check_png_file(argv[2], atoi(argv[3]), atoi(argv[4]));
    if (argc == 3 && strcmp(argv[1], "--png") == 0)
        return make_scratch(argv[2]) == 0 ? test_png() : 2;
    if (make_scratch(argc > 1 ? argv[1] : "demo_scratch") != 0)
        return 2;
    test_params();
    test_conservation_elastic();
    test_momentum_without_walls();
    test_restitution();
    test_head_on(70);
    test_head_on(700);
    test_determinism();
    test_render();
    return check_finish("test_demo", 1);
}
