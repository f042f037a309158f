// bpx demo: the paper's test scenario (Woulfe et al. 2007, section 5) as a library: spheres in a
// closed box, and the central loop's first four stages (broad phase through bpx, narrow phase,
// collision response, physics). Display lives in demo_render.h. SPDX-License-Identifier: MIT
//
// Units: metres, seconds, kilograms. Axes: y is up; the box interior is [0, W] x [0, H] x [0, D]
// with W the width (x), H the height (y) and D the depth (z).
//
// Bit-reproducible: the state after any number of cycles is a pure function of the parameters
// (seeded PRNG, fixed time step, IEEE double arithmetic with only +, -, *, / and sqrt, compiled
// without FMA contraction); bpx returns the same sorted pair list for every backend and thread
// count, and pairs are processed in that order. Library code: never prints, never exits.
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <bpx/bpx.h>

#ifdef __cplusplus
extern "C" {
#endif

/// An error message from the demo library (English, one line).
typedef struct demo_error {
    char message[256];
} demo_error;

/// The scenario. Get one from demo_default_params(), change fields, pass it to demo_sim_create.
typedef struct demo_params {
    uint32_t sphere_count; ///< spheres (the paper: 50 .. 500). Default 500. Range 1 .. 1 000 000.
    double radius;         ///< sphere radius, m. Default 25 (the paper).
    double gap;            ///< gap between neighbouring spheres at initialisation, m. Default 10.
    double wall_gap;       ///< gap between the outer spheres and the walls at start, m. Default 10.
    double height;         ///< inner height of the box, m. Default 400 (the paper).
    uint32_t layers;       ///< horizontal layers of the initial grid. Default 1 (see docs/demo.md).
    double max_speed;      ///< initial velocity components uniform in [-max, max], m/s. Default 40.
    double mass;           ///< mass of every sphere, kg. Default 1 (momentum = velocity).
    double restitution;    ///< coefficient of restitution, 0 .. 1, walls too. Default 1 (elastic).
    double dt;             ///< fixed time step, s. Default 1/60.
    uint64_t seed;         ///< seed of the initial velocities. Default 1.
} demo_params;

/// The defaults above.
demo_params demo_default_params(void);

/// Checks ranges and that the initial grid fits the height. Returns true, or false with a message.
bool demo_params_check(const demo_params *params, demo_error *err);

/// The inner size of the box the parameters give, m: [0] width (x), [1] height (y), [2] depth (z).
/// Width and depth follow from the grid: columns (rows) * 2r + gaps between + 2 * wall gap.
void demo_params_box_size(const demo_params *params, double size[3]);

/// One cycle's figures.
typedef struct demo_step {
    uint64_t broad_ns;    ///< stage 1: bpx_world_update_centres + bpx_world_collide, wall clock
    uint64_t narrow_ns;   ///< stage 2: exact sphere-sphere tests of the broad-phase pairs
    uint64_t response_ns; ///< stage 3: impulses (spheres, walls) and overlap correction
    uint64_t physics_ns;  ///< stage 4: integration of positions
    uint64_t pairs;       ///< overlapping AABB pairs from bpx
    uint64_t contacts;    ///< of those, pairs of spheres that touch or overlap
    uint64_t impulses;    ///< sphere-sphere impulses applied (contacts that were approaching)
    uint64_t wall_hits;   ///< wall impulses applied
    bpx_cycle_stats bpx;  ///< bpx's own counters and per-stage ns for the broad phase
} demo_step;

typedef struct demo_sim demo_sim;

/// Creates the scenario: spheres on the initial grid, velocities from the seed, a bpx world made
/// from world_def (NULL: bpx defaults) with the spheres' extents loaded once (the paper's
/// initialisation phase). Returns 0, or -1 with a message (bad parameters, bpx error, memory).
int demo_sim_create(const demo_params *params, const bpx_world_def *world_def, demo_sim **out,
                    demo_error *err);

/// Frees everything. NULL is allowed.
void demo_sim_destroy(demo_sim *sim);

/// Replaces the state: centres (3n doubles, m) and velocities (3n doubles, m/s), for tests and
/// custom set-ups. Every centre must keep its sphere inside the box (r <= x <= size - r per axis)
/// and every value must be finite; otherwise returns -1 with a message and changes nothing.
int demo_sim_set_state(demo_sim *sim, const double *centres, const double *velocities,
                       demo_error *err);

/// Runs one cycle of the paper's central loop, stages 1 to 4, in order:
///   1. broad phase: the centres go to bpx (bpx_world_update_centres), bpx finds the pairs;
///   2. narrow phase: each pair, in bpx's (i, j) order, is a contact if the spheres touch;
///   3. collision response: per contact in order, an impulse along the normal if approaching
///      (momentum-conserving, restitution e), then the overlap is removed by moving both spheres
///      apart (positions only, so energy and momentum are untouched); then per sphere and axis a
///      wall impulse if this step would carry it through a wall;
///   4. physics: x += v dt.
/// step (may be NULL) receives the figures. Returns 0, or -1 with a message (bpx error).
int demo_sim_step(demo_sim *sim, demo_step *step, demo_error *err);

/// The parameters the simulation was made with.
const demo_params *demo_sim_params(const demo_sim *sim);
/// Spheres.
uint32_t demo_sim_count(const demo_sim *sim);
/// Completed cycles.
uint64_t demo_sim_cycle(const demo_sim *sim);
/// Inner size of the box, m (see demo_params_box_size).
void demo_sim_box_size(const demo_sim *sim, double size[3]);
/// Sphere centres, m: x, y, z per sphere (3n doubles). Valid until the next step.
const double *demo_sim_positions(const demo_sim *sim);
/// Sphere velocities, m/s: x, y, z per sphere (3n doubles). Valid until the next step.
const double *demo_sim_velocities(const demo_sim *sim);
/// The AABBs bpx saw in the last broad phase (before any step: the initial positions), bit for
/// bit as bpx's updater makes them: min = c + (-r), max = c - (-r) in float. out holds n boxes.
void demo_sim_boxes(const demo_sim *sim, bpx_box *out);
/// The pairs of the last broad phase, sorted by (i, j). *count receives their number.
const bpx_pair *demo_sim_pairs(const demo_sim *sim, size_t *count);

/// Total kinetic energy, J.
double demo_sim_kinetic_energy(const demo_sim *sim);
/// Total linear momentum, kg m/s.
void demo_sim_momentum(const demo_sim *sim, double p[3]);
/// Sum of all wall impulses so far, kg m/s: momentum(t) = momentum(0) + this, up to rounding.
void demo_sim_wall_impulse(const demo_sim *sim, double j[3]);
/// Largest overlap of two spheres seen by any narrow phase so far, m (0 if none).
double demo_sim_max_penetration(const demo_sim *sim);
/// Largest sphere speed seen at the end of any cycle so far, m/s.
double demo_sim_max_speed(const demo_sim *sim);

/// The world's backend and SIMD width, for reports.
bpx_backend demo_sim_backend(const demo_sim *sim);
bpx_simd demo_sim_simd(const demo_sim *sim);

/// Nanoseconds on a monotonic clock (for the display stage's timing).
uint64_t demo_now_ns(void);

#ifdef __cplusplus
}
#endif
