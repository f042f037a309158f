// bpx demo: the paper's test scenario, stages 1-4 of the central loop. SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L
#include "demo_sim.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "scenes.h"

struct demo_sim {
    demo_params params;
    uint32_t n;
    double size[3];    // inner box size, m
    double *pos;       // 3n centres, m
    double *vel;       // 3n velocities, m/s
    float *minima;     // 3n origin-centred AABB minima, loaded into bpx once
    float *centres;    // 3n centres as sent to bpx in the last broad phase
    uint32_t *contact; // indices into the pair list of the last narrow phase
    size_t contact_cap;
    bpx_world *world;
    const bpx_pair *pairs; // last broad phase's pairs (owned by the world)
    size_t pair_count;
    uint64_t cycle;
    double wall_impulse[3];
    double max_penetration;
    double max_speed;
};

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static int
fail(demo_error *err, const char *fmt, ...)
{
    if (err) {
        va_list args;
        va_start(args, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, args);
        va_end(args);
    }
    return -1;
}

uint64_t demo_now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

demo_params demo_default_params(void)
{
    return (demo_params){
        .sphere_count = 500,
        .radius = 25.0,
        .gap = 10.0,
        .wall_gap = 10.0,
        .height = 400.0,
        .layers = 1,
        .max_speed = 40.0,
        .mass = 1.0,
        .restitution = 1.0,
        .dt = 1.0 / 60.0,
        .seed = 1,
    };
}

// Columns and rows of one layer of the initial grid: the smallest square-ish grid that holds
// ceil(n / layers) spheres (columns along x, rows along z).
static void grid_shape(const demo_params *p, uint32_t *per_layer, uint32_t *cols, uint32_t *rows)
{
    uint32_t layers = p->layers ? p->layers : 1;
    uint32_t k = (p->sphere_count + layers - 1) / layers;
    uint32_t c = 1;
    while ((uint64_t)c * c < k)
        c++;
    *per_layer = k;
    *cols = c;
    *rows = (k + c - 1) / c;
}

void demo_params_box_size(const demo_params *p, double size[3])
{
    uint32_t per_layer, cols, rows;
    grid_shape(p, &per_layer, &cols, &rows);
    double d = 2.0 * p->radius;
    size[0] = cols * d + (cols - 1) * p->gap + 2.0 * p->wall_gap;
    size[1] = p->height;
    size[2] = rows * d + (rows - 1) * p->gap + 2.0 * p->wall_gap;
}

bool demo_params_check(const demo_params *p, demo_error *err)
{
    if (!p)
        return fail(err, "null parameters") == 0;
    if (p->sphere_count < 1 || p->sphere_count > 1000000)
        return fail(err, "sphere count %u is outside 1 .. 1000000", p->sphere_count) == 0;
    if (!(p->radius > 0 && p->radius <= 1e6))
        return fail(err, "radius %g m is outside (0, 1e6]", p->radius) == 0;
    if (!(p->gap >= 0 && p->gap <= 1e6))
        return fail(err, "gap %g m is outside [0, 1e6]", p->gap) == 0;
    if (!(p->wall_gap >= 0 && p->wall_gap <= 1e6))
        return fail(err, "wall gap %g m is outside [0, 1e6]", p->wall_gap) == 0;
    if (p->layers < 1 || p->layers > 100000)
        return fail(err, "layers %u is outside 1 .. 100000", p->layers) == 0;
    if (!(p->max_speed >= 0 && p->max_speed <= 1e5))
        return fail(err, "speed %g m/s is outside [0, 1e5]", p->max_speed) == 0;
    if (!(p->mass > 0 && p->mass <= 1e12))
        return fail(err, "mass %g kg is outside (0, 1e12]", p->mass) == 0;
    if (!(p->restitution >= 0 && p->restitution <= 1))
        return fail(err, "restitution %g is outside [0, 1]", p->restitution) == 0;
    if (!(p->dt > 0 && p->dt <= 10))
        return fail(err, "time step %g s is outside (0, 10]", p->dt) == 0;
    double stack = p->layers * 2.0 * p->radius + (p->layers - 1) * p->gap + 2.0 * p->wall_gap;
    if (!(p->height > 0 && p->height <= 1e7) || stack > p->height)
        return fail(err,
                    "%u layer(s) of spheres of radius %g m with %g m gaps and %g m to the walls "
                    "need a height of %g m; the box is %g m high",
                    p->layers, p->radius, p->gap, p->wall_gap, stack, p->height) == 0;
    // A step longer than the sphere radius at the initial speeds could let a sphere cross the
    // box's free space in one step; refuse the settings rather than simulate them badly.
    if (p->max_speed * 1.7320508075688772 * p->dt > p->radius)
        return fail(err,
                    "a step of %g s at up to %g m/s per axis moves a sphere more than its radius "
                    "(%g m): choose a smaller --dt",
                    p->dt, p->max_speed, p->radius) == 0;
    return true;
}

static void initial_state(demo_sim *s)
{
    const demo_params *p = &s->params;
    uint32_t per_layer, cols, rows;
    grid_shape(p, &per_layer, &cols, &rows);
    double d = 2.0 * p->radius, pitch = d + p->gap;
    // The layers sit in the middle of the height, the grid in the middle of the floor plan.
    double stack = p->layers * d + (p->layers - 1) * p->gap;
    double y0 = 0.5 * (p->height - stack) + p->radius;
    double x0 = p->wall_gap + p->radius, z0 = p->wall_gap + p->radius;
    scene_rng rng;
    scene_rng_seed(&rng, p->seed);
    float vmax = (float)p->max_speed;
    for (uint32_t i = 0; i < s->n; i++) {
        uint32_t layer = i / per_layer, k = i % per_layer;
        double *x = &s->pos[3 * (size_t)i];
        x[0] = x0 + (k % cols) * pitch;
        x[1] = y0 + layer * pitch;
        x[2] = z0 + (k / cols) * pitch;
        double *v = &s->vel[3 * (size_t)i];
        for (int a = 0; a < 3; a++)
            v[a] = (double)scene_rng_range(&rng, -vmax, vmax);
        for (int a = 0; a < 3; a++) {
            s->minima[3 * (size_t)i + a] = (float)-p->radius;
            s->centres[3 * (size_t)i + a] = (float)x[a];
        }
    }
}

int demo_sim_create(const demo_params *params, const bpx_world_def *world_def, demo_sim **out,
                    demo_error *err)
{
    if (!out)
        return fail(err, "null output pointer");
    *out = NULL;
    if (!demo_params_check(params, err))
        return -1;
    demo_sim *s = calloc(1, sizeof *s);
    if (!s)
        return fail(err, "out of memory");
    s->params = *params;
    s->n = params->sphere_count;
    demo_params_box_size(params, s->size);
    size_t n3 = 3 * (size_t)s->n;
    s->pos = malloc(n3 * sizeof *s->pos);
    s->vel = malloc(n3 * sizeof *s->vel);
    s->minima = malloc(n3 * sizeof *s->minima);
    s->centres = malloc(n3 * sizeof *s->centres);
    if (!s->pos || !s->vel || !s->minima || !s->centres) {
        demo_sim_destroy(s);
        return fail(err, "out of memory for %u spheres", params->sphere_count);
    }
    initial_state(s);

    bpx_world_def def = world_def ? *world_def : bpx_default_world_def();
    if (def.capacity_hint == 0)
        def.capacity_hint = s->n;
    bpx_status status = bpx_world_create(&def, &s->world);
    if (status != BPX_OK) {
        demo_sim_destroy(s);
        return fail(err, "cannot create the bpx world: %s", bpx_status_string(status));
    }
    // The paper's initialisation phase: each sphere's origin-centred AABB, once.
    if (bpx_world_load_extents(s->world, s->minima, s->n) != BPX_OK) {
        fail(err, "bpx: %s", bpx_world_error(s->world)->message);
        demo_sim_destroy(s);
        return -1;
    }
    *out = s;
    return 0;
}

void demo_sim_destroy(demo_sim *s)
{
    if (!s)
        return;
    bpx_world_destroy(s->world);
    free(s->pos);
    free(s->vel);
    free(s->minima);
    free(s->centres);
    free(s->contact);
    free(s);
}

int demo_sim_set_state(demo_sim *s, const double *centres, const double *velocities,
                       demo_error *err)
{
    if (!s || !centres || !velocities)
        return fail(err, "null argument");
    double r = s->params.radius;
    for (uint32_t i = 0; i < s->n; i++)
        for (int a = 0; a < 3; a++) {
            double x = centres[3 * (size_t)i + a], v = velocities[3 * (size_t)i + a];
            if (!isfinite(x) || !isfinite(v))
                return fail(err, "sphere %u: a NaN or infinite value on axis %d", i, a);
            if (x < r || x > s->size[a] - r)
                return fail(err, "sphere %u: centre %g on axis %d is outside [%g, %g]", i, x, a, r,
                            s->size[a] - r);
        }
    size_t n3 = 3 * (size_t)s->n;
    memcpy(s->pos, centres, n3 * sizeof *s->pos);
    memcpy(s->vel, velocities, n3 * sizeof *s->vel);
    for (size_t k = 0; k < n3; k++)
        s->centres[k] = (float)s->pos[k];
    return 0;
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// Stage 2: the pairs whose spheres touch (distance <= 2r; touching counts, as in bpx).
static int narrow_phase(demo_sim *s, size_t *contacts, demo_error *err)
{
    if (s->pair_count > s->contact_cap) {
        size_t cap = s->pair_count + s->pair_count / 2 + 16;
        uint32_t *grown = realloc(s->contact, cap * sizeof *grown);
        if (!grown)
            return fail(err, "out of memory for %zu contacts", s->pair_count);
        s->contact = grown;
        s->contact_cap = cap;
    }
    double reach = 2.0 * s->params.radius, reach2 = reach * reach;
    size_t count = 0;
    for (size_t k = 0; k < s->pair_count; k++) {
        const double *a = &s->pos[3 * (size_t)s->pairs[k].i];
        const double *b = &s->pos[3 * (size_t)s->pairs[k].j];
        double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double d2 = dot3(d, d);
        if (d2 <= reach2) {
            s->contact[count++] = (uint32_t)k;
            double depth = reach - sqrt(d2);
            if (depth > s->max_penetration)
                s->max_penetration = depth;
        }
    }
    *contacts = count;
    return 0;
}

// Stage 3. Equal masses: the impulse changes v_i by +a and v_j by -a with one and the same
// vector a, so m v_i + m v_j is kept up to the rounding of the two additions; with e = 1 the
// normal components are exchanged, keeping kinetic energy up to rounding.
static void respond(demo_sim *s, size_t contacts, demo_step *step)
{
    const double e = s->params.restitution, m = s->params.mass, r = s->params.radius;
    const double reach = 2.0 * r, dt = s->params.dt;
    uint64_t impulses = 0, wall_hits = 0;
    for (size_t c = 0; c < contacts; c++) {
        const bpx_pair *pair = &s->pairs[s->contact[c]];
        double *pi = &s->pos[3 * (size_t)pair->i], *pj = &s->pos[3 * (size_t)pair->j];
        double *vi = &s->vel[3 * (size_t)pair->i], *vj = &s->vel[3 * (size_t)pair->j];
        double d[3] = {pj[0] - pi[0], pj[1] - pi[1], pj[2] - pi[2]};
        double dist = sqrt(dot3(d, d));
        double nrm[3] = {1.0, 0.0, 0.0}; // coincident centres: any fixed normal will do
        if (dist > 0)
            for (int a = 0; a < 3; a++)
                nrm[a] = d[a] / dist;
        double dv[3] = {vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]};
        double vn = dot3(dv, nrm);
        if (vn < 0) {
            double k = 0.5 * (1.0 + e) * vn; // impulse / m for equal masses
            for (int a = 0; a < 3; a++) {
                double change = k * nrm[a];
                vi[a] += change;
                vj[a] -= change;
            }
            impulses++;
        }
        double depth = reach - dist;
        if (depth > 0) {
            // Move both apart by half the overlap each. Positions only: no velocity changes,
            // so this cannot add kinetic energy or momentum.
            double half = 0.5 * depth;
            for (int a = 0; a < 3; a++) {
                pi[a] -= half * nrm[a];
                pj[a] += half * nrm[a];
            }
        }
    }
    // Walls: a sphere whose next step would carry it through a wall is bounced now (a speculative
    // contact): it never leaves the box and never passes a wall, whatever its speed, and turns at
    // most |v| dt short of the wall (0.67 m at 40 m/s and dt = 1/60 s).
    for (uint32_t i = 0; i < s->n; i++) {
        double *x = &s->pos[3 * (size_t)i], *v = &s->vel[3 * (size_t)i];
        for (int a = 0; a < 3; a++) {
            double lo = r, hi = s->size[a] - r;
            // The overlap correction may have pushed a sphere into a wall: put it back.
            if (x[a] < lo)
                x[a] = lo;
            if (x[a] > hi)
                x[a] = hi;
            double next = x[a] + v[a] * dt;
            if ((v[a] < 0 && next < lo) || (v[a] > 0 && next > hi)) {
                double before = v[a];
                v[a] = -e * v[a];
                s->wall_impulse[a] += m * (v[a] - before);
                wall_hits++;
            }
        }
    }
    step->impulses = impulses;
    step->wall_hits = wall_hits;
}

int demo_sim_step(demo_sim *s, demo_step *out, demo_error *err)
{
    if (!s)
        return fail(err, "null simulation");
    demo_step step = {0};
    size_t n3 = 3 * (size_t)s->n;

    // 1. Broad phase: the paper's updating phase, 3 floats per sphere, then all AABB pairs.
    uint64_t t0 = demo_now_ns();
    for (size_t k = 0; k < n3; k++)
        s->centres[k] = (float)s->pos[k];
    if (bpx_world_update_centres(s->world, s->centres) != BPX_OK ||
        bpx_world_collide(s->world) != BPX_OK)
        return fail(err, "bpx: %s", bpx_world_error(s->world)->message);
    s->pairs = bpx_world_pairs(s->world, &s->pair_count);
    uint64_t t1 = demo_now_ns();

    // 2. Narrow phase.
    size_t contacts = 0;
    if (narrow_phase(s, &contacts, err) != 0)
        return -1;
    uint64_t t2 = demo_now_ns();

    // 3. Collision response.
    respond(s, contacts, &step);
    uint64_t t3 = demo_now_ns();

    // 4. Physics: explicit Euler is exact here, velocities being constant between impulses.
    const double dt = s->params.dt;
    for (size_t k = 0; k < n3; k++)
        s->pos[k] += s->vel[k] * dt;
    uint64_t t4 = demo_now_ns();

    for (uint32_t i = 0; i < s->n; i++) {
        const double *v = &s->vel[3 * (size_t)i];
        double speed = sqrt(dot3(v, v));
        if (speed > s->max_speed)
            s->max_speed = speed;
    }
    s->cycle++;
    step.broad_ns = t1 - t0;
    step.narrow_ns = t2 - t1;
    step.response_ns = t3 - t2;
    step.physics_ns = t4 - t3;
    step.pairs = s->pair_count;
    step.contacts = contacts;
    step.bpx = bpx_world_stats(s->world);
    if (out)
        *out = step;
    return 0;
}

const demo_params *demo_sim_params(const demo_sim *s)
{
    return &s->params;
}

uint32_t demo_sim_count(const demo_sim *s)
{
    return s->n;
}

uint64_t demo_sim_cycle(const demo_sim *s)
{
    return s->cycle;
}

void demo_sim_box_size(const demo_sim *s, double size[3])
{
    memcpy(size, s->size, sizeof s->size);
}

const double *demo_sim_positions(const demo_sim *s)
{
    return s->pos;
}

const double *demo_sim_velocities(const demo_sim *s)
{
    return s->vel;
}

void demo_sim_boxes(const demo_sim *s, bpx_box *out)
{
    for (uint32_t i = 0; i < s->n; i++)
        for (int a = 0; a < 3; a++) {
            float c = s->centres[3 * (size_t)i + a], m = s->minima[3 * (size_t)i + a];
            out[i].min[a] = c + m; // as bpx's updater: centre + minimum, centre - minimum
            out[i].max[a] = c - m;
        }
}

const bpx_pair *demo_sim_pairs(const demo_sim *s, size_t *count)
{
    if (count)
        *count = s->pair_count;
    return s->pairs;
}

double demo_sim_kinetic_energy(const demo_sim *s)
{
    double sum = 0;
    for (uint32_t i = 0; i < s->n; i++) {
        const double *v = &s->vel[3 * (size_t)i];
        sum += dot3(v, v);
    }
    return 0.5 * s->params.mass * sum;
}

void demo_sim_momentum(const demo_sim *s, double p[3])
{
    double sum[3] = {0, 0, 0};
    for (uint32_t i = 0; i < s->n; i++)
        for (int a = 0; a < 3; a++)
            sum[a] += s->vel[3 * (size_t)i + a];
    for (int a = 0; a < 3; a++)
        p[a] = s->params.mass * sum[a];
}

void demo_sim_wall_impulse(const demo_sim *s, double j[3])
{
    memcpy(j, s->wall_impulse, sizeof s->wall_impulse);
}

double demo_sim_max_penetration(const demo_sim *s)
{
    return s->max_penetration;
}

double demo_sim_max_speed(const demo_sim *s)
{
    return s->max_speed;
}

bpx_backend demo_sim_backend(const demo_sim *s)
{
    return bpx_world_backend(s->world);
}

bpx_simd demo_sim_simd(const demo_sim *s)
{
    return bpx_world_simd(s->world);
}
